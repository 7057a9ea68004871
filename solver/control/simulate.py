"""Closed-loop simulation of a designed control law (ask kind ``simulate``).

The law is the ``u`` of another ask of the problem (``control_law`` or ``regulation``, chosen by ``ask:``), the plant
the spec's robot with its numeric ``values`` (a regulation's ``assume:`` relations on top: they describe the robot):
    B(q) q̈ + c(q, q̇) + g(q) + F_v q̇ = G u(t, q, q̇, â, ξ) + τ_ext(q),    â̇ = Γ Y_rᵀ s   (adaptive law only),
                                                                           ξ̇ = e         (PID regulation only),
with τ_ext = Σ J(q)ᵀF the regulation's ``external:`` forces (0 otherwise),
integrated by :func:`solver.math.ode.solve` (or scipy's ``solve_ivp``, ``method:``) from (q₀, q̇₀, â₀, ξ₀ = 0)
in chunks (the iterative law from the regulation's û₀, the same constant feedforward as its static iterates),
within a budget of right-hand-side evaluations and wall seconds. The reference q_d(t) is any expression of t
(constant, polynomial, sinusoidal, ...): its derivatives are taken exactly. Reported: the error e = q_d − q (or
r_d − r) at the end and at its largest, the settling time (the instant after which ‖e‖ stays below ``settle``), the
largest inputs, the final estimates; figures of errors, inputs and estimates.
"""
from __future__ import annotations

import time
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field

from solver.dynamics.model import derive, require_model
from solver.math.numeric import lambdify_np
from solver.registry import ask_kind
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.models import Strict

ExprT = Union[str, int, float, list[Any]]
Scalar = Union[str, int, float]
CONTROL_KINDS = ("control_law", "regulation")


class SimulateAsk(Strict):
    """Closed-loop simulation of the control law of another ask, with the robot's numeric values."""

    kind: Literal["simulate"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    ask: Optional[int] = Field(None, ge=1, description="the number (1, 2, ... in asks:) of the control_law or "
                                                       "regulation ask to simulate; default the first one")
    q0: Optional[ExprT] = Field(None, description="initial configuration (list of n numbers); default the q0 of "
                                                  "a regulation ask with law: iterative, else 0")
    dq0: Optional[ExprT] = Field(None, description="initial velocity (list of n numbers); default 0")
    qd: Optional[ExprT] = Field(None, description="the reference: one expression of t per tracked variable (joint "
                                                  "coordinates; link coordinates for elastic; task for Cartesian), "
                                                  "e.g. ['pi/2 + 3*sin(pi*t/2)', '1 - cos(2*pi*t)'], '[0.5, 1]' or "
                                                  "polynomials; default the law's own constant q_d")
    set: dict[str, ExprT] = Field({}, description="values of the law's remaining symbols (gains kp1.., lambda1.., "
                                                  "gamma1..; an auxiliary input v1 as an expression of t, q, dq)")
    ahat0: Optional[ExprT] = Field(None, description="adaptive: initial estimates (list of p numbers); default 0")
    T: Scalar = Field(5, description="simulated time [s]")
    points: int = Field(400, ge=20, le=5000, description="samples of the plotted curves")
    settle: Optional[Scalar] = Field(None, description="settling band on ‖e‖ (absolute); default 2% of the "
                                                       "largest ‖e‖")
    max_steps: int = Field(200000, ge=100, le=5000000, description="budget of right-hand-side evaluations")
    wall: float = Field(30.0, gt=0, le=600, description="budget of wall seconds")
    method: Literal["auto", "RK45", "LSODA", "Radau", "DOP853"] = Field(
        "auto", description="integrator: auto (Dormand-Prince 5(4), scipy's LSODA once the closed loop proves "
                            "stiff) or a method of scipy's solve_ivp")
    rtol: float = Field(1e-7, gt=0, le=1e-2, description="relative tolerance of the integrator")
    iterations: int = Field(20, ge=1, le=200, description="regulation law: iterative: the largest number of "
                                                         "iterations, each a motion of T seconds with a constant "
                                                         "feedforward, then û ← g(q)")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")


class _Budget(Exception):
    pass


def _place(problem, ctx, *key: Any):  # type: ignore[no-untyped-def]
    return problem.located.place(ctx.path + tuple(key))


def _qname(name: str, mark: str) -> str:
    head = name.rstrip("0123456789")
    return head + mark + name[len(head):]


def _target(problem, options: SimulateAsk, ctx):  # type: ignore[no-untyped-def]
    """(index, ask) of the simulated control ask."""
    if options.ask is not None:
        i = options.ask - 1
        if i >= len(problem.asks) or problem.asks[i].kind not in CONTROL_KINDS:
            raise UserError(f"ask: {options.ask} is not a control_law or regulation ask", _place(problem, ctx, "ask"),
                            "count the asks from 1")
        return i, problem.asks[i]
    for i, a in enumerate(problem.asks):
        if a.kind in CONTROL_KINDS:
            return i, a
    raise UserError("simulate needs a control_law or regulation ask in the problem", _place(problem, ctx, "kind"),
                    "add the control law to simulate")


def _vector(problem, ctx, key: str, n: int, names: dict) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """A list of n expressions (one expression is also accepted when n = 1), parsed with ``names``."""
    val = ctx.parse_at(ctx.path + (key,), names)
    vals = val if isinstance(val, list) else [val]
    if len(vals) != n or any(isinstance(x, list) for x in vals):
        raise UserError(f"{key} must list {n} values", _place(problem, ctx, key))
    return [sp.sympify(x) for x in vals]


def _law_record(problem, ask, sol: Solution) -> dict:  # type: ignore[no-untyped-def]
    """What the law tracks and the symbols of its desired signals: the record left by control_law, or, for
    regulation, read from the law's step: the joint coordinates with the desired symbols found by name (qd1, dqd1,
    ...); elastic: the link (non-actuated) coordinates and their q_d; cartesian_pd: the task f(q) and p_d; pid also
    the controller state ξ and its rate ξ̇ = e; with ``external:`` forces τ_ext(q) = Σ J(q)ᵀF (the true forces, which
    act on the plant whatever the law compensates); the ask's ``assume:`` relations (they describe the controlled
    robot: the plant satisfies them too); iterative: the ask's starting configuration q₀ and feedforward û₀ (None
    without its q0)."""
    sfx = getattr(ask.options, "suffix", "")
    rec = problem.__dict__.get("_law" + sfx) if ask.kind == "control_law" else None
    if rec is not None and rec.get("kind") == ask.kind:
        return rec
    robot = problem.robot
    law = getattr(ask.options, "law", "")
    step = next((st.data for st in sol.steps if st.name == "law"), {})
    ext = sol.results.get("tau_ext" + sfx) if ask.kind == "regulation" else None
    model = next((st.data for st in sol.steps if st.name == "model"), {})
    iterative = next((st.data for st in sol.steps if st.name == "iterative"), {})
    out = {"kind": ask.kind, "subs": {}, "ahat": [], "adot": None, "true_a": None, "xi": [], "xidot": None,
           "tau_ext": sp.Matrix(ext.value) if ext is not None else None, "assumed": dict(model.get("assumed") or {}),
           "u0": iterative.get("u0"), "q0": iterative.get("q0")}
    if law in ("elastic", "cartesian_pd"):
        tracked, want, key = ((list(step["qs"]), sp.Matrix(step["qd"]), "qd") if law == "elastic"
                              else (list(step["f"]), sp.Matrix(step["pd"]), "pd"))
        desired = [[s if isinstance(s, sp.Symbol) else None, None, None] for s in want]
        given = list(want) if getattr(ask.options, key, None) is not None else None
        return {**out, "tracked": tracked, "desired": desired, "qd": given}
    desired = []
    for c in robot.q:
        row = []
        for pre in ("", "d", "dd"):
            s = problem.names.get(pre + _qname(c.name, "d"))
            row.append(s if isinstance(s, sp.Symbol) else None)
        desired.append(row)
    qd_given = None
    if getattr(ask.options, "qd", None) is not None:
        val = ask.ctx.expr("qd")
        qd_given = [sp.sympify(x) for x in (val if isinstance(val, list) else [val])]
    if law == "pid":
        out["xi"] = list(step["xi"])
        out["xidot"] = sp.Matrix(sol.results["controller_rate" + sfx].value)
    return {**out, "tracked": list(robot.q), "desired": desired, "qd": qd_given}


def validate_simulate(problem, options: SimulateAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The robot and the simulated ask, checked as :func:`solve_simulate` finds them; the rest of the options
    (references, values, initial state) depend on the law's solution and are read when solving."""
    require_model(problem)
    _target(problem, options, ctx)


@ask_kind("simulate", SimulateAsk, "closed-loop simulation of a control law (errors, inputs, estimates)",
          validate=validate_simulate)
def solve_simulate(problem, options: SimulateAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the suffix): e_final, e_final_norm, e_max_norm, settling_time, u_max, t_end, completed,
    nfev; adaptive also ahat_final; pid also xi_final."""
    from solver.registry import get_kind
    robot = require_model(problem)
    dm = derive(robot)
    n = robot.n
    idx, ask = _target(problem, options, ctx)
    cache = problem.__dict__.setdefault("_control_solutions", {})
    if idx not in cache:
        cache[idx] = get_kind(ask.kind).solve(problem, ask.options, ask.ctx)
    law_sol = cache[idx]
    sfx = getattr(ask.options, "suffix", "")
    if "u" + sfx not in law_sol.results:
        raise UserError(f"ask {idx + 1} ({ask.kind}) has no control input u to simulate",
                        _place(problem, ctx, "ask"), "simulate a law that gives u")
    rec = _law_record(problem, ask, law_sol)
    vals, assumed = plant_values(problem.values, rec.get("assumed") or {})
    u = sp.Matrix(law_sol.results["u" + sfx].value).xreplace(rec["subs"])
    q, dq = list(robot.q), list(robot.dq)
    t = sp.Symbol("t", real=True)
    # the reference and its derivatives
    tracked = rec["tracked"]
    m = len(tracked)
    if options.qd is not None:
        ref = _vector(problem, ctx, "qd", m, {**problem.names, "t": t})
        bad = set().union(*(x.free_symbols for x in ref)) - {t} - set(vals)
        if bad:
            raise UserError(f"qd may use only t and parameters with values (not {', '.join(sorted(map(str, bad)))})",
                            _place(problem, ctx, "qd"))
    elif rec.get("qd") is not None:
        ref = list(rec["qd"])
    else:
        raise UserError("simulate needs the reference qd (the law's desired values are symbols)",
                        _place(problem, ctx, "qd"), "e.g. qd: [0.5, 'sin(t)']")
    subs: dict = {}
    for i, row in enumerate(rec["desired"]):
        for k, s in enumerate(row):
            if s is not None:
                subs[s] = sp.diff(ref[i], t, k)
    # user-set symbols (gains, auxiliary inputs)
    setv: dict = {}
    for key in options.set:
        s = problem.names.get(key)
        if not isinstance(s, sp.Symbol):
            raise UserError(f"set: {key} is not a symbol of the problem or of the law", _place(problem, ctx, "set", key))
        val = ctx.parse_at(ctx.path + ("set", key), {**problem.names, "t": t})
        if isinstance(val, list):
            raise UserError(f"set: {key} must be one expression", _place(problem, ctx, "set", key))
        setv[s] = sp.sympify(val)
    ahat = list(rec["ahat"])
    xi = list(rec.get("xi", []))    # pid: the controller state, ξ̇ = e, ξ(0) = 0
    state = q + dq + ahat + xi
    # the iterative gravity compensation: constant feedforward symbols û, updated between iterations
    ff = sorted([x for x in set().union(*(e.free_symbols for e in u)) if x.name.startswith("uhat")
                 and ask.kind == "regulation" and getattr(ask.options, "law", "") == "iterative"], key=str)
    allowed = set(state) | {t} | set(ff)

    def close(x: sp.Expr) -> sp.Expr:
        for _ in range(3):
            x = x.xreplace(setv).xreplace(subs)
        return x.xreplace(vals)

    u_num = u.applyfunc(close)
    adot = rec["adot"].applyfunc(close) if rec["adot"] is not None else None
    xidot = rec["xidot"].applyfunc(close) if rec.get("xidot") is not None else None
    plant_B = dm.B.xreplace(vals)
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    tau_ext = rec.get("tau_ext")
    tau_ext = tau_ext if tau_ext is not None else sp.zeros(n, 1)
    plant_g = dm.g - tau_ext    # the conservative generalized force on the plant: gravity and external forces
    plant_n = (dm.c + plant_g + Fv * sp.Matrix(dq)).xreplace(vals)
    G = (dm.G if dm.G is not None else sp.eye(n)).xreplace(vals)
    free = set()
    for x in (list(u_num) + list(plant_B) + list(plant_n) + list(G) + (list(adot) if adot is not None else [])
              + (list(xidot) if xidot is not None else [])):
        free |= x.free_symbols - allowed
    if free:
        raise UserError("simulate needs numbers for " + ", ".join(sorted(map(str, free))),
                        _place(problem, ctx, "set"), "give them in the problem's values: or in set: {name: value}")
    err_expr = [(ref[i] - tracked[i]).xreplace(vals) for i in range(m)]
    args = [t] + state + ff
    f_u = lambdify_np(args, list(u_num))
    f_B = lambdify_np(args, plant_B)
    f_n = lambdify_np(args, list(plant_n))
    f_G = lambdify_np(args, G)
    f_a = lambdify_np(args, list(adot)) if adot is not None else None
    f_xi = lambdify_np(args, list(xidot)) if xidot is not None else None
    f_e = lambdify_np(args, err_expr)
    q0_from = None
    if options.q0 is None and rec.get("q0") is not None:    # iterative: the regulation ask's starting configuration
        q0, q0_from = _numbers(list(rec["q0"]), vals), "ask"
        if q0 is None:
            raise UserError(f"the q0 of ask {idx + 1} needs numbers to start the simulation from",
                            _place(problem, ctx, "kind"), "give its parameters values:, or give q0: here")
    else:
        q0 = _floats(problem, options, ctx, "q0", n, vals)
    dq0 = _floats(problem, options, ctx, "dq0", n, vals)
    a0 = _floats(problem, options, ctx, "ahat0", len(ahat), vals) if ahat else []
    y0 = np.array(q0 + dq0 + a0 + [0.0] * len(xi), dtype=float)
    budget = {"nfev": 0, "deadline": time.monotonic() + options.wall}
    used = {"method": options.method}  # auto: DOPRI5 until a chunk proves stiff, then LSODA for the rest
    ffv, u0_from = np.zeros(0), None
    if ff:    # û₀: the regulation ask's (its u0, or g − τ_ext at its q0), else g − τ_ext at the simulation's q(0)
        u0_from = ("given" if getattr(ask.options, "u0", None) is not None else
                   "ask" if rec.get("u0") is not None else "start")
        if rec.get("u0") is not None:
            u0v = list(rec["u0"])
        elif u0_from == "given":
            u0v = ask.ctx.expr("u0")
            u0v = u0v if isinstance(u0v, list) else [u0v]
        else:
            u0v = list(plant_g.xreplace(dict(zip(q, q0))))
        u0n = _numbers(u0v, vals)
        if u0n is None:
            raise UserError(f"the initial feedforward u0 of ask {idx + 1} needs numbers", _place(problem, ctx, "kind"),
                            "give its parameters values:")
        ffv = np.array(u0n)
    f_g = lambdify_np([q], list(plant_g.xreplace(vals))) if ff else None

    def rhs(tt: float, y: np.ndarray) -> np.ndarray:
        budget["nfev"] += 1
        if budget["nfev"] > options.max_steps or time.monotonic() > budget["deadline"]:
            raise _Budget()
        a = [tt, *y, *ffv]
        uu = np.array(f_u(*a), dtype=float).ravel()
        B = np.array(f_B(*a), dtype=float)
        nn = np.array(f_n(*a), dtype=float).ravel()
        Gm = np.array(f_G(*a), dtype=float).reshape(n, -1)
        ddq = np.linalg.solve(B, Gm @ uu - nn)
        out = [y[n:2 * n], ddq]
        if f_a is not None:
            out.append(np.array(f_a(*a), dtype=float).ravel())
        if f_xi is not None:
            out.append(np.array(f_xi(*a), dtype=float).ravel())
        return np.concatenate(out)

    T = _number(problem, options, ctx, "T", vals)
    settle = _number(problem, options, ctx, "settle", vals) if options.settle is not None else None
    if settle is not None and not settle > 0:
        raise UserError("settle must be a positive band on ||e||", _place(problem, ctx, "settle"))
    if not (0 < T <= 1e4):
        raise UserError("T must be a positive time (at most 10^4 s)", _place(problem, ctx, "T"))
    T_phase = T
    phases = options.iterations if ff else 1
    eps = None
    if ff:
        eps = _numbers([ask.ctx.expr("epsilon")], vals) if getattr(ask.options, "epsilon", None) is not None \
            else [settle if settle is not None else 1e-3]
        if eps is None:
            raise UserError(f"the epsilon of ask {idx + 1} needs a number", _place(problem, ctx, "kind"),
                            "give its parameters values:")
        eps = eps[0]
    Ttot = T * phases
    grid = np.linspace(0.0, Ttot, options.points * (min(phases, 10) if ff else 1))
    ts, ys, FF = [0.0], [y0], [ffv.copy()]
    completed, y = True, y0
    iter_errors: list[float] = []
    for k in range(phases):
        chunks = np.linspace(k * T, (k + 1) * T, 21)
        for a, b in zip(chunks[:-1], chunks[1:]):
            sel = grid[(grid > a) & (grid <= b)]
            try:
                r = _integrate(rhs, (a, b), y, used, sel if len(sel) else None, options.rtol)
            except _Budget:
                completed = False
                break
            if not r.success:
                completed = False
                break
            y = r.y[:, -1] if len(sel) == 0 else _final(rhs, b, r, used, options.rtol)
            ts += list(r.t)
            ys += list(r.y.T)
            FF += [ffv.copy()] * len(r.t)
            if ts[-1] < b - 1e-12:    # the end of the chunk is not on the grid: keep it
                ts.append(float(b))
                ys.append(y)
                FF.append(ffv.copy())
            if not np.all(np.isfinite(y)):
                completed = False
                break
        if not completed or not ff:
            break
        err = float(np.linalg.norm(np.array(f_e((k + 1) * T, *y, *ffv), dtype=float)))
        iter_errors.append(err)
        if err < eps:
            break
        ffv = np.array(f_g(list(y[:n])), dtype=float).ravel()    # û_{k+1} = g(q) − τ_ext(q) at the end of iteration k
    T = Ttot if not ff else T * max(len(iter_errors), 1)
    Ts = np.array(ts)
    Y = np.array(ys)
    E = np.array([np.array(f_e(tt, *yy, *fv), dtype=float).ravel() for tt, yy, fv in zip(Ts, Y, FF)])
    U = np.array([np.array(f_u(tt, *yy, *fv), dtype=float).ravel() for tt, yy, fv in zip(Ts, Y, FF)])
    en = np.linalg.norm(E, axis=1)
    band = settle if settle is not None else 0.02 * max(float(en.max()), 1e-12)
    above = np.nonzero(en > band)[0]
    settling = 0.0 if len(above) == 0 else (float(Ts[above[-1] + 1]) if above[-1] + 1 < len(Ts) else None)
    sol = Solution("simulate", title=options.title or f"Simulation of the closed loop (ask {idx + 1})")

    def add(name: str, value: Any, kind: str, label: str) -> None:
        sol.add(name + options.suffix, value, kind, label=label)

    add("e_final", sp.Matrix([sp.Float(x, 6) for x in E[-1]]), "vector", "e(T)")
    add("e_final_norm", sp.Float(en[-1], 6), "number", "\\|e(T)\\|")
    add("e_max_norm", sp.Float(en.max(), 6), "number", "\\max_t\\|e(t)\\|")
    add("settling_time", sp.Float(settling, 6) if settling is not None else sp.oo, "number", "t_s")
    crossings = [sign_changes(E[:, i]) for i in range(m)]
    add("e_sign_changes", sp.Matrix([sp.Integer(c) for c in crossings]), "vector", "\\#\\{e_i = 0\\}")
    add("oscillatory", sp.Matrix([sp.Integer(int(c > 0)) for c in crossings]), "vector",
        "e_i \\text{ changes sign}")
    add("u_max", sp.Matrix([sp.Float(x, 6) for x in np.abs(U).max(axis=0)]), "vector", "\\max_t|u_i(t)|")
    add("t_end", sp.Float(Ts[-1], 6), "number", "t_{end}")
    add("completed", bool(completed), "bool", "\\text{completed}")
    add("nfev", sp.Integer(budget["nfev"]), "number", "\\text{evaluations}")
    A = Y[:, 2 * n:2 * n + len(ahat)]
    XI = Y[:, 2 * n + len(ahat):]
    if ff:
        done = bool(iter_errors) and iter_errors[-1] < eps
        add("iterations_sim", sp.Integer(len(iter_errors)) if done else sp.oo, "number", "i")
        add("iteration_errors", [sp.Float(x, 6) for x in iter_errors], "list", "\\|e_i\\|")
    if ahat:
        add("ahat_final", sp.Matrix([sp.Float(x, 6) for x in A[-1]]), "vector", "\\hat a(T)")
    if xi:
        add("xi_final", sp.Matrix([sp.Float(x, 6) for x in XI[-1]]), "vector", "\\xi(T)")
    true_a = None
    if rec.get("true_a") is not None:
        try:
            true_a = [float(sp.sympify(x).xreplace(vals)) for x in rec["true_a"]]
        except (TypeError, ValueError):
            true_a = None
    _figures(sol, Ts, E, U, A, en, band, settling, rec, true_a, problem, options, n, m)
    sol.step("simulate", ask=idx + 1, kind=ask.kind, law=getattr(ask.options, "law", ""), ref=sp.Matrix(ref),
             tracked=sp.Matrix(tracked), q0=sp.Matrix(q0), **({"q0_from": q0_from} if q0_from else {}),
             dq0=sp.Matrix(dq0), a0=sp.Matrix(a0) if a0 else None,
             T=T, method=used["method"], setv=list(setv.items()), completed=completed,
             t_end=float(Ts[-1]), nfev=budget["nfev"], e_final=float(en[-1]), e_max=float(en.max()),
             settling=settling, band=band, adaptive=bool(ahat), n=n, m=m,
             umax=[float(x) for x in np.abs(U).max(axis=0)], ahat_final=_column(A[-1]) if ahat else None,
             true_a=_column(true_a) if true_a else None, crossings=crossings,
             iterative=bool(ff), iter_errors=iter_errors, eps=eps, phase=T_phase,
             **({"u0_from": u0_from, "u0": _column(FF[0]), "q0_ask": rec.get("q0") if u0_from == "ask" else None}
                if ff else {}),
             **({"friction": True} if dm.Fv is not None else {}), **({"input_map": True} if dm.G is not None else {}),
             **({"assumed": assumed} if assumed else {}),
             **({"external": True} if rec.get("tau_ext") is not None else {}),
             **({"integral": True, "xi_final": _column(XI[-1])} if xi else {}))
    return sol


def plant_values(values: dict, assumed: dict) -> tuple[dict, list]:
    """The plant's parameter values: the problem's ``values`` with the simulated ask's assumed relations
    {symbol: expression} on top (they describe the controlled robot, so they override a value given for the same
    symbol); also the report rows (symbol, relation, its value with the others, the overridden value or None)."""
    if not assumed:
        return dict(values), []
    base = {k: v for k, v in values.items() if k not in assumed}
    out, rows = dict(values), []
    for s, rel in assumed.items():
        x = sp.sympify(rel)
        for _ in range(3):
            x = x.xreplace(assumed)
        x = x.xreplace(base)
        out[s] = x
        rows.append((s, sp.sympify(rel), x, values.get(s)))
    return out, rows


def _column(xs: Any) -> sp.Matrix:
    """Numbers as a column of Floats (printed as a vector in the reports)."""
    return sp.Matrix([sp.Float(float(x), 15) for x in xs])


def sign_changes(e: np.ndarray, rel: float = 1e-3) -> int:
    """Zero crossings of a sampled error, ignoring values below rel·max|e| (integration noise near 0)."""
    big = np.abs(e) > rel * max(float(np.abs(e).max()), 1e-300)
    s = np.sign(e[big])
    return int(np.count_nonzero(s[1:] != s[:-1]))


def _integrate(rhs, span: tuple[float, float], y: np.ndarray, used: dict, t_eval,  # type: ignore[no-untyped-def]
               rtol: float):
    """One chunk of the simulation with ``used["method"]``: auto is :func:`solver.math.ode.solve` (DOPRI5), which
    hands a stiff chunk to LSODA; from then on every chunk goes to LSODA directly ("LSODA (stiff)"). The other
    methods are scipy's solve_ivp's."""
    method = used["method"]
    if method == "auto":
        from solver.math.ode import solve
        r = solve(rhs, span, y, t_eval=t_eval, rtol=rtol, atol=rtol * 1e-2)
        if r.method == "LSODA":
            used["method"] = "LSODA (stiff)"
        return r
    from scipy.integrate import solve_ivp
    return solve_ivp(rhs, span, y, method="LSODA" if method == "LSODA (stiff)" else method, t_eval=t_eval,
                     rtol=rtol, atol=rtol * 1e-2)


def _final(rhs, b: float, r, used: dict, rtol: float):  # type: ignore[no-untyped-def]
    """The state at b (t_eval ends at b when b is on the grid; else integrate the remaining bit)."""
    if abs(r.t[-1] - b) < 1e-12:
        return r.y[:, -1]
    return _integrate(rhs, (r.t[-1], b), r.y[:, -1], used, None, rtol).y[:, -1]


def _numbers(xs: list, values: dict) -> Optional[list[float]]:
    """Expressions as floats with the plant's parameter ``values`` (None if one is not a real number)."""
    out = []
    for x in xs:
        x = sp.sympify(x).xreplace(values) if not isinstance(x, list) else None
        if x is None or x.free_symbols or not x.is_real:
            return None
        out.append(float(x))
    return out


def _number(problem, options: SimulateAsk, ctx, key: str, values: dict) -> float:  # type: ignore[no-untyped-def]
    """A scalar option (a number, or an expression parsed with the problem's names: parameters with values
    allowed), as a float with the plant's ``values``."""
    raw = getattr(options, key)
    x = _numbers([ctx.expr(key) if isinstance(raw, str) else raw], values)
    if x is None:
        raise UserError(f"{key} must be a number", _place(problem, ctx, key))
    return x[0]


def _floats(problem, options: SimulateAsk, ctx, key: str, n: int, values: dict) -> list[float]:  # type: ignore[no-untyped-def]
    """The numbers of a list option with the plant's ``values`` (default zeros)."""
    if getattr(options, key) is None:
        return [0.0] * n
    val = ctx.expr(key)
    vals = val if isinstance(val, list) else [val]
    if len(vals) != n or any(isinstance(x, list) for x in vals):
        raise UserError(f"{key} must list {n} numbers", _place(problem, ctx, key))
    out = _numbers(vals, values)
    if out is None:
        raise UserError(f"{key} must be numbers", _place(problem, ctx, key))
    return out


def _figures(sol, Ts, E, U, A, en, band, settling, rec, true_a, problem, options, n, m):  # type: ignore[no-untyped-def]
    t = [float(x) for x in Ts]
    names = [problem.latex_names.get(s, str(s)) if isinstance(s, sp.Symbol) else f"r_{{{i + 1}}}"
             for i, s in enumerate(rec["tracked"])]

    def sample() -> list[Panel]:
        err = Panel("$t$ [s]", "$e$", [Curve(f"$e_{{{i + 1}}}$ (${names[i]}$)", t, [float(x) for x in E[:, i]])
                                     for i in range(m)] + [Curve("$\\|e\\|$", t, [float(x) for x in en], dashed=True)])
        if settling is not None and settling > 0:
            err.markers.append((settling, band, f"$t_s$ = {settling:.3g} s"))
        torque = Panel("$t$ [s]", "$u$", [Curve(f"$u_{{{i + 1}}}$", t, [float(x) for x in U[:, i]])
                                        for i in range(U.shape[1])])
        panels = [err, torque]
        if A.shape[1]:
            est = Panel("$t$ [s]", "$\\hat a$", [Curve(f"$\\hat a_{{{i + 1}}}$", t, [float(x) for x in A[:, i]])
                                               for i in range(A.shape[1])])
            if true_a is not None:
                est.hlines = [(a, f"$a_{{{i + 1}}}$") for i, a in enumerate(true_a)]
            panels.append(est)
        return panels

    caption = "Closed-loop simulation: tracking errors, inputs" + (" and parameter estimates (true values dashed)"
                                                                   if A.shape[1] else "") + "."
    sol.figures.append(Figure("simulation" + options.suffix, caption, sample))
