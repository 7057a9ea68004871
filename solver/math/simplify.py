"""Teacher-style simplification of manipulator formulas.

Dynamics expressions are trigonometric polynomials: sums of products of sin/cos of linear combinations of
angles, with polynomial coefficients in the parameters, prismatic coordinates and velocities. Writing
cos(x) = (z + 1/z)/2 and sin(x) = (z - 1/z)/(2i) with z = e^{ix} for every angle turns such an expression into a
Laurent polynomial in the z's, whose collected form is unique. Pairing the monomials z^k and z^{-k} gives the
canonical Fourier form

    f = a_0 + sum_k ( a_k cos(k.x) + b_k sin(k.x) ),

which is what a teacher prints (c_2, c_{23}, s_{12} rather than products), with each coefficient factored.
Because the form is canonical, f == 0 exactly when the canonical form of f is 0 (no false zeros from numerics).
Expressions outside this class (rational in trig functions, tan, atan2, ...) fall back to sympy's simplifiers.
"""
from __future__ import annotations

from fractions import Fraction
from functools import lru_cache
from typing import Any

import sympy as sp
from sympy.polys.domains import QQ, ZZ

from solver.math.fourier import (NotTrigPolynomial, TrigPoly, _Algebra, _canon, add_distinct, factor_small,
                                  fourier_coefficients, mul_distinct, nice_poly, product_cost_bound, product_form,
                                  product_groups)
from solver.math.budget import BudgetExceeded, cpu_budget
from solver.math.opcount import count_ops

_TRIG = (sp.sin, sp.cos)
FACTOR_BUDGET = 5.0  # CPU seconds of one cosmetic factorization (a hang on an unlucky generator order)


def angle_symbols(expr: sp.Expr) -> list[sp.Symbol]:
    """Symbols appearing inside sin/cos arguments, sorted by name."""
    found: set[sp.Symbol] = set()
    for f in expr.atoms(sp.sin, sp.cos):
        found |= f.args[0].free_symbols
    return sorted(found, key=lambda s: s.name)


def _linear(arg: sp.Expr, angles: list[sp.Symbol]) -> tuple[tuple[int, ...], sp.Expr]:
    """arg = k.x + b with integer k and constant b, or NotTrigPolynomial."""
    poly = sp.Poly(arg, *angles) if angles else None
    if poly is None or poly.total_degree() > 1:
        raise NotTrigPolynomial(arg)
    k = []
    for x in angles:
        c = poly.coeff_monomial(x)
        if not (c.is_Integer):
            raise NotTrigPolynomial(arg)
        k.append(int(c))
    b = poly.coeff_monomial(1)
    if b.free_symbols:
        raise NotTrigPolynomial(arg)
    return tuple(k), b


def _laurent_coefficients(expr: sp.Expr, angles: list[sp.Symbol]) -> dict[tuple[int, ...], tuple[sp.Expr, sp.Expr]]:
    """{k: (a_k, b_k)} through z = e^{ix}: general (any constant offsets) but slower than
    :func:`solver.fourier.fourier_coefficients`."""
    if expr.atoms(sp.tan, sp.cot, sp.sec, sp.csc, sp.atan2, sp.asin, sp.acos, sp.atan, sp.Abs, sp.sign):
        raise NotTrigPolynomial(expr)
    aset = set(angles)
    if any(not (p.exp.is_Integer and p.exp > 0) and p.base.free_symbols & aset for p in expr.atoms(sp.Pow)):
        raise NotTrigPolynomial(expr)   # an angle in a denominator or a radical: refused before expanding
    fast = _offset_coefficients(expr, angles)
    if fast is not None:
        return fast
    zs = [sp.Dummy(f"z_{x.name}") for x in angles]

    def expo(k: tuple[int, ...], b: sp.Expr, sign: int) -> sp.Expr:
        mono = sp.Mul(*[z ** (sign * kj) for z, kj in zip(zs, k)])
        phase = sp.cos(b) + sign * sp.I * sp.sin(b) if b != 0 else sp.Integer(1)
        return mono * phase

    def sub(f: sp.Expr) -> sp.Expr:
        k, b = _linear(f.args[0], angles)
        if isinstance(f, sp.cos):
            return (expo(k, b, 1) + expo(k, b, -1)) / 2
        return (expo(k, b, 1) - expo(k, b, -1)) / (2 * sp.I)

    laurent = sp.expand(expr.replace(lambda e: isinstance(e, _TRIG), sub))
    zset = set(zs)
    coeffs: dict[tuple[int, ...], list[sp.Expr]] = {}
    for term in sp.Add.make_args(laurent):
        k = [0] * len(zs)
        rest = []
        for fac in sp.Mul.make_args(term):
            base, e = fac.as_base_exp()
            if base in zset and e.is_Integer:
                k[zs.index(base)] += int(e)
            elif fac.free_symbols & zset:
                raise NotTrigPolynomial(expr)
            else:
                rest.append(fac)
        coeffs.setdefault(tuple(k), []).append(sp.Mul(*rest))
    out: dict[tuple[int, ...], tuple[sp.Expr, sp.Expr]] = {}
    for k in coeffs:
        if next((v for v in k if v), 1) < 0:
            continue
        ck = sp.Add(*coeffs[k])
        if not any(k):
            out[k] = (sp.expand(ck), sp.Integer(0))
            continue
        cn = sp.Add(*coeffs.get(tuple(-v for v in k), []))
        a, b = sp.expand(ck + cn), sp.expand(sp.I * (ck - cn))
        if a.has(sp.I) or b.has(sp.I):
            raise NotTrigPolynomial(expr)
        out[k] = (a, b)
    for k in coeffs:  # terms present only with negative k
        neg = tuple(-v for v in k)
        if next((v for v in k if v), 1) < 0 and neg not in out:
            cn = sp.Add(*coeffs[k])
            a, b = sp.expand(cn), sp.expand(-sp.I * cn)
            if a.has(sp.I) or b.has(sp.I):
                raise NotTrigPolynomial(expr)
            out[neg] = (a, b)
    return out


_SQRT: dict[int, sp.Dummy] = {}  # n -> the generator standing for √n in :class:`_OffsetAlgebra`


class _OffsetAlgebra(_Algebra):
    """fourier's algebra with two more kinds of atoms, the ones offsets such as π/4 or π/6 bring: √n (n a positive
    integer, a generator r with r² = n applied at the end) and sin/cos(k·x + b) of any constant b whose sin and cos
    are sums of rationals and such roots (cos(k·x + b) = cos b cos(k·x) − sin b sin(k·x)). Anything else raises
    NotTrigPolynomial, as in fourier's algebra."""

    def __init__(self, angles: list[sp.Symbol], gens: list[sp.Symbol], inverse: dict[sp.Expr, sp.Dummy]) -> None:
        super().__init__(angles, gens)
        self.inverse = inverse   # {a symbol or a sum without angles, as written: the generator standing for its 1/·}

    def conv(self, e: sp.Expr) -> TrigPoly:
        if e.is_Pow and e.exp == sp.S.Half and e.base.is_Integer and e.base > 0:
            g = _SQRT.get(int(e.base))
            if g is None or g not in self.gen:
                raise NotTrigPolynomial(e)
            return self.const(self.gen[g])
        if e.is_Pow and e.exp.is_Integer and e.exp < 0:
            t = self.inverse.get(e.base)
            if t is None:
                raise NotTrigPolynomial(e)
            return self.const(self.gen[t] ** int(-e.exp))
        return super().conv(e)

    def trig(self, f: sp.Expr) -> TrigPoly:
        k = [0] * len(self.angles)
        b = sp.Integer(0)
        for term, coeff in f.args[0].as_coefficients_dict().items():
            if term in self.index and coeff.is_Integer:
                k[self.index[term]] += int(coeff)
            elif term.is_number:
                b += coeff * term
            else:
                raise NotTrigPolynomial(f)
        if not any(k):  # (a constant sin/cos: the general path decides)
            raise NotTrigPolynomial(f)
        cos_b, sin_b = self.conv(sp.cos(b)), self.conv(sp.sin(b))
        kc, sc = _canon(tuple(k), 0)   # (the sign of cos(-k·x) is +1)
        ks, ss = _canon(tuple(k), 1)
        cos_k, sin_k = {kc: self.R.one}, {ks: self.R.one if ss > 0 else -self.R.one}
        if isinstance(f, sp.cos):   # cos(k·x + b) = cos b cos(k·x) − sin b sin(k·x)
            return self._sum(self.mul(cos_b, cos_k), self.mul(sin_b, sin_k), -1)
        return self._sum(self.mul(sin_b, cos_k), self.mul(cos_b, sin_k), 1)   # sin b cos(k·x) + cos b sin(k·x)

    def _sum(self, a: TrigPoly, b: TrigPoly, sign: int) -> TrigPoly:
        out = dict(a)
        for key, c in b.items():
            self.add_into(out, key, c if sign > 0 else -c)
        return out


def _offset_coefficients(expr: sp.Expr, angles: list[sp.Symbol]) -> dict | None:
    """:func:`_laurent_coefficients` of a trigonometric polynomial whose arguments have constant offsets (π/4, π/6)
    and whose coefficients have square roots of integers (√2/2), by sparse ring arithmetic (:class:`_OffsetAlgebra`)
    instead of expanding the z-form: the coefficients a_k, b_k are polynomials over Q in the symbols and the roots,
    each root's powers reduced (√n² = n) and written back, the same expanded sums as sympy's expansion gives. None
    for anything else (other functions and constants, powers that are not natural numbers, no angle): the general
    path then decides."""
    def root_bases(e: sp.Expr) -> set[int]:
        return {int(p.base) for p in e.atoms(sp.Pow) if p.exp == sp.S.Half and p.base.is_Integer and p.base > 0}

    ns = root_bases(expr)
    for f in expr.atoms(sp.sin, sp.cos):   # and the roots the offsets bring (cos π/4 = √2/2)
        b = f.args[0].as_independent(*angles)[0]
        if b != 0:
            ns |= root_bases(sp.cos(b)) | root_bases(sp.sin(b))
    if len(ns) > 1:   # (√2·√3 is √6: a relation between the roots; the general path)
        return None
    inverse: dict[sp.Expr, sp.Dummy] = {}   # 1/m₂, 1/(a² + q₂²): a generator each, by the expanded base
    by_base: dict[sp.Expr, sp.Dummy] = {}   # the same by the base as written
    sums: set[sp.Expr] = set()   # the bases as written whose expansion is a sum
    for p in expr.atoms(sp.Pow):
        if p.exp.is_Integer and p.exp < 0 and p.base not in by_base:
            key = p.base if p.base.is_Symbol else sp.expand(p.base)
            if not (key.is_Symbol or key.is_Add):
                return None
            by_base[p.base] = inverse.setdefault(key, sp.Dummy("inv"))
            if key.is_Add:
                sums.add(p.base)
    trig_over_sum = bool(sums) and _trig_over_sum(expr, frozenset(sums))
    if sums and not trig_over_sum:  # a sum in a denominator of terms without angles only: the general path (its
        return None                 # expanded form is sympy's), the ring not built
    gens = sorted(expr.free_symbols, key=lambda s: s.name)
    alg = _OffsetAlgebra(angles, gens + [_SQRT.setdefault(n, sp.Dummy(f"sqrt{n}")) for n in sorted(ns)]
                         + list(inverse.values()), by_base)
    try:
        tp = alg.conv(expr)
    except NotTrigPolynomial:
        return None
    R = alg.R
    roots = [(R.symbols.index(_SQRT[n]), n) for n in ns]
    pairs = [(R.symbols.index(b), R.symbols.index(t)) for b, t in inverse.items() if b.is_Symbol]

    def reduced(p):  # type: ignore[no-untyped-def]
        """p with √n² = n and x·(1/x) = 1 applied: a polynomial in the roots and a Laurent one in the symbols."""
        if not roots and not pairs:
            return p
        acc: dict = {}
        for mono, c in p.iterterms():
            m = list(mono)
            for i, n in roots:
                c *= R.domain(n) ** (m[i] // 2)
                m[i] %= 2
            for i, j in pairs:
                low = min(m[i], m[j])
                m[i] -= low
                m[j] -= low
            acc[tuple(m)] = acc.get(tuple(m), R.domain.zero) + c
        return R.from_dict({m: c for m, c in acc.items() if c})

    if trig_over_sum:
        # sympy's expansion of the z-form writes a term z⁻ᵏ/(a² + q₂²) over one expanded denominator (the z inside
        # it), which the general path refuses: so does this one, wherever a product of the expansion, before like
        # terms are collected, has a sine or cosine and such a denominator (whether sympy's collection would by
        # chance cancel every such term is not looked for: refused before expanding)
        raise NotTrigPolynomial(expr)
    tp = {key: r for key, c in tp.items() if (r := reduced(c))}
    back = list(R.symbols)
    for i, n in roots:
        back[i] = sp.sqrt(n)
    for b, t in inverse.items():
        back[R.symbols.index(t)] = 1 / b
    zero = sp.Integer(0)
    out: dict[tuple[int, ...], tuple[sp.Expr, sp.Expr]] = {}
    for (k, kind), c in tp.items():
        a, b = out.get(k, (zero, zero))
        out[k] = (c.as_expr(*back), b) if kind == 0 else (a, c.as_expr(*back))
    return out


def _trig_over_sum(expr: sp.Expr, sums: frozenset) -> bool:
    """Whether a product of the expansion of ``expr`` (a sum of products of its leaves, before like terms are
    collected) has both a sin/cos and a negative power of one of the bases ``sums``. Read on the tree: for each node
    the kinds (sin/cos or not, such a denominator or not) of the products its expansion has, a product's kinds
    the unions of one kind of each factor."""
    memo: dict[sp.Expr, frozenset] = {}

    def kinds(e: sp.Expr) -> frozenset:
        hit = memo.get(e)
        if hit is not None:
            return hit
        if isinstance(e, (sp.sin, sp.cos)) and e.free_symbols:
            out = frozenset({(True, False)})
        elif e.is_Add:
            out = frozenset().union(*(kinds(a) for a in e.args))
        elif e.is_Mul or (e.is_Pow and e.exp.is_Integer and e.exp > 0):
            factors = e.args if e.is_Mul else [e.base] * min(int(e.exp), 3)   # (3 factors reach every union)
            out = frozenset({(False, False)})
            for f in factors:
                out = frozenset((t1 or t2, d1 or d2) for t1, d1 in out for t2, d2 in kinds(f))
        elif e.is_Pow and e.exp.is_Integer and e.exp < 0 and e.base in sums:
            out = frozenset({(False, True)})
        else:
            out = frozenset({(False, False)})
        memo[e] = out
        return out
    return (True, True) in kinds(expr)


# Size limits of the printed form: a trigonometric polynomial with more monomials than LARGE (over all its
# Fourier coefficients; LARGE_MANY_ANGLES with more than three angles) keeps the Fourier form (no product form c₂ s₂ ...) and its coefficients are not fully
# factored (content and monomial factors only), since factoring and comparing forms cost more than they give.
LARGE = 400
LARGE_MANY_ANGLES = 60  # the same past this size when more than three angles occur (six-joint arms)


def _fourier(expr: sp.Expr) -> sp.Expr:
    """Canonical Fourier form of a trigonometric polynomial (see module doc)."""
    angles = angle_symbols(expr)
    try:
        coeffs: dict = fourier_coefficients(expr, angles)
    except NotTrigPolynomial:
        return fourier_expr(_laurent_coefficients(expr, angles), angles, _nice)
    return fourier_expr(coeffs, angles)


def fourier_expr(coeffs: dict, angles: list[sp.Symbol], nice=nice_poly) -> sp.Expr:  # type: ignore[no-untyped-def]
    """The printed form of f = Σ a_k cos(k·x) + b_k sin(k·x) given by its coefficients {k: (a_k, b_k)}
    (polynomials, or sympy expressions with ``nice=_nice``): each coefficient through ``nice``, and the product
    form over single angles when shorter (only below the size LARGE)."""
    fourier, nice, large = _fourier_sum(coeffs, angles, nice)
    mixed = any(v < 0 or v > 1 for k in coeffs for v in k if any(k))
    if mixed and not large:
        if nice is nice_poly:
            groups = product_groups(coeffs, angles)
            if product_cost_bound(groups) >= count_ops(fourier):  # (it cannot be shorter: not printed)
                return fourier
            product = product_form(coeffs, angles, groups)
        else:
            product = _product_form(fourier, angles)
        if count_ops(product) < count_ops(fourier):
            return product
    return fourier


def fourier_sum_ops(coeffs: dict, angles: list[sp.Symbol]) -> int:
    """count_ops of the Fourier sum of polynomial coefficients as :func:`fourier_expr` writes it: an upper bound of
    count_ops(fourier_expr(coeffs, angles)) (the product form is printed only when shorter), without the product
    form."""
    return count_ops(_fourier_sum(coeffs, angles, nice_poly)[0])


def _fourier_sum(coeffs: dict, angles: list[sp.Symbol], nice):  # type: ignore[no-untyped-def]
    """(Σ nice(a_k) cos(k·x) + nice(b_k) sin(k·x), the ``nice`` used, large): :func:`fourier_expr`'s Fourier
    form, each coefficient through ``nice`` (content and monomial only past the size LARGE)."""
    size = sum(len(a) + len(b) for a, b in coeffs.values()) if nice is nice_poly else 0
    used = sum(1 for j in range(len(angles)) if any(k[j] for k in coeffs))
    large = size > LARGE or (used > 3 and size > LARGE_MANY_ANGLES)
    if large:
        nice = _nice_large
    out = []
    ang = tuple(angles)
    # rational polynomial coefficients: the products and the sum built directly (fourier.mul_distinct, add_distinct)
    direct = nice is not _nice and all(p.ring.domain in (QQ, ZZ) for ab in coeffs.values() for p in ab)
    for k in sorted(coeffs, key=lambda t: (sum(abs(v) for v in t), [-abs(v) for v in t], t)):
        a, b = coeffs[k]
        theta, cos, sin = _harmonic(k, ang)
        phased = _with_phase(a, b, theta) if nice is _nice and a and b else None
        if phased is not None:
            out.append(phased)
            continue
        if direct and not any(k):
            if a:
                out.append(nice(a))
            continue
        if a:
            out.append(_term(nice(a), cos) if direct else nice(a) * cos)
        if b:
            out.append(_term(nice(b), sin) if direct else nice(b) * sin)
    if not out:
        return sp.S.Zero, nice, large
    return (add_distinct(out) if direct else sp.Add(*out)), nice, large


_TERMS: dict[tuple[sp.Expr, sp.Expr], sp.Expr] = {}  # (coefficient, cos/sin) -> their product


def _term(c: sp.Expr, f: sp.Expr) -> sp.Expr:
    """The term c·f of a coefficient and a harmonic's cos/sin (fourier.mul_distinct), one object per product: the same terms recur in a model's entries, and the
    printers' memos then find them by identity (as sympy's cache made them: an equal object costs a comparison)."""
    hit = _TERMS.get((c, f))
    if hit is None:
        if len(_TERMS) > 50000:
            _TERMS.clear()
        hit = _TERMS[(c, f)] = mul_distinct(sp.S.One, [c, f])
    return hit


@lru_cache(maxsize=4096)
def _harmonic(k: tuple[int, ...], angles: tuple[sp.Symbol, ...]) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """(θ = k·x, cos θ, sin θ), built once per harmonic; without sympy's evaluation of cos and sin when it has
    nothing to do (θ a sum of symbols without a minus sign to extract: no multiple of π, no zero), the same
    objects."""
    if not any(k):
        return sp.S.Zero, sp.S.One, sp.S.Zero
    theta = sum((kj * x for kj, x in zip(k, angles)), sp.Integer(0))
    evaluate = not theta.free_symbols or theta.could_extract_minus_sign() or \
        not all(type(x) is sp.Symbol for x in theta.free_symbols)
    return theta, sp.cos(theta, evaluate=evaluate), sp.sin(theta, evaluate=evaluate)


def _nice_large(p):  # type: ignore[no-untyped-def]
    """A coefficient of a large polynomial: content and monomial factor only."""
    return nice_poly(p, max_terms=0)


def _with_phase(a: sp.Expr, b: sp.Expr, theta: sp.Expr) -> sp.Expr | None:
    """a cos θ + b sin θ as one shifted sinusoid when a/b is a number and the phase a rational multiple of π:
    (√2/2)(cos q - sin q) -> cos(q + π/4). Used only for expressions written with such offsets."""
    if not _proportional(a, b):
        return None
    rho = simplified(a / b)
    if not rho.is_number or not rho.is_real:
        return None
    amp = sp.radsimp(sp.simplify(b * sp.sqrt(rho**2 + 1)))
    best = None
    for fn, phase in ((sp.cos, sp.atan2(-1, rho)), (sp.sin, sp.atan2(rho, 1))):
        if (phase / sp.pi).is_Rational and (best is None or abs(phase) < abs(best[1])):
            best = (fn, phase)
    if best is None:
        return None
    return _nice(amp) * best[0](theta + best[1])


def _proportional(a: sp.Expr, b: sp.Expr) -> bool:
    """False when a/b is not a number: different symbols, or different values of a/b at two points (floats;
    True means "maybe", for the exact test)."""
    syms = a.free_symbols | b.free_symbols
    if a.free_symbols != b.free_symbols:
        return False
    if not syms:
        return True
    ordered = sorted(syms, key=lambda x: x.name)
    vals = []
    for k in (0, 1):
        point = {x: sp.Float(0.37 + 0.61 * j + 0.29 * k * (j + 1) ** 0.5) for j, x in enumerate(ordered)}
        try:
            vals.append(complex(a.xreplace(point) / b.xreplace(point)))
        except (TypeError, ZeroDivisionError):
            return True
    return abs(vals[0] - vals[1]) <= 1e-9 * max(1.0, abs(vals[0]))


def _product_form(expr: sp.Expr, angles: list[sp.Symbol]) -> sp.Expr:
    """Sum over monomials in sin/cos of single angles (c1 c2, s2^2, ...), coefficients factored."""
    e = sp.expand(sp.expand_trig(expr))
    groups: dict[sp.Expr, list[sp.Expr]] = {}
    for term in sp.Add.make_args(e):
        trig, rest = [], []
        for fac in sp.Mul.make_args(term):
            (trig if fac.has(*angles) and fac.atoms(sp.sin, sp.cos) else rest).append(fac)
        groups.setdefault(sp.Mul(*trig), []).append(sp.Mul(*rest))
    return sp.Add(*[_nice(sp.Add(*c)) * t for t, c in groups.items()])


@lru_cache(maxsize=4096)
def _simplified(e: sp.Basic) -> sp.Basic:
    return sp.simplify(e)


def simplified(e: object) -> object:
    """sp.simplify(e), memoized for exact expressions (a problem's planning asks simplify the same breaks, bounds,
    instants and torques many times). Floats (equal at different precisions) and matrices are not memoized."""
    if isinstance(e, sp.Expr) and not e.has(sp.Float):
        return _simplified(e)
    return sp.simplify(e)


@lru_cache(maxsize=20000)
def factor_within(x: sp.Expr, budget: float = FACTOR_BUDGET) -> sp.Expr:
    """sp.factor(x) within a CPU budget: multivariate factoring (Wang's algorithm) can take minutes for some
    orderings of the generators (they follow the hash seed of the process); past the budget only the common
    factors are pulled out (factor_terms). Memoized: the same coefficients recur across the asks of a problem."""
    try:
        with cpu_budget(budget):
            fast = factor_rational(x)
            return fast if fast is not None else sp.factor(x)
    except BudgetExceeded:
        return sp.factor_terms(x)


class _NotRational(Exception):
    pass


def _fraction(e: sp.Expr, R, index: dict | None = None) -> tuple:  # type: ignore[no-untyped-def]
    """e = n / Π bᵏ in the polynomial ring R: (n, {b: k}) with each b monic, never multiplied out (a denominator
    (q1² + d²)³ stays the cube of its base, whose factors are found on the base alone). ``index``: {generator of R as
    an expression: its position} (built from R when not given). Monomials are read into their term directly and
    the terms of a sum gathered in one dictionary (converting each symbol through R(e) and adding the terms one by
    one, each sum a copy of the last, cost more than the rest)."""
    if index is None:
        index = {x: i for i, x in enumerate(R.symbols)}
    return _read_fraction(e, R, index, R.domain)


def _read_fraction(e: sp.Expr, R, index: dict, QQ) -> tuple:  # type: ignore[no-untyped-def]
    if e.is_Rational:
        return R.ground_new(QQ(e.p, e.q)), {}
    if e.is_Symbol or isinstance(e, (sp.sin, sp.cos)):  # a generator of R (raises if it is not one)
        i = index.get(e)
        if i is None:
            raise ValueError(e)
        return R.gens[i], {}
    if e.is_Add:
        parts = [_read_fraction(a, R, index, QQ) for a in e.args]
        common: dict = {}
        for _, d in parts:
            for b, k in d.items():
                common[b] = max(common.get(b, 0), k)
        acc: dict = {}
        zero = QQ.zero
        for ni, di in parts:
            for b, k in common.items():
                if k > di.get(b, 0):
                    ni = ni * b ** (k - di.get(b, 0))
            for m, c in ni.items():
                acc[m] = acc.get(m, zero) + c
        n = R.zero
        for m, c in acc.items():
            if c:
                n[m] = c
        return n, common
    if e.is_Mul:
        mono = _monomial(e, R, index, QQ)
        if mono is not None:
            return mono, {}
        n, d = R.one, {}
        for a in e.args:
            na, da = _read_fraction(a, R, index, QQ)
            n *= na
            for b, k in da.items():
                d[b] = d.get(b, 0) + k
        return n, d
    if e.is_Pow and e.exp.is_Integer:
        k = int(e.exp)
        nb, db = _read_fraction(e.base, R, index, QQ)
        if k >= 0:
            return nb ** k, {b: j * k for b, j in db.items()}
        if not nb:
            raise ZeroDivisionError
        num = R.one
        for b, j in db.items():
            num *= b ** (-j * k)
        if nb.is_ground:
            return num.quo_ground(nb.LC ** -k), {}
        lc = nb.LC
        return num.quo_ground(lc ** -k), {nb.quo_ground(lc): -k}
    raise _NotRational


def _monomial(e: sp.Expr, R, index: dict, QQ):  # type: ignore[no-untyped-def]
    """The term of R a product of a rational and natural powers of generators is; None for any other product."""
    exps = [0] * R.ngens
    c = QQ.one
    for a in e.args:
        if a.is_Rational:
            c *= QQ(a.p, a.q)
            continue
        b, k = (a.base, a.exp) if a.is_Pow else (a, sp.S.One)
        i = index.get(b)
        if i is None or not (k.is_Integer and k > 0):
            return None
        exps[i] += int(k)
    return R.term_new(tuple(exps), c)


def _ring_generators(x: sp.Expr, opaque_trig: bool = False) -> list[sp.Expr] | None:
    """:func:`_generators` of x (in sympy's order) when x is built of rationals, symbols, sin/cos of symbols, sums,
    products and integer powers only, in one walk of its tree; None for anything else (floats, other numbers and
    functions, radicals: nothing :func:`_fraction` reads) and for an x without symbols. ``opaque_trig``: also sin/cos
    of any non-numeric argument (sin(q1 + q2)), each an independent generator as sympy's polys take it."""
    from sympy.polys.polyutils import _sort_gens
    bare: set = set()
    trig: set = set()
    seen: set = set()
    stack = [x]
    while stack:
        e = stack.pop()
        if e.is_Symbol:
            bare.add(e)
        elif e.is_Rational:
            continue
        elif isinstance(e, (sp.sin, sp.cos)):
            if not (e.args[0].is_Symbol or (opaque_trig and not e.args[0].is_number)):
                return None
            trig.add(e)
        elif e.is_Add or e.is_Mul or (e.is_Pow and e.exp.is_Integer):
            if e in seen:
                continue
            seen.add(e)
            stack.extend(e.args)
        else:
            return None
    if not bare and not trig:
        return None
    return _sort_gens(list(bare | trig))


def _over_QQ(x: sp.Expr) -> bool:
    """Whether x is a rational function with rational coefficients of its symbols and of sin/cos of symbols
    (generators, as sp.factor takes them; no other functions, radicals, floats)."""
    return bool(x.free_symbols) and not x.atoms(sp.Float) and all(
        p.exp.is_Integer for p in x.atoms(sp.Pow)) and all(
        isinstance(f, (sp.sin, sp.cos)) and f.args[0].is_Symbol for f in x.atoms(sp.Function))


def _generators(x: sp.Expr) -> list[sp.Expr]:
    """The generators sp.factor would take, in its order: the symbols outside sin/cos and the sin/cos atoms."""
    from sympy.polys.polyutils import _sort_gens
    trig = x.atoms(sp.sin, sp.cos)
    inner = {f.args[0] for f in trig}
    bare = {s for s in x.free_symbols if s not in inner or _outside_trig(x, s)}
    return _sort_gens(list(bare | trig))


def _outside_trig(x: sp.Expr, s: sp.Symbol) -> bool:
    """Whether the symbol s occurs in x outside the arguments of sin and cos."""
    if x == s:
        return True
    if isinstance(x, (sp.sin, sp.cos)):
        return False
    return any(_outside_trig(a, s) for a in x.args)


def _factors(p) -> tuple:  # type: ignore[no-untyped-def]
    """(content, {factor as an expression: exponent}) of the polynomial p, by fourier's memoized factorization in
    the ring of the generators p uses."""
    if p.is_ground:
        return p.LC, {}
    content, fl = factor_small(p)
    out: dict = {}
    for g, k in fl:
        key = g.as_expr()
        out[key] = out.get(key, 0) + k
    return content, out


def factor_rational(x: sp.Expr) -> sp.Expr | None:
    """sp.factor(x) for a rational function with rational coefficients in its symbols and sines and cosines (of any
    argument, opaque generators as in sympy): x = n / Π bᵏ over the ring of its generators (:func:`ring_fraction`,
    the bases of the denominators kept apart), n and each base b factored by :func:`fourier.factor_small`
    (factor_list_fast: gcds where linear in a generator), the irreducible factors common to the numerator and the
    denominator cancelled, in sympy's generator order; None for anything else."""
    from sympy.core.mul import _keep_coeff
    nb = ring_fraction(x, opaque_trig=True)
    if nb is None:
        return None
    n, bases = nb
    if not n:
        return sp.Integer(0)
    coeff, num = _factors(n)
    den: dict = {}
    for b, k in bases.items():
        cb, fb = _factors(b)
        coeff /= cb ** k
        for g, j in fb.items():
            den[g] = den.get(g, 0) + j * k
    for g in list(den):
        common = min(den[g], num.get(g, 0))
        if common:
            num[g] -= common
            den[g] -= common
    parts = [g ** k for g, k in num.items() if k] + [g ** -k for g, k in den.items() if k]
    return _keep_coeff(sp.QQ.to_sympy(coeff), sp.Mul(*parts))


def _nice(c: sp.Expr) -> sp.Expr:
    """A coefficient as a teacher writes it: factored when that is shorter, else expanded."""
    if c.is_number or c.is_Symbol or not c.is_Add:
        return c
    f = sp.factor_terms(c)
    if len(c.args) <= 12:  # full factorization only where it stays cheap: (q̇1 + q̇2)(2q̇1 + q̇2)
        g = factor_within(f)
        f = g if count_ops(g) < count_ops(f) else f
    return f if count_ops(f) < count_ops(c) else c


def _sum_denominator(expr: sp.Expr) -> bool:
    """Whether a denominator of ``expr`` is a sum (a rational function, not a polynomial over monomials): a sum to
    a negative power reached through sums, products and positive integer powers, the factors the denominator of
    together(expr) is made of (without building it)."""
    if expr.is_Add or expr.is_Mul:
        return any(_sum_denominator(a) for a in expr.args)
    if expr.is_Pow:
        if expr.exp.is_negative:
            return bool(expr.base.is_Add)
        return bool(expr.exp.is_Integer) and _sum_denominator(expr.base)
    return False


def _term_fraction(t: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """n/d = t with the common factors cancelled, as fraction(factor_within(t)) gives them up to the form of n (the
    caller factors the sums of numerators): d is factored (memoized), and each of its factors g divides n out as
    often as it goes, by exact division over the ring of t's symbols; n is not factored. Terms with a numeric d,
    with fractions inside n, or outside the rational functions over QQ: fraction(factor_within(t))."""
    from sympy.polys.rings import ring
    n, d = sp.fraction(t)
    if not d.free_symbols or not _over_QQ(t) or _sum_denominator(n):  # (fractions inside n: the whole term)
        return sp.fraction(factor_within(t))
    fd = factor_within(d)
    c, rest = fd.as_coeff_Mul()
    powers = [f.as_base_exp() for f in sp.Mul.make_args(rest)]
    bases = [f.as_base_exp()[0] for f in sp.Mul.make_args(n) if not f.is_Number]
    if all(b.is_Symbol or isinstance(b, (sp.sin, sp.cos)) for b in bases) and not any(
            g in bases for g, _ in powers):  # a monomial n: only a factor of its own could cancel
        return n, fd
    try:
        R = ring(tuple(_generators(t)), sp.QQ)[0]
        index = {x: i for i, x in enumerate(R.symbols)}
        N, left, cancelled = _polynomial(n, R, index), [], False
        for g, k in powers:
            G = _polynomial(g, R, index)
            N, j = divide_power(N, G, k) if not G.is_ground else (N, 0)
            left.append(g ** (k - j))
            cancelled = cancelled or j > 0
    except (sp.PolynomialError, TypeError, ValueError, ZeroDivisionError):
        return sp.fraction(factor_within(t))
    return (N.as_expr() / c, sp.Mul(*left)) if cancelled else (n, fd)


def _polynomial(e: sp.Expr, R, index: dict):  # type: ignore[no-untyped-def]
    """R(e) for a polynomial e over R's generators, read as :func:`_fraction` reads it (R(e) itself, with its
    errors, for anything else)."""
    try:
        n, dens = _fraction(e, R, index)
    except (_NotRational, ValueError, ZeroDivisionError):
        return R(e)
    return n if not dens else R(e)


def divide_power(p: Any, g: Any, k: int) -> tuple[Any, int]:
    """(p / g^j, j) for the largest j <= k with g^j dividing p: p and g polynomials of one ring over a field,
    divided with remainder until it is not zero."""
    j = 0
    while j < k:
        q, r = p.div(g)
        if r:
            break
        p, j = q, j + 1
    return p, j


def expand_polynomial(expr: sp.Expr) -> sp.Expr:
    """sp.expand(expr) for a polynomial in its symbols and sines and cosines; a rational function with sums in
    its denominators is returned as given (expanding distributes every numerator over the fractions: a longer
    form, and slow)."""
    return expr if _sum_denominator(expr) else sp.expand(expr)


def _rational(expr: sp.Expr) -> sp.Expr:
    """A rational function without angles, shortest of: one factored fraction, or the terms grouped by
    denominator up to a constant factor (m1 + m3/4 + Iy*(D - 2d)^2/((q1 - q2)^2 + (D - 2d)^2)^2 stays so)."""
    groups: dict[sp.Expr, list[sp.Expr]] = {}
    for t in sp.Add.make_args(sp.expand(expr, deep=False)):
        n, d = _term_fraction(t)
        c, base = d.as_content_primitive()
        if base.free_symbols:  # n/(4 X²), n'/(2 X²), n''/(2X)²: one group X², numerators n/4, n'/2 and n''/4
            n, d = n / c, base
        groups.setdefault(d, []).append(n)
    by_den = sp.Add(*[factor_within(sp.Add(*ns)) / d for d, ns in groups.items()])
    split = _by_parameters(groups)
    if split is not None and count_ops(split) < count_ops(by_den):
        by_den = split
    if len(groups) == 1 or count_ops(expr) > 150:   # one denominator already, or too big to combine cheaply
        return by_den
    whole = factor_within(expr if _over_QQ(expr) else sp.cancel(expr))  # (the fast path needs no cancel)
    return by_den if count_ops(by_den) <= count_ops(whole) else whole


def _shorter_split(x: sp.Expr) -> sp.Expr:
    """x = n/d, or its split by the parameters d does not have (:func:`_by_parameters`) when that is shorter."""
    n, d = sp.fraction(x)
    split = _by_parameters({d: [n]}) if d.free_symbols else None
    return split if split is not None and count_ops(split) < count_ops(x) else x


def _by_parameters(groups: dict[sp.Expr, list[sp.Expr]]) -> sp.Expr | None:
    """Σ_d N_d/d with each numerator split by the monomials μ of the symbols that d does not have, each part
    cancelled against d: Σ μ·(c_μ/d), for the denominators d that are sums, where some c_μ shares a factor with d.
    B₁₁ = (4D⁴m₁ + D⁴m₃ + 4D²I_y + ...)/(4((q₁ − q₂)² + (D − 2d)²)²) becomes m₁ + m₃/4 + I_y (D − 2d)²/((q₁ − q₂)² +
    (D − 2d)²)². None where nothing cancels (or past a size). In the ring of the symbols, each part divided by the
    factors of d by exact division (:func:`divide_power`)."""
    from sympy.polys.rings import ring
    if any(d.has(sp.Float) or any(x.has(sp.Float) for x in ns) for d, ns in groups.items()):
        return None  # (the ring over QQ would turn floats into fractions)
    out, split = [], False
    for d, ns in groups.items():
        n = sp.Add(*ns)
        other = sorted(n.free_symbols - d.free_symbols, key=lambda s: s.name)
        parts = None
        bases = [f.as_base_exp() for f in sp.Mul.make_args(d) if not f.is_Number]
        if other and count_ops(n) <= 600 and any(b.is_Add for b, _ in bases):
            try:
                gens = sorted(n.free_symbols | d.free_symbols, key=lambda s: s.name)
                R = ring(gens, sp.QQ)[0]
                parts = parts_by(R(n), [gens.index(x) for x in other])
                G = [(R(b), k) for b, k in bases]
            except (sp.PolynomialError, TypeError, ValueError, ZeroDivisionError):
                parts = None
        cut = []
        c0 = sp.Mul(*[f for f in sp.Mul.make_args(d) if f.is_Number])
        if parts and len(parts) > 1:
            for mu, c in parts.items():
                left = []
                for (b, k), (g, _) in zip(bases, G):
                    c, j = divide_power(c, g, k) if not g.is_ground else (c, 0)
                    left.append(b ** (k - j))
                cut.append((mu, c, c0 * sp.Mul(*left)))
        if not any(rest != d for _, _, rest in cut):  # (nothing cancelled)
            out.append(factor_within(n) / d)
            continue
        split = True
        for mu, c, rest in cut:
            mono = sp.Mul(*[x ** k for x, k in zip(other, mu)])
            out.append(mono * factor_within(c.as_expr() / rest))
    return sp.Add(*out) if split else None


def parts_by(p, idx: list[int]) -> dict:
    """A polynomial p of a ring as Σ_e c_e x^e over the generators of positions ``idx``: {e: c_e}, c_e free of them."""
    R = p.ring
    parts: dict[tuple, dict] = {}
    for monom, coeff in p.iterterms():
        rest = list(monom)
        for i in idx:
            rest[i] = 0
        parts.setdefault(tuple(monom[i] for i in idx), {})[tuple(rest)] = coeff
    return {e: R.from_dict(d) for e, d in parts.items()}


def tidy_expanded(expr: sp.Expr) -> sp.Expr:
    """tidy(sp.expand(expr)) without expanding: for a trigonometric polynomial (a product of large sums, a power
    of a determinant) the canonical Fourier form is computed from the tree by sparse ring arithmetic, which gives
    the same coefficients as from the expanded sum (the form is canonical); anything else is expanded and tidied.
    Memoized (the constrained reduction tidies the same products several times)."""
    return _tidy_expanded(sp.sympify(expr))


@lru_cache(maxsize=4096)
def _tidy_expanded(expr: sp.Expr) -> sp.Expr:
    form = _tree_form(expr)   # (also when a symbol or an angle cancels: see _tree_form)
    return fourier_expr(*form) if form is not None else tidy(sp.expand(expr))


@lru_cache(maxsize=1024)
def _tree_form(expr: sp.Expr) -> tuple[dict, list[sp.Symbol]] | None:
    """(Fourier coefficients, angles) of a trigonometric polynomial, computed from its tree; None for anything
    else. fourier_expr of them is tidy(sp.expand(expr)) also when a symbol or an angle cancels: the expanded sum
    has the same coefficients, and fourier_expr reads a generator or an angle that no coefficient uses (an
    exponent 0 in every monomial, a 0 in every k) nowhere: not in the order of the terms, the signs (_flip), the
    factors (factor_small drops it) or the product form (cos⁰ sin⁰ = 1). Memoized: the result is shared, not to
    be changed."""
    if not expr.free_symbols or expr.is_Atom:  # (floats: NotTrigPolynomial, sympy's rounded products then)
        return None
    angles = angle_symbols(expr)
    try:
        return fourier_coefficients(expr, angles), angles
    except NotTrigPolynomial:
        return None


@lru_cache(maxsize=1024)
def fourier_form(expr: sp.Expr) -> tuple[dict, list[sp.Symbol]] | None:
    """(Fourier coefficients, angles) of a trigonometric polynomial, computed from its tree (:func:`_tree_form`),
    when no angle or symbol cancels: its generators are then those of the expression. None for anything else.
    Memoized: the result is shared, not to be changed."""
    form = _tree_form(expr)
    if form is None:
        return None
    coeffs, angles = form
    used = [x for j, x in enumerate(angles) if any(k[j] for k in coeffs)]
    if len(used) < len(angles):  # angles that cancelled: the form over those left, as from the sum
        return None
    syms = sorted(expr.free_symbols, key=lambda x: x.name)  # fourier_coefficients' generators
    used_gens = {syms[i] for a, b in coeffs.values() for p in (a, b) for m in p.itermonoms()
                 for i, e in enumerate(m) if e}
    if coeffs and used_gens | set(angles) == expr.free_symbols:  # no symbol cancelled
        return coeffs, angles
    return None


def _transcendental_atoms(M: Any) -> list[sp.Expr]:
    """The sin/cos in M of a number other than a rational multiple of π (sin(3/10), cos(1))."""
    return [f for f in M.atoms(sp.sin, sp.cos) if f.args[0].is_number and not (f.args[0] / sp.pi).is_Rational]


def transcendental(M: Any) -> bool:
    """Whether M has a sin/cos of a number other than a rational multiple of π (no short closed form: the exact
    products of sin(3/10), cos(7/10), ... run to pages)."""
    return bool(_transcendental_atoms(M))


def evaluate_transcendental(expr: sp.Expr, digits: int = 15) -> sp.Expr:
    """``expr`` with each sin/cos of a number that is not a rational multiple of π evaluated to ``digits`` digits
    (other numbers, and the symbols, kept exact)."""
    rep = {f: sp.Float(sp.N(f, digits), digits) for f in _transcendental_atoms(expr)}
    return expr.xreplace(rep) if rep else expr


MAX_DENOMINATOR = 10**4   # a float that is p/q with a larger q prints as the float


@lru_cache(maxsize=20000)
def together(expr: sp.Expr) -> sp.Expr:
    """``sp.together(expr)`` (deep=False), step by step as sympy takes it (each sum's terms put together, then over
    a common denominator by gcd_terms), with each subexpression's result memoized: the entries of a law B a + n
    share the numerators of a, which sympy's together would take apart once per entry."""
    if expr.is_Atom or expr.is_Function:
        return expr
    if expr.is_Add:
        return sp.gcd_terms([together(a) for a in expr.args], fraction=True)
    if expr.is_Pow:
        return expr.func(together(expr.base), expr.exp)
    return expr.func(*[together(a) for a in expr.args])


def _small_rational(x: sp.Float) -> sp.Expr:
    """sp.nsimplify(x) when it is a rational p/q with q <= MAX_DENOMINATOR, else x (the general path of
    :func:`_tidy_float`)."""
    r = sp.nsimplify(x)
    return r if r.is_Rational and r.q <= MAX_DENOMINATOR else x


def _near(t: float, den: int, tol: float) -> bool:
    """Whether a non-zero rational with denominator <= den lies within tol of t (limit_denominator: the nearest)."""
    f = Fraction(t)
    r = f.limit_denominator(den)
    return r != 0 and abs(f - r) <= tol


def _no_rational_closed_form(x: sp.Float) -> bool:
    """True when nsimplify(x, rational=False), for a positive 15-digit float x in [10⁻⁶, 10⁶], cannot be a rational
    with q <= MAX_DENOMINATOR and, should mpmath's identify find nothing, x's decimal digits are not such a
    rational either; False when that is not excluded (the caller then searches).

    nsimplify calls identify(x, tol=1e-15) (maxcoeff M = 1000, no constants), which returns the first of: for
    t = x, 1/x, x², 1/x², √x, 1/√x (and e^{±x}, e^{1/x}, ±ln x, 1/ln x, whose closed forms are never rational
    but 1 = exp(0), when x is within 4·10⁻⁸ of 1) a PSLQ relation found with |relation| < tol·|vector|,
    coefficients <= M: r₀t + r₁ ≈ 0, so t is within 1.5·10⁻¹⁵·max(1, |t|) of −r₁/r₀ (denominator <= 1000, and
    |t| <= 1001); or a + bt + ct² ≈ 0 and t is near its root v: a rational v has denominator | c (<= 1000) and
    lies within 3.5·10⁻¹⁵·max(1, t²) of t when the roots differ (they are 1/c apart at least), within
    4.2·10⁻⁸·max(1, |t|) when v is a double root (then its denominator n has n² | c: n <= 31); an irrational
    v = ±√(−a/c) gives a rational x only through v² = −a/c (denominator <= 1000, x within 10⁻¹⁴ relative);
    last, x = 2^a 3^b 5^c 7^d within 10⁻¹³ relative. A rational with q <= 10⁴ from the decimal digits is within
    10⁻¹⁴ relative of x. Each window below is 10× these bounds (x's own at 10⁻¹² relative, denominators <= 10⁴),
    t computed in floats (1 ulp). For the floats a computation leaves (341.848933914192...) it holds almost always,
    and tidy keeps them without the search (25-50 ms each)."""
    if x._prec != 53:
        return False
    v = float(x)
    if not 1e-6 <= v <= 1e6:
        return False
    if _near(v, MAX_DENOMINATOR, v * 1e-12):
        return False
    for t in (v, 1 / v, v * v, 1 / (v * v), v ** 0.5, v ** -0.5):
        if t > 1002:   # no relation with coefficients <= 1000 has a root there
            continue
        if _near(t, 31, 4.2e-7 * max(1.0, t)) or _near(t, 2000, 3.5e-14 * max(1.0, t * t)):
            return False
    return True


@lru_cache(maxsize=20000)
def _tidy_float(x: sp.Float) -> sp.Expr:
    """:func:`_small_rational` of a float with one search for a closed form instead of two: nsimplify(x, rational=False)
    is the closed form mpmath's identify finds, or x when it finds none; only then does nsimplify(x) fall back to
    the rational of x's decimal digits, which has q <= MAX_DENOMINATOR only when x is within 10⁻¹² (relative) of
    such a rational (its 15 digits are), the one case passed to :func:`_small_rational`. identify(−x) is −identify(x)
    and the decimal fallback is odd too, so −x is tidied as x."""
    if not x.is_finite:
        return _small_rational(x)
    if x.is_negative:
        return -_tidy_float(-x)
    if _no_rational_closed_form(x):
        return x
    r = sp.nsimplify(x, rational=False)
    if not isinstance(r, sp.Float):   # a closed form (identify's string, sympified: exact)
        return r if r.is_Rational and r.q <= MAX_DENOMINATOR else x
    exact = Fraction(*sp.Rational(x).as_numer_denom())   # x's binary value
    if abs(exact - exact.limit_denominator(MAX_DENOMINATOR)) <= exact / 10**12:
        return _small_rational(x)
    return x


@lru_cache(maxsize=20000)
def tidy(expr: sp.Expr) -> sp.Expr:
    """Simplify ``expr`` to the compact form a teacher prints (canonical for trigonometric polynomials)."""
    expr = sp.sympify(expr)
    if expr.is_number:
        if expr.is_Float:   # 0.5 → 1/2, but 0.4926... stays a float (not 2^(31/111)·3^(73/111)·…/…)
            return _tidy_float(expr)
        return sp.simplify(expr)
    if not expr.free_symbols:
        return expr
    if expr.has(sp.Float) and not angle_symbols(expr) and expr.is_polynomial(*expr.free_symbols):
        return sp.expand(expr)  # numbers substituted: sympy's factoring of float coefficients is unbounded
    if not angle_symbols(expr) and _sum_denominator(expr):
        return _rational(expr)
    try:
        return _fourier(expr)
    except NotTrigPolynomial:
        pass
    num, den = sp.fraction(together(expr))
    if den != 1:
        try:
            n, d = _fourier(num), _fourier(den)
            if not angle_symbols(n / d):
                return _shorter_split(factor_within(n / d))
            return n / d
        except NotTrigPolynomial:
            pass
    radical = _tidy_radicals(expr)
    if radical is not None:
        return radical
    if _proved_zero(expr):  # sin(2 asin x) - 2x√(1 - x²): a small part of simplify's cost
        return sp.Integer(0)
    try:
        return sp.trigsimp(sp.simplify(expr))
    except BudgetExceeded:  # a caller's CPU budget ran out: let it know
        raise
    except Exception:  # pragma: no cover - sympy internals
        return expr


def _proved_zero(expr: sp.Expr) -> bool:
    """Whether :func:`_algebraic_zero` proves an expression outside the canonical forms (radicals, other
    functions) zero; False when it does not decide."""
    if _canonical_coefficients(expr):
        return False
    try:
        return bool(_algebraic_zero(expr))
    except BudgetExceeded:
        raise
    except Exception:  # pragma: no cover - sympy internals
        return False


def _tidy_radicals(expr: sp.Expr) -> sp.Expr | None:
    """An expression in sin/cos and radicals of them as one ratio: each radical X^(p/q) a symbol r^p, numerator and
    denominator tidied, then r = X^(1/q) put back with X as given or tidied, whichever is shorter:
    ∂‖a(q) − b‖/∂q = (a − b)ᵀ ∂a/∂q / ‖a − b‖ with its numerator in Fourier form and ‖a − b‖ the distance it is.
    None for other functions or nested radicals."""
    if not all(isinstance(f, _TRIG) for f in expr.atoms(sp.Function)):
        return None
    rads = [p for p in expr.atoms(sp.Pow) if p.base.free_symbols and p.exp.is_Rational and not p.exp.is_Integer]
    if not rads or any(o != p and p.base.has(o) for p in rads for o in rads):
        return None
    gens: dict[tuple[sp.Expr, int], sp.Dummy] = {}
    sub = {}
    for p in rads:
        r = gens.setdefault((p.base, int(p.exp.q)), sp.Dummy("r"))
        sub[p] = r ** int(p.exp.p)
    num, den = sp.fraction(sp.together(expr.xreplace(sub)))
    body = tidy(num) / tidy(den)
    back = {r: min((base, tidy(base)), key=count_ops) ** sp.Rational(1, q) for (base, q), r in gens.items()}
    return body.xreplace(back)


def tidy_matrix(m: sp.Matrix) -> sp.Matrix:
    """:func:`tidy` applied entry by entry."""
    return m.applyfunc(tidy)


def _canonical_coefficients(expr: sp.Expr) -> bool:
    """Whether the Fourier form of ``expr`` is canonical: no radicals of non-constant expressions and no functions
    other than sin/cos (sqrt(2)*sqrt(a^2 + b) vs a + ..., tanh vs sinh/cosh have several forms)."""
    if any(p.base.free_symbols and not p.exp.is_Integer for p in expr.atoms(sp.Pow)):
        return False
    return all(isinstance(f, (sp.sin, sp.cos)) for f in expr.atoms(sp.Function))


def _algebraic_zero(expr: sp.Expr) -> bool | None:
    """Exact zero test of an algebraic expression in sines, cosines and radicals.

    sin x, cos x of each angle become generators s, c (arguments k·x + b expanded); a radical (γ·A/B)^(p/q), with
    A, B primitive polynomials reduced modulo s² + c² = 1 (inner radicals already generators) and γ > 0 rational,
    becomes r^p·γ^(p/q): one generator r per distinct (A/B)^(1/q), however it was written, and γ^(p/q) in sympy's
    normal form (√8 = 2√2) with a generator ρ per root b^(1/m) left in it; any other function is opaque. The
    numerator N of the resulting rational function is divided by {B r^q − A, ρ^m − b, s² + c² − 1}: a remainder 0
    writes N as a combination of them, which proves expr ≡ 0 (with polynomial radicands their leading monomials
    are coprime in lex order r > s > c > the rest: a Gröbner basis, so 0 iff N is in the ideal).
    True: zero; False: undecided (|x| = √x², relations between roots of different orders are not used);
    None: not mapped (a radical of a function other than sin/cos)."""
    from sympy.polys.fields import field
    from sympy.polys.orderings import lex
    trig = {f: sp.expand_trig(f) for f in expr.atoms(sp.sin, sp.cos)}
    e = expr.xreplace(trig) if trig else expr
    angles = sorted({f.args[0] for f in e.atoms(sp.sin, sp.cos) if f.args[0].is_Symbol}, key=str)
    sc = {x: (sp.Dummy(f"s_{x}"), sp.Dummy(f"c_{x}")) for x in angles}
    e = e.xreplace({f: sc[f.args[0]][0 if isinstance(f, sp.sin) else 1]
                    for f in e.atoms(sp.sin, sp.cos) if f.args[0] in sc})
    rads = [p for p in e.atoms(sp.Pow) if p.exp.is_Rational and not p.exp.is_Integer]
    if any(p.base.atoms(sp.Function) for p in rads):
        return None
    opaque = {f: sp.Dummy("f") for f in e.atoms(sp.Function)}
    depth = {p: sum(1 for o in rads if o != p and p.base.has(o)) for p in rads}
    rads.sort(key=lambda p: depth[p])       # innermost first; they take the last (lowest) generators in lex order
    pool = [sp.Dummy("r") for _ in range(2 * len(rads))]
    trig_gens = [g for x in angles for g in sc[x]]
    syms = pool + trig_gens + sorted(e.xreplace(opaque).free_symbols - set(trig_gens), key=str)
    try:
        F = field(syms, sp.QQ, lex)[0]
        R = F.ring
        sub: dict[sp.Expr, sp.Expr] = {}
        keys: dict[tuple, sp.Dummy] = {}
        basis = []

        def generator(key: tuple, relation) -> sp.Dummy:  # type: ignore[no-untyped-def]
            if key not in keys:
                keys[key] = pool[len(pool) - 1 - len(keys)]
                basis.append(relation(R.gens[syms.index(keys[key])]))
            return keys[key]

        pythagoras = [R.gens[syms.index(s_)] ** 2 + R.gens[syms.index(c_)] ** 2 - 1 for s_, c_ in sc.values()]

        def normal(f):  # type: ignore[no-untyped-def]
            return f.rem(pythagoras) if pythagoras else f

        for p in rads:
            q, k = int(p.exp.q), int(p.exp.p)
            P = F.from_expr(p.base.xreplace(sub).xreplace(opaque))
            ca, A = normal(P.numer).primitive()
            cb, B = normal(P.denom).primitive()
            ratio = R.domain.to_sympy(ca) / R.domain.to_sympy(cb)
            c = abs(ratio)
            if ratio < 0:
                A = -A
            val = sp.Integer(1)
            if A != 1 or B != 1:
                val *= generator(("r", A, B, q), lambda g, A=A, B=B, q=q: B * g ** q - A) ** k
            n = c ** p.exp     # sympy's normal form of a rational's root: 4^(1/2) = 2, 8^(1/2) = 2·2^(1/2)
            sub[p] = val * n.xreplace({
                a: generator(("c", a.base, int(a.exp.q)), lambda g, b=a.base, m=int(a.exp.q): g ** m - R.from_expr(b))
                ** int(a.exp.p) for a in n.atoms(sp.Pow) if a.base.is_Rational and not a.exp.is_Integer})
        num = F.from_expr(e.xreplace(sub).xreplace(opaque)).numer
        basis = sorted(basis, key=lambda g: g.LM, reverse=True)
        basis += pythagoras
        return not (num.rem(basis) if basis else num)
    except (ValueError, sp.PolynomialError, TypeError, ZeroDivisionError):
        return None


def ring_fraction(expr: sp.Expr, opaque_trig: bool = False) -> tuple | None:
    """(n, {b: k}) with expr = n / Π bᵏ over the ring of its generators with rational coefficients
    (:func:`_fraction`: read from the tree, nothing multiplied out but n); None for anything that is not a rational
    function over QQ of its symbols and sines and cosines (of symbols; of any argument with ``opaque_trig``, each an
    independent generator: no trigonometric identity is used)."""
    from sympy.polys.rings import ring
    gens = _ring_generators(expr, opaque_trig)
    if gens is None:
        return None
    R = ring(tuple(gens), sp.QQ)[0]
    try:
        return _fraction(expr, R, {x: i for i, x in enumerate(gens)})
    except (_NotRational, ZeroDivisionError, sp.PolynomialError, TypeError, ValueError, RecursionError):
        return None


def _rational_zero(expr: sp.Expr) -> bool | None:
    """expr ≡ 0 for a rational function with rational coefficients: e = n / Π bᵏ (:func:`ring_fraction`) is zero
    iff n is; None for anything else."""
    if expr.is_Rational:
        return expr == 0
    nb = ring_fraction(expr)
    return None if nb is None else not nb[0]


def is_zero(expr: sp.Expr) -> bool | None:
    """Exact zero test for trigonometric polynomials; None when the canonical form does not decide (a non-zero
    form of an expression with radicals or other functions does not prove it non-zero)."""
    expr = sp.sympify(expr)
    canonical = _canonical_coefficients(expr)
    if canonical and not angle_symbols(expr):   # a rational function: exact and fast
        z = _rational_zero(expr)
        return z if z is not None else sp.cancel(expr) == 0
    if not canonical:   # radicals or other functions: True is a proof, anything else is not
        z0 = _algebraic_zero(expr)
        if z0 is not None:
            return True if z0 else None
    try:
        z = _fourier(expr) == 0
    except NotTrigPolynomial:
        num, _ = sp.fraction(sp.together(expr))
        try:
            z = _fourier(num) == 0
        except NotTrigPolynomial:
            return None
    return True if z else (False if canonical else None)


def zero_or_simplified(expr: sp.Expr) -> bool:
    """expr ≡ 0: :func:`is_zero` where it decides, else sympy's ``simplify(expr) == 0``."""
    if expr == 0:
        return True
    z = is_zero(expr)
    return bool(z) if z is not None else sp.simplify(expr) == 0


def group_expanded(expr: sp.Expr, v: list[sp.Symbol]) -> dict[sp.Expr, list[sp.Expr]]:
    """The terms of expand(expr) by their monomial in the symbols v: {m: [the rest of each term with m]}."""
    vs = set(v)
    groups: dict[sp.Expr, list[sp.Expr]] = {}
    for term in sp.Add.make_args(sp.expand(expr)):
        mono, rest = [], []
        for fac in sp.Mul.make_args(term):
            (mono if fac.as_base_exp()[0] in vs else rest).append(fac)
        groups.setdefault(sp.Mul(*mono), []).append(sp.Mul(*rest))
    return groups


def _by_monomial(e: sp.Expr, v: set[sp.Symbol]) -> dict[sp.Expr, list[sp.Expr]] | None:
    """e as Σ_m (Σ c) m over monomials m of the symbols v, read from its tree (sums, products, powers with natural
    exponents of v), the subtrees free of v not expanded: {m: [c, ...]}; None where v sits elsewhere (a
    denominator, a function)."""
    if not (e.free_symbols & v):
        return {sp.Integer(1): [e]}
    if e in v:
        return {e: [sp.Integer(1)]}
    if e.is_Add:
        out: dict[sp.Expr, list[sp.Expr]] = {}
        for a in e.args:
            part = _by_monomial(a, v)
            if part is None:
                return None
            for m, cs in part.items():
                out.setdefault(m, []).extend(cs)
        return out
    if e.is_Mul or (e.is_Pow and e.exp.is_Integer and e.exp > 0):
        factors = e.args if e.is_Mul else [e.base] * int(e.exp)
        acc: dict[sp.Expr, list[sp.Expr]] = {sp.Integer(1): [sp.Integer(1)]}
        for f in factors:
            part = _by_monomial(f, v)
            if part is None:
                return None
            nxt: dict[sp.Expr, list[sp.Expr]] = {}
            for m1, c1 in acc.items():
                for m2, c2 in part.items():
                    nxt.setdefault(m1 * m2, []).append(sp.Add(*c1) * sp.Add(*c2))
            acc = nxt
        return acc
    return None


def velocity_terms(expr: sp.Expr, v: list[sp.Symbol]) -> list[sp.Expr]:
    """``expr`` as terms coefficient·monomial of the velocities ``v``, highest degree first, each coefficient
    tidied: ‖v_c‖² -> [(l1² + q2²) q̇1², 2 l1 q̇1 q̇2, q̇2²]."""
    groups = _by_monomial(expr, set(v))
    if groups is None:
        groups = group_expanded(expr, v)

    def key(m: sp.Expr) -> tuple:
        degs = sp.Poly(m, *v).monoms()[0] if m != 1 else (0,) * len(v)
        return (-sum(degs), [-d for d in degs])

    out = [tidy(sp.Add(*groups[m])) * m for m in sorted(groups, key=key)]
    return [t for t in out if t != 0]


def rational_matrix(M: sp.Matrix):  # type: ignore[no-untyped-def]
    """``M`` as a DomainMatrix over the field of rational functions of its symbols with rational coefficients,
    where every entry is such a function, else None. Its det, rref and nullspace are exact and much faster than
    Matrix's with simplification; entries such as cos θ, sin θ or √a are refused (as independent generators,
    their relations would be missed: a rank too high, a determinant not simplified to 0)."""
    from sympy.polys.matrices import DomainMatrix
    try:
        dM = DomainMatrix.from_Matrix(M)
    except Exception:  # noqa: BLE001 - entries sympy's domains do not take
        return None
    K = dM.domain
    if K.is_ZZ or K.is_QQ or ((K.is_PolynomialRing or K.is_FractionField) and (K.dom.is_ZZ or K.dom.is_QQ)
                              and all(g.is_Symbol for g in K.symbols)):
        return dM.to_field()
    return None


def exact_det(M: sp.Matrix) -> sp.Expr:
    """det M: over the field of rational functions when the entries allow (:func:`rational_matrix`), else
    ``M.det()``."""
    dM = rational_matrix(M) if M.rows else None
    if dM is None:
        return M.det()
    return dM.domain.to_sympy(dM.det())


def matmul(A: sp.MatrixBase, B: sp.MatrixBase) -> sp.Matrix:
    """A·B with the entries sympy's product builds, Σ_k A_ik B_kj as one Add over the non-zero pairs in order of k,
    without its checks for infinities (0·B_kj and 0·A_ik for every entry), which query the assumptions of every
    entry: seconds on large rational entries that are then never asked again."""
    if A.cols != B.rows:
        raise sp.ShapeError(f"Matrix size mismatch: {A.shape} * {B.shape}")
    a = [[x for x in A.row(i)] for i in range(A.rows)]
    b = [[B[k, j] for k in range(B.rows)] for j in range(B.cols)]
    return sp.Matrix(A.rows, B.cols, [sp.Add(*[x * y for x, y in zip(row, col) if x and y]) for row in a for col in b])
