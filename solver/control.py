"""Joint-space control laws built on the dynamic model (ask kind ``control_law``).

    model:             B(q) q̈ + c(q, q̇) + g(q) (+ F_v q̇) = G u
    computed_torque:   G u = B(q) (q̈_d + K_D ė + K_P e) + c(q, q̇) + g(q) (+ F_v q̇),   e = q_d − q
                       => B (ë + K_D ė + K_P e) = 0  => ë + K_D ė + K_P e = 0 (B is positive definite)
    pd_gravity:        G u = K_P e − K_D q̇ + g(q)   (constant q_d)
                       => B q̈ + c + (F_v +) K_D q̇ − K_P e = 0, with (q_d, 0) the unique equilibrium

Gains are diagonal, K_P = diag(kp1..kpn), K_D = diag(kd1..kdn), symbolic by default (``kp:``/``kd:`` give them);
the desired trajectory is q_d = (qd1..), q̇_d = (dqd1..), q̈_d = (ddqd1..) (one per coordinate name: q1 -> qd1,
theta1 -> thetad1), or q_d from ``qd:`` for regulation. Symbols created here are added to the problem's names
(so that answers can use them) and never clash with the problem's own names.
"""
from __future__ import annotations

from typing import Any, Literal, Optional, Union

import sympy as sp
from pydantic import Field

from .dynamics import derive, require_model
from .errors import UserError
from .registry import PropertyVerdict, ask_kind, property_check
from .results import Solution
from .simplify import is_zero, tidy
from .spec import Strict

ExprT = Union[str, int, float, list[Any]]
LAWS = {"computed_torque": "computed torque (feedback linearization in joint space)",
        "pd_gravity": "PD with gravity compensation"}


class ControlLawAsk(Strict):
    """A joint-space control law for the robot's dynamic model, with its closed-loop dynamics."""

    kind: Literal["control_law"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    law: Literal["computed_torque", "pd_gravity"] = Field(
        "computed_torque", description="computed_torque: u = B(q)(ddq_d + K_D de + K_P e) + c + g (+ F_v dq); "
                                       "pd_gravity: u = K_P e - K_D dq + g(q) (constant q_d)")
    kp: Optional[ExprT] = Field(None, description="proportional gains: one expression (same for every joint) or a "
                                                  "list of n (diagonal of K_P); default kp1..kpn")
    kd: Optional[ExprT] = Field(None, description="derivative gains, as kp; default kd1..kdn")
    qd: Optional[ExprT] = Field(None, description="a constant desired configuration (list of n expressions); "
                                                  "default qd1..qdn")
    regulation: bool = Field(False, description="computed_torque only: constant q_d (dq_d = ddq_d = 0)")


def _fresh(problem, base: str) -> str:  # type: ignore[no-untyped-def]
    """``base`` or, if taken by the problem, ``base`` + c, cc, ..."""
    mine = problem.__dict__.setdefault("_control_names", set())
    name = base
    while name in problem.names and name not in mine:
        name += "c"
    mine.add(name)
    return name


def _symbol(problem, name: str, tex: str) -> sp.Symbol:  # type: ignore[no-untyped-def]
    """A real symbol registered in the problem's names (answers and reports can use it)."""
    name = _fresh(problem, name)
    s = sp.Symbol(name, real=True)
    problem.names.setdefault(name, s)
    problem.latex_names.setdefault(s, tex)
    return s


def _sub_tex(tex: str, sub: str) -> str:
    head, _, tail = tex.partition("_")
    tail = tail.strip("{}")
    return f"{head}_{{{sub}{',' if tail and sub else ''}{tail}}}" if (tail or sub) else head


def _gains(problem, options: ControlLawAsk, ctx, key: str, n: int, pos: bool) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    q = problem.robot.q
    if getattr(options, key) is None:
        syms = []
        for i, qi in enumerate(q):
            s = sp.Symbol(_fresh(problem, f"{key}{i + 1}"), positive=True)
            problem.names.setdefault(s.name, s)
            problem.latex_names.setdefault(s, f"k_{{{key[1].upper()},{i + 1}}}")
            syms.append(s)
        return syms
    val = ctx.expr(key)
    vals = val if isinstance(val, list) else [val] * n
    if len(vals) != n or any(isinstance(v, list) for v in vals):
        raise UserError(f"{key} must be one expression or a list of {n} (the diagonal of K_{key[1].upper()})",
                        problem.located.place(ctx.path + (key,)), f"write e.g. {key}: 100 or {key}: [100, 50]")
    return [sp.sympify(v) for v in vals]


def _input_inverse(problem, dm, ctx, law: str) -> sp.Matrix | None:  # type: ignore[no-untyped-def]
    G = dm.G
    if G is None:
        return None
    place = problem.located.place(ctx.path + ("law",))
    if G.rows != G.cols:
        raise UserError(f"{law} needs a square input map G (one input per generalized coordinate), but G is "
                        f"{G.rows}x{G.cols}: the robot is underactuated", place,
                        "this law cannot assign every joint acceleration; remove the ask or the input_map")
    det = sp.simplify(G.det())
    if det == 0:
        raise UserError(f"{law} needs an invertible input map G, but det G = 0", place,
                        "check robot.input_map")
    return G.inv().applyfunc(sp.simplify)


def _zero(x: sp.Expr) -> bool:
    z = is_zero(sp.expand(x))
    if z is None:
        z = sp.simplify(x) == 0
    return bool(z)


def reference_law(problem, law: str, dm, K: dict) -> tuple[sp.Matrix, sp.Matrix]:  # type: ignore[no-untyped-def]
    """(tau, v): the generalized forces of the law and, for computed torque, the commanded acceleration v."""
    robot = problem.robot
    dq = sp.Matrix(robot.dq)
    e, de = K["qd"] - sp.Matrix(robot.q), K["dqd"] - dq
    KP, KD = sp.diag(*K["kp"]), sp.diag(*K["kd"])
    fr = dm.Fv * dq if dm.Fv is not None else sp.zeros(robot.n, 1)
    if law == "computed_torque":
        v = K["ddqd"] + KD * de + KP * e
        return dm.B * v + dm.c + dm.g + fr, v
    return KP * e - KD * dq + dm.g, KP * e - KD * dq


@ask_kind("control_law", ControlLawAsk,
          "joint-space control law (computed torque, PD + gravity compensation) and its closed-loop dynamics")
def solve_control_law(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: u, closed_loop, closed_loop_check; pd_gravity also equilibrium_check."""
    robot = require_model(problem)
    dm = derive(robot)
    n = robot.n
    law = options.law
    Ginv = _input_inverse(problem, dm, ctx, law)
    q, dq, ddq = sp.Matrix(robot.q), sp.Matrix(robot.dq), sp.Matrix(robot.ddq)
    regulation = law == "pd_gravity" or options.regulation
    if options.qd is not None:
        if not regulation:
            raise UserError("qd: (a constant desired configuration) needs regulation: true",
                            problem.located.place(ctx.path + ("qd",)), "add regulation: true, or remove qd:")
        val = ctx.expr("qd")
        vals = val if isinstance(val, list) else [val]
        if len(vals) != n or any(isinstance(v, list) for v in vals):
            raise UserError(f"qd must be a list of {n} expressions", problem.located.place(ctx.path + ("qd",)))
        qd = sp.Matrix([sp.sympify(v) for v in vals])
    else:
        qd = sp.Matrix([_symbol(problem, _qname(s.name, "d"), _sub_tex(problem.latex_names.get(s, s.name), "d"))
                        for s in robot.q])
    if regulation:
        dqd = ddqd = sp.zeros(n, 1)
    else:
        dqd = sp.Matrix([_symbol(problem, "d" + _qname(s.name, "d"),
                                 "\\dot " + _sub_tex(problem.latex_names.get(s, s.name), "d")) for s in robot.q])
        ddqd = sp.Matrix([_symbol(problem, "dd" + _qname(s.name, "d"),
                                  "\\ddot " + _sub_tex(problem.latex_names.get(s, s.name), "d")) for s in robot.q])
    kp = _gains(problem, options, ctx, "kp", n, True)
    kd = _gains(problem, options, ctx, "kd", n, True)
    K = {"qd": qd, "dqd": dqd, "ddqd": ddqd, "kp": kp, "kd": kd}
    tau, v = reference_law(problem, law, dm, K)
    u = (Ginv * tau) if Ginv is not None else tau
    u = u.applyfunc(lambda x: sp.collect(sp.expand(x), kp + kd, func=tidy) if Ginv is None else tidy(x))
    G = dm.G if dm.G is not None else sp.eye(n)
    fr = dm.Fv * dq if dm.Fv is not None else sp.zeros(n, 1)
    nvec = dm.c + dm.g + fr
    e, de, dde = qd - q, dqd - dq, ddqd - ddq
    KP, KD = sp.diag(*kp), sp.diag(*kd)
    if law == "computed_torque":
        closed = dde + KD * de + KP * e
        # along the closed loop B q̈ + n = G u, so B (ë + K_D ė + K_P e) = B (q̈_d + K_D ė + K_P e) - (G u - n)
        residual = dm.B * (ddqd + KD * de + KP * e) - (G * u - nvec)
    else:
        closed = dm.B * ddq + dm.c + fr + KD * dq - KP * e
        residual = (dm.B * ddq + nvec - G * u) - closed
    ok = all(_zero(x) for x in residual)
    sol = Solution("control_law", title=options.title or f"Control law: {LAWS[law]}")
    sol.add("u", u, "vector", label="u")
    sol.add("closed_loop", closed.applyfunc(sp.expand), "vector",
            label="\\ddot e + K_D\\dot e + K_P e" if law == "computed_torque"
            else "B(q)\\ddot q + c(q,\\dot q) + K_D\\dot q - K_P e")
    sol.add("closed_loop_check", bool(ok), "bool", label="\\text{closed loop verified}")
    eq_ok = None
    if law == "pd_gravity":
        at = {**{a: b for a, b in zip(robot.q, qd)}, **{s: 0 for s in robot.dq + robot.ddq}}
        eq_ok = all(_zero(x.xreplace(at)) for x in closed)
        sol.add("equilibrium_check", bool(eq_ok), "bool", label="(q_d, 0) \\text{ equilibrium}")
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("law", law=law, KP=KP, KD=KD, qd=qd, dqd=dqd, ddqd=ddqd, v=v, tau=tau, u=u, Ginv=Ginv,
             regulation=regulation, e=e, friction=dm.Fv is not None)
    sol.step("closed_loop", law=law, closed=closed, ok=ok, eq_ok=eq_ok, kp=kp, kd=kd, n=n, friction=dm.Fv is not None,
             skew=dm.skew)
    return sol


def _qname(name: str, mark: str) -> str:
    """q1 -> qd1, theta1 -> thetad1, x -> xd."""
    head = name.rstrip("0123456789")
    return head + mark + name[len(head):]


# ------------------------------------------------------------------------------------------------ grading
def _control_ask(problem):  # type: ignore[no-untyped-def]
    for a in problem.asks:
        if a.kind == "control_law":
            return a
    return None


@property_check("u")
def check_control_law(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Computed torque: u is right iff the closed loop it gives is q̈ ≡ q̈_d + K_D ė + K_P e, i.e.
    B⁻¹ G (u − u_ref) ≡ 0 (checked on adj(B) G (u − u_ref)); names the closed-loop equations that fail and a missing
    c or g term. Other laws: None (compare with the reference)."""
    from .equivalence import scalar_equiv
    ask, ref = _control_ask(problem), results.get("u")
    robot = problem.robot
    if ask is None or ref is None or robot is None or ask.options.law != "computed_torque":
        return None
    try:
        U = sp.Matrix(value) if isinstance(value, list) else sp.Matrix([value])
    except (ValueError, TypeError, sp.ShapeError):
        return None
    n = robot.n
    if U.shape == (1, n):
        U = U.T
    if U.shape != (n, 1):
        return PropertyVerdict(False, 0.0, [f"u must have {n} components (one per joint), not {len(U)}"])
    d = U - ref.value
    if all(scalar_equiv(x, 0).ok for x in d):
        return PropertyVerdict(True, 1.0, ["substituted in the model, u gives q̈ = q̈_d + K_D ė + K_P e: the closed "
                                           "loop is ë + K_D ė + K_P e = 0 (exact linearization and decoupling)"])
    dm = derive(robot)
    G = dm.G if dm.G is not None else sp.eye(n)
    acc = dm.B.adjugate() * (G * d)  # det(B) (q̈ − q̈_ref)
    bad = [str(i + 1) for i, x in enumerate(acc) if not scalar_equiv(x, 0).ok]
    fb = ["substituted in the model B q̈ + c + g = u, this u does not give ë + K_D ė + K_P e = 0: closed-loop "
          "equation(s) " + ", ".join(bad or ["?"]) + " fail (the joint accelerations are not q̈_d + K_D ė + K_P e)"]
    Gd = G * d
    for term, label in ((dm.c, "the Coriolis/centrifugal term c(q, q̇)"), (dm.g, "the gravity term g(q)")):
        if any(x != 0 for x in term) and all(scalar_equiv(x + t, 0).ok for x, t in zip(Gd, term)):
            fb.append(f"{label} is missing")
        elif any(x != 0 for x in term) and all(scalar_equiv(x - t, 0).ok for x, t in zip(Gd, term)):
            fb.append(f"{label} is counted twice (or with the wrong sign)")
    return PropertyVerdict(False, 0.0, fb, final=False)
