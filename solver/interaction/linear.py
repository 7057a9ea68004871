"""Linear time-invariant tools for interaction control: closed loops as polynomial matrices in s, transfer
functions, equilibria, Routh-Hurwitz conditions, pole placement and simulation.

A linear closed loop is a list of residuals r(ẍ, ẋ, x, w) = 0, affine in the state and in the exogenous inputs
(desired force, references, rest positions). With X(s) the Laplace transforms (zero initial state):

    A(s) X(s) = b(s) U(s),   A(s) = ∂r/∂ẍ s² + ∂r/∂ẋ s + ∂r/∂x,   char. polynomial  det A(s)
    equilibrium:  A(0) x̄ = -r(0, 0, 0, ū)          (when A(0) is invertible)

Routh: for a_n sⁿ + ... + a_0 (a_n > 0) every root has negative real part iff every entry of the first column of
the Routh table is positive; the conditions are returned in the canonical form of
:func:`solver.math.equivalence.normalize_condition` (positive factors removed, always-true ones dropped).
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from typing import Any, Sequence

import numpy as np
import sympy as sp
from sympy.polys.rings import sring

from solver.math.equivalence import identically_zero, numer_denom, reduce_conditions, ring_numer_denom
from solver.math.fourier import factor_list_expr
from solver.math.numeric import evaluate_np
from solver.math.opcount import count_ops
from solver.math.search import lp_max
from solver.math.simplify import factor_within, tidy, zero_or_simplified

S = sp.Symbol("s")  # the Laplace variable (the problem's own `s` replaces it when declared)
MAX_SYMBOLIC_DEGREE = 6  # Routh tables and closed-form poles are symbolic up to this degree
EXACT_LP_PAIRS = 60      # AM-GM programs with at most this many pairs: exact simplex; larger ones: HiGHS


class NotLinear(Exception):
    """The closed loop is not linear time-invariant in the chosen state (the message says which term)."""


@dataclass
class LinearLoop:
    """r(ẍ, ẋ, x) = A2 ẍ + A1 ẋ + A0 x + r0(u): the matrices and the constant part (inputs, offsets)."""

    x: list[sp.Symbol]
    dx: list[sp.Symbol]
    ddx: list[sp.Symbol]
    A2: sp.Matrix
    A1: sp.Matrix
    A0: sp.Matrix
    r0: sp.Matrix

    def A(self, s: sp.Symbol) -> sp.Matrix:
        return (self.A2 * s**2 + self.A1 * s + self.A0).applyfunc(sp.expand)


def linear_loop(residual: sp.Matrix, x: list, dx: list, ddx: list) -> LinearLoop:
    """Split a residual vector into A2 ẍ + A1 ẋ + A0 x + r0; raises NotLinear when a coefficient depends on the
    state (or the residual is not affine in it)."""
    state = list(x) + list(dx) + list(ddx)
    r = residual.applyfunc(sp.expand)
    A2, A1, A0 = r.jacobian(ddx), r.jacobian(dx), r.jacobian(x)
    for M in (A2, A1, A0):
        for e in M:
            if e.free_symbols & set(state):
                raise NotLinear(f"the coefficient {e} depends on the state")
    r0 = r.xreplace({v: 0 for v in state}).applyfunc(sp.expand)
    rest = (r - A2 * sp.Matrix(ddx) - A1 * sp.Matrix(dx) - A0 * sp.Matrix(x) - r0).applyfunc(sp.expand)
    if any(e != 0 for e in rest):
        raise NotLinear("the closed loop is not affine in the state")
    return LinearLoop(list(x), list(dx), list(ddx), A2, A1, A0, r0)


def equilibrium(loop: LinearLoop) -> sp.Matrix | None:
    """x̄ with A0 x̄ + r0 = 0 (ẍ = ẋ = 0); None when A0 is singular (no isolated equilibrium)."""
    if loop.A0.shape[0] != loop.A0.shape[1] or zero_or_simplified(loop.A0.det()):
        return None
    return loop.A0.LUsolve(-loop.r0).applyfunc(lambda e: factor_within(sp.cancel(e)))


def steady_velocity(loop: LinearLoop) -> sp.Matrix | None:
    """The constant velocity v̄ of a steady motion x(t) = x₀ + v̄ t (ẍ = 0) when positions do not fully act:
    A0 v̄ = 0 and A1 v̄ + A0 x₀ + r0 = 0; None when A0 is invertible (an equilibrium instead) or v̄ is not unique."""
    n = loop.A0.rows
    if n != loop.A0.cols or not zero_or_simplified(loop.A0.det()):
        return None
    v = sp.symbols(f"_v0:{n}")
    x0 = sp.symbols(f"_x0:{n}")
    V, X0 = sp.Matrix(v), sp.Matrix(x0)
    eqs = list(loop.A0 * V) + list(loop.A1 * V + loop.A0 * X0 + loop.r0)
    sols = sp.linsolve(eqs, list(v) + list(x0))
    if not sols:
        return None
    sol = next(iter(sols))
    vel = sp.Matrix(sol[:n])
    if vel.free_symbols & (set(v) | set(x0)):
        return None
    if all(zero_or_simplified(e) for e in vel):
        return None  # at rest: no steady motion
    return vel.applyfunc(lambda e: factor_within(sp.cancel(e)))


def char_poly(loop: LinearLoop, s: sp.Symbol) -> sp.Expr:
    """det A(s), expanded and collected in powers of s."""
    A = loop.A(s)
    d = _det(sp.ImmutableMatrix(A)) if A.shape[0] > 1 else A[0, 0]
    return collect_s(d, s)


@lru_cache(maxsize=64)
def _det(A: sp.ImmutableMatrix) -> sp.Expr:
    """det A (Berkowitz), memoized: the characteristic polynomial and the transfer functions of one loop (the
    plant's P(s) and Q(s)/U(s), the closed loop's det A(s) and W(s)) need the same determinant."""
    return A.det(method="berkowitz")


@lru_cache(maxsize=64)
def _adjugate(A: sp.ImmutableMatrix) -> sp.ImmutableMatrix:
    """adj A (Berkowitz), memoized as :func:`_det`."""
    return sp.ImmutableMatrix(A.adjugate())


def collect_s(p: sp.Expr, s: sp.Symbol) -> sp.Expr:
    """p collected in powers of s, each coefficient factored when that is shorter."""
    poly = sp.Poly(sp.expand(p), s)
    out = sp.Integer(0)
    for (k,), c in zip(poly.monoms(), poly.coeffs()):
        f = factor_within(c)
        out += (f if count_ops(f) <= count_ops(c) else c) * s**k
    return out


def transfer(loop: LinearLoop, output: sp.Matrix, inputs: dict[sp.Symbol, sp.Expr], s: sp.Symbol) -> sp.Matrix:
    """Y(s)/U(s) for the output y = Cx (+ Du) and the input u (a symbol of r0): X(s) = -A(s)⁻¹ ∂r0/∂u U(s),
    other inputs at zero. ``inputs`` maps the input symbol to its direct feedthrough in the output (often 0)."""
    (u, feed), = inputs.items()
    bu = -loop.r0.diff(u)
    A = loop.A(s)
    if A.shape[0] > 1:
        Ai = sp.ImmutableMatrix(A)
        X = _adjugate(Ai).as_mutable() * bu / _det(Ai)
    else:
        X = bu / A[0, 0]
    C = output.jacobian(loop.x)
    return (C * X).applyfunc(lambda e: rational(e + feed, s))


def rational(e: sp.Expr, s: sp.Symbol) -> sp.Expr:
    """A rational function of s as N(s)/D(s), both collected in s (common factors cancelled)."""
    n, d = numer_denom(e)  # common factors cancelled (sparse rational functions)
    if not d.has(s):
        return collect_s(n, s) / d if n.has(s) else factor_within(n / d)
    lead = sp.Poly(d, s).LC()
    n, d = sp.expand(n / lead), sp.expand(d / lead)
    # keep the leading coefficient of the denominator when it is a plain parameter (m s² + ...), as printed
    if lead.is_Symbol or (lead.is_Mul and all(f.is_Symbol for f in lead.args)):
        n, d = sp.expand(n * lead), sp.expand(d * lead)
    return collect_s(n, s) / collect_s(d, s)


def s_factors(p: sp.Expr, s: sp.Symbol, max_ops: int = 3000) -> list[tuple[sp.Expr, int]]:
    """The factors of p(s) that depend on s, with multiplicities (the constant content dropped): a decoupled
    closed loop gives one factor per direction. p itself when it does not factor (or is too large to try)."""
    p = sp.expand(p)
    if count_ops(p) > max_ops:
        return [(collect_s(p, s), 1)]
    num, _ = sp.fraction(sp.together(p))
    try:
        _, fl = factor_list_expr(sp.expand(num))
    except sp.PolynomialError:
        return [(collect_s(p, s), 1)]
    out = [(collect_s(f, s), k) for f, k in fl if f.has(s)]
    if len(out) == 1 and out[0][1] == 1:
        return [(collect_s(p, s), 1)]  # keep the content (leading coefficient) of an irreducible polynomial
    return out or [(collect_s(p, s), 1)]


def coefficients(p: sp.Expr, s: sp.Symbol) -> list[sp.Expr]:
    """[a_n, ..., a_0] of a polynomial in s."""
    return [factor_within(c) for c in sp.Poly(sp.expand(p), s).all_coeffs()]


@lru_cache(maxsize=256)
def _hurwitz(b: tuple[sp.Expr, ...]) -> tuple[Any, tuple[Any, ...]]:
    """(K, [Δ_1..Δ_n] as elements of K), K the domain of the coefficients (a polynomial ring, usually)."""
    from sympy.polys.matrices import DomainMatrix

    n = len(b) - 1

    def coef(k: int) -> sp.Expr:
        return b[k] if 0 <= k <= n else sp.Integer(0)

    dH = DomainMatrix.from_Matrix(sp.Matrix(n, n, lambda i, j: coef(2 * j - i + 1)))
    dets = [dH[0, 0].element]
    for k in range(2, n + 1):  # the last column is (0, ..., 0, b_n): Δ_n = b_n Δ_{n-1}, no determinant
        dets.append(dH[n - 1, n - 1].element * dets[-1] if k == n else dH[:k, :k].det())
    return dH.domain, tuple(dets)


def short_hurwitz_determinants(coeffs: Sequence[sp.Expr]) -> list[sp.Expr]:
    """Δ_1..Δ_n, the leading principal minors of the Hurwitz matrix H_ij = b_{2j-i+1} of b_0 sⁿ + b_1 sⁿ⁻¹ + ...
    + b_n (exact polynomial arithmetic, no fractions, memoized: the Routh column uses them too), each factored when
    that is shorter (:func:`_short`)."""
    K, dets = _hurwitz(tuple(sp.sympify(c) for c in coeffs))
    return [_short(_to_expr(K, d), _is_expanded(K)) for d in dets]


def _is_expanded(K: Any) -> bool:
    """Whether :func:`_to_expr` gives K's elements as sp.expand leaves them: polynomials, numbers and EX, not a
    field of fractions (n/d, which expand would split into terms)."""
    return bool(K.is_PolynomialRing or K.is_EX or K.is_ZZ or K.is_QQ)


def _to_expr(K: Any, d: Any) -> sp.Expr:
    """A domain element as an expanded expression (EX's elements are expanded here; 0 exactly when zero)."""
    if not d:
        return sp.Integer(0)
    return sp.expand(K.to_sympy(d)) if K.is_EX else K.to_sympy(d)


def routh_column(coeffs: Sequence[sp.Expr]) -> list[sp.Expr]:
    """First column of the Routh table of b_0 sⁿ + ... + b_n (coefficients from the highest power):
    b_0, Δ_1, Δ_2/Δ_1, ..., Δ_n/Δ_{n-1} (Hurwitz determinants; common factors cancelled). A zero Δ_k (the
    degenerate case, not Hurwitz) ends the column with 0. Memoized."""
    return list(_routh_column(tuple(sp.sympify(c) for c in coeffs)))


@lru_cache(maxsize=256)
def _routh_column(coeffs: tuple[sp.Expr, ...]) -> tuple[sp.Expr, ...]:
    K, deltas = _hurwitz(coeffs)
    ring = K.is_PolynomialRing  # the gcds in the sparse polynomial ring, no conversions
    out = [factor_within(coeffs[0])]
    prev = None
    for d in deltas:
        if not d:
            out.append(sp.Integer(0))
            break
        if prev is None:
            out.append(_short(_to_expr(K, d), _is_expanded(K)))
        elif ring:
            _, a, b = d.cofactors(prev)
            out.append(_short(a.as_expr(), True) / _short(b.as_expr(), True))
        else:
            out.append(_ratio(_to_expr(K, d), _to_expr(K, prev)))
        prev = d
    return tuple(out)


def _ratio(a: sp.Expr, b: sp.Expr) -> sp.Expr:
    """a/b with the polynomial gcd cancelled (a, b polynomials in their symbols)."""
    if b == 1:
        return _short(a)
    gens = sorted((a.free_symbols | b.free_symbols), key=lambda x: x.name)
    if not gens:
        return sp.nsimplify(a / b)
    try:  # sparse polynomials: their gcd is ~10x faster than the dense Poly's on these many-parameter entries
        _, (pa, pb) = sring([sp.expand(a), sp.expand(b)], *gens)
        _, ca, cb = pa.cofactors(pb)
        return _short(ca.as_expr(), True) / _short(cb.as_expr(), True)
    except (sp.PolynomialError, sp.GeneratorsNeeded):
        return sp.cancel(a / b)


def _short(p: sp.Expr, expanded: bool = False) -> sp.Expr:
    """A polynomial factored when that is shorter (and cheap); ``expanded``: p is expanded already (a ring
    element's expression: expanding it again walks every term for nothing)."""
    p = p if expanded else sp.expand(p)
    if count_ops(p) > 400:
        return p
    f = factor_within(p)
    return f if count_ops(f) <= count_ops(p) else p


def hurwitz_conditions(column: Sequence[sp.Expr]) -> list[sp.Expr]:
    """The non-trivial conditions c > 0 for every root in the open left half plane, one per entry of the Routh
    column (b_0 > 0 taken as the reference sign), reduced by :func:`solver.math.equivalence.reduce_conditions`
    (positive factors, always-true conditions and factors that are earlier conditions removed)."""
    return reduce_conditions(list(column))


def always_positive(c: sp.Expr) -> bool | None:
    """True when c = n/d with n and d polynomials with positive coefficients (or an AM-GM certificate) in
    positive symbols (hence > 0 everywhere), False when c is a non-positive number, None when undecided. n and d
    are read over the ring of c's symbols (:func:`solver.math.equivalence.ring_numer_denom`, nothing expanded
    as expressions), else from the expansion."""
    c = sp.sympify(c)
    if c.is_number:
        return bool(sp.expand(c) > 0)
    if not all(s.is_positive for s in c.free_symbols):
        return None
    nd = ring_numer_denom(c)
    if nd is not None and not all(g.is_Symbol for g in nd[0].ring.symbols):
        return None  # (sines, cosines: not positive generators)
    if nd is not None:
        if all(p.is_ground for p in nd):  # a number written otherwise: its sign
            return bool(nd[0].LC * nd[1].LC > 0)
        parts = [[(m, Fraction(int(k.numerator), int(k.denominator))) for m, k in p.terms()] for p in nd]
    else:
        c = sp.expand(c)
        if c.is_number:
            return bool(c > 0)
        if any(p.exp.is_negative for p in c.atoms(sp.Pow)):
            num, den = sp.fraction(sp.together(c))
            exprs: tuple[sp.Expr, ...] = (sp.expand(num), sp.expand(den))
        else:  # a polynomial, expanded above: together() would only clear the rational coefficients' denominators
            exprs = (c,)
        parts = [_terms(e) for e in exprs]
        if any(p is None for p in parts):
            return None
    for terms in parts:
        if all(k > 0 for _, k in terms) or _amgm(terms):
            continue
        return None
    return True


def _terms(p: sp.Expr) -> list[tuple[tuple[int, ...], Fraction]] | None:
    """The (exponents, coefficient) terms of a polynomial with rational coefficients; None for anything else."""
    gens = sorted(p.free_symbols, key=lambda x: x.name)
    if not gens:
        return [((), Fraction(str(p)))] if p.is_Rational else None
    try:
        P = sp.Poly(p, *gens)
    except sp.PolynomialError:
        return None
    if any(not k.is_Rational for _, k in P.terms()):
        return None
    return [(m, Fraction(int(k.p), int(k.q))) for m, k in P.terms()]


def amgm_certificate(p: sp.Expr, max_terms: int = 400) -> bool:
    """Whether the polynomial p (in positive symbols) is > 0 by an AM-GM certificate (:func:`_amgm`)."""
    terms = _terms(sp.expand(p))
    return terms is not None and _amgm(terms, max_terms)


def _amgm(terms: list[tuple[tuple[int, ...], Fraction]], max_terms: int = 400) -> bool:
    """Whether Σ c·m (exponents m, coefficients c, positive symbols) is > 0 by an AM-GM certificate: every negative
    term −c·m is covered by pairs of positive terms a·x, b·y with x·y = m² (a x + b y ≥ 2√(ab)·m), found by a
    linear program (exact, :func:`solver.math.search.lp_max`, up to EXACT_LP_PAIRS pairs; scipy's HiGHS for
    larger ones; not run when some negative term has no pair) and re-checked in exact rational arithmetic. A
    sufficient test: False means "not proved"."""
    if len(terms) > max_terms:
        return False
    pos = {m: c for m, c in terms if c > 0}
    neg = {m: -c for m, c in terms if c < 0}
    if not pos:
        return False
    if 0 not in [sum(m) for m in pos] and all(all(e == 0 for e in m) for m in neg):
        return False
    pairs = []  # (negative monomial, x, y) with x + y = 2 m; x == y allowed (a term covering itself)
    for m in neg:
        for x in pos:
            y = tuple(2 * a - b for a, b in zip(m, x))
            if min(y, default=0) >= 0 and y in pos and x <= y:
                pairs.append((m, x, y))
    if len({m for m, _, _ in pairs}) < len(neg):  # a negative term no pair covers: the program is infeasible
        return False
    pl, nl = list(pos), list(neg)
    # variables t_k >= 0: pair k uses t_k of x and of y (t_k of x when x == y) and covers 2 t_k (t_k) of m
    A_ub: list[list[int]] = []
    b_ub: list[Fraction] = []
    for x in pl:  # usage of each positive term <= its coefficient
        A_ub.append([(1 if x in (px, py) else 0) for (_, px, py) in pairs])
        b_ub.append(pos[x])
    for m in nl:  # coverage of each negative term >= its coefficient
        A_ub.append([-(1 if px == py else 2) if pm == m else 0 for (pm, px, py) in pairs])
        b_ub.append(-neg[m])
    cost = [(1 if px == py else 2) for (_, px, py) in pairs]  # use as little as possible: keep slack
    if len(pairs) <= EXACT_LP_PAIRS:  # exact, and without scipy.optimize's import (half a second to a second)
        status, exact = lp_max([-c for c in cost], A_ub, b_ub)
        if status != 0 or exact is None:
            return False
        t = exact
    else:
        from scipy.optimize import linprog
        res = linprog(cost, A_ub=A_ub, b_ub=[float(b) for b in b_ub], bounds=[(0, None)] * len(pairs),
                      method="highs")
        if res.status != 0:
            return False
        t = [Fraction(v).limit_denominator(10**6) for v in res.x]
    use = {x: Fraction(0) for x in pl}
    cover = {m: Fraction(0) for m in nl}
    for tk, (m, x, y) in zip(t, pairs):
        use[x] += tk
        if y != x:
            use[y] += tk
        cover[m] += tk if x == y else 2 * tk
    covered = all(use[x] <= pos[x] for x in pl) and all(cover[m] >= neg[m] for m in nl)
    return covered and any(use[x] < pos[x] for x in pl)  # a positive term left over: strictly positive


def stable_for_all(conditions: Sequence[sp.Expr], samples: int = 3000,
                   seed: int = 7) -> tuple[bool | None, dict[sp.Symbol, sp.Expr] | None]:
    """Whether every condition holds for all admissible parameter values: (True, None) when proved (positive
    coefficients, or an AM-GM certificate), (False, witness) when a random search finds parameter values (exact
    rationals, re-checked exactly) where a condition fails, (None, None) otherwise."""
    verdicts = [always_positive(c) for c in conditions]
    if any(v is False for v in verdicts):
        return False, {}
    if all(v is True for v in verdicts):
        return True, None
    syms = sorted(set().union(*[sp.sympify(c).free_symbols for c in conditions]), key=lambda x: x.name)
    if not syms or not all(x.is_positive for x in syms):
        return None, None  # conditions on gains of any sign: they are design conditions, not a property
    rng = np.random.default_rng(seed)
    X = 10 ** rng.uniform(-2, 2, size=(samples, len(syms)))  # every sample at once (log-uniform in [0.01, 100])
    bad = np.zeros(samples, dtype=bool)
    with np.errstate(all="ignore"):
        for c in conditions:
            try:
                val = np.broadcast_to(np.asarray(evaluate_np(sp.sympify(c), syms, list(X.T)), dtype=float),
                                      (samples,))
            except (ZeroDivisionError, OverflowError, ValueError, TypeError):
                continue
            bad |= val <= 0
    for i in np.flatnonzero(bad):  # in the order drawn; a candidate is re-checked exactly at rounded values
        point = {x: sp.Rational(repr(round(v, 3)) if abs(v) >= 1 else f"{v:.3g}")  # (the decimal, exactly)
                 for x, v in zip(syms, X[i].tolist())}
        if any(sp.sympify(c).xreplace(point) <= 0 for c in conditions):
            return False, point
    return None, None


def classify(loop: LinearLoop, subs: dict, s: sp.Symbol) -> str | None:
    """The stability of the closed loop at numeric parameter values ``subs``: "asymptotic" (every root of det A(s)
    in the open left half-plane), "marginal" (none in the right half-plane, and each root s₀ on the imaginary axis
    semisimple: dim ker A(s₀) equal to its multiplicity, e.g. a simple pole at s = 0 of an undriven direction) or
    "unstable" (a root in the right half-plane, or a repeated one on the axis with fewer independent modes: a
    response growing like t); None when symbols remain or det A(s) is constant. Exact where it matters: the
    values as rationals, the multiplicities from the square-free factorization, the kernel at s = 0 exactly."""
    exact = {k: sp.Rational(float(v)) if isinstance(v, (float, sp.Float)) else v for k, v in subs.items()}
    A2, A1, A0 = (M.xreplace(exact) for M in (loop.A2, loop.A1, loop.A0))
    if any(e.free_symbols for M in (A2, A1, A0) for e in M):
        return None
    p = sp.Poly(char_poly(LinearLoop(loop.x, loop.dx, loop.ddx, A2, A1, A0, loop.r0), s), s)
    if p.degree() < 1:
        return None
    if not all(c.is_Rational for c in p.all_coeffs()):  # (radicals, π: their rational approximations)
        p = sp.Poly([sp.Rational(float(c)) if c != 0 else 0 for c in p.all_coeffs()], s)
    try:
        factors = sp.sqf_list(p)[1]
    except (sp.PolynomialError, sp.DomainError):
        factors = [(p, 1)]
    axis: list[tuple[complex, int]] = []
    for f, k in factors:
        roots = np.roots([complex(c) for c in f.all_coeffs()])
        scale = max([1.0] + [abs(r) for r in roots])
        for r in roots:
            if r.real > 1e-9 * scale:
                return "unstable"
            if r.real >= -1e-9 * scale:
                axis.append((complex(0.0, r.imag), k))
    if not axis:
        return "asymptotic"
    n = A0.rows
    for s0, k in axis:
        if k == 1:
            continue  # a simple root: one mode
        if s0 == 0:
            nullity = n - A0.rank()
        else:
            M = np.array((A2 * s0 ** 2 + A1 * s0 + A0).evalf().tolist(), dtype=complex)
            sv = np.linalg.svd(M, compute_uv=False)
            nullity = int(np.sum(sv <= 1e-9 * max(1.0, sv[0])))
        if nullity < k:
            return "unstable"
    return "marginal"


def marginal_for_all(loop: LinearLoop, factors: Sequence[tuple[sp.Expr, int]], s: sp.Symbol) -> bool | None:
    """For a loop whose only roots off the open left half-plane are at s = 0 (factors c·s, total multiplicity k)
    for every positive value of the parameters (every other factor's Routh conditions proved): True (marginally
    stable) when dim ker A(0) = k for generic values (then for all: it cannot exceed k), False (unstable) when it
    is smaller; None when another factor is not proved stable or there is no root at s = 0."""
    k = 0
    for f, m in factors:
        P = sp.Poly(f, s)
        if P.degree() == 1 and P.nth(0) == 0:
            k += m
            continue
        conditions = hurwitz_conditions(routh_column(coefficients(f, s)))
        if conditions and stable_for_all(conditions)[0] is not True:
            return None
    if k == 0:
        return None
    return loop.A0.rows - loop.A0.rank(simplify=True) == k


# ------------------------------------------------------------------------------------------------ design
def desired_polynomial(s: sp.Symbol, poles: Sequence[sp.Expr] | None = None, omega_n: sp.Expr | None = None,
                       zeta: sp.Expr | None = None) -> sp.Expr:
    """Π (s - p_i), or s² + 2ζω_n s + ω_n²."""
    if poles is not None:
        return sp.expand(sp.Mul(*[(s - p) for p in poles]))
    return sp.expand(s**2 + 2 * zeta * omega_n * s + omega_n**2)


def match_polynomial(p: sp.Expr, target: sp.Expr, s: sp.Symbol, unknowns: Sequence[sp.Symbol]) -> dict | None:
    """Values of ``unknowns`` with p(s) ≡ a_n·target(s) (a_n the leading coefficient of p, target monic of the
    same degree). None when no solution exists."""
    P = sp.Poly(sp.expand(p), s)
    T = sp.Poly(sp.expand(target), s)
    if P.degree() != T.degree():
        return None
    lead = P.LC()
    eqs = [sp.expand(c - lead * t) for c, t in zip(P.all_coeffs()[1:], T.all_coeffs()[1:])]
    eqs = [e for e in eqs if e != 0]
    sol = [x for x in sp.solve(eqs, list(unknowns), dict=True)  # (sympy drops an equation free of the unknowns,
           if all(identically_zero(e.xreplace(x)) for e in eqs)]   #  e.g. a constant term that no gain reaches)
    if not sol:
        return None
    return {k: factor_within(v) for k, v in sol[0].items()}


def second_order(m: sp.Expr, d: sp.Expr, k: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """(ω_n, ζ) of m s² + d s + k: ω_n = √(k/m), ζ = d / (2√(k m))."""
    return sp.sqrt(k / m), d / (2 * sp.sqrt(k * m))


def short_poles(p: sp.Expr, s: sp.Symbol, max_ops: int = 24) -> list[sp.Expr] | None:
    """:func:`poles`, but closed forms only when they are short enough to read."""
    out = poles(p, s)
    if out is not None and sum(count_ops(x) for x in out) > max_ops:
        return None
    return out


def poles(p: sp.Expr, s: sp.Symbol) -> list[sp.Expr] | None:
    """Roots of p(s): numeric (complex floats as sympy numbers) when p has numeric coefficients, closed form up to
    degree 2 otherwise, None beyond."""
    poly = sp.Poly(sp.expand(p), s)
    if all(c.is_number for c in poly.all_coeffs()):
        roots = np.roots([complex(c) for c in poly.all_coeffs()])
        out = []
        for r in sorted(roots, key=lambda z: (z.real, z.imag)):
            re_, im = float(r.real), float(r.imag)
            out.append(sp.Float(re_, 6) + (sp.I * sp.Float(im, 6) if abs(im) > 1e-9 * max(1.0, abs(re_)) else 0))
        return out
    if poly.degree() <= 2:
        return [tidy(r) for r in sp.roots(poly, multiple=True)]
    return None


# ------------------------------------------------------------------------------------------------ numerics
def expm(A: np.ndarray) -> np.ndarray:
    """e^A by scaling and squaring: the Taylor series of e^{A/2^s} with ‖A/2^s‖₁ ≤ 1/2 to 20 terms (remainder
    below 2⁻²¹/21! ≈ 10⁻²⁶), squared s times."""
    norm = float(np.linalg.norm(A, 1))
    s = int(np.ceil(np.log2(norm / 0.5))) if norm > 0.5 else 0
    B = A / 2.0 ** s
    out = term = np.eye(A.shape[0])
    for k in range(1, 21):
        term = term @ B / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def simulate(loop: LinearLoop, subs: dict[sp.Symbol, float], x0: Sequence[float], v0: Sequence[float],
             t_end: float, points: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The exact response of A2 ẍ + A1 ẋ + A0 x + r0 = 0 (numbers substituted) from (x0, v0) on ``points``
    equally spaced times of [0, t_end]; rows of A2 that are zero are algebraic-free integrator rows (ẋ appears
    instead): A2 may be singular only where A1 is not, e.g. the integral state w with ẇ = e. The state y (x and
    the ẋ of the second-order coordinates) obeys ẏ = K y + k, so that [y(t + h); 1] = e^{[K k; 0 0] h} [y(t); 1]
    (no numerical integration, no scipy.integrate). Returns (t, x(t), ẋ(t)) as arrays."""
    def num(M: sp.Matrix) -> np.ndarray:
        return np.array(M.xreplace(subs).evalf().tolist(), dtype=float)

    A2, A1, A0, r0 = num(loop.A2), num(loop.A1), num(loop.A0), num(loop.r0).ravel()
    n = A2.shape[0]
    second = [i for i in range(n) if np.any(A2[:, i] != 0)]
    first = [i for i in range(n) if i not in second]
    # state: x (all), ẋ of the second-order coordinates; unknowns per step: ẍ of `second`, ẋ of `first`
    E = np.zeros((n, n))
    E[:, second] = A2[:, second]
    E[:, first] = A1[:, first]

    def rhs(y: np.ndarray) -> np.ndarray:
        x = y[:n]
        v = np.zeros(n)
        v[second] = y[n:]
        b = -(A1[:, second] @ v[second] + A0 @ x + r0)
        sol = np.linalg.solve(E, b)
        dx = np.zeros(n)
        dx[second] = v[second]
        dx[first] = sol[first]
        return np.concatenate([dx, sol[second]])

    y0 = np.concatenate([np.asarray(x0, float), np.asarray(v0, float)[second]])
    m = len(y0)
    k = rhs(np.zeros(m))  # ẏ = K y + k: k at y = 0, the columns of K from the unit vectors
    Kt = np.zeros((m + 1, m + 1))
    Kt[:m, m] = k
    for j, unit in enumerate(np.eye(m)):
        Kt[:m, j] = rhs(unit) - k
    t = np.linspace(0.0, t_end, points)
    step = expm(Kt * (t[1] - t[0])) if points > 1 else np.eye(m + 1)
    Y = np.empty((m + 1, points))
    Y[:, 0] = np.append(y0, 1.0)
    for j in range(1, points):
        Y[:, j] = step @ Y[:, j - 1]
    return t, Y[:n], (Kt @ Y)[:n]  # ẋ: the first rows of ẏ = K y + k
