"""Hybrid force/velocity control in a task frame (``force_control`` with ``law: hybrid``).

Task frame: the columns of R (m x m) are its axes in the base frame; the task velocity and the force the robot
exerts on the environment, in the task frame, are v_t = Rᵀ J(q) q̇ = J_t q̇ and f_t = Rᵀ F. Each task direction is
force- or motion-controlled (rigid, frictionless environment):

    force direction i:   natural  v_i = 0,   artificial  f_i = f_i,d
    motion direction i:  natural  f_i = 0,   artificial  v_i = v_i,d

A redundant robot gets extra motion rows r_aug(q) (``augment``), so that J_a = [J_t; ∂r_aug/∂q] is square. With
T, Y the selections of the motion and force directions (Tᵀ Y = 0) and the model B q̈ + n = G u − J_tᵀ f_t:

    G u = B J_a⁻¹ (T a − J̇_a q̇) + n(q, q̇) + J_tᵀ Y a_f
    =>  Λ_a T (σ − a) = Y (a_f − λ)   (v̇_a = T σ, f_t = Y λ, Λ_a = J_a⁻ᵀ B J_a⁻¹)
    =>  σ = a  (premultiply by Tᵀ, Tᵀ Λ_a T > 0),   λ = a_f:   decoupled double integrators and force loops,

closed with a = v̇_d + K_V (v_d − v) and a_f = f_d + K_I ∫ (f_d − f) (nominal: a = v̇_d, a_f = f_d).
"""
from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from solver.dynamics.model import derive, has_model
from solver.math.equivalence import scalar_equiv
from solver.math.simplify import evaluate_transcendental, tidy
from solver.registry import PropertyVerdict
from solver.results import Solution
from solver.spec.expr import shape_of

ROTATIONAL = {"rx": "x", "ry": "y", "rz": "z"}


def default_axes(m: int) -> list[str]:
    return {1: ["x"], 2: ["x", "y"], 3: ["x", "y", "z"], 6: ["x", "y", "z", "rx", "ry", "rz"]}.get(
        m, [f"d{i + 1}" for i in range(m)])


def quantity_names(axis: str) -> tuple[str, str, str, str]:
    """(velocity, force, their LaTeX) of a task direction: x -> v_x, f_x; rx -> omega_x, mu_x."""
    if axis in ROTATIONAL:
        a = ROTATIONAL[axis]
        return f"omega_{a}", f"mu_{a}", f"\\omega_{{{a}}}", f"\\mu_{{{a}}}"
    return f"v_{axis}", f"f_{axis}", f"v_{{{axis}}}", f"f_{{{axis}}}"


@dataclass
class HybridTask:
    """The hybrid law's options as read and checked (:func:`read_hybrid`): the task Jacobian J (None: constraints
    only), the task directions, the frame R and the augmented square J_a with det J_a ≢ 0."""
    q: list[sp.Symbol]
    J: sp.Matrix | None
    m: int
    axes: list[str]
    force_dirs: list[str]
    motion_dirs: list[str]
    R: sp.Matrix | None = None
    Jt: sp.Matrix | None = None
    aug: sp.Matrix | None = None
    names: list[str] = field(default_factory=list)   # the rows of J_a: task axes, then augmented rows
    motion_all: list[str] = field(default_factory=list)
    Ja: sp.Matrix | None = None
    detJa: sp.Expr | None = None


def read_hybrid(c) -> HybridTask:  # type: ignore[no-untyped-def]
    """The options of ``law: hybrid`` read and checked, without the dynamic model: what ``check`` runs, and the
    first thing the solver runs (so both fail with the same message). The values of velocity:, nominal: and at:
    may name the quantities the solver introduces (v_t_d, a_t, ...): only their keys are checked here."""
    problem, o = c.problem, c.options
    robot = problem.robot
    q = list(robot.q) if robot is not None else []
    J = None
    if o.task is not None or o.jacobian is not None:
        if robot is None:
            raise c.fail(("task",) if o.task is not None else ("jacobian",), "task:/jacobian: need robot: (its "
                         "coordinates)", "add robot: {joints: [...]}")
        if o.task is not None and o.jacobian is not None:
            raise c.fail(("jacobian",), "give task: (r = f(q)) or jacobian:, not both")
        if o.task is not None:
            r = c.vector(("task",), None, "task")
            J = r.jacobian(q).applyfunc(tidy)
        else:
            val = c.ctx.expr("jacobian")
            shp = shape_of(val)
            J = sp.Matrix([val]) if len(shp) == 1 else sp.Matrix(val) if len(shp) == 2 else None
            if J is None or J.cols != len(q):
                raise c.fail(("jacobian",), f"jacobian must be a matrix with {len(q)} columns (one per coordinate)")
    m = J.rows if J is not None else (len(o.axes) if o.axes else 6)
    axes = list(o.axes) if o.axes else default_axes(m)
    if len(axes) != m or len(set(axes)) != m:
        raise c.fail(("axes",), f"axes must be {m} distinct names (one per task direction)")
    force_dirs, motion_dirs = _directions(c, axes)
    h = HybridTask(q, J, m, axes, force_dirs, motion_dirs)
    if J is None:
        return h
    n = len(q)
    h.R = _frame(c, m)
    h.Jt = (h.R.T * J).applyfunc(tidy)
    h.aug, aug_names = _augment(c, q)
    Ja = h.Jt.col_join(h.aug) if h.aug is not None else h.Jt
    if Ja.rows != n:
        where = ("augment",) if o.augment is not None else (("task",) if o.task is not None else ("jacobian",))
        raise c.fail(where, f"the (augmented) task Jacobian is {Ja.rows}x{n}: the law needs it square",
                     f"add {n - Ja.rows} motion row(s) with augment: (e.g. [q{n}])" if Ja.rows < n
                     else "the task has more directions than the robot has joints")
    if Ja.rows != Ja.cols:
        raise c.fail(("augment",), "the augmented Jacobian must be square")
    detJa = tidy(Ja.det(method="berkowitz"))
    if detJa == 0 or scalar_equiv(detJa, 0).ok:
        raise c.fail(("augment",) if h.aug is not None else ("task",), "the (augmented) task Jacobian is singular "
                     "everywhere", "choose other task/augment rows")
    h.Ja, h.detJa = Ja, detJa
    h.names = list(axes) + aug_names
    h.motion_all = [a for a in axes if a in motion_dirs] + aug_names
    for k in o.velocity or {}:
        if k not in h.motion_all:
            raise c.fail(("velocity", k), f"'{k}' is not a motion-controlled direction",
                         "motion directions: " + ", ".join(h.motion_all))
    force_all = [a for a in axes if a in force_dirs]
    for key, vals in (o.nominal or {}).items():
        if key not in ("acceleration", "force"):
            raise c.fail(("nominal", key), f"unknown nominal: {key}", "use acceleration: and force:")
        pool = h.motion_all if key == "acceleration" else force_all
        for k in vals:
            if k not in pool:
                raise c.fail(("nominal", key, k), f"'{k}' is not a {'motion' if key == 'acceleration' else 'force'}"
                             f"-controlled direction", "directions: " + ", ".join(pool))
    return h


def solve_hybrid(c) -> Solution:  # type: ignore[no-untyped-def]
    """Results: natural, artificial, n_force, n_motion; with a task: J, J_t, J_a, Jdot, R; with a dynamic
    model: u, closed_loop, closed_loop_check, and with nominal references u_nominal, ddq_nominal (u_nominal_at);
    with velocity: qdot."""
    from solver.interaction.force import _step, fresh

    problem, o = c.problem, c.options
    sfx = o.suffix
    sol = Solution("force_control", title=o.title or "Hybrid force/velocity control")

    def add(name: str, value: Any, kind: str | None = None, label: str = "") -> None:
        sol.add(name + sfx, value, kind, label=label)

    h = read_hybrid(c)
    robot, q, J, m, axes, force_dirs, motion_dirs = problem.robot, h.q, h.J, h.m, h.axes, h.force_dirs, h.motion_dirs
    # constraints
    natural, artificial, rows = [], [], []
    for a in axes:
        vn, fn, vt, ft = quantity_names(a)
        v, f = fresh(problem, vn, vt), fresh(problem, fn, ft)
        vd = fresh(problem, vn + "_d", vt[:-1] + ",d}")
        fd = fresh(problem, fn + "_d", ft[:-1] + ",d}")
        if a in force_dirs:
            natural.append(v)
            artificial.append(f - fd)
        else:
            natural.append(f)
            artificial.append(v - vd)
        rows.append({"axis": a, "force": a in force_dirs, "v": v, "f": f, "vd": vd, "fd": fd})
    add("natural", [sp.Matrix([x]) for x in natural], "set", label="\\text{natural constraints} = 0")
    add("artificial", [sp.Matrix([x]) for x in artificial], "set", label="\\text{artificial constraints} = 0")
    add("n_force", sp.Integer(len(force_dirs)), "number", label="\\text{force loops}")
    add("n_motion", sp.Integer(len(motion_dirs)), "number", label="\\text{motion loops}")
    _step(sol, "hybrid_constraints", rows=rows, m=m, n_force=len(force_dirs), n_motion=len(motion_dirs))
    if J is None:
        return sol
    R, Jt, aug, Ja, detJa, names, motion_all = h.R, h.Jt, h.aug, h.Ja, h.detJa, h.names, h.motion_all
    n = len(q)
    dq = sp.Matrix(robot.dq)
    add("J", J, "matrix", label="J(q)")
    if R != sp.eye(m):
        add("R", R, "matrix", label="R")
        add("J_t", Jt, "matrix", label="J_t = R^T J")
    if aug is not None:
        add("J_a", Ja, "matrix", label="J_a")
    Jdot = sum((J.diff(x) * v for x, v in zip(q, dq)), sp.zeros(*J.shape)).applyfunc(tidy)
    Jadot = sum((Ja.diff(x) * v for x, v in zip(q, dq)), sp.zeros(*Ja.shape)).applyfunc(tidy)
    add("Jdot", Jdot, "matrix", label="\\dot J(q, \\dot q)")
    Jai = (Ja.adjugate() / detJa).applyfunc(lambda x: tidy(sp.cancel(x)) if sp.count_ops(x) < 300 else x)
    idx_m = [names.index(a) for a in motion_all]
    idx_f = [axes.index(a) for a in axes if a in force_dirs]
    T = sp.Matrix.hstack(*[sp.eye(n)[:, i] for i in idx_m]) if idx_m else sp.zeros(n, 0)
    Y = sp.Matrix.hstack(*[sp.eye(m)[:, i] for i in idx_f]) if idx_f else sp.zeros(m, 0)
    data: dict[str, Any] = {"J": J, "R": R, "Jt": Jt, "Ja": Ja, "aug": aug, "Jdot": Jdot, "Jadot": Jadot,
                            "Jai": Jai, "n": n, "m": m, "motion": motion_all, "force": [a for a in axes if a in force_dirs],
                            "framed": R != sp.eye(m), "detJa": detJa}
    if o.velocity is not None:
        va = sp.zeros(n, 1)
        for k in o.velocity:
            va[names.index(k)] = c.ctx.expr("velocity", k)
        qdot = (Jai * va).applyfunc(lambda x: tidy(sp.expand(x)))
        add("qdot", qdot, "vector", label="\\dot q")
        data.update(va=va, qdot=qdot)
    if robot is None or not has_model(robot):
        _step(sol, "hybrid_kinematics", **data)
        return sol
    dm = derive(robot)
    G = dm.G if dm.G is not None else sp.eye(n)
    if G.rows != G.cols:
        raise c.fail(("law",), "the hybrid law needs a square input map G")
    nvec = (dm.c + dm.g + (dm.Fv * dq if dm.Fv is not None else sp.zeros(n, 1))).applyfunc(tidy)
    a = sp.Matrix([fresh(problem, f"a_{k}", f"a_{{{k}}}") for k in motion_all])
    af = sp.Matrix([fresh(problem, f"af_{k}", f"a_{{f,{k}}}") for k in data["force"]])
    Gi = G.inv() if G != sp.eye(n) else G

    def law(acc: sp.Matrix, force: sp.Matrix) -> tuple[sp.Matrix, sp.Matrix]:
        ddq = (Jai * ((T * acc if T.cols else sp.zeros(n, 1)) - Jadot * dq)).applyfunc(lambda x: tidy(sp.expand(x)))
        tau = dm.B * ddq + nvec + (Jt.T * Y * force if Y.cols else sp.zeros(n, 1))
        return (Gi * tau).applyfunc(lambda x: tidy(sp.expand(x))), ddq

    u, _ = law(a, af)
    ok = decoupled(dm.B, nvec, G, Ja, Jadot, Jt, T, Y, u, a, af, q, list(dq))
    closed = sp.Matrix([sp.Symbol(f"sigma_{k}") - x for k, x in zip(motion_all, a)] +
                       [sp.Symbol(f"lambda_{k}") - x for k, x in zip(data["force"], af)])
    add("u", u, "vector", label="u")
    add("closed_loop_check", bool(ok), "bool", label="\\text{decoupled closed loop verified}")
    data.update(B=dm.B, nvec=nvec, G=G, a=a, af=af, u=u, ok=ok, T=T, Y=Y, closed=closed)
    if o.nominal is not None:
        acc = sp.zeros(len(motion_all), 1)
        fo = sp.zeros(len(data["force"]), 1)
        for key, vals in o.nominal.items():   # (keys checked by read_hybrid)
            pool = motion_all if key == "acceleration" else data["force"]
            for k in vals:
                (acc if key == "acceleration" else fo)[pool.index(k)] = c.ctx.expr("nominal", key, k)
        un, ddqn = law(acc, fo)
        add("u_nominal", un, "vector", label="u_d")
        add("ddq_nominal", ddqn, "vector", label="\\ddot q_d")
        data.update(acc=acc, fo=fo, un=un, ddqn=ddqn)
        if o.at is not None:
            subs = {}
            for k in o.at:
                sym = problem.names.get(k)
                if not isinstance(sym, sp.Symbol):
                    raise c.fail(("at", k), f"unknown name '{k}' in at:")
                subs[sym] = c.ctx.expr("at", k)
            # sin(3/10), cos(1): evaluated (their exact products are unbounded), also those tidy's Fourier form
            # of an angle left symbolic makes (cos(φ − 1) = cos φ cos 1 + sin φ sin 1)
            una = un.xreplace(subs).applyfunc(
                lambda x: evaluate_transcendental(tidy(sp.expand(evaluate_transcendental(x)))))
            add("u_nominal_at", una, "vector", label="u_d\\big|_{*}")
            data.update(at=subs, una=una)
    _step(sol, "hybrid_law", **data, raw=dict(data))
    from solver.interaction.force import _register_checks
    _register_checks(sfx)
    return sol


def _directions(c, axes: list[str]) -> tuple[list[str], list[str]]:  # type: ignore[no-untyped-def]
    o = c.options
    if o.force is None and o.motion is None:
        raise c.fail(("law",), "law: hybrid needs force: and/or motion: (the task directions of each kind)",
                     "e.g. force: [z] (the others are motion-controlled)")
    for key in ("force", "motion"):
        for i, a in enumerate(getattr(o, key) or []):
            if a not in axes:
                raise c.fail((key, i), f"'{a}' is not a task direction", "directions: " + ", ".join(axes))
            if (getattr(o, key) or []).count(a) > 1:
                raise c.fail((key, i), f"'{a}' is listed twice in {key}:")
    f = list(o.force) if o.force is not None else [a for a in axes if a not in (o.motion or [])]
    mo = list(o.motion) if o.motion is not None else [a for a in axes if a not in f]
    both = [a for a in f if a in mo]
    if both:
        raise c.fail(("motion", mo.index(both[0])) if o.motion is not None else ("force",),
                     f"direction '{both[0]}' is both force- and motion-controlled",
                     "a direction is force-controlled (the environment blocks the motion) or motion-controlled "
                     "(free, no force), not both")
    missing = [a for a in axes if a not in f and a not in mo]
    if missing:
        raise c.fail(("force",), f"direction(s) {', '.join(missing)} neither force- nor motion-controlled",
                     "list every task direction in force: or motion:")
    return f, mo


def _frame(c, m: int) -> sp.Matrix:  # type: ignore[no-untyped-def]
    if c.options.frame is None:
        return sp.eye(m)
    val = c.ctx.expr("frame")
    if shape_of(val) != (m, m):
        raise c.fail(("frame",), f"frame must be a {m}x{m} rotation matrix (task axes as columns), got shape "
                                 f"{shape_of(val)}")
    R = sp.Matrix(val)
    if any(sp.simplify(x) != 0 for x in (R.T * R - sp.eye(m))):
        raise c.fail(("frame",), "frame must be a rotation matrix (orthonormal columns)")
    return R


def _augment(c, q: list[sp.Symbol]) -> tuple[sp.Matrix | None, list[str]]:  # type: ignore[no-untyped-def]
    if c.options.augment is None:
        return None, []
    r = c.vector(("augment",), None, "augment")
    names = [e.name if isinstance(e, sp.Symbol) and e in q else f"r{i + 1}" for i, e in enumerate(r)]
    return r.jacobian(q).applyfunc(tidy), names


def decoupled(B, nvec, G, Ja, Jadot, Jt, T, Y, u, a, af, q, dq, trials: int = 3) -> bool:  # type: ignore[no-untyped-def]
    """Substituting u in B q̈ + n = G u − J_tᵀ Y λ with q̈ = J_a⁻¹(T σ − J̇_a q̇) and solving for (σ, λ) gives
    σ = a and λ = a_f: checked at random states and parameters (30 digits)."""
    rng = random.Random(11)
    syms = set().union(*[M.free_symbols for M in (B, nvec, G, Ja, Jadot, Jt, u)]) | set(a) | set(af)
    for _ in range(trials):
        pt = {s: sp.Rational(rng.randint(150, 950), 311) * (1 if (s.is_positive or rng.random() < .5) else -1)
              for s in syms}
        N = lambda M: M.xreplace(pt).evalf(30)  # noqa: E731
        Jai = N(Ja).inv()
        A = sp.Matrix.hstack(N(B) * Jai * T, N(Jt).T * Y) if Y.cols else N(B) * Jai * T
        rhs = N(G) * N(u) - N(nvec) + N(B) * Jai * N(Jadot) * N(sp.Matrix(dq))
        try:
            x = A.LUsolve(rhs)
        except (ValueError, ZeroDivisionError):
            return False
        want = N(a).col_join(N(af)) if Y.cols else N(a)
        if any(abs(complex(d)) > 1e-15 * (1 + abs(complex(w))) for d, w in zip(x - want, want)):
            return False
    return True


def check_hybrid_law(problem, ask, value) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """A hybrid law is right iff, substituted in the model, its closed loop is σ = a, λ = a_f (decoupled)."""
    from solver.interaction.force import Ctx
    sol = solve_hybrid(Ctx(problem, ask.options, ask.ctx))
    st = next((s.data["raw"] for s in sol.steps if s.name == "hybrid_law"), None)
    if st is None:
        return None
    U = sp.Matrix(value) if isinstance(value, list) else sp.Matrix([value])
    if U.shape == (1, st["u"].rows):
        U = U.T
    if U.shape != st["u"].shape:
        return PropertyVerdict(False, 0.0, [f"u must have {st['u'].rows} components"])
    ok = decoupled(st["B"], st["nvec"], st["G"], st["Ja"], st["Jadot"], st["Jt"], st["T"], st["Y"], U,
                   st["a"], st["af"], list(problem.robot.q), list(problem.robot.dq))
    if ok:
        return PropertyVerdict(True, 1.0, ["substituted in the model, the law decouples: v̇ = a in the motion "
                                           "directions and f = a_f in the force directions"])
    return PropertyVerdict(False, 0.0, ["substituted in the model, this law does not give v̇ = a and f = a_f "
                                        "(the closed loop is not decoupled)"], final=False)
