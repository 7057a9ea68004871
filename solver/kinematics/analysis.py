"""Kinematic analysis of a serial robot (ask kind ``kinematics``).

For a task r = f(q) ∈ R^m of a robot with n joints (given as expressions, or the position/planar pose of a DH
frame):

    direct kinematics  ⁰T_e = ⁰A_1 ¹A_2 ... ⁿ⁻¹A_n (DH),  r = f(q)
    analytic Jacobian  J(q) = ∂f/∂q        (or ∂f/∂x for other variables x: sensitivity to kinematic parameters)
    geometric Jacobian [v; ω] = J_g(q) q̇,  column i = [z_{i-1} × (p_e - o_{i-1}); z_{i-1}] (R), [z_{i-1}; 0] (P)
    J̇ = Σ_k ∂J/∂q_k q̇_k,   r̈ = J q̈ + J̇ q̇
    singularities      det J = 0 (square, factored), all m×m minors = 0 (non-square)
    at a configuration rank, bases of N(J) and R(J), manipulability √det(J Jᵀ), J⁻¹
    inverse kinematics f(q) = r_d in closed form (all solutions), by elimination (:mod:`solver.math.trigsolve`).
"""
from __future__ import annotations

import random
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field, model_validator

from solver.kinematics import geometry as geo
from solver.kinematics.sketch import robot_sketch, skeleton
from solver.math.simplify import tidy, transcendental
from solver.math.trigsolve import Solver, Stage, check_families, numeric_function, trig_factors
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Solution
from solver.spec.expr import shape_of
from solver.spec.models import Strict
from solver.spec.problem import AskReader

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
TASK_WORDS = ("position", "pose")
SYMBOLIC_INVERSE = 3     # J⁻¹ given symbolically up to this size
SYMBOLIC_MANIP_OPS = 600
MINOR_OPS = 160          # maximal minors computed symbolically for Jacobians up to this size


class SketchSpec(Strict):
    """What the robot sketch shows."""

    points: Optional[list[ExprT]] = Field(
        None, description="planar points P_0 (base), P_1, ..., P_n (end effector) in q, joint i at P_{i-1}; "
                          "default: the DH frame origins, or read off a planar position task")
    at: Optional[list[dict[str, Scalar]]] = Field(None, description="more configurations to draw")


class KinematicsAsk(Strict):
    """Direct and differential kinematics, singularities, inverse kinematics."""

    kind: Literal["kinematics"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    task: Optional[ExprT] = Field(
        None, description="r = f(q): expressions (a vector or a scalar), or `position` (the position of the end "
                          "effector of a DH robot: x, y for a planar robot, else x, y, z) or `pose` (planar DH "
                          "robot: x, y and the orientation angle φ). Default: position")
    frame: Optional[int] = Field(None, description="DH frame taken as the end effector (default: the last, n)")
    point: Optional[ExprT] = Field(None, description="a point fixed in that frame (3 coordinates in it), "
                                                     "instead of its origin")
    expressed_in: Union[Literal["base", "end_effector"], int] = Field(
        "base", description="frame of the geometric Jacobian and of v, ω: base, end_effector (the frame of the "
                            "point) or a frame number k")
    geometric: Optional[bool] = Field(None, description="also the 6×n geometric Jacobian (DH robots; default: yes "
                                                        "when the task is a position or pose)")
    wrt: Optional[list[str]] = Field(None, description="differentiate with respect to these variables (coordinates "
                                                       "or parameters, e.g. DH lengths for calibration) instead of q")
    jdot: bool = Field(False, description="also J̇(q, q̇) and J̇ q̇")
    velocities: bool = Field(False, description="also ṙ = J q̇ (and v, ω with the geometric Jacobian)")
    force: Optional[ExprT] = Field(None, description="a task force F: the joint torques Jᵀ F")
    at: Optional[dict[str, Scalar]] = Field(
        None, description="a configuration {q1: ..., q2: ...} (also velocities dq1.., or parameters) where rank, "
                          "null/range space bases, manipulability and the numeric values are computed")
    target: Optional[ExprT] = Field(None, description="desired task value r_d: inverse kinematics f(q) = r_d in "
                                                      "closed form (all solutions)")
    singularities: Union[bool, Literal["analytic", "geometric"]] = Field(
        True, description="singular configurations in closed form: of J (analytic), of the geometric Jacobian, "
                          "or false")
    tol: float = Field(1e-9, gt=0, description="relative tolerance on the singular values for the numeric rank")
    sketch: Union[bool, SketchSpec] = Field(True, description="draw the planar robot (false: no sketch)")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$",
                        description="appended to every result name (several kinematics asks in one problem)")

    @model_validator(mode="after")
    def _checks(self) -> "KinematicsAsk":
        if self.target is not None and self.wrt is not None:
            raise ValueError("target: (inverse kinematics) is for the joint coordinates, without wrt:")
        return self


# ------------------------------------------------------------------------------------------------ inputs
class _Spec(AskReader):
    """The parsed, validated inputs of one ask."""

    def __init__(self, problem, options: KinematicsAsk, ctx) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.options, self.ctx = problem, options, ctx
        robot = problem.robot
        if robot is None:
            raise self.fail((), "a kinematics ask needs a robot (its joints)", "add robot: {joints: [R, R], ...}")
        self.robot = robot
        self.q, self.dq, self.joints = list(robot.q[:len(robot.joints)]), list(robot.dq[:len(robot.joints)]), \
            list(robot.joints)
        self.n = len(self.q)
        self.dh = bool(robot.frames)
        self.k = self._frame()
        self.T = None
        self.point_base = None
        if self.dh:
            F = robot.frames[self.k]
            if options.point is not None:
                pt = self._vector("point", 3, "point")
                self.point_base = (F[:3, 3] + F[:3, :3] * pt).applyfunc(tidy)
                self.T = F[:3, :3].row_join(self.point_base).col_join(sp.Matrix([[0, 0, 0, 1]]))
            else:
                self.T = F
        self.planar = self.dh and geo.dh_skeleton(robot) is not None
        self.task_kind, self.r = self._task()
        self.wrt = self._wrt()
        self.m = self.r.shape[0]
        self.state = self._state()
        self.force = self._vector("force", self.m, "force") if options.force is not None else None
        self.target = self._vector("target", self.m, "target") if options.target is not None else None
        if self.target is not None and self.m != self.n:
            raise self.fail(("target",), f"inverse kinematics in closed form needs as many task components as "
                                         f"joints (m = {self.m}, n = {self.n})",
                            "for a redundant robot use a redundancy ask (velocity level)")
        ex = options.expressed_in
        self.express = 0 if ex == "base" else (self.k if ex == "end_effector" else int(ex))
        if self.dh and not 0 <= self.express < len(robot.frames):
            raise self.fail(("expressed_in",), f"no frame {ex}: frames are 0..{len(robot.frames) - 1}")
        geometric = options.geometric if options.geometric is not None else self.task_kind in TASK_WORDS
        if geometric and not self.dh:
            raise self.fail(("geometric",), "the geometric Jacobian needs the frames of a DH table",
                            "give robot: {dh: ...}, or drop geometric:")
        self.geometric = geometric and options.wrt is None

    def _frame(self) -> int:
        f = self.options.frame
        if f is None:
            return self.n
        if not self.dh:
            raise self.fail(("frame",), "frame: needs a DH table (robot: {dh: ...})")
        if not 0 <= f <= self.n:
            raise self.fail(("frame",), f"frame must be between 0 and {self.n}, got {f}")
        return f

    def _task(self) -> tuple[str, sp.Matrix]:
        raw = self.options.task
        word = raw.strip() if isinstance(raw, str) and raw.strip() in TASK_WORDS and \
            raw.strip() not in self.problem.names else None
        if raw is None or word is not None:
            word = word or "position"
            if not self.dh:
                raise self.fail(("task",) if raw is not None else (),
                                "this robot has no DH frames: give the task as expressions, task: [f1(q), f2(q)]",
                                "e.g. task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]")
            p = self.T[:3, 3]
            if word == "position":
                return word, (p[:2, :] if self.planar else p).applyfunc(tidy)
            phi = geo.planar_angle(self.T[:3, :3]) if self.planar else None
            if phi is None:
                raise self.fail(("task",), "task: pose is for planar robots (x, y and the angle φ)",
                                "give the orientation as expressions, or use task: position")
            return word, sp.Matrix([tidy(p[0]), tidy(p[1]), phi])
        val = self.ctx.expr("task")
        shp = shape_of(val)
        if len(shp) > 1:
            raise self.fail(("task",), f"task must be a vector (or a scalar), got shape {shp}",
                            "write [f1(q), f2(q)]")
        r = sp.Matrix(val if isinstance(val, list) else [val])
        if not r.free_symbols & set(self.q) and self.options.wrt is None:
            raise self.fail(("task",), "the task does not depend on the joint coordinates",
                            "write r = f(q) with " + ", ".join(s.name for s in self.q))
        return "expressions", r

    def _wrt(self) -> list[sp.Symbol]:
        names = self.options.wrt
        if names is None:
            return list(self.q)
        out = []
        for i, nm in enumerate(names):
            s = self.problem.names.get(nm)
            if s is None or not isinstance(s, sp.Symbol):
                raise self.fail(("wrt", i), f"unknown variable '{nm}' in wrt:", "use coordinates or declared symbols")
            out.append(s)
        return out

    def _state(self) -> dict[sp.Symbol, sp.Expr] | None:
        if self.options.at is None:
            return None
        state = {}
        for name in self.options.at:
            s = self.problem.names.get(name)
            if s is None or not isinstance(s, sp.Symbol):
                raise self.fail(("at", name), f"'{name}' in at: is not a coordinate, velocity or parameter",
                                "use " + ", ".join(x.name for x in self.q))
            v = self.ctx.expr("at", name)
            if isinstance(v, list):
                raise self.fail(("at", name), f"the value of {name} must be a scalar")
            state[s] = v
        return state


# ------------------------------------------------------------------------------------------------ helpers
def _num(M: Any) -> Any:
    """Exact numbers kept exact; anything with a float, or with sin/cos of a number that is not a rational multiple
    of π (sin(3/10): its exact products run to pages), evaluated to 15 digits."""
    def one(x: sp.Expr) -> sp.Expr:
        if x.is_number:
            if x.atoms(sp.Float) or transcendental(x):
                return sp.Float(sp.N(x, 15), 15)
            y = sp.nsimplify(x) if x.is_Rational else sp.radsimp(x)
            return y
        return x
    return M.applyfunc(one) if isinstance(M, sp.MatrixBase) else one(sp.sympify(M))


def _display(M: Any) -> Any:
    """A float copy for display when an exact value has irrational entries."""
    if M is None:
        return None
    items = list(M) if isinstance(M, sp.MatrixBase) else [M]
    if all(x.is_Rational or x.free_symbols or x.atoms(sp.Float) for x in items):
        return None
    return M.evalf(6) if isinstance(M, sp.MatrixBase) else sp.Float(sp.N(M, 6), 6)


def _short(e: Any, ops: int = 24) -> Any:
    """A long exact value shown as a 6-digit float (display only)."""
    if isinstance(e, sp.MatrixBase):
        return e.applyfunc(lambda x: _short(x, ops))
    if isinstance(e, sp.Basic) and sp.count_ops(e) > ops:
        return e.evalf(4)
    return e


def _nfy(e: sp.Expr) -> sp.Expr:
    """Every number inside e (also inside atan2, sqrt) to 4 significant digits, but integers and rational exponents
    exact (q₃², √x, -q₁: not q₃^{2.0}, x^{0.5}, -1.0 q₁)."""
    if e.is_Integer:
        return e
    if e.is_number:
        v = e.evalf(4)
        return sp.Integer(int(v)) if v.is_Float and float(v).is_integer() else v
    if not e.args:
        return e
    if e.is_Pow and e.exp.is_Rational:
        return sp.Pow(_nfy(e.base), e.exp)
    return e.func(*[_nfy(a) for a in e.args])


def _stage_view(st: Any, numeric: bool) -> Stage:
    """A stage of the elimination with its long numbers shortened (numeric data: to 4 digits), for the report."""
    ops = 8 if numeric else 40
    return Stage(st.unknown, st.method, [_short(e, ops) for e in st.equations], [_short(v, ops) for v in st.values],
                 {k: _short(v, ops) for k, v in st.data.items()})


def _generic_rank(M: sp.Matrix, trials: int = 3) -> int:
    """Rank of M at random points (the rank almost everywhere)."""
    syms = sorted(M.free_symbols, key=lambda s: s.name)
    rng = random.Random(7)
    best = 0
    for _ in range(trials):
        pt = {s: rng.uniform(0.3, 2.0) * (1 if (s.is_positive or rng.random() < 0.5) else -1) for s in syms}
        try:
            a = geo.to_np(M.xreplace(pt))  # (subs: the same numbers, several times slower)
        except (TypeError, ValueError):
            continue
        s = np.linalg.svd(a, compute_uv=False)
        best = max(best, int(np.sum(s > 1e-9 * max(1.0, s[0]))) if s.size else 0)
    return best


def _inverse(J: sp.Matrix, d: sp.Expr) -> sp.Matrix:
    """J⁻¹ = adj(J)/det J, entries tidied."""
    adj = J.adjugate().applyfunc(tidy)
    return adj.applyfunc(lambda e: sp.factor_terms(tidy(e / d)) if e != 0 else e)


def _minor_name(cols: tuple[int, ...]) -> str:
    return "minor_" + "".join(str(c) for c in cols) if all(c < 10 for c in cols) else \
        "minor_" + "_".join(str(c) for c in cols)


def _config_label(state: dict, latex: dict) -> str:
    parts = []
    for k, v in state.items():
        parts.append(f"{latex.get(k, sp.latex(k))} = {sp.latex(v)}")
    return "$" + ",\\ ".join(parts) + "$" if parts else ""


def _no_geometric(spec: _Spec) -> Exception:
    return spec.fail(("singularities",), "singularities: geometric needs the geometric Jacobian (a DH robot)")


def validate_kinematics(problem, options: KinematicsAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_kinematics` reads them, without the analysis."""
    spec = _Spec(problem, options, ctx)
    if options.singularities == "geometric" and list(spec.wrt) == list(spec.q) and not spec.geometric:
        raise _no_geometric(spec)
    if options.sketch is not False:
        _sketch_options(problem, spec)


# ------------------------------------------------------------------------------------------------ solver
@ask_kind("kinematics", KinematicsAsk,
          "direct and differential kinematics: Jacobians, J̇q̇, singularities, rank and bases at a configuration, "
          "inverse kinematics, manipulability", validate=validate_kinematics)
def solve_kinematics(problem, options: KinematicsAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (each with the ask's suffix): A1..An, T, R (DH), p, J, Jg, JL, JA, J_inv, det_J or minor_<cols>,
    singularities, rank, manipulability, Jdot, Jdot_qdot, rdot, v, omega, JtF; at a configuration: p_at, J_at,
    Jg_at, det_J_at or minor_<cols>_at, rank, singular, null_basis, range_basis, manipulability_at, J_inv_at,
    JtF_at; with a target: ik, n_ik."""
    spec = _Spec(problem, options, ctx)
    sfx = options.suffix
    sol = Solution("kinematics", title=options.title or "Kinematic analysis")
    robot, q, n, m = spec.robot, spec.q, spec.n, spec.m

    def add(name: str, value: Any, kind: str | None = None, label: str = "") -> None:
        sol.add(name + sfx, value, kind, label=label)

    # ---- direct kinematics
    A = []
    if spec.dh:
        A = [geo.relative(robot.frames, i - 1, i) for i in range(1, n + 1)]
        base = robot.frames[0] != sp.eye(4)
        if n <= 8:
            for i, Ai in enumerate(A, 1):
                add(f"A{i}", Ai, "matrix", label=f"{{}}^{{{i - 1}}}A_{{{i}}}")
        add("T", spec.T, "matrix", label=f"{{}}^{{0}}T_{{{spec.k}}}")
        add("R", spec.T[:3, :3], "matrix", label=f"{{}}^{{0}}R_{{{spec.k}}}")
        sol.step("dh", A=A, T=spec.T, k=spec.k, n=n, base=robot.frames[0] if base else None,
                 convention=robot.dh_convention, point=options.point is not None, planar=spec.planar,
                 p=spec.point_base)
    add("p", spec.r, "vector", label="r(q)" if spec.task_kind == "expressions" else "p(q)")
    wrt_q = list(spec.wrt) == list(q)  # derivatives with respect to the joint coordinates
    J = geo.analytic_jacobian(spec.r, spec.wrt)
    add("J", J, "matrix", label="J(q)")
    sol.step("task", r=spec.r, J=J, kind=spec.task_kind, wrt=sp.Matrix(spec.wrt), m=m, nw=len(spec.wrt),
             wrt_q=wrt_q, planar=spec.planar, k=spec.k, dh=spec.dh)
    if options.wrt is not None and len(spec.wrt) == 1 and spec.dh:
        dT = spec.T.diff(spec.wrt[0]).applyfunc(tidy)
        add("dT", dT, "matrix", label=f"\\partial T / \\partial {sp.latex(spec.wrt[0])}")
        sol.step("sensitivity", x=spec.wrt[0], dT=dT, k=spec.k)

    # ---- geometric Jacobian
    Jg = None
    if spec.geometric:
        Jg = geo.geometric_jacobian(robot.frames, spec.joints, robot.dh_convention or "standard",
                                    spec.point_base, spec.express)
        add("Jg", Jg, "matrix", label="J_g(q)")
        add("JL", Jg[:3, :], "matrix", label="J_L(q)")
        add("JA", Jg[3:, :], "matrix", label="J_A(q)")
        axes = geo.joint_axes(robot.frames, robot.dh_convention or "standard", n)
        sol.step("geometric", Jg=Jg, express=spec.express, k=spec.k, joints=spec.joints,
                 convention=robot.dh_convention, z=[sp.Matrix(z).T for z, _ in axes],
                 o=[sp.Matrix(o).T for _, o in axes])

    # ---- time derivative
    if options.jdot and wrt_q:
        Jd = geo.jacobian_dot(J, q, spec.dq)
        Jdq = (Jd * sp.Matrix(spec.dq)).applyfunc(lambda e: sp.factor_terms(tidy(e)))
        add("Jdot", Jd, "matrix", label="\\dot J(q, \\dot q)")
        add("Jdot_qdot", Jdq, "vector", label="\\dot J \\dot q")
        sol.step("jdot", Jd=Jd, Jdq=Jdq, dq=sp.Matrix(spec.dq))

    # ---- velocities and forces
    rddot = None
    if options.velocities:
        rdot = (J * sp.Matrix(spec.dq if wrt_q else [sp.Symbol("d" + s.name) for s in spec.wrt])).applyfunc(tidy)
        add("rdot", rdot, "vector", label="\\dot r")
        if wrt_q:
            Jd = sol.results["Jdot" + sfx].value if "Jdot" + sfx in sol.results else geo.jacobian_dot(J, q, spec.dq)
            ddq = sp.Matrix(list(robot.ddq[:n]))
            rddot = (J * ddq + Jd * sp.Matrix(spec.dq)).applyfunc(lambda e: sp.factor_terms(tidy(e)))
            add("rddot", rddot, "vector", label="\\ddot r")
        v = w = None
        if Jg is not None:
            v = (Jg[:3, :] * sp.Matrix(spec.dq)).applyfunc(tidy)
            w = (Jg[3:, :] * sp.Matrix(spec.dq)).applyfunc(tidy)
            add("v", v, "vector", label="v")
            add("omega", w, "vector", label="\\omega")
        sol.step("velocity", rdot=rdot, rddot=rddot, v=v, w=w, express=spec.express)
    JtF = None
    if spec.force is not None:
        JtF = (J.T * spec.force).applyfunc(tidy)
        add("JtF", JtF, "vector", label="J^T F")

    # ---- square / non-square structure, singularities
    square = m == len(spec.wrt)
    dJ = None
    mins: dict = {}
    if square and wrt_q:
        dJ = geo.det(J)
        add("det_J", sp.factor_terms(dJ), "scalar", label="\\det J(q)")
        if m <= SYMBOLIC_INVERSE and dJ != 0:
            add("J_inv", _inverse(J, dJ), "matrix", label="J^{-1}(q)")
    elif not square and geo.n_minors(m, len(spec.wrt)) <= geo.MAX_MINORS and wrt_q and m <= 4 \
            and options.singularities != "geometric" and sp.count_ops(J) <= MINOR_OPS:
        mins = geo.minors(J)
        for cols, v in mins.items():
            add(_minor_name(cols), v, "scalar", label="\\det J_{" + ",".join(map(str, cols)) + "}")
    rank_generic = _generic_rank(J)
    sol.step("structure", square=square, det=dJ, det_factored=(sp.factor_terms(dJ) if dJ is not None else None),
             minors=[(c, v) for c, v in mins.items()], m=m, n=len(spec.wrt), rank=rank_generic,
             inv=sol.results.get("J_inv" + sfx), wide=m < len(spec.wrt))
    if options.singularities and wrt_q:
        _singularities(sol, add, spec, J, Jg, dJ, mins, rank_generic)

    # ---- manipulability (symbolic, small)
    w_sym = None
    if wrt_q and square and dJ is not None:
        w_sym = sp.Abs(sp.factor_terms(dJ))
    elif wrt_q and m < n and m <= 3 and n <= 4 and sp.count_ops(J) <= MINOR_OPS:
        dd = geo.det((J * J.T).applyfunc(tidy))
        if sp.count_ops(dd) <= SYMBOLIC_MANIP_OPS:
            c, facs = trig_factors(dd)
            w_sym = sp.sqrt(geo.factored(c, facs))
            w_sym = w_sym if len(str(w_sym)) <= 90 else None  # a long radicand says nothing: only at a configuration
    if w_sym is not None:
        add("manipulability", w_sym, "scalar", label="w(q)")
        sol.step("manipulability", w=w_sym, square=square)

    # ---- at a configuration
    if spec.state is not None:
        _at_configuration(sol, add, spec, J, Jg, JtF, dJ, mins)
    elif not any(k.startswith("rank") for k in sol.results):
        add("rank", sp.Integer(rank_generic), "number", label="\\operatorname{rank} J")

    # ---- inverse kinematics
    ik_confs: list = []
    if spec.target is not None:
        ik_confs = _inverse_kinematics(sol, add, spec)

    # ---- sketch
    if options.sketch is not False:
        _sketch(sol, problem, spec, ik_confs)
    return sol


def _singularities(sol: Solution, add, spec: _Spec, J, Jg, dJ, mins, rank_generic) -> None:  # type: ignore[no-untyped-def]
    options = spec.options
    which = options.singularities
    use_geo = which == "geometric" or (which is True and dJ is None and not mins and Jg is not None
                                       and Jg.shape[0] == Jg.shape[1])
    if which == "geometric" and Jg is None:
        raise _no_geometric(spec)
    M = J
    d, mn = dJ, mins
    gk = gj = None
    if use_geo:
        M = Jg
        if M.shape[0] != M.shape[1]:
            return
        d, gk, gj = geo.geometric_det(spec.robot.frames, spec.joints, spec.robot.dh_convention or "standard")
        mn = {}
    elif d is None and not mn:
        sol.step("singular_skipped", m=M.shape[0], n=M.shape[1])
        return
    if rank_generic < min(M.shape) and not use_geo:
        sol.step("singular_everywhere", rank=rank_generic, m=M.shape[0], n=M.shape[1])
        return
    size = sp.count_ops(d) if d is not None else sum(sp.count_ops(v) for v in mn.values())
    if size > geo.MAX_DET_OPS or (d is None and size > geo.MAX_DET_OPS // 5):
        sol.step("singular_skipped", m=M.shape[0], n=M.shape[1])
        return
    sing = geo.singular_configurations(M, spec.q, spec.joints, spec.problem.values, dmat=d, mins=mn or None)
    if use_geo:
        add("det_Jg", sing.product, "scalar", label="\\det J_g(q)")
    elif sing.product is not None and "det_J" + spec.options.suffix in sol.results:
        sol.results["det_J" + spec.options.suffix].value = sing.product
    configs = [sp.Matrix([f.values[x] for x in spec.q]) for f in sing.families if not f.pending]
    if sing.complete and sing.families:
        add("singularities", configs, "set", label="\\text{singular } q")
    const_f = sp.factor_terms(sing.constant) if sing.constant is not None else None
    sol.step("singular", sing=sing, geometric=use_geo, configs=configs, const=const_f,
             frame=gk if use_geo else None, point=gj if use_geo else None,
             q=sp.Matrix(spec.q).T, free=[[x for x in f.free] for f in sing.families],
             pending=[f.pending for f in sing.families if f.pending], square=d is not None)


def _at_configuration(sol: Solution, add, spec: _Spec, J, Jg, JtF, dJ, mins) -> None:  # type: ignore[no-untyped-def]
    problem = spec.problem
    subs = {**problem.values, **spec.state}
    Ja = _num(J.subs(subs))
    pa = _num(spec.r.subs(subs))
    add("p_at", pa, "vector", label="r\\big|_{*}")
    add("J_at", Ja, "matrix", label="J\\big|_{*}")
    data: dict[str, Any] = {"state": spec.state, "p": pa, "J": Ja, "J_num": _display(Ja), "p_num": _display(pa)}
    used = set().union(*[e.free_symbols for e in list(J) + list(spec.r)])
    data["values"] = {k: v for k, v in problem.values.items() if k in used and k not in spec.state}
    if Jg is not None:
        Jga = _num(Jg.subs(subs))
        add("Jg_at", Jga, "matrix", label="J_g\\big|_{*}")
        data["Jg"] = Jga
    dT = sol.results.get("dT" + spec.options.suffix)
    if dT is not None:
        dTa = _num(dT.value.subs(subs).applyfunc(tidy))
        add("dT_at", dTa, "matrix", label=dT.label + "\\big|_{*}")
        data["dT"] = dTa
    if spec.options.velocities:
        for nm in ("rdot", "rddot"):
            r = sol.results.get(nm + spec.options.suffix)
            if r is not None:
                val = r.value.subs(subs).applyfunc(lambda e: sp.factor_terms(tidy(e)))
                add(nm + "_at", val, "vector", label=r.label + "\\big|_{*}")
                data[nm] = val
    if JtF is not None:
        JtFa = _num(JtF.subs(subs))
        add("JtF_at", JtFa, "vector", label="J^T F\\big|_{*}")
        data["JtF"], data["F"] = JtFa, _num(spec.force.subs(subs))
    numeric = not Ja.free_symbols
    data["numeric"] = numeric
    approx = bool(Ja.atoms(sp.Float)) or transcendental(Ja)  # (the inverse and w in floating point)
    if numeric:
        sp_ = geo.spaces(Ja, spec.options.tol)
        m, nw = Ja.shape
        add("rank", sp.Integer(sp_.rank), "number", label="\\operatorname{rank} J")
        add("singular", bool(sp_.rank < min(m, nw)), "bool", label="\\text{singular}")
        add("null_basis", sp_.null, "matrix", label="\\mathcal N(J)")
        add("range_basis", sp_.range, "matrix", label="\\mathcal R(J)")
        data["spaces"] = sp_
        data["sigma"] = [sp.Float(s, 6) for s in sp_.sigma]
        if dJ is not None:
            d = _num(dJ.subs(subs)) if dJ.free_symbols else dJ
            d = _num(sp.sympify(d))
            add("det_J_at", d, "number", label="\\det J\\big|_{*}")
            data["det"] = d
            if d != 0 and not (d.is_Float and abs(d) < 1e-12):
                Jinv = _num(Ja.inv()) if not approx else geo.from_np(np.linalg.inv(geo.to_np(Ja)))
                add("J_inv_at", Jinv, "matrix", label="J^{-1}\\big|_{*}")
                data["J_inv"], data["J_inv_num"] = Jinv, _display(Jinv)
        mins_at = []
        for cols, v in mins.items():
            va = _num(sp.sympify(v).subs(subs))
            add(_minor_name(cols) + "_at", va, "number",
                label="\\det J_{" + ",".join(map(str, cols)) + "}\\big|_{*}")
            mins_at.append((cols, va, _display(va)))
        data["minors"] = mins_at
        if m <= nw:
            JJt = Ja * Ja.T
            w = sp.sqrt(_num(JJt.det())) if not approx else sp.Float(np.sqrt(max(0.0, np.linalg.det(
                geo.to_np(JJt)))), 15)
            w = _num(sp.sympify(w))
            add("manipulability_at", w, "number", label="w\\big|_{*}")
            data["w"], data["w_num"] = w, _display(w)
    sol.step("config", **data)


def _inverse_kinematics(sol: Solution, add, spec: _Spec) -> list:  # type: ignore[no-untyped-def]
    """f(q) = r_d by elimination. With numeric data the system is solved for a symbolic target (and symbolic
    parameters), then the numbers are substituted in each family: the algebra stays exact and fast, and the
    families that are not real at the target are the missing solutions."""
    problem = spec.problem
    q = spec.q
    target = spec.target
    params = set(problem.symbols.values())
    numeric = not (target.free_symbols - params) and all(s in problem.values for s in
                                                          (target.free_symbols | spec.r.free_symbols) - set(q))
    if numeric:
        goal = sp.Matrix([sp.Dummy(f"r{i + 1}", real=True) for i in range(spec.m)])
    else:
        goal = target
    eqs = [spec.r[i] - goal[i] for i in range(spec.m)]
    prismatic = [x for x, j in zip(q, spec.joints) if j == "P"]
    fams = Solver(q, prismatic).solve(eqs)
    closed = [f for f in fams if not f.pending]
    symbols_t = [s for s in goal if isinstance(s, sp.Symbol) and s not in params]
    others = sorted(set().union(*[e.free_symbols for e in eqs]) - set(q) - set(symbols_t), key=lambda s: s.name)
    plain = len(symbols_t) == spec.m and len(set(symbols_t)) == spec.m

    def sampler(rng: random.Random) -> dict:
        pt = geo._param_point(rng, others, {} if numeric else problem.values)
        if plain:
            qs = {x: (rng.uniform(-3.0, 3.0) if j == "R" else rng.uniform(-1.5, 1.5)) for x, j in zip(q, spec.joints)}
            for s_, e in zip(goal, spec.r):
                pt[s_] = float(sp.N(e.subs({**pt, **qs})))
        return pt
    kept = check_families(closed, eqs, q, sampler)
    stages = kept[0].stages if kept else (fams[0].stages if fams else [])
    if numeric:
        at = {**problem.values, **dict(zip(goal, target.subs(problem.values)))}
        sols = _numeric_solutions(kept, q, spec, at)
        def ev(e: Any) -> Any:  # display: the numbers substituted and evaluated (exact substitution is slow)
            if isinstance(e, sp.MatrixBase):
                return e.applyfunc(ev)
            if isinstance(e, sp.Basic):
                out = _nfy(e.xreplace(at))
                return out.xreplace({f: sp.Integer(0) for f in out.atoms(sp.Float) if abs(f) < 1e-12})
            return e
        stages = [Stage(st.unknown, st.method, [ev(e) for e in st.equations], [ev(v) for v in st.values],
                        {k: ev(v) for k, v in st.data.items()}) for st in stages]
        free = [[] for _ in sols]
    else:
        sols = [sp.Matrix([f.values[x] for x in q]) for f in kept]
        free = [f.free for f in kept]
    complete = all(not f.pending for f in fams)
    if complete:
        add("ik", sols, "set", label="q \\text{ with } f(q) = r_d")
        add("n_ik", sp.Integer(len(sols)), "number", label="\\#\\text{solutions}")
    sol.step("ik", target=target, eqs=[sp.Eq(spec.r[i], target[i]) for i in range(spec.m)],
             stages=[_stage_view(s_, numeric) for s_ in stages],
             solutions=sols, numeric=numeric, complete=complete, dropped=len(closed) - len(kept),
             nums=[_display(s_) for s_ in sols], free=free,
             radicals=any(any(p.exp.is_Rational and p.exp.q == 2 for p in x.atoms(sp.Pow)) for s_ in sols for x in s_),
             pending=[f.pending for f in fams if f.pending])
    confs = []
    if numeric:
        for k, s_ in enumerate(sols, 1):
            confs.append((f"solution {k}", dict(zip(q, s_))))
    return confs


def _numeric_solutions(fams: list, q: list, spec: _Spec, at: dict) -> list[sp.Matrix]:
    """The real solutions at the numeric target: each family evaluated, checked on f(q) = r_d, duplicates (modulo
    2π) dropped; a value is given exactly when it is a short exact number (π/3, 1/2, √2), else to 15 digits."""
    out: list[sp.Matrix] = []
    seen: list[np.ndarray] = []
    syms = sorted(at, key=lambda s: s.name)
    point = [complex(sp.N(at[s])) for s in syms]
    r_num = np.array([complex(sp.N(e.subs(at))) for e in spec.target], dtype=complex)
    task_f = numeric_function(list(spec.r), list(q) + syms)
    rev = np.array([j == "R" for j in spec.joints])
    for fam in fams:
        zs = numeric_function([fam.values[x] for x in q], syms)(*point)
        if any(not np.isfinite(z) or abs(z.imag) > 1e-9 * max(1.0, abs(z.real)) for z in zs):
            continue
        num = np.array([z.real for z in zs])
        diff = np.array(task_f(*num, *point)) - r_num
        for k in range(len(diff)):  # angles in the task (φ) compare modulo 2π
            d = diff[k].real / (2 * np.pi)
            if abs(diff[k]) > 1e-7 and abs(d - round(d)) < 1e-9:
                diff[k] = 0
        if np.max(np.abs(diff)) > 1e-7 * max(1.0, float(np.max(np.abs(r_num)))):
            continue
        if any(np.all(np.where(rev, np.abs(np.angle(np.exp(1j * (num - s0)))), np.abs(num - s0)) < 1e-8) for s0 in seen):
            continue
        seen.append(num)
        out.append(sp.Matrix([_exact_or_float(v) for v in num]))
    return out


def _exact_or_float(x: float) -> sp.Expr:
    """A short exact number equal to x to 1e-12 (0, π/3, √3/2), else x to 15 digits."""
    try:
        e = sp.nsimplify(x, [sp.pi], tolerance=1e-13, rational=False)
    except (ValueError, TypeError):
        e = None
    if e is not None and sp.count_ops(e) <= 6 and abs(float(sp.N(e)) - x) < 1e-12 * max(1.0, abs(x)):
        return e
    return sp.Integer(0) if abs(x) < 1e-14 else sp.Float(x, 15)


def _sketch_options(problem, spec: _Spec) -> tuple[list[sp.Matrix] | None, list[tuple[str, dict]]]:  # type: ignore[no-untyped-def]
    """The sketch's given points and extra configurations (label, {coordinate: value})."""
    opts = spec.options.sketch
    points = None
    extra: list[tuple[str, dict]] = []
    if isinstance(opts, SketchSpec):
        if opts.points is not None:
            pts = spec.ctx.expr("sketch", "points")
            if len(pts) != spec.n + 1 or any(shape_of(p) != (2,) for p in pts):
                raise spec.fail(("sketch", "points"), f"sketch points must be {spec.n + 1} planar points [x, y] "
                                                      "(base, after each joint)")
            points = [sp.Matrix(p) for p in pts]
        for i, st in enumerate(opts.at or []):
            conf = {}
            for name in st:
                s = problem.names.get(name)
                if s is None:
                    raise spec.fail(("sketch", "at", i, name), f"'{name}' is not a coordinate")
                conf[s] = spec.ctx.expr("sketch", "at", i, name)
            extra.append((_config_label(conf, problem.latex_names), conf))
    return points, extra


def _sketch(sol: Solution, problem, spec: _Spec, ik_confs: list) -> None:  # type: ignore[no-untyped-def]
    points, extra = _sketch_options(problem, spec)
    task = spec.r if spec.task_kind == "expressions" else None
    if points is None and skeleton(spec.robot, task) is None:
        return
    confs = []
    if spec.state is not None:
        st = {k: v for k, v in spec.state.items() if k in spec.q}
        if st:
            label = _config_label(st, problem.latex_names)
            missing = [x for x in spec.q if x not in st]
            st.update({x: sp.Integer(0) for x in missing})  # coordinates the exercise leaves arbitrary: drawn at 0
            if missing:
                label += " (" + ", ".join(f"${problem.latex_names.get(x, x.name)} = 0$" for x in missing) + ")"
            confs.append((label, st))
    confs += ik_confs + extra
    fig = robot_sketch(problem, confs, task=task, points=points, name="sketch" + spec.options.suffix,
                       caption="The robot" + (" at the configurations of the exercise" if confs else ""))
    if fig is not None:
        sol.figures.append(fig)


# ------------------------------------------------------------------------------------------------ grading
def _suffix(name: str, base: str) -> str:
    return name[len(base):]


@property_check("null_basis")
def check_null_basis(problem, results, name, N, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Any basis of N(J): J N = 0 and rank N = n - rank J."""
    J = results.get("J_at" + _suffix(name, "null_basis"))
    ref = results.get(name)
    if J is None or ref is None or not isinstance(N, list):
        return None
    try:
        Nm = sp.Matrix(N)
    except (ValueError, TypeError):
        return None
    J = J.value
    if Nm.shape[0] != J.shape[1] and Nm.shape[1] == J.shape[1]:
        Nm = Nm.T  # basis vectors written as rows
    if Nm.shape[0] != J.shape[1] or Nm.free_symbols:
        return None
    need = ref.value.shape[1]
    a, b = geo.to_np(J), geo.to_np(Nm)
    scale = max(1.0, float(np.max(np.abs(a))) if a.size else 1.0) * max(1.0, float(np.max(np.abs(b))) if b.size else 1.0)
    if b.size and float(np.max(np.abs(a @ b))) > 1e-6 * scale:
        return PropertyVerdict(False, 0.0, ["J N ≠ 0: some vector is not in the null space of J"])
    rk = int(np.linalg.matrix_rank(b, tol=1e-8)) if b.size else 0
    if rk != need or Nm.shape[1] != need:
        return PropertyVerdict(False, 0.5, [f"the vectors are in the null space, but a basis needs {need} independent "
                                            f"vectors (got {Nm.shape[1]} of rank {rk})"])
    return PropertyVerdict(True, 1.0, ["a basis of the null space of J (J N = 0, full column rank)"])


@property_check("range_basis")
def check_range_basis(problem, results, name, Rb, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Any basis of R(J): each column in R(J), rank = rank J."""
    J = results.get("J_at" + _suffix(name, "range_basis"))
    ref = results.get(name)
    if J is None or ref is None or not isinstance(Rb, list):
        return None
    try:
        Rm = sp.Matrix(Rb)
    except (ValueError, TypeError):
        return None
    J = J.value
    if Rm.shape[0] != J.shape[0] and Rm.shape[1] == J.shape[0]:
        Rm = Rm.T
    if Rm.shape[0] != J.shape[0] or Rm.free_symbols:
        return None
    a, b = geo.to_np(J), geo.to_np(Rm)
    rj = int(np.linalg.matrix_rank(a, tol=1e-8))
    if int(np.linalg.matrix_rank(np.hstack([a, b]), tol=1e-8)) != rj:
        return PropertyVerdict(False, 0.0, ["some vector is not in the range of J"])
    rk = int(np.linalg.matrix_rank(b, tol=1e-8))
    if rk != rj or Rm.shape[1] != rj:
        return PropertyVerdict(False, 0.5, [f"the vectors are in the range, but a basis needs {rj} independent "
                                            f"vectors (got {Rm.shape[1]} of rank {rk})"])
    return PropertyVerdict(True, 1.0, ["a basis of the range space of J"])
