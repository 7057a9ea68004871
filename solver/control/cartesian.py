"""Feedback linearization in the task space (``control_law`` with ``law: cartesian_computed_torque``).

    model            B(q) q̈ + c(q, q̇) + g(q) (+ F_v q̇) = τ = G u
    linearization    τ = B(q) a + c + g (+ F_v q̇)                   =>  q̈ = a
    task             r = f(q) ∈ R^m (m ≤ n),  ṙ = J(q) q̇,  r̈ = J q̈ + J̇ q̇ = J a + J̇ q̇
    error frame      e_t = Rᵀ(r_d − r) with a constant rotation R (default I)
    task accel.      a_t = Rᵀ r̈_d + K_D Rᵀ(ṙ_d − J q̇) + K_P Rᵀ(r_d − f(q)),   a_r = R a_t
    m = n            a = J⁻¹(a_r − J̇ q̇)                                          (det J ≠ 0)
    m < n            a = J^#(a_r − J̇ q̇) + (I − J^# J) a_0,   J^# = Jᵀ(J Jᵀ)⁻¹       (J full row rank)
                     a_0 = null − K_v q̇ + step ∇H(q)                               (the null-space acceleration)
    =>  J q̈ + J̇ q̇ = a_r  =>  ë_t + K_D ė_t + K_P e_t = 0 (decoupled along the axes of R); J (I − J^# J) a_0 = 0.

With isotropic gains (K = k I) R K Rᵀ = K: the frame changes nothing. J^# is symbolic within a CPU budget; beyond
it the law is evaluated at the ``at:`` state.
"""
from __future__ import annotations

import random
from typing import Any, Callable

import sympy as sp

from solver.control.laws import (
    ControlLawAsk,
    _at_pairs,
    _gains,
    _input_inverse,
    _symbol,
    _zero,
    record_law,
)
from solver.dynamics.model import derive, require_model
from solver.kinematics.methods import NAMED_H, damping_matrix, named_objective
from solver.math.budget import BudgetExceeded, cpu_budget
from solver.math.fourier import NotTrigPolynomial, TrigPoly
from solver.math.simplify import expand_polynomial, factor_within, matmul, tidy
from solver.math.trigpoly import TrigAlgebra
from solver.results import Solution
from solver.spec.expr import shape_of
from solver.spec.problem import AskReader

PINV_SECONDS = 8.0  # CPU budget of the symbolic pseudoinverse and of the law built on it
TIDY_SECONDS = 2.0  # CPU budget of the cosmetic simplification of a_0


def task_terms(f: sp.Matrix, q: list, dq: list) -> tuple[sp.Matrix, sp.Matrix]:
    """(J, J̇ q̇) of the task r = f(q): J = ∂f/∂q, J̇ q̇ = Σ_k (∂J/∂q_k q̇_k) q̇."""
    J = f.jacobian(q).applyfunc(tidy)
    v = sp.Matrix(dq)
    Jdot = sp.zeros(*J.shape)
    for qk, dqk in zip(q, dq):
        Jdot += sp.diff(J, qk) * dqk
    return J, (Jdot * v).applyfunc(tidy)


def rotation_2d(angle: sp.Expr) -> sp.Matrix:
    """R(α) = [[cos α, −sin α], [sin α, cos α]]."""
    return sp.Matrix([[sp.cos(angle), -sp.sin(angle)], [sp.sin(angle), sp.cos(angle)]])


def task_acceleration(f: sp.Matrix, J: sp.Matrix, dq: sp.Matrix, KP: sp.Matrix, KD: sp.Matrix, rd: sp.Matrix,
                      drd: sp.Matrix, ddrd: sp.Matrix, R: sp.Matrix | None) -> tuple[sp.Matrix, sp.Matrix]:
    """(a_t, a_r): a_t = Rᵀ r̈_d + K_D Rᵀ(ṙ_d − J q̇) + K_P Rᵀ(r_d − f) in the error frame, a_r = R a_t in the base
    frame (R = I without a frame)."""
    Rt = R.T if R is not None else sp.eye(f.rows)
    at = Rt * ddrd + KD * Rt * (drd - J * dq) + KP * Rt * (rd - f)
    ar = R * at if R is not None else at
    return at.applyfunc(sp.expand), ar.applyfunc(sp.expand)


def pinv_law(J: sp.Matrix, Jdq: sp.Matrix, ar: sp.Matrix, a0: sp.Matrix | None) -> dict[str, Any]:
    """J^# = Jᵀ(JJᵀ)⁻¹ = Jᵀ adj(JJᵀ)/D = N/D, D = det(JJᵀ), P = I − J^# J = (D I − N J)/D and
    a = J^#(a_r − J̇ q̇) + P a_0, every entry a numerator over D. Numerators and D are kept in the canonical
    trigonometric form (fast; the factoring the redundancy ask applies for display is too slow for an n×n P).
    "ok" (J a + J̇ q̇ = a_r and J P a_0 = 0) and "null_ok" (J P a_0 = 0, with a_0) are decided exactly there; None
    off the algebra (the caller checks the law at random points)."""
    try:
        return _pinv_law_canonical(J, Jdq, ar, a0)
    except NotTrigPolynomial:  # (radicals, parameters in denominators, floats: sympy expressions, tidied)
        return _pinv_law_tidied(J, Jdq, ar, a0)


def _pinv_law_tidied(J: sp.Matrix, Jdq: sp.Matrix, ar: sp.Matrix, a0: sp.Matrix | None) -> dict[str, Any]:
    """:func:`pinv_law` with sympy products, each tidied (any entries)."""
    n = J.cols
    A = (J * J.T).applyfunc(tidy)
    D = tidy(A.det()) if A.rows > 1 else A[0, 0]
    N = (J.T * (A.adjugate() if A.rows > 1 else sp.Matrix([[1]]))).applyfunc(tidy)
    num_ps = (N * (ar - Jdq)).applyfunc(tidy)
    PD = (D * sp.eye(n) - N * J).applyfunc(tidy)     # D (I − J^# J)
    a_null = None
    num = num_ps
    if a0 is not None:
        num_null = (PD * a0).applyfunc(tidy)
        a_null = num_null.applyfunc(lambda x: x / D)
        num = num_ps + num_null
    return {"J_pinv": N.applyfunc(lambda x: x / D), "det": D, "P": PD.applyfunc(lambda x: x / D),
            "a_ps": num_ps.applyfunc(lambda x: x / D), "a_null": a_null, "a": num.applyfunc(lambda x: x / D),
            "ok": None, "null_ok": None}


def _pinv_law_canonical(J: sp.Matrix, Jdq: sp.Matrix, ar: sp.Matrix, a0: sp.Matrix | None) -> dict[str, Any]:
    """:func:`pinv_law` computed in the trigonometric-polynomial algebra (products, det and adjugate on Fourier
    coefficients, each result written once: what tidying every product gives, without expanding sympy
    products); NotTrigPolynomial when an entry is not a trigonometric polynomial with polynomial coefficients."""
    alg = TrigAlgebra.of([J, Jdq, ar] + ([a0] if a0 is not None else []))
    Jt = alg.matrix(J)
    D, adj = alg.det_adj(alg.matmul(Jt, alg.T(Jt)))
    N = alg.matmul(alg.T(Jt), adj)
    num_ps = alg.matmul(N, alg.matrix(ar - Jdq))
    NJ = alg.matmul(N, Jt)
    n = J.cols
    PD = [[alg.sub(D if i == j else {}, NJ[i][j]) for j in range(n)] for i in range(n)]
    De = alg.expr(D)

    def printed(M: list[list[TrigPoly]]) -> sp.Matrix:
        return sp.Matrix([[alg.expr(x) for x in row] for row in M])

    def over(M: sp.Matrix) -> sp.Matrix:
        return M.applyfunc(lambda x: x / De)

    num = ps = printed(num_ps)
    a_null = None
    JPa0: list[list[TrigPoly]] = [[] for _ in range(J.rows)]
    if a0 is not None:  # (the two numerators added as printed, not in one canonical form: as pinv_law does)
        null = alg.matmul(PD, alg.matrix(a0))
        num_null = printed(null)
        a_null = over(num_null)
        num = ps + num_null
        JPa0 = alg.matmul(Jt, null)
    # exact checks (canonical forms: zero iff the function is): J (I − J^# J) a_0 = 0, and J a + J̇ q̇ = a_r, i.e.
    # J num_ps + D (J̇ q̇ − a_r) = 0 and J P_D a_0 = 0
    Jps, rest = alg.matmul(Jt, num_ps), alg.matrix(Jdq - ar)
    ok = all(not alg.add(Jps[i][0], alg.mul(D, rest[i][0])) for i in range(J.rows))
    null_ok = all(not x for row in JPa0 for x in row)
    return {"J_pinv": over(printed(N)), "det": De, "P": over(printed(PD)), "a_ps": over(ps), "a_null": a_null,
            "a": over(num), "ok": ok and null_ok, "null_ok": null_ok if a0 is not None else None}


class _TaskInputs(AskReader):
    """The task, its error frame and the null-space acceleration of one ask."""

    def __init__(self, problem, options: ControlLawAsk, ctx, robot) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.ctx, self.options = problem, ctx, options
        n = robot.n
        self.q, self.dq = list(robot.q), list(robot.dq)
        if options.task is None:
            raise self.fail(("law",), "law: cartesian_computed_torque needs task: r = f(q), a list of m <= n "
                            "expressions", "e.g. task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]")
        val = ctx.expr("task")
        vals = val if isinstance(val, list) else [val]
        if not vals or len(vals) > n or any(isinstance(x, list) for x in vals):
            raise self.fail(("task",), f"task must list 1 to {n} expressions (one per task coordinate; at most one "
                                       f"per joint), got {len(vals)}", "write task: [f1(q), f2(q)]")
        self.f = sp.Matrix([sp.sympify(x) for x in vals])
        self.m = self.f.rows
        self.R = self._frame() if options.frame is not None else None
        nulls = [k for k in ("null", "damping", "gradient") if getattr(options, k) is not None]
        if nulls and self.m == n:
            raise self.fail((nulls[0],), f"{nulls[0]}: is a null-space acceleration, but the task has m = n = {n} "
                                         "coordinates (J is square: no null space)", "remove it")
        if options.step is not None and options.gradient is None:
            raise self.fail(("step",), "step: is the step along the gradient of gradient: H(q)", "add gradient:")
        if options.joint_ranges is not None and not (isinstance(options.gradient, str)
                                                     and options.gradient.strip() == "joint_range"):
            raise self.fail(("joint_ranges",), "joint_ranges: belongs to gradient: joint_range", "remove it")
        self.null = self._vector("null", n, "null (the preferred joint acceleration a_0)") \
            if options.null is not None else None
        self.Kv = damping_matrix(self, n) if options.damping is not None else None
        self.H, self.H_name, self.step = None, None, sp.Integer(1)
        if options.gradient is not None:
            if isinstance(options.gradient, str) and options.gradient.strip() in NAMED_H:
                self.H_name = options.gradient.strip()
                J = self.f.jacobian(self.q)
                self.H = named_objective(self, self.H_name, J, self.q, options.joint_ranges)
            else:
                H = ctx.expr("gradient")
                if isinstance(H, list):
                    raise self.fail(("gradient",), "gradient: must be a scalar function H(q)", "write e.g. sin(q2)^2")
                self.H = sp.sympify(H)
            if self.H.free_symbols & set(self.dq):
                raise self.fail(("gradient",), "H(q) must not depend on the joint velocities")
            if options.step is not None:
                self.step = sp.sympify(ctx.expr("step"))
                if isinstance(self.step, list) or self.step.free_symbols & set(self.q + self.dq):
                    raise self.fail(("step",), "step must be a number or an expression of parameters")

    def _frame(self) -> sp.Matrix:
        val = self.ctx.expr("frame")
        shp = shape_of(val)
        m = self.m
        if shp == ():
            if m != 2:
                raise self.fail(("frame",), f"frame: an angle rotates a 2-D task; this task has {m} coordinates",
                                f"give the {m}x{m} rotation matrix")
            R = rotation_2d(sp.sympify(val))
        elif shp == (m, m):
            R = sp.Matrix(val)
        else:
            raise self.fail(("frame",), f"frame must be an angle (2-D task) or a {m}x{m} rotation matrix, got shape "
                                        f"{shp}")
        if R.free_symbols & set(self.q + self.dq):
            raise self.fail(("frame",), "the frame of the task error must be constant (no q, dq in R)")
        if not all(_zero(x) for x in (R.T * R - sp.eye(m))):
            raise self.fail(("frame",), "frame must be a rotation matrix (R^T R = I)",
                            "e.g. [[cos(alpha), -sin(alpha)], [sin(alpha), cos(alpha)]]")
        return R

    def a0(self) -> sp.Matrix | None:
        """a_0 = null − K_v q̇ + step ∇H(q), or None."""
        parts = []
        if self.null is not None:
            parts.append(self.null)
        if self.Kv is not None:
            parts.append(-self.Kv * sp.Matrix(self.dq))
        if self.H is not None:
            parts.append(self.step * sp.Matrix([sp.diff(self.H, x) for x in self.q]))
        if not parts:
            return None
        a0 = sum(parts[1:], parts[0])
        try:
            with cpu_budget(TIDY_SECONDS):
                return a0.applyfunc(tidy)
        except BudgetExceeded:   # e.g. the gradient of the manipulability √det(JJᵀ): kept as derived
            return a0


def _task_gains_and_reference(problem, options: ControlLawAsk, ctx, inp: _TaskInputs) -> tuple:  # type: ignore[no-untyped-def]
    """K_P, K_D (diagonals) and r_d, ṙ_d, r̈_d: the ask's or default symbols (registered in the problem)."""
    m = inp.m
    kp = _gains(problem, options, ctx, "kp", m, True)
    kd = _gains(problem, options, ctx, "kd", m, True)
    if options.rd is not None:
        if not options.regulation:
            raise inp.fail(("rd",), "rd: (a constant desired task value) needs regulation: true", "add regulation: true")
        rd = inp._vector("rd", m, "rd (the desired task value)")
    else:
        rd = sp.Matrix([_symbol(problem, f"rd{i + 1}", f"r_{{d,{i + 1}}}") for i in range(m)])
    if options.regulation:
        drd = ddrd = sp.zeros(m, 1)
    else:
        drd = sp.Matrix([_symbol(problem, f"drd{i + 1}", f"\\dot r_{{d,{i + 1}}}") for i in range(m)])
        ddrd = sp.Matrix([_symbol(problem, f"ddrd{i + 1}", f"\\ddot r_{{d,{i + 1}}}") for i in range(m)])
    return kp, kd, rd, drd, ddrd


def validate_cartesian(problem, options: ControlLawAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The options of law: cartesian_computed_torque read and checked as :func:`solve_cartesian` reads them (the
    task, its frame, the null-space terms, the gains, r_d and its symbols), without the model."""
    inp = _TaskInputs(problem, options, ctx, require_model(problem))
    _task_gains_and_reference(problem, options, ctx, inp)


def solve_cartesian(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: r, J, det_J (m = n), J_inv (m = n), J_pinv, P_null, a0, a_null, null_check (m < n), Jdot_dq,
    R_frame, e_t, a_t, KP_base, KD_base, isotropic (with frame:), a_r, a, u, u_a, closed_loop, closed_loop_check;
    with at: u_at (and a_at, J_at, J_pinv_at when the pseudoinverse is numeric)."""
    robot = require_model(problem)
    dm = derive(robot)
    n = robot.n
    inp = _TaskInputs(problem, options, ctx, robot)
    f, m, R = inp.f, inp.m, inp.R
    Ginv = _input_inverse(problem, dm, ctx, "cartesian_computed_torque")
    q, dq = list(robot.q), list(robot.dq)
    v = sp.Matrix(dq)
    J, Jdq = task_terms(f, q, dq)
    square = m == n
    detJ = None
    if square:
        detJ = factor_within(tidy(J.det()))  # the canonical trigonometric form, factored (sp.simplify: ~10x slower)
        if _zero(detJ):
            raise inp.fail(("task",), "the task Jacobian is singular everywhere: the task cannot be controlled")
    kp, kd, rd, drd, ddrd = _task_gains_and_reference(problem, options, ctx, inp)
    KP, KD = sp.diag(*kp), sp.diag(*kd)
    a_t, a_r = task_acceleration(f, J, v, KP, KD, rd, drd, ddrd, R)
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    nvec = dm.c + dm.g + Fv * v
    G = dm.G if dm.G is not None else sp.eye(n)
    a0 = inp.a0()
    if not square and not J.free_symbols & set(q) and J.rank() < m:
        raise inp.fail(("task",), f"the task Jacobian has rank {J.rank()} < m = {m}: the task cannot be controlled")
    pairs = _at_pairs(problem, options, ctx)
    at = dict(pairs) if pairs is not None else None
    ps: dict[str, Any] | None = None
    numeric_reason = None
    Jinv = None
    if square:
        Jinv = (J.adjugate() / detJ).applyfunc(tidy)
        a = matmul(Jinv, a_r - Jdq).applyfunc(tidy)
    else:
        try:
            with cpu_budget(PINV_SECONDS):
                ps = pinv_law(J, Jdq, a_r, a0)
            a = ps["a"]
        except BudgetExceeded:
            numeric_reason = (f"the symbolic pseudoinverse of the {m}x{n} task Jacobian (and the law built on it) "
                              f"did not finish within {PINV_SECONDS:g} s of CPU time")
            if at is None or {s for s in q + dq} - set(at):
                raise inp.fail(("task",), numeric_reason, "give at: a state (q1.., dq1.., and the other symbols) "
                                                          "where the law is evaluated numerically") from None
            a = None
    sol = Solution("control_law", title=options.title or (
        "Control law: computed torque in the Cartesian space" if square and R is None and a0 is None
        else "Control law: feedback linearization in the task space"))
    sol.add("r", f, "vector", label="r = f(q)")
    sol.add("J", J, "matrix", label="J(q)")
    if square:
        sol.add("det_J", detJ, "scalar", label="\\det J(q)")
        sol.add("J_inv", Jinv, "matrix", label="J^{-1}(q)")
    sol.add("Jdot_dq", Jdq, "vector", label="\\dot J(q)\\dot q")
    if R is not None:
        e_t = (R.T * (rd - f)).applyfunc(sp.expand)
        simplified: dict[sp.Expr, sp.Expr] = {}   # (R K Rᵀ is symmetric: each pair of entries simplified once)

        def trigsimp(x: sp.Expr) -> sp.Expr:
            x = sp.expand(x)
            if x not in simplified:
                simplified[x] = sp.trigsimp(x)
            return simplified[x]
        KPb, KDb = (R * KP * R.T).applyfunc(trigsimp), (R * KD * R.T).applyfunc(trigsimp)
        iso = all(_zero(x) for x in list(KPb - KP) + list(KDb - KD))
        sol.add("R_frame", R, "matrix", label="R")
        sol.add("e_t", e_t, "vector", label="e_t = R^T(r_d - r)")
        sol.add("a_t", a_t, "vector", label="a_t")
        sol.add("KP_base", KPb, "matrix", label="R K_P R^T")
        sol.add("KD_base", KDb, "matrix", label="R K_D R^T")
        sol.add("isotropic", bool(iso), "bool", label="R K_P R^T = K_P,\\ R K_D R^T = K_D")
    sol.add("a_r", a_r.applyfunc(tidy), "vector", label="a_r")
    ddr = sp.Matrix([_symbol(problem, f"ddr{i + 1}", f"\\ddot r_{{{i + 1}}}") for i in range(m)])
    Rt = R.T if R is not None else sp.eye(m)
    closed = Rt * (ddrd - ddr) + KD * Rt * (drd - J * v) + KP * Rt * (rd - f)
    asym = sp.Matrix([_symbol(problem, f"a{i + 1}", f"a_{{{i + 1}}}") for i in range(n)])
    if Ginv is None:  # B a + n is the model B q̈ + n, already in its tidy form, at q̈ = a
        u_a = dm.lhs.xreplace(dict(zip(robot.ddq, asym)))
    else:
        u_a = (Ginv * (dm.B * asym + nvec)).applyfunc(tidy)
    u = ok = null_ok = None
    if ps is not None:
        sol.add("J_pinv", ps["J_pinv"], "matrix", label="J^{\\#}(q)")
        sol.add("P_null", ps["P"], "matrix", label="I - J^{\\#}J")
        if a0 is not None:
            sol.add("a0", a0, "vector", label="a_0")
            sol.add("a_null", ps["a_null"], "vector", label="(I - J^{\\#}J)a_0")
            null_ok = ps["null_ok"] if ps.get("null_ok") is not None else _vanishes(list(matmul(J, ps["a_null"])))
            sol.add("null_check", bool(null_ok), "bool", label="J(I - J^{\\#}J)a_0 = 0")
    elif not square and a0 is not None:
        sol.add("a0", a0, "vector", label="a_0")
    if a is not None:
        tau = matmul(dm.B, a) + nvec
        u = matmul(Ginv, tau) if Ginv is not None else tau
        u = u.applyfunc(tidy) if square else u
        sol.add("a", a, "vector", label="a")
        sol.add("u", u, "vector", label="u")
        sol.add("u_a", u_a, "vector", label="u(a)")
        # q̈ = B⁻¹(G u − n): with u = B a + n (m < n, not rewritten) that is a itself, checked without the model
        if square:
            ok = _check(dm.B, matmul(G, u) - nvec, J, Jdq, a_r)
        else:  # (exact in the canonical algebra when the pseudoinverse was computed there)
            ok = ps["ok"] if ps is not None and ps.get("ok") is not None else _check(None, a, J, Jdq, a_r)
        sol.add("closed_loop", closed.applyfunc(expand_polynomial), "vector",
                label="\\ddot e_t + K_D\\dot e_t + K_P e_t" if R is not None else "\\ddot e_r + K_D\\dot e_r + K_P e_r")
        sol.add("closed_loop_check", bool(ok), "bool", label="\\text{closed loop verified}")
    else:
        sol.add("u_a", u_a, "vector", label="u(a)")
    num = None
    if at is not None:
        num = _at_state(at, problem.values, dm.B, nvec, G, Ginv, J, Jdq, a_r, a0, u)
        sol.add("u_at", num["u"], "vector", label="u")
        if a is None:
            sol.add("J_at", num["J"], "matrix", label="J\\big|_{*}")
            sol.add("J_pinv_at", num["J_pinv"], "matrix", label="J^{\\#}\\big|_{*}")
            sol.add("a_at", num["a"], "vector", label="a\\big|_{*}")
            sol.add("closed_loop_check", bool(num["ok"]), "bool", label="\\text{closed loop verified at the state}")
    record_law(problem, options.suffix, list(f), [[a_, b, c] for a_, b, c in zip(rd, drd, ddrd)],
               list(rd) if options.rd is not None else None)
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("cartesian", f=f, J=J, detJ=detJ, Jdq=Jdq, KP=KP, KD=KD, rd=rd, drd=drd, ddrd=ddrd, m=m, n=n,
             regulation=options.regulation, a=a_r.applyfunc(tidy), a_t=a_t, R=R, u=u, ok=ok, kp=kp, kd=kd,
             Ginv=Ginv, friction=dm.Fv is not None, square=square, Jinv=Jinv, ps=ps, a0=a0, null_ok=null_ok,
             H=inp.H, H_name=inp.H_name, step=inp.step, Kv=inp.Kv, null=inp.null, qacc=a,
             isotropic=sol.results["isotropic"].value if R is not None else None,
             KPb=sol.results["KP_base"].value if R is not None else None,
             KDb=sol.results["KD_base"].value if R is not None else None,
             numeric_reason=numeric_reason, at=pairs, num=num)
    return sol


def _at_state(at: dict, values: dict, B: sp.Matrix, nvec: sp.Matrix, G: sp.Matrix, Ginv: sp.Matrix | None,
              J: sp.Matrix, Jdq: sp.Matrix, ar: sp.Matrix, a0: sp.Matrix | None,
              u: sp.Matrix | None) -> dict[str, Any]:
    """The law at a state: u substituted when it is symbolic; otherwise J^# (exact when small, else floats), a and u
    computed there, and J a + J̇ q̇ = a_r checked."""
    subs = {**values, **at}

    def ev(M: sp.Matrix) -> sp.Matrix:
        return M.xreplace(at).xreplace(subs).applyfunc(lambda x: tidy(x) if x.free_symbols else sp.nsimplify(x)
                                                        if x.is_Float else sp.simplify(x))

    if u is not None:
        try:
            with cpu_budget(PINV_SECONDS):
                return {"u": u.xreplace(at).applyfunc(lambda x: tidy(sp.simplify(x)))}
        except BudgetExceeded:
            return {"u": u.xreplace(subs).evalf(15)}
    Jn, Jdqn, arn = ev(J), ev(Jdq), ev(ar)
    a0n = ev(a0) if a0 is not None else None
    try:
        with cpu_budget(PINV_SECONDS):
            r = pinv_law(Jn, Jdqn, arn, a0n)
            Jp, a = r["J_pinv"], r["a"].applyfunc(sp.simplify)
    except BudgetExceeded:
        Jn, Jdqn, arn = Jn.evalf(15), Jdqn.evalf(15), arn.evalf(15)
        Jp = Jn.T * (Jn * Jn.T).inv()
        a = Jp * (arn - Jdqn)
        if a0n is not None:
            a += (sp.eye(J.cols) - Jp * Jn) * a0n.evalf(15)
    tau = ev(B) * a + ev(nvec)
    un = (ev(Ginv) * tau) if Ginv is not None else tau
    resid = list(Jn * a + Jdqn - arn)
    floats = any(x.atoms(sp.Float) for x in resid)   # floating point: a tolerance relative to the size of a_r
    ok = _vanishes(resid, tol=1e-9 if floats else None, scale=list(arn))
    def show(x: sp.Expr) -> sp.Expr:   # numbers with floating-point parts as floats, exact ones simplified
        if not x.free_symbols and x.atoms(sp.Float):
            v = sp.N(x, 15)
            return sp.Integer(0) if v.is_real and abs(v) < 1e-12 else v   # rounding noise of an exact zero
        return sp.simplify(x)

    return {"J": Jn.applyfunc(show), "J_pinv": Jp.applyfunc(show), "a": a.applyfunc(show), "u": un.applyfunc(show),
            "ok": ok}


def _vanishes(exprs: list, digits: int = 40, tol: float | None = None, scale: list | None = None) -> bool:
    """Every expression is zero at random rational points of its symbols (``digits`` digits): below 10^(15 −
    digits), or below ``tol`` (1 + max |scale|) for floating-point data."""
    rng = random.Random(11)
    exprs = [sp.sympify(x) for x in exprs]
    scale = [sp.sympify(x) for x in (scale or [])]
    syms = sorted(set().union(*(x.free_symbols for x in exprs + scale)), key=str)
    size = _magnitudes(exprs + scale, syms, digits)
    for _ in range(3 if syms else 1):
        pt = [sp.Rational(rng.randint(2, 19), rng.randint(3, 9)) for _ in syms]
        values = size(pt)
        bound = 10 ** (-digits + 15)
        if tol is not None:
            bound = tol * (1 + max(values[len(exprs):] or [0]))
        if any(v > bound for v in values[:len(exprs)]):
            return False
    return True


def _magnitudes(exprs: list[sp.Expr], syms: list[sp.Symbol], digits: int) -> Callable[[list], list[float]]:
    """point -> [|e(point)|] computed with ``digits`` digits: by one mpmath function of all the expressions
    (lambdify; several times faster than sympy's evalf of each at each point), else by evalf."""
    import mpmath
    try:
        f = sp.lambdify(syms, exprs, modules="mpmath")
    except Exception:  # noqa: BLE001 - a function lambdify cannot print: sympy's evalf
        f = None

    def by_evalf(pt: list) -> list[float]:
        at = dict(zip(syms, pt))
        return [abs(complex(x.xreplace(at).evalf(digits))) for x in exprs]

    def by_mpmath(pt: list) -> list[float]:
        try:
            with mpmath.workdps(digits):
                return [float(abs(mpmath.mpc(v))) for v in f(*[mpmath.mpf(int(x.p)) / int(x.q) for x in pt])]
        except (TypeError, ValueError, ZeroDivisionError, NameError, AttributeError):
            return by_evalf(pt)
    return by_mpmath if f is not None else by_evalf


def _check_exact(B: sp.Matrix | None, rhs: sp.Matrix, J: sp.Matrix, Jdq: sp.Matrix, a: sp.Matrix) -> bool | None:
    """:func:`_check` by the randomized exact test (:func:`solver.math.equivalence.exact_test`: points where sin
    and cos are rational, B q̈ = rhs solved over Q): a non-zero residual proves the law wrong, zero at three points
    proves it right (Schwartz-Zippel); None when an entry is not a rational function of the values (floats,
    radicals)."""
    from sympy.polys.matrices import DomainMatrix
    from sympy.polys.matrices.exceptions import DMNonInvertibleMatrixError

    from solver.math.equivalence import exact_test
    mats = [M for M in (B, rhs, J, Jdq, a) if M is not None]
    exprs = [sp.sympify(x) for M in mats for x in M]
    if any(x.atoms(sp.Float) for x in exprs):
        return None

    def at(point, M: sp.Matrix) -> DomainMatrix:  # type: ignore[no-untyped-def]
        """M at the point, over Q."""
        values = [[point.value(M[i, j]) for j in range(M.cols)] for i in range(M.rows)]
        return DomainMatrix([[sp.QQ(v.numerator, v.denominator) for v in row] for row in values], M.shape, sp.QQ)

    def residuals(point):  # type: ignore[no-untyped-def]
        ddq = at(point, rhs)
        if B is not None:
            try:
                ddq = at(point, B).lu_solve(ddq)
            except DMNonInvertibleMatrixError:
                raise ZeroDivisionError("B singular here") from None
        return (at(point, J) * ddq + at(point, Jdq) - at(point, a)).to_Matrix()

    return exact_test(residuals, exprs, trials=3, seed=5)


def _check(B: sp.Matrix | None, rhs: sp.Matrix, J: sp.Matrix, Jdq: sp.Matrix, a: sp.Matrix) -> bool:
    """J q̈ + J̇ q̇ = a with q̈ = B⁻¹ rhs from the model (q̈ = rhs when B is None): exactly at random rational points
    (:func:`_check_exact`), else at random rational points to 40 digits."""
    exact = _check_exact(B, rhs, J, Jdq, a)
    if exact is not None:
        return exact
    rng = random.Random(5)
    syms = sorted(set().union(*(x.free_symbols for x in (list(B) if B is not None else []) + list(rhs) + list(a))),
                  key=str)
    for _ in range(3):
        at = {s: sp.Rational(rng.randint(2, 19), rng.randint(3, 9)) for s in syms}
        ddq = rhs.xreplace(at).evalf(40)
        if B is not None:
            ddq = B.xreplace(at).evalf(40).LUsolve(ddq)
        res = (J.xreplace(at) * ddq + Jdq.xreplace(at) - a.xreplace(at)).evalf(40)
        if any(abs(complex(x)) > 1e-25 for x in res):
            return False
    return True


def check_task_law(problem, results, sfx: str, value) -> Any:  # type: ignore[no-untyped-def]
    """A task-space u is right iff, substituted in the model, it gives J q̈ + J̇ q̇ = a_r (the designed task
    acceleration): then ë_t + K_D ė_t + K_P e_t = 0. For m < n any null-space term passes (a different a_0 is
    another valid design, said in the feedback). Checked at random points (40 digits)."""
    from solver.control.laws import _answer_vector
    from solver.registry import PropertyVerdict
    robot = problem.robot
    n = robot.n
    U = _answer_vector(value, n)
    if not isinstance(U, sp.Matrix):
        return U
    need = ("r", "J", "Jdot_dq", "a_r")
    if any(k + sfx not in results for k in need):
        return None
    J, Jdq, ar = (sp.Matrix(results[k + sfx].value) for k in ("J", "Jdot_dq", "a_r"))
    dm = derive(robot)
    G = dm.G if dm.G is not None else sp.eye(n)
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    nvec = dm.c + dm.g + Fv * sp.Matrix(robot.dq)
    try:
        ok = _check(dm.B, G * U - nvec, J, Jdq, ar)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    if not ok:
        return PropertyVerdict(False, 0.0, ["substituted in the model B q̈ + c + g = u, this u does not give "
                                            "J q̈ + J̇ q̇ = a_r: the task error does not obey ë + K_D ė + K_P e = 0 "
                                            "(check J̇ q̇, the inverse or pseudoinverse of J, and c + g)"], final=False)
    ref = sp.Matrix(results["u" + sfx].value)
    same = _vanishes(list(U - ref))
    note = "substituted in the model, u gives J q̈ + J̇ q̇ = a_r: the task error obeys ë + K_D ė + K_P e = 0"
    if not same and J.rows < n:
        note += " (with another null-space term than the reference: a different, equally valid self-motion)"
    return PropertyVerdict(True, 1.0, [note])
