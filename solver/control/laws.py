"""Joint-space control laws built on the dynamic model (ask kind ``control_law``).

    model:             B(q) q̈ + c(q, q̇) + g(q) (+ F_v q̇) = G u
    computed_torque:   G u = B(q) (q̈_d + K_D ė + K_P e) + c(q, q̇) + g(q) (+ F_v q̇),   e = q_d − q
                       => B (ë + K_D ė + K_P e) = 0  => ë + K_D ė + K_P e = 0 (B is positive definite)
    pd_gravity:        G u = K_P e − K_D q̇ + g(q)   (constant q_d)
                       => B q̈ + c + (F_v +) K_D q̇ − K_P e = 0, with (q_d, 0) the unique equilibrium
    adaptive:          G u = Y_r â + K_D s, â̇ = Γ Y_rᵀ s (Slotine-Li); partly adaptive G u = Y_K a_K + Y_U â_U + K_D s,
                       â̇_U = Γ Y_Uᵀ s; the split and the Lyapunov function V with its checked V̇: control/adaptive.py

Gains are diagonal, K_P = diag(kp1..kpn), K_D = diag(kd1..kdn), symbolic by default (``kp:``/``kd:`` give them);
the desired trajectory is q_d = (qd1..), q̇_d = (dqd1..), q̈_d = (ddqd1..) (one per coordinate name: q1 -> qd1,
theta1 -> thetad1), or q_d from ``qd:`` for regulation. Symbols created here are added to the problem's names
(so that answers can use them) and never clash with the problem's own names.
"""
from __future__ import annotations

from typing import Any, Literal, Optional, Union

import sympy as sp
from pydantic import Field

from solver.dynamics.model import derive, require_model
from solver.math.equivalence import identically_zero as _zero
from solver.math.simplify import expand_polynomial, tidy
from solver.registry import PROPERTY_CHECKS, PropertyVerdict, ask_kind, property_check
from solver.results import Result, Solution
from solver.spec.errors import UserError
from solver.spec.models import Strict

ExprT = Union[str, int, float, list[Any]]
LAWS = {"computed_torque": "computed torque (feedback linearization in joint space)",
        "pd_gravity": "PD with gravity compensation",
        "pd_constant": "PD with constant gravity compensation g(q_d)",
        "lyapunov_tracking": "Lyapunov-based tracking (passivity, without cancellation)",
        "adaptive": "adaptive control (Slotine-Li)",
        "cartesian_computed_torque": "computed torque in the Cartesian space",
        "elastic": "feedback linearization of a robot with elastic joints",
        "partial_fbl": "partial feedback linearization of an underactuated robot",
        "linearization": "linear approximation at an equilibrium and its controllability"}
JOINT_LAWS = ("computed_torque", "pd_gravity", "pd_constant", "adaptive", "lyapunov_tracking")


class ControlLawAsk(Strict):
    """A joint-space control law for the robot's dynamic model, with its closed-loop dynamics."""

    kind: Literal["control_law"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    law: Literal["computed_torque", "pd_gravity", "pd_constant", "adaptive", "lyapunov_tracking", "cartesian_computed_torque", "elastic",
                 "partial_fbl", "linearization"] = Field(
        "computed_torque", description="computed_torque: u = B(q)(ddq_d + K_D de + K_P e) + c + g (+ F_v dq); "
                                       "pd_gravity: u = K_P e - K_D dq + g(q) (constant q_d); "
                                       "pd_constant: u = K_P e - K_D dq + g(q_d) (constant q_d); "
                                       "lyapunov_tracking: u = B(q) ddq_d + S(q, dq) dq_d + g + K_D de + K_P e; "
                                       "cartesian_computed_torque: u = B a + c + g, a = J^-1 (a_r - dJ dq), "
                                       "a_r = ddr_d + K_D(dr_d - J dq) + K_P(r_d - r), r = task(q); for m < n "
                                       "a = J^# (a_r - dJ dq) + (I - J^# J) a_0; frame: R rotates the error; "
                                       "elastic: feedback linearization of the reduced model of elastic joints "
                                       "(link output, 4th order, jerk and snap); "
                                       "partial_fbl: collocated (actuated coordinates) or non-collocated (passive "
                                       "coordinates) partial feedback linearization of an underactuated robot; "
                                       "linearization: linear approximation at an equilibrium, controllability; "
                                       "adaptive (Slotine-Li): u = Y(q, dq, dq_r, ddq_r) ahat + K_D s, "
                                       "dahat = Gamma Y^T s, s = dq_r - dq, dq_r = dq_d + Lambda e")
    kp: Optional[ExprT] = Field(None, description="proportional gains: one expression (same for every joint) or a "
                                                  "list of n (diagonal of K_P); default kp1..kpn")
    kd: Optional[ExprT] = Field(None, description="derivative gains, as kp; default kd1..kdn")
    qd: Optional[ExprT] = Field(None, description="a constant desired configuration (list of n expressions); "
                                                  "default qd1..qdn")
    regulation: bool = Field(False, description="computed_torque, adaptive: constant q_d (dq_d = ddq_d = 0)")
    lam: Optional[ExprT] = Field(None, alias="lambda",
                                 description="adaptive: Lambda, as kp (diagonal); default lambda1..lambdan")
    gamma: Optional[ExprT] = Field(None, description="adaptive: Gamma, one expression, a list of p (diagonal of "
                                                     "the adaptation gain) or a p x p symmetric positive definite "
                                                     "matrix; default gamma1..gammap")
    task: Optional[ExprT] = Field(None, description="cartesian_computed_torque: the task r = f(q) (a list of m <= n "
                                                    "expressions; J = df/dq, inverted (m = n) or pseudoinverted)")
    frame: Optional[ExprT] = Field(None, description="cartesian_computed_torque: a constant rotation R (m x m, or an "
                                                     "angle for a 2-D task) of the frame of the task error: "
                                                     "e_t = R^T (r_d - r), a = J^-1 (R a_t - dJ dq)")
    null: Optional[ExprT] = Field(None, description="cartesian_computed_torque, m < n: the preferred joint "
                                                    "acceleration a_0 (n expressions) projected in the null space "
                                                    "of J (quote the key: \"null\":)")
    damping: Optional[ExprT] = Field(None, description="cartesian_computed_torque, m < n: K_v (scalar, n diagonal "
                                                       "entries or n x n): -K_v dq is added to a_0")
    gradient: Optional[Union[str, int, float]] = Field(
        None, description="cartesian_computed_torque, m < n: H(q) (or manipulability, joint_range as in the "
                          "redundancy ask): step * grad H is added to a_0")
    step: Optional[Union[str, int, float]] = Field(None, description="the step along grad H (negative: the "
                                                                     "anti-gradient); default 1")
    joint_ranges: Optional[dict[str, tuple[Union[str, int, float], Union[str, int, float]]]] = Field(
        None, description="{q1: [min, max], ...} for gradient: joint_range")
    rd: Optional[ExprT] = Field(None, description="cartesian_computed_torque: a constant desired task value r_d "
                                                  "(needs regulation: true); default symbols rd1.., drd1.., ddrd1..")
    collocated: bool = Field(True, description="partial_fbl: true linearizes the actuated coordinates "
                                               "(ddq_a = v), false the passive ones (ddq_p = v, needs the "
                                               "inertial coupling M_pa of full row rank)")
    gains: Optional[list[ExprT]] = Field(None, description="elastic: the gains [k0, k1, k2, k3] of v = y_d^(4) + "
                                                           "K3 (y_d^(3) - y^(3)) + ... + K0 (y_d - y) (each one "
                                                           "expression or a diagonal list; default symbols)")
    equilibrium: Optional[dict[str, ExprT]] = Field(None, description="linearization: the equilibrium "
                                                                      "configuration {q1: .., q2: ..} (at rest)")
    at: Optional[dict[str, ExprT]] = Field(None, description="joint-space laws: values of names (q1, dq1, qd1, dqd1, "
                                                            "ddqd1, parameters) where u is evaluated (u_at)")
    parametrization: Optional[str] = Field(
        None, pattern=r"^[A-Za-z0-9_]*$",
        description="adaptive: the suffix of the linear_parametrization ask whose Y and a the law uses (\"\" for "
                    "the one without suffix); default the first one of the whole model (part: model). With a "
                    "parametrization of a part of the model (part: gravity or inertia) only its coefficients are "
                    "estimated and the rest of the model is compensated with its known value")
    known_coefficients: Optional[ExprT] = Field(
        None, description="adaptive: the coefficients of the parametrization (expressions, as written in its "
                          "coefficients:) whose values are known: compensated exactly (Y_K a_K), not estimated; "
                          "only the others are updated (a partly adaptive law)")
    lyapunov: Optional[Literal["slotine_li", "with_e"]] = Field(
        None, description="adaptive: the Lyapunov function; slotine_li (default): V = 1/2 s^T B s + 1/2 atilde^T "
                          "Gamma^-1 atilde, dV = -s^T K_D s; with_e: V + e^T K_P e with K_P = K_D Lambda (the form "
                          "of u = Y ahat + K_P e + K_D de), dV = -de^T K_D de - e^T Lambda K_D Lambda e")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$",
                        description="appended to every result name (several control asks in one problem)")


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


GAINS = {"kp": ("kp", "kp", "k_{{P,{i}}}", "K_P"), "kd": ("kd", "kd", "k_{{D,{i}}}", "K_D"),
         "lam": ("lambda", "lambda", "\\lambda_{{{i}}}", "Lambda"), "gamma": ("gamma", "gamma", "\\gamma_{{{i}}}", "Gamma")}


def _gains(problem, options: ControlLawAsk, ctx, key: str, n: int, pos: bool) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """The diagonal of a gain matrix: n positive symbols (default) or the ask's value (one or n expressions)."""
    vals = _gain_values(problem, options, ctx, key, n)
    return vals if vals is not None else _gain_symbols(problem, key, n)


def _gain_symbols(problem, key: str, n: int) -> list[sp.Symbol]:  # type: ignore[no-untyped-def]
    """The default diagonal of a gain matrix: n positive symbols registered in the problem's names."""
    _, base, tex, _ = GAINS[key]
    return [_gain_symbol(problem, f"{base}{i + 1}", tex.format(i=i + 1)) for i in range(n)]


def _gain_values(problem, options: ControlLawAsk, ctx, key: str, n: int) -> list[sp.Expr] | None:  # type: ignore[no-untyped-def]
    """The ask's diagonal of a gain matrix (one expression or a list of n), None when not given."""
    yaml_key, _, _, label = GAINS[key]
    if getattr(options, key) is None:
        return None
    val = ctx.expr(yaml_key)
    vals = val if isinstance(val, list) else [val] * n
    if len(vals) != n or any(isinstance(v, list) for v in vals):
        raise UserError(f"{yaml_key} must be one expression or a list of {n} (the diagonal of {label})",
                        problem.located.place(ctx.path + (yaml_key,)),
                        f"write e.g. {yaml_key}: 100 or {yaml_key}: [{', '.join(['100'] * n)}]")
    return [sp.sympify(v) for v in vals]


def listed_values(problem, ctx, key: str, count: int, what: str) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """The ``count`` expressions of a list option (one expression when count is 1), else a spec error
    "key must list count values (what)"."""
    val = ctx.expr(key)
    vals = val if isinstance(val, list) else [val]
    if len(vals) != count:
        raise UserError(f"{key} must list {count} values ({what})", problem.located.place(ctx.path + (key,)))
    return [sp.sympify(x) for x in vals]


def _gain_symbol(problem, name: str, tex: str) -> sp.Symbol:  # type: ignore[no-untyped-def]
    """A positive gain symbol registered in the problem's names."""
    s = sp.Symbol(_fresh(problem, name), positive=True)
    problem.names.setdefault(s.name, s)
    problem.latex_names.setdefault(s, tex)
    return s


def _gamma(problem, options: ControlLawAsk, ctx, p: int) -> sp.Matrix:  # type: ignore[no-untyped-def]
    """Γ: diagonal (default symbols, one expression, a list of p) or a p×p symmetric matrix (positive definite
    when numeric)."""
    val = ctx.expr("gamma") if options.gamma is not None else None
    if not (isinstance(val, list) and val and isinstance(val[0], list)):
        return sp.diag(*_gains(problem, options, ctx, "gamma", p, True))
    place = problem.located.place(ctx.path + ("gamma",))
    if len(val) != p or any(not isinstance(r, list) or len(r) != p for r in val):
        raise UserError(f"gamma as a matrix must be {p}x{p} (one row and column per dynamic coefficient)", place)
    Gam = sp.Matrix([[sp.sympify(x) for x in r] for r in val])
    if any(not _zero(x) for x in (Gam - Gam.T)):
        raise UserError("gamma must be symmetric", place, "write a symmetric positive definite matrix")
    if not Gam.free_symbols:
        import numpy as np
        ev = np.linalg.eigvalsh(np.array(Gam.evalf(), dtype=float))
        if ev.min() <= 0:
            raise UserError(f"gamma must be positive definite (smallest eigenvalue {ev.min():.4g})", place)
    return Gam


def record_law(problem, sfx: str, tracked: list, desired: list, qd: list | None = None, subs: dict | None = None,
               ahat: list | None = None, adot: sp.Matrix | None = None, true_a: list | None = None) -> None:  # type: ignore[no-untyped-def]
    """What ``simulate`` needs of a law: the tracked variables, per variable the symbols of the desired value and its
    derivatives (None where numeric or zero), the constant numeric q_d (if given), the substitutions that write u in
    the state (adaptive q̇_r, q̈_r; elastic v), the estimates and their update law, the true coefficients."""
    problem.__dict__["_law" + sfx] = {"kind": "control_law", "tracked": list(tracked),
                                      "desired": [[s if isinstance(s, sp.Symbol) else None for s in row]
                                                  for row in desired],
                                      "qd": qd, "subs": subs or {}, "ahat": list(ahat or []), "adot": adot,
                                      "true_a": true_a}


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
    if law == "lyapunov_tracking":
        frd = dm.Fv * K["dqd"] if dm.Fv is not None else sp.zeros(robot.n, 1)
        return dm.B * K["ddqd"] + dm.S * K["dqd"] + dm.g + frd + KD * de + KP * e, KD * de + KP * e
    if law == "pd_constant":
        gd = dm.g.xreplace(dict(zip(robot.q, K["qd"])))
        return KP * e - KD * dq + gd, KP * e - KD * dq
    return KP * e - KD * dq + dm.g, KP * e - KD * dq


def _check_options(problem, options: ControlLawAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """Every option given is one of the law's."""
    law = options.law
    allowed = {"cartesian_computed_torque": {"kp", "kd", "task", "rd", "regulation", "frame", "null", "damping",
                                             "gradient", "step", "joint_ranges", "at"},
               "partial_fbl": {"kp", "kd", "qd", "collocated"}, "elastic": {"gains", "regulation", "qd"},
               "linearization": {"equilibrium"}}
    opt_keys = {"lam": "lambda", "gamma": "gamma", "qd": "qd", "kp": "kp", "kd": "kd", "task": "task", "rd": "rd",
                "gains": "gains", "equilibrium": "equilibrium", "at": "at", "parametrization": "parametrization",
                "known_coefficients": "known_coefficients", "lyapunov": "lyapunov", "frame": "frame", "null": "null",
                "damping": "damping", "gradient": "gradient", "step": "step", "joint_ranges": "joint_ranges"}
    allowed["adaptive"] = {"kp", "kd", "qd", "regulation", "lam", "gamma", "parametrization", "known_coefficients",
                           "lyapunov"}
    mine = allowed.get(law, {"kp", "kd", "qd", "regulation", "lam", "gamma", "at"})
    for key, yk in opt_keys.items():
        if getattr(options, key) is not None and key not in mine:
            users = [k for k, v in allowed.items() if key in v and (k, key) != ("adaptive", "kp")] or \
                ["computed_torque", "adaptive"]
            raise UserError(f"{yk}: is not an option of law: {law} (it is one of law: {', '.join(users)})",
                            problem.located.place(ctx.path + (yk,)), "remove it")


def _joint_law_gains(problem, options: ControlLawAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The gains a joint-space law does not take."""
    law = options.law
    if law != "adaptive" and (options.lam is not None or options.gamma is not None):
        raise UserError("lambda: and gamma: are gains of law: adaptive", problem.located.place(ctx.path + ("law",)),
                        "write law: adaptive, or remove them")


def _desired_q(problem, options: ControlLawAsk, ctx, robot, regulation: bool) -> sp.Matrix | None:  # type: ignore[no-untyped-def]
    """The constant q_d of ``qd:`` (None: not given), which needs regulation; law: adaptive takes no kp:."""
    qd = None
    if options.qd is not None:
        if not regulation:
            raise UserError("qd: (a constant desired configuration) needs regulation: true",
                            problem.located.place(ctx.path + ("qd",)), "add regulation: true, or remove qd:")
        val = ctx.expr("qd")
        vals = val if isinstance(val, list) else [val]
        if len(vals) != robot.n or any(isinstance(v, list) for v in vals):
            raise UserError(f"qd must be a list of {robot.n} expressions", problem.located.place(ctx.path + ("qd",)))
        qd = sp.Matrix([sp.sympify(v) for v in vals])
    if options.law == "adaptive" and options.kp is not None:
        raise UserError("law: adaptive has no K_P (K_D s = K_D (de + Lambda e) is the PD action, K_P = K_D Lambda)",
                        problem.located.place(ctx.path + ("kp",)), "give lambda: and kd: instead")
    return qd


def validate_control_law(problem, options: ControlLawAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The options of the joint-space laws read and checked as :func:`solve_control_law` reads them (the law's
    options, q_d, the gains), of the Cartesian law (:func:`~solver.control.cartesian.validate_cartesian`) and of
    the elastic, underactuated and linearization laws (the readers their solvers run first:
    :func:`~solver.control.elastic.read_elastic`, :func:`~solver.control.underactuated.read_partial`,
    :func:`~solver.control.linearization.read_equilibrium`), without the model."""
    _check_options(problem, options, ctx)
    if options.law == "cartesian_computed_torque":
        from solver.control.cartesian import validate_cartesian
        validate_cartesian(problem, options, ctx)
    elif options.law == "elastic":
        from solver.control.elastic import read_elastic
        read_elastic(problem, options, ctx)
    elif options.law == "partial_fbl":
        from solver.control.underactuated import read_partial
        read_partial(problem, options, ctx)
    elif options.law == "linearization":
        from solver.control.linearization import read_equilibrium
        read_equilibrium(problem, options, ctx)
    if options.law not in JOINT_LAWS:
        return
    robot = require_model(problem)
    _joint_law_gains(problem, options, ctx)
    regulation = options.law in ("pd_gravity", "pd_constant") or options.regulation
    _desired_q(problem, options, ctx, robot, regulation)
    if options.law != "adaptive":
        _gains(problem, options, ctx, "kp", robot.n, True)
        _gains(problem, options, ctx, "kd", robot.n, True)


@ask_kind("control_law", ControlLawAsk,
          "joint-space control law (computed torque, PD + gravity compensation) and its closed-loop dynamics",
          validate=validate_control_law)
def solve_control_law(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """The law's solution, every result name followed by the ask's ``suffix``."""
    sol = _solve_law(problem, options, ctx)
    sfx = options.suffix
    if sfx:
        sol.results = {k + sfx: Result(k + sfx, r.value, r.kind, r.label) for k, r in sol.results.items()}
    _register_checks(sfx)
    if len(ctx.path) == 2 and isinstance(ctx.path[1], int):   # simulate reuses it
        problem.__dict__.setdefault("_control_solutions", {})[ctx.path[1]] = sol
    return sol


def _solve_law(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: u, closed_loop, closed_loop_check; pd_gravity, pd_constant also equilibrium_check."""
    _check_options(problem, options, ctx)
    law = options.law
    if law not in JOINT_LAWS:
        from solver.control import cartesian, elastic, linearization, underactuated
        solver = {"cartesian_computed_torque": cartesian.solve_cartesian, "elastic": elastic.solve_elastic,
                  "partial_fbl": underactuated.solve_partial, "linearization": linearization.solve_linearization}
        return solver[law](problem, options, ctx)
    robot = require_model(problem)
    dm = derive(robot)
    n = robot.n
    Ginv = _input_inverse(problem, dm, ctx, law)
    _joint_law_gains(problem, options, ctx)
    q, dq, ddq = sp.Matrix(robot.q), sp.Matrix(robot.dq), sp.Matrix(robot.ddq)
    regulation = law in ("pd_gravity", "pd_constant") or options.regulation
    qd = _desired_q(problem, options, ctx, robot, regulation)
    if qd is None:
        qd = sp.Matrix([_symbol(problem, _qname(s.name, "d"), _sub_tex(problem.latex_names.get(s, s.name), "d"))
                        for s in robot.q])
    if regulation:
        dqd = ddqd = sp.zeros(n, 1)
    else:
        dqd = sp.Matrix([_symbol(problem, "d" + _qname(s.name, "d"),
                                 "\\dot " + _sub_tex(problem.latex_names.get(s, s.name), "d")) for s in robot.q])
        ddqd = sp.Matrix([_symbol(problem, "dd" + _qname(s.name, "d"),
                                  "\\ddot " + _sub_tex(problem.latex_names.get(s, s.name), "d")) for s in robot.q])
    if law == "adaptive":
        return _solve_adaptive(problem, options, ctx, robot, dm, Ginv, qd, dqd, ddqd, regulation)
    if law == "lyapunov_tracking" and dm.S is None:
        raise UserError("law: lyapunov_tracking needs the factorization S(q, dq) (Christoffel symbols), not available "
                        "with a given c(q, dq)", problem.located.place(ctx.path + ("law",)), "give B (and g) only")
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
    elif law == "pd_constant":
        closed = dm.B * ddq + dm.c + fr + KD * dq - KP * e + dm.g - dm.g.xreplace(dict(zip(robot.q, qd)))
        residual = (dm.B * ddq + nvec - G * u) - closed
    elif law == "lyapunov_tracking":
        frs = dm.Fv * de if dm.Fv is not None else sp.zeros(n, 1)
        closed = dm.B * dde + dm.S * de + frs + KD * de + KP * e
        residual = (dm.B * ddq + nvec - G * u) + closed
    else:
        closed = dm.B * ddq + dm.c + fr + KD * dq - KP * e
        residual = (dm.B * ddq + nvec - G * u) - closed
    ok = all(_zero(x) for x in residual)
    record_law(problem, options.suffix, list(q), [[a, b, c] for a, b, c in zip(qd, dqd, ddqd)],
               list(qd) if options.qd is not None else None)
    sol = Solution("control_law", title=options.title or f"Control law: {LAWS[law]}")
    sol.add("u", u, "vector", label="u")
    sol.add("closed_loop", closed.applyfunc(expand_polynomial), "vector",
            label="\\ddot e + K_D\\dot e + K_P e" if law == "computed_torque"
            else "B\\ddot e + S\\dot e + K_D\\dot e + K_P e" if law == "lyapunov_tracking"
            else "B(q)\\ddot q + c(q,\\dot q) + K_D\\dot q - K_P e" + (" + g(q) - g(q_d)" if law == "pd_constant" else ""))
    sol.add("closed_loop_check", bool(ok), "bool", label="\\text{closed loop verified}")
    u_at = _at(problem, options, ctx, u)
    if u_at is not None:
        sol.add("u_at", u_at, "vector", label="u")
    eq_ok = None
    if law in ("pd_gravity", "pd_constant"):
        at = {**{a: b for a, b in zip(robot.q, qd)}, **{s: 0 for s in robot.dq + robot.ddq}}
        eq_ok = all(_zero(x.xreplace(at)) for x in closed)
        sol.add("equilibrium_check", bool(eq_ok), "bool", label="(q_d, 0) \\text{ equilibrium}")
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("law", law=law, KP=KP, KD=KD, qd=qd, dqd=dqd, ddqd=ddqd, v=v, tau=tau, u=u, Ginv=Ginv,
             regulation=regulation, e=e, friction=dm.Fv is not None)
    sol.step("closed_loop", law=law, closed=closed, ok=ok, eq_ok=eq_ok, kp=kp, kd=kd, n=n, friction=dm.Fv is not None,
             skew=dm.skew, u_at=u_at, at=_at_pairs(problem, options, ctx))
    return sol


def _at_pairs(problem, options: ControlLawAsk, ctx) -> list | None:  # type: ignore[no-untyped-def]
    if options.at is None:
        return None
    out = []
    for key in options.at:
        s = problem.names.get(key)
        if not isinstance(s, sp.Symbol):
            raise UserError(f"at: {key} is not a name of the problem or of the law (q1, dq1, qd1, dqd1, ddqd1, a "
                            f"parameter)", problem.located.place(ctx.path + ("at", key)))
        val = ctx.expr("at", key)
        if isinstance(val, list):
            raise UserError(f"at: {key} must be one expression", problem.located.place(ctx.path + ("at", key)))
        out.append((s, sp.sympify(val)))
    return out


def _at(problem, options: ControlLawAsk, ctx, u: sp.Matrix) -> sp.Matrix | None:  # type: ignore[no-untyped-def]
    """u with the at: values substituted (simplified)."""
    pairs = _at_pairs(problem, options, ctx)
    if pairs is None:
        return None
    return u.xreplace(dict(pairs)).applyfunc(lambda x: tidy(sp.simplify(x)))


# ------------------------------------------------------------------------------------------------ adaptive
def model_parametrization(problem, robot, dm, suffix: str | None = None, where: tuple = ()):  # type: ignore[no-untyped-def]
    """The linear parametrization Y a used by the law: that of the ``linear_parametrization`` ask with ``suffix`` (any
    part), or by default of the first one of the whole model (part: model); with its ``coefficients:`` if given,
    else computed the same way. Returns (par, ask, part)."""
    from solver.dynamics.parametrization import ParamError, compute_auto, compute_given, model_vector
    lps = [a for a in problem.asks if a.kind == "linear_parametrization"]
    if suffix is None:
        ask = next((a for a in lps if getattr(a.options, "part", "model") == "model"), None)
    else:
        ask = next((a for a in lps if a.options.suffix == suffix), None)
        if ask is None:
            have = ", ".join(repr(a.options.suffix) for a in lps) or "none"
            raise UserError(f"parametrization: {suffix!r} is not the suffix of a linear_parametrization ask of the "
                            f"problem (suffixes: {have})", problem.located.place(where),
                            "add the linear_parametrization ask, or write the suffix of one of them")
    part = ask.options.part if ask is not None else "model"
    vec = model_vector(dm, robot, part)
    known = list(problem.known)
    dyn = [s for s in problem.symbols.values() if s not in set(known)]
    coeffs = None
    if ask is not None and ask.options.coefficients is not None:
        val = ask.ctx.expr("coefficients")
        coeffs = [sp.sympify(v) for v in (val if isinstance(val, list) else [val])]
    try:
        par = compute_given(vec, robot, dyn, coeffs, known) if coeffs is not None else compute_auto(vec, robot, dyn)
    except ParamError as exc:
        at = ask.ctx.path + ("coefficients",) if coeffs is not None else ()
        raise UserError("adaptive control needs a linear parametrization of the model: " + exc.message,
                        problem.located.place(at) if at else None, exc.hint) from None
    return par, ask, part


def reference_regressor(Y: sp.Matrix, robot, dqr: list, ddqr: list) -> sp.Matrix:  # type: ignore[no-untyped-def]
    """Y(q, q̇, q̇_r, q̈_r) from Y(q, q̇, q̈), column by column (each column is a model term B_j q̈ + c_j + g_j + F_j q̇,
    with c_j a quadratic form in q̇ with symmetric Christoffel matrices):
    B_j q̈ -> B_j q̈_r, F_j q̇ -> F_j q̇_r, c_j(q̇) = q̇ᵀ C_j q̇ -> q̇ᵀ C_j q̇_r = ½ (∂c_j/∂q̇) q̇_r (the S of the
    Christoffel factorization), g_j unchanged. So Y_r a = B q̈_r + S q̇_r + g (+ F_v q̇_r)."""
    dq, ddq = list(robot.dq), list(robot.ddq)
    zero_v = {v: 0 for v in dq + ddq}
    out = sp.zeros(Y.rows, Y.cols)
    for k in range(Y.rows):
        for j in range(Y.cols):
            y = sp.expand(Y[k, j])
            yg = y.xreplace(zero_v)
            yb = sum((sp.diff(y, a).xreplace(zero_v) * ar for a, ar in zip(ddq, ddqr)), sp.Integer(0))
            yv = sp.expand(y.xreplace({a: 0 for a in ddq}) - yg)
            lin = [sp.diff(yv, v).xreplace(zero_v) for v in dq]
            yf = sum((c * vr for c, vr in zip(lin, dqr)), sp.Integer(0))
            yc = sp.expand(yv - sum((c * v for c, v in zip(lin, dq)), sp.Integer(0)))
            ys = sum((sp.diff(yc, v) * vr for v, vr in zip(dq, dqr)), sp.Integer(0)) / 2
            out[k, j] = tidy(sp.expand(yb + ys + yg + yf))
    return out


def _known_indices(problem, options: ControlLawAsk, ctx, a: sp.Matrix) -> list[int]:  # type: ignore[no-untyped-def]
    """Indices in a of the ``known_coefficients:`` (each must equal one coefficient of the parametrization)."""
    if options.known_coefficients is None:
        return []
    place = problem.located.place(ctx.path + ("known_coefficients",))
    val = ctx.expr("known_coefficients")
    vals = val if isinstance(val, list) else [val]
    out: list[int] = []
    listed = ", ".join(f"a{i + 1} = {sp.sstr(x)}" for i, x in enumerate(a))
    for v in vals:
        if isinstance(v, list):
            raise UserError("known_coefficients must be a list of expressions", place, "write e.g. [m3, m3*d3]")
        j = next((j for j in range(a.rows) if _zero(sp.sympify(v) - a[j])), None)
        if j is None:
            raise UserError(f"known_coefficients: {sp.sstr(v)} is not a coefficient of the linear parametrization "
                            f"used by the law ({listed})", place, "write the coefficients as they are in a")
        if j in out:
            raise UserError(f"known_coefficients: a{j + 1} = {sp.sstr(a[j])} is listed twice", place)
        out.append(j)
    if len(out) == a.rows:
        raise UserError("every coefficient is known: nothing is estimated", place,
                        "remove known_coefficients (or use law: lyapunov_tracking, the law with the known model)")
    return out


def _solve_adaptive(problem, options: ControlLawAsk, ctx, robot, dm, Ginv, qd, dqd, ddqd,  # type: ignore[no-untyped-def]
                    regulation: bool) -> Solution:
    """Slotine-Li, fully or partly adaptive. Results u, Y_r (whole-model parametrization), a_adapt (the estimated
    coefficients), dqr, ddqr, s, a_hat_dot, Yr_check, closed_loop, closed_loop_check, V, V_dot, V_check; a partly
    adaptive law also Y_U, Y_K, a_K (known coefficients), tau_K (the known part), p_U, B_U, S_U."""
    from solver.control import adaptive as ad
    n = robot.n
    if dm.S is None:
        raise UserError("law: adaptive needs the factorization S(q, dq) (Christoffel symbols), not available with a "
                        "given c(q, dq)", problem.located.place(ctx.path + ("law",)))
    q, dq, ddq = sp.Matrix(robot.q), sp.Matrix(robot.dq), sp.Matrix(robot.ddq)
    par, pask, part = model_parametrization(problem, robot, dm, options.parametrization,
                                            ctx.path + ("parametrization",))
    known_idx = _known_indices(problem, options, ctx, par.a)
    partial = bool(known_idx) or part != "model"
    lam = _gains(problem, options, ctx, "lam", n, True)
    kd = _gains(problem, options, ctx, "kd", n, True)
    pU = par.p - len(known_idx)
    unk = [j for j in range(par.p) if j not in set(known_idx)]
    # estimates: numbered as the coefficients of the parametrization (a partly adaptive law keeps the index of a_j);
    # those of a part's parametrization carry its suffix (a_g -> ahatg1, ahatg2); default adaptation gains alike
    tag = (options.parametrization or "").strip("_") if part != "model" else ""
    if options.gamma is None and partial:
        Gam = sp.diag(*[_gain_symbol(problem, f"gamma{tag}{j + 1}", f"\\gamma_{{{tag + ',' if tag else ''}{j + 1}}}")
                        for j in unk])
    else:
        Gam = _gamma(problem, options, ctx, pU)
    Lam, KD = sp.diag(*lam), sp.diag(*kd)

    def tex_of(s: sp.Symbol) -> str:
        return problem.latex_names.get(s, s.name)

    dqr = [_symbol(problem, "d" + _qname(s.name, "r"), "\\dot " + _sub_tex(tex_of(s), "r")) for s in robot.q]
    ddqr = [_symbol(problem, "dd" + _qname(s.name, "r"), "\\ddot " + _sub_tex(tex_of(s), "r")) for s in robot.q]
    ahat = [_symbol(problem, f"ahat{tag}{j + 1}", f"\\hat a_{{{tag + ',' if tag else ''}{j + 1}}}") for j in unk]
    e, de = qd - q, dqd - dq
    dqr_def = (dqd + Lam * e).applyfunc(sp.expand)
    ddqr_def = (ddqd + Lam * de).applyfunc(sp.expand)
    defs = dict(zip(dqr, dqr_def)) | dict(zip(ddqr, ddqr_def))
    fr = (lambda v: dm.Fv * v) if dm.Fv is not None else (lambda v: sp.zeros(n, 1))
    dqr_v, ddqr_v, ahat_v = sp.Matrix(dqr), sp.Matrix(ddqr), sp.Matrix(ahat)
    target = dm.B * ddqr_v + dm.S * dqr_v + dm.g + fr(dqr_v)
    Ypar = ad.christoffel_column(par.Y, robot) if part == "inertia" else par.Y
    Yr = reference_regressor(Ypar, robot, dqr, ddqr)
    YU, aU, YK, aK = ad.split_columns(Yr, par.a, known_idx)
    tauK = (target - YU * aU).applyfunc(lambda x: tidy(sp.expand(x)))
    if part == "model":
        yr_ok = all(_zero(x) for x in (Yr * par.a - target))
        if known_idx:
            yr_ok = yr_ok and all(_zero(x) for x in (YK * aK - tauK))
    else:   # the part's regressor reproduces its term of the model (the rest is the known tau_K)
        part_r = dm.g if part == "gravity" else dm.B * ddqr_v + dm.S * dqr_v
        yr_ok = all(_zero(x) for x in (Yr * par.a - part_r))
    unknown = ad.unknown_part(YU, aU, robot, ddqr) if partial else None
    s_r = dqr_v - dq                                   # s in the reference symbols
    tau = YU * ahat_v + (YK * aK if part == "model" else tauK) + KD * s_r
    u = (Ginv * tau).applyfunc(tidy) if Ginv is not None else tau.applyfunc(lambda x: tidy(sp.expand(x)))
    adot = (Gam * YU.T * s_r).applyfunc(lambda x: tidy(sp.expand(x)))
    # closed loop: B sdot + S s (+ F_v s) + K_D s = Y_U (a_U - ahat_U), s = de + Lambda e, sdot = ddq_r - ddq
    s = (de + Lam * e).applyfunc(sp.expand)
    sdot = ddqr_def - ddq
    closed = (dm.B * sdot + dm.S * s + fr(s) + KD * s).applyfunc(sp.expand)
    G = dm.G if dm.G is not None else sp.eye(n)
    u_state = u.xreplace(defs)
    atil = (aU - ahat_v).applyfunc(sp.expand)
    model_lhs = dm.B * ddq + dm.c + dm.g + fr(dq)
    residual = closed - (YU.xreplace(defs) * atil) - (G * u_state - model_lhs)
    ok = yr_ok and all(_zero(x) for x in residual)
    # Lyapunov function and its derivative along the closed loop
    with_e = options.lyapunov == "with_e"
    V = ad.lyapunov_function(dm.B, s, e, aU, ahat, Gam, KD, Lam, with_e)
    V_dot = ad.lyapunov_rate(s, e, de, KD, Lam, dm.Fv, with_e)
    rates: dict[sp.Symbol, sp.Expr] = dict(zip(ahat, adot.xreplace(defs)))
    if not regulation:
        rates |= {x: v for x, v in zip(qd, dqd) if isinstance(x, sp.Symbol)}
        rates |= {x: v for x, v in zip(dqd, ddqd) if isinstance(x, sp.Symbol)}
    forces = G * u_state - (dm.c + dm.g + fr(dq))
    v_ok = ad.lyapunov_derivative_check(V, V_dot, robot, dm.B, s, forces, rates)
    idx = [f"{tag + ',' if tag else ''}{j + 1}" for j in unk]
    V_compact, V_dot_compact = ad.compact_forms(n, idx, Gam, KD, Lam, dm.Fv, with_e)
    record_law(problem, options.suffix, list(q), [[a_, b, c] for a_, b, c in zip(qd, dqd, ddqd)],
               list(qd) if options.qd is not None else None, subs=defs, ahat=ahat, adot=adot.xreplace(defs),
               true_a=list(aU))
    problem.__dict__["_adaptive" + options.suffix] = {"defs": defs, "ahat": ahat, "Yr": YU, "Lam": Lam,
                                                      "qd": list(qd), "dqd": list(dqd),
                                                      "known": (YK * aK if part == "model" else tauK), "G": G,
                                                      "partial": partial}
    kind = "partly adaptive" if partial else "Slotine-Li"
    sol = Solution("control_law", title=options.title or f"Control law: {LAWS['adaptive']}"
                   + (" with a known part of the model" if partial else ""))
    sol.add("u", u, "vector", label="u")
    if part == "model":
        sol.add("Y_r", Yr, "matrix", label="Y(q,\\dot q,\\dot q_r,\\ddot q_r)")
    sol.add("a_adapt", aU, "vector", label="a_U" if partial else "a")
    if partial:
        sol.add("Y_U", YU, "matrix", label="Y_U(q,\\dot q,\\dot q_r,\\ddot q_r)")
        if part == "model":
            sol.add("Y_K", YK, "matrix", label="Y_K(q,\\dot q,\\dot q_r,\\ddot q_r)")
            sol.add("a_K", aK, "vector", label="a_K")
        sol.add("tau_K", tauK, "vector", label="\\tau_K = B\\ddot q_r + S\\dot q_r + g - Y_U a_U")
        sol.add("p_U", sp.Integer(pU), "scalar", label="p_U")
        sol.add("B_U", unknown.B_U, "matrix", label="B_U(q)")
        sol.add("S_U", unknown.S_U, "matrix", label="S_U(q,\\dot q)")
        if unknown.skew_U is not None:
            sol.add("skew_U", bool(unknown.skew_U), "bool", label="\\dot B_U - 2S_U \\text{ skew-symmetric}")
    sol.add("dqr", dqr_def, "vector", label="\\dot q_r")
    sol.add("ddqr", ddqr_def, "vector", label="\\ddot q_r")
    sol.add("s", s, "vector", label="s = \\dot q_r - \\dot q")
    sol.add("a_hat_dot", adot, "vector", label="\\dot{\\hat a}" + ("_U" if partial else ""))
    sol.add("Yr_check", bool(yr_ok), "bool",
            label="Y_r a \\equiv B\\ddot q_r + S\\dot q_r + g" if part == "model" else
            "Y_U a_U \\equiv g(q)" if part == "gravity" else "Y_U a_U \\equiv B\\ddot q_r + S\\dot q_r")
    sol.add("closed_loop", closed, "vector", label="B(q)\\dot s + S(q,\\dot q)s + K_D s")
    sol.add("closed_loop_check", bool(ok), "bool", label="\\text{closed loop verified}")
    sol.add("V", V, "scalar", label="V")
    sol.add("V_dot", V_dot, "scalar", label="\\dot V")
    sol.add("V_check", bool(v_ok), "bool", label="\\dot V \\text{ along the closed loop verified}")
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("reference", qd=qd, dqd=dqd, ddqd=ddqd, regulation=regulation, Lam=Lam, dqr=dqr_v, ddqr=ddqr_v,
             dqr_def=dqr_def, ddqr_def=ddqr_def, s=s, e=e)
    asyms = sp.Matrix([sp.Symbol(f"a_{j + 1}") for j in range(par.p)])
    if part == "model":
        sol.step("regressor", S=dm.S, skew=dm.skew, Y=Yr, a=par.a, p=par.p, given=pask is not None
                 and pask.options.coefficients is not None, ok=yr_ok, friction=dm.Fv is not None, asyms=asyms)
    if partial:
        pick = lambda idx: sp.Matrix([asyms[j] for j in idx]) if idx else sp.zeros(0, 1)  # noqa: E731
        sol.step("split", part=part, S=dm.S, skew=dm.skew, YU=YU, aU=aU, YK=YK, aK=aK, tauK=tauK, pU=pU,
                 pK=len(known_idx), aU_syms=pick(unk), aK_syms=pick(known_idx), BU=unknown.B_U, SU=unknown.S_U,
                 skew_U=unknown.skew_U, ok=yr_ok, friction=dm.Fv is not None, p=par.p)
    sol.step("law", law="adaptive", KD=KD, u=u, ahat=ahat_v, Ginv=Ginv, friction=dm.Fv is not None,
             partial=partial, model_part=part == "model", kind=kind)
    sol.step("update", Gam=Gam, adot=adot, p=pU, partial=partial, ahat=ahat_v, idx=idx)
    sol.step("closed_loop", law="adaptive", closed=closed, ok=ok, friction=dm.Fv is not None, skew=dm.skew, n=n,
             partial=partial)
    sol.step("lyapunov", with_e=with_e, V_rest=V_compact, V_dot=V_dot_compact, ok=v_ok, skew=dm.skew,
             friction=dm.Fv is not None, partial=partial, KP=KD * Lam)
    return sol


def _qname(name: str, mark: str) -> str:
    """q1 -> qd1, theta1 -> thetad1, x -> xd."""
    head = name.rstrip("0123456789")
    return head + mark + name[len(head):]


# ------------------------------------------------------------------------------------------------ grading
def _control_ask(problem, sfx: str = ""):  # type: ignore[no-untyped-def]
    for a in problem.asks:
        if a.kind == "control_law" and a.options.suffix == sfx:
            return a
    return None


def _register_checks(sfx: str) -> None:
    """The property check of u under its suffixed name (the check registered before stays the fallback)."""
    if not sfx or getattr(PROPERTY_CHECKS.get("u" + sfx), "_control_law", False):
        return
    previous = PROPERTY_CHECKS.get("u" + sfx)

    def check(problem, results, name, value, other, options):  # type: ignore[no-untyped-def]
        v = check_control_law(problem, results, name, value, other, options)
        if v is None and previous is not None:
            return previous(problem, results, name, value, other, options)
        return v

    check._control_law = True  # type: ignore[attr-defined]
    property_check("u" + sfx)(check)


def _suffix_of(problem, name: str) -> Optional[str]:  # type: ignore[no-untyped-def]
    for a in problem.asks:
        if a.kind == "control_law" and name == "u" + a.options.suffix:
            return a.options.suffix
    return None


def _answer_vector(value, n: int) -> sp.Matrix | PropertyVerdict | None:  # type: ignore[no-untyped-def]
    try:
        U = sp.Matrix(value) if isinstance(value, list) else sp.Matrix([value])
    except (ValueError, TypeError, sp.ShapeError):
        return None
    if U.shape == (1, n):
        U = U.T
    if U.shape != (n, 1):
        return PropertyVerdict(False, 0.0, [f"u must have {n} components (one per joint), not {len(U)}"])
    return U


def check_adaptive(problem, results, sfx: str, value) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Adaptive u: right iff G u = Y(q, q̇, q̇_r, q̈_r) â + K_e e + K_ė ė (partly adaptive: Y_K a_K + Y_U â_U + ...,
    the known part on the reference signals) with constant K_ė = K_ėᵀ > 0 and
    M = K_e − K_ė Λ such that M = Mᵀ ≥ 0, MΛ = (MΛ)ᵀ ≥ 0 (M = 0: the Slotine–Li K_D s; otherwise
    V = ½sᵀBs + ½ãᵀΓ⁻¹ã + ½eᵀMe still gives V̇ = −sᵀK_ės − eᵀMΛe ≤ 0). Symbolic gains are sampled at positive
    values."""
    info = problem.__dict__.get("_adaptive" + sfx)
    robot = problem.robot
    if info is None or robot is None:
        return None
    n = robot.n
    U = _answer_vector(value, n)
    if not isinstance(U, sp.Matrix):
        return U
    defs, ahat, Yr, Lam, qd, dqd = (info[k] for k in ("defs", "ahat", "Yr", "Lam", "qd", "dqd"))
    q, dq = list(robot.q), list(robot.dq)
    G = info.get("G", sp.eye(n))
    known = info.get("known", sp.zeros(n, 1))
    d = ((G * U).xreplace(defs) - (Yr * sp.Matrix(ahat) + known).xreplace(defs)).applyfunc(sp.expand)
    if any(_nonzero(sp.diff(x, a)) for x in d for a in ahat):
        return PropertyVerdict(False, 0.0, ["the part of u in the estimates â is not Y(q, q̇, q̇_r, q̈_r) â (the "
                                            "model evaluated on the reference velocity and acceleration, with c "
                                            "factorized as S q̇_r)" + (" restricted to the estimated coefficients, "
                                            "Y_U â_U" if info.get("partial") else "")], final=False)
    Ke = (-d.jacobian(q)).applyfunc(sp.expand)
    Kde = (-d.jacobian(dq)).applyfunc(sp.expand)
    moving = set(q) | set(dq) | set(robot.ddq) | set(ahat)
    e = sp.Matrix(qd) - sp.Matrix(q)
    de = sp.Matrix(dqd) - sp.Matrix(dq)
    rest = (d - Ke * e - Kde * de).applyfunc(sp.expand)
    if (Ke.free_symbols | Kde.free_symbols) & moving or any(_nonzero(x) for x in rest):
        fb = ["besides Y â, u must be a PD action K_P e + K_D ė (= K_D s) with constant gains: it is not"]
        if info.get("partial"):
            fb = ["besides Y_K a_K + Y_U â_U, u must be a PD action K_P e + K_D ė (= K_D s) with constant gains: "
                  "it is not"]
            dk = (d + known.xreplace(defs)).applyfunc(sp.expand)
            lin = dk - (-dk.jacobian(q)) * e - (-dk.jacobian(dq)) * de
            if not ((dk.jacobian(q).free_symbols | dk.jacobian(dq).free_symbols) & moving) and \
                    all(_zero(x) for x in lin.applyfunc(sp.expand)):
                fb.append("the known part of the model, Y_K(q, q̇, q̇_r, q̈_r) a_K (evaluated on the reference "
                          "velocity and acceleration), is not compensated")
        return PropertyVerdict(False, 0.0, fb, final=False)
    M = Ke - Kde * Lam
    import numpy as np
    rng = np.random.default_rng(7)
    syms = sorted((Kde.free_symbols | M.free_symbols | Lam.free_symbols), key=str)
    for _ in range(8):
        at = {x: sp.Float(rng.uniform(0.5, 3.0)) for x in syms}
        kd_ = np.array(Kde.xreplace(at).evalf(), dtype=float)
        m_ = np.array(M.xreplace(at).evalf(), dtype=float)
        ml = np.array((M * Lam).xreplace(at).evalf(), dtype=float)
        if not np.allclose(kd_, kd_.T) or np.linalg.eigvalsh(kd_).min() <= 0:
            return PropertyVerdict(False, 0.0, ["the gain of ė (K_D) must be symmetric positive definite"],
                                   final=False)
        if np.abs(m_).max() > 1e-12 and (not np.allclose(m_, m_.T) or not np.allclose(ml, ml.T)
                                         or np.linalg.eigvalsh(m_).min() < -1e-12
                                         or np.linalg.eigvalsh((ml + ml.T) / 2).min() < -1e-12):
            return PropertyVerdict(False, 0.5, ["u = Y â + K_P e + K_D ė with K_P − K_D Λ not positive "
                                                "semidefinite: the Lyapunov argument (V̇ = −sᵀK_D s − eᵀ(K_P − "
                                                "K_D Λ)Λ e) fails; take K_P = K_D Λ (u = Y â + K_D s)"], final=False)
    note = ("u = Y_K a_K + Y_U â_U + K_D s (partly adaptive: the known part compensated exactly)"
            if info.get("partial") and all(_zero(x) for x in M) else
            "u = Y(q, q̇, q̇_r, q̈_r) â + K_D s (Slotine–Li)" if all(_zero(x) for x in M) else
            "u = Y â + K_P e + K_D ė with K_P − K_D Λ ≥ 0: V = ½sᵀBs + ½ãᵀΓ⁻¹ã + ½eᵀ(K_P − K_D Λ)e has V̇ ≤ 0")
    return PropertyVerdict(True, 1.0, [note + "; with the update â̇ = Γ Yᵀ s the tracking error converges to zero"])


def _nonzero(x: sp.Expr) -> bool:
    return not _zero(x)


@property_check("u")
def check_control_law(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Computed torque: u is right iff the closed loop it gives is q̈ ≡ q̈_d + K_D ė + K_P e, i.e.
    B⁻¹ G (u − u_ref) ≡ 0 (checked on adj(B) G (u − u_ref)); names the closed-loop equations that fail and a missing
    c or g term. Adaptive: ``check_adaptive``. Other laws: None (compare with the reference)."""
    from solver.math.equivalence import scalar_equiv
    sfx = _suffix_of(problem, name)
    if sfx is None:
        return None
    ask, ref = _control_ask(problem, sfx), results.get(name)
    robot = problem.robot
    if ask is not None and ask.options.law == "adaptive" and ref is not None:
        return check_adaptive(problem, results, sfx, value)
    if ask is not None and ask.options.law == "cartesian_computed_torque" and ref is not None and robot is not None:
        from solver.control.cartesian import check_task_law
        return check_task_law(problem, results, sfx, value)
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
