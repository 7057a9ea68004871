"""Exact arithmetic on trigonometric polynomials (the algebra behind :mod:`solver.simplify`).

A trigonometric polynomial in the angles x = (x_1..x_m) is written uniquely as

    f = Σ_k a_k cos(k·x) + b_k sin(k·x),   k ∈ Z^m with first non-zero entry > 0 (or k = 0, b_0 = 0),

with a_k, b_k polynomials (rational coefficients) in the remaining symbols. Products follow the
product-to-sum rules

    c_a c_b = ½(c_{a-b} + c_{a+b}),  s_a s_b = ½(c_{a-b} - c_{a+b}),  s_a c_b = ½(s_{a+b} + s_{a-b}),

so the canonical form of a sum of products is computed term by term on sparse polynomials (sympy's
``PolyElement``) without ever building the expanded expression. Offsets that are multiples of π/2 are
folded in (cos(x + π/2) = -sin x); anything else (other constants in arguments, tan, fractions, floats,
radicals) raises :class:`NotTrigPolynomial` and the caller falls back to a slower general method.
"""
from __future__ import annotations

from functools import cmp_to_key, lru_cache
from typing import Callable

import sympy as sp
from sympy.polys.domains import QQ, ZZ
from sympy.polys.rings import PolyElement, PolyRing

from solver.math import ringcode

ringcode.install()  # a ring's monomial arithmetic compiled once per user, not once per process
Key = tuple[tuple[int, ...], int]  # (k, 0 for cos | 1 for sin)
TrigPoly = dict[Key, PolyElement]


class NotTrigPolynomial(Exception):
    """The expression is not a polynomial in sin/cos of integer combinations of angles."""


@lru_cache(maxsize=256)
def _ring(gens: tuple[sp.Symbol, ...]) -> PolyRing:
    return PolyRing(gens, QQ)


def split_angle(arg: sp.Expr, index: dict[sp.Symbol, int]) -> tuple[list[int], int]:
    """arg = Σ k_j x_j + r·π/2 with integer k_j and r: returns (k, r), the x_j numbered by ``index``;
    NotTrigPolynomial for any other argument."""
    k = [0] * len(index)
    quarter = 0
    for term, coeff in arg.as_coefficients_dict().items():
        if term in index and coeff.is_Integer:
            k[index[term]] += int(coeff)
        elif term is sp.pi and (2 * coeff).is_Integer:
            quarter += int(2 * coeff)
        else:
            raise NotTrigPolynomial(arg)
    return k, quarter


def _canon(k: tuple[int, ...], kind: int) -> tuple[Key, int] | None:
    """Key with first non-zero entry of k positive, and the sign picked up (None: sin 0 = 0)."""
    first = next((v for v in k if v), 0)
    if first == 0:
        return (((0,) * len(k), 0), 1) if kind == 0 else None
    if first > 0:
        return (k, kind), 1
    return (tuple(-v for v in k), kind), (-1 if kind else 1)


def times(p: PolyElement, x) -> PolyElement:  # type: ignore[no-untyped-def]
    """p·x for a non-zero element x of p's coefficient domain (sympy's ``p * x`` converts x and goes through
    the generic product first)."""
    return p.new([(m, c * x) for m, c in p.items()])


class _Algebra:
    """Conversion of sympy expressions into :data:`TrigPoly` over one ring."""

    def __init__(self, angles: list[sp.Symbol], gens: list[sp.Symbol]):
        self.angles = angles
        self.index = {a: i for i, a in enumerate(angles)}
        self.R = _ring(tuple(gens))
        self.gen = dict(zip(gens, self.R.gens))
        self.zero_k = (0,) * len(angles)
        self.memo: dict[sp.Expr, TrigPoly] = {}

    def const(self, c: PolyElement) -> TrigPoly:
        return {(self.zero_k, 0): c} if c else {}

    def add_into(self, acc: TrigPoly, key: Key, c: PolyElement) -> None:
        v = acc.get(key)
        v = c if v is None else v + c
        if v:
            acc[key] = v
        else:
            acc.pop(key, None)

    def mul(self, A: TrigPoly, B: TrigPoly) -> TrigPoly:
        if len(A) > len(B):
            A, B = B, A
        out: TrigPoly = {}
        half = QQ(1, 2)
        halved = None  # ½ b_k of the non-constant harmonics of B, computed once (product-to-sum halves each)
        for (ka, ta), ca in A.items():
            if not any(ka):  # constant: scale
                for key, cb in B.items():
                    self.add_into(out, key, ca * cb)
                continue
            if halved is None:
                halved = {key: times(cb, half) for key, cb in B.items() if any(key[0])}
            for (kb, tb), cb in B.items():
                if not any(kb):
                    self.add_into(out, (ka, ta), ca * cb)
                    continue
                diff = tuple(a - b for a, b in zip(ka, kb))
                summ = tuple(a + b for a, b in zip(ka, kb))
                c = ca * halved[(kb, tb)]
                if ta == 0 and tb == 0:  # c_a c_b
                    terms = ((diff, 0, 1), (summ, 0, 1))
                elif ta == 1 and tb == 1:  # s_a s_b
                    terms = ((diff, 0, 1), (summ, 0, -1))
                elif ta == 1:  # s_a c_b
                    terms = ((summ, 1, 1), (diff, 1, 1))
                else:  # c_a s_b = ½(s_{a+b} - s_{a-b})
                    terms = ((summ, 1, 1), (diff, 1, -1))
                for k, kind, sign in terms:
                    canon = _canon(k, kind)
                    if canon is not None:
                        key, s = canon
                        self.add_into(out, key, c if s * sign > 0 else -c)
        return out

    def trig(self, f: sp.Expr) -> TrigPoly:
        return self.trig_of(f.args[0], 0 if isinstance(f, sp.cos) else 1)

    def trig_of(self, arg: sp.Expr, kind: int) -> TrigPoly:
        """cos(arg) (kind 0) or sin(arg) (kind 1), arg = Σ k_j x_j + r·π/2 (NotTrigPolynomial otherwise)."""
        if arg.is_zero:
            return self.const(self.R.one) if kind == 0 else {}
        k, quarter = split_angle(arg, self.index)  # offset quarter·π/2
        sign = 1
        # shift by quarter·π/2: cos -> -sin -> -cos -> sin; sin -> cos -> -sin -> -cos
        for _ in range(quarter % 4):
            if kind == 0:
                kind, sign = 1, -sign
            else:
                kind = 0
        canon = _canon(tuple(k), kind)
        if canon is None:
            return {}
        key, s = canon
        return {key: self.R.one if s * sign > 0 else -self.R.one}

    def conv(self, e: sp.Expr) -> TrigPoly:
        hit = self.memo.get(e)
        if hit is not None:
            return hit
        if e.is_Rational:
            out = self.const(self.R.ground_new(QQ(int(e.p), int(e.q))))
        elif e.is_Symbol:
            if e not in self.gen:
                raise NotTrigPolynomial(e)
            out = self.const(self.gen[e])
        elif e.is_Add:
            out = {}
            for a in e.args:
                for key, c in self.conv(a).items():
                    self.add_into(out, key, c)
        elif e.is_Mul:
            out = self.const(self.R.one)
            for a in e.args:
                out = self.mul(out, self.conv(a))
        elif e.is_Pow:
            base, ex = e.args
            if not (ex.is_Integer and ex >= 0):
                raise NotTrigPolynomial(e)
            b = self.conv(base)
            if len(b) == 1 and not any(next(iter(b))[0]):
                out = self.const(next(iter(b.values())) ** int(ex))
            else:
                out, n = self.const(self.R.one), int(ex)
                while n:
                    if n & 1:
                        out = self.mul(out, b)
                    n >>= 1
                    if n:
                        b = self.mul(b, b)
        elif isinstance(e, (sp.sin, sp.cos)):
            out = self.trig(e)
        else:
            raise NotTrigPolynomial(e)
        self.memo[e] = out
        return out


def ring_reader(R: PolyRing, leaf: Callable[[sp.Expr], PolyElement]) -> Callable[[sp.Expr], PolyElement]:
    """A reader of sympy expressions into the sparse ring ``R``, memoized on subexpressions: rationals, sums,
    products and natural powers read by structure, every other node (a symbol, sin/cos, ...) by ``leaf``, which
    raises (its own exception) for what it refuses; the reader lets that exception through."""
    memo: dict[sp.Expr, PolyElement] = {}

    def read(e: sp.Expr) -> PolyElement:
        hit = memo.get(e)
        if hit is not None:
            return hit
        if e.is_Rational:
            out = R.ground_new(QQ(int(e.p), int(e.q)))
        elif e.is_Add:
            out = R.zero
            for a in e.args:
                out += read(a)
        elif e.is_Mul:
            out = R.one
            for a in e.args:
                out *= read(a)
        elif e.is_Pow and e.exp.is_Integer and e.exp >= 0:
            out = read(e.base) ** int(e.exp)
        else:
            out = leaf(e)
        memo[e] = out
        return out
    return read


def _multiple_angle(n: int, C: PolyElement, S: PolyElement) -> tuple[PolyElement, PolyElement]:
    """(cos n x, sin n x) as sympy's expand_trig writes them, in the ring of C = cos x, S = sin x: cos n x = T_|n|(C);
    sin n x = (−1)^((n−1)/2) T_n(S) for odd n, (−1)^(n/2−1) C U_{n−1}(S) for even n, and −sin(|n| x) for n < 0."""
    a = abs(n)
    t0, t1 = C.ring.one, C  # T_0, T_1 of C
    for _ in range(a - 1):
        t0, t1 = t1, 2 * C * t1 - t0
    cos_n = t1 if a else C.ring.one
    if a == 0:
        return cos_n, C.ring.zero
    if a % 2:
        v0, v1 = C.ring.one, S  # T_0, T_1 of S
        for _ in range(a - 1):
            v0, v1 = v1, 2 * S * v1 - v0
        sin_n = (-1) ** ((a - 1) // 2) * v1
    else:
        u0, u1 = C.ring.one, 2 * S  # U_0, U_1 of S
        for _ in range(a - 2):
            u0, u1 = u1, 2 * S * u1 - u0
        sin_n = (-1) ** (a // 2 - 1) * C * u1
    return cos_n, (sin_n if n > 0 else -sin_n)


def ring_trig(arg: sp.Expr, cs: dict[sp.Symbol, tuple[PolyElement, PolyElement]]
              ) -> tuple[PolyElement, PolyElement]:
    """(cos arg, sin arg) of an integer combination arg = Σ n_j x_j as sympy's expand_trig writes them, in the ring
    where cs[x] = (cos x, sin x): the addition formulas over the terms, each n x by :func:`_multiple_angle`.
    ValueError for any other argument (a constant, a fraction, a symbol not in ``cs``)."""
    R = next(iter(cs.values()))[0].ring if cs else None
    if R is None:
        raise ValueError(arg)
    c, s = R.one, R.zero
    for term in sp.Add.make_args(arg):
        n, x = term.as_coeff_Mul()
        if not (n.is_Integer and x in cs):
            raise ValueError(arg)
        cn, sn = _multiple_angle(int(n), *cs[x])
        c, s = c * cn - s * sn, s * cn + c * sn
    return c, s


def fourier_coefficients(expr: sp.Expr, angles: list[sp.Symbol]) -> dict[tuple[int, ...], tuple[PolyElement, PolyElement]]:
    """{k: (a_k, b_k)} of ``expr`` as sparse polynomials, zero pairs omitted."""
    gens = sorted(expr.free_symbols, key=lambda s: s.name)
    alg = _Algebra(angles, gens)
    tp = alg.conv(expr)
    zero = alg.R.zero
    out: dict[tuple[int, ...], tuple[PolyElement, PolyElement]] = {}
    for (k, kind), c in tp.items():
        a, b = out.get(k, (zero, zero))
        out[k] = (c, b) if kind == 0 else (a, c)
    return out


def _cost(p: PolyElement) -> int:
    """Operation count of ``p`` as printed (as sympy's count_ops): one per +/-, product and power."""
    size = len(p) - 1
    for monom, coeff in p.iterterms():
        used = len(monom) - monom.count(0)  # generators in the term; those with a power: used − (exponents 1)
        factors = used + (abs(coeff) != 1)
        size += max(factors - 1, 0) + used - monom.count(1) + (coeff < 0)
    return size


def _product_cost(factors: list[tuple[PolyElement, int]]) -> int:
    """Operation count of Π f^e."""
    parts = [(f, e) for f, e in factors if f != 1 and f != -1]
    negate = any(f == -1 for f, _ in factors)
    return max(len(parts) - 1, 0) + sum(_cost(f) + (e > 1) for f, e in parts) + negate


_FACTORS: dict = {}  # factorizations already computed (the same coefficients recur in B, C_k, c, S, the model)


def factor_small(p: PolyElement) -> tuple[PolyElement, list[tuple[PolyElement, int]]]:
    """Factorization (content over QQ, [(f, e)]) of ``p``, in its ring over QQ; memoized. Sympy's dense
    factorization, where it is needed, runs in the ring of only the generators the polynomial uses (it recurses
    over every generator; a ring per subset of the generators would cost more than the rest: sympy compiles the
    monomial arithmetic of every new ring)."""
    if p.ring.domain != QQ:
        p = p.set_ring(_ring(p.ring.symbols))
    hit = _FACTORS.get(p)
    if hit is None:
        if len(_FACTORS) > 20000:
            _FACTORS.clear()
        hit = factor_list_fast(p)
        check = p.ring.ground_new(hit[0])
        for f, e in hit[1]:
            check *= f**e
        if check != p:  # cannot happen (the factors are exact); sympy's factorization if it ever did
            hit = _dense_factor_list(p)
        _FACTORS[p] = hit
    content, factors = hit
    return content, list(factors)  # a new list: the caller changes signs in place


def _degrees(p: PolyElement) -> tuple[int, ...]:
    """The degree of ``p`` (non-zero) in each generator, in one pass over its monomials (``p.degree(x)`` makes
    one per generator)."""
    return tuple(map(max, zip(*p.itermonoms())))


def _monomial_part(p: PolyElement) -> tuple[tuple[int, ...], PolyElement]:
    """(m, p / x^m) for the largest monomial x^m dividing ``p`` (non-zero): its exponents, the least of each
    generator's over the terms, and the quotient (by the ring's compiled monomial division)."""
    mono = tuple(map(min, zip(*p.itermonoms())))
    if not any(mono):
        return mono, p
    ldiv = p.ring.monomial_ldiv
    return mono, p.ring.dtype([(ldiv(m, mono), c) for m, c in p.iterterms()])


def _dense_factor_list(p: PolyElement, of: PolyElement | None = None) -> tuple:
    """``p.factor_list()`` computed in the ring of the generators that ``of`` (default ``p``) uses, the factors
    brought back (sympy orders the factors differently in rings with other generators)."""
    R = p.ring
    used = [i for i, d in enumerate(_degrees(p if of is None else of)) if d > 0]
    if len(used) == R.ngens:
        return p.factor_list()
    c, fl = p.set_ring(PolyRing(tuple(R.symbols[i] for i in used), R.domain)).factor_list()
    return c, [(f.set_ring(R), e) for f, e in fl]


def factor_list_fast(p: PolyElement) -> tuple:
    """``p.factor_list()`` (content, [(f, e)], each f primitive with a positive leading coefficient), computed
    by gcds wherever ``p`` is linear in a generator x: p = a x + b = g · (p/g) with g = gcd(a, b), and p/g,
    primitive and of degree 1 in x, is irreducible; g is factored the same way. The coefficients of a dynamic
    model are mostly linear in a mass or an inertia, and a gcd costs far less than Wang's factorization, which
    is used only for the parts of degree ≥ 2 in every generator."""
    R = p.ring
    if p.is_ground:
        return p.LC if p else R.domain.zero, []
    if R.domain != ZZ:  # over QQ: the factors of the integer polynomial d p, content / d
        den, pz = p.clear_denoms()
        c, fl = factor_list_fast(pz.set_ring(R.clone(domain=ZZ)))
        return R.domain.convert(c) / R.domain.convert(den), [(f.set_ring(R), e) for f, e in fl]
    content, prim = p.primitive()
    if prim.LC < 0:
        content, prim = -content, -prim
    factors: list[tuple[PolyElement, int]] = []
    mono, prim = _monomial_part(prim)
    factors.extend((R.gens[i], e) for i, e in enumerate(mono) if e)
    known: list[tuple[PolyElement, int]] | None = None  # the factors of prim, once known
    while not prim.is_ground:
        i = next((j for j, d in enumerate(_degrees(prim)) if d == 1), None)
        if i is None and irreducible(prim):
            factors.append((prim, 1))
            break
        root = _linear_root(prim) if i is None else None
        if root is not None:
            factors.append(root)
            break
        if i is None:
            c, rest = _dense_factor_list(prim, p)  # (in the ring of p's generators, as sympy's own order)
            factors.extend(rest)
            content *= c
            break
        # prim = a x_i + b: its one factor in x_i is h = prim / gcd(a, b), the others are those of gcd(a, b)
        if known is None:
            a = R.from_dict({m[:i] + (0,) + m[i + 1:]: c for m, c in prim.iterterms() if m[i] == 1})
            b = R.from_dict({m: c for m, c in prim.iterterms() if m[i] == 0})
            known = _common_factors(a, b)
            g = R.one
            for f, e in known:
                g *= f**e
            h = prim.exquo(g)
        else:
            h = next(f for f, _ in known if f.degree(i))
            known = [(f, e) for f, e in known if f is not h]
            g = prim.exquo(h)
        factors.append((h, 1))
        prim = g
    return content, factors


def _common_factors(a: PolyElement, b: PolyElement) -> list[tuple[PolyElement, int]]:
    """The irreducible factors of gcd(a, b) (primitive, positive leading coefficients; a, b ≠ 0 without a common
    integer content): those of the shorter one that divide the other, as often as they do. Costs a factorization
    of a smaller polynomial and a few exact divisions, where a multivariate gcd (heuristic, by evaluation and
    interpolation in every generator of the ring) costs far more."""
    if len(b) < len(a):
        a, b = b, a
    out = []
    for f, e in factor_list_fast(a)[1]:
        k = 0
        while k < e and _divides(f, b):
            b = b.exquo(f)
            k += 1
        if k:
            out.append((f, k))
    return out


def _divides(f: PolyElement, b: PolyElement) -> bool:
    """Whether f divides b exactly (one divisor: the remainder of the division is 0 exactly when it does)."""
    if len(f) == 1:  # a monomial: every term of b has its powers
        (m, _), = f.iterterms()
        return all(all(x >= y for x, y in zip(t, m)) for t in b.itermonoms())
    if not b or any(x > y for x, y in zip(_degrees(f), _degrees(b))):
        return False
    return not b.rem(f)


def _linear_root(p: PolyElement) -> tuple[PolyElement, int] | None:
    """(f, d) with p = f^d, f = αx + β linear in the generator x of least degree d ≥ 2 and α an integer, when p
    (primitive, positive leading coefficient) is such a power, as the squares (q̇₁ + q̇₂)² of a Coriolis term are:
    the coefficients of x^d and x^(d−1) give α = (p_d)^(1/d) and β = p_(d−1) / (d α^(d−1)), and f^d = p is
    checked. f is then primitive, hence irreducible; None otherwise (the general factorization decides)."""
    R = p.ring
    d, i = min((d, j) for j, d in enumerate(_degrees(p)) if d >= 1)
    if d < 2:
        return None
    top = [(m, c) for m, c in p.iterterms() if m[i] == d]
    if len(top) != 1 or any(top[0][0][:i] + top[0][0][i + 1:]):
        return None
    alpha, exact = sp.integer_nthroot(abs(int(top[0][1])), d)
    if not exact or (top[0][1] < 0 and d % 2 == 0):
        return None
    if top[0][1] < 0:
        alpha = -alpha
    den = d * alpha ** (d - 1)
    beta = {}
    for m, c in p.iterterms():
        if m[i] == d - 1:
            if c % den:
                return None
            beta[m[:i] + (0,) + m[i + 1:]] = c // den
    f = R.from_dict(beta) + R.gens[i] * alpha
    if f.LC < 0:
        f = -f
    return (f, d) if f**d == p else None


def irreducible(p: PolyElement, tries: int = 2) -> bool:
    """A sufficient test (True proves it, False decides nothing) that ``p`` over ZZ, primitive, is irreducible:
    for the generator x of least degree d ≥ 1, if the coefficients of p in x have no common factor and
    p(x, a₂, ..., aₙ) at integers a (leading coefficient ≠ 0 there) is irreducible of degree d over Q, then p is:
    every factor of p has positive degree in x, so p = f g would give p(x, a) = f(x, a) g(x, a) (Hilbert). Costs
    a few sparse gcds and one univariate factorization, where Wang's multivariate algorithm costs far more."""
    from sympy.polys.factortools import dup_factor_list
    R = p.ring
    if p.is_ground or R.ngens < 2:
        return False
    degs = [(d, j) for j, d in enumerate(_degrees(p)) if d >= 1]
    d, i = min(degs)
    coeffs: dict[int, dict] = {}
    for m, c in p.iterterms():
        coeffs.setdefault(m[i], {})[m[:i] + (0,) + m[i + 1:]] = c
    content = None
    for part in sorted(coeffs.values(), key=len):
        g = R.from_dict(part)
        content = g if content is None else content.gcd(g)
        if content.is_ground:
            break
    if content is None or not content.is_ground:
        return False
    for t in range(tries):
        point = [0 if j == i else 2 + (7 * j + 13 * t * t + 5 * t) % 29 for j in range(R.ngens)]
        uni = [ZZ(0)] * (d + 1)
        for m, c in p.iterterms():
            v = c
            for j, e in enumerate(m):
                if e and j != i:
                    v *= point[j] ** e
            uni[d - m[i]] += v
        if uni[0] == 0:
            continue
        _, fl = dup_factor_list(uni, ZZ)
        if len(fl) == 1 and fl[0][1] == 1 and len(fl[0][0]) == d + 1:
            return True
    return False


def _flip(f: PolyElement) -> bool:
    """Whether -f reads better than f: every term negative, or as many negative as positive terms and the
    simplest term (lowest degree, then the latest generator by name: coordinates after parameters) negative:
    q̇₂ - ℓ₁ q̇₃ and q₃ - d_c3 rather than their opposites."""
    signs = [c < 0 for c in f.itercoeffs()]
    if all(signs):
        return True
    if 2 * sum(signs) != len(signs):
        return False
    lead = min(f.itermonoms(), key=lambda m: (sum(m), tuple(-x for x in m[::-1])))
    return f[lead] < 0


_PREFIX_SORT = cmp_to_key(sp.Basic.compare)  # sympy's canonical order of the arguments of a sum or product


def mul_distinct(coeff: sp.Expr, factors: list[sp.Expr]) -> sp.Expr:
    """``coeff · Π factors`` as sympy's ``Mul`` writes it, built without its flattening: the coefficient first
    (unless 1), then the factors in sympy's argument order, products among them opened (their coefficients taken
    into ``coeff``). For a rational ``coeff`` and canonical commutative factors with pairwise distinct bases, none
    a power of a number (sympy merges √2·√3): what ``Mul`` gives, except that a coefficient times a single sum
    stays a product, as ``Mul(2, x + y, evaluate=False)`` (``Mul`` would distribute it)."""
    flat: list[sp.Expr] = []
    for f in factors:
        if f.is_Mul:
            args = f.args
            if args[0].is_Number:
                coeff *= args[0]
                args = args[1:]
            flat.extend(args)
        elif f.is_Number:
            coeff *= f
        else:
            flat.append(f)
    if coeff.is_zero:
        return sp.S.Zero
    if not flat:
        return coeff
    flat.sort(key=_PREFIX_SORT)
    if coeff is sp.S.One:
        return flat[0] if len(flat) == 1 else sp.Mul._from_args(flat, True)
    return sp.Mul._from_args([coeff] + flat, True)


def add_distinct(terms: list[sp.Expr]) -> sp.Expr:
    """``Add(*terms)`` as sympy writes it, built without its flattening, for canonical commutative terms of
    which no two differ only in their numerical coefficient (monomials of one polynomial, terms of distinct
    harmonics): sums among them opened, numbers added into the constant, which comes first, the rest in
    sympy's argument order. A single term is returned as it is (as ``Add`` does)."""
    if len(terms) == 1:
        return terms[0]
    const: sp.Expr = sp.S.Zero
    flat: list[sp.Expr] = []
    for t in terms:
        if t.is_Add:
            for a in t.args:
                if a.is_Number:
                    const += a
                else:
                    flat.append(a)
        elif t.is_Number:
            const += t
        else:
            flat.append(t)
    if not flat:
        return const
    flat.sort(key=_PREFIX_SORT)
    if const is not sp.S.Zero:
        flat.insert(0, const)
    return flat[0] if len(flat) == 1 else sp.Add._from_args(flat, True)


_POWERS: dict[tuple[sp.Symbol, int], sp.Expr] = {}


def _power(g: sp.Symbol, m: int) -> sp.Expr:
    """g**m of a generator (memoized: the same powers recur in every coefficient)."""
    hit = _POWERS.get((g, m))
    if hit is None:
        if len(_POWERS) > 10000:
            _POWERS.clear()
        hit = _POWERS[(g, m)] = g ** m
    return hit


_EXPRS: dict = {}  # polynomial -> its tree: equal factors of different coefficients become one object, which the
# printers' memos then find by identity (equal but distinct trees are compared node by node at every hit)


def poly_expr(p: PolyElement) -> sp.Expr:
    """``p.as_expr()``, the same tree built without sympy's flattening: a polynomial's terms are distinct
    monomials, so each product is its coefficient (first, unless 1) and its powers in sympy's argument order, and
    the sum its constant (first) and its terms in that order, as ``Mul.flatten`` and ``Add.flatten`` leave them.
    Memoized."""
    hit = _EXPRS.get(p)
    if hit is None:
        if len(_EXPRS) > 50000:
            _EXPRS.clear()
        hit = _EXPRS[p] = _poly_expr(p)
    return hit


def _poly_expr(p: PolyElement) -> sp.Expr:
    gens = p.ring.symbols
    to_sympy = p.ring.domain.to_sympy
    terms, const = [], None
    for monom, coeff in p.iterterms():
        c = to_sympy(coeff)
        factors = [g if m == 1 else _power(g, m) for g, m in zip(gens, monom) if m]
        if not factors:
            const = c
            continue
        factors.sort(key=_PREFIX_SORT)
        if c is sp.S.One:
            terms.append(factors[0] if len(factors) == 1 else sp.Mul._from_args(factors))
        else:
            terms.append(sp.Mul._from_args([c] + factors))
    if not terms:
        return const if const is not None else sp.S.Zero
    if len(terms) == 1 and const is None:
        return terms[0]
    terms.sort(key=_PREFIX_SORT)
    return sp.Add._from_args(([const] if const is not None else []) + terms)


_NICE: dict = {}  # printed forms already computed (the same coefficients recur across a model's entries)


def nice_poly(p: PolyElement, max_terms: int = 12) -> sp.Expr:
    """:func:`_nice_poly`, memoized."""
    key = (p, max_terms)
    hit = _NICE.get(key)
    if hit is None:
        if len(_NICE) > 50000:
            _NICE.clear()
        hit = _NICE[key] = _nice_poly(p, max_terms)
    return hit


def _nice_poly(p: PolyElement, max_terms: int = 12) -> sp.Expr:
    """``p`` as a teacher writes it: content and monomial factor pulled out, and fully factored when that is
    shorter and ``p`` has at most ``max_terms`` terms: 2 m₂ l₁ d₂ q̇₁ q̇₂ + m₂ l₁ d₂ q̇₂² -> m₂ l₁ d₂ q̇₂ (2 q̇₁ + q̇₂).
    A minus sign is pulled out only when every term is negative."""
    if len(p) <= 1:
        return poly_expr(p)
    R = p.ring
    content, prim = p.primitive()
    if content < 0:
        content, prim = -content, -prim
    if _flip(prim):
        content, prim = -content, -prim
    mono, prim = _monomial_part(prim)
    lead = R.from_dict({mono: content})
    best = [(lead, 1), (prim, 1)]
    p_cost = _cost(p) + (content < 0)  # an extracted minus sign is free: -g₀(q₂ - d₁) vs g₀ d₁ - g₀ q₂
    if 2 < len(prim) <= max_terms:
        c, factors = factor_small(prim)
        if len(factors) > 1 or any(e > 1 for _, e in factors):
            sign = 1
            for i, (f, e) in enumerate(factors):
                if _flip(f):
                    factors[i] = (-f, e)
                    sign *= (-1) ** e
            cand = [(lead * R.ground_new(c * sign), 1)] + factors
            if _product_cost(cand) < _product_cost(best):
                best = cand
    if _product_cost(best) >= p_cost:
        return poly_expr(p)
    number, rest = sp.S.One, []
    for f, e in best:
        x = poly_expr(f)
        if f.is_ground:
            number *= x ** e
        else:
            rest.append(x if e == 1 else x ** e)
    return mul_distinct(number, rest)  # (2*(q3 - d) and -(a + b) stay factored: Mul(2, x + y) would distribute)


@lru_cache(maxsize=16)
def _trig_ring(m: int) -> PolyRing:
    """Q[c_1..c_m, s_1..s_m]: the monomials of a product form (its symbols never leave this module)."""
    return _ring(tuple([sp.Dummy(f"c{i}") for i in range(m)] + [sp.Dummy(f"s{i}") for i in range(m)]))


@lru_cache(maxsize=4096)
def _cos_sin(k: tuple[int, ...]) -> tuple[PolyElement, PolyElement]:
    """(cos(k·x), sin(k·x)) in _trig_ring(len(k)): Chebyshev for each multiple angle, cos(n x) = T_n(c),
    sin(n x) = s U_{n-1}(c), then the addition formulas over the angles."""
    Rt = _trig_ring(len(k))
    m = len(k)
    C, S = Rt.gens[:m], Rt.gens[m:]
    i = next((j for j, v in enumerate(k) if v), None)
    if i is None:
        return Rt.one, Rt.zero
    n = k[i]
    t0, t1, u0, u1 = Rt.one, C[i], Rt.zero, Rt.one  # T_0, T_1, U_{-1}, U_0
    for _ in range(abs(n) - 1):
        t0, t1 = t1, 2 * C[i] * t1 - t0
        u0, u1 = u1, 2 * C[i] * u1 - u0
    ca, sa = t1, (S[i] * u1 if n >= 0 else -S[i] * u1)
    cb, sb = _cos_sin(tuple(0 if j == i else v for j, v in enumerate(k)))
    return ca * cb - sa * sb, sa * cb + ca * sb


def product_groups(coeffs: dict[tuple[int, ...], tuple[PolyElement, PolyElement]],
                   angles: list[sp.Symbol]) -> dict[tuple[int, ...], PolyElement]:
    """The same function over monomials in cos/sin of single angles: {exponents of (c₁..c_m, s₁..s_m): its
    coefficient}; multiple angles by Chebyshev: cos(n x) = T_n(c), sin(n x) = s U_{n-1}(c)."""
    R = next(iter(coeffs.values()))[0].ring
    Rt = _trig_ring(len(angles))  # the trigonometric monomials alone; coefficients stay in R
    groups: dict[tuple[int, ...], PolyElement] = {}
    for k, (a, b) in coeffs.items():
        ck, sk = _cos_sin(k)
        for coeff, trig_poly in ((a, ck), (b, sk)):
            if not coeff:
                continue
            for mono, c in trig_poly.iterterms():
                acc = groups.get(mono)
                term = coeff * R.domain.convert(c, Rt.domain)
                groups[mono] = term if acc is None else acc + term
    return {k: g for k, g in groups.items() if g}


def product_cost_bound(groups: dict[tuple[int, ...], PolyElement]) -> int:
    """A lower bound of count_ops of the product form of ``groups``, without printing it: one +/- between terms,
    and per term c·Π fᵉ (f = cos/sin of one angle) the count of Π fᵉ (one per sin/cos, per power, per product)
    plus, whatever form the coefficient c takes, one for c other than ±1 (a product, a quotient or a minus sign)
    and at least one per symbol of c (its leaves joined by one +, * or ^ each, and joined to Π fᵉ: k leaves, k
    operations); nothing for the constant term (−(a + b) counts a single operation)."""
    bound = len(groups) - 1
    for key, g in groups.items():
        factors = sum(1 for e in key if e)
        if factors:  # (the constant term may count nothing: 3)
            used = sum(1 for d in g.degrees() if d > 0)
            bound += 2 * factors - 1 + sum(1 for e in key if e > 1) + max(used, not (g.is_ground and abs(g.LC) == 1))
    return bound


def product_form(coeffs: dict[tuple[int, ...], tuple[PolyElement, PolyElement]], angles: list[sp.Symbol],
                 groups: dict[tuple[int, ...], PolyElement] | None = None) -> sp.Expr:
    """The same function written over monomials in cos/sin of single angles (c₂ s₂, c₁ c₂ s₃, ...), each
    coefficient through :func:`nice_poly` (``groups``: :func:`product_groups`, when already computed)."""
    if groups is None:
        groups = product_groups(coeffs, angles)
    evaluate = [type(x) is not sp.Symbol for x in angles]  # (cos x of a symbol: nothing to evaluate, the same object)
    trig = [f(x, evaluate=e) for f in (sp.cos, sp.sin) for x, e in zip(angles, evaluate)]
    terms = [mul_distinct(sp.S.One, [nice_poly(g)] + [f if e == 1 else f ** e for f, e in zip(trig, key) if e])
             for key, g in groups.items()]  # (distinct monomials in cos/sin times polynomials: nothing merges)
    return add_distinct(terms) if terms else sp.S.Zero


def factor_list_expr(expr: sp.Expr) -> tuple[sp.Expr, list[tuple[sp.Expr, int]]]:
    """``sp.factor_list(expr)`` of a polynomial expression with integer or rational coefficients, through
    :func:`factor_list_fast` (gcds where linear in a generator) in the ring of its generators, ordered as sympy
    orders them; sympy's own factorization for any other coefficient domain."""
    from sympy.polys.rings import sring
    try:
        R, p = sring(expr)
    except (sp.PolynomialError, sp.polys.polyerrors.GeneratorsNeeded, ValueError, TypeError):
        return sp.factor_list(expr)
    if (R.domain != ZZ and R.domain != QQ) or any(g.is_number for g in R.symbols):  # sqrt(2), pi: sympy's way
        return sp.factor_list(expr)
    c, fl = factor_small(p)
    return QQ.to_sympy(QQ.convert(c)), [(f.as_expr(), e) for f, e in fl]
