"""Properties of the dynamic model (ask kind ``dynamic_properties``).

    eigenvalues:      0 < λ_m ≤ λ_min(B(q)) ≤ λ_max(B(q)) ≤ λ_M for all q: the extreme values over q (numeric search
                      over one period of each angle, recognized in closed form at angles multiple of π/12), the
                      eigenvalues in closed form for n ≤ 2 and, with symbolic parameters, λ_M ≤ max_q tr B (termwise)
    alpha:            ‖∂g/∂q‖ ≤ α (solver.control.gravity_bound)
    factorizations:   c = S q̇; S₁ from the Christoffel symbols (Ḃ − 2S₁ skew); S₂ from the monomials of c, each
                      q̇_i q̇_j (i ≤ j) of c_k put in column i (S₂)_{ki} += γ_kij q̇_j, or S₁ + S₀ with S₀ q̇ = 0
                      when that is S₁ again; each given S checked: S q̇ ≡ c and whether Ḃ − 2S is skew
    momentum:         p = B(q) q̇, and ṗ = u + S₁ᵀ q̇ − g(q) (with S₁ the Christoffel factorization)
    inverse dynamics: u_d(t) = B(q_d) q̈_d + c(q_d, q̇_d) + g(q_d) along a given q_d(t)
    coordinates:      q = T θ: B_θ = Tᵀ B(Tθ) T, g_θ = Tᵀ g(Tθ), c_θ from the Christoffel symbols of B_θ
    feasibility:      B symmetric, independent of q₁ (the base coordinate), positive definite for all q (leading
                      principal minors of each diagonal block at the configurations where the trigonometric terms
                      are extreme: angles multiple of π/4; the conditions that hold whenever others do dropped),
                      g = ∂U/∂q (∂g/∂q symmetric)
    power:            Ė = q̇ᵀ (u − F_v q̇), U̇ = q̇ᵀ g, Ṫ = Ė − U̇, L̇ = Ṫ − U̇ at a given state
"""
from __future__ import annotations

import itertools
from typing import Any, Literal

import numpy as np
import sympy as sp
from pydantic import Field

from solver.control.gravity_bound import (
    _snap,
    abs_bound,
    gradient_bound,
    matrix_function,
    maximize,
)
from solver.dynamics.model import (
    christoffel,
    coordinate_ranges,
    coriolis,
    derive,
    require_model,
)
from solver.math.numeric import lambdify_np
from solver.math.simplify import (
    angle_symbols, evaluate_transcendental, factor_within, is_zero, tidy, tidy_expanded, tidy_matrix,
)
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Solution
from solver.spec.errors import UserError
from solver.spec.expr import as_written
from solver.spec.loader import latex_of
from solver.spec.models import ExprT, Strict
from solver.spec.robot import Robot

FINDS = ("eigenvalues", "alpha", "factorizations", "momentum", "inverse_dynamics", "coordinates", "feasibility",
         "power")


# ------------------------------------------------------------------------------------------------ math
def bdot(B: sp.Matrix, q: list[sp.Symbol], dq: list[sp.Symbol]) -> sp.Matrix:
    """Ḃ = Σ_k ∂B/∂q_k q̇_k."""
    return tidy_matrix(sum((B.diff(a) * v for a, v in zip(q, dq)), sp.zeros(*B.shape)))


def is_skew(N: sp.Matrix) -> bool:
    return all(is_zero(sp.expand(x)) for x in (N + N.T))


def monomial_factorization(c: sp.Matrix, dq: list[sp.Symbol]) -> sp.Matrix:
    """S with (S)_{ki} = Σ_{j ≥ i} γ_kij q̇_j, where c_k = Σ_{i ≤ j} γ_kij q̇_i q̇_j (each monomial in the column of
    its first velocity); a component c_k ≡ 0 gives a zero row."""
    n = len(dq)
    S = sp.zeros(n, n)
    for k in range(n):
        ck = sp.expand(c[k])
        if ck == 0:
            continue   # (Poly(0).terms() is one constant term 0, not a quadratic monomial)
        poly = sp.Poly(ck, *dq)
        for mono, coeff in poly.terms():
            idx = [i for i, e in enumerate(mono) for _ in range(e)]
            if len(idx) != 2:
                raise ValueError("c is not quadratic in the velocities")
            i, j = sorted(idx)
            S[k, i] += coeff * dq[j]
    return tidy_matrix(S)


def null_term(dq: list[sp.Symbol]) -> sp.Matrix:
    """S₀(q̇) with S₀ q̇ = 0 and S₀ + S₀ᵀ ≠ 0: the first row (q̇₂, −q̇₁, 0, ...)."""
    n = len(dq)
    S0 = sp.zeros(n, n)
    if n >= 2:
        S0[0, 0], S0[0, 1] = dq[1], -dq[0]
    return S0


def alternative_factorization(B: sp.Matrix, c: sp.Matrix, q: list[sp.Symbol], dq: list[sp.Symbol],
                              S1: sp.Matrix) -> tuple[sp.Matrix, str]:
    """A factorization S₂ ≠ S₁ (S₂ q̇ = c) with Ḃ − 2S₂ not skew: the monomial one, else S₁ + S₀."""
    Bd = bdot(B, q, dq)
    try:
        S2 = monomial_factorization(c, dq)
        if not is_skew(Bd - 2 * S2):
            return S2, "monomials"
    except ValueError:
        pass
    return tidy_matrix(S1 + null_term(dq)), "null"


def diagonal_blocks(B: sp.Matrix) -> list[list[int]]:
    """Index sets of the diagonal blocks of B (connected components of its non-zero pattern)."""
    n = B.rows
    seen, out = set(), []
    for s in range(n):
        if s in seen:
            continue
        comp, stack = [], [s]
        seen.add(s)
        while stack:
            i = stack.pop()
            comp.append(i)
            for j in range(n):
                if j not in seen and not is_zero(B[i, j]):
                    seen.add(j)
                    stack.append(j)
        out.append(sorted(comp))
    return out


def _nonneg(d: sp.Expr) -> bool:
    d = factor_within(sp.expand(d))
    return d == 0 or bool(d.is_nonnegative)


def worst_case(m: sp.Expr, q: list[sp.Symbol], revolute: set[sp.Symbol]) -> list[sp.Expr]:
    """The values of m(q) at the configurations with the angles it depends on in {k π/2} (where cos, sin and their
    squares are extreme), prismatic coordinates at 0, without the ones that are another plus something
    non-negative (they hold whenever the other does)."""
    angles = [a for a in angle_symbols(m) if a in revolute]
    others = {x: sp.Integer(0) for x in q if x in m.free_symbols and x not in angles}
    grid = [sp.Integer(0), sp.pi / 2, sp.pi, -sp.pi / 2]
    vals: list[sp.Expr] = []
    for pt in itertools.product(grid, repeat=len(angles)):
        v = sp.expand(m.xreplace({**others, **dict(zip(angles, pt))}))
        if not any(sp.expand(v - w) == 0 for w in vals):
            vals.append(v)
    kept = [v for i, v in enumerate(vals) if not any(j != i and _nonneg(v - w) for j, w in enumerate(vals))]
    # a value above the mean of two others holds when both do (cos = 0 between cos = ±1)
    return [v for i, v in enumerate(kept)
            if not any(j != i and k != i and j < k and _nonneg(v - (w + x) / 2)
                       for j, w in enumerate(kept) for k, x in enumerate(kept))]


def pd_conditions(B: sp.Matrix, q: list[sp.Symbol], revolute: set[sp.Symbol]
                  ) -> tuple[list[sp.Expr], list[sp.Expr], bool, list[tuple[list[int], list[sp.Expr]]], list[sp.Expr]]:
    """(conditions c > 0, minors, possible, per-block minors, diagonal conditions) for B(q) ≻ 0 at every q: every
    diagonal entry (necessary) and the leading principal minors of each diagonal block (Sylvester), each in its
    worst configurations (:func:`worst_case`), normalized (positive factors removed) and reduced.
    ``possible`` is False when a condition can never hold."""
    from solver.math.equivalence import normalize_condition, reduce_conditions
    blocks = diagonal_blocks(B)
    minors: list[sp.Expr] = []
    per_block = []
    possible = True

    worst: dict[sp.Expr, list[tuple[sp.Expr, sp.Expr]]] = {}   # (the diagonal entries are collected twice)

    def collect(exprs: list[sp.Expr]) -> list[sp.Expr]:
        nonlocal possible
        out: list[sp.Expr] = []
        for m in exprs:
            if m not in worst:
                worst[m] = [(v, normalize_condition(v)) for v in worst_case(m, q, revolute)]
            for v, nc in worst[m]:
                if nc == -1 or bool(v.is_nonpositive):
                    possible = False
                if nc != 1 and not any(sp.expand(nc - x) == 0 for x in out):
                    out.append(nc)
        return out

    for blk in blocks:
        M = B.extract(blk, blk)
        mins = [tidy(M[:k, :k].det()) for k in range(1, len(blk) + 1)]
        per_block.append((blk, mins))
        minors += mins
    diag = collect([B[i, i] for i in range(B.rows)])
    conds = collect([B[i, i] for i in range(B.rows)] + minors)
    return reduce_conditions(conds), minors, possible, per_block, reduce_conditions(diag)


def _real_eigenvalues(M: sp.Matrix) -> list[sp.Expr]:
    """The eigenvalues of a numeric symmetric matrix in closed form without I (cubic formulas of 3x3 matrices
    are complex-looking: then [])."""
    try:
        ev = [sp.radsimp(e) for e in M.eigenvals(multiple=True)]
    except Exception:  # noqa: BLE001 - sympy could not find the roots
        return []
    return ev if all(not e.has(sp.I) for e in ev) else []


def eigen_bounds(B: sp.Matrix, q: list[sp.Symbol], revolute: set[sp.Symbol], values: dict,
                 ranges: dict[sp.Symbol, tuple[float, float]]) -> dict[str, Any]:
    """Extreme eigenvalues of B(q) over q: numeric search with exact recognition, or termwise bounds."""
    out: dict[str, Any] = {}
    if B.rows <= 2:
        out["eigs"] = [tidy(e) for e in B.eigenvals(multiple=True)] if B.rows == 2 else [B[0, 0]]
    coords = [x for x in q if any(x in e.free_symbols for e in B)]
    Bv = B.xreplace(values)
    params = set().union(*[e.free_symbols for e in Bv]) - set(coords)
    if params:
        out["method"] = "termwise"
        out["lambda_max"] = abs_bound(sp.expand(B.trace()), set(coords), {c: ranges[c] for c in coords if c in ranges})
        return out
    missing = [c for c in coords if c not in revolute and c not in ranges]
    if missing:
        raise ValueError(f"give a range for {', '.join(map(str, missing))}")
    if not coords:
        ev = sorted(_real_eigenvalues(Bv), key=lambda e: float(sp.N(e)))
        if not ev:
            ev = [sp.Float(x, 10) for x in np.linalg.eigvalsh(np.array(Bv.evalf(), dtype=float))]
        out.update(method="constant", lambda_min=tidy(ev[0]), lambda_max=tidy(ev[-1]),
                   q_lambda_min=sp.Matrix(q) * 0, q_lambda_max=sp.Matrix(q) * 0)
        return out
    box = [ranges.get(c, (-np.pi, np.pi)) for c in coords]
    periodic = [c in revolute and c not in ranges for c in coords]
    fn = matrix_function(Bv, coords)

    def eig(pts: np.ndarray) -> np.ndarray:
        return np.linalg.eigvalsh(fn(pts))

    vmax, xmax = maximize(lambda p: eig(p)[:, -1], box, periodic)
    shift = abs(vmax) + 1.0          # maximize needs a positive objective: shift − λ_min
    vmin, xmin = maximize(lambda p: shift - eig(p)[:, 0], box, periodic)
    vmin = shift - vmin
    exact = True
    for key, v, x, pick in (("lambda_max", vmax, xmax, max), ("lambda_min", vmin, xmin, min)):
        snapped = [_snap(float(xi), c, revolute, ranges) for xi, c in zip(x, coords)]
        val: sp.Expr = sp.Float(v, 10)
        conf = sp.Matrix([sp.Float(float(x[coords.index(c)]), 6) if c in coords else sp.Integer(0) for c in q])
        if all(s is not None for s in snapped):
            at = dict(zip(coords, snapped))
            ev = _real_eigenvalues(Bv.xreplace(at).applyfunc(sp.nsimplify))
            cand = pick(ev, key=lambda e: float(sp.N(e))) if ev else None
            if cand is not None and abs(float(sp.N(cand)) - v) <= 1e-8 * max(1.0, abs(v)):
                val = sp.nsimplify(sp.radsimp(cand))
                conf = sp.Matrix([at.get(c, sp.Integer(0)) for c in q])
            else:
                exact = False
        else:
            exact = False
        out[key], out["q_" + key] = val, conf
    out["method"] = "exact" if exact else "numeric"
    return out


def affine_bound(A: sp.Matrix, coord: sp.Symbol, others: set[sp.Symbol]) -> tuple[sp.Expr, sp.Expr] | None:
    """(α, β) with ‖A(q)‖ ≤ α + β |s| for every q, s = ``coord`` unbounded: ‖A‖ ≤ ‖A‖_F ≤ ‖A_s‖_F + ‖A_0‖_F
    (A_s: the entries that depend on s, A_0: the others), each entry bounded termwise (|sin|, |cos| ≤ 1), an entry
    of A_s by u + v|s|, so that ‖A_s‖_F ≤ ‖u‖ + |s| ‖v‖ (Minkowski): α = ‖u‖ + ‖A_0‖_F, β = ‖v‖.
    None if an entry is not affine in |s| after bounding."""
    Q = sp.Dummy("Q", positive=True)
    us, vs, ws = [], [], []
    for a in A:
        if a == 0:
            continue
        b = abs_bound(sp.expand(a), others | {coord}, {coord: (-Q, Q)})
        if b is None:
            return None
        b = sp.expand(b.replace(lambda e: isinstance(e, sp.Max), lambda e: Q))
        if not b.has(Q):
            ws.append(b)
            continue
        poly = sp.Poly(b, Q)
        if poly.degree() > 1:
            return None
        vs.append(poly.coeff_monomial(Q))
        us.append(poly.coeff_monomial(1))

    def norm(xs: list[sp.Expr]) -> sp.Expr:
        return sp.sqrt(factor_within(sum((x ** 2 for x in xs), sp.Integer(0)))) if len(xs) != 1 else xs[0]

    return tidy(norm(us) + norm(ws)), tidy(norm(vs))


def change_coordinates(B: sp.Matrix, g: sp.Matrix, q: list[sp.Symbol], T: sp.Matrix, th: list[sp.Symbol],
                       dth: list[sp.Symbol], phi: sp.Matrix | None = None) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """q = T θ (or q = φ(θ) with T = ∂φ/∂θ): (B_θ, c_θ, g_θ) with B_θ = Tᵀ B(q(θ)) T, g_θ = Tᵀ g(q(θ)), c_θ from the
    Christoffel symbols of B_θ (q̇ = T θ̇: the kinetic energy is ½θ̇ᵀTᵀBTθ̇)."""
    sub = dict(zip(q, list(phi if phi is not None else T * sp.Matrix(th))))
    Bt = tidy_matrix(T.T * B.xreplace(sub) * T)
    gt = tidy_matrix(T.T * g.xreplace(sub))
    ct = coriolis(christoffel(Bt, th), dth)
    return Bt, ct, gt


# ------------------------------------------------------------------------------------------------ the ask
class GivenFactorization(Strict):
    name: str = Field(description="result prefix, e.g. S2 (results <name>_valid, <name>_skew, <name>_N)")
    S: ExprT = Field(description="the n x n matrix S(q, dq) to check")


class Candidate(Strict):
    name: str = Field(description="result prefix, e.g. MA")
    B: ExprT = Field(description="the n x n inertia matrix, in the robot's coordinates q1..qn")
    g: ExprT | None = Field(None, description="the gravity vector (default 0)")


class Fault(Strict):
    joint: int = Field(description="the joint i whose acceleration is imposed (1..n)")
    ddq: ExprT = Field(description="the imposed acceleration of joint i, e.g. -lambda2*dq2 (incipient block)")


class DynamicPropertiesAsk(Strict):
    """Properties of the dynamic model of the spec's robot."""

    kind: Literal["dynamic_properties"]
    title: str | None = Field(None, description="heading of this part in the report")
    find: list[Literal["eigenvalues", "alpha", "factorizations", "momentum", "inverse_dynamics", "coordinates",
                       "feasibility", "power", "forward_dynamics", "fault", "torque_limits", "balancing",
                       "cartesian_inertia"]] = Field(
        description="which properties")
    task: ExprT | None = Field(None, description="cartesian_inertia: the task r = f(q) (m ≤ n expressions)")
    unknowns: list[str] = Field([], description="balancing: the parameters to choose so that g(q) ≡ 0")
    ranges: dict[str, tuple[float, float]] = Field(
        {}, description="range per coordinate for the searches over q (needed for prismatic ones)")
    factorizations: list[GivenFactorization] = Field([], description="factorizations S to check")
    trajectory: ExprT | None = Field(None, description="q_d(t) for inverse_dynamics: n expressions in t")
    times: list[str | int | float] = Field([], description="times where u_d(t) is evaluated (u_d_at<k>)")
    cases: list[dict[str, str | int | float]] = Field(
        [], description="inverse_dynamics, torque_limits: parameter values substituted (u_d_case<k>, tau_lower_case<k>, ...), e.g. [{q2b: pi/2}]")
    transform: ExprT | None = Field(None, description="coordinates: the n x n matrix T with q = T θ")
    map: ExprT | None = Field(None, description="coordinates: q = φ(θ), n expressions in the new coordinates "
                                                "(a nonlinear change, e.g. q = f⁻¹(p))")
    new_coordinates: list[str] | None = Field(None, description="names of θ (default th1..thn); "
                                                                  "velocities d<name>")
    candidates: list[Candidate] = Field([], description="feasibility: other (B, g) to judge, results prefixed "
                                                           "<name>_ (B_indep_q1, det_B, pd_conditions, real_robot, ...)")
    state: dict[str, str | int | float] | None = Field(
        None, description="power: the state (q.., dq..) where Ė, U̇, Ṫ, L̇ are evaluated")
    u: ExprT | None = Field(None, description="power, forward_dynamics, fault: the input u (n expressions)")
    limits: ExprT | None = Field(None, description="torque_limits: the bounds T_i in |u_i| <= T_i (n expressions)")
    fault: Fault | None = Field(None, description="fault: the extra torque τ_f,i at one joint that imposes its "
                                                     "acceleration (B q̈ + c + g = G u − e_i τ_f,i)")


def _place(problem, ctx, *sub):  # type: ignore[no-untyped-def]
    return problem.located.place(ctx.path + tuple(sub))


def _square(problem, ctx, n: int, name: str, *sub) -> sp.Matrix:  # type: ignore[no-untyped-def]
    """The option at ``sub`` read as an n×n matrix; a user error naming ``name`` otherwise."""
    val = ctx.expr(*sub)
    try:
        M = sp.Matrix(val)
    except (TypeError, ValueError):
        M = None
    if M is None or M.shape != (n, n):
        raise UserError(f"{name} must be a {n}x{n} matrix", _place(problem, ctx, *sub))
    return M


def _ranges(problem, options: DynamicPropertiesAsk, ctx, robot: Robot) -> dict:  # type: ignore[no-untyped-def]
    """The range of each coordinate named in ``ranges:``."""
    return coordinate_ranges(problem, options.ranges, ctx, robot)


def validate_dynamic_properties(problem, options: DynamicPropertiesAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The options read and checked as :func:`solve_dynamic_properties` reads them (a robot with dynamics, the
    ranges, then each `find`'s own options by its ``_read_<find>``, the reader its solver calls), without deriving
    the model; what needs the model (B's eigenvalues, a balancing unknown absent from g(q)) is checked when
    solving."""
    robot = require_model(problem)
    _ranges(problem, options, ctx, robot)
    for what in options.find:
        reader = READERS.get(what)
        if reader is not None:
            reader(problem, options, ctx, robot)


def _read_factorizations(problem, options: DynamicPropertiesAsk, ctx, robot: Robot) -> list[sp.Matrix]:  # type: ignore[no-untyped-def]
    """The given S matrices (n x n) of ``factorizations``; the Christoffel factorization needs B (not a given c)."""
    if robot.given_c is not None:
        raise UserError("factorizations need c from B (the model gives c directly)",
                        problem.located.place(("robot", "model", "c")), "give B instead of c")
    return [_square(problem, ctx, robot.n, "S", "factorizations", k, "S") for k in range(len(options.factorizations))]


def _read_coordinates(problem, options: DynamicPropertiesAsk, ctx, robot: Robot  # type: ignore[no-untyped-def]
                      ) -> tuple[sp.Matrix, list[sp.Symbol], list[sp.Symbol], sp.Matrix | None]:
    """(T, θ, θ̇, φ) of ``coordinates``: q = T θ (T invertible n x n) or q = φ(θ) (T = ∂φ/∂θ not singular), with
    the new names, which must not be names of the problem yet (the solver registers them, not this reader)."""
    n, q = robot.n, robot.q
    if (options.transform is None) == (options.map is None):
        raise UserError("coordinates needs transform: (q = T θ) or map: (q = φ(θ))",
                        _place(problem, ctx, "find"), "add transform: [[1, 0], [1, 1]]")
    T = None
    if options.transform is not None:
        T = sp.Matrix(ctx.expr("transform"))
        if T.shape != (n, n) or T.det() == 0:
            raise UserError(f"transform must be an invertible {n}x{n} matrix",
                            _place(problem, ctx, "transform"))
    names = options.new_coordinates or [f"th{i + 1}" for i in range(n)]
    if len(names) != n:
        raise UserError(f"{len(names)} names for {n} coordinates", _place(problem, ctx, "new_coordinates"))
    th = [sp.Symbol(s, real=True) for s in names]
    dth = [sp.Symbol("d" + s, real=True) for s in names]
    for s_, ds_ in zip(th, dth):
        if problem.names.get(s_.name, s_) != s_ or problem.names.get(ds_.name, ds_) != ds_:
            raise UserError(f"'{s_.name}' is already a name of the problem",
                            _place(problem, ctx, "new_coordinates"), "choose other names")
    phi = None
    if T is None:
        raw = problem.parse_at(ctx.path + ("map",), {**problem.names, **{x.name: x for x in th + dth}})
        if not isinstance(raw, list) or len(raw) != n or any(isinstance(x, list) for x in raw):
            raise UserError(f"map must list {n} expressions q_i = φ_i(θ)", _place(problem, ctx, "map"))
        phi = sp.Matrix(raw)
        extra = phi.free_symbols & set(q)
        if extra:
            raise UserError("map must be written in the new coordinates, not in "
                            + ", ".join(sorted(x.name for x in extra)), _place(problem, ctx, "map"))
        T = phi.jacobian(th)
        if is_zero(sp.simplify(T.det())):
            raise UserError("the map q = φ(θ) is singular (its Jacobian has zero determinant)",
                            _place(problem, ctx, "map"))
    return T, th, dth, phi


def _read_feasibility(problem, options: DynamicPropertiesAsk, ctx, robot: Robot  # type: ignore[no-untyped-def]
                      ) -> list[tuple[str, sp.Matrix, sp.Matrix]]:
    """(name, B, g) of each of ``candidates``: a plain name, B n x n, g of n components (default 0)."""
    n = robot.n
    out = []
    for k, cand in enumerate(options.candidates):
        if not cand.name.isidentifier():
            raise UserError(f"candidate name '{cand.name}' is not a plain name",
                            _place(problem, ctx, "candidates", k, "name"), "use letters, digits and _")
        Bc = _square(problem, ctx, n, "B", "candidates", k, "B")
        gc = sp.Matrix(ctx.expr("candidates", k, "g")) if cand.g is not None else sp.zeros(n, 1)
        if gc.shape != (n, 1):
            raise UserError(f"g must have {n} components", _place(problem, ctx, "candidates", k, "g"))
        out.append((cand.name, Bc, gc))
    return out


@ask_kind("dynamic_properties", DynamicPropertiesAsk,
          "model properties: eigenvalue bounds of B, α, factorizations of c, momentum, inverse dynamics, "
          "other coordinates, conditions for a real robot, energy rates", validate=validate_dynamic_properties)
def solve_dynamic_properties(problem, options: DynamicPropertiesAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results by `find`: see docs/spec.md (lambda_min/max, alpha, S_skew/S_alt/..., p, u_d, B_new, conditions...)."""
    robot: Robot = require_model(problem)
    dm = derive(robot)
    n, q, dq = robot.n, robot.q, robot.dq
    revolute = {x for x, j in zip(q, robot.joints) if j == "R"}
    ranges = _ranges(problem, options, ctx, robot)
    sol = Solution("dynamic_properties", title=options.title or "Properties of the dynamic model")
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, q=q)
    for what in options.find:
        if what == "eigenvalues":
            try:
                eb = eigen_bounds(dm.B, q, revolute, problem.values, ranges)
            except ValueError as exc:
                raise UserError(str(exc), _place(problem, ctx, "find"), "add ranges: {q2: [lo, hi]}") from None
            if "eigs" in eb:
                sol.add("eig_B", eb["eigs"], "list", label="\\lambda_i(B(q))")
            for k in ("lambda_min", "lambda_max"):
                if eb.get(k) is not None:
                    sol.add(k, eb[k], "scalar", label="\\lambda_{m}" if k == "lambda_min" else "\\lambda_{M}")
                if eb.get("q_" + k) is not None:
                    sol.add("q_" + k, eb["q_" + k], "vector", label=f"q_{{{k}}}")
            sol.step("eigenvalues", **eb, trace=tidy(dm.B.trace()))
        elif what == "alpha":
            gb = gradient_bound(dm.g, q, revolute, ranges, problem.values)
            sol.add("dg_dq", gb.A, "matrix", label="\\partial g/\\partial q")
            affine = None
            if gb.method == "unbounded" and len(gb.unbounded) == 1 and gb.unbounded[0] not in revolute:
                affine = affine_bound(gb.A, gb.unbounded[0], set(gb.coords) - set(gb.unbounded))
            if affine is not None:
                sol.add("alpha", affine[0], "scalar", label="\\alpha")
                sol.add("beta", affine[1], "scalar", label="\\beta")
            else:
                sol.add("alpha", gb.alpha, "scalar", label="\\alpha")
            if gb.q_max is not None:
                sol.add("q_alpha", gb.q_max, "vector", label="q_\\alpha")
            sol.step("alpha", gb=gb, affine=affine, s=gb.unbounded[0] if affine is not None else None)
        elif what == "factorizations":
            given = _read_factorizations(problem, options, ctx, robot)
            Bd = bdot(dm.B, q, dq)
            S1 = dm.S
            S2, how = alternative_factorization(dm.B, dm.c, q, dq, S1)
            N1, N2 = tidy_matrix(Bd - 2 * S1), tidy_matrix(Bd - 2 * S2)
            sol.add("Bdot", Bd, "matrix", label="\\dot B")
            sol.add("S_skew", S1, "matrix", label="S_1")
            sol.add("N_skew", N1, "matrix", label="\\dot B - 2S_1")
            sol.add("S_alt", S2, "matrix", label="S_2")
            sol.add("N_alt", N2, "matrix", label="\\dot B - 2S_2")
            sol.add("skew_alt", is_skew(N2), "bool", label="\\dot B - 2S_2 \\text{ skew}")
            checked = []
            for f, S in zip(options.factorizations, given):
                valid = all(is_zero(sp.expand(x)) for x in (S * sp.Matrix(dq) - dm.c))
                N = tidy_matrix(Bd - 2 * S)
                skew = is_skew(N)
                sol.add(f"{f.name}_valid", valid, "bool", label=f"{f.name}\\,\\dot q = c")
                sol.add(f"{f.name}_skew", skew, "bool", label=f"\\dot B - 2{f.name} \\text{{ skew}}")
                sol.add(f"{f.name}_N", N, "matrix", label=f"\\dot B - 2{f.name}")
                checked.append((f.name, S, valid, N, skew))
            sol.step("factorizations", C=dm.C, c=dm.c, Bdot=Bd, S1=S1, N1=N1, S2=S2, N2=N2, how=how,
                     S0=null_term(dq), checked=checked, dq=dq)
        elif what == "momentum":
            p = tidy_matrix(dm.B * sp.Matrix(dq))
            sol.add("p", p, "vector", label="p = B(q)\\dot q")
            beta = tidy_matrix(dm.g - (dm.S.T * sp.Matrix(dq) if dm.S is not None else sp.zeros(n, 1)))
            if dm.S is not None:
                sol.add("beta_momentum", beta, "vector", label="\\beta = g - S^T\\dot q")
            sol.step("momentum", p=p, beta=beta if dm.S is not None else None)
        elif what == "inverse_dynamics":
            _inverse_dynamics(problem, options, ctx, sol, dm, robot)
        elif what == "coordinates":
            T, th, dth, phi = _read_coordinates(problem, options, ctx, robot)
            for s_, ds_ in zip(th, dth):
                problem.names[s_.name], problem.names[ds_.name] = s_, ds_   # expected: values may use them
                base = latex_of(s_.name).replace("th_", "\\theta_")
                problem.latex_names.setdefault(s_, base)
                problem.latex_names.setdefault(ds_, f"\\dot{{{base}}}")
            Bt, ct, gt = change_coordinates(dm.B, dm.g, q, T, th, dth, phi)
            sol.add("B_new", Bt, "matrix", label="B_\\theta")
            sol.add("c_new", ct, "vector", label="c_\\theta")
            sol.add("g_new", gt, "vector", label="g_\\theta")
            if phi is not None:
                sol.add("J_map", T, "matrix", label="\\partial\\varphi/\\partial\\theta")
            sol.step("coordinates", T=T, th=th, q=q, Bt=Bt, ct=ct, gt=gt, phi=phi,
                     Tinv=T.inv() if phi is None else None)
        elif what == "feasibility":
            candidates = _read_feasibility(problem, options, ctx, robot)
            _feasibility(sol, dm.B, dm.g, robot, revolute)
            for name, Bc, gc in candidates:
                _feasibility(sol, Bc, gc, robot, revolute, name + "_")
        elif what == "power":
            _power(problem, options, ctx, sol, dm, robot)
        elif what == "forward_dynamics":
            _forward(problem, options, ctx, sol, dm, robot)
        elif what == "fault":
            _fault(problem, options, ctx, sol, dm, robot)
        elif what == "torque_limits":
            _torque_limits(problem, options, ctx, sol, dm, robot)
        elif what == "balancing":
            _balancing(problem, options, ctx, sol, dm, robot)
        elif what == "cartesian_inertia":
            _cartesian_inertia(problem, options, ctx, sol, dm, robot)
    return sol


def cartesian_inertia(J: sp.Matrix, B: sp.Matrix) -> sp.Matrix:
    """M_p = J⁻ᵀ B J⁻¹ = adj(J)ᵀ B adj(J) / det(J)² for a square J: polynomial numerators (expanded and tidied
    once) over one denominator, each entry then written by `tidy` (no general simplification)."""
    d = tidy_expanded(J.det())
    adj = J.adjugate()
    N = (adj.T * B * adj).applyfunc(tidy_expanded)
    return tidy_matrix(N / d ** 2)


def _read_cartesian_inertia(problem, options, ctx, robot  # type: ignore[no-untyped-def]
                            ) -> tuple[sp.Matrix, sp.Matrix, dict, sp.Matrix | None]:
    """(f, J, state, J at the state) of ``cartesian_inertia``: m ≤ n task components; with a full state (every q)
    the Jacobian there (parameter values substituted) has full row rank (else None)."""
    if options.task is None:
        raise UserError("cartesian_inertia needs task: [f1(q), ...]", _place(problem, ctx, "find"),
                        "add task: [l1*cos(q1) + ..., ...]")
    val = ctx.expr("task")
    f = sp.Matrix(val if isinstance(val, list) else [val])
    q = list(robot.q)
    J = f.jacobian(q)
    m, n = J.shape
    if m > n:
        raise UserError(f"the task has {m} components for {n} joints", _place(problem, ctx, "task"))
    state = _read_state(problem, options, ctx, robot) if options.state else {}
    Ja = None
    if state and all(x in state for x in q):
        Ja = J.xreplace({**state, **problem.values})
        if Ja.rank() < m:
            raise UserError("the task Jacobian is singular at this state: no Cartesian inertia",
                            _place(problem, ctx, "state"))
    return f, J, state, Ja


def _cartesian_inertia(problem, options, ctx, sol, dm, robot) -> None:  # type: ignore[no-untyped-def]
    """M_p = (J B⁻¹ Jᵀ)⁻¹ (= J⁻ᵀ B J⁻¹ for a square J): symbolic for a square J, and at `state` (q values) with its
    eigenvalues and inverse (p̈ = M_p⁻¹ F from rest without gravity)."""
    f, J, state, Ja = _read_cartesian_inertia(problem, options, ctx, robot)
    m, n = J.shape
    sol.add("J_cart", J.applyfunc(tidy), "matrix", label="J(q)")
    Mp = None
    if m == n and sp.count_ops(J) + sp.count_ops(dm.B) <= 400:
        Mp = cartesian_inertia(J, dm.B)
        sol.add("M_p", Mp, "matrix", label="M_p(q) = J^{-T} B J^{-1}")
    at = None
    if Ja is not None:
        Ba = dm.B.xreplace({**state, **problem.values})
        Mpa = (Ja * Ba.inv() * Ja.T).inv().applyfunc(sp.nsimplify if all(x.is_Rational for x in Ja) and all(
            x.is_Rational for x in Ba) else sp.simplify)
        Mpa = Mpa.applyfunc(lambda x: sp.nsimplify(x) if x.is_Float and sp.nsimplify(x).is_Rational else x)
        eig = sorted((sp.nsimplify(e) if e.is_number else e for e in Mpa.eigenvals(multiple=True)),
                     key=lambda e: -float(sp.N(e)))
        at = {"J": Ja, "B": Ba, "Mp": Mpa, "eig": eig, "inv": Mpa.inv()}
        sol.add("M_p_at", Mpa, "matrix", label="M_p\\big|_{*}")
        sol.add("eig_M_p_at", sp.Matrix(eig), "vector", label="\\lambda_i(M_p)\\big|_{*}")
        sol.add("M_p_inv_at", at["inv"], "matrix", label="M_p^{-1}\\big|_{*}")
    sol.step("cartesian_inertia", f=f, J=J, Mp=Mp, square=m == n, state=state, at=at)


def balancing_conditions(g: sp.Matrix, q: list[sp.Symbol], revolute: set[sp.Symbol]) -> list[sp.Expr]:
    """The conditions (expressions = 0) for g(q) ≡ 0: g expanded in sin q_i, cos q_i (revolute) and q_i
    (prismatic), every coefficient of the monomials zero. Gravity terms are of degree ≤ 1 in the sine and cosine
    of each angle, where these monomials are independent functions: the conditions are then also necessary."""
    gens: list[sp.Expr] = []
    for x in q:
        gens += [sp.sin(x), sp.cos(x)] if x in revolute else [x]
    conds: list[sp.Expr] = []
    for gi in g:
        e = sp.expand(sp.expand_trig(gi))
        if e == 0:
            continue
        for c in sp.Poly(e, *gens).coeffs():
            c = factor_within(c)
            if c != 0 and all(not sp.simplify(c - d) == 0 and not sp.simplify(c + d) == 0 for d in conds):
                conds.append(c)
    return conds


def _not_in_gravity(problem, ctx, k: int, name: str) -> UserError:  # type: ignore[no-untyped-def]
    return UserError(f"'{name}' is not a parameter of g(q)",
                     _place(problem, ctx, "unknowns", k), "name parameters that appear in the gravity term")


def _read_balancing(problem, options, ctx, robot) -> list[sp.Symbol]:  # type: ignore[no-untyped-def]
    """The ``unknowns`` of ``balancing``: names of the problem that are not coordinates (whether g(q) contains
    them is checked by the solver, on the model)."""
    if not options.unknowns:
        raise UserError("balancing needs unknowns: [the parameters to choose]", _place(problem, ctx, "find"),
                        "add unknowns: [d1, d2]")
    unk = []
    for k, name in enumerate(options.unknowns):
        x = problem.names.get(name)
        if x is None or x in robot.q:
            raise _not_in_gravity(problem, ctx, k, name)
        unk.append(x)
    return unk


def _balancing(problem, options, ctx, sol, dm, robot) -> None:  # type: ignore[no-untyped-def]
    """Parameters (``unknowns``) making g(q) ≡ 0: solve the coefficient conditions."""
    unk = _read_balancing(problem, options, ctx, robot)
    for k, (name, x) in enumerate(zip(options.unknowns, unk)):
        if not (dm.g.free_symbols & {x}):
            raise _not_in_gravity(problem, ctx, k, name)
    revolute = {x for x, j in zip(robot.q, robot.joints) if j == "R"}
    g = dm.g
    conds = balancing_conditions(g, list(robot.q), revolute)
    sols = sp.solve(conds, unk, dict=True) if conds else [{}]
    # keep the solutions that meet every condition (sympy ignores the equations free of the unknowns)
    sols = [sl for sl in sols if all(is_zero(sp.simplify(c.xreplace(sl))) for c in conds)]
    sol.add("balancing_conditions", sp.Matrix(conds) if conds else sp.zeros(1, 1), "vector",
            label="\\text{conditions } (=0)")
    sol.add("balanceable", bool(sols), "bool", label="g(q) \\equiv 0 \\text{ possible}")
    vals = None
    if sols:
        vals = sp.Matrix([tidy(sols[0].get(x, x)) for x in unk])
        sol.add("balancing", vals, "vector", label="(" + ", ".join(sp.latex(x) for x in unk) + ")")
    sol.step("balancing", g=dm.g, conds=conds, unknowns=unk, sols=sols, vals=vals)


def _read_inverse_dynamics(problem, options, ctx, robot  # type: ignore[no-untyped-def]
                           ) -> tuple[sp.Symbol, list[sp.Expr], list[sp.Expr], list[dict]]:
    """(t, q_d(t), the times, the parameter values of each case) of ``inverse_dynamics``: n expressions in t."""
    n = robot.n
    if options.trajectory is None:
        raise UserError("inverse_dynamics needs trajectory: (q_d(t), n expressions in t)",
                        _place(problem, ctx, "find"), "add trajectory: [sin(t), t^2]")
    t = problem.symbols.get("t") or sp.Symbol("t", real=True)
    names = {**problem.names, "t": t}
    qd = problem.parse_at(ctx.path + ("trajectory",), names)
    if not isinstance(qd, list) or len(qd) != n:
        raise UserError(f"trajectory must be a list of {n} expressions in t", _place(problem, ctx, "trajectory"))
    times = [problem.parse_at(ctx.path + ("times", k), names) for k in range(len(options.times))]
    return t, [sp.sympify(x) for x in qd], times, _case_subs(problem, ctx, options, robot, names)


def _inverse_dynamics(problem, options, ctx, sol, dm, robot) -> None:  # type: ignore[no-untyped-def]
    t, qd, times, case_subs = _read_inverse_dynamics(problem, options, ctx, robot)
    dqd = [sp.diff(x, t) for x in qd]
    ddqd = [sp.diff(x, t, 2) for x in qd]
    sub = {**dict(zip(robot.q, qd)), **dict(zip(robot.dq, dqd)), **dict(zip(robot.ddq, ddqd))}
    ud = tidy_matrix(dm.lhs.xreplace(sub))
    sol.add("u_d", ud, "vector", label="u_d(t)")
    rows = []
    for k, tk in enumerate(times):
        v = ud.xreplace({t: tk}).applyfunc(tidy)
        sol.add(f"u_d_at{k + 1}", v, "vector", label=f"u_d(t_{k + 1})")
        rows.append((tk, v, v.xreplace(problem.values).evalf(6) if problem.values else None))
    cases = []
    for k, sub in enumerate(case_subs):
        v = ud.xreplace(sub).applyfunc(tidy)
        sol.add(f"u_d_case{k + 1}", v, "vector", label=f"u_d\\big|_{{{k + 1}}}")
        cases.append((sub, v))
    sol.step("inverse_dynamics", qd=sp.Matrix(qd), dqd=sp.Matrix(dqd), ddqd=sp.Matrix(ddqd), ud=ud, rows=rows,
             cases=cases)


def base_invariance(B: sp.Matrix, q: list[sp.Symbol], revolute: set[sp.Symbol]) -> tuple[bool, sp.Matrix | None]:
    """Whether B(q + δ v) ≡ B(q) for v = e₁ (relative coordinates: moving the first joint moves the whole robot) or
    v = the revolute coordinates all 1 (absolute angles: a rotation of the base adds δ to each of them); (ok, v)."""
    d = sp.Dummy("delta")
    cands = [sp.Matrix([int(i == 0) for i in range(len(q))]),
             sp.Matrix([int(x in revolute and any(x in a.free_symbols for a in B.atoms(sp.sin, sp.cos)))
                        for x in q])]
    for v in cands:
        if not any(v):
            continue
        shifted = B.xreplace({x: x + d * vi for x, vi in zip(q, v) if vi})
        if all(is_zero(sp.expand(sp.expand_trig(x))) for x in (shifted - B)):
            return True, v
    return False, None


def _feasibility(sol, B, g, robot, revolute, prefix: str = "") -> None:  # type: ignore[no-untyped-def]
    q = robot.q
    sym = all(is_zero(x) for x in (B - B.T))
    indep = not any(q[0] in e.free_symbols for e in B)
    invariant, shift = base_invariance(B, q, revolute)
    conds, _, possible, blocks, diag = pd_conditions(B, q, revolute)
    A = g.jacobian(q)
    conservative = all(is_zero(sp.expand(x)) for x in (A - A.T))
    real = bool(sym and invariant and possible and conservative)
    sol.add(prefix + "B_symmetric", sym, "bool", label="B = B^T")
    sol.add(prefix + "B_indep_q1", indep, "bool", label="B \\text{ independent of } q_1")
    sol.add(prefix + "B_base_invariant", invariant, "bool", label="B \\text{ invariant under a motion of the base}")
    sol.add(prefix + "det_B", tidy(B.det()), "scalar", label="\\det B(q)")
    sol.add(prefix + "diag_conditions", diag, "conditions", label="b_{ii}(q) > 0\\ \\forall q")
    sol.add(prefix + "pd_conditions", conds, "conditions", label="B(q) \\succ 0\\ \\forall q")
    sol.add(prefix + "pd_possible", possible, "bool", label="B(q) \\succ 0 \\text{ possible}")
    sol.add(prefix + "g_conservative", conservative, "bool", label="\\partial g/\\partial q \\text{ symmetric}")
    sol.add(prefix + "real_robot", real, "bool", label="\\text{can be a robot model}")
    sol.step("feasibility", label=prefix[:-1], B=B, sym=sym, indep=indep, invariant=invariant, shift=shift, conds=conds, diag=diag, blocks=blocks, possible=possible,
             conservative=conservative, real=real, A=A, det=tidy(B.det()), q1=q[0], g=g)


def _read_state(problem, options, ctx, robot) -> dict:  # type: ignore[no-untyped-def]
    state = {}
    for name in options.state or {}:
        sym = problem.names.get(name)
        if sym is None or sym not in robot.q + robot.dq:
            raise UserError(f"'{name}' in state: is not a coordinate or velocity", _place(problem, ctx, "state", name),
                            "use q1, dq1, ...")
        state[sym] = ctx.expr("state", name)
    return state


MAX_SYMBOLIC_INVERSE = 2   # B⁻¹ with symbolic parameters only up to this size (3x3 trigonometric inverses explode)


def _inverse(problem, ctx, B: sp.Matrix, q: list[sp.Symbol]) -> tuple[sp.Matrix, dict]:  # type: ignore[no-untyped-def]
    """(B⁻¹ (entries simplified), the parameter values substituted in it): beyond MAX_SYMBOLIC_INVERSE the values
    are substituted first, and the caller must substitute them in every other term too."""
    used: dict = {}
    if B.rows > MAX_SYMBOLIC_INVERSE:
        used = dict(problem.values)
        B = B.xreplace(used)
        if set().union(*[e.free_symbols for e in B]) - set(q):
            raise UserError(f"B⁻¹ of a {B.rows}x{B.rows} inertia matrix with symbolic parameters is too large",
                            _place(problem, ctx, "find"), "give numeric values: for the parameters")
    det = tidy(B.det(method="berkowitz"))
    if is_zero(det):
        raise UserError("B(q) is singular: it has no inverse", _place(problem, ctx, "find"),
                        "check the masses and inertias of the model")
    # B⁻¹ = adj(B)/det B entry by entry: Gaussian elimination on sin/cos entries grows without bound from n = 3
    return B.adjugate(method="berkowitz").applyfunc(lambda x: tidy(tidy(x) / det)), used


def _read_forward_dynamics(problem, options, ctx, robot) -> tuple[list, dict]:  # type: ignore[no-untyped-def]
    """(u, state) of ``forward_dynamics``: one input per column of G (the inputs' names allowed), the state's
    coordinates and velocities."""
    m = len(robot.inputs)
    if options.u is None:
        raise UserError("forward_dynamics needs u: [...]", _place(problem, ctx, "find"), "add u: [0, ua]")
    u = problem.parse_at(ctx.path + ("u",), {**problem.names, **{x.name: x for x in robot.inputs}})
    if not isinstance(u, list) or len(u) != m:
        raise UserError(f"u must be a list of {m} expressions", _place(problem, ctx, "u"))
    return u, _read_state(problem, options, ctx, robot)


def _forward(problem, options, ctx, sol, dm, robot) -> None:  # type: ignore[no-untyped-def]
    """q̈ = B⁻¹ (G u − c − g − F_v q̇) for the given u (at the given state, else symbolic)."""
    u, state = _read_forward_dynamics(problem, options, ctx, robot)
    G = robot.input_map if robot.input_map is not None else sp.eye(robot.n)
    v = sp.Matrix(robot.dq)
    # the state first: B(q*) and u − n(q*, q̇*) are smaller than B(q) and u − n, and numbers off the π grid
    # (q1 = 0.3) evaluated, since their exact products run to pages
    B = evaluate_transcendental(dm.B.xreplace(state))
    Binv, used = _inverse(problem, ctx, B, robot.q)
    u = [sp.sympify(x).xreplace(used) for x in u]   # the values of B⁻¹ in every term (c, g, F_v, u) too
    rhs = (G * sp.Matrix(u) - dm.c - dm.g - (dm.Fv * v if dm.Fv is not None else sp.zeros(robot.n, 1))).xreplace(used)
    state = {x: sp.sympify(e).xreplace(used) for x, e in state.items()}
    rhs = evaluate_transcendental(rhs.xreplace(state)).applyfunc(tidy)
    ddq = tidy_matrix(Binv * rhs)
    sol.add("ddq", ddq, "vector", label="\\ddot q")
    shown = {x: as_written(options.state[x.name], e) for x, e in state.items()}   # (the entries as written)
    sol.step("forward_dynamics", u=sp.Matrix(u), Binv=Binv, rhs=rhs, state=shown, ddq=ddq)


def _read_fault(problem, options, ctx, robot) -> tuple[int, list, sp.Expr]:  # type: ignore[no-untyped-def]
    """(joint i, u, the imposed q̈_i) of ``fault``."""
    n = robot.n
    if options.fault is None or options.u is None:
        raise UserError("fault needs fault: {joint: i, ddq: ...} and u: [...]", _place(problem, ctx, "find"),
                        "add fault: {joint: 2, ddq: -lambda2*dq2} and u: [tau1, tau2]")
    i = options.fault.joint
    if not 1 <= i <= n:
        raise UserError(f"joint must be between 1 and {n}", _place(problem, ctx, "fault", "joint"))
    names = {**problem.names, **{x.name: x for x in robot.inputs}}
    u = problem.parse_at(ctx.path + ("u",), names)
    m = len(robot.inputs)
    if not isinstance(u, list) or len(u) != m:
        raise UserError(f"u must be a list of {m} expressions", _place(problem, ctx, "u"))
    a = problem.parse_at(ctx.path + ("fault", "ddq"), names)
    if isinstance(a, list):
        raise UserError("ddq must be one expression", _place(problem, ctx, "fault", "ddq"))
    return i, u, a


def _fault(problem, options, ctx, sol, dm, robot) -> None:  # type: ignore[no-untyped-def]
    """B q̈ + n = G u − e_i τ_f with H = B⁻¹: q̈ = H (G u − n) − h_i τ_f, so q̈_i = a needs
    τ_f = (h_iᵀ (G u − n) − a) / h_ii, and then q̈_j = h_jᵀ (G u − n) − h_ji τ_f."""
    n = robot.n
    i, u, a = _read_fault(problem, options, ctx, robot)
    G = robot.input_map if robot.input_map is not None else sp.eye(n)
    v = sp.Matrix(robot.dq)
    H, used = _inverse(problem, ctx, dm.B, robot.q)
    u, a = [sp.sympify(x).xreplace(used) for x in u], sp.sympify(a).xreplace(used)   # the values of H everywhere
    w = (G * sp.Matrix(u) - dm.c - dm.g - (dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1))).xreplace(used)
    k = i - 1
    tau_f = tidy((H[k, :] * w)[0] / H[k, k] - a / H[k, k])
    ddq = (H * w - H[:, k] * tau_f).applyfunc(tidy)
    ddq[k] = tidy(ddq[k])
    sol.add("H", H, "matrix", label="H = B^{-1}")
    sol.add("tau_f", tau_f, "scalar", label=f"\\tau_{{f,{i}}}")
    sol.add("ddq_fault", ddq, "vector", label="\\ddot q")
    sol.step("fault", i=i, a=a, H=H, w=w.applyfunc(tidy), tau_f=tau_f, ddq=ddq)


def _case_subs(problem, ctx, options, robot, names=None) -> list[dict]:  # type: ignore[no-untyped-def]
    """The parameter values of each entry of ``cases:`` (``names``: extra symbols, e.g. of a trajectory)."""
    out = []
    for k, case in enumerate(options.cases):
        sub = {}
        for name in case:
            sym = problem.names.get(name)
            if sym is None or not isinstance(sym, sp.Symbol) or sym in robot.q + robot.dq + robot.ddq:
                raise UserError(f"'{name}' in cases: is not a parameter", _place(problem, ctx, "cases", k, name),
                                "use a symbol declared under symbols:")
            sub[sym] = problem.parse_at(ctx.path + ("cases", k, name), names)
        out.append(sub)
    return out


def _read_torque_limits(problem, options, ctx, robot) -> tuple[sp.Matrix, list[dict]]:  # type: ignore[no-untyped-def]
    """(T, the parameter values of each case) of ``torque_limits``: n bounds, one torque per coordinate."""
    n = robot.n
    if robot.input_map is not None:
        raise UserError("torque_limits needs one torque per coordinate (no input_map)", _place(problem, ctx, "find"))
    if options.limits is None:
        raise UserError("torque_limits needs limits: [T1, T2, ...]", _place(problem, ctx, "find"), "add limits: [T1, T2]")
    T = ctx.expr("limits")
    if not isinstance(T, list) or len(T) != n:
        raise UserError(f"limits must be a list of {n} expressions", _place(problem, ctx, "limits"))
    return sp.Matrix(T), _case_subs(problem, ctx, options, robot)


def _torque_limits(problem, options, ctx, sol, dm, robot) -> None:  # type: ignore[no-untyped-def]
    """|u_i| ≤ T_i with u = B q̈ + n (n = c + g + F_v q̇): −T − n ≤ B q̈ ≤ T − n, a parallelogram (n = 2) of
    accelerations with vertices B⁻¹(±T₁ − n₁, ±T₂ − n₂); the zero-torque lines b_i1 q̈₁ + b_i2 q̈₂ = 0 have slopes
    −b_i1/b_i2; q̈ = 0 is feasible iff |n_i| ≤ T_i."""
    n = robot.n
    T, case_subs = _read_torque_limits(problem, options, ctx, robot)
    v = sp.Matrix(robot.dq)
    nv = (dm.c + dm.g + (dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1))).applyfunc(tidy)
    Bq = (dm.B * sp.Matrix(robot.ddq)).applyfunc(tidy)
    lo, hi = (-T - nv).applyfunc(tidy), (T - nv).applyfunc(tidy)
    sol.add("acc_map", Bq, "vector", label="B(q)\\ddot q")
    sol.add("tau_lower", lo, "vector", label="-T - n")
    sol.add("tau_upper", hi, "vector", label="T - n")
    slopes = []
    if n == 2:
        for i in range(2):
            if not is_zero(dm.B[i, 1]):
                sl = tidy(-dm.B[i, 0] / dm.B[i, 1])
                sol.add(f"slope{i + 1}", sl, "scalar", label=f"\\text{{slope}}_{i + 1}")
                slopes.append((i + 1, sl))
    zero = reduce_conds([T[i] - nv[i] for i in range(n)] + [T[i] + nv[i] for i in range(n)])
    sol.add("zero_acc_conditions", zero, "conditions", label="\\ddot q = 0 \\text{ feasible}")
    cases = []
    for k, sub in enumerate(case_subs):
        l_k, h_k = lo.xreplace(sub).applyfunc(tidy), hi.xreplace(sub).applyfunc(tidy)
        sol.add(f"tau_lower_case{k + 1}", l_k, "vector", label=f"(-T - n)_{{{k + 1}}}")
        sol.add(f"tau_upper_case{k + 1}", h_k, "vector", label=f"(T - n)_{{{k + 1}}}")
        cases.append((sub, l_k, h_k))
    vertices = []
    if n == 2:
        Binv = dm.B.inv().applyfunc(tidy)
        for s1 in (1, -1):
            for s2 in (1, -1):
                vertices.append((Binv * sp.Matrix([s1 * T[0] - nv[0], s2 * T[1] - nv[1]])).applyfunc(tidy))
        sol.add("acc_vertices", vertices, "list", label="\\ddot q_{\\text{vertices}}")
    sol.step("torque_limits", T=T, nv=nv, Bq=Bq, lo=lo, hi=hi, slopes=slopes, zero=zero, cases=cases,
             vertices=vertices)


def reduce_conds(conds: list[sp.Expr]) -> list[sp.Expr]:
    from solver.math.equivalence import normalize_condition, reduce_conditions
    return reduce_conditions([normalize_condition(c) for c in conds])


def _read_power(problem, options, ctx, robot) -> tuple[dict, sp.Matrix]:  # type: ignore[no-untyped-def]
    """(state, u) of ``power``: both needed, u of n generalized forces."""
    n = robot.n
    if options.state is None or options.u is None:
        raise UserError("power needs state: {q.., dq..} and u: [...]", _place(problem, ctx, "find"),
                        "add state: {q1: 0, dq1: 1, ...} and u: [1, 0]")
    state = _read_state(problem, options, ctx, robot)
    u = ctx.expr("u")
    if not isinstance(u, list) or len(u) != n:
        raise UserError(f"u must be a list of {n} expressions", _place(problem, ctx, "u"))
    return state, sp.Matrix(u)


def _power(problem, options, ctx, sol, dm, robot) -> None:  # type: ignore[no-untyped-def]
    n = robot.n
    state, u = _read_power(problem, options, ctx, robot)
    v = sp.Matrix(robot.dq)
    fr = dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1)
    Edot = (v.T * (u - fr))[0]
    Udot = (v.T * dm.g)[0]
    vals = {k: tidy(x.xreplace(state).xreplace(problem.values)) for k, x in
            {"Edot": Edot, "Udot": Udot, "Tdot": Edot - Udot, "Ldot": Edot - 2 * Udot}.items()}
    labels = {"Edot": "\\dot E", "Udot": "\\dot U", "Tdot": "\\dot T", "Ldot": "\\dot L"}
    for k, x in vals.items():
        sol.add(k, x, "scalar", label=labels[k])
    sol.step("power", u=u, state=state, Edot=Edot, Udot=Udot, vals=vals, friction=dm.Fv is not None)


READERS = {"factorizations": _read_factorizations, "inverse_dynamics": _read_inverse_dynamics,
           "coordinates": _read_coordinates, "feasibility": _read_feasibility, "power": _read_power,
           "forward_dynamics": _read_forward_dynamics, "fault": _read_fault, "torque_limits": _read_torque_limits,
           "balancing": _read_balancing, "cartesian_inertia": _read_cartesian_inertia}
"""The reader of each `find` with options of its own: ``_read_<find>(problem, options, ctx, robot)``, called by its
solver and by the validate hook."""


# ------------------------------------------------------------------------------------------------ grading
def _matrix(value: Any, n: int) -> sp.Matrix | None:
    try:
        M = sp.Matrix(value)
    except (TypeError, ValueError):
        return None
    return M if M.shape == (n, n) else None


@property_check("S_skew", "S_alt", "N_skew", "N_alt")
def check_factorizations(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """S_skew: S q̇ ≡ c and Ḃ − 2S skew; S_alt: S q̇ ≡ c and Ḃ − 2S not skew. N_*: the same for S = (Ḃ − N)/2."""
    from solver.math.equivalence import scalar_equiv
    robot = problem.robot
    Bd = results.get("Bdot")
    if robot is None or Bd is None or results.get("S_skew") is None:
        return None
    n = robot.n
    M = _matrix(value, n)
    if M is None:
        return None
    S = (Bd.value - M) / 2 if name.startswith("N") else M
    if name.startswith("N") and other is not None:          # with the student's own S: N must be Ḃ − 2S
        S_own = _matrix(other("S" + name[1:]), n) if other("S" + name[1:]) is not None else None
        if S_own is not None and not all(scalar_equiv(x, 0).ok for x in (M - (Bd.value - 2 * S_own))):
            return PropertyVerdict(False, 0.0, ["N differs from Ḃ − 2S with your S"], final=False)
    c = results["S_skew"].value * sp.Matrix(robot.dq)
    if not all(scalar_equiv(x, y).ok for x, y in zip(S * sp.Matrix(robot.dq), c)):
        return PropertyVerdict(False, 0.0, ["S q̇ differs from c(q, q̇): not a factorization"], final=False)
    N = Bd.value - 2 * S
    skew = all(scalar_equiv(x, 0).ok for x in (N + N.T))
    want_skew = name.endswith("skew")
    if skew == want_skew:
        return PropertyVerdict(True, 1.0, ["S q̇ = c and Ḃ − 2S " + ("skew-symmetric" if skew else "not skew-symmetric")
                                           + ", as asked"])
    return PropertyVerdict(False, 0.5, ["S q̇ = c holds, but Ḃ − 2S is " + ("" if skew else "not ") +
                                        "skew-symmetric, which is not what was asked"])


DynamicPropertiesAsk.model_rebuild()


@property_check("beta")
def check_affine_bound(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """(α, β) with ‖∂g/∂q‖ ≤ α + β|s| for every q is not unique: the answer's β (with the answer's α, else the
    reference α) is checked at random configurations (|s| up to 100) and parameter values."""
    A, ref_alpha = results.get("dg_dq"), results.get("alpha")
    if A is None or ref_alpha is None or problem.robot is None:
        return None
    alpha = other("alpha") if other is not None else None
    alpha = ref_alpha.value if alpha is None or isinstance(alpha, list) else alpha
    if isinstance(value, list):
        return None
    beta = sp.sympify(value)
    robot = problem.robot
    coords = [x for x in robot.q if any(x in e.free_symbols for e in A.value)]
    rng = np.random.default_rng(5)
    params = sorted(set().union(*[e.free_symbols for e in A.value], alpha.free_symbols, beta.free_symbols)
                    - set(robot.q), key=lambda s: s.name)
    for trial in range(3):
        vals = {p: problem.values.get(p, sp.Float(rng.uniform(0.5, 2.0))) for p in params}
        An = lambdify_np(coords, A.value.xreplace(vals))
        a, b = float(alpha.xreplace(vals)), float(beta.xreplace(vals))
        for _ in range(200):
            rev = np.array([robot.joints[robot.q.index(c)] == "R" for c in coords])
            ang = rng.uniform(-np.pi, np.pi, len(coords)) if _ % 2 else rng.integers(-3, 5, len(coords)) * np.pi / 4
            lin = rng.choice([0.0, 0.1, 1.0, 10.0, 100.0], len(coords)) * rng.uniform(-1, 1, len(coords))
            x = np.where(rev, ang, lin)
            s = max((abs(v) for v, c in zip(x, coords) if robot.joints[robot.q.index(c)] == "P"), default=0.0)
            nrm = np.linalg.norm(np.array(An(*x), dtype=float), 2)
            if nrm > a + b * s + 1e-9:
                return PropertyVerdict(False, 0.0, [(f"not a bound: ‖∂g/∂q‖ = {nrm:.4g} > α + β|s| = {a + b * s:.4g} "
                                                     f"at q = {np.round(x, 3).tolist()}")])
    return PropertyVerdict(True, 1.0, ["α + β|s| bounds ‖∂g/∂q‖ at every sampled configuration"])
