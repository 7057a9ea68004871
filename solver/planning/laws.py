"""Timing laws: closed-form pieces of a function of time (used by the asks ``trajectory`` and ``time_scaling``).

A scalar law is q(t) = p_k(t) for t in [t_k, t_{k+1}], k = 0..N-1 (right-continuous at the inner breaks).

    polynomial   p(t) = Σ_j a_j σ^j, σ = (t − t_k)/h_k, the a_j from conditions q^(r)(τ) = v (one linear system)
    spline       one polynomial per interval [t_k, t_{k+1}] through the via points, C^c at the inner knots
    trapezoidal  (bang-coast-bang) q̈ = ±A on [0, T_s] and [T − T_s, T], q̇ = V between:
                 A = Δ/(T_s (T − T_s)),  V = A T_s = Δ/(T − T_s)
    bang_bang    T_s = T/2:  A = 4Δ/T²,  V = 2Δ/T (the peak velocity)
    cycloidal    q = q_i + Δ (σ − sin(2πσ)/(2π))      (sinusoidal acceleration, zero at both ends)
    harmonic     q = q_i + Δ (1 − cos(πσ))/2          (cosine acceleration)
    expression   q(t) given

Everything is sympy: exact when the data are, symbolic in the parameters otherwise. The extrema of |q^(r)(t)|
are searched among the ends of the pieces and the zeros of q^(r+1) inside them (exact when sympy finds them,
else numerically with the parameter values, on a grid refined by a bounded scalar search: tolerance 1e-9 T).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from math import factorial
from typing import Any, Callable, Optional

import numpy as np
import sympy as sp

from solver.math.equivalence import exact_zero
from solver.math.numeric import lambdify_np
from solver.math.simplify import simplified
from solver.math.opcount import count_ops
from solver.math.search import golden_min

SIZE_LIMIT = 400  # count_ops above which extrema are searched numerically
GRID = 801        # samples per piece for numeric searches


class LawError(ValueError):
    """Inconsistent or insufficient data for a law (the caller turns it into a spec error at the right line)."""

    def __init__(self, message: str, field_name: str = "law", hint: str | None = None) -> None:
        super().__init__(message)
        self.field = field_name
        self.hint = hint


# ------------------------------------------------------------------------------------------------ the law
@dataclass
class Law:
    """q(t) = pieces[k] for t in [breaks[k], breaks[k+1]]; ``params`` holds the law's named constants
    (A, V, Ts, coefficients a_j of the normalized polynomials...)."""

    t: sp.Symbol
    breaks: list[sp.Expr]
    pieces: list[sp.Expr]
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def start(self) -> sp.Expr:
        return self.breaks[0]

    @property
    def end(self) -> sp.Expr:
        return self.breaks[-1]

    @property
    def bounded(self) -> bool:
        return self.end != sp.oo

    def diff(self, k: int = 1) -> "Law":
        return Law(self.t, self.breaks, [sp.diff(p, self.t, k) for p in self.pieces])

    def piece_of(self, tau: sp.Expr) -> int:
        """Index of the piece holding ``tau`` (the later one at an inner break; the last one at the end)."""
        for k in range(len(self.pieces) - 1):
            lt = less(tau, self.breaks[k + 1])
            if lt is None:
                raise LawError(f"cannot tell whether t = {tau} comes before the break t = {self.breaks[k + 1]}",
                               "at", "give a time whose position among the breaks is known")
            if lt:
                return k
        return len(self.pieces) - 1

    def at(self, tau: sp.Expr) -> sp.Expr:
        return simplified(self.pieces[self.piece_of(tau)].subs(self.t, tau))

    def jump(self, k: int) -> sp.Expr:
        """p_k(t_k) − p_{k−1}(t_k) at the inner break k (0 when continuous)."""
        b = self.breaks[k]
        return simplified(self.pieces[k].subs(self.t, b) - self.pieces[k - 1].subs(self.t, b))

    def subs(self, m: dict) -> "Law":
        return Law(self.t, [sp.sympify(b).subs(m) for b in self.breaks], [p.subs(m) for p in self.pieces],
                   {k: (v.subs(m) if isinstance(v, (sp.Basic, sp.MatrixBase)) else v) for k, v in self.params.items()})

    def numeric_pieces(self, values: dict) -> tuple[list[Callable[[np.ndarray], np.ndarray]], list[float]]:
        """Each piece as a vectorized float function of t (``values`` substituted, other symbols set to 1),
        and the breaks as floats."""
        fns, bks = [], []
        for p in self.pieces:
            e = p.subs(values)
            e = e.subs({s: 1 for s in e.free_symbols - {self.t}})
            fn = lambdify_np(self.t, e)
            fns.append(lambda x, fn=fn: np.broadcast_to(np.asarray(fn(x), dtype=float), np.shape(x)))
        for b in self.breaks:
            v = sp.sympify(b).subs(values)
            bks.append(float(v.subs({s: 1 for s in v.free_symbols})))
        return fns, bks


def less(a: sp.Expr, b: sp.Expr) -> Optional[bool]:
    """a < b, when it can be decided (None otherwise): from the assumptions on b − a as it is, else on b − a
    simplified."""
    d = sp.sympify(b) - sp.sympify(a)
    if d.is_positive:
        return True
    if d.is_nonpositive:
        return False
    d = simplified(d)
    if d.is_positive:
        return True
    if d.is_nonpositive:
        return False
    return None


# ------------------------------------------------------------------------------------------------ polynomials
@dataclass
class Cond:
    """q^(order)(time) = value."""

    time: sp.Expr
    order: int
    value: sp.Expr
    source: str = ""  # the spec field it comes from (for error messages)


def piecewise_polynomial(t: sp.Symbol, knots: list[sp.Expr], degree: int, continuity: int,
                         conds: list[Cond], end_positions: list[sp.Expr] | None = None) -> Law:
    """One polynomial of ``degree`` per interval [t_k, t_{k+1}] in σ = (t − t_k)/h_k, C^continuity at the
    inner knots, meeting ``conds`` (a condition at an inner knot applies to the later piece) and, with
    ``end_positions``, p_k(t_k) = x_k and p_k(t_{k+1}) = x_{k+1} on every piece: the unique solution of the
    linear system in the coefficients."""
    nseg = len(knots) - 1
    h = [simplified(knots[k + 1] - knots[k]) for k in range(nseg)]
    size = nseg * (degree + 1)
    rows: list[list[sp.Expr]] = []
    rhs: list[sp.Expr] = []

    def row(k: int, sigma: sp.Expr, order: int) -> list[sp.Expr]:
        r = [sp.Integer(0)] * size
        for j in range(order, degree + 1):
            r[k * (degree + 1) + j] = sp.Integer(factorial(j) // factorial(j - order)) * sigma ** (j - order) \
                / h[k] ** order
        return r

    for c in conds:
        k = 0
        for kk in range(nseg - 1):
            lt = less(c.time, knots[kk + 1])
            if lt is None:
                raise LawError(f"cannot place the condition time {c.time} among the knots", c.source)
            if lt:
                break
            k = kk + 1
        sigma = simplified((c.time - knots[k]) / h[k])
        rows.append(row(k, sigma, c.order))
        rhs.append(c.value)
    if end_positions is not None:
        for k in range(nseg):
            for sigma, x in ((sp.Integer(0), end_positions[k]), (sp.Integer(1), end_positions[k + 1])):
                rows.append(row(k, sigma, 0))
                rhs.append(x)
    first = 1 if end_positions is not None else 0
    for k in range(1, nseg):  # continuity at the inner knot k: p_{k-1}^(r)(1) = p_k^(r)(0)
        for r in range(first, continuity + 1):
            a, b = row(k - 1, sp.Integer(1), r), row(k, sp.Integer(0), r)
            rows.append([x - y for x, y in zip(a, b)])
            rhs.append(sp.Integer(0))
    n_eq = len(rows)
    if n_eq != size:
        raise LawError(f"{n_eq} conditions for {size} coefficients ({nseg} piece(s) of degree {degree})",
                       "law", "give exactly one condition per coefficient (or change the degree)")
    M, b = sp.Matrix(rows), sp.Matrix(rhs)
    det = simplified(M.det())
    if det == 0:
        raise LawError("the conditions do not determine the polynomial (they are dependent or inconsistent: "
                       "e.g. two conditions on the same derivative at the same time)", "law",
                       "check the times and orders of the conditions")
    a = M.LUsolve(b).applyfunc(simplified)
    pieces, coeffs = [], []
    for k in range(nseg):
        ak = [a[k * (degree + 1) + j] for j in range(degree + 1)]
        coeffs.append(ak)
        sigma = (t - knots[k]) / h[k]
        pieces.append(sp.Add(*[ak[j] * sigma ** j for j in range(degree + 1)]))
    return Law(t, list(knots), pieces, {"coeffs": coeffs, "degree": degree, "h": h})


def rest_defaults(conds: list[Cond], t0: sp.Expr, t1: sp.Expr, needed: int) -> list[Cond]:
    """Complete ``conds`` up to ``needed`` with rest conditions q^(r)(t0) = q^(r)(t1) = 0, r = 1, 2, ...
    (lowest order first, start before end), skipping those already given."""
    out = list(conds)
    have = {(simplified(c.time), c.order) for c in conds}
    r = 1
    while len(out) < needed and r < 10:
        for tt in (t0, t1):
            if len(out) < needed and (simplified(tt), r) not in have:
                out.append(Cond(tt, r, sp.Integer(0), "rest"))
        r += 1
    return out


# ------------------------------------------------------------------------------------------------ profiles
def trapezoidal(t: sp.Symbol, qi: sp.Expr, qf: sp.Expr, T: sp.Expr, Ts: sp.Expr) -> Law:
    """Bang-coast-bang: q̈ = A on [0, Ts], 0 on [Ts, T − Ts], −A on [T − Ts, T]; Ts = T/2 is bang-bang."""
    D = qf - qi
    A = simplified(D / (Ts * (T - Ts)))
    V = simplified(A * Ts)
    p1 = qi + A * t ** 2 / 2
    p3 = qf - A * (T - t) ** 2 / 2
    bang = simplified(Ts - T / 2) == 0
    if bang:
        return Law(t, [sp.Integer(0), T / 2, T], [p1, p3], {"A": A, "V": V, "Ts": T / 2, "Delta": D})
    p2 = qi + V * (t - Ts / 2)
    return Law(t, [sp.Integer(0), Ts, T - Ts, T], [p1, p2, p3], {"A": A, "V": V, "Ts": Ts, "Delta": D})


def trapezoid_Ts(D: sp.Expr, T: sp.Expr, V: sp.Expr | None = None, A: sp.Expr | None = None) -> sp.Expr:
    """The acceleration time Ts of a trapezoidal profile of duration T from the cruise speed V (Ts = T − Δ/V)
    or the acceleration A (Ts = T/2 − sqrt(T²/4 − Δ/A)); V and A are magnitudes along Δ."""
    sgn = sp.sign(D) if D.is_number and D != 0 else sp.Integer(1)
    if V is not None:
        return simplified(T - D / (sgn * V))
    return simplified(T / 2 - sp.sqrt(T ** 2 / 4 - D / (sgn * A)))


def check_trapezoid(Ts: sp.Expr, T: sp.Expr, given: str) -> None:
    """0 < Ts <= T/2, when decidable; else a LawError naming the bound to change."""
    lo, hi = less(0, Ts), less(T / 2, Ts)
    if lo is False or hi is True:
        hints = {"V": "the cruise speed must satisfy |Δ|/T < V <= 2|Δ|/T",
                 "A": "the acceleration must satisfy A >= 4|Δ|/T²",
                 "Ts": "the acceleration time must satisfy 0 < Ts <= T/2"}
        raise LawError(f"no trapezoidal profile with these data (Ts = {Ts}, T = {T})", given, hints.get(given))


def min_time_trapezoid(D: sp.Expr, V: sp.Expr, A: sp.Expr) -> tuple[sp.Expr, sp.Expr, Optional[bool], sp.Expr]:
    """Minimum time of a rest-to-rest motion by |Δ| under |q̇| <= V, |q̈| <= A:
    T = |Δ|/V + V/A with a coast phase (|Δ| > V²/A), else T = 2 sqrt(|Δ|/A) (bang-bang).
    Returns (T_coast, T_bang, coast?, the condition |Δ| − V²/A > 0 as an expression)."""
    aD = sp.Abs(D) if not (D.is_nonnegative or D.is_nonpositive) else (D if D.is_nonnegative else -D)
    T_coast = simplified(aD / V + V / A)
    T_bang = simplified(2 * sp.sqrt(aD / A))
    margin = simplified(aD - V ** 2 / A)
    coast = True if margin.is_positive else (False if margin.is_nonpositive else None)
    return T_coast, T_bang, coast, margin


def cycloidal(t: sp.Symbol, qi: sp.Expr, qf: sp.Expr, T: sp.Expr) -> Law:
    s = t / T
    D = qf - qi
    return Law(t, [sp.Integer(0), T], [qi + D * (s - sp.sin(2 * sp.pi * s) / (2 * sp.pi))],
               {"Delta": D, "A": simplified(2 * sp.pi * D / T ** 2), "V": simplified(2 * D / T)})


def harmonic(t: sp.Symbol, qi: sp.Expr, qf: sp.Expr, T: sp.Expr) -> Law:
    s = t / T
    D = qf - qi
    return Law(t, [sp.Integer(0), T], [qi + D * (1 - sp.cos(sp.pi * s)) / 2],
               {"Delta": D, "A": simplified(sp.pi ** 2 * D / (2 * T ** 2)), "V": simplified(sp.pi * D / (2 * T))})


# ------------------------------------------------------------------------------------------------ extrema
@dataclass
class Extremum:
    """max_t |f(t)|: ``value`` the signed f there, ``time`` (None if not unique/known), ``how``:
    exact | values (chosen among exact candidates with the parameter values) | numeric | symbolic (a Max)."""

    value: sp.Expr
    abs: sp.Expr
    time: Optional[sp.Expr]
    how: str


def _transcendental_in(f: sp.Expr, t: sp.Symbol) -> bool:
    """Whether f has a function of a nonlinear polynomial in t (cos(3Δ t²/T² − 2Δ t³/T³ + q₀) along a cubic):
    f = 0 then has no closed-form roots, and simplifying f to find them costs seconds for nothing."""
    for fn in f.atoms(sp.Function):
        for arg in fn.args:
            if isinstance(arg, sp.Expr) and arg.has(t) and not (arg.is_polynomial(t) and sp.degree(arg, t) <= 1):
                return True
    return False


def _linear_root_at_end(f1: sp.Expr, t: sp.Symbol, a: sp.Expr, b: sp.Expr) -> bool:
    """Whether f1 is linear in t, with a slope provably non-zero and f1 zero at a or at b (exact tests): its
    only root is then an end of the interval, so there is none inside, found without simplifying f1 in σ
    (seconds for a torque with radicals in its coefficients)."""
    slope = sp.diff(f1, t)
    if slope.has(t) or not (slope.is_zero is False or exact_zero(slope) is False):
        return False
    return any(exact_zero(f1.subs(t, e)) is True for e in (a, b))


def _interior_roots(f1: sp.Expr, t: sp.Symbol, a: sp.Expr, b: sp.Expr) -> Optional[list[sp.Expr]]:
    """Zeros of f1 strictly inside (a, b), found in σ = (t − a)/(b − a) ∈ (0, 1); None when they cannot be
    found exactly."""
    if f1 == 0 or not f1.has(t):
        return []
    if count_ops(f1) > SIZE_LIMIT or _transcendental_in(f1, t):
        return None
    if _linear_root_at_end(f1, t, a, b):
        return []
    s = sp.Dummy("sigma", real=True)
    g = simplified(f1.subs(t, a + (b - a) * s))
    try:
        if g.is_polynomial(s) and sp.degree(g, s) <= 4:
            sols = sp.solve(g, s)
        else:
            ss = sp.solveset(g, s, sp.Interval.open(0, 1))
            if ss is sp.S.EmptySet:
                return []
            if not isinstance(ss, sp.FiniteSet):
                return None
            sols = list(ss)
    except (NotImplementedError, ValueError, TypeError):
        return None
    out = []
    for x in sols:
        x = simplified(x)
        if x.has(sp.I):
            if simplified(sp.im(x)) != 0:
                continue
            x = simplified(sp.re(x))
        lo, hi = less(0, x), less(x, 1)
        if lo is None or hi is None:
            return None
        if lo and hi:
            out.append(simplified(a + (b - a) * x))
    return out


def extremum(law: Law, values: dict) -> Optional[Extremum]:
    """max over the law's interval of |q(t)|; None for an unbounded interval, or when the candidates cannot be
    found exactly and some parameter has no value."""
    if not law.bounded:
        return None
    t = law.t
    cands: list[tuple[sp.Expr, sp.Expr]] = []  # (time, value)
    for k, p in enumerate(law.pieces):
        a, b = law.breaks[k], law.breaks[k + 1]
        roots = _interior_roots(sp.diff(p, t), t, a, b)
        if roots is None:
            if any(p.subs(values).free_symbols - {t} for p in law.pieces) or \
                    any(sp.sympify(x).subs(values).free_symbols for x in law.breaks):
                return None  # neither exact nor numeric: parameters without values
            return _numeric_extremum(law, values)
        for tau in [a, *roots, b]:
            cands.append((tau, simplified(p.subs(t, tau))))
    if all(not v.free_symbols for _, v in cands):
        best = max(cands, key=lambda c: float(sp.Abs(c[1])))
        return Extremum(best[1], sp.Abs(best[1]), best[0], "exact")
    nonzero = [c for c in cands if simplified(c[1]) != 0]
    if not nonzero:
        return Extremum(sp.Integer(0), sp.Integer(0), None, "exact")
    distinct: list[tuple[sp.Expr, sp.Expr]] = []
    for c in nonzero:
        if not any(simplified(sp.Abs(c[1]) - sp.Abs(d[1])) == 0 for d in distinct):
            distinct.append(c)
    if len(distinct) == 1:
        c = distinct[0]
        return Extremum(c[1], simplified(sp.Abs(c[1])), c[0], "exact")
    # several symbolic candidates: one that dominates all the others by a constant ratio, else the values
    for c in distinct:
        ok = True
        for d in distinct:
            if d is c:
                continue
            r = simplified(sp.Abs(c[1]) / sp.Abs(d[1]))
            if not (r.is_number and r >= 1):
                ok = False
                break
        if ok:
            return Extremum(c[1], simplified(sp.Abs(c[1])), c[0], "exact")
    numeric = [(c, c[1].subs(values)) for c in distinct]
    if all(not v.free_symbols for _, v in numeric):
        c = max(numeric, key=lambda x: float(sp.Abs(x[1])))[0]
        return Extremum(c[1], simplified(sp.Abs(c[1])), c[0], "values")
    return Extremum(sp.Max(*[sp.Abs(c[1]) for c in distinct]), sp.Max(*[sp.Abs(c[1]) for c in distinct]), None,
                    "symbolic")


def _numeric_extremum(law: Law, values: dict) -> Extremum:
    fns, bks = law.numeric_pieces(values)
    best: tuple = (bks[0], 0.0, 0.0, 0)  # (t, |f|, f, piece)
    for k, fn in enumerate(fns):
        a, b = bks[k], bks[k + 1]
        grid = np.linspace(a, b, GRID)
        vals = fn(grid)
        j = int(np.argmax(np.abs(vals)))
        cand = (float(grid[j]), float(abs(vals[j])), float(vals[j]))
        lo, hi = grid[max(j - 1, 0)], grid[min(j + 1, GRID - 1)]
        if hi > lo:
            x, fx = golden_min(lambda x: -abs(float(fn(np.array([x]))[0])), lo, hi, 1e-12 * max(1.0, b - a))
            if -fx > cand[1]:
                cand = (x, -fx, float(fn(np.array([x]))[0]))
        if cand[1] > best[1]:
            best = cand + (k,)
    k = best[3] if len(best) > 3 else 0
    for j in (k, k + 1):  # at a break of the law: the exact value of the piece there
        if j < len(bks) and abs(best[0] - bks[j]) <= 1e-7 * max(1.0, abs(bks[-1] - bks[0])):
            v = simplified(law.pieces[k].subs(law.t, law.breaks[j]))
            return Extremum(v, simplified(sp.Abs(v)), law.breaks[j], "exact")
    return Extremum(sp.Float(best[2], 12), sp.Float(best[1], 12), sp.Float(best[0], 12), "numeric")


def sample(law: Law, values: dict, points: int = 240) -> tuple[list[float], list[float]]:
    """(t, q(t)) on the law's interval for plotting, with both one-sided values at every inner break."""
    fns, bks = law.numeric_pieces(values)
    xs: list[float] = []
    ys: list[float] = []
    total = bks[-1] - bks[0]
    for k, fn in enumerate(fns):
        a, b = bks[k], bks[k + 1]
        m = max(8, int(points * (b - a) / total)) if total > 0 else 8
        grid = np.linspace(a, b, m)
        xs += [float(x) for x in grid]
        ys += [float(y) for y in fn(grid)]
    return xs, ys
