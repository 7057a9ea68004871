"""The bound α on the gradient of the gravity term, ‖∂g/∂q‖ ≤ α for every q (pure functions, reusable).

    A(q) = ∂g/∂q  (the Hessian of U when g = ∇U: symmetric),   ‖A‖ = √λ_max(AᵀA)   (= max |λ_i(A)| if symmetric)
    symmetric 2×2, A = [[a, b], [b, c]]:   ‖A‖ = ½ (|a + c| + √((a − c)² + 4 b²))
    α_max = max_q ‖A(q)‖ (the least α),   α_F = max_q ‖A(q)‖_F ≥ α_max  (‖A‖² = λ_max(AᵀA) ≤ tr(AᵀA) = ‖A‖_F²)

Three ways, from the best to the most conservative:
  * exact: A = k·Ā(q) with k free of q and Ā free of symbolic parameters (or with their numeric values); the
    maximum of ‖Ā‖ is found numerically (grid over one period of every angle and the ranges of the prismatic
    coordinates, then local refinement) and recognized in closed form at a configuration with angles multiple of
    π/12 when the exact norm there equals the numeric maximum;
  * numeric: every parameter has a value: the numeric maximum and its configuration;
  * termwise (always closed form): the norm formula above (Frobenius for n ≥ 3) bounded term by term with
    |sin|, |cos| ≤ 1, |x + y| ≤ |x| + |y|, |x y| = |x| |y| and each prismatic coordinate at the end of its range.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
import sympy as sp

from solver.math.numeric import lambdify_np
from solver.math.search import pattern_max
from solver.math.simplify import factor_within, tidy

GRID_POINTS = 20_000      # grid evaluations for a numeric maximum
RANDOM_ABOVE = 6          # more coordinates than this: random samples instead of a grid
_REL = 1e-8


@dataclass
class GradientBound:
    """α and how it was obtained."""

    A: sp.Matrix                        # ∂g/∂q
    symmetric: bool
    norm_expr: Optional[sp.Expr]        # ‖A(q)‖ in closed form (n = 1, symmetric 2×2), else None
    alpha: sp.Expr                      # the α to use: alpha_max when found, else the termwise bound
    method: str                         # zero | exact | numeric | termwise
    alpha_max: Optional[sp.Expr] = None  # max_q ‖A(q)‖ (exact or float), None if not found
    q_max: Optional[sp.Matrix] = None   # a maximizing configuration (coordinates A depends on; others 0)
    factor: sp.Expr = sp.Integer(1)     # k in A = k·Ā
    frobenius: Optional[sp.Expr] = None  # max_q ‖A(q)‖_F
    q_frobenius: Optional[sp.Matrix] = None
    termwise: Optional[sp.Expr] = None  # closed-form termwise bound
    coords: list[sp.Symbol] = field(default_factory=list)   # coordinates A depends on
    unbounded: list[sp.Symbol] = field(default_factory=list)  # coordinates without a range that make ‖A‖ unbounded


# ------------------------------------------------------------------------------------------------ closed forms
def gradient(g: sp.Matrix, q: list[sp.Symbol]) -> sp.Matrix:
    """A(q) = ∂g/∂q."""
    return g.jacobian(q).applyfunc(tidy)


def norm_formula(A: sp.Matrix) -> Optional[sp.Expr]:
    """‖A‖ in closed form: |a| (1×1), ½(|a + c| + √((a − c)² + 4b²)) (symmetric 2×2); None otherwise."""
    if A.shape == (1, 1):
        return sp.Abs(A[0, 0])
    if A.shape == (2, 2) and sp.expand(A[0, 1] - A[1, 0]) == 0:
        a, b, c = A[0, 0], A[0, 1], A[1, 1]
        return (sp.Abs(a + c) + sp.sqrt((a - c) ** 2 + 4 * b ** 2)) / 2
    return None


def _range_bound(lo: sp.Expr, hi: sp.Expr) -> sp.Expr:
    """max |x| over [lo, hi]."""
    if sp.sympify(lo).is_nonnegative:
        return sp.sympify(hi)
    if sp.sympify(hi).is_nonpositive:
        return -sp.sympify(lo)
    return sp.Max(sp.Abs(lo), sp.Abs(hi))


def abs_bound(e: sp.Expr, coords: set[sp.Symbol], ranges: dict[sp.Symbol, tuple[sp.Expr, sp.Expr]]) -> Optional[sp.Expr]:
    """An upper bound of |e| over the coordinates (parameters kept), term by term: |sin|, |cos| ≤ 1,
    |x + y| ≤ |x| + |y|, |x y| = |x| |y|, |x^k| = |x|^k, √ monotone, a coordinate at the end of its range.
    None when some factor cannot be bounded (a coordinate without range outside sin/cos, a denominator in q)."""
    e = sp.sympify(e)
    if not (e.free_symbols & coords):
        return sp.Abs(e) if not e.is_nonnegative else e
    if e.is_Symbol:
        return _range_bound(*ranges[e]) if e in ranges else None
    if isinstance(e, (sp.sin, sp.cos)):
        return sp.Integer(1)
    if isinstance(e, sp.Abs):
        return abs_bound(e.args[0], coords, ranges)
    if e.is_Add or e.is_Mul:
        parts = [abs_bound(a, coords, ranges) for a in e.args]
        if any(p is None for p in parts):
            return None
        return sp.Add(*parts) if e.is_Add else sp.Mul(*parts)
    if e.is_Pow and e.exp.is_Rational and e.exp > 0:
        b = abs_bound(e.base, coords, ranges)
        return None if b is None else b ** e.exp
    return None


def termwise_bound(A: sp.Matrix, coords: set[sp.Symbol], ranges: dict) -> Optional[sp.Expr]:
    """Closed-form α ≥ ‖A(q)‖: the norm formula (n ≤ 2, symmetric) or √Σ a_ij² (Frobenius) bounded termwise
    (each square expanded first, so that (x + y)² gives |x|² + 2|x||y| + |y|²)."""
    A = A.applyfunc(sp.expand)
    if A.shape == (1, 1):
        return abs_bound(A[0, 0], coords, ranges)
    if A.shape == (2, 2) and sp.expand(A[0, 1] - A[1, 0]) == 0:
        a, b, c = A[0, 0], A[0, 1], A[1, 1]
        t1 = abs_bound(sp.expand(a + c), coords, ranges)
        t2 = abs_bound(sp.expand((a - c) ** 2 + 4 * b ** 2), coords, ranges)
        if t1 is None or t2 is None:
            return None
        return (t1 + sp.sqrt(factor_within(t2))) / 2
    parts = [abs_bound(x, coords, ranges) for x in A if x != 0]
    if any(p is None for p in parts):
        return None
    return sp.sqrt(sp.expand(sum((p ** 2 for p in parts), sp.Integer(0))))


def common_factor(A: sp.Matrix, coords: set[sp.Symbol]) -> sp.Expr:
    """k free of q with A = k·Ā: the product of the q-free factors (with their least power) common to every
    non-zero entry of A (sign excluded)."""
    entries = [factor_within(x) for x in A if x != 0]
    if not entries:
        return sp.Integer(1)
    common: Optional[dict] = None
    for x in entries:
        pw: dict = {}
        for f in sp.Mul.make_args(x):
            if f.is_number or (f.free_symbols & coords):
                continue
            base, ex = f.as_base_exp()
            pw[base] = pw.get(base, 0) + ex
        if common is None:
            common = pw
        else:
            common = {b: min(e, pw[b]) for b, e in common.items() if b in pw}
    return sp.Mul(*[b ** e for b, e in (common or {}).items()])


# ------------------------------------------------------------------------------------------------ numerics
def matrix_function(M: sp.Matrix, coords: list[sp.Symbol]) -> Callable[[np.ndarray], np.ndarray]:
    """Vectorized M(q): points (N, k) -> (N, rows, cols)."""
    f = lambdify_np(coords, M.tolist())

    def ev(pts: np.ndarray) -> np.ndarray:
        pts = np.atleast_2d(pts)
        out = f(*pts.T)
        N = pts.shape[0]
        return np.stack([np.stack([np.broadcast_to(np.asarray(x, dtype=float), (N,)) for x in row], -1)
                         for row in out], -2)

    return ev


def spectral(Ms: np.ndarray) -> np.ndarray:
    return np.linalg.svd(Ms, compute_uv=False)[..., 0]


def frob(Ms: np.ndarray) -> np.ndarray:
    return np.sqrt((Ms ** 2).sum(axis=(-2, -1)))


def box_of(coords: list[sp.Symbol], revolute: set[sp.Symbol], ranges: dict[sp.Symbol, tuple[float, float]]
           ) -> list[tuple[float, float]]:
    """The search box: one period for an angle without range, the given range otherwise."""
    out = []
    for c in coords:
        if c in ranges:
            out.append(ranges[c])
        elif c in revolute:
            out.append((-np.pi, np.pi))
        else:
            raise ValueError(f"no range for {c}")
    return out


def maximize(fn: Callable[[np.ndarray], np.ndarray], box: list[tuple[float, float]], periodic: list[bool],
             seed: int = 7) -> tuple[float, np.ndarray]:
    """max of a vectorized fn over the box (grid, or random samples past RANDOM_ABOVE coordinates, then a local
    refinement of the six best points by :func:`solver.math.search.pattern_max`, periodic coordinates free);
    returns (value, point)."""
    k = len(box)
    if k == 0:
        v = fn(np.zeros((1, 0)))
        return float(v[0]), np.zeros(0)
    if k <= RANDOM_ABOVE:
        m = max(3, int(round(GRID_POINTS ** (1.0 / k))))
        m = 24 * max(1, m // 24) if m >= 24 else (12 if m >= 12 else m)  # angles k·π/12 (or π/6) on the grid
        axes = [np.linspace(lo, hi, m, endpoint=not per) for (lo, hi), per in zip(box, periodic)]
        pts = np.array(list(itertools.product(*axes)))
        spacing = m - 1
    else:
        rng = np.random.default_rng(seed)
        lo, hi = np.array([b[0] for b in box]), np.array([b[1] for b in box])
        pts = lo + (hi - lo) * rng.random((GRID_POINTS, k))
        spacing = GRID_POINTS ** (1.0 / k)
    vals = fn(pts)
    vals = np.where(np.isnan(vals), -np.inf, vals)  # (undefined points never win)
    vmax = vals.max()
    top = np.flatnonzero(vals >= vmax * (1 - 1e-12 if vmax >= 0 else 1 + 1e-12))  # (within 10⁻¹² of the top)
    best = max(top, key=lambda i: tuple(pts[i]))      # ties: the lexicographically largest point
    best_v, best_x = float(vals[best]), pts[best]
    lower = np.array([-np.inf if per else float(b[0]) for b, per in zip(box, periodic)])
    upper = np.array([np.inf if per else float(b[1]) for b, per in zip(box, periodic)])
    step = np.array([(float(hi) - float(lo)) / spacing for lo, hi in box])
    for i in np.argsort(-vals)[:6]:
        x, v = pattern_max(fn, pts[i], step, lower, upper)
        if v > best_v * (1 + 1e-12 if best_v >= 0 else 1 - 1e-12) + 1e-14:
            best_v, best_x = v, x
    return best_v, best_x


def _snap(x: float, c: sp.Symbol, revolute: set[sp.Symbol], ranges: dict) -> Optional[sp.Expr]:
    """An exact value near x: a multiple of π/12 for an angle (wrapped to (−π, π]), a range end or a simple
    rational for a prismatic coordinate."""
    if c in revolute:
        x = (x + np.pi) % (2 * np.pi) - np.pi
        k = round(x / (np.pi / 12))
        if abs(x - k * np.pi / 12) < 1e-4:
            v = sp.Rational(k, 12) * sp.pi
            return v if v != -sp.pi else sp.pi
        return None
    for end in ranges.get(c, ()):
        if abs(float(end) - x) < 1e-6 * max(1.0, abs(x)):
            return sp.nsimplify(end)
    r = sp.nsimplify(x, tolerance=1e-7, rational=True)
    return r if r.q <= 12 else None


def exact_norm(M: sp.Matrix, symmetric: bool, frobenius: bool = False) -> Optional[sp.Expr]:
    """‖M‖ (or ‖M‖_F) of a numeric sympy matrix, exactly (None when the eigenvalues are not found)."""
    if frobenius:
        return sp.sqrt(sp.nsimplify(sum(x ** 2 for x in M)))
    try:
        if symmetric:
            ev = list(M.eigenvals().keys())
            if not ev:
                return None
            top = max(ev, key=lambda v: abs(complex(sp.N(v))))
            return _real_root(top) if top.has(sp.I) else sp.nsimplify(top)
        ev = list((M.T * M).eigenvals().keys())
        if not ev:
            return None
        top = max(ev, key=lambda v: abs(complex(sp.N(v))))
        return sp.sqrt(_real_root(top)) if top.has(sp.I) else sp.sqrt(top)
    except Exception:  # pragma: no cover - sympy could not find the roots
        return None


def _real_root(v: sp.Expr) -> sp.Float:
    """A real eigenvalue whose closed form needs complex radicals (a cubic with three real roots, casus
    irreducibilis: 2 400 characters with I that do not even convert to float): its value, from the radicals
    evaluated to 30 digits (the imaginary part there is rounding), as a 15-digit float."""
    return sp.Float(sp.re(sp.N(v, 30)), 15)


def gradient_bound(g: sp.Matrix, q: list[sp.Symbol], revolute: set[sp.Symbol],
                   ranges: dict[sp.Symbol, tuple[sp.Expr, sp.Expr]] | None = None,
                   values: dict[sp.Symbol, sp.Expr] | None = None) -> GradientBound:
    """α with ‖∂g/∂q‖ ≤ α for every q (angles free or in ``ranges``, prismatic coordinates in ``ranges``)."""
    ranges = dict(ranges or {})
    values = dict(values or {})
    A = gradient(g, q)
    symmetric = all(sp.expand(A[i, j] - A[j, i]) == 0 for i in range(A.rows) for j in range(i))
    nf = norm_formula(A)
    coords = [c for c in q if any(c in x.free_symbols for x in A)]
    out = GradientBound(A, symmetric, nf, sp.Integer(0), "zero", coords=coords)
    if not coords and all(x == 0 for x in A):
        out.alpha_max, out.frobenius, out.termwise = sp.Integer(0), sp.Integer(0), sp.Integer(0)
        return out
    cset = set(coords)
    # coordinates that need a range: prismatic ones, and angles that appear outside sin/cos
    unb = []
    for c in coords:
        if c in ranges:
            continue
        if c not in revolute or any(_outside_trig(x, c) for x in A):
            unb.append(c)
    out.unbounded = unb
    out.termwise = None if unb else termwise_bound(A, cset, ranges)
    if unb:
        out.alpha, out.method = sp.oo, "unbounded"
        return out
    k = common_factor(A, cset)
    out.factor = k
    Abar = (A / k).applyfunc(lambda x: factor_within(x))
    Abar_v = Abar.xreplace(values)
    if Abar_v != Abar:           # the maximum needs numeric values: use them in k too (α for these values)
        k = k.xreplace(values)
        out.factor = k
    params = set().union(*[x.free_symbols for x in Abar_v]) - cset
    rng_v = {c: tuple(sp.sympify(v).xreplace(values) for v in ranges[c]) for c in coords if c in ranges}
    if params or any(not all(sp.sympify(v).is_number for v in r) for r in rng_v.values()):
        out.alpha, out.method = (out.termwise if out.termwise is not None else sp.nan), "termwise"
        return out
    box = box_of(coords, revolute, {c: (float(a), float(b)) for c, (a, b) in rng_v.items()})
    periodic = [c in revolute and c not in ranges for c in coords]
    fn = matrix_function(Abar_v, coords)
    vmax, xmax = maximize(lambda p: spectral(fn(p)), box, periodic)
    fmax, fx = maximize(lambda p: frob(fn(p)), box, periodic)
    out.alpha_max, out.q_max = _recognize(Abar_v, coords, xmax, vmax, revolute, rng_v, symmetric, False, k, q)
    out.frobenius, out.q_frobenius = _recognize(Abar_v, coords, fx, fmax, revolute, rng_v, symmetric, True, k, q)
    exact = not out.alpha_max.atoms(sp.Float)
    out.alpha, out.method = out.alpha_max, ("exact" if exact else "numeric")
    return out


def _outside_trig(e: sp.Expr, c: sp.Symbol) -> bool:
    """Whether c appears in e other than inside sin/cos."""
    e2 = e.replace(lambda x: isinstance(x, (sp.sin, sp.cos)), lambda x: sp.Integer(1))
    return c in e2.free_symbols


def _recognize(Abar: sp.Matrix, coords: list[sp.Symbol], x: np.ndarray, v: float, revolute: set, ranges: dict,
               symmetric: bool, frobenius: bool, k: sp.Expr, q: list[sp.Symbol]) -> tuple[sp.Expr, sp.Matrix]:
    """(k·max, configuration): exact when the snapped configuration gives the numeric maximum exactly."""
    snapped = [_snap(float(xi), c, revolute, ranges) for xi, c in zip(x, coords)]
    if all(s is not None for s in snapped):
        at = dict(zip(coords, snapped))
        val = exact_norm(Abar.xreplace(at).applyfunc(sp.nsimplify), symmetric, frobenius)
        if val is not None:
            val = val if val.atoms(sp.Float) else sp.nsimplify(sp.radsimp(val))
            if abs(abs(complex(sp.N(val))) - v) <= _REL * max(1.0, v):
                return k * sp.Abs(val) if not val.is_nonnegative else k * val, \
                    sp.Matrix([at.get(c, sp.Integer(0)) for c in q])
    wrapped = {c: ((float(xi) + np.pi) % (2 * np.pi) - np.pi if c in revolute and c not in ranges else float(xi))
               for xi, c in zip(x, coords)}
    return k * sp.Float(v, 10), sp.Matrix([sp.Float(wrapped[c], 6) if c in wrapped else sp.Integer(0) for c in q])
