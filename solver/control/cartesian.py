"""Computed torque in the Cartesian (task) space (``control_law`` with ``law: cartesian_computed_torque``).

    r = f(q),  ṙ = J(q) q̇,  r̈ = J(q) q̈ + J̇(q, q̇) q̇          (J square, nonsingular)
    G u = B(q) J⁻¹(q) (a − J̇ q̇) + c(q, q̇) + g(q) (+ F_v q̇),   a = r̈_d + K_D(ṙ_d − J q̇) + K_P(r_d − f(q))
    => q̈ = J⁻¹(a − J̇ q̇)  => r̈ = a  => ë_r + K_D ė_r + K_P e_r = 0,   e_r = r_d − r
(away from the singularities det J = 0).
"""
from __future__ import annotations

import sympy as sp

from solver.control.laws import ControlLawAsk, _gains, _input_inverse, _symbol, _zero, record_law
from solver.dynamics.model import derive, require_model
from solver.math.simplify import tidy
from solver.results import Solution
from solver.spec.errors import UserError


def task_terms(f: sp.Matrix, q: list, dq: list) -> tuple[sp.Matrix, sp.Matrix]:
    """(J, J̇ q̇) of the task r = f(q): J = ∂f/∂q, J̇ q̇ = Σ_k (∂J/∂q_k q̇_k) q̇."""
    J = f.jacobian(q).applyfunc(tidy)
    v = sp.Matrix(dq)
    Jdot = sp.zeros(*J.shape)
    for qk, dqk in zip(q, dq):
        Jdot += sp.diff(J, qk) * dqk
    return J, (Jdot * v).applyfunc(tidy)


def solve_cartesian(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: r, J, det_J, Jdot_dq, a_r (the commanded task acceleration), u, closed_loop, closed_loop_check."""
    robot = require_model(problem)
    dm = derive(robot)
    n = robot.n
    place = problem.located.place(ctx.path + ("task",))
    if options.task is None:
        raise UserError("law: cartesian_computed_torque needs task: r = f(q), a list of n expressions", place,
                        "e.g. task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]")
    val = ctx.expr("task")
    vals = val if isinstance(val, list) else [val]
    if len(vals) != n or any(isinstance(x, list) for x in vals):
        raise UserError(f"task must list {n} expressions (a square Jacobian: one task coordinate per joint)", place)
    Ginv = _input_inverse(problem, dm, ctx, "cartesian_computed_torque")
    q, dq = list(robot.q), list(robot.dq)
    f = sp.Matrix([sp.sympify(x) for x in vals])
    J, Jdq = task_terms(f, q, dq)
    detJ = sp.factor(sp.simplify(J.det()))
    if _zero(detJ):
        raise UserError("the task Jacobian is singular everywhere: the task cannot be controlled", place)
    kp = _gains(problem, options, ctx, "kp", n, True)
    kd = _gains(problem, options, ctx, "kd", n, True)
    KP, KD = sp.diag(*kp), sp.diag(*kd)
    if options.rd is not None:
        if not options.regulation:
            raise UserError("rd: (a constant desired task value) needs regulation: true",
                            problem.located.place(ctx.path + ("rd",)), "add regulation: true")
        rv = ctx.expr("rd")
        rv = rv if isinstance(rv, list) else [rv]
        if len(rv) != n:
            raise UserError(f"rd must list {n} values", problem.located.place(ctx.path + ("rd",)))
        rd = sp.Matrix([sp.sympify(x) for x in rv])
    else:
        rd = sp.Matrix([_symbol(problem, f"rd{i + 1}", f"r_{{d,{i + 1}}}") for i in range(n)])
    if options.regulation:
        drd = ddrd = sp.zeros(n, 1)
    else:
        drd = sp.Matrix([_symbol(problem, f"drd{i + 1}", f"\\dot r_{{d,{i + 1}}}") for i in range(n)])
        ddrd = sp.Matrix([_symbol(problem, f"ddrd{i + 1}", f"\\ddot r_{{d,{i + 1}}}") for i in range(n)])
    v = sp.Matrix(dq)
    a = ddrd + KD * (drd - J * v) + KP * (rd - f)
    Jinv = (J.adjugate() / detJ).applyfunc(tidy)
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    tau = dm.B * Jinv * (a - Jdq) + dm.c + dm.g + Fv * v
    u = ((Ginv * tau) if Ginv is not None else tau).applyfunc(tidy)
    # exact check: q̈ from the model under u, then J q̈ + J̇ q̇ = a
    G = dm.G if dm.G is not None else sp.eye(n)
    rhs = G * u - dm.c - dm.g - Fv * v
    ok = _check(dm.B, rhs, J, Jdq, a)
    ddr = sp.Matrix([_symbol(problem, f"ddr{i + 1}", f"\\ddot r_{{{i + 1}}}") for i in range(n)])
    closed = (ddrd - ddr) + KD * (drd - J * v) + KP * (rd - f)
    record_law(problem, options.suffix, list(f), [[a_, b, c] for a_, b, c in zip(rd, drd, ddrd)],
               list(rd) if options.rd is not None else None)
    sol = Solution("control_law", title=options.title or "Control law: computed torque in the Cartesian space")
    sol.add("r", f, "vector", label="r = f(q)")
    sol.add("J", J, "matrix", label="J(q)")
    sol.add("det_J", detJ, "scalar", label="\\det J(q)")
    sol.add("Jdot_dq", Jdq, "vector", label="\\dot J(q)\\dot q")
    sol.add("a_r", a.applyfunc(tidy), "vector", label="a")
    sol.add("u", u, "vector", label="u")
    sol.add("closed_loop", closed.applyfunc(sp.expand), "vector", label="\\ddot e_r + K_D\\dot e_r + K_P e_r")
    sol.add("closed_loop_check", bool(ok), "bool", label="\\text{closed loop verified}")
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("cartesian", f=f, J=J, detJ=detJ, Jdq=Jdq, KP=KP, KD=KD, rd=rd, drd=drd, ddrd=ddrd,
             regulation=options.regulation, a=a.applyfunc(tidy), u=u, ok=ok, kp=kp, kd=kd, n=n, Ginv=Ginv,
             friction=dm.Fv is not None)
    return sol


def _check(B: sp.Matrix, rhs: sp.Matrix, J: sp.Matrix, Jdq: sp.Matrix, a: sp.Matrix) -> bool:
    """J q̈ + J̇ q̇ = a with q̈ = B⁻¹ rhs from the model, at random rational points (40 digits)."""
    import random
    rng = random.Random(5)
    syms = sorted(set().union(*(x.free_symbols for x in list(B) + list(rhs) + list(a))), key=str)
    for _ in range(3):
        at = {s: sp.Rational(rng.randint(2, 19), rng.randint(3, 9)) for s in syms}
        Bn = B.xreplace(at).evalf(40)
        ddq = Bn.LUsolve(rhs.xreplace(at).evalf(40))
        res = (J.xreplace(at) * ddq + Jdq.xreplace(at) - a.xreplace(at)).evalf(40)
        if any(abs(complex(x)) > 1e-25 for x in res):
            return False
    return True
