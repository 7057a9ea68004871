"""The method path of the ``redundancy`` ask: several tasks, velocity or acceleration level, and the methods
pseudoinverse, weighted pseudoinverse, damped least squares, null-space term, task priority, extended Jacobian and
SNS at one state, compared in one table (math in :mod:`solver.kinematics.resolution`).

At acceleration level, with q̇ given at the state, each task r_k = f_k(q) has r̈_k = J_k q̈ + J̇_k q̇, and every method
is applied to the vector r̈_k − J̇_k q̇; the preferred acceleration is q̈₀ (``null:``), −K_d q̇ (``damping:``), or
their sum.
"""
from __future__ import annotations

import math
from typing import Any, Literal, Union

import numpy as np
import sympy as sp
from pydantic import Field

from solver.kinematics import resolution as rs
from solver.math.numeric import lambdify_np
from solver.registry import PropertyVerdict, property_check
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.expr import shape_of
from solver.spec.models import Strict
from solver.spec.problem import AskReader

ExprT = Union[str, int, float, list[Any]]
Scalar = Union[str, int, float]

METHODS = ("pseudoinverse", "weighted", "dls", "null_space", "priority", "extended", "sns", "scaled", "max_scaling",
           "reduced_gradient", "extended_optimal")
Method = Literal["pseudoinverse", "weighted", "dls", "null_space", "priority", "extended", "sns", "scaled",
                 "max_scaling", "reduced_gradient", "extended_optimal"]
NAMED_H = ("manipulability", "joint_range")
EXACT_SIZE = 48  # total entries of the stacked Jacobian up to which exact data are solved exactly


class TaskItem(Strict):
    """One task of a multi-task problem (the list order is the priority order)."""

    name: str = Field(..., pattern=r"^[A-Za-z][A-Za-z0-9]*$", description="short name, used in result names")
    task: ExprT | None = Field(None, description="task function r = f(q) (vector or scalar)")
    jacobian: ExprT | None = Field(None, description="task Jacobian J(q), instead of task:")
    velocity: ExprT | None = Field(None, description="desired task velocity ṙ (velocity level)")
    acceleration: ExprT | None = Field(None, description="desired task acceleration r̈ (acceleration level)")


class Motion(Strict):
    """A motion at velocity level from a start configuration, with constant task velocities."""

    start: dict[str, Scalar] = Field(..., description="q at t = 0 {q1: ..., ...}")
    duration: float = Field(..., gt=0, le=1e4, description="seconds to integrate (stops earlier at a singularity)")
    method: Literal["pseudoinverse", "weighted", "dls", "extended", "priority", "null_space", "sns", "scaled"] | None = Field(
        None, description="the method commanding q̇ (q̈ at acceleration level; null_space, sns and scaled only "
                          "there); default: the first of methods: that applies")
    steps: int = Field(400, ge=10, le=20000, description="integration steps (RK4; smaller near a singularity)")
    sigma_min: float = Field(1e-4, gt=0, lt=1, description="stop when the smallest singular value of the "
                                                           "(stacked or projected) Jacobian falls below this")


class VariableDamping(Strict):
    """μ chosen from the smallest singular value σ of J: μ² = μ_max²(1 − (σ/ε)²) for σ < ε, else 0."""

    epsilon: float = Field(..., gt=0, description="size of the singular region (on σ_min)")
    max: float = Field(..., gt=0, description="largest damping μ_max (at σ = 0)")


class Bounds(Strict):
    lower: ExprT | None = Field(None, description="lower bounds (n values)")
    upper: ExprT | None = Field(None, description="upper bounds (n values)")
    position: list[ExprT] | None = Field(None, description="joint range [[min, max], ...] (with velocity:, "
                                                                "acceleration: and T: the bounds are derived)")
    velocity: ExprT | None = Field(None, description="|q̇_i| ≤ V_i (n values)")
    acceleration: ExprT | None = Field(None, description="|q̈_i| ≤ A_i (n values, acceleration level)")
    T: Scalar | None = Field(None, description="the control sampling time of the derived bounds")


def wants_methods(o: Any) -> bool:
    """True when the ask uses the method path (any of its options given)."""
    if isinstance(o.gradient, str) and o.gradient.strip() in NAMED_H:
        return True
    return any(getattr(o, k) is not None for k in ("tasks", "methods", "mu", "bounds", "damping",
                                                    "joint_velocity", "acceleration", "direction", "motion")) or o.level == "acceleration"


# ------------------------------------------------------------------------------------------------ parsing
def damping_matrix(reader: AskReader, n: int, key: str = "damping") -> sp.Matrix:
    """K_d of q̈₀ = −K_d q̇ from ``damping:``: a scalar (K_d = k I), n diagonal entries or an n×n matrix."""
    v = reader.ctx.expr(key)
    shp = shape_of(v)
    K = (v * sp.eye(n) if shp == () else sp.diag(*v) if shp == (n,) else sp.Matrix(v) if shp == (n, n) else None)
    if K is None:
        raise reader.fail((key,), f"{key} must be a scalar, {n} diagonal entries or {n}x{n}")
    return K


def named_objective(reader: AskReader, name: str, J: sp.Matrix, q: list, ranges: dict | None) -> sp.Expr:
    """A named H(q) of ``gradient:``: manipulability √det(JJᵀ) of the (stacked) task Jacobian J (parameter values
    substituted); joint_range −1/(2n) Σ ((q_i − q̄_i)/(q_M,i − q_m,i))² from ``joint_ranges:``."""
    if name == "manipulability":
        JE = J.subs(reader.problem.values)
        return sp.sqrt((JE * JE.T).det())
    if not ranges:
        raise reader.fail(("gradient",), "gradient: joint_range needs joint_ranges: {q1: [min, max], ...}")
    terms = []
    for x in q:
        if x.name not in ranges:
            raise reader.fail(("joint_ranges",), f"joint_ranges: misses {x.name}")
        lo, hi = (reader.ctx.expr("joint_ranges", x.name, k) for k in (0, 1))
        terms.append(((x - (lo + hi) / 2) / (hi - lo)) ** 2)
    return -sp.Add(*terms) / (2 * len(q))


class _MSpec(AskReader):
    """The parsed, validated inputs of the method path; ``check_only`` (validation): the same checks without B
    (`weight: inertia`) and without the value of a named H."""

    def __init__(self, problem, o, ctx, check_only: bool = False) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.o, self.ctx = problem, o, ctx
        self.options = o
        self.check_only = check_only
        robot = problem.robot
        self.acc = o.level == "acceleration"
        self.q: list[sp.Symbol] = list(robot.q) if robot is not None else []
        self.tasks: list[dict[str, Any]] = []
        if o.tasks:
            for i, t in enumerate(o.tasks):
                if (t.task is None) == (t.jacobian is None):
                    raise self.fail(("tasks", i), "give exactly one of task: or jacobian: for each task")
                self.tasks.append(self._task(("tasks", i), t, t.name))
        else:
            self.tasks.append(self._task((), o, "r"))
        self.n = len(self.q)
        self.state = self._state()
        self.methods: list[str] = list(o.methods) if o.methods else self._default_methods()
        self.qd = self._vec("joint_velocity", self.n) if o.joint_velocity is not None else None
        if self.acc and self.qd is None:
            raise self.fail(("level",), "the acceleration level needs the joint velocity at the state",
                            "add joint_velocity: [qdot1, ..., qdotn] (zeros for a robot at rest)")
        self.W = None
        if o.weight is not None:
            from solver.kinematics.redundancy import (
                _Spec,  # the weight parser of the ask
            )
            self.W = _Spec._weight(self)  # type: ignore[arg-type]
        if "weighted" in self.methods and self.W is None:
            raise self.fail(("methods",), "the weighted method needs weight:")
        self.mu = None
        self.mu_auto = o.mu if isinstance(o.mu, VariableDamping) else None
        if o.mu is not None and self.mu_auto is None:
            self.mu = ctx.expr("mu")
        if "dls" in self.methods and self.mu is None and self.mu_auto is None:
            raise self.fail(("methods",), "the dls method needs mu: (the damping factor μ)")
        self.Kd = damping_matrix(self, self.n) if o.damping is not None else None
        self.q0 = None
        for key in ("null", "qdot0"):
            if getattr(o, key) is not None:
                self.q0 = self._vec(key, self.n)
        self.H = None
        self.H_name = None
        if isinstance(o.gradient, str) and o.gradient.strip() in NAMED_H:
            self.H_name = o.gradient.strip()
            self.H = self._named_H(self.H_name) if not check_only or self.H_name != "manipulability" else None
            self.step = ctx.expr("step") if "step" in o.model_fields_set else sp.Integer(1)
        elif o.gradient is not None:
            H = ctx.expr("gradient")
            if isinstance(H, list):
                raise self.fail(("gradient",), "gradient: must be a scalar function H(q)")
            self.H = H
            self.step = ctx.expr("step") if "step" in o.model_fields_set else sp.Integer(1)
        self.lo = self.hi = None
        if o.bounds is not None:
            if isinstance(o.bounds, Bounds) and o.bounds.lower is not None and o.bounds.upper is not None:
                self.lo = list(self._vec(("bounds", "lower"), self.n))
                self.hi = list(self._vec(("bounds", "upper"), self.n))
            elif isinstance(o.bounds, Bounds):
                self.lo, self.hi = self._derived_bounds(o.bounds)
            else:
                b = ctx.expr("bounds")
                b = [b] * self.n if not isinstance(b, list) else b
                if shape_of(b) != (self.n,):
                    raise self.fail(("bounds",), f"bounds must have {self.n} components (symmetric ±) or be "
                                                 "{lower: [...], upper: [...]}")
                self.hi = list(b)
                self.lo = [-x for x in b]
        self.direction = None
        if o.direction is not None:
            if len(self.tasks) > 1:
                raise self.fail(("direction",), "direction: applies to a single task")
            if isinstance(o.direction, str) and o.direction.strip() == "stop":
                if self.qd is None:
                    raise self.fail(("direction",), "direction: stop needs joint_velocity:")
                self.direction = -self.tasks[0]["J"] * self.qd
            else:
                self.direction = self._vec("direction", self.tasks[0]["m"])
            if problem.robot is not None and self.qd is not None:
                self.direction = self.direction.subs({d: self.qd[i] for i, d in enumerate(problem.robot.dq)})
        if "max_scaling" in self.methods and (self.direction is None or self.lo is None):
            raise self.fail(("methods",), "max_scaling needs direction: and bounds:")
        if any(m in self.methods for m in ("sns", "scaled")) and self.lo is None:
            raise self.fail(("methods",), "sns and scaled need bounds: on the joint "
                                          + ("accelerations" if self.acc else "velocities"))
        if len(self.tasks) > 1 and ("null_space" in self.methods or "weighted" in self.methods):
            pass

    def _derived_bounds(self, b: Bounds) -> tuple[list, list]:
        """Bounds on the command from joint range Q, velocity V and acceleration A limits over one sampling time T
        (the SNS convention): velocity level max{(Q_min − q)/T, −V} ≤ q̇ ≤ min{(Q_max − q)/T, V}; acceleration level
        max{2(Q_min − q − q̇T)/T², −(V + q̇)/T, −A} ≤ q̈ ≤ min{2(Q_max − q − q̇T)/T², (V − q̇)/T, A}."""
        if b.T is None or b.velocity is None or (self.acc and b.acceleration is None):
            raise self.fail(("bounds",), "give lower:/upper:, or T: with velocity: (and acceleration: at "
                                         "acceleration level), position: optional")
        T = self.ctx.expr("bounds", "T")
        V = list(self._vec(("bounds", "velocity"), self.n))
        A = list(self._vec(("bounds", "acceleration"), self.n)) if self.acc else None
        Q = None
        if b.position is not None:
            if len(b.position) != self.n:
                raise self.fail(("bounds", "position"), f"position: needs {self.n} ranges [min, max]")
            Q = [(self.ctx.expr("bounds", "position", i, 0), self.ctx.expr("bounds", "position", i, 1))
                 for i in range(self.n)]
        vals = {**self.problem.values, **self.state}
        q = [x.subs(vals) for x in self.q]
        qd = list(self.qd.subs(self.problem.values)) if self.qd is not None else [0] * self.n
        lo, hi = [], []
        for i in range(self.n):
            if self.acc:
                cl = [-(V[i] + qd[i]) / T, -A[i]]
                ch = [(V[i] - qd[i]) / T, A[i]]
                if Q:
                    cl.append(2 * (Q[i][0] - q[i] - qd[i] * T) / T ** 2)
                    ch.append(2 * (Q[i][1] - q[i] - qd[i] * T) / T ** 2)
            else:
                cl, ch = [-V[i]], [V[i]]
                if Q:
                    cl.append((Q[i][0] - q[i]) / T)
                    ch.append((Q[i][1] - q[i]) / T)
            cl = [sp.nsimplify(sp.sympify(c)) if sp.sympify(c).is_Float else sp.sympify(c) for c in cl]
            ch = [sp.nsimplify(sp.sympify(c)) if sp.sympify(c).is_Float else sp.sympify(c) for c in ch]
            lo.append(sp.Max(*cl))
            hi.append(sp.Min(*ch))
            if bool(lo[-1] > hi[-1]):
                raise self.fail(("bounds",), f"the derived bounds of joint {i + 1} are empty ({lo[-1]} > {hi[-1]})")
        return lo, hi

    def _named_H(self, name: str) -> sp.Expr:
        return named_objective(self, name, sp.Matrix.vstack(*[t["J"] for t in self.tasks]), self.q,
                               self.o.joint_ranges)

    def _default_methods(self) -> list[str]:
        out = ["pseudoinverse"] if len(self.tasks) == 1 else ["extended", "priority"]
        if self.o.weight is not None:
            out.append("weighted")
        if self.o.mu is not None:
            out.append("dls")
        if any(getattr(self.o, k) is not None for k in ("null", "qdot0", "gradient", "damping")):
            out.append("null_space")
        if self.o.direction is not None:
            return ["max_scaling"]
        if self.o.bounds is not None:
            out += ["scaled", "sns"]
        return out

    def _vec(self, key: Any, size: int) -> sp.Matrix:
        path = key if isinstance(key, tuple) else (key,)
        val = self.ctx.expr(*path)
        if not isinstance(val, list):
            val = [val]
        if shape_of(val) != (size,):
            raise self.fail(path, f"{path[-1]} must have {size} components, got shape {shape_of(val)}")
        return sp.Matrix(val)

    def _task(self, path: tuple, t: Any, name: str) -> dict[str, Any]:
        if t.task is not None:
            if self.problem.robot is None:
                raise self.fail(path + ("task",), "task: needs the robot's coordinates")
            val = self.ctx.expr(*path, "task")
            f = sp.Matrix(val if isinstance(val, list) else [val])
            J = f.jacobian(self.q)
        else:
            val = self.ctx.expr(*path, "jacobian")
            shp = shape_of(val)
            J = sp.Matrix([[val]]) if shp == () else sp.Matrix([val]) if len(shp) == 1 else sp.Matrix(val)
            f = None
            if not self.q:
                self.q = [sp.Symbol(f"q{i + 1}", real=True) for i in range(J.shape[1])]
            if J.shape[1] != len(self.q):
                raise self.fail(path + ("jacobian",), f"jacobian must have {len(self.q)} columns")
        m = J.shape[0]
        key = "acceleration" if self.acc else "velocity"
        raw = getattr(t, key)
        if raw is None and getattr(self.o, "direction", None) is not None and not path:
            return {"name": name, "f": f, "J": J, "r": sp.zeros(m, 1), "m": m}
        if raw is None:
            raise self.fail(path or (key,), f"give {key}: (the desired task {key}, {m} components)")
        val = self.ctx.expr(*path, key)
        val = val if isinstance(val, list) else [val]
        if shape_of(val) != (m,):
            raise self.fail(path + (key,), f"{key} must have {m} components, got shape {shape_of(val)}")
        return {"name": name, "f": f, "J": J, "r": sp.Matrix(val), "m": m}

    def _state(self) -> dict[sp.Symbol, sp.Expr]:
        if self.o.at is None and all(t["f"] is None and not (t["J"].free_symbols & set(self.q)) for t in self.tasks):
            return {}  # constant Jacobians (given numerically): no configuration needed
        if self.o.at is None:
            raise self.fail((), "the methods need a configuration", "add at: {q1: ..., q2: ...}")
        by_name = {s.name: s for s in self.q}
        state = {}
        for name in self.o.at:
            if name not in by_name:
                raise self.fail(("at", name), f"'{name}' in at: is not a coordinate", "use " + ", ".join(by_name))
            state[by_name[name]] = self.ctx.expr("at", name)
        missing = [s.name for s in self.q if s not in state]
        if missing:
            raise self.fail(("at",), "at: must give every coordinate; missing " + ", ".join(missing))
        return state


def read_methods(problem, o, ctx) -> None:  # type: ignore[no-untyped-def]
    """The method path's options read and checked as :func:`solve_methods` reads them (validation)."""
    _MSpec(problem, o, ctx, check_only=True)


# ------------------------------------------------------------------------------------------------ helpers
def _is_rational(M: sp.Matrix) -> bool:
    return all(sp.nsimplify(x).is_Rational if x.is_Float else bool(x.is_Rational) for x in M)


def _exact(x: sp.Expr) -> sp.Expr:
    """Rational for a Rational-valued Float-free number; the expression itself otherwise (π stays π)."""
    return sp.nsimplify(x) if x.is_Rational or x.atoms(sp.Float) else sp.simplify(x) if sp.count_ops(x) > 8 else x


def _exact_number(M: sp.Matrix) -> bool:
    """Exact numbers (no Float) of moderate size, e.g. 3*pi**2/4."""
    return all(x.is_number and not x.atoms(sp.Float) and sp.count_ops(x) <= 30 for x in M)


def _vec_latex_name(acc: bool) -> str:
    return "\\ddot q" if acc else "\\dot q"


# ------------------------------------------------------------------------------------------------ solver
def solve_methods(problem, o, ctx, sol: Solution) -> Solution:  # type: ignore[no-untyped-def]
    """Results (suffixed): J[_k], J_at[_k], Jdot_qdot[_k], rank[_k], J_pinv, rank_JE, JE, JE_pinv, P1..,
    J2P1.., rank_J2P1.., algorithmic_singular, J_dls, <v>_ps, <v>_w, <v>_dls, <v>, <v>_tp, <v>_e, <v>_sns,
    <v>_ps_scaled, ps_scaling, sns_scale, <v>_sns_<it>, norm_<v>_<method>, err_<task>_<method>
    with <v> = qdot (velocity level) or qddot (acceleration level)."""
    spec = _MSpec(problem, o, ctx)
    sfx = o.suffix
    acc = spec.acc
    v = "qddot" if acc else "qdot"
    vl = _vec_latex_name(acc)
    multi = len(spec.tasks) > 1

    def add(name: str, value: Any, kind: str | None = None, label: str = "") -> None:
        sol.add(name + sfx, value, kind, label=label)

    def tn(base: str, k: int) -> str:
        return f"{base}{k}" if multi else base

    subs = {**problem.values, **spec.state}
    tasks_num = []
    for k, t in enumerate(spec.tasks, start=1):
        Ja = t["J"].subs(subs)
        add(tn("J", k), t["J"], "matrix", label=f"J_{{{k}}}(q)" if multi else "J(q)")
        add(tn("J_at", k), Ja, "matrix", label=f"J_{{{k}}}" if multi else "J")
        h = None
        if t["f"] is not None:
            add(tn("f", k), t["f"], "vector", label=f"f_{{{k}}}(q)" if multi else "f(q)")
            add(tn("r_at", k), t["f"].subs(subs), "vector", label=f"r_{{{k}}}" if multi else "r")
        if acc:
            rdot = (t["J"] * spec.qd).subs(subs)
            add(tn("rdot_at", k), rdot, "vector", label=f"\\dot r_{{{k}}} = J_{{{k}}}\\dot q" if multi
                else "\\dot r = J\\dot q")
            if problem.robot is not None and sp.count_ops(t["J"]) <= 400:
                from solver.math.simplify import tidy
                dq = sp.Matrix(list(problem.robot.dq))
                Jd_sym = sum((t["J"].diff(x) * dq[i] for i, x in enumerate(spec.q)), sp.zeros(*t["J"].shape))
                add(tn("Jdot_qdot_sym", k), (Jd_sym * dq).applyfunc(tidy), "vector",
                    label=f"\\dot J_{{{k}}}(q)\\dot q" if multi else "\\dot J(q)\\dot q")
            Jdot = sum((t["J"].diff(x) * spec.qd[i] for i, x in enumerate(spec.q)), sp.zeros(*t["J"].shape))
            Jdot_at = Jdot.subs(subs)
            add(tn("Jdot_at", k), Jdot_at.applyfunc(sp.nsimplify) if _is_rational(Jdot_at) else Jdot_at, "matrix",
                label=f"\\dot J_{{{k}}}" if multi else "\\dot J")
            h = (Jdot * spec.qd).subs(subs)
            h = h.applyfunc(sp.nsimplify) if _is_rational(h) else h
            add(tn("Jdot_qdot", k), h, "vector", label=f"\\dot J_{{{k}}}\\dot q" if multi else "\\dot J \\dot q")
        r = t["r"].subs(subs)
        x = r - h if h is not None else r
        tasks_num.append({**t, "Ja": Ja, "h": h, "ra": r, "x": x})
    free = set()
    for t in tasks_num:
        free |= t["Ja"].free_symbols | t["x"].free_symbols
    if spec.W is not None:
        free |= spec.W.subs(subs).free_symbols
    if free:
        names = ", ".join(sorted(s.name for s in free))
        raise spec.fail(("at",), f"the methods are computed on numbers; {names} left symbolic",
                        "give them values: (or in at:)")
    mats = [t["Ja"] for t in tasks_num]
    if spec.W is not None:
        mats.append(spec.W.subs(subs))
    vecs = [t["x"] for t in tasks_num] + ([spec.qd] if spec.qd is not None else [])
    if spec.direction is not None:
        vecs.append(spec.direction)
    size = sum(t["Ja"].shape[0] for t in tasks_num) * spec.n
    # exact when the matrices are rational and the vectors exact numbers (π, surds: only scaled and compared)
    exact = size <= EXACT_SIZE and all(_is_rational(M.subs(subs)) for M in mats) and \
        all(_exact_number(M.subs(subs)) for M in vecs) and \
        (spec.mu is None or _is_rational(sp.Matrix([spec.mu]).subs(subs))) and \
        (spec.Kd is None or _is_rational(spec.Kd.subs(subs))) and \
        (spec.lo is None or _exact_number(sp.Matrix(spec.lo + spec.hi).subs(subs)))
    la = rs.LA(exact, o.rank_tol)
    Js = [la.mat(t["Ja"].applyfunc(sp.nsimplify) if exact else t["Ja"]) for t in tasks_num]
    xs = [la.mat(t["x"].applyfunc(_exact) if exact else t["x"]) for t in tasks_num]
    sol.step("m_setup", tasks=tasks_num, q=sp.Matrix(spec.q), n=spec.n, acc=acc, state=spec.state,
             qd=spec.qd, exact=exact, tol=o.rank_tol, multi=multi, methods=spec.methods,
             values={k: val for k, val in problem.values.items()
                     if any(k in t["J"].free_symbols for t in spec.tasks)})

    # ranks of each task
    for k, (t, J) in enumerate(zip(tasks_num, Js), start=1):
        rk = la.rank(J)
        t["rank"] = rk
        add(tn("rank", k), sp.Integer(rk), "number", label=f"\\operatorname{{rank}} J_{{{k}}}" if multi else
            "\\operatorname{rank} J")
        if not multi:
            add("singular", bool(rk < t["m"]), "bool", label="\\text{singular}")
    sv = [la.svals(J) for J in Js]
    sol.step("m_rank", tasks=tasks_num, svals=[[sp.Float(float(s), 6) for s in x] for x in sv], tol=o.rank_tol,
             exact=exact)

    JE = la.vstack(Js)
    xE = la.vstack(xs)
    n = spec.n
    add("J_task", la.sym(JE), "matrix", label="J" if not multi else "J_E")
    add("task_x", la.sym(xE), "vector", label="\\ddot r_d - \\dot J\\dot q" if acc else "\\dot r_d")
    if spec.lo is not None:
        add("bounds_lower", sp.Matrix([b.subs(subs) for b in spec.lo]), "vector", label="\\text{lower bounds}")
        add("bounds_upper", sp.Matrix([b.subs(subs) for b in spec.hi]), "vector", label="\\text{upper bounds}")
    # preferred (null-space) vector
    q0 = None
    grad = None
    if spec.q0 is not None or spec.H is not None or spec.Kd is not None:
        q0s = sp.zeros(n, 1)
        grad = None
        if spec.q0 is not None:
            q0s += spec.q0.subs(subs)
        if spec.H is not None:
            from solver.math.simplify import tidy
            if spec.H_name == "manipulability":  # √det(JJᵀ): its symbolic gradient is long; evaluated at the state
                grad = sp.Matrix([sp.diff(spec.H, x) for x in spec.q]).subs(subs).evalf(15)
            else:
                gsym = sp.Matrix([tidy(sp.diff(spec.H, x)) for x in spec.q])
                add("grad_H", gsym, "vector", label="\\nabla_q H(q)")
                grad = gsym.subs(subs)
            q0s += spec.step * grad
            add("grad_H_at", grad, "vector", label="\\nabla_q H")
        if spec.Kd is not None:
            q0s += -(spec.Kd * spec.qd).subs(subs)
        q0s = q0s.subs(subs)
        if q0s.free_symbols:
            raise spec.fail(("at",), "the preferred null-space vector depends on "
                            + ", ".join(sorted(x.name for x in q0s.free_symbols)) + ", left symbolic",
                            "give them values:")
        if exact and not _exact_number(q0s):
            la = rs.LA(False, o.rank_tol)
            exact = False
            Js = [la.mat(t["Ja"]) for t in tasks_num]
            xs = [la.mat(t["x"]) for t in tasks_num]
            JE, xE = la.vstack(Js), la.vstack(xs)
        q0 = la.mat(q0s.applyfunc(_exact) if exact else q0s)
        add(f"{v}0", la.sym(q0), "vector", label=f"{vl}_0")
        sol.step("m_null", q0=la.sym(q0), grad=grad, H=None if spec.H_name == "manipulability" else spec.H,
                 H_name=spec.H_name, step=getattr(spec, "step", None), Kd=spec.Kd,
                 acc=acc, given=spec.q0)

    results: list[tuple[str, str, Any]] = []  # (method label, result name, vector)

    def record(method: str, label: str, vec: Any) -> None:
        name = f"{v}_{method}" if method else v
        add(name, la.sym(vec), "vector", label=f"{vl}_{{\\mathrm{{{label}}}}}" if label else vl)
        results.append((label or "null space", name, vec))

    Jp = None
    for meth in spec.methods:
        if meth == "pseudoinverse":
            Jp = la.pinv(JE)
            vec = Jp @ xE
            add("J_pinv", la.sym(Jp), "matrix", label="J^{\\#}")
            if multi:
                add("JE", la.sym(JE), "matrix", label="J_E")
            sol.step("m_pinv", J=la.sym(JE), Jp=la.sym(Jp), x=la.sym(xE), v=la.sym(vec), acc=acc,
                     rank=la.rank(JE), m=JE.shape[0], multi=multi, full=la.rank(JE) == JE.shape[0])
            record("ps", "PS", vec)
        elif meth == "weighted":
            W = la.mat(spec.W.subs(subs).applyfunc(sp.nsimplify) if exact else spec.W.subs(subs))
            JWp = rs.weighted_pinv(la, JE, W)
            vec = JWp @ xE
            add("J_pinv_W", la.sym(JWp), "matrix", label="J^{\\#}_W")
            sol.step("m_weighted", W=la.sym(W), Jp=la.sym(JWp), v=la.sym(vec), acc=acc)
            record("w", "W", vec)
        elif meth == "dls":
            if spec.mu_auto is not None:
                mu = rs.variable_damping(la, JE, spec.mu_auto.epsilon, spec.mu_auto.max)
                if exact:  # σ_min is irrational in general: μ to 12 decimals, the rest stays exact
                    mu = sp.Rational(str(round(mu, 12)))
                add("mu_dls", la.scalar(mu), "number", label="\\mu")
            else:
                mu = spec.mu.subs(subs) if isinstance(spec.mu, sp.Basic) else spec.mu
                mu = sp.nsimplify(mu) if exact else float(mu)
            Jd = rs.dls(la, JE, mu)
            vec = Jd @ xE
            add("J_dls", la.sym(Jd), "matrix", label="J_{DLS}")
            sol.step("m_dls", mu=la.scalar(mu), auto=spec.mu_auto, J=la.sym(JE), Jd=la.sym(Jd), v=la.sym(vec), acc=acc,
                     JJ=la.sym(JE @ JE.T + mu ** 2 * la.eye(JE.shape[0])))
            record("dls", "DLS", vec)
        elif meth == "null_space":
            if q0 is None:
                raise spec.fail(("methods",), "null_space needs null:, gradient: or damping:")
            Jp1 = Jp if Jp is not None else la.pinv(JE)
            P = rs.projector(la, JE, Jp1)
            vps = Jp1 @ xE
            vec = vps + P @ q0
            add("P", la.sym(P), "matrix", label="I - J^{\\#}J")
            sol.step("m_ns", P=la.sym(P), vps=la.sym(vps), vn=la.sym(P @ q0), v=la.sym(vec), acc=acc)
            record("", "", vec)
        elif meth == "reduced_gradient":
            if q0 is None or spec.H is None:
                raise spec.fail(("methods",), "reduced_gradient needs gradient: (H(q), or a named H)")
            gnum = grad if grad is not None else sp.Matrix([sp.diff(spec.H, x) for x in spec.q]).subs(subs)
            gvec = la.mat(gnum.applyfunc(_exact) if exact else gnum.evalf(15))
            if spec.o.partition:
                names = [x.name for x in spec.q]
                bad = [p for p in spec.o.partition if p not in names]
                if bad or len(spec.o.partition) != JE.shape[0]:
                    raise spec.fail(("partition",), f"partition: must name {JE.shape[0]} coordinates (the joints of "
                                                    "the square J_a)")
                a_idx = [names.index(p) for p in spec.o.partition]
            else:
                a_idx = rs.best_partition(la, JE)
            Ja = JE[:, a_idx]
            if la.rank(Ja) < JE.shape[0]:
                raise spec.fail(("partition",), "J_a is singular here: choose other joints in partition:")
            stp = spec.step.subs(problem.values) if isinstance(spec.step, sp.Basic) else spec.step
            stp = _exact(sp.sympify(stp)) if exact else float(sp.N(stp))
            vec, gr = rs.reduced_gradient(la, JE, xE, gvec, a_idx, stp)
            add("grad_reduced", la.sym(gr), "vector", label="\\nabla' H")
            add("Ja", la.sym(Ja), "matrix", label="J_a")
            add("Ja_inv", la.sym(la.inv(Ja)), "matrix", label="J_a^{-1}")
            add("Jb", la.sym(JE[:, [j for j in range(spec.n) if j not in a_idx]]), "matrix", label="J_b")
            sol.step("m_rg", a=[spec.q[i] for i in a_idx], b=[x for i, x in enumerate(spec.q) if i not in a_idx],
                     Ja=la.sym(Ja), gr=la.sym(gr), v=la.sym(vec), step=la.scalar(stp), acc=acc,
                     grad=la.sym(gvec))
            record("rg", "RG", vec)
        elif meth == "extended_optimal":
            # Baillieul: with n - m = 1, the optimality condition of H along the self-motion, g(q) = n(q)ᵀ∇H = 0,
            # n(q) the generalized cross product of the rows of J (signed m x m minors), completes J to a square J_ext
            JEs = sp.Matrix.vstack(*[t["J"] for t in spec.tasks]).subs(problem.values)
            mE = JEs.shape[0]
            if spec.H is None or spec.n - mE != 1:
                raise spec.fail(("methods",), "extended_optimal needs gradient: (H) and a redundancy degree n - m = 1")
            nvec = sp.Matrix([(-1) ** j * JEs[:, [c for c in range(spec.n) if c != j]].det() for j in range(spec.n)])
            gH = sp.Matrix([sp.diff(spec.H, x) for x in spec.q]).subs(problem.values)
            g = (nvec.T * gH)[0, 0]
            dg = sp.Matrix([[sp.diff(g, x) for x in spec.q]])
            Jx = sp.Matrix.vstack(JEs, dg).subs(subs)
            g_at = g.subs(subs)
            Jxn = la.mat(Jx.applyfunc(_exact) if exact and _exact_number(Jx) and _is_rational(Jx) else Jx.evalf(15))
            if la.exact and not _is_rational(Jx):
                lf = rs.LA(False, o.rank_tol)
                Jxn, xx = lf.mat(Jx.evalf(15)), lf.mat(la.sym(xE).evalf(15))
            else:
                lf, xx = la, xE
            rk = lf.rank(Jxn)
            rhs = lf.vstack([xx, lf.zeros(1, 1)])
            vec_f = (lf.inv(Jxn) if rk == spec.n else lf.pinv(Jxn)) @ rhs
            vec = la.mat(lf.sym(vec_f)) if la.exact and lf is not la else vec_f
            add("g_opt_at", g_at.evalf(15) if not g_at.is_Rational else g_at, "number",
                label="g(q) = n(q)^T\\nabla H")
            add("J_ext", lf.sym(Jxn), "matrix", label="J_{ext}")
            sol.step("m_extopt", n=lf.sym(Jxn), g=sp.Float(float(sp.N(g_at)), 6), rank=rk, v=lf.sym(vec_f),
                     nvec=nvec if sp.count_ops(nvec) < 60 else None, acc=acc)
            record("xo", "ext,opt", vec)
        elif meth == "extended":
            vec, JEe, JEp, rk = rs.extended(la, Js, xs)
            add("JE", la.sym(JEe), "matrix", label="J_E")
            detE = None
            if JEe.shape[0] == n and n <= 4:
                JEs = sp.Matrix.vstack(*[t["J"] for t in spec.tasks])
                if sp.count_ops(JEs) <= 200:
                    from solver.math.simplify import factor_within, tidy
                    detE = factor_within(tidy(JEs.det()))
                    add("det_JE_sym", detE, "scalar", label="\\det J_E(q)")
            add("rank_JE", sp.Integer(rk), "number", label="\\operatorname{rank} J_E")
            add("JE_pinv", la.sym(JEp), "matrix", label="J_E^{\\#}")
            sol.step("m_ext", detE=detE, JE=la.sym(JEe), JEp=la.sym(JEp), rank=rk, m=JEe.shape[0], n=n, x=la.sym(xE),
                     v=la.sym(vec), acc=acc, square=JEe.shape[0] == n)
            record("e", "E", vec)
        elif meth == "priority":
            if not multi:
                raise spec.fail(("methods",), "priority needs two or more tasks: (tasks: [...])")
            vec, levels = rs.task_priority(la, Js, xs, q0)
            alg = False
            add("J1_pinv", la.sym(levels[0].JP_pinv), "matrix", label="J_1^{\\#}")
            for lv in levels:
                if lv.k >= 2:
                    add(f"P{lv.k - 1}", la.sym(lv.P_prev), "matrix", label=f"P_{{{lv.k - 1}}}")
                    add(f"J{lv.k}P{lv.k - 1}", la.sym(lv.JP), "matrix", label=f"J_{{{lv.k}}}P_{{{lv.k - 1}}}")
                    add(f"J{lv.k}P{lv.k - 1}_pinv", la.sym(lv.JP_pinv), "matrix",
                        label=f"(J_{{{lv.k}}}P_{{{lv.k - 1}}})^{{\\#}}")
                    add(f"rank_J{lv.k}P{lv.k - 1}", sp.Integer(lv.rank_JP), "number",
                        label=f"\\operatorname{{rank}}(J_{{{lv.k}}}P_{{{lv.k - 1}}})")
                    alg = alg or lv.algorithmic
            add("algorithmic_singular", bool(alg), "bool", label="\\text{algorithmic singularity}")
            J1s = spec.tasks[0]["J"].subs(problem.values)
            J2P1 = None
            if not (J1s.free_symbols & set(spec.q)) and not J1s.free_symbols:
                P1s = sp.eye(n) - J1s.pinv() * J1s
                J2P1 = (spec.tasks[1]["J"] * P1s).applyfunc(lambda e: sp.factor_terms(sp.simplify(e)))
                add("J2P1_sym", J2P1, "matrix", label="J_2(q) P_1")
            sol.step("m_tp", levels=[{"k": lv.k, "P": la.sym(lv.P_prev), "JP": la.sym(lv.JP),
                                      "JPp": la.sym(lv.JP_pinv), "rJ": lv.rank_J, "rJP": lv.rank_JP,
                                      "alg": lv.algorithmic, "smin": sp.Float(lv.smin_JP, 4),
                                      "corr": la.sym(lv.correction), "v": la.sym(lv.qdot)} for lv in levels],
                     names=[t["name"] for t in tasks_num], v=la.sym(vec), acc=acc, null=q0 is not None,
                     J2P1_sym=J2P1)
            record("tp", "TP", vec)
        elif meth == "scaled":
            Jp1 = Jp if Jp is not None else la.pinv(JE)
            vps = Jp1 @ xE
            lo = [_exact(b.subs(subs)) if exact else float(b.subs(subs)) for b in spec.lo]
            hi = [_exact(b.subs(subs)) if exact else float(b.subs(subs)) for b in spec.hi]
            k = rs.ps_scaling(la, vps, lo, hi)
            vec = vps / k
            add("ps_scaling", la.scalar(k), "number", label="k")
            add("ps_fraction", la.scalar(1 / k), "number", label="1/k")
            sol.step("m_scaled", vps=la.sym(vps), k=la.scalar(k), v=la.sym(vec), x=la.sym(xE), xs=la.sym(xE / k),
                     lo=lo, hi=hi, acc=acc, needed=k != 1)
            record("ps_scaled", "PS,scaled", vec)
        elif meth == "max_scaling":
            lo = [_exact(b.subs(subs)) if exact else float(b.subs(subs)) for b in spec.lo]
            hi = [_exact(b.subs(subs)) if exact else float(b.subs(subs)) for b in spec.hi]
            d = spec.direction.subs(subs)
            d = la.mat(d.applyfunc(_exact) if exact else d)
            Jp1 = Jp if Jp is not None else la.pinv(JE)
            a_v = Jp1 @ d
            b_v = Jp1 @ xE
            ms = rs.max_scaling(la, a_v, b_v, lo, hi)
            add("direction", la.sym(d), "vector", label="d")
            add("a_dir", la.sym(a_v), "vector", label="a = J^{\\#} d")
            add("b_drift", la.sym(b_v), "vector", label="b = J^{\\#}(r_d - \\dot J\\dot q)")
            add("lambda_i", sp.Matrix([_inf(u) for u in ms.upper]), "vector", label="\\lambda_i")
            for i, u in enumerate(ms.upper):
                if _inf(u).is_finite:
                    add(f"lambda_{i + 1}", _inf(u), "number", label=f"\\lambda_{{{i + 1}}}")
            add("scaling_feasible", ms.lam is not None, "bool", label="\\text{feasible}")
            vec = None
            if ms.lam is not None and ms.lam != float("inf") and ms.lam != sp.oo:
                vec = a_v * ms.lam + b_v
                add("lambda_max", la.scalar(ms.lam), "number", label="\\lambda^*")
                add("task_max", la.sym(d * ms.lam), "vector", label="\\ddot r = \\lambda^* d" if acc else "\\dot r = \\lambda^* d")
            sol.step("m_maxs", d=la.sym(d), a=la.sym(a_v), b=la.sym(b_v), lo=lo, hi=hi, acc=acc,
                     ivs=[None if iv is None else (_show(iv[0]), _show(iv[1])) for iv in ms.intervals],
                     lo_m=sp.Matrix([la.scalar(x) for x in lo]), hi_m=sp.Matrix([la.scalar(x) for x in hi]),
                     upper=[_inf(u) for u in ms.upper], lam=None if ms.lam is None else _inf(ms.lam),
                     v=la.sym(vec) if vec is not None else None, stop=isinstance(spec.o.direction, str))
            if vec is not None:
                record("max", "max", vec)
        elif meth == "sns":
            lo = [_exact(b.subs(subs)) if exact else float(b.subs(subs)) for b in spec.lo]
            hi = [_exact(b.subs(subs)) if exact else float(b.subs(subs)) for b in spec.hi]
            res = rs.sns(la, JE, xE, lo, hi)
            add("sns_scale", la.scalar(res.s), "number", label="s")
            add("sns_iterations", sp.Integer(len(res.steps)), "number", label="\\text{SNS iterations}")
            for st in res.steps:
                add(f"{v}_sns_{st.it}", la.sym(st.qdot), "vector", label=f"{vl}^{{({st.it})}}")
                if st.saturated:
                    _sns_reduced(add, la, JE, xE, st, v, vl)
            rows = [{"it": st.it, "sat": [i + 1 for i in st.saturated], "v": la.sym(st.qdot),
                     "v_num": la.sym(st.qdot).applyfunc(lambda x: x if x.is_Rational else x.evalf(5)),
                     "viol": [i + 1 for i in st.violating],
                     "scale": la.scalar(st.scale) if st.scale is not None else None,
                     "crit": st.critical + 1 if st.critical is not None else None,
                     "bound": la.scalar(st.bound) if st.bound is not None else None,
                     "rank": st.rank_JW} for st in res.steps]
            sol.step("m_sns", rows=rows, v=la.sym(res.qdot), s=la.scalar(res.s), lo=lo, hi=hi, acc=acc,
                     lo_m=sp.Matrix([la.scalar(x) for x in lo]), hi_m=sp.Matrix([la.scalar(x) for x in hi]),
                     feasible=res.feasible, n=n, m=JE.shape[0], **({"preferred": True} if q0 is not None else {}),
                     realized=float(la.norm(JE @ res.qdot - xE * res.s)) <= 1e-9 * max(1.0, float(la.norm(xE))))
            record("sns", "SNS", res.qdot)
    # comparison
    table = []
    for label, name, vec in results:
        errs = []
        for t, J, x in zip(tasks_num, Js, xs):
            e = J @ vec - x
            errs.append(la.norm(e))
            add(f"err_norm_{t['name']}_{name}", errs[-1], None,
                label=f"\\|J_{{{t['name']}}}{vl} - " + ("(\\ddot r - \\dot J\\dot q)" if acc else "\\dot r") + "\\|")
            add(f"err_{t['name']}_{name}", la.sym(e), "vector",
                label=f"J_{{{t['name']}}}{vl} - " + ("(\\ddot r - \\dot J\\dot q)" if acc else "\\dot r"))
        nm = la.norm(vec)
        add(f"norm_{name}", nm, None, label=f"\\|{vl}_{{\\mathrm{{{label}}}}}\\|")
        add(f"achieved_{name}", la.sym(JE @ vec), "vector", label=f"J{vl}_{{\\mathrm{{{label}}}}}")
        table.append({"label": label, "name": name + sfx, "v": la.sym(vec), "norm": nm,
                      "v_num": la.sym(vec).applyfunc(lambda x: x if x.is_Integer else x.evalf(5)),
                      "norm_num": sp.Float(float(nm), 6), "errs": [sp.Float(float(e), 6) for e in errs]})
    if spec.lo is not None:
        lo = [float(b.subs(subs)) for b in spec.lo]
        hi = [float(b.subs(subs)) for b in spec.hi]
        for row in table:
            row["within"] = all(lo[i] - 1e-9 <= float(row["v"][i]) <= hi[i] + 1e-9 for i in range(n))
    sol.step("m_compare", table=table, names=[t["name"] for t in tasks_num], acc=acc, bounds=spec.lo is not None)
    motion = None
    if o.motion is not None:
        motion = _motion(sol, problem, spec, add, tasks_num)
    _sketch(sol, problem, spec, tasks_num, table, subs, acc, motion)
    return sol


def _motion(sol: Solution, problem, spec: _MSpec, add, tasks: list) -> dict | None:  # type: ignore[no-untyped-def]
    """Integrate q̇ = method(q) (RK4, constant task velocities) from the start configuration; stop where the
    monitored smallest singular value falls below sigma_min (the first singularity met)."""
    mo = spec.o.motion
    if spec.acc:
        return _motion_acc(sol, problem, spec, add, tasks)
    if mo.method in ("null_space", "sns", "scaled"):
        raise spec.fail(("motion", "method"), f"{mo.method} along a motion is available at acceleration level")
    meth = mo.method or next((m for m in spec.methods if m in ("pseudoinverse", "weighted", "dls", "extended",
                                                                "priority")), "pseudoinverse")
    if meth == "priority" and len(tasks) < 2:
        raise spec.fail(("motion", "method"), "priority needs two or more tasks")
    by_name = {x.name: x for x in spec.q}
    start = []
    for x in spec.q:
        if x.name not in mo.start:
            raise spec.fail(("motion", "start"), f"start: must give every coordinate; missing {x.name}")
    for name in mo.start:
        if name not in by_name:
            raise spec.fail(("motion", "start", name), f"'{name}' is not a coordinate")
    start = [float(sp.N(spec.ctx.expr("motion", "start", x.name).subs(problem.values))) for x in spec.q]
    la = rs.LA(False, spec.o.rank_tol)
    Jf = [lambdify_np([spec.q], t["J"].subs(problem.values)) for t in tasks]
    xs = [np.array(sp.Matrix(t["r"]).subs(problem.values).evalf().tolist(), dtype=float).reshape(-1, 1)
          for t in tasks]
    if meth == "weighted":
        Wf = lambdify_np([spec.q], spec.W.subs(problem.values))
    mu = float(sp.N(sp.sympify(spec.mu).subs(problem.values))) if (meth == "dls" and spec.mu is not None) else None

    def jac(q: np.ndarray) -> list[np.ndarray]:
        return [np.atleast_2d(np.array(f(list(q)), dtype=float)) for f in Jf]

    # with task functions, the singular configuration is refined on r(q) = r(q(0)) + ṙ t, det J_E(q) = 0
    fb = all(tk["f"] is not None for tk in tasks)
    ff = [lambdify_np([spec.q], tk["f"].subs(problem.values)) for tk in tasks] if fb else []
    r0 = [np.array(f(start), dtype=float).reshape(-1, 1) for f in ff]
    now = [0.0]

    def vel(q: np.ndarray) -> tuple[np.ndarray, float]:
        Js = jac(q)
        xs_t = xs
        JE, xE = np.vstack(Js), np.vstack(xs_t)
        if meth == "priority":
            v, levels = rs.task_priority(la, Js, xs_t)
            sig = min([float(np.linalg.svd(Js[0], compute_uv=False)[-1])] + [lv.smin_JP for lv in levels[1:]])
        else:
            sv = np.linalg.svd(JE, compute_uv=False)
            sig = float(sv[min(JE.shape) - 1])
            if meth == "dls":
                v = rs.dls(la, JE, mu) @ xE
            elif meth == "weighted":
                v = rs.weighted_pinv(la, JE, np.array(Wf(list(q)), dtype=float)) @ xE
            else:
                v = la.pinv(JE) @ xE
        return v.ravel(), sig

    q = np.array(start)
    t, dt0 = 0.0, mo.duration / mo.steps
    ts, qs, vs, sigs = [], [], [], []
    reached = False
    while t < mo.duration - 1e-12 and len(ts) < 50 * mo.steps:
        now[0] = t
        v, sig = vel(q)
        ts.append(t), qs.append(q.copy()), vs.append(v), sigs.append(sig)
        if sig < mo.sigma_min:
            reached = True
            break
        dt = min(dt0, mo.duration - t, 0.002 / max(1e-12, float(np.max(np.abs(v)))) if np.max(np.abs(v)) > 0
                 else dt0)
        k1 = v
        now[0] = t + dt / 2
        k2 = vel(q + dt / 2 * k1)[0]
        k3 = vel(q + dt / 2 * k2)[0]
        now[0] = t + dt
        k4 = vel(q + dt * k3)[0]
        q = q + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += dt
    if not reached:
        now[0] = t
        v, sig = vel(q)
        ts.append(t), qs.append(q.copy()), vs.append(v), sigs.append(sig)
    refined = False
    m_tot = sum(x.shape[0] for x in xs)
    if reached and fb and m_tot == len(spec.q) and meth != "priority":
        z = np.concatenate([qs[-1], [ts[-1]]])
        xv = np.vstack(xs).ravel()
        rv = np.vstack(r0).ravel()

        def F(zz: np.ndarray) -> np.ndarray:
            qq, tt = zz[:-1], zz[-1]
            rq = np.concatenate([np.array(f(list(qq)), dtype=float).ravel() for f in ff])
            return np.concatenate([rq - rv - xv * tt, [np.linalg.det(np.vstack(jac(qq)))]])

        for _ in range(30):
            Fz = F(z)
            if np.linalg.norm(Fz) < 1e-12:
                break
            D = np.column_stack([(F(z + e) - F(z - e)) / 2e-7 for e in np.eye(z.size) * 1e-7])
            try:
                z = z - np.linalg.solve(D, Fz)
            except np.linalg.LinAlgError:
                break
        if np.linalg.norm(F(z)) < 1e-9 and np.linalg.norm(z[:-1] - qs[-1]) < 0.05:
            qs[-1], ts[-1], refined = z[:-1], float(z[-1]), True
    qe = sp.Matrix([sp.Float(x, 15) if abs(x) > 1e-12 else sp.Integer(0) for x in qs[-1]])
    add("q_end", qe, "vector", label="q(t_{end})")
    add("t_end", sp.Float(ts[-1], 15), "number", label="t_{end}")
    add("singularity_reached", bool(reached), "bool", label="\\text{singularity reached}")
    if reached:
        add("q_s", qe, "vector", label="q_s")
    pos = next((t for t in tasks if t["f"] is not None and t["m"] == 2), None)
    p_end = None
    if pos is not None:
        p_end = pos["f"].subs(problem.values).subs(dict(zip(spec.q, list(qe))))
        add("p_end", p_end.evalf(15), "vector", label="p(t_{end})")
    sol.step("m_motion", method=meth, start=sp.Matrix(start), duration=mo.duration, reached=reached,
             t_end=sp.Float(ts[-1], 6), q_end=qe.evalf(6), sig=sp.Float(sigs[-1], 3), sigma_min=mo.sigma_min,
             p_end=None if p_end is None else p_end.evalf(6), refined=refined, acc=False)
    lo = [float(sp.N(b.subs(problem.values))) for b in spec.lo] if spec.lo is not None else None
    hi = [float(sp.N(b.subs(problem.values))) for b in spec.hi] if spec.hi is not None else None
    T, V, S = list(ts), np.array(vs), list(sigs)
    peak = np.max(np.abs(V), axis=1)
    keep = peak <= 20 * max(1e-9, float(np.median(peak)))  # the blow-up at a singularity would hide the rest
    if not np.all(keep):
        T, V, S = [x for x, k in zip(T, keep) if k], V[keep], [x for x, k in zip(S, keep) if k]

    def sample() -> list[Panel]:
        curves = [Curve(f"$\\dot q_{{{i + 1}}}$", T, [float(x) for x in V[:, i]]) for i in range(V.shape[1])]
        hl = _bound_lines(lo, hi)
        return [Panel("$t$ [s]", "$\\dot q$", curves, hlines=hl),
                Panel("$t$ [s]", "$\\sigma_{min}$", [Curve("$\\sigma_{min}$", T, S)])]

    sol.figures.append(Figure("motion" + spec.o.suffix, f"Joint velocities along the motion ({meth}) and the "
                              "smallest singular value monitored" + (", with the bounds (dashed)" if hi else "")
                              + (" (the last samples, where the joint velocity blows up at the singularity, are not "
                                 "drawn)" if not np.all(keep) else "") + ".", sample))
    pts = [(float(sp.N(pos["f"][0].subs(problem.values).subs(dict(zip(spec.q, list(qq)))))),
            float(sp.N(pos["f"][1].subs(problem.values).subs(dict(zip(spec.q, list(qq))))))) for qq in qs[::max(1, len(qs) // 60)]] \
        if pos is not None else None
    return {"start": dict(zip(spec.q, [sp.Float(x, 6) for x in start])),
            "end": dict(zip(spec.q, list(qe))), "path": pts, "reached": reached}


def _motion_acc(sol: Solution, problem, spec: _MSpec, add, tasks: list) -> dict | None:  # type: ignore[no-untyped-def]
    """Acceleration level: integrate (q, q̇) with q̈ = method(q, q̇) applied to x = r̈_d − J̇(q)q̇ (constant r̈_d), RK4;
    stop at a singularity (σ_min below sigma_min). The report plots q̈(t) (with the bounds) and q̇(t)."""
    mo = spec.o.motion
    meth = mo.method or next((m for m in spec.methods if m in ("pseudoinverse", "weighted", "dls", "extended",
                                                                "priority", "null_space", "sns", "scaled")),
                             "pseudoinverse")
    if meth == "priority" and len(tasks) < 2:
        raise spec.fail(("motion", "method"), "priority needs two or more tasks")
    if meth in ("sns", "scaled") and spec.lo is None:
        raise spec.fail(("motion", "method"), f"{meth} needs bounds:")
    for x in spec.q:
        if x.name not in mo.start:
            raise spec.fail(("motion", "start"), f"start: must give every coordinate; missing {x.name}")
    n = len(spec.q)
    q_start = np.array([float(sp.N(spec.ctx.expr("motion", "start", x.name).subs(problem.values))) for x in spec.q])
    qd_start = np.array([float(sp.N(v.subs(problem.values))) for v in spec.qd])
    la = rs.LA(False, spec.o.rank_tol)
    dq = sp.symbols(f"_dq1:{n + 1}")
    Jf, hf = [], []
    for t in tasks:
        J = t["J"].subs(problem.values)
        Jdot = sum((J.diff(x) * dq[i] for i, x in enumerate(spec.q)), sp.zeros(*J.shape))
        Jf.append(lambdify_np([spec.q], J))
        hf.append(lambdify_np([spec.q, dq], Jdot * sp.Matrix(dq)))
    rdd = [np.array(t["r"].subs(problem.values).evalf().tolist(), dtype=float).reshape(-1, 1) for t in tasks]
    lo = [float(sp.N(b.subs(problem.values))) for b in spec.lo] if spec.lo is not None else None
    hi = [float(sp.N(b.subs(problem.values))) for b in spec.hi] if spec.hi is not None else None
    Kd = np.array(spec.Kd.subs(problem.values).evalf().tolist(), dtype=float) if spec.Kd is not None else None
    mu = float(sp.N(sp.sympify(spec.mu).subs(problem.values))) if (meth == "dls" and spec.mu is not None) else None
    Wf = lambdify_np([spec.q], spec.W.subs(problem.values)) if meth == "weighted" else None
    q0c = np.array(spec.q0.subs(problem.values).evalf().tolist(), dtype=float).reshape(-1, 1) \
        if spec.q0 is not None and not spec.q0.free_symbols else None

    def acc(q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, float]:
        Js = [np.atleast_2d(np.array(f(list(q)), dtype=float)) for f in Jf]
        xs = [r - np.array(h(list(q), list(qd)), dtype=float).reshape(-1, 1) for r, h in zip(rdd, hf)]
        JE, xE = np.vstack(Js), np.vstack(xs)
        sv = np.linalg.svd(JE, compute_uv=False)
        sig = float(sv[min(JE.shape) - 1])
        if meth == "priority":
            a, levels = rs.task_priority(la, Js, xs)
            sig = min([float(np.linalg.svd(Js[0], compute_uv=False)[-1])] + [lv.smin_JP for lv in levels[1:]])
        elif meth == "dls":
            muv = mu if mu is not None else rs.variable_damping(la, JE, spec.mu_auto.epsilon, spec.mu_auto.max)
            a = rs.dls(la, JE, muv) @ xE
        elif meth == "weighted":
            a = rs.weighted_pinv(la, JE, np.array(Wf(list(q)), dtype=float)) @ xE
        elif meth == "sns":
            a = rs.sns(la, JE, xE, lo, hi).qdot
        else:
            Jp = la.pinv(JE)
            a = Jp @ xE
            if meth == "scaled":
                a = a / rs.ps_scaling(la, a, lo, hi)
            elif meth == "null_space":
                v0 = np.zeros((n, 1))
                if Kd is not None:
                    v0 = v0 - Kd @ qd.reshape(-1, 1)
                if q0c is not None:
                    v0 = v0 + q0c
                a = a + (np.eye(n) - Jp @ JE) @ v0
        return a.ravel(), sig

    q, qd = q_start.copy(), qd_start.copy()
    t, dt = 0.0, mo.duration / mo.steps
    ts, qs, qds, qdds, sigs = [], [], [], [], []
    reached = False
    while t < mo.duration - 1e-12:
        a, sig = acc(q, qd)
        ts.append(t), qs.append(q.copy()), qds.append(qd.copy()), qdds.append(a), sigs.append(sig)
        if sig < mo.sigma_min:
            reached = True
            break
        h = min(dt, mo.duration - t)
        k1q, k1v = qd, a
        k2q, k2v = qd + h / 2 * k1v, acc(q + h / 2 * k1q, qd + h / 2 * k1v)[0]
        k3q, k3v = qd + h / 2 * k2v, acc(q + h / 2 * k2q, qd + h / 2 * k2v)[0]
        k4q, k4v = qd + h * k3v, acc(q + h * k3q, qd + h * k3v)[0]
        q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
        qd = qd + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        t += h
    if not reached:
        a, sig = acc(q, qd)
        ts.append(t), qs.append(q.copy()), qds.append(qd.copy()), qdds.append(a), sigs.append(sig)
    qe = sp.Matrix([sp.Float(x, 15) if abs(x) > 1e-12 else sp.Integer(0) for x in qs[-1]])
    add("q_end", qe, "vector", label="q(t_{end})")
    add("qdot_end", sp.Matrix([sp.Float(x, 15) for x in qds[-1]]), "vector", label="\\dot q(t_{end})")
    add("t_end", sp.Float(ts[-1], 15), "number", label="t_{end}")
    add("singularity_reached", bool(reached), "bool", label="\\text{singularity reached}")
    QDD = np.array(qdds)
    if hi is not None:
        within = bool(np.all(QDD <= np.array(hi) + 1e-7) and np.all(QDD >= np.array(lo) - 1e-7))
        add("motion_within_bounds", within, "bool", label="\\text{within bounds along the motion}")
    sol.step("m_motion", method=meth, start=sp.Matrix(q_start), duration=mo.duration, reached=reached,
             t_end=sp.Float(ts[-1], 6), q_end=qe.evalf(6), sig=sp.Float(sigs[-1], 3), sigma_min=mo.sigma_min,
             p_end=None, refined=False, acc=True)
    T, QD = list(ts), np.array(qds)

    def sample() -> list[Panel]:
        ca = [Curve(f"$\\ddot q_{{{i + 1}}}$", T, [float(x) for x in QDD[:, i]]) for i in range(n)]
        cv = [Curve(f"$\\dot q_{{{i + 1}}}$", T, [float(x) for x in QD[:, i]]) for i in range(n)]
        return [Panel("$t$ [s]", "$\\ddot q$", ca, hlines=_bound_lines(lo, hi)), Panel("$t$ [s]", "$\\dot q$", cv)]

    sol.figures.append(Figure("motion" + spec.o.suffix, f"Joint accelerations (with the bounds, dashed) and "
                              f"velocities along the motion ({meth}).", sample))
    return {"start": dict(zip(spec.q, [sp.Float(x, 6) for x in q_start])), "end": dict(zip(spec.q, list(qe))),
            "path": None, "reached": reached}


def _sns_reduced(add: Any, la: rs.LA, J: Any, x: Any, st: rs.SNSStep, v: str, vl: str) -> None:
    """The reduced problem of an SNS iteration with saturated joints S: J_{-S} (the columns of the active joints),
    the residual task x_k = s x − Σ_{j∈S} J_j v_j (s = 1 unless the task is scaled), its solution
    v_{-S} = J_{-S}^# x_k (the active components of the iterate) and J_{-S}^#."""
    n = la.shape(J)[1]
    act = [i for i in range(n) if i not in st.saturated]
    s = st.scale if (not st.violating and st.scale is not None) else 1
    vN = la.zeros(n, 1)
    for i in st.saturated:
        vN[i, 0] = st.qdot[i, 0]
    Jr = J[:, act]
    xk = x * s - J @ vN
    k = st.it
    add(f"J_sns_{k}", la.sym(Jr), "matrix", label=f"J_{{-S}}^{{({k})}}")
    add(f"task_sns_{k}", la.sym(xk), "vector", label=f"x^{{({k})}} = s\\,x - J_S {vl}_S")
    add(f"J_sns_{k}_pinv", la.sym(la.pinv(Jr)), "matrix", label=f"(J_{{-S}}^{{({k})}})^{{\\#}}")
    add(f"{v}_sns_{k}_active", la.sym(st.qdot[act, :] if not la.exact else st.qdot.extract(act, [0])), "vector",
        label=f"{vl}_{{-S}}^{{({k})}}")


def _sketch(sol: Solution, problem, spec: _MSpec, tasks: list, table: list, subs: dict, acc: bool,  # type: ignore[no-untyped-def]
            motion: dict | None = None) -> None:
    """The planar robot at the state, with the desired task vector of the first planar-position task."""
    if spec.o.sketch is False or problem.robot is None:
        return
    from solver.kinematics.sketch import robot_sketch
    task = next((t["f"] for t in tasks if t["f"] is not None and t["m"] == 2), None)
    arrows = []
    if task is not None:
        t = next(t for t in tasks if t["f"] is task)
        r = t["ra"]
        try:
            vals = [float(sp.N(c)) for c in r]
        except (TypeError, ValueError):
            vals = None
        if vals and math.hypot(*vals) > 0:
            scale = 0.3 / math.hypot(*vals)
            pos = task.subs(subs)
            arrows.append(("$\\ddot r_d$" if acc else "$\\dot r_d$", spec.state, pos,
                           [x * scale * _reach(task, subs) for x in vals]))
    confs = [("$q$", spec.state)]
    paths = None
    if motion is not None:
        same = all(abs(float(sp.N(spec.state[x])) - float(motion["start"][x])) < 1e-5 for x in spec.q)
        confs = [("$q(0)$", motion["start"])] + ([] if same else confs) + \
            [("$q_s$" if motion["reached"] else "$q(t_{end})$", motion["end"])]
        if motion["path"]:
            paths = [("path", motion["path"])]
    fig = robot_sketch(problem, confs, task=task, arrows=arrows, paths=paths,
                       name="sketch" + spec.o.suffix,
                       caption="The robot at the state used" + (", with the task direction" if arrows else "")
                       + (" (and at the start of the motion, with the end-effector path)" if motion else ""))
    if fig is not None:
        sol.figures.append(fig)
    if spec.lo is not None and table:
        lo = [float(b.subs(subs)) for b in spec.lo]
        hi = [float(b.subs(subs)) for b in spec.hi]
        rows = [(r["label"], [float(x) for x in r["v"]]) for r in table]

        def sample() -> list[Panel]:
            js = list(range(1, spec.n + 1))
            curves = [Curve(f"{lab}", [float(j) for j in js], vals) for lab, vals in rows]
            curves += [Curve("bounds", [float(j) for j in js], hi, dashed=True),
                       Curve("", [float(j) for j in js], lo, dashed=True)]
            return [Panel("joint $i$", "$\\ddot q_i$" if acc else "$\\dot q_i$", curves, categorical=True)]

        sol.figures.append(Figure("bounds" + spec.o.suffix, "Joint " + ("accelerations" if acc else "velocities")
                                  + " of each method against their bounds (dashed).", sample))


def _bound_lines(lo: list | None, hi: list | None) -> list[tuple[float, str]]:
    """Horizontal lines at the distinct bounds, one legend entry ("bounds") for all."""
    if hi is None or lo is None:
        return []
    vals = sorted({round(float(v), 12) for v in list(hi) + list(lo)})
    return [(v, "bounds" if k == 0 else "") for k, v in enumerate(vals)]


def _inf(x: Any) -> sp.Expr:
    """A number for display, with ±∞."""
    if x in (float("inf"), sp.oo):
        return sp.oo
    if x in (float("-inf"), -sp.oo):
        return -sp.oo
    return x if isinstance(x, sp.Basic) else sp.Float(float(x), 15)


def _show(x: Any) -> sp.Expr:
    """±∞ or a 4-digit float, for tables."""
    y = _inf(x)
    return y if y.is_infinite else sp.Float(y.evalf(15), 4)


def _reach(task: sp.Matrix, subs: dict) -> float:
    try:
        return max(0.2, float(sp.sqrt(sum(c ** 2 for c in task.subs(subs))).evalf()))
    except (TypeError, ValueError):
        return 1.0


@property_check("qdot_sns", "qddot_sns")
def check_sns(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Any joint vector within the bounds realizing the task (scaled by no less than SNS's factor) is feasible;
    full credit when its norm is not larger than the SNS solution's, half otherwise."""
    sfx = name[len("qddot_sns" if name.startswith("qddot") else "qdot_sns"):]
    need = ["J_task", "task_x", "bounds_lower", "bounds_upper", "sns_scale"]
    if any(results.get(k + sfx) is None for k in need) or results.get(name) is None:
        return None
    try:
        v = np.array(sp.Matrix(value).evalf().tolist(), dtype=float).ravel()
    except (TypeError, ValueError, AttributeError):
        return None
    J = np.array(results["J_task" + sfx].value.evalf().tolist(), dtype=float)
    x = np.array(results["task_x" + sfx].value.evalf().tolist(), dtype=float).ravel()
    lo = np.array(results["bounds_lower" + sfx].value.evalf().tolist(), dtype=float).ravel()
    hi = np.array(results["bounds_upper" + sfx].value.evalf().tolist(), dtype=float).ravel()
    s = float(results["sns_scale" + sfx].value)
    ref = np.array(results[name].value.evalf().tolist(), dtype=float).ravel()
    if v.shape != ref.shape:
        return PropertyVerdict(False, 0.0, [f"the answer must have {ref.size} components"])
    tol = 1e-6 * max(1.0, float(np.max(np.abs(hi))))
    if np.any(v < lo - tol) or np.any(v > hi + tol):
        bad = [str(i + 1) for i in range(v.size) if v[i] < lo[i] - tol or v[i] > hi[i] + tol]
        return PropertyVerdict(False, 0.0, ["joint(s) " + ", ".join(bad) + " out of bounds"])
    Jv = J @ v
    xn = float(np.linalg.norm(x)) or 1.0
    k = float(Jv @ x) / xn ** 2
    if np.linalg.norm(Jv - k * x) > 1e-6 * max(1.0, xn) or k < s - 1e-6:
        return PropertyVerdict(False, 0.0, ["within the bounds, but the task is not realized"
                                            + (" (only scaled)" if k < s - 1e-6 else " (wrong direction)")])
    if np.linalg.norm(v) > np.linalg.norm(ref) * (1 + 1e-6) + 1e-9:
        return PropertyVerdict(True, 0.5, [(f"feasible and realizes the task, but its norm {np.linalg.norm(v):.4g} "
                                            f"is larger than SNS's {np.linalg.norm(ref):.4g}")])
    return PropertyVerdict(True, 1.0, ["feasible (within every bound) and realizes the task"])
