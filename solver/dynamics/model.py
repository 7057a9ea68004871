"""Euler-Lagrange dynamic model (ask kind ``dynamic_model``).

    T = Σ_i ½ m_i v_ciᵀ v_ci + ½ ω_iᵀ I_i ω_i (+ T_extra) = ½ q̇ᵀ B(q) q̇,     U = -Σ_i m_i g₀ᵀ p_ci (+ U_extra)
    C_k(q) = ½ (∂b_k/∂q + (∂b_k/∂q)ᵀ - ∂B/∂q_k),   c_k = q̇ᵀ C_k q̇,   s_kᵀ = q̇ᵀ C_k  (so Ḃ - 2S is skew)
    g(q) = (∂U/∂q)ᵀ,    B(q) q̈ + S(q, q̇) q̇ + g(q) + F_v q̇ = G u
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal, Optional, Union

import sympy as sp
from pydantic import Field

from solver.math.simplify import is_zero, tidy, tidy_matrix, velocity_terms
from solver.math.sweep import coordinate_figure
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Deferred, Resolving, Solution
from solver.spec.errors import UserError
from solver.spec.models import Strict
from solver.spec.robot import Body, Robot


@dataclass
class BodyEnergy(Resolving):
    """One body's p_c, v_c, ‖v_c‖², ω, T_i and U_i (any of them may be given Deferred: printed when first read);
    optionally the velocity terms of v_c, ‖v_c‖² and 2T_i as a report prints them (:func:`velocity_terms`), when
    the derivation has them at hand (else the report computes them from the expressions)."""

    body: Body
    pc: sp.Matrix
    vc: sp.Matrix
    v2: sp.Expr
    omega: sp.Matrix
    T: sp.Expr
    U: sp.Expr | None
    terms: tuple[list[list[sp.Expr]], list[sp.Expr], list[sp.Expr]] | None = field(  # (v_c, ‖v_c‖², 2T_i)
        default=None, metadata={"json": False})


@dataclass
class DynamicModel:
    """Every quantity of the Lagrangian model, simplified."""

    bodies: list[BodyEnergy]
    T_extra: sp.Expr
    T: sp.Expr
    B: sp.Matrix
    C: list[sp.Matrix] | None
    c: sp.Matrix
    S: sp.Matrix | None
    skew: bool | None
    U_extra: sp.Expr
    U: sp.Expr | None
    g: sp.Matrix
    Fv: sp.Matrix | None
    G: sp.Matrix | None
    u: sp.Matrix
    lhs: sp.Matrix
    notes: list[str] = field(default_factory=list)


def quadratic_form_matrix(T: sp.Expr, dq: list[sp.Symbol]) -> sp.Matrix:
    """B with T = ½ q̇ᵀ B q̇ (the Hessian of T in q̇); raises ValueError if T is not such a form."""
    B = sp.hessian(T, dq).applyfunc(tidy)
    v = sp.Matrix(dq)
    if not is_zero(sp.expand(T - (v.T * B * v)[0] / 2)):
        raise ValueError("kinetic energy is not a quadratic form in the velocities")
    return B


def body_energy(body: Body, robot: Robot) -> BodyEnergy:
    """p_c, v_c = J_v(q) q̇, ‖v_c‖², ω and T_i = ½ m ‖v_c‖² + ½ ωᵀ I ω of one body."""
    q, dq = robot.q, robot.dq
    pc = body.com.applyfunc(tidy)
    vc = (pc.jacobian(q) * sp.Matrix(dq)).applyfunc(tidy)
    v2 = tidy((vc.T * vc)[0])
    T = tidy(body.mass * v2 / 2 + (body.omega.T * body.inertia * body.omega)[0] / 2)
    U = None
    if robot.gravity is not None:
        U = tidy(-body.mass * (robot.gravity.T * pc)[0])
    return BodyEnergy(body, pc, vc, v2, body.omega, T, U)


def inertia_matrix(robot: Robot, energies: list[BodyEnergy]) -> sp.Matrix:
    """B(q) = Σ m J_vᵀ J_v + J_ωᵀ I J_ω (+ Hessian of T_extra)."""
    n, q, dq = robot.n, robot.q, robot.dq
    B = sp.zeros(n, n)
    for e in energies:
        Jv = e.pc.jacobian(q)
        Jw = e.omega.jacobian(dq)
        B += e.body.mass * Jv.T * Jv + Jw.T * e.body.inertia * Jw
    for t in robot.kinetic_extra:
        B += sp.hessian(t, dq)
    if robot.given_B is not None:
        B += robot.given_B
    return tidy_matrix(B)


def christoffel(B: sp.Matrix, q: list[sp.Symbol]) -> list[sp.Matrix]:
    """C_k = ½ (∂b_k/∂q + (∂b_k/∂q)ᵀ - ∂B/∂q_k), k = 1..n (b_k: k-th column of B)."""
    out = []
    for k, qk in enumerate(q):
        J = B[:, k].jacobian(q)
        out.append(tidy_matrix((J + J.T - B.diff(qk)) / 2))
    return out


def coriolis(C: list[sp.Matrix], dq: list[sp.Symbol]) -> sp.Matrix:
    """c_k = q̇ᵀ C_k q̇."""
    v = sp.Matrix(dq)
    return sp.Matrix([tidy((v.T * Ck * v)[0]) for Ck in C])


def factorization(C: list[sp.Matrix], dq: list[sp.Symbol]) -> sp.Matrix:
    """S with rows s_kᵀ = q̇ᵀ C_k: S q̇ = c and Ḃ - 2S skew-symmetric."""
    v = sp.Matrix(dq)
    return tidy_matrix(sp.Matrix.vstack(*[(v.T * Ck) for Ck in C]))


def is_skew_bdot_2s(B: sp.Matrix, S: sp.Matrix, robot: Robot) -> bool:
    """N = Ḃ - 2S, checked N + Nᵀ ≡ 0 exactly (N + Nᵀ is symmetric: its upper triangle)."""
    Bdot = sum((B.diff(qk) * dqk for qk, dqk in zip(robot.q, robot.dq)), sp.zeros(*B.shape))
    N = Bdot - 2 * S
    return all(is_zero(N[i, j] + N[j, i]) for i in range(N.rows) for j in range(i, N.cols))


def gravity_vector(U: sp.Expr, q: list[sp.Symbol]) -> sp.Matrix:
    """g(q) = (∂U/∂q)ᵀ."""
    return sp.Matrix([tidy(sp.diff(U, qk)) for qk in q])


def has_model(robot: Robot) -> bool:
    """Whether the robot carries mass: bodies, a given inertia matrix or added kinetic energy."""
    return bool(robot.bodies) or robot.given_B is not None or bool(robot.kinetic_extra)


def require_model(problem) -> Robot:  # type: ignore[no-untyped-def]
    """The problem's robot, or a spec error when a dynamics ask has no masses to work with."""
    robot = problem.robot
    if robot is None or not has_model(robot):
        raise UserError("this ask needs the robot's dynamics, but the robot has no bodies and no model",
                        problem.located.place(("robot",)), "add links: (explicit), dh: (DH table) or model: {B: ...}")
    return robot


_DERIVED: dict[int, tuple[Robot, DynamicModel]] = {}   # id(robot) -> (robot, model): a problem's asks share one
_DERIVED_MAX = 8


def derive(robot: Robot) -> DynamicModel:
    """The full Lagrangian model of ``robot``: in the canonical trigonometric-polynomial form throughout when the
    robot's data allow (solver.dynamics.canonical), else entry by entry with :func:`tidy`. Derived once per robot
    object (robots are not changed after loading): the asks of a problem (model, control law, regulation, ...) each
    get their own copy of the same model."""
    hit = _DERIVED.get(id(robot))
    if hit is None or hit[0] is not robot:
        if len(_DERIVED) >= _DERIVED_MAX:
            _DERIVED.pop(next(iter(_DERIVED)))
        hit = _DERIVED[id(robot)] = (robot, _derive(robot))
    return _copy(hit[1])


def _copy(dm: DynamicModel) -> DynamicModel:
    """A copy whose matrices and lists a caller may change without touching the shared model."""
    def m(x):  # type: ignore[no-untyped-def]
        return x.copy() if isinstance(x, sp.MatrixBase) else x
    return DynamicModel(list(dm.bodies), dm.T_extra, dm.T, m(dm.B), [m(x) for x in dm.C] if dm.C is not None else None,
                        m(dm.c), m(dm.S), dm.skew, dm.U_extra, dm.U, m(dm.g), m(dm.Fv), m(dm.G), m(dm.u), m(dm.lhs),
                        list(dm.notes))


def _derive(robot: Robot) -> DynamicModel:
    from solver.dynamics.canonical import derive_canonical
    fast = derive_canonical(robot)
    if fast is not None:
        return fast
    n, q, dq = robot.n, robot.q, robot.dq
    energies = [body_energy(b, robot) for b in robot.bodies]
    T_extra = tidy(sum(robot.kinetic_extra, sp.Integer(0)))
    B = inertia_matrix(robot, energies)
    T = tidy((sp.Matrix(dq).T * B * sp.Matrix(dq))[0] / 2)
    if robot.given_c is not None:
        C, c, S, skew = None, tidy_matrix(robot.given_c), None, None
    else:
        C = christoffel(B, q)
        c = coriolis(C, dq)
        S = factorization(C, dq)
        skew = is_skew_bdot_2s(B, S, robot)
    U_extra = tidy(sum(robot.potential_extra, sp.Integer(0)))
    U: sp.Expr | None = None
    if robot.given_g is not None:
        g = tidy_matrix(robot.given_g)
        if robot.potential_extra:
            g += gravity_vector(U_extra, q)
            g = tidy_matrix(g)
    else:
        U = sum((e.U for e in energies if e.U is not None), sp.Integer(0)) + U_extra
        if robot.given_U is not None:
            U += robot.given_U
        U = tidy(U)
        g = gravity_vector(U, q)
    Fv = robot.friction
    G = robot.input_map
    u = sp.Matrix(robot.inputs)
    lhs = B * sp.Matrix(robot.ddq) + c + g + (Fv * sp.Matrix(dq) if Fv is not None else sp.zeros(n, 1))
    lhs = tidy_matrix(lhs)
    return DynamicModel(energies, T_extra, T, B, C, c, S, skew, U_extra, U, g, Fv, G, u, lhs)


def model_row(dm: DynamicModel, robot: Robot, i: int) -> list[sp.Expr]:
    """Terms of the i-th equation: Σ_j b_ij q̈_j, then c_i, g_i and friction (for printing in this order)."""
    terms = [dm.B[i, j] * a for j, a in enumerate(robot.ddq) if dm.B[i, j] != 0]
    terms += velocity_terms(dm.c[i], robot.dq)
    terms += [dm.g[i]] if dm.g[i] != 0 else []
    if dm.Fv is not None:
        terms += [dm.Fv[i, j] * robot.dq[j] for j in range(robot.n) if dm.Fv[i, j] != 0]
    return terms


LARGE_MODEL = 6000  # nodes of B past which the report writes the model with abbreviations (SYMORO-style)


def node_count(m: sp.Matrix, limit: int) -> int:
    """Nodes of the expression trees of ``m``'s entries, counted up to just past ``limit``."""
    count = 0
    for x in m:
        for _ in sp.preorder_traversal(x):
            count += 1
            if count > limit:
                return count
    return count


def abbreviate(values: dict[str, sp.Matrix], coordinates: set[sp.Symbol]) -> dict:
    """The customized model of a large robot (as SYMORO writes it): each sum of parameters only (no q, q̇, q̈)
    inside ``values`` becomes K_j, defined once; {"defs": [(K_j, sum)], name: value with the K_j}."""
    defs: dict[sp.Expr, sp.Symbol] = {}
    memo: dict[sp.Expr, sp.Expr] = {}

    def rep(e: sp.Expr) -> sp.Expr:
        if e.is_Atom:
            return e
        hit = memo.get(e)
        if hit is not None:
            return hit
        if e.is_Add and not (e.free_symbols & coordinates):
            if -e in defs:
                out = -defs[-e]
            else:
                out = defs.setdefault(e, sp.Symbol(f"K_{{{len(defs) + 1}}}"))
        elif e.is_Add:  # the terms free of coordinates as one K_j, the others term by term
            free = [a for a in e.args if not (a.free_symbols & coordinates)]
            rest = [rep(a) for a in e.args if a.free_symbols & coordinates]
            out = sp.Add(rep(sp.Add(*free)) if len(free) > 1 else sp.Add(*free), *rest)
        else:
            out = e.func(*[rep(a) for a in e.args])
        memo[e] = out
        return out

    out: dict = {name: (v.applyfunc(rep) if isinstance(v, sp.MatrixBase) else [m.applyfunc(rep) for m in v])
                 for name, v in values.items() if v is not None}
    out["defs"] = [(k, e) for e, k in defs.items()]
    return out


class ModelView:
    """The model's terms in the order a report prints them, computed when a template first asks: per body the
    velocity components, ‖v_c‖² and 2T_i as velocity terms (``vc``, ``v2``, ``T2``), the rows of the model."""

    def __init__(self, dm: DynamicModel, robot: Robot) -> None:
        self.dm, self.robot = dm, robot

    @cached_property
    def vc(self) -> list[list[list[sp.Expr]]]:
        return [e.terms[0] if e.given("terms") else [velocity_terms(x, self.robot.dq) for x in e.vc]
                for e in self.dm.bodies]

    @cached_property
    def v2(self) -> list[list[sp.Expr]]:
        return [e.terms[1] if e.given("terms") else velocity_terms(e.v2, self.robot.dq) for e in self.dm.bodies]

    @cached_property
    def T2(self) -> list[list[sp.Expr]]:
        return [e.terms[2] if e.given("terms") else velocity_terms(2 * e.T, self.robot.dq) for e in self.dm.bodies]

    @cached_property
    def rows(self) -> list[list[sp.Expr]]:
        return [model_row(self.dm, self.robot, i) for i in range(self.robot.n)]


# ------------------------------------------------------------------------------------------------
class DynamicModelAsk(Strict):
    """Derive the Euler-Lagrange dynamic model."""

    kind: Literal["dynamic_model"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    show: list[Literal["energies", "B", "christoffel", "c", "S", "g", "model"]] = Field(
        ["energies", "B", "christoffel", "c", "S", "g", "model"], description="which parts to explain in the report")
    at: Optional[dict[str, Union[str, int, float]]] = Field(
        None, description="a state (q, dq, ddq values) where B, c, g and the model are also evaluated numerically")
    plots: bool = Field(True, description="figures of g(q) and B(q) along each coordinate (written with -o)")
    ranges: dict[str, tuple[float, float]] = Field(
        {}, description="plot range per coordinate, e.g. {q2: [0, 0.5]}; default [-pi, pi] (R), [-1, 1] (P)")


def _state(problem, options: DynamicModelAsk, ctx, robot: Robot) -> dict:  # type: ignore[no-untyped-def]
    """The ``at:`` state by coordinate, velocity or acceleration symbol."""
    state = {}
    for name in options.at or {}:
        if name not in problem.names or not any(name == s.name for s in robot.q + robot.dq + robot.ddq):
            raise UserError(f"'{name}' in at: is not a coordinate, velocity or acceleration",
                            problem.located.place(ctx.path + ("at", name)), "use q1, dq1, ddq1, ...")
        state[problem.names[name]] = ctx.expr("at", name)
    return state


def coordinate_ranges(problem, ranges: dict, ctx, robot: Robot, noun: str = "range") -> dict:  # type: ignore[no-untyped-def]
    """The numeric range {coordinate: (low, high)} of each coordinate named in an ask's ``ranges:``; a user error
    for a name that is no coordinate or an empty range (``noun``: what the message calls it)."""
    by_name = {s.name: s for s in robot.q}
    out = {}
    for name, (lo, hi) in ranges.items():
        if name not in by_name:
            raise UserError(f"'{name}' in ranges: is not a coordinate", problem.located.place(ctx.path + ("ranges",)),
                            "use " + ", ".join(by_name))
        if not lo < hi:
            raise UserError(f"empty {noun} for {name}: [{lo}, {hi}]",
                            problem.located.place(ctx.path + ("ranges", name)), "write [low, high] with low < high")
        out[by_name[name]] = (float(lo), float(hi))
    return out


def _plot_ranges(problem, options: DynamicModelAsk, ctx, robot: Robot) -> dict:  # type: ignore[no-untyped-def]
    """The plot range of each coordinate named in ``ranges:``."""
    return coordinate_ranges(problem, options.ranges, ctx, robot, "plot range")


def validate_dynamic_model(problem, options: DynamicModelAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_dynamic_model` reads them, without deriving the model."""
    robot = require_model(problem)
    _state(problem, options, ctx, robot)
    if options.plots:
        _plot_ranges(problem, options, ctx, robot)


@ask_kind("dynamic_model", DynamicModelAsk, "Euler-Lagrange dynamic model: T, U, B, Christoffel, c, S, g",
          validate=validate_dynamic_model)
def solve_dynamic_model(problem, options: DynamicModelAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: T, U, B, christoffel, c, S, g, model (+ T<i>, U<i>, pc<i>, vc<i> in the base frame, w<i> in the frame
    of the body's inertia and, for a body with a rotation (DH, rotation:), w<i>_0 in the base frame; skew)."""
    robot = require_model(problem)
    dm = derive(robot)
    sol = Solution("dynamic_model", title=options.title or "Dynamic model")
    for i, e in enumerate(dm.bodies, 1):  # (per-body quantities printed only when read: Deferred)
        sol.add(f"pc{i}", Deferred(lambda e=e: e.pc), "vector", label=f"p_{{c{i}}}", detail=True)
        sol.add(f"vc{i}", Deferred(lambda e=e: e.vc), "vector", label=f"v_{{c{i}}}", detail=True)
        sol.add(f"w{i}", Deferred(lambda e=e: e.omega), "vector", label=f"\\omega_{{{i}}}",
                detail=True)  # in the frame of the body's inertia
        if e.body.omega_frame == "link" and e.body.given("rotation"):  # also in the base frame: ⁰ω = ⁰R ω
            sol.add(f"w{i}_0", Deferred(lambda e=e: (e.body.rotation * e.omega).applyfunc(tidy)), "vector",
                    label=f"{{}}^0\\omega_{{{i}}}", detail=True)
        sol.add(f"T{i}", Deferred(lambda e=e: e.T), "scalar", label=f"T_{{{i}}}", detail=True)
        if e.given("U"):
            sol.add(f"U{i}", Deferred(lambda e=e: e.U), "scalar", label=f"U_{{{i}}}", detail=True)
    sol.add("T", dm.T, "scalar", label="T")
    sol.add("B", dm.B, "matrix", label="B(q)")
    if dm.C is not None:
        sol.add("christoffel", dm.C, "list", label="C_k(q)")
    sol.add("c", dm.c, "vector", label="c(q,\\dot q)")
    if dm.S is not None:
        sol.add("S", dm.S, "matrix", label="S(q,\\dot q)")
        sol.add("skew", bool(dm.skew), "bool", label="\\dot B - 2S \\text{ skew-symmetric}")
    if dm.U is not None:
        sol.add("U", dm.U, "scalar", label="U")
    sol.add("g", dm.g, "vector", label="g(q)")
    sol.add("model", dm.lhs, "vector", label="B(q)\\ddot q + c(q,\\dot q) + g(q)")
    abbr = None
    if node_count(dm.B, LARGE_MODEL) > LARGE_MODEL:
        abbr = abbreviate({"B": dm.B, "C": dm.C, "g": dm.g}, set(robot.q + robot.dq + robot.ddq))
    sol.step("model", dm=dm, show=options.show, robot=robot, view=ModelView(dm, robot), abbr=abbr)
    if options.at:
        state = _state(problem, options, ctx, robot)
        subs = {**problem.values, **{x: val.subs(problem.values) for x, val in state.items()}}  # values in at: too
        num = {k: (v.subs(subs) if hasattr(v, "subs") else v) for k, v in
               {"B": dm.B, "c": dm.c, "g": dm.g, "model": dm.lhs}.items()}
        for k, v in num.items():
            sol.add(f"{k}_at", v, label=f"{k}\\big|_{{*}}")
        sol.step("at", state=state, values=problem.values, num=num)
    if options.plots:
        add_figures(sol, dm, problem, options, ctx)
    return sol


def add_figures(sol: Solution, dm: DynamicModel, problem, options: DynamicModelAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """g_i(q) and the configuration-dependent entries b_ij(q), each along the coordinates they depend on."""
    robot: Robot = problem.robot
    by_name = {s.name: s for s in robot.q}
    ranges = _plot_ranges(problem, options, ctx, robot)
    reference = {}
    for name in options.at or {}:
        v = problem.names.get(name)
        if v in by_name.values():
            value = ctx.expr("at", name)
            if getattr(value, "is_number", False):
                reference[v] = float(value)
    n = robot.n
    gravity = [(f"$g_{{{i + 1}}}$", dm.g[i]) for i in range(n) if dm.g[i] != 0]
    inertia = [(f"$b_{{{i + 1}{j + 1}}}$", dm.B[i, j]) for i in range(n) for j in range(i, n)
               if dm.B[i, j].free_symbols & set(robot.q)]
    names = problem.latex_names
    for fig in (
        coordinate_figure("gravity", "Gravity terms $g_i(q)$ along each coordinate they depend on.", gravity,
                          robot, problem.values, reference, ranges, names) if gravity else None,
        coordinate_figure("inertia", "Configuration-dependent entries $b_{ij}(q)$ of the inertia matrix.", inertia,
                          robot, problem.values, reference, ranges, names) if inertia else None,
    ):
        if fig is not None:
            sol.figures.append(fig)


# ------------------------------------------------------------------------------------------------ grading
@property_check("S")
def check_factorization(problem, results, name, S, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Any S with S q̇ ≡ c; full credit only with Ḃ - 2S skew-symmetric when ``options.require_skew``."""
    from solver.math.equivalence import scalar_equiv
    robot, c, B = problem.robot, results.get("c"), results.get("B")
    if robot is None or c is None or not isinstance(S, list):
        return None
    try:
        S = sp.Matrix(S)
    except (ValueError, TypeError):
        return None
    n = robot.n
    if S.shape != (n, n):
        return None
    if not all(scalar_equiv(x, y).ok for x, y in zip(S * sp.Matrix(robot.dq), c.value)):
        return PropertyVerdict(False, 0.0, ["S q̇ differs from c(q, q̇): not a valid factorization"], final=False)
    skew = None
    if B is not None:
        N = sum((B.value.diff(q) * v for q, v in zip(robot.q, robot.dq)), sp.zeros(n, n)) - 2 * S
        skew = all(scalar_equiv(x, 0).ok for x in (N + N.T))
    if skew or not getattr(options, "require_skew", True):
        return PropertyVerdict(True, 1.0, ["valid factorization: S q̇ = c" + (", Ḃ - 2S skew-symmetric" if skew else "")])
    return PropertyVerdict(False, 0.5, ["S q̇ = c holds, but Ḃ - 2S is not skew-symmetric "
                                        "(build S from the Christoffel symbols)"])


@property_check("U", *[f"U{i}" for i in range(1, 13)])
def check_potential(problem, results, name, U, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """A potential energy is defined up to an additive constant: ∂(U - U_ref)/∂q ≡ 0."""
    from solver.math.equivalence import scalar_equiv
    ref = results.get(name)
    if ref is None or problem.robot is None or isinstance(U, list):
        return None
    d = U - ref.value
    if scalar_equiv(d, 0).ok or not all(scalar_equiv(sp.diff(d, q), 0).ok for q in problem.robot.q):
        return None  # equal, or really different: the reference comparison says so
    return PropertyVerdict(True, 1.0, ["equal to the reference up to an additive constant "
                                       "(fine for a potential energy)"])
