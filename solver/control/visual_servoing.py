"""Image-based visual servoing (ask kind ``visual_servoing``): interaction matrices of point features, their null
spaces, IBVS laws and their singularities.

A point P = (X, Y, Z) in the frame of a pin-hole camera of focal length λ projects to u = λX/Z, v = λY/Z. When
the camera moves with the twist (V, Ω) (in its own frame) the point moves as Ṗ = −V − Ω × P, hence

    ṡ = J_p(u, v, Z) (V; Ω),   J_p = [ −λ/Z   0    u/Z   uv/λ      −(λ + u²/λ)   v ]
                                     [  0   −λ/Z   v/Z   λ + v²/λ  −uv/λ        −u ]

Polar coordinates ρ = √(u² + v²), θ = atan2(v, u): (u̇, v̇) = J_t (ρ̇, θ̇), J_t = [[cθ, −ρ sθ], [sθ, ρ cθ]], det J_t = ρ,
so J_polar = J_t⁻¹ J_p(ρ cθ, ρ sθ, Z) (undefined at ρ = 0; J_t^DLS = J_tᵀ(σ² I + J_t J_tᵀ)⁻¹ stays bounded).
Several points stack their matrices; the average (barycenter) of n points has J̄ = (1/n) Σ J_pi.
Camera motions that leave the features still are the null space of J; the IBVS law is (V; Ω) = k J^# (s_d − s)
(or q̇ = k (J J_m)^# e + (I − J^# J) q̇₀ through a robot's camera Jacobian J_m), and the scalar task η = ‖e‖ has
J_η = −eᵀ J / η, J_η^# = −η Jᵀ e / (eᵀ J Jᵀ e). Numerically the rank counts the singular values above
``tol`` · max(1, σ₁).
"""
from __future__ import annotations

import random
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import BaseModel, Field, field_validator, model_validator

from solver.math.numeric import lambdify_np
from solver.math.simplify import factor_within, rational_matrix, tidy, zero_or_simplified
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
MAX_POINTS = 12
MAX_STEPS = 20_000


class SimulateSpec(BaseModel):
    """A simulated IBVS run with the numeric data (the camera moves, the 3D points stay)."""

    model_config = {"extra": "forbid"}
    time: float = Field(5.0, gt=0, le=1e4, description="duration of the simulation")
    steps: int = Field(1000, ge=10, le=MAX_STEPS, description="integration steps (RK4)")
    depth: Literal["true", "desired", "constant"] = Field(
        "true", description="depth used in the law: the current one (true), the desired one, or the initial one")

    @field_validator("depth", mode="before")
    @classmethod
    def _yaml_true(cls, v: Any) -> Any:
        """YAML reads an unquoted ``depth: true`` as the boolean: it means the current depth."""
        return "true" if v is True else v


class VisualServoingAsk(Strict):
    """Interaction matrix of point features (Cartesian or polar), of their average, null space, IBVS law."""

    kind: Literal["visual_servoing"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    points: ExprT = Field(description="the point features, one [u, v, Z] per point ([rho, theta, Z] in polar "
                                      "coordinates); a single point may be written [u, v, Z]")
    coordinates: Literal["cartesian", "polar"] = Field("cartesian", description="image coordinates of the points")
    focal: Scalar = Field("lambda", description="focal length λ (an expression; declare the symbol lambda)")
    feature: Literal["points", "average"] = Field(
        "points", description="points: every point's (u, v) stacked; average: their barycenter (ū, v̄)")
    at: Optional[dict[str, Scalar]] = Field(None, description="numeric values of symbols (with the problem's "
                                                              "values) for ranks, singular values and the law")
    tol: float = Field(1e-9, gt=0, lt=1, description="numeric rank: singular values above tol·max(1, σ₁)")
    desired: Optional[ExprT] = Field(None, description="desired feature vector s_d (same size as s): IBVS law")
    gain: Scalar = Field("k", description="IBVS gain k (an expression)")
    norm: bool = Field(False, description="also the scalar task η = ‖s_d − s‖: J_η and J_η^#")
    robot_jacobian: Optional[ExprT] = Field(None, description="J_m (6×n): camera twist = J_m q̇ (eye-in-hand); "
                                                              "the law is then in q̇")
    qdot0: Optional[ExprT] = Field(None, description="with robot_jacobian: q̇₀ projected in the null space")
    damping: Optional[Scalar] = Field(None, description="polar: σ of the damped inverse J_t^DLS (an expression)")
    simulate: Optional[SimulateSpec] = Field(None, description="IBVS run (numeric points and desired features): "
                                                               "image-plane paths and error plots")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")

    @model_validator(mode="after")
    def _check(self) -> "VisualServoingAsk":
        if self.simulate is not None and self.desired is None:
            raise ValueError("simulate: needs desired: (the desired features)")
        if self.qdot0 is not None and self.robot_jacobian is None:
            raise ValueError("qdot0: needs robot_jacobian:")
        if self.norm and self.desired is None:
            raise ValueError("norm: true needs desired: (e = s_d − s)")
        if self.coordinates == "polar" and self.feature == "average":
            raise ValueError("the average feature is given in Cartesian coordinates")
        return self


# ------------------------------------------------------------------------------------------------ the math
def point_matrix(u: sp.Expr, v: sp.Expr, Z: sp.Expr, lam: sp.Expr) -> sp.Matrix:
    """J_p(u, v, Z): ṡ = J_p (V; Ω) for s = (u, v), Ṗ = −V − Ω × P."""
    return sp.Matrix([[-lam / Z, 0, u / Z, u * v / lam, -(lam + u ** 2 / lam), v],
                      [0, -lam / Z, v / Z, lam + v ** 2 / lam, -u * v / lam, -u]])


def projection(P: sp.Matrix, lam: sp.Expr) -> sp.Matrix:
    """(u, v) = λ (X, Y) / Z."""
    return sp.Matrix([lam * P[0] / P[2], lam * P[1] / P[2]])


def polar_jacobian(rho: sp.Expr, theta: sp.Expr) -> sp.Matrix:
    """J_t = ∂(u, v)/∂(ρ, θ) for u = ρ cos θ, v = ρ sin θ."""
    return sp.Matrix([[sp.cos(theta), -rho * sp.sin(theta)], [sp.sin(theta), rho * sp.cos(theta)]])


def polar_matrix(rho: sp.Expr, theta: sp.Expr, Z: sp.Expr, lam: sp.Expr) -> sp.Matrix:
    """J_polar = J_t⁻¹ J_p(ρ cos θ, ρ sin θ, Z)."""
    Jt_inv = sp.Matrix([[sp.cos(theta), sp.sin(theta)], [-sp.sin(theta) / rho, sp.cos(theta) / rho]])
    return (Jt_inv * point_matrix(rho * sp.cos(theta), rho * sp.sin(theta), Z, lam)).applyfunc(tidy)


def dls_inverse(J: sp.Matrix, sigma: sp.Expr) -> sp.Matrix:
    """J^DLS = Jᵀ (σ² I + J Jᵀ)⁻¹ = Jᵀ adj(M) / det M with M = σ² I + J Jᵀ tidied first (cos²θ + sin²θ = 1 in
    its entries), each entry then factored; sympy's inverse and simplify only when det M tidies to 0."""
    M = (sigma ** 2 * sp.eye(J.shape[0]) + J * J.T).applyfunc(tidy)
    d = tidy(M.det())
    if d == 0:  # (σ = 0 and J Jᵀ singular: no inverse, sympy says so)
        return (J.T * M.inv()).applyfunc(lambda x: _factored(sp.simplify(x)))
    return (J.T * M.adjugate()).applyfunc(lambda x: _factored(tidy(x) / d))


def average(mats: list[sp.Matrix]) -> sp.Matrix:
    """(1/n) Σ J_i, entry by entry with the common factors of the sums pulled out."""
    n = len(mats)
    S = sum(mats[1:], mats[0])
    return S.applyfunc(lambda x: sp.factor_terms(sp.expand(x)) / n)


def _laurent_content(xs: list[sp.Expr]) -> sp.Expr:
    """The common monomial factor (powers of symbols, possibly negative) of every term of every entry."""
    terms = [t for x in xs for t in sp.Add.make_args(sp.expand(x)) if t != 0]
    if not terms:
        return sp.Integer(1)
    common: Optional[dict] = None
    for t in terms:
        pw = {b: e for b, e in t.as_powers_dict().items() if b.is_Symbol and e.is_Integer}
        if common is None:
            common = pw
        else:
            common = {b: (min(e, pw[b]) if e > 0 else max(e, pw[b])) for b, e in common.items()
                      if b in pw and (e > 0) == (pw[b] > 0)}
    return sp.Mul(*[b ** e for b, e in (common or {}).items()])


def content_free(vec: sp.Matrix) -> sp.Matrix:
    """vec divided by the monomial factor common to all its terms (1/Z in (u/Z, v/Z, λ/Z))."""
    c = _laurent_content(list(vec))
    return vec.applyfunc(lambda x: sp.expand(x / c)) if c != 1 else vec


def primitive(vec: sp.Matrix) -> sp.Matrix:
    """vec divided by the rational content of its terms (the gcd of their numeric coefficients): (0, 0, 4) ->
    (0, 0, 1), (1/2, 1/3) -> (3, 2); the signs as they are."""
    coeffs = [t.as_coeff_Mul()[0] for x in vec for t in sp.Add.make_args(sp.expand(x)) if t != 0]
    if not coeffs or not all(c.is_Rational for c in coeffs):
        return vec
    c = sp.Integer(0)
    for x in coeffs:
        c = sp.gcd(c, abs(x))
    return vec if c in (0, 1) else vec.applyfunc(lambda x: sp.expand(x / c) if x.is_number else sp.factor_terms(x / c))


def cleared(vec: sp.Matrix) -> sp.Matrix:
    """vec times the lcm of its denominators, divided by the gcd of the numerators, with the last non-zero entry's
    leading coefficient positive (a canonical representative of the direction)."""
    nums = _cleared_sparse(vec)
    if nums is None:
        nums = _cleared_sympy(vec)
    last = [x for x in nums if x != 0]
    if last:
        lead = sp.Poly(last[-1], *sorted(last[-1].free_symbols, key=str)).LC() if last[-1].free_symbols else last[-1]
        if lead.is_number and lead < 0:
            nums = [-x for x in nums]
    return sp.Matrix([_shorter_factored(x) if x.free_symbols else x for x in nums])


def _cleared_sympy(vec: sp.Matrix) -> list[sp.Expr]:
    """The numerators of :func:`cleared` by sympy's cancel, lcm and gcd (any entries; gcds only, no multivariate
    factoring)."""
    fr = [sp.fraction(sp.cancel(sp.together(x))) for x in vec]
    den = sp.Integer(1)
    for _, d in fr:
        den = sp.lcm(den, d)
    nums = [sp.expand(sp.cancel(x * den)) for x in vec]
    g = sp.Integer(0)
    for x in nums:
        if x != 0:
            g = sp.gcd(g, x)
    return [sp.cancel(x / g) for x in nums] if g != 0 and g != 1 else nums


def _cleared_sparse(vec: sp.Matrix) -> list[sp.Expr] | None:
    """The numerators of :func:`cleared` (times the lcm of the denominators, over the gcd of the numerators, with
    integer coefficients and no common integer factor) in the sparse field of rational functions of the
    symbols; None where the entries are not such functions (then sympy's cancel/lcm/gcd do it)."""
    from math import lcm
    dM = rational_matrix(vec) if len(vec) else None
    if dM is None or not dM.domain.is_FractionField:
        return None
    R = dM.domain.field.ring
    fr = [dM[i, 0].element for i in range(vec.rows)]
    den = R.one
    for f in fr:
        if f:
            den = den.lcm(f.denom)
    nums = [f.numer * den.exquo(f.denom) if f else R.zero for f in fr]
    if not R.domain.is_ZZ:  # one common integer multiplier: integer coefficients
        m = lcm(*[int(c.denominator) for p in nums for c in p.itercoeffs()] or [1])
        Z = R.clone(domain=sp.ZZ)
        nums = [Z.from_dict({k: int(c * m) for k, c in p.iterterms()}) for p in nums]
        R = Z
    g = R.zero
    for p in nums:
        if p:
            g = p if not g else g.gcd(p)
    if g and g != R.one:
        nums = [p.exquo(g) for p in nums]
    return [p.as_expr() for p in nums]


def _factored(x: sp.Expr, budget: float = 1.0) -> sp.Expr:
    """factor_within(x) within a 1 s CPU budget (:func:`solver.math.simplify.factor_within`)."""
    return factor_within(x, budget)


def _shorter_factored(x: sp.Expr) -> sp.Expr:
    """x factored (within the budget) when that is shorter."""
    f = _factored(x)
    return f if sp.count_ops(f) < sp.count_ops(x) else x


def null_basis(J: sp.Matrix) -> list[sp.Matrix]:
    """A basis of N(J) (reduced row echelon form: the free entries are the unit vectors, as Matlab's null(J, 'r'))."""
    return [v.applyfunc(tidy) for v in J.nullspace(simplify=True)]


def generic_rank(J: sp.Matrix, rng: random.Random, exclude: Optional[dict] = None) -> int:
    """Rank at a random rational point (the rank for almost every value of the symbols)."""
    syms = sorted(J.free_symbols, key=str)
    best = 0
    for _ in range(2):
        sub = {s: sp.Rational(rng.randint(1, 97), rng.randint(1, 13)) * (1 if s.is_positive else rng.choice((1, -1)))
               for s in syms}
        try:
            best = max(best, J.subs(sub).rank())
        except (ZeroDivisionError, ValueError):
            continue
    return best


def _float_rank(M: sp.Matrix, rng: random.Random, tol: float = 1e-9) -> int:
    """Rank at a random point of the symbols (floating point, singular values above tol·max(1, σ₁))."""
    syms = sorted(M.free_symbols, key=str)
    f = lambdify_np(syms, M)
    best = 0
    for _ in range(2):
        args = [rng.uniform(0.3, 2.0) * (1 if s.is_positive else rng.choice((1, -1))) for s in syms]
        A = np.array(f(*args), dtype=float)
        if np.all(np.isfinite(A)):
            best = max(best, numeric_rank(A, tol)[0])
    return best


def numeric_rank(A: np.ndarray, tol: float) -> tuple[int, np.ndarray]:
    """Rank from the singular values σ_i > tol·max(1, σ₁), and the singular values."""
    s = np.linalg.svd(A, compute_uv=False)
    return int(np.sum(s > tol * max(1.0, s[0] if s.size else 0.0))), s


def pinv_row(Jrow: sp.Matrix) -> sp.Matrix:
    """J^# = Jᵀ / (J Jᵀ) of a 1×n row."""
    return Jrow.T / (Jrow * Jrow.T)[0, 0]


def simulate_ibvs(P0: np.ndarray, s_d: np.ndarray, lam: float, k: float, T: float, steps: int, average_of: bool,
                  depth: str, Z_d: Optional[np.ndarray] = None) -> dict[str, np.ndarray]:
    """IBVS run: 3D points P_i (camera frame) with Ṗ_i = −V − Ω × P_i, (V; Ω) = k Ĵ^# (s_d − s) (RK4).
    Returns times, image points (steps+1, n, 2), errors (steps+1)."""
    n = P0.shape[0]
    Z0 = P0[:, 2].copy()

    def feats(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        uv = lam * P[:, :2] / P[:, 2:3]
        return uv, (uv.mean(0) if average_of else uv.reshape(-1))

    def J_of(uv: np.ndarray, Z: np.ndarray) -> np.ndarray:
        rows = []
        for (u, v), z in zip(uv, Z):
            rows.append([[-lam / z, 0, u / z, u * v / lam, -(lam + u * u / lam), v],
                         [0, -lam / z, v / z, lam + v * v / lam, -u * v / lam, -u]])
        J = np.array(rows)
        return J.mean(0) if average_of else J.reshape(2 * n, 6)

    def rhs(P: np.ndarray) -> np.ndarray:
        uv, s = feats(P)
        Z = P[:, 2] if depth == "true" else (Z_d if depth == "desired" and Z_d is not None else Z0)
        tw = k * np.linalg.pinv(J_of(uv, Z)) @ (s_d - s)
        V, W = tw[:3], tw[3:]
        return -V[None, :] - np.cross(W[None, :], P)

    h = T / steps
    P = P0.astype(float).copy()
    ts, imgs, errs = [0.0], [feats(P)[0]], [float(np.linalg.norm(s_d - feats(P)[1]))]
    for i in range(steps):
        k1 = rhs(P)
        k2 = rhs(P + h / 2 * k1)
        k3 = rhs(P + h / 2 * k2)
        k4 = rhs(P + h * k3)
        P = P + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not np.all(np.isfinite(P)) or np.any(P[:, 2] <= 0):
            break
        ts.append((i + 1) * h)
        uv, s = feats(P)
        imgs.append(uv)
        errs.append(float(np.linalg.norm(s_d - s)))
    return {"t": np.array(ts), "uv": np.array(imgs), "err": np.array(errs)}


# ------------------------------------------------------------------------------------------------ the ask
def _points(problem, ctx, options: VisualServoingAsk) -> list[list[sp.Expr]]:  # type: ignore[no-untyped-def]
    raw = ctx.expr("points")
    shp = shape_of(raw)
    place = problem.located.place(ctx.path + ("points",))
    if shp == (3,):
        raw, shp = [raw], (1, 3)
    if len(shp) != 2 or shp[1] != 3:
        names = "[rho, theta, Z]" if options.coordinates == "polar" else "[u, v, Z]"
        raise UserError(f"points: must be a list of {names} triples", place, "e.g. [[u1, v1, Z1], [u2, v2, Z2]]")
    if shp[0] > MAX_POINTS:
        raise UserError(f"at most {MAX_POINTS} points", place)
    return [[sp.sympify(x) for x in p] for p in raw]


def _values(problem, ctx, options: VisualServoingAsk) -> dict:  # type: ignore[no-untyped-def]
    vals = dict(problem.values)
    if options.at:
        for k in options.at:
            sym = problem.names.get(k)
            if not isinstance(sym, sp.Symbol):
                raise UserError(f"at: '{k}' is not a declared symbol", problem.located.place(ctx.path + ("at", k)))
            vals[sym] = sp.sympify(ctx.expr("at", k))
    return vals


def _matrix(problem, ctx, field: str, rows: Optional[int] = None) -> sp.Matrix:  # type: ignore[no-untyped-def]
    raw = ctx.expr(field)
    shp = shape_of(raw)
    place = problem.located.place(ctx.path + (field,))
    if len(shp) == 1:
        M = sp.Matrix(raw)
    elif len(shp) == 2 and shp[1] > 0:
        M = sp.Matrix(raw)
    else:
        raise UserError(f"{field}: a vector or a matrix is needed", place)
    if rows is not None and M.shape[0] != rows:
        raise UserError(f"{field}: {rows} rows expected, got {M.shape[0]}", place)
    return M


def _field(problem, ctx, options: BaseModel, field: str) -> sp.Expr:  # type: ignore[no-untyped-def]
    """The parsed field, or its default name (a declared symbol, else a positive symbol of that name)."""
    if field in options.model_fields_set:
        return sp.sympify(ctx.expr(field))
    name = str(getattr(options, field))
    return problem.names.get(name, sp.Symbol(name, positive=True))


def _num(M: sp.Matrix, vals: dict) -> Optional[np.ndarray]:
    X = M.subs(vals)
    if X.free_symbols:
        return None
    try:
        return np.array(X.evalf(20).tolist(), dtype=float)
    except TypeError:
        return None


def _show(M: sp.Matrix) -> sp.Matrix:
    return M.applyfunc(lambda x: x if not x.is_number or x.is_Rational else sp.Float(x, 6))


def _desired(problem, ctx, rows: int) -> sp.Matrix:  # type: ignore[no-untyped-def]
    """s_d, with as many components as s."""
    sd = _matrix(problem, ctx, "desired")
    if sd.shape != (rows, 1):
        raise UserError(f"desired: {rows} components expected (as s), got {sd.shape[0]}",
                        problem.located.place(ctx.path + ("desired",)))
    return sd


def validate_visual_servoing(problem, options: VisualServoingAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_visual_servoing` reads them (focal length, points,
    damping, gain, state, robot Jacobian, desired features), without the interaction matrices."""
    _field(problem, ctx, options, "focal")
    pts = _points(problem, ctx, options)
    if options.coordinates == "polar" and options.damping is not None:
        sp.sympify(ctx.expr("damping"))
    _field(problem, ctx, options, "gain")
    _values(problem, ctx, options)
    if options.robot_jacobian is not None:
        _matrix(problem, ctx, "robot_jacobian", rows=6)
    if options.desired is not None:
        _desired(problem, ctx, 2 if options.feature == "average" else 2 * len(pts))


@ask_kind("visual_servoing", VisualServoingAsk,
          "interaction matrix of point features (Cartesian, polar, average), null space, IBVS law",
          validate=validate_visual_servoing)
def solve_visual_servoing(problem, options: VisualServoingAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the suffix): J_p1.. (per point), J_s, J_v, J_omega, s, rank, rank_v, rank_omega, dim_null,
    dim_null_v, dim_null_omega, null_motions, null_motions_cleared, null_translation, null_rotation,
    null_axis_motion; polar: J_t, det_J_t, J_t_inv, J_p_t, J_polar (= J_s), J_t_dls, det_J_t_dls; average:
    barycenter; with desired: e, law; with norm: eta, J_eta, J_eta_pinv; with robot_jacobian: J_task, law_q;
    with numbers: J_at, sigma_at, rank_at, cond_at, singular_at, law_at."""
    sfx = options.suffix
    sol = Solution("visual_servoing", title=options.title or "Visual servoing")
    lam = _field(problem, ctx, options, "focal")
    pts = _points(problem, ctx, options)
    n = len(pts)
    polar = options.coordinates == "polar"
    rng = random.Random(7)

    def add(name: str, value: Any, kind: Optional[str] = None, label: str = "") -> Any:
        return sol.add(name + sfx, value, kind, label=label)

    mats, cart = [], []
    for i, (a, b, Z) in enumerate(pts, 1):
        if polar:
            Jp = polar_matrix(a, b, Z, lam)
            cart.append((a * sp.cos(b), a * sp.sin(b), Z))
        else:
            Jp = point_matrix(a, b, Z, lam)
            cart.append((a, b, Z))
        mats.append(Jp)
        if n > 1:
            add(f"J_p{i}", Jp, "matrix", label=f"J_{{p{i}}}")
    data: dict[str, Any] = {"n": n, "polar": polar, "feature": options.feature, "lam": lam, "points": pts,
                            "mats": mats, "dls": None, "N": None, "Jm": None, "e": None, "norm": False,
                            "Jn": None, "law_at": None, "decoupled": None}
    if polar:
        rho, th, Z = pts[0]
        Jt = polar_jacobian(rho, th)
        add("J_t", Jt, "matrix", label="J_t(\\rho, \\theta)")
        add("det_J_t", tidy(Jt.det()), "scalar", label="\\det J_t")
        Jti = Jt.inv().applyfunc(tidy)
        add("J_t_inv", Jti, "matrix", label="J_t^{-1}")
        Jpt = point_matrix(rho * sp.cos(th), rho * sp.sin(th), Z, lam)
        add("J_p_t", Jpt, "matrix", label="J_p(\\rho\\cos\\theta, \\rho\\sin\\theta)")
        data.update(Jt=Jt, Jti=Jti, Jpt=Jpt, det_Jt=tidy(Jt.det()))
        if options.damping is not None:
            sig = sp.sympify(ctx.expr("damping"))
            D = dls_inverse(Jt, sig)
            dD = _factored(sp.simplify(D.det()))
            add("J_t_dls", D, "matrix", label="J_t^{DLS}")
            add("det_J_t_dls", dD, "scalar", label="\\det J_t^{DLS}")
            data.update(dls=D, det_dls=dD, sigma=sig)
    if options.feature == "average":
        J = average(mats)
        s = sp.Matrix([sum(p[0] for p in cart) / n, sum(p[1] for p in cart) / n])
        add("barycenter", s, "vector", label="\\bar s")
    else:
        J = sp.Matrix.vstack(*mats)
        s = sp.Matrix([x for p in (pts if polar else cart) for x in p[:2]])
    add("s", s, "vector", label="s")
    add("J_s", J, "matrix", label="J_s" if options.feature == "points" else "\\bar J")
    if polar:
        add("J_polar", J, "matrix", label="J_{p,polar}")
    Jv, Jw = J[:, :3], J[:, 3:]
    add("J_v", Jv, "matrix", label="J_v")
    add("J_omega", Jw, "matrix", label="J_\\omega")
    if J.rows == 2:
        dec = sp.Matrix([[_single_row(J[:, j]) for j in range(6)]])
        add("decoupled", dec, "matrix", label="\\text{decoupled}")
        data["decoupled"] = dec
    r, rv, rw = generic_rank(J, rng), generic_rank(Jv, rng), generic_rank(Jw, rng)
    add("rank", sp.Integer(r), "number", label="\\operatorname{rank} J")
    add("rank_v", sp.Integer(rv), "number", label="\\operatorname{rank} J_v")
    add("rank_omega", sp.Integer(rw), "number", label="\\operatorname{rank} J_\\omega")
    add("dim_null", sp.Integer(6 - r), "number", label="\\dim\\mathcal N(J)")
    add("dim_null_v", sp.Integer(3 - rv), "number", label="\\dim\\mathcal N(J_v)")
    add("dim_null_omega", sp.Integer(3 - rw), "number", label="\\dim\\mathcal N(J_\\omega)")
    data.update(J=J, Jv=Jv, Jw=Jw, s=s, rank=r, rank_v=rv, rank_w=rw)

    # ---- null space
    if J.rows <= 2 or (J.rows <= 4 and len(J.free_symbols) <= 6):
        N = null_basis(J)
        if N:
            Nm = sp.Matrix.hstack(*N)
            add("null_motions", Nm, "matrix", label="N")
            Nc = sp.Matrix.hstack(*[cleared(v) for v in N])
            add("null_motions_cleared", Nc, "matrix", label="N_c")
            data.update(N=Nm, Nc=Nc)
    special = _special_motions(J, Jv, Jw, cart, lam, options.feature, polar)
    for name, (vec, label) in special.items():
        add(name, vec, "vector", label=label)
    data["special"] = {k: v[0] for k, v in special.items()}

    # ---- laws
    k = _field(problem, ctx, options, "gain")
    vals = _values(problem, ctx, options)
    Jm = None
    if options.robot_jacobian is not None:
        Jm = _matrix(problem, ctx, "robot_jacobian", rows=6)
        Jtask = J * Jm
        add("J_task", Jtask, "matrix", label="J_s J_m")
        data["Jm"] = Jm
    if options.desired is not None:
        sd = _desired(problem, ctx, s.shape[0])
        e = sd - s
        add("e", e, "vector", label="e = s_d - s")
        Jlaw = J if Jm is None else J * Jm  # ė = −k Jlaw Jlaw^# e: −k e only when Jlaw has full row rank
        rank_law = r if Jm is None else generic_rank(Jlaw, random.Random(7))
        data.update(sd=sd, e=e, k=k)
        if rank_law < Jlaw.rows:  # (rows, columns, rank) of a J without full row rank
            data["deficient"] = (Jlaw.rows, Jlaw.cols, rank_law)
        if options.norm:
            Jfull = J if Jm is None else J * Jm
            eta = sp.sqrt(sum((x ** 2 for x in e), sp.Integer(0)))
            w = Jfull.T * e                      # Jᵀe
            s2 = (w.T * w)[0, 0]                 # eᵀ J Jᵀ e
            Jeta = -w.T / eta
            Jeta_pinv = -eta * w / s2
            add("eta", eta, "scalar", label="\\eta")
            add("J_eta", Jeta, "matrix", label="J_\\eta")
            add("J_eta_pinv", Jeta_pinv, "vector", label="J_\\eta^\\#")
            law_eta = k * Jeta_pinv * (0 - eta)  # the error on η is η_d − η = −η
            add("law_eta", law_eta, "vector", label="\\dot q" if Jm is not None else "(V; \\Omega)")
            # J_η J_η^# = (wᵀw)/s2 = 1 (the same expression), so η̇ = J_η q̇ = −kη exactly
            add("eta_dot", -k * eta * ((w.T * w)[0, 0] / s2), "scalar", label="\\dot\\eta")
            P = sp.eye(Jfull.cols) - w * w.T / s2
            rP = _float_rank(P, rng)
            add("P_eta", P, "matrix", label="P = I - J_\\eta^\\# J_\\eta")
            add("rank_P", sp.Integer(rP), "number", label="\\operatorname{rank} P")
            data.update(eta=eta, norm=True, rank_P=rP, n_q=Jfull.cols)
    # ---- numbers
    Jn = _num(J if Jm is None else J * Jm, vals) if (vals or not J.free_symbols) else None
    if Jn is not None:
        rk, sv = numeric_rank(Jn, options.tol)
        add("J_at", _show(sp.Matrix(Jn.tolist())), "matrix", label="J\\big|_*")
        add("sigma_at", sp.Matrix([sp.Float(x, 6) for x in sv]), "vector", label="\\sigma")
        add("rank_at", sp.Integer(rk), "number", label="\\operatorname{rank} J\\big|_*")
        add("singular_at", bool(rk < min(Jn.shape)), "bool", label="\\text{singular}")
        cond = sp.oo if rk < min(Jn.shape) else sp.Float(sv[0] / sv[-1], 6)
        add("cond_at", cond, "number", label="\\kappa")
        data.update(Jn=sp.Matrix(Jn.tolist()), sv=[sp.Float(x, 6) for x in sv], rank_at=rk, cond=cond,
                    tol=options.tol)
        if options.desired is not None:
            en = _num(data["e"], vals)
            kn = _num(sp.Matrix([k]), vals)
            if en is not None and kn is not None:
                law = kn[0, 0] * np.linalg.pinv(Jn, rcond=options.tol) @ en.reshape(-1)
                if Jm is not None and options.qdot0 is not None:
                    q0 = _num(_matrix(problem, ctx, "qdot0"), vals)
                    if q0 is not None:
                        Jp = np.linalg.pinv(Jn, rcond=options.tol)
                        law = law + (np.eye(Jn.shape[1]) - Jp @ Jn) @ q0.reshape(-1)
                lv = sp.Matrix([sp.Float(x, 8) for x in law])
                add("law_at", lv, "vector", label="\\dot q" if Jm is not None else "(V; \\Omega)")
                data["law_at"] = lv
    sol.step("vs", **data)
    if options.simulate is not None:
        _simulation_figure(sol, problem, ctx, options, cart, lam, vals, data)
    return sol


def _single_row(col: sp.Matrix) -> int:
    """The (1-based) row of the only entry of ``col`` not identically zero, 0 if none or several."""
    nz = [i for i, x in enumerate(col) if not zero_or_simplified(x)]
    return nz[0] + 1 if len(nz) == 1 else 0


def _null_directions(M: sp.Matrix) -> list[sp.Matrix]:
    """A basis of N(M), each vector up to a factor (callers keep ``cleared(v)``, a canonical representative):
    exact Gauss–Jordan over the field of fractions where the entries allow (``rational_matrix``; 1.5 s -> 5 ms
    for the 2x3 J_ω of an average of three points), else ``Matrix.nullspace(simplify=True)``."""
    dM = rational_matrix(M)
    if dM is None:
        return M.nullspace(simplify=True)
    N = dM.nullspace().to_Matrix()
    return [N[i, :].T for i in range(N.rows)]


def _special_motions(J: sp.Matrix, Jv: sp.Matrix, Jw: sp.Matrix, cart: list, lam: sp.Expr, feature: str,
                     polar: bool) -> dict[str, tuple[sp.Matrix, str]]:
    """Null motions with a physical meaning: a pure translation (V, 0), a pure rotation (0, Ω), a rotation about
    the optical axis compensated by a translation parallel to the image plane."""
    out: dict[str, tuple[sp.Matrix, str]] = {}
    z3 = sp.zeros(3, 1)
    if feature == "average" or len(cart) == 1:
        # N(J_v) for (averages of) points: (Σ u_i/Z_i, Σ v_i/Z_i, λ Σ 1/Z_i); rotation about z: (Σ v_i, −Σ u_i, 0)
        tu = sum((p[0] / p[2] for p in cart), sp.Integer(0))
        tv = sum((p[1] / p[2] for p in cart), sp.Integer(0))
        tz = lam * sum((1 / p[2] for p in cart), sp.Integer(0))
        out["null_translation"] = (primitive(content_free(sp.Matrix.vstack(sp.Matrix([tu, tv, tz]), z3))), "(V; 0)")
        axis = sp.Matrix([sum((p[1] for p in cart), sp.Integer(0)), -sum((p[0] for p in cart), sp.Integer(0)), 0,
                          0, 0, tz])
        out["null_axis_motion"] = (primitive(content_free(axis)), "(V_{xy}; \\Omega_z)")
        if len(cart) == 1:
            u, v, _ = cart[0]
            out["null_rotation"] = (primitive(content_free(sp.Matrix([0, 0, 0, u, v, lam]))), "(0; \\Omega)")
        elif J.rows <= 2:
            Nw = _null_directions(Jw)
            if len(Nw) == 1:
                out["null_rotation"] = (sp.Matrix.vstack(z3, cleared(Nw[0])), "(0; \\Omega)")
        if polar:
            out = {k: (v.applyfunc(tidy), lab) for k, (v, lab) in out.items()}
        return out
    Nv = _null_directions(Jv) if Jv.rows <= 4 else []
    if len(Nv) == 1:
        out["null_translation"] = (sp.Matrix.vstack(cleared(Nv[0]), z3), "(V; 0)")
    Nw = _null_directions(Jw) if Jw.rows <= 4 else []
    if len(Nw) == 1:
        out["null_rotation"] = (sp.Matrix.vstack(z3, cleared(Nw[0])), "(0; \\Omega)")
    return out


def _simulation_figure(sol: Solution, problem, ctx, options: VisualServoingAsk, cart: list, lam: sp.Expr,  # type: ignore[no-untyped-def]
                       vals: dict, data: dict) -> None:
    place = problem.located.place(ctx.path + ("simulate",))
    try:
        lam_n = float(sp.sympify(lam).subs(vals))
        k_n = float(sp.sympify(data["k"]).subs(vals))
        P0 = np.array([[float(sp.sympify(p[0] * p[2] / lam).subs(vals)), float(sp.sympify(p[1] * p[2] / lam).subs(vals)),
                        float(sp.sympify(p[2]).subs(vals))] for p in cart])
        sd = np.array([float(x.subs(vals)) for x in data["sd"]])
    except (TypeError, ValueError):
        raise UserError("simulate: needs numeric points, desired features, focal length and gain "
                        "(give values: or at:)", place) from None
    spec = options.simulate
    assert spec is not None
    avg = options.feature == "average"

    def panels() -> list[Panel]:
        res = simulate_ibvs(P0, sd, lam_n, k_n, spec.time, spec.steps, avg, spec.depth)
        uv = res["uv"]
        curves, marks = [], []
        for i in range(uv.shape[1]):
            curves.append(Curve(f"point {i + 1}", list(uv[:, i, 0]), list(uv[:, i, 1])))
            marks.append((float(uv[0, i, 0]), float(uv[0, i, 1]), f"{i + 1}"))
        if avg:
            m = uv.mean(1)
            curves.append(Curve("barycenter", list(m[:, 0]), list(m[:, 1]), dashed=True))
            marks.append((float(sd[0]), float(sd[1]), "$\\bar s_d$"))
        else:
            for i in range(len(sd) // 2):
                marks.append((float(sd[2 * i]), float(sd[2 * i + 1]), f"$s_{{d{i + 1}}}$"))
        img = Panel("$u$", "$v$", curves, markers=marks, equal_axes=True)
        err = Panel("$t$", "$\\|e\\|$", [Curve("$\\|s_d - s\\|$", list(res["t"]), list(res["err"]))])
        return [img, err]

    sol.figures.append(Figure("image", "IBVS run: feature paths in the image plane (from the numbered initial "
                                       "points) and the error norm.", panels))


# ------------------------------------------------------------------------------------------------ grading
def _suffix_of(name: str, base: str) -> str:
    return name[len(base):]


def _null_check(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Any camera motion (or basis of motions) with J x = 0 at random values of the symbols; a basis needs
    dim N(J) independent columns; a pure translation/rotation needs the other block zero."""
    base = next((b for b in ("null_motions_cleared", "null_motions", "null_translation", "null_rotation",
                             "null_axis_motion") if name.startswith(b)), None)
    if base is None:
        return None
    J = results.get("J_s" + _suffix_of(name, base))
    if J is None:
        return None
    try:
        X = sp.Matrix(value)
        if X.shape[0] != 6 and X.shape[1] == 6:
            X = X.T
        if X.shape[0] != 6:
            return PropertyVerdict(False, 0.0, ["a camera motion has 6 components (V; Ω)"])
        syms = sorted((J.value.free_symbols | X.free_symbols), key=str)
        rng = random.Random(11)
        sub = {s: sp.Rational(rng.randint(2, 60), rng.randint(2, 9)) for s in syms}
        R = (J.value * X).subs(sub).evalf(30)
        Xn = X.subs(sub).evalf(30)
        scale = max(1.0, max(abs(float(x)) for x in Xn))
        if max(abs(float(x)) for x in R) > 1e-12 * scale:
            return PropertyVerdict(False, 0.0, ["J (V; Ω) ≠ 0: the features move"])
        rank = np.linalg.matrix_rank(np.array(Xn.tolist(), dtype=float), tol=1e-9 * scale)
    except (TypeError, ValueError, AttributeError, sp.ShapeError):
        return None
    if base.startswith("null_motions"):
        need = int(results["dim_null" + _suffix_of(name, base)].value)
        if rank < need:
            return PropertyVerdict(False, 0.5, [f"null motions, but only {rank} independent of {need}"])
        return PropertyVerdict(True, 1.0, ["a basis of the null space of J"])
    if rank == 0:
        return PropertyVerdict(False, 0.0, ["the zero motion"])
    if base == "null_translation" and any(x != 0 for x in Xn[3:]):
        return PropertyVerdict(False, 0.5, ["leaves the features still but is not a pure translation"])
    if base == "null_rotation" and any(x != 0 for x in Xn[:3]):
        return PropertyVerdict(False, 0.5, ["leaves the features still but is not a pure rotation"])
    return PropertyVerdict(True, 1.0, ["J (V; Ω) = 0: the features stay still"])


for _b in ("null_motions", "null_motions_cleared", "null_translation", "null_rotation", "null_axis_motion"):
    property_check(*[_b + s for s in ("", "_origin", "_cart", "_1", "_2")])(_null_check)
