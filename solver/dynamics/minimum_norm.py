"""Minimum-norm torques and accelerations realizing a task acceleration (ask kind ``minimum_norm``).

With the dynamic model B(q)q̈ + n(q, q̇) = τ and a task r = f(q) with r̈ = J q̈ + J̇ q̇, every solution of the task
satisfies J q̈ = x := r̈_d − J̇ q̇. Among them (J of full row rank):

    min ½‖q̈‖²          q̈ = J^# x                                  τ = B q̈ + n
    min ½ q̈ᵀBq̈         q̈ = J_B^# x = B⁻¹Jᵀ(JB⁻¹Jᵀ)⁻¹ x             (minimum kinetic-energy rate)
    min ½‖τ‖²          τ = (JB⁻¹)^# (x + JB⁻¹n)                     q̈ = B⁻¹(τ − n)
    min ½‖τ‖²_W        τ = (JB⁻¹)_W^# (x + JB⁻¹n)                   (W = B⁻²: the best-conditioned choice)

since J B⁻¹ τ = x + J B⁻¹ n. The command is affine in the task, τ = M x + c; with bounds |τ_i| ≤ τ_max,i the largest
feasible fraction s ∈ [0, 1] of the task is the largest s with the bounds on s M x + c (none when even s = 0, the
torque n that only holds the motion, or every s ≤ 1 violates them).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Union

import numpy as np
import sympy as sp
from pydantic import Field

from solver.kinematics import resolution as rs
from solver.registry import ask_kind
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

ExprT = Union[str, int, float, list[Any]]
Scalar = Union[str, int, float]
Objective = Literal["acceleration", "inertia", "torque", "weighted_torque"]
LABEL = {"acceleration": "\\tfrac12\\lVert\\ddot q\\rVert^2", "inertia": "\\tfrac12\\,\\ddot q^T B \\ddot q",
         "torque": "\\tfrac12\\lVert\\tau\\rVert^2", "weighted_torque": "\\tfrac12\\lVert\\tau\\rVert^2_W"}
SHORT = {"acceleration": "acc", "inertia": "kin", "torque": "tau", "weighted_torque": "tauW"}


class MinimumNormAsk(Strict):
    """Torques and joint accelerations realizing a task acceleration with minimum (weighted) norm."""

    kind: Literal["minimum_norm"]
    title: str | None = Field(None, description="heading of this part in the report")
    task: ExprT | None = Field(None, description="task function r = f(q) (vector or scalar)")
    jacobian: ExprT | None = Field(None, description="task Jacobian J(q), instead of task:")
    at: dict[str, Scalar] | None = Field(
        None, description="configuration {q1: ..., qn: ...}; without it the solutions are symbolic at a generic "
                          "state (q, q̇) (small tasks, within a CPU budget)")
    joint_velocity: ExprT | None = Field(None, description="q̇ at the state (zeros for a robot at rest); "
                                                              "default with at: zeros, without at: the symbols dq")
    acceleration: ExprT = Field(..., description="desired task acceleration r̈_d")
    objectives: list[Objective] = Field(
        ["acceleration", "inertia", "torque"],
        description="acceleration (½‖q̈‖²), inertia (½q̈ᵀBq̈), torque (½‖τ‖²), weighted_torque (½‖τ‖²_W, needs "
                    "weight:)")
    weight: ExprT | None = Field(
        None, description="W of weighted_torque (n x n, n diagonal entries, or `inverse_inertia_squared` for B⁻²)")
    bounds: ExprT | None = Field(None, description="torque bounds |τ_i| ≤ τ_max,i (n values)")
    null_torque: ExprT | None = Field(
        None, description="τ₀ (e.g. -KD*dq1, ...): the torque τ = M^#d + (I − M^#M)τ₀ minimizing ½‖τ − τ₀‖² "
                          "(M = JB⁻¹, d = x + JB⁻¹n), which damps q̇ without affecting the task")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")


def _fail(problem, ctx, sub: tuple, message: str, hint: str | None = None) -> UserError:  # type: ignore[no-untyped-def]
    return UserError(message, problem.located.place(ctx.path + sub), hint)


def _vec(problem, ctx, key: str, size: int) -> sp.Matrix:  # type: ignore[no-untyped-def]
    v = ctx.expr(key)
    v = v if isinstance(v, list) else [v]
    if shape_of(v) != (size,):
        raise _fail(problem, ctx, (key,), f"{key} must have {size} components, got shape {shape_of(v)}")
    return sp.Matrix(v)


def minimum_norm_solutions(la: rs.LA, B: Any, n: Any, J: Any, x: Any, objectives: list[str],
                           W: Any | None = None) -> dict[str, tuple[Any, Any, Any, Any]]:
    """For each objective: (q̈, τ, M, c) with τ = M x + c (the command affine in the task)."""
    Bi = la.inv(B)
    out = {}
    for o in objectives:
        if o == "acceleration":
            Jp = la.pinv(J)
            M, c = B @ Jp, n
        elif o == "inertia":
            Jp = rs.weighted_pinv(la, J, B)
            M, c = B @ Jp, n
        else:
            JB = J @ Bi
            Jp = la.pinv(JB) if o == "torque" else rs.weighted_pinv(la, JB, W)
            M, c = Jp, Jp @ (JB @ n)
        tau = M @ x + c
        qdd = Bi @ (tau - n)
        out[o] = (qdd, tau, M, c)
    return out


def _costs(la: rs.LA, qdd: Any, tau: Any, B: Any, W: Any | None) -> dict[str, Any]:
    half = sp.Rational(1, 2) if la.exact else 0.5
    out = {"acceleration": half * (qdd.T @ qdd)[0, 0], "inertia": half * (qdd.T @ B @ qdd)[0, 0],
           "torque": half * (tau.T @ tau)[0, 0]}
    if W is not None:
        out["weighted_torque"] = half * (tau.T @ W @ tau)[0, 0]
    return {k: (sp.nsimplify(v) if la.exact else sp.Float(float(v), 15)) for k, v in out.items()}


@dataclass
class _Inputs:
    """The task and the state of the ask: J(q) (and f(q) when given), q, q̇ and, with ``at:``, the state, q̇ there
    and r̈_d."""

    J: sp.Matrix
    f: sp.Matrix | None
    q: list
    dq: list
    state: dict | None = None
    qd: sp.Matrix | None = None
    rdd: sp.Matrix | None = None


def _read(problem, options: MinimumNormAsk, ctx) -> _Inputs:  # type: ignore[no-untyped-def]
    """The task, and with ``at:`` the state, the joint velocity and the task acceleration, checked."""
    from solver.dynamics.model import has_model
    robot = problem.robot
    if robot is None or not has_model(robot):
        raise _fail(problem, ctx, (), "minimum_norm needs a robot with a dynamic model (bodies or model:)")
    if (options.task is None) == (options.jacobian is None):
        raise _fail(problem, ctx, (), "give exactly one of task: or jacobian:")
    q, dq = list(robot.q), list(robot.dq)
    nq = len(q)
    if options.task is not None:
        val = ctx.expr("task")
        f = sp.Matrix(val if isinstance(val, list) else [val])
        Jq = f.jacobian(q)
    else:
        val = ctx.expr("jacobian")
        shp = shape_of(val)
        Jq = sp.Matrix([[val]]) if shp == () else sp.Matrix([val]) if len(shp) == 1 else sp.Matrix(val)
        f = None
    if Jq.shape[1] != nq:
        raise _fail(problem, ctx, ("jacobian",), f"the task Jacobian must have {nq} columns")
    m = Jq.shape[0]
    if options.at is None:
        return _Inputs(Jq, f, q, dq)
    state = {}
    by_name = {s.name: s for s in q}
    for name in options.at:
        if name not in by_name:
            raise _fail(problem, ctx, ("at", name), f"'{name}' in at: is not a coordinate")
        state[by_name[name]] = ctx.expr("at", name)
    if len(state) != nq:
        raise _fail(problem, ctx, ("at",), "at: must give every coordinate")
    qd = _vec(problem, ctx, "joint_velocity", nq) if options.joint_velocity is not None else sp.zeros(nq, 1)
    rdd = _vec(problem, ctx, "acceleration", m)
    return _Inputs(Jq, f, q, dq, state, qd, rdd)


def _weight(problem, options: MinimumNormAsk, ctx, nq: int) -> sp.Matrix:  # type: ignore[no-untyped-def]
    """The given weight W (a scalar, nq diagonal entries or an nq×nq matrix)."""
    w = ctx.expr("weight")
    shp = shape_of(w)
    W = (sp.diag(*w) if shp == (nq,) else sp.Matrix(w) if shp == (nq, nq) else
         w * sp.eye(nq) if shp == () else None)
    if W is None:
        raise _fail(problem, ctx, ("weight",), f"weight must be {nq}x{nq} or {nq} diagonal entries")
    return W


def validate_minimum_norm(problem, options: MinimumNormAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_minimum_norm` reads them, without the model (the size
    of a symbolic task; the state, velocity, acceleration, weight and bounds at a state)."""
    r = _read(problem, options, ctx)
    m, nq = r.J.shape
    if r.state is None:
        if m > 2 or nq > 3:
            raise _too_big(problem, ctx, m, nq)
        if options.joint_velocity is not None:
            _vec(problem, ctx, "joint_velocity", nq)
        _vec(problem, ctx, "acceleration", m)
        return
    if "weighted_torque" in options.objectives:
        if options.weight is None:
            raise _fail(problem, ctx, ("objectives",), "weighted_torque needs weight:")
        if not (isinstance(options.weight, str) and options.weight.strip() == "inverse_inertia_squared"):
            _weight(problem, options, ctx, nq)
    if options.bounds is not None:
        _vec(problem, ctx, "bounds", nq)


def _too_big(problem, ctx, m: int, nq: int) -> UserError:  # type: ignore[no-untyped-def]
    return _fail(problem, ctx, ("at",), f"a symbolic minimum-norm solution is given for tasks of up to 2 rows and "
                 f"3 joints (here {m}x{nq})", "add at: for the solution at a state")


@ask_kind("minimum_norm", MinimumNormAsk,
          "torques and accelerations realizing a task acceleration with minimum ½‖τ‖², ½‖τ‖²_W, ½‖q̈‖², ½q̈ᵀBq̈",
          validate=validate_minimum_norm)
def solve_minimum_norm(problem, options: MinimumNormAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (suffixed): J_at, Jdot_qdot, B_at, n_at, x, and for each objective o (acc, kin, tau, tauW):
    qddot_o, tau_o, H_<o'>_o (every cost at every solution), err_o, within_o, scale_o."""
    from solver.dynamics.model import derive
    robot = problem.robot
    sfx = options.suffix
    sol = Solution("minimum_norm", title=options.title or "Minimum-norm torques and accelerations for a task")

    def add(name: str, value: Any, kind: str | None = None, label: str = "") -> None:
        sol.add(name + sfx, value, kind, label=label)

    r = _read(problem, options, ctx)
    if r.state is None:
        return _symbolic(problem, options, ctx, sol, add, r.J, r.f, r.q, r.dq)
    q, dq, nq, m, Jq, f, state, qd, rdd = r.q, r.dq, len(r.q), r.J.shape[0], r.J, r.f, r.state, r.qd, r.rdd
    dm = derive(robot)
    ddq = list(robot.ddq)
    nvec = dm.lhs.subs({d: 0 for d in ddq})  # n(q, q̇) = c + g (+ friction)
    subs = {**problem.values, **state, **{d: qd[i] for i, d in enumerate(dq)}}
    Jdot = sum((Jq.diff(x) * qd[i] for i, x in enumerate(q)), sp.zeros(m, nq))
    vals = {"J": Jq.subs(subs), "h": (Jdot * qd).subs(subs), "B": dm.B.subs(subs), "n": nvec.subs(subs),
            "r": rdd.subs(subs)}
    W = None
    if "weighted_torque" in options.objectives:
        if options.weight is None:
            raise _fail(problem, ctx, ("objectives",), "weighted_torque needs weight:")
        if isinstance(options.weight, str) and options.weight.strip() == "inverse_inertia_squared":
            Bi = vals["B"].inv()
            W = Bi * Bi
        else:
            W = _weight(problem, options, ctx, nq).subs(subs)
        vals["W"] = W
    free = set().union(*[M.free_symbols for M in vals.values()])
    if free:
        raise _fail(problem, ctx, ("at",), "the minimum-norm solutions are computed on numbers; "
                    + ", ".join(sorted(s.name for s in free)) + " left symbolic", "give them values:")
    exact = all(x.is_Rational for M in vals.values() for x in M) and nq <= 6
    la = rs.LA(exact)
    mat = {k: la.mat(v) for k, v in vals.items()}
    x = mat["r"] - mat["h"]
    if la.rank(mat["J"]) < m:
        sol.step("singular", rank=la.rank(mat["J"]), m=m)
    add("J_at", la.sym(mat["J"]), "matrix", label="J")
    add("Jdot_qdot", la.sym(mat["h"]), "vector", label="\\dot J\\dot q")
    add("B_at", la.sym(mat["B"]), "matrix", label="B(q)")
    add("n_at", la.sym(mat["n"]), "vector", label="n(q,\\dot q)")
    sol.step("setup", f=f, J=Jq, B=dm.B, n=nvec, state=state, qd=qd, Ja=la.sym(mat["J"]), h=la.sym(mat["h"]),
             Ba=la.sym(mat["B"]), na=la.sym(mat["n"]), x=la.sym(x), r=la.sym(mat["r"]), exact=exact, W=vals.get("W"))
    sols = minimum_norm_solutions(la, mat["B"], mat["n"], mat["J"], x, list(options.objectives), mat.get("W"))
    lo = hi = None
    if options.bounds is not None:
        b = _vec(problem, ctx, "bounds", nq).subs(problem.values)
        hi = [sp.nsimplify(v) if exact else float(v) for v in b]
        lo = [-v for v in hi]
    table = []
    for o, (qdd, tau, M, c) in sols.items():
        k = SHORT[o]
        add(f"qddot_{k}", la.sym(qdd), "vector", label=f"\\ddot q_{{\\mathrm{{{k}}}}}")
        add(f"tau_{k}", la.sym(tau), "vector", label=f"\\tau_{{\\mathrm{{{k}}}}}")
        err = mat["J"] @ qdd - x
        add(f"err_{k}", la.sym(err), "vector", label="J\\ddot q + \\dot J\\dot q - \\ddot r_d")
        costs = _costs(la, qdd, tau, mat["B"], mat.get("W"))
        for c_name, c_val in costs.items():
            add(f"H_{SHORT[c_name]}_{k}", c_val, None, label=f"{LABEL[c_name]}\\big|_{{{k}}}")
        realized = all(v == 0 for v in err) if exact else bool(  # (J q̈ = x: not so at a singularity)
            np.max(np.abs(np.asarray(err, dtype=float))) <= 1e-9 * (1 + np.max(np.abs(np.asarray(x, dtype=float)))))
        row = {"o": o, "k": k, "label": LABEL[o], "qdd": la.sym(qdd), "tau": la.sym(tau), "costs": costs,
               "qdd_num": la.sym(qdd).evalf(5), "tau_num": la.sym(tau).evalf(5), "realized": realized,
               "err_num": la.sym(err).evalf(5)}
        if lo is not None:
            within = all(lo[i] <= tau[i, 0] <= hi[i] for i in range(nq)) if exact else \
                all(lo[i] - 1e-9 <= float(tau[i, 0]) <= hi[i] + 1e-9 for i in range(nq))
            add(f"within_{k}", bool(within), "bool", label="|\\tau_i| \\le \\tau_{max,i}")
            ms = rs.max_scaling(la, M @ x, c, lo, hi)
            one = sp.Integer(1) if exact else 1.0
            s = None if (ms.lam is None or ms.low > one) else min(ms.lam, one)  # the largest s in [0, 1]
            if not realized:  # (a least-squares solution at a singularity: no fraction of the task is realized)
                s = None
            if s is not None:
                add(f"scale_{k}", la.scalar(s), "number", label="s_{max}")
            row.update(within=within, scale=None if s is None else la.scalar(s))
        table.append(row)
        sol.step("objective", o=o, k=k, label=LABEL[o], qdd=la.sym(qdd), tau=la.sym(tau), M=la.sym(M),
                 c=la.sym(c), exact=exact, weighted=o == "weighted_torque")
    sol.step("compare", table=table, costs=[c for c in ("acceleration", "inertia", "torque", "weighted_torque")
                                            if c in table[0]["costs"]], labels=LABEL, bounds=hi is not None,
             unrealized=not all(r["realized"] for r in table),
             hi=hi, hi_m=sp.Matrix([la.scalar(v) for v in hi]) if hi is not None else None)
    if hi is not None:
        hv = [float(v) for v in hi]
        rows = [("min " + r["o"].replace("_", " "), [float(v) for v in r["tau"]]) for r in table]

        def sample() -> list[Panel]:
            js = [float(j) for j in range(1, nq + 1)]
            curves = [Curve(lab, js, v) for lab, v in rows]
            curves += [Curve("$\\pm\\tau_{max}$", js, hv, dashed=True), Curve("", js, [-v for v in hv], dashed=True)]
            return [Panel("joint", "$\\tau_i$", curves)]

        sol.figures.append(Figure("torques" + sfx, "Torques of each solution against their bounds (dashed).",
                                  sample))
    return sol


SYMBOLIC_SECONDS = 6.0


def _symbolic(problem, options: MinimumNormAsk, ctx, sol: Solution, add, Jq: sp.Matrix,  # type: ignore[no-untyped-def]
              f: sp.Matrix | None, q: list, dq: list) -> Solution:
    """Generic state (q, q̇): M = JB⁻¹, d = r̈_d − J̇q̇ + JB⁻¹n, τ* = M^#d (and the other objectives)."""
    from solver.dynamics.model import derive
    from solver.kinematics.redundancy import _quot, _tidy_rational
    from solver.math.budget import BudgetExceeded, cpu_budget
    m, nq = Jq.shape
    if m > 2 or nq > 3:
        raise _too_big(problem, ctx, m, nq)
    qd = _vec(problem, ctx, "joint_velocity", nq) if options.joint_velocity is not None else sp.Matrix(dq)
    rdd = _vec(problem, ctx, "acceleration", m)
    dm = derive(problem.robot)
    nvec = dm.lhs.subs({d: 0 for d in problem.robot.ddq})
    if options.joint_velocity is not None:
        nvec = nvec.subs({d: qd[i] for i, d in enumerate(dq)})
    Jdot = sum((Jq.diff(x) * qd[i] for i, x in enumerate(q)), sp.zeros(m, nq))
    h = (Jdot * qd).applyfunc(_tidy_rational)
    T = _tidy_rational
    try:
        with cpu_budget(SYMBOLIC_SECONDS):
            # numerators and denominators kept apart (trigonometric polynomials tidy fast; their quotients do not):
            # M = N/det B with N = J adj B; M^# = Nᵀ adj G det B / det G with G = N Nᵀ
            B = dm.B
            detB = T(B.det())
            N = (Jq * B.adjugate()).applyfunc(T)
            M = N.applyfunc(lambda e: _quot(e, detB))
            dnum = (rdd * detB - h * detB + N * nvec).applyfunc(T)
            d = dnum.applyfunc(lambda e: _quot(e, detB))
            add("J", Jq, "matrix", label="J(q)")
            add("Jdot_qdot_sym", h, "vector", label="\\dot J\\dot q")
            add("M", M, "matrix", label="M = J B^{-1}")
            add("d", d, "vector", label="d = \\ddot r_d - \\dot J\\dot q + J B^{-1} n")
            G = (N * N.T).applyfunc(T)
            dG = T(G.det()) if m > 1 else G[0, 0]
            adjG = G.adjugate().applyfunc(T) if m > 1 else sp.Matrix([[1]])
            NtA = (N.T * adjG).applyfunc(T)
            Mp = NtA.applyfunc(lambda e: _quot(T(e * detB), dG))
            out = {"M": M, "d": d, "Mp": Mp, "B": B, "n": nvec, "h": h, "J": Jq, "f": f}
            tau_num = (NtA * dnum).applyfunc(T)
            if "torque" in options.objectives:
                tau = tau_num.applyfunc(lambda e: _quot(e, dG))
                add("M_pinv", Mp, "matrix", label="M^{\\#}")
                add("tau_tau", tau, "vector", label="\\tau^* = M^{\\#} d")
                out["tau"] = tau
            if options.weight is not None and "weighted_torque" in options.objectives:
                w = ctx.expr("weight")
                shp = shape_of(w)
                W = sp.diag(*w) if shp == (nq,) else sp.Matrix(w) if shp == (nq, nq) else None
                if W is None:
                    raise _fail(problem, ctx, ("weight",), f"weight must be {nq}x{nq} or {nq} diagonal entries")
                Wi = W.inv()
                GW = (N * Wi * N.T).applyfunc(T)
                dGW = T(GW.det()) if m > 1 else GW[0, 0]
                adjGW = GW.adjugate().applyfunc(T) if m > 1 else sp.Matrix([[1]])
                MpW = (Wi * N.T * adjGW).applyfunc(lambda e: _quot(T(e * detB), dGW))
                add("M_pinv_W", MpW, "matrix", label="M_W^{\\#}")
                tauW = (Wi * N.T * adjGW * dnum).applyfunc(lambda e: _quot(T(e), dGW))
                add("tau_tauW", tauW, "vector", label="\\tau_W = M_W^{\\#} d")
                out.update(W=W, MpW=MpW)
            if options.null_torque is not None:
                t0 = _vec(problem, ctx, "null_torque", nq)
                tns_num = (tau_num + dG * t0 - NtA * N * t0).applyfunc(T)
                tns = tns_num.applyfunc(lambda e: _quot(e, dG))
                add("tau_ns", tns, "vector", label="M^{\\#}d + (I - M^{\\#}M)\\tau_0")
                out.update(t0=t0, tns=tns)
    except BudgetExceeded:
        sol.step("too_big", seconds=SYMBOLIC_SECONDS)
        return sol
    sol.step("symbolic", **out)
    return sol
