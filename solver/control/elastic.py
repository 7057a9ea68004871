"""Feedback linearization of robots with elastic joints (``control_law`` with ``law: elastic``).

The coordinates are the link positions q (rows of G that are zero: no input) and the motor positions θ (the
actuated rows). Reduced model (Spong): the link equations contain neither θ̈ nor θ̇,
    B(q) q̈ + n(q, q̇) + e(q − θ) = 0,          B_m θ̈ (+ M_θq q̈) + n_θ(q, θ, q̇, θ̇) = G_m u,
with e the elastic torque (K(q − θ) for linear springs, any invertible ∂e/∂θ otherwise). With the output y = q:
    ÿ = f₂(q, θ, q̇) = −B⁻¹(n + e),   y⁽³⁾ = f₃(q, θ, q̇, θ̇) = ∂f₂/∂q q̇ + ∂f₂/∂θ θ̇ + ∂f₂/∂q̇ f₂   (jerk),
    y⁽⁴⁾ = α(x) + β(x) u   (snap),   β = ∂f₃/∂θ̇ B_m⁻¹ G_m   (the decoupling matrix, −B⁻¹ ∂e/∂θ B_m⁻¹ G_m),
so u = β⁻¹(v − α) gives y⁽⁴⁾ = v (relative degree 4 for every output, no zero dynamics) and
    v = y_d⁽⁴⁾ + K₃(y_d⁽³⁾ − y⁽³⁾) + K₂(ÿ_d − ÿ) + K₁(ẏ_d − ẏ) + K₀(y_d − y)
gives e⁽⁴⁾ + K₃e⁽³⁾ + K₂ë + K₁ė + K₀e = 0. With linear springs also θ = q + K⁻¹(B q̈ + n), and u written in the
linearizing coordinates (q, q̇, q̈, q⃛) and q⁽⁴⁾ = v (Spong's form): u = G_m⁻¹[B_m θ̈ + K(θ − q)].
"""
from __future__ import annotations

import random
from dataclasses import dataclass

import sympy as sp

from solver.control.laws import (
    ControlLawAsk,
    _qname,
    _sub_tex,
    _symbol,
    _zero,
    listed_values,
    record_law,
)
from solver.dynamics.model import derive, require_model
from solver.math.simplify import factor_within, tidy
from solver.results import Solution
from solver.spec.errors import UserError


def _time_derivative(f: sp.Expr, x: list, xdot: list) -> sp.Expr:
    return sum((sp.diff(f, a) * b for a, b in zip(x, xdot)), sp.Integer(0))


@dataclass
class ElasticInputs:
    """The options of ``law: elastic`` as read: the motor (actuated) and link coordinates (indices), G_m, and the
    q_d and gains K₀..K₃ given (None: not given)."""

    mot: list[int]
    lnk: list[int]
    Gm: sp.Matrix
    yd: list[sp.Expr] | None
    K: list[list[sp.Expr]] | None


def read_elastic(problem, options: ControlLawAsk, ctx) -> ElasticInputs:  # type: ignore[no-untyped-def]
    """The options of ``law: elastic`` read and checked without the model (``check`` runs it, and
    :func:`solve_elastic` first): the input map (one motor per link coordinate), qd: (one per link) and gains:."""
    from solver.control.underactuated import split_inputs
    robot = require_model(problem)
    mot, lnk, Gm = split_inputs(problem, robot.input_map, robot.n, ctx, "elastic")
    if len(mot) != len(lnk):
        raise UserError(f"law: elastic needs one motor per link coordinate ({len(mot)} actuated, {len(lnk)} passive "
                        f"coordinates)", problem.located.place(ctx.path + ("law",)),
                        "check robot.coordinates and input_map")
    yd = listed_values(problem, ctx, "qd", len(lnk), "one per link") if options.qd is not None else None
    return ElasticInputs(mot, lnk, Gm, yd, _read_gains(problem, options, ctx, len(lnk)))


def solve_elastic(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: ddy (ÿ as a function of the state), jerk, alpha, beta, det_beta, u, v_law, closed_loop_check;
    with linear springs also theta_y (θ(q, q̇, q̈)) and u_y (u in the linearizing coordinates)."""
    read = read_elastic(problem, options, ctx)
    robot = problem.robot
    dm = derive(robot)
    n = robot.n
    mot, lnk, Gm = read.mot, read.lnk, read.Gm
    place = problem.located.place(ctx.path + ("law",))
    X, dX, ddX = list(robot.q), list(robot.dq), list(robot.ddq)
    q = [X[i] for i in lnk]
    th = [X[i] for i in mot]
    dq, dth = [dX[i] for i in lnk], [dX[i] for i in mot]
    ddq_s = [ddX[i] for i in lnk]
    M = dm.B
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    nv = (dm.c + dm.g + Fv * sp.Matrix(dX)).applyfunc(sp.expand)
    ML, MLth = M.extract(lnk, lnk), M.extract(lnk, mot)
    nL = nv.extract(lnk, [0])
    if any(not _zero(x) for x in MLth) or any(not _zero(sp.diff(x, d)) for x in nL for d in dth):
        raise UserError("law: elastic needs the reduced model of elastic joints: the link equations must contain "
                        "neither the motor accelerations nor the motor velocities", place,
                        "neglect the angular kinetic energy of the rotors due to the link motion (Spong's "
                        "assumption): give the motors' kinetic energy as 1/2*Im*dtheta^2 only")
    if all(_zero(sp.diff(x, t)) for x in nL for t in th):
        raise UserError("law: elastic: the link equations do not depend on the motor positions (no elastic "
                        "coupling)", place)
    MLi = (ML.adjugate() / factor_within(ML.det())).applyfunc(sp.simplify)
    f2 = (-MLi * nL).applyfunc(tidy)
    state = q + th + dq + dth
    f3 = sp.Matrix([_light(_time_derivative(x, q + th + dq, dq + dth + list(f2))) for x in f2])
    Mth, MthL = M.extract(mot, mot), M.extract(mot, lnk)
    nth = nv.extract(mot, [0])
    Mthi = (Mth.adjugate() / factor_within(Mth.det())).applyfunc(sp.simplify)
    # only the θ̇ term of f3 = ∂f2/∂q q̇ + ∂f2/∂θ θ̇ + ∂f2/∂q̇ f2 contains θ̇: β = ∂f2/∂θ B_m⁻¹ G_m
    ddth0 = Mthi * (-nth - MthL * f2)
    alpha = sp.Matrix([_light(_time_derivative(x, state, dq + dth + list(f2) + list(ddth0))) for x in f3])
    beta = (f2.jacobian(th) * Mthi * Gm).applyfunc(tidy)
    detb = factor_within(sp.simplify(beta.det()))
    if _zero(detb):
        raise UserError("law: elastic: the decoupling matrix of y⁽⁴⁾ is singular (the motors do not reach the "
                        "link accelerations through the springs)", place)
    # the desired output and the gains
    tex = [problem.latex_names.get(s, s.name) for s in q]
    if options.regulation or options.qd is not None:
        if read.yd is not None:
            yd = read.yd
        else:
            yd = [_symbol(problem, _qname(s.name, "d"), _sub_tex(t, "d")) for s, t in zip(q, tex)]
        yds = [yd] + [[sp.Integer(0)] * len(q) for _ in range(4)]
    else:
        yds = [[_symbol(problem, pre + _qname(s.name, "d"), acc + _sub_tex(t, "d") + post) for s, t in zip(q, tex)]
               for pre, acc, post in (("", "", ""), ("d", "\\dot ", ""), ("dd", "\\ddot ", ""),
                                      ("ddd", "", "^{(3)}"), ("dddd", "", "^{(4)}"))]
    K = read.K if read.K is not None else _default_gains(problem, len(q))
    derivs = [sp.Matrix(q), sp.Matrix(dq), f2, f3]
    v_law = sp.Matrix(yds[4])
    for j in range(4):
        v_law += sp.diag(*K[j]) * (sp.Matrix(yds[j]) - derivs[j])
    v_law = v_law.applyfunc(_light)
    beta_inv = (beta.adjugate() / detb).applyfunc(tidy)
    vs = sp.Matrix([_symbol(problem, f"v{i + 1}", f"v_{{{i + 1}}}") for i in range(len(q))])
    u_v = (beta_inv * (vs - alpha)).applyfunc(_light)
    ok = _check(M, nv, dm.G, X, dX, lnk, f2, f3, u_v, vs, problem)
    record_law(problem, options.suffix, q, [[yds[j][i] for j in range(5)] for i in range(len(q))],
               list(yds[0]) if options.qd is not None else None, subs=dict(zip(vs, v_law)))
    sol = Solution("control_law", title=options.title or "Feedback linearization of the elastic-joint robot")
    sol.add("ddy", f2, "vector", label="\\ddot q = f_2(q,\\theta,\\dot q)")
    sol.add("jerk", f3, "vector", label="q^{(3)}")
    sol.add("alpha", alpha, "vector", label="\\alpha(x)")
    sol.add("beta", beta, "matrix", label="\\beta(x)")
    sol.add("det_beta", detb, "scalar", label="\\det\\beta")
    sol.add("u", u_v, "vector", label="u")
    sol.add("v_law", v_law, "vector", label="v")
    theta_y = u_y = None
    lin_th = all(_zero(sp.diff(x, a, b)) for x in nL for a in th for b in th)
    if lin_th:
        # θ(q, q̇, q̈) from the link equations, then u in the linearizing coordinates
        d3 = [_symbol(problem, "ddd" + s.name, f"{t}^{{(3)}}") for s, t in zip(q, tex)]
        d4 = [_symbol(problem, "dddd" + s.name, f"{t}^{{(4)}}") for s, t in zip(q, tex)]
        EL = (ML * sp.Matrix(ddq_s) + nL)
        Jth = EL.jacobian(th)
        sol_th = (-(Jth.adjugate() / factor_within(Jth.det())) * EL.xreplace({t: 0 for t in th})).applyfunc(_light)
        theta_y = sol_th
        lin_vars = q + dq + ddq_s + d3
        dth_y = sp.Matrix([_time_derivative(x, lin_vars, dq + ddq_s + d3 + d4) for x in sol_th])
        ddth_y = sp.Matrix([_time_derivative(x, lin_vars, dq + ddq_s + d3 + d4) for x in dth_y])
        sub = dict(zip(th, sol_th)) | dict(zip(dth, dth_y))
        rhs = Mth * ddth_y + MthL * sp.Matrix(ddq_s) + nth.xreplace(sub)
        Gmi = (Gm.adjugate() / factor_within(Gm.det())).applyfunc(sp.simplify)
        u_y = (Gmi * rhs).applyfunc(_light)
        sol.add("theta_y", theta_y, "vector", label="\\theta(q,\\dot q,\\ddot q)")
        sol.add("u_y", u_y, "vector", label="u(q,\\dot q,\\ddot q,q^{(3)},q^{(4)})")
    sol.add("closed_loop_check", bool(ok), "bool", label="q^{(4)} = v \\text{ verified}")
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("elastic", q=sp.Matrix(q), theta=sp.Matrix(th), f2=f2, f3=f3, alpha=alpha, beta=beta, detb=detb,
             v=vs, u=u_v, v_law=v_law, K=[sp.diag(*k) for k in K], regulation=options.regulation,
             theta_y=theta_y, u_y=u_y, ok=ok, small=sum(sp.count_ops(x) for x in u_v) < 400,
             alpha_small=sum(sp.count_ops(x) for x in alpha) < 400)
    return sol


def _default_gains(problem, m: int) -> list[list[sp.Symbol]]:  # type: ignore[no-untyped-def]
    """The default K₀..K₃: diagonal, symbols k0_1.. (positive; Hurwitz s⁴ + k3 s³ + k2 s² + k1 s + k0 is the
    designer's choice)."""
    return [[_pos(problem, f"k{j}_{i + 1}", f"k_{{{j},{i + 1}}}") for i in range(m)] for j in range(4)]


def _read_gains(problem, options: ControlLawAsk, ctx, m: int) -> list[list[sp.Expr]] | None:  # type: ignore[no-untyped-def]
    """The diagonals of K₀..K₃ of ``gains:`` (each one expression or m), None when not given."""
    if options.gains is None:
        return None
    place = problem.located.place(ctx.path + ("gains",))
    if len(options.gains) != 4:
        raise UserError("gains must be [k0, k1, k2, k3] (each one expression or a list of one per link)", place)
    out = []
    for j in range(4):
        val = ctx.expr("gains", j)
        vals = val if isinstance(val, list) else [val] * m
        if len(vals) != m:
            raise UserError(f"gains[{j}] must be one expression or a list of {m}", place)
        out.append([sp.sympify(x) for x in vals])
    return out


def _pos(problem, name: str, tex: str) -> sp.Symbol:  # type: ignore[no-untyped-def]
    s = _symbol(problem, name, tex)
    p = sp.Symbol(s.name, positive=True)
    problem.names[s.name] = p
    problem.latex_names[p] = tex
    return p


def _check(M, nv, G, X, dX, lnk, f2, f3, u_v, vs, problem) -> bool:  # type: ignore[no-untyped-def]
    """y⁽⁴⁾ = v along the full model M ẍ + n = G u under the law, at random rational states and parameters: ÿ from
    the model equals f₂, and dy⁽³⁾/dt with ẍ from the model equals v."""
    rng = random.Random(11)
    syms = sorted((M.free_symbols | nv.free_symbols | set().union(*(x.free_symbols for x in u_v))) - set(vs),
                  key=str)
    for _ in range(2):
        at = {s: sp.Rational(rng.randint(3, 17), rng.randint(4, 9)) for s in syms}
        at |= {v: sp.Rational(rng.randint(-9, 9), 7) for v in vs}
        U = u_v.xreplace(at)
        Mn, nn = M.xreplace(at), nv.xreplace(at)
        ddx = Mn.LUsolve((G.xreplace(at) if G is not None else sp.eye(M.rows)) * U - nn)
        if any(_big(ddx[i] - f2[k].xreplace(at)) for k, i in enumerate(lnk)):
            return False
        for k in range(len(lnk)):
            d4 = sum((sp.diff(f3[k], a).xreplace(at) * b.xreplace(at) for a, b in zip(X, dX)), sp.Integer(0))
            d4 += sum((sp.diff(f3[k], a).xreplace(at) * ddx[j] for j, a in enumerate(dX)), sp.Integer(0))
            if _big(d4 - vs[k].xreplace(at)):
                return False
    return True


def _big(x: sp.Expr) -> bool:
    """|x| > 1e-20 in 40-digit arithmetic (x is a number built from rationals and functions of them)."""
    return abs(complex(sp.N(x, 40))) > 1e-20


def _light(x: sp.Expr) -> sp.Expr:
    """tidy for short expressions; long ones (jerk, snap of several links) are left as derived."""
    return tidy(x) if sp.count_ops(x) < 250 else x
