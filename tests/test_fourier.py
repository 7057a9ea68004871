"""Trigonometric-polynomial algebra: canonical forms agree with the original functions, zero tests are exact."""
from __future__ import annotations

import random

import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from sympy.polys.domains import QQ as QQ_
from sympy.polys.domains import ZZ as ZZ_

from solver.math.fourier import NotTrigPolynomial, fourier_coefficients, nice_poly, product_form
from solver.math.simplify import is_zero, tidy

q1, q2, q3, a, b = sp.symbols("q1 q2 q3 a b", real=True)
ANGLES = [q1, q2, q3]


def rebuild(coeffs, angles):  # type: ignore[no-untyped-def]
    return sum((ak.as_expr() * sp.cos(sum(k * x for k, x in zip(kk, angles)))
                + bk.as_expr() * sp.sin(sum(k * x for k, x in zip(kk, angles)))
                for kk, (ak, bk) in coeffs.items()), sp.Integer(0))


def same_function(f, g, trials: int = 4) -> bool:  # type: ignore[no-untyped-def]
    rng = random.Random(1)
    for _ in range(trials):
        point = {s: sp.Rational(rng.randint(-300, 300), 97) for s in f.free_symbols | g.free_symbols}
        if abs(sp.N((f - g).subs(point), 30)) > 1e-20:
            return False
    return True


atoms = st.sampled_from([a, b, q2, sp.Integer(2), sp.Rational(1, 2), sp.cos(q1), sp.sin(q2), sp.cos(q1 + q2),
                         sp.sin(q1 - 2 * q3), sp.cos(q2 + sp.pi / 2), sp.sin(q3 - sp.pi)])
exprs = st.recursive(atoms, lambda inner: st.one_of(
    st.builds(lambda x, y: x + y, inner, inner), st.builds(lambda x, y: x * y, inner, inner),
    st.builds(lambda x: x ** 2, inner)), max_leaves=8)


@settings(max_examples=60, deadline=None)
@given(exprs)
def test_canonical_form_is_the_same_function(e: sp.Expr) -> None:
    coeffs = fourier_coefficients(e, ANGLES)
    assert same_function(rebuild(coeffs, ANGLES), e)
    assert same_function(tidy(e), e)


def test_product_to_sum_identities_are_exact() -> None:
    assert fourier_coefficients(sp.sin(q1) ** 2 + sp.cos(q1) ** 2 - 1, ANGLES) == {}
    assert is_zero(sp.cos(q1 + q2) - sp.cos(q1) * sp.cos(q2) + sp.sin(q1) * sp.sin(q2))
    assert is_zero(sp.sin(2 * q2) - 2 * sp.sin(q2) * sp.cos(q2))
    assert is_zero(sp.cos(q2 + sp.pi / 2) + sp.sin(q2))
    assert not is_zero(sp.cos(q2) ** 2 - sp.cos(2 * q2))
    c = fourier_coefficients(a * sp.cos(q1) ** 2, ANGLES)  # a c1² = a/2 + a/2 cos 2q1
    assert {k: (x.as_expr(), y.as_expr()) for k, (x, y) in c.items()} == {(0, 0, 0): (a / 2, 0), (2, 0, 0): (a / 2, 0)}


def test_algebraic_zero_test_uses_the_radical_relations() -> None:
    """Radicals r = P^(1/q) as generators reduced modulo r^q − P: True only for an exact zero, None otherwise."""
    x, y = sp.symbols("x y")
    s = sp.sqrt(x ** 2 + y)
    assert is_zero(s ** 3 / (x ** 2 + y) - s) is True
    assert is_zero(1 / (1 + sp.sqrt(x)) - (1 - sp.sqrt(x)) / (1 - x)) is True
    assert is_zero(x ** sp.Rational(1, 3) * x ** sp.Rational(1, 2) - x ** sp.Rational(5, 6)) is True
    assert is_zero(s / (x + s) - (s * x - s ** 2) / (x ** 2 - s ** 2)) is True
    assert is_zero(1 / (1 + sp.sqrt(x)) - (1 + sp.sqrt(x)) / (1 - x)) is None   # not zero: undecided, never True
    assert is_zero(sp.sqrt(x) * sp.sqrt(y) - sp.sqrt(x * y)) is None           # false for x, y < 0
    assert is_zero(sp.sqrt(4 * x ** 2 + 8 * y) - 2 * sp.sqrt(x ** 2 + 2 * y)) is True   # radicands up to a content
    assert is_zero(sp.sqrt(8 * x) - 2 * sp.sqrt(2) * sp.sqrt(x)) is True
    assert is_zero(sp.sqrt(-2 * x) - sp.sqrt(2) * sp.sqrt(x)) is None
    assert is_zero(sp.sqrt(x + sp.sqrt(2) * y) ** 3 - (x + sp.sqrt(2) * y) * sp.sqrt(x + sp.sqrt(2) * y)) is True


def test_algebraic_zero_test_with_angles() -> None:
    """sin, cos of each angle as generators with s² + c² = 1, radicals of trigonometric polynomials as generators:
    the derivative of a distance √(x(q)² + y(q)²) in two written forms, a phase-shifted sinusoid."""
    l1, d = sp.symbols("l1 d", positive=True)
    x = l1 * sp.cos(q1) + q2 * sp.sin(q1) - d
    y = l1 * sp.sin(q1) - q2 * sp.cos(q1)
    r = sp.sqrt(x ** 2 + y ** 2)
    grad = sp.diff(r, q1)
    other = (d * l1 * sp.sin(q1) - d * q2 * sp.cos(q1)) / sp.sqrt(sp.expand(x ** 2 + y ** 2))
    assert is_zero(grad - other) is True
    assert is_zero(grad - 2 * other) is None
    assert is_zero(sp.sqrt(2) * sp.cos(q1 + sp.pi / 4) - sp.cos(q1) + sp.sin(q1)) is True
    assert is_zero(sp.sqrt(sp.sin(q1) ** 2 + sp.cos(q1) ** 2 + a) - sp.sqrt(1 + a)) is True
    assert is_zero(sp.sqrt(1 - sp.sin(q1) ** 2) - sp.cos(q1)) is None          # |cos q1|: undecided, never True
    assert is_zero(sp.exp(a) * sp.sin(2 * q1) - 2 * sp.exp(a) * sp.sin(q1) * sp.cos(q1)) is True


def test_other_functions_are_refused() -> None:
    for e in (sp.tan(q1), a / b * sp.cos(q1), sp.cos(q1 + 1), sp.sqrt(2) * sp.cos(q1), sp.Float(0.5) * sp.sin(q1)):
        try:
            fourier_coefficients(e, [q1])
        except NotTrigPolynomial:
            continue
        raise AssertionError(f"{e} accepted")


def test_nice_poly_factors_like_a_teacher() -> None:
    dq1, dq2, m, l, d = sp.symbols("dq1 dq2 m l d")
    coeffs = fourier_coefficients((-2 * m * l * d * dq1 * dq2 - m * l * d * dq2**2) * sp.sin(q2), [q2])
    assert sp.srepr(nice_poly(coeffs[(1,)][1])) == sp.srepr(-d * l * m * dq2 * (2 * dq1 + dq2))
    e = nice_poly(fourier_coefficients(2 * q3 - 2 * d, [])[()][0])
    assert str(e) == "2*(-d + q3)"  # content kept outside, q3 - d (not d - q3)
    e = nice_poly(fourier_coefficients(-a * m - l * m, [])[()][0])
    assert str(e) == "-m*(a + l)"


def test_product_form_over_single_angles() -> None:
    e = (a - b) * sp.sin(2 * q2) / 2
    coeffs = fourier_coefficients(e, [q2])
    p = product_form(coeffs, [q2])
    assert p.has(sp.sin(q2) * sp.cos(q2)) and not p.has(sp.sin(2 * q2)) and same_function(p, e)
    assert tidy(e) == p  # chosen because it is shorter


def test_constant_offsets_keep_their_phase() -> None:
    assert tidy(sp.cos(q1 + sp.pi / 4)) == sp.cos(q1 + sp.pi / 4)
    assert tidy(3 * sp.sin(q1 - sp.pi / 6)) == 3 * sp.sin(q1 - sp.pi / 6)
    assert tidy(sp.sin(q1) + sp.cos(q1)) == sp.sin(q1) + sp.cos(q1)  # no phase invented where none was written


# ------------------------------------------------------------------ factorization by gcds (issue 11)
def _random_products(dom, seed: int, count: int):  # type: ignore[no-untyped-def]
    """Products of random small polynomials in 5 generators over ``dom`` (powers, integer or rational content)."""
    from sympy.polys.rings import ring
    R, *G = ring("x,y,z,w,u", dom)
    rng = random.Random(seed)

    def rnd(k: int):  # type: ignore[no-untyped-def]
        c = (lambda: dom.convert(rng.randint(-3, 3)) / dom.convert(rng.randint(1, 3))) if dom == QQ_ else \
            (lambda: dom.convert(rng.randint(-3, 3)))
        return sum((c() * G[rng.randrange(5)] ** rng.randint(0, 2) * G[rng.randrange(5)] ** rng.randint(0, 1)
                    for _ in range(k)), R.zero)

    for _ in range(count):
        p = R.one
        for _ in range(rng.randint(1, 4)):
            p *= rnd(rng.randint(1, 4)) ** rng.randint(1, 3)
        yield p * (rng.randint(-6, 6) or 1)



@pytest.mark.parametrize("dom", [ZZ_, QQ_])
def test_factor_list_fast_equals_sympys_factorization(dom) -> None:  # type: ignore[no-untyped-def]
    """Same content and the same factors with multiplicities as ``factor_list`` (order aside), over ZZ and QQ:
    the QQ case once returned a factor with its content 2 inside (2 d₂ m₂ + 2 l₂ m₃ instead of d₂ m₂ + l₂ m₃)."""
    from solver.math.fourier import factor_list_fast
    seen_linear = 0
    for p in _random_products(dom, 7, 400):
        ref, got = p.factor_list(), factor_list_fast(p)
        assert got[0] == ref[0], p
        assert sorted((str(f), e) for f, e in got[1]) == sorted((str(f), e) for f, e in ref[1]), p
        seen_linear += any(p.degree(i) == 1 for i in range(p.ring.ngens))
    assert seen_linear > 50  # the gcd path was exercised, not only sympy's fallback


def test_factor_list_fast_on_powers_of_linear_forms() -> None:
    """Powers of forms linear in every generator ((q̇₁ + q̇₂)², (x − 2y + 3)³, ...), alone, perturbed (no longer
    powers) or times other factors: the same factorization as sympy's, where the root path (α x + β)^d = p
    is taken and where it is not."""
    from sympy.polys.rings import ring

    from solver.math.fourier import _linear_root, factor_list_fast
    R, *G = ring("x,y,z,w", ZZ_)
    rng = random.Random(3)
    roots = 0
    for _ in range(300):
        lin = sum((rng.choice([0, 1, -1, 2, -3]) * g for g in G[:rng.randint(2, 4)]), R.zero)
        lin += rng.choice([0, 0, 1, -2]) + rng.choice([0, 0, 1]) * G[0] * G[3]
        if lin.is_ground:
            continue
        p = lin ** rng.randint(2, 4)
        p += rng.choice([0, 0, 0, 1, -1])
        if rng.random() < 0.3:
            p *= G[1] + 2 * G[2] - 1
        if rng.random() < 0.5:
            p = -p
        ref, got = p.factor_list(), factor_list_fast(p)
        assert got[0] == ref[0], p
        assert sorted((str(f), e) for f, e in got[1]) == sorted((str(f), e) for f, e in ref[1]), p
        prim = p.primitive()[1]
        roots += _linear_root(prim if prim.LC > 0 else -prim) is not None
    assert roots > 50
    x, y = G[:2]
    assert _linear_root((x + y) ** 2) == (x + y, 2) and _linear_root(x**2 + x * y + y**2) is None


def test_factor_list_fast_on_a_christoffel_coefficient() -> None:
    """2 d₂ m₂ q̇₁ + d₂ m₂ q̇₂ + 2 l₂ m₃ q̇₁ + l₂ m₃ q̇₂ over QQ = (2 q̇₁ + q̇₂)(d₂ m₂ + l₂ m₃)."""
    from sympy.polys.rings import ring

    from solver.math.fourier import factor_list_fast
    R, d2, m2, l2, m3, dq1, dq2 = ring("d2,m2,l2,m3,dq1,dq2", QQ_)
    c, fl = factor_list_fast(2 * d2 * m2 * dq1 + d2 * m2 * dq2 + 2 * l2 * m3 * dq1 + l2 * m3 * dq2)
    assert c == 1 and sorted(str(f) for f, _ in fl) == sorted(["2*dq1 + dq2", "d2*m2 + l2*m3"])


def test_factor_list_expr_equals_sympys_on_expressions() -> None:
    """sympy's factor_list of polynomial expressions (symbols with assumptions, sin/cos generators, rational
    coefficients): the same coefficient and factors, signs normalized the same way."""
    from solver.math.fourier import factor_list_expr
    syms = list(sp.symbols("k_d k_f m k_i x a2 b Omega")) + list(sp.symbols("M K", positive=True))
    gens = syms + [sp.cos(syms[0]), sp.sin(syms[4])]
    rng = random.Random(5)

    def rnd() -> sp.Expr:
        return sum(sp.Rational(rng.randint(-3, 3), rng.randint(1, 2)) * rng.choice(gens) ** rng.randint(0, 2)
                   * rng.choice(gens) for _ in range(rng.randint(1, 4)))

    for _ in range(150):
        e = sp.expand(sp.Mul(*[rnd() ** rng.randint(1, 2) for _ in range(rng.randint(1, 3))]))
        ref, got = sp.factor_list(e), factor_list_expr(e)
        assert got[0] == ref[0] and sorted(map(str, got[1])) == sorted(map(str, ref[1])), e
    for c in (sp.sqrt(2), sp.pi, sp.sqrt(2) * sp.pi):  # numbers that sring would take as generators
        assert factor_list_expr(c * a + c * b) == sp.factor_list(c * a + c * b)


def test_tidy_of_a_distance_gradient_keeps_the_distance() -> None:
    """∂‖a(q) − b‖/∂q: numerator in Fourier form over the radical as given (the sum of squares, shorter than its
    expansion), equal to the original; no trigsimp fallback (which wrote sin(q + π/4) terms)."""
    l1, l2 = sp.symbols("l1 l2", positive=True)
    ax = l1 * sp.cos(q1) - (q2 - l2) * sp.sin(q1) - sp.Rational(1, 10) - sp.sqrt(2) * l1
    ay = l1 * sp.sin(q1) + (q2 - l2) * sp.cos(q1) + sp.Rational(1, 10)
    d = sp.sqrt(ax ** 2 + ay ** 2)
    for x in (q1, q2):
        g = sp.diff(d, x)
        t = tidy(g)
        assert is_zero(t - g) is True
        assert t.atoms(sp.Pow) & {d, 1 / d} and not t.has(sp.pi)
        num = sp.fraction(sp.together(t))[0]
        assert not any(p.base.free_symbols and not p.exp.is_Integer for p in num.atoms(sp.Pow))  # √ only below


@pytest.mark.parametrize("dom", [ZZ_])
def test_irreducible_is_a_proof(dom) -> None:  # type: ignore[no-untyped-def]
    """``irreducible`` (specialization to one variable, content checked) never says True of a reducible
    polynomial, and proves the irreducible ones of degree ≥ 2 in every generator that Wang's algorithm finds."""
    from solver.math.fourier import irreducible
    proved = 0
    for p in _random_products(dom, 7, 300):
        content, prim = p.primitive()
        if prim.is_ground:
            continue
        factors = prim.factor_list()[1]
        single = len(factors) == 1 and factors[0][1] == 1
        if irreducible(prim):
            assert single, p
            proved += 1
    assert proved > 20


def test_irreducible_on_known_polynomials() -> None:
    from sympy.polys.rings import ring

    from solver.math.fourier import irreducible
    R, x, y, z = ring("x,y,z", ZZ_)
    assert irreducible(x**2 * y**2 + z**2 * x + y**3 + 1)
    assert not irreducible((x**2 + y**2 + z) * (x**2 * z + y**2 + 1))      # a product
    assert not irreducible((y**2 + z**2 + 1) * x**2 + (y**2 + z**2 + 1))  # content y² + z² + 1 in x (and in z)


@settings(max_examples=80, deadline=None)
@given(exprs)
def test_product_cost_bound_is_a_lower_bound(e: sp.Expr) -> None:
    """fourier_expr skips printing the product form when this bound is already no shorter than the Fourier form:
    the bound must never exceed the product form's count (otherwise a shorter form could be missed)."""
    from solver.math.fourier import product_cost_bound, product_groups
    from solver.math.opcount import count_ops
    coeffs = fourier_coefficients(e, ANGLES)
    if not coeffs:
        return
    groups = product_groups(coeffs, ANGLES)
    assert product_cost_bound(groups) <= count_ops(product_form(coeffs, ANGLES, groups))


@settings(max_examples=80, deadline=None)
@given(exprs)
def test_product_form_is_sympys_sum_of_products_node_for_node(e: sp.Expr) -> None:
    """product_form builds its sum and products without sympy's flattening (fourier.mul_distinct, add_distinct):
    the same tree, in stored order, as Add(*[nice(g)·Π f^e]) evaluated by sympy."""
    from solver.math.fourier import product_groups
    coeffs = fourier_coefficients(e, ANGLES)
    if not coeffs:
        return
    groups = product_groups(coeffs, ANGLES)
    trig = [sp.cos(x) for x in ANGLES] + [sp.sin(x) for x in ANGLES]
    ref = sp.Add(*[nice_poly(g) * sp.Mul(*[f ** k for f, k in zip(trig, key)]) for key, g in groups.items()])
    assert tree(product_form(coeffs, ANGLES, groups)) == tree(ref)


def test_product_form_not_printed_when_it_cannot_be_shorter(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A long trigonometric polynomial whose product form is longer: fourier_expr returns the Fourier form without
    building the product form (whose coefficients are factored one by one); a short one still gets it."""
    import solver.math.simplify as S
    calls = []
    monkeypatch.setattr(S, "product_form", lambda *x: calls.append(x) or product_form(*x))
    long = sum((a + k * b) * sp.cos(k * q1 - q2) for k in range(1, 6))
    coeffs = fourier_coefficients(long, [q1, q2])
    out = S.fourier_expr(coeffs, [q1, q2])
    assert calls == [] and out.has(sp.cos(5 * q1 - q2)) and same_function(out, long)
    assert S.count_ops(product_form(coeffs, [q1, q2])) >= S.count_ops(out)
    # each symbol of a coefficient counts at least one operation in the product form (a (b + c) cos 2q₁ + ...: the
    # Fourier form counts 11, the product form 17, and the bound, 13 with the symbols, 9 without them, decides)
    c, d = sp.symbols("c d", real=True)
    two = a * (b + c) * sp.cos(2 * q1) + a * (c + d) * sp.sin(2 * q1)
    coeffs = fourier_coefficients(two, [q1])
    assert S.count_ops(S.fourier_expr(coeffs, [q1])) == 11 and calls == []
    assert S.count_ops(product_form(coeffs, [q1])) == 17
    short = (a - b) * sp.sin(2 * q2) / 2
    assert S.fourier_expr(fourier_coefficients(short, [q2]), [q2]).has(sp.sin(q2) * sp.cos(q2)) and len(calls) == 1


def test_ring_reader_reads_by_structure_and_leaves_the_rest_to_its_leaf():
    from sympy.polys.rings import ring

    from solver.math.fourier import ring_reader
    x, y, q = sp.symbols("x y q")
    R, X, Y, S = ring("X Y S", sp.QQ)
    seen = []

    def leaf(e):
        seen.append(e)
        if e in (x, y):
            return X if e == x else Y
        if e == sp.sin(q):
            return S
        raise LookupError(e)
    read = ring_reader(R, leaf)
    assert read(sp.Rational(3, 2) * (x + y) ** 2 * sp.sin(q) - x / 4) == sp.Rational(3, 2) * (X + Y) ** 2 * S - X / 4
    read(x * sp.sin(q) + x)   # memoized: no leaf call again
    assert sorted(map(str, seen)) == ["sin(q)", "x", "y"]
    with pytest.raises(LookupError):
        read(sp.cos(q) + x)
    with pytest.raises(LookupError):
        read(1 / x)   # a negative power is a leaf too


def test_ring_trig_is_sympys_expand_trig():
    """cos/sin of Σ n_j x_j in the ring of (cos x_j, sin x_j): sympy's expand_trig, multiple angles included;
    anything but an integer combination of the given angles is refused."""
    from sympy.polys.rings import ring

    from solver.math.fourier import ring_trig
    x, y, c1, s1, c2, s2 = sp.symbols("x y c1 s1 c2 s2")
    R, C1, S1, C2, S2 = ring("c1 s1 c2 s2", sp.QQ)
    back = {sp.cos(x): c1, sp.sin(x): s1, sp.cos(y): c2, sp.sin(y): s2}
    for arg in [x, -x, 2 * x, 3 * x, -4 * x, 5 * x, x + y, 2 * x - 3 * y, -x - 2 * y]:
        c, s = ring_trig(arg, {x: (C1, S1), y: (C2, S2)})
        for f, got in ((sp.cos(arg), c), (sp.sin(arg), s)):
            assert sp.expand(sp.expand_trig(f).xreplace(back) - got.as_expr()) == 0, f
    for bad in (x + 1, x / 2, 2 * sp.Symbol("z")):
        with pytest.raises(ValueError):
            ring_trig(bad, {x: (C1, S1)})


def tree(e: sp.Basic):  # type: ignore[no-untyped-def]
    """The stored tree, arguments in stored order (srepr orders the terms of a sum)."""
    return (type(e).__name__, tuple(tree(x) for x in e.args)) if e.args else sp.srepr(e)


@pytest.mark.parametrize("domain", ["QQ", "ZZ"])
def test_poly_expr_builds_sympys_own_tree(domain: str) -> None:
    """poly_expr (no flattening) gives p.as_expr() node for node: same arguments in the same order (the LaTeX
    printer prints some products in stored order), on random polynomials with constants, ±1 and fractions."""
    from solver.math.fourier import _ring, poly_expr
    syms = sp.symbols("I1 d2 dq1 dq2 g0 l1 m2 q1")
    R = _ring(tuple(syms))
    dom = QQ_ if domain == "QQ" else ZZ_
    R = R if dom is QQ_ else R.clone(domain=ZZ_)
    rng = random.Random(domain)
    for _ in range(500):
        d = {}
        for _ in range(rng.randint(1, 6)):
            m = tuple(rng.choice([0, 0, 0, 1, 2, 3]) for _ in syms)
            d[m] = dom.convert(rng.choice([-3, -1, 1, 1, 2, 5])) / (dom.convert(rng.choice([1, 2, 3])) if dom is QQ_
                                                                    else dom.one)
        p = R.from_dict(d)
        assert tree(poly_expr(p)) == tree(p.as_expr()), p
    assert poly_expr(R.zero) == 0 and poly_expr(R.one) == 1


def test_mul_and_add_distinct_build_sympys_own_tree() -> None:
    """mul_distinct and add_distinct (no flattening) give what Mul and Add give, node for node, on the
    shapes the Fourier sums are made of: polynomials, products of a content, monomials and factors, a number
    times a single sum (kept a product, as Mul(..., evaluate=False)), cos/sin of distinct harmonics; random."""
    from solver.math.fourier import _ring, add_distinct, mul_distinct, poly_expr
    syms = sp.symbols("I1 d2 dq1 dq2 g0 l1 m2 q1")
    R = _ring(tuple(syms))
    rng = random.Random(7)
    trig = [f(h) for h in (q2, q1 + q2, q2 - q3, 2 * q3, q1 + q2 + q3) for f in (sp.cos, sp.sin)]

    def poly(terms: int, start: int = 0):  # type: ignore[no-untyped-def]
        d = {}
        for _ in range(terms):
            m = tuple(rng.choice([0, 0, 1, 2]) if i >= start else 0 for i in range(len(syms)))
            d[m] = QQ_(rng.choice([-3, -1, 1, 1, 2, 5]), rng.choice([1, 1, 2, 3]))
        return R.from_dict(d)

    def coefficient():  # type: ignore[no-untyped-def]
        """A coefficient as nice_poly writes one: a polynomial, a product of a monomial and factors, or a number
        times one sum."""
        shape = rng.randrange(4)
        if shape == 0:
            return poly_expr(poly(rng.randint(1, 5)))
        number = sp.Rational(rng.choice([-3, -1, 1, 2]), rng.choice([1, 2]))
        if shape == 1:
            return mul_distinct(number, [poly_expr(poly(2, 4))])
        factors = [poly_expr(R.from_dict({tuple(rng.choice([0, 1, 2]) for _ in syms): QQ_(1)})),
                   poly_expr(poly(2, 2)) ** rng.choice([1, 2]), poly_expr(poly(3, 5))]
        return mul_distinct(number, factors[:rng.randint(1, 3)])

    for _ in range(400):
        c, f = coefficient(), rng.choice(trig)
        assert tree(mul_distinct(sp.S.One, [c, f])) == tree(c * f), (c, f)
        number = sp.Rational(rng.choice([-2, -1, 1, 3]), rng.choice([1, 2]))
        s = poly_expr(poly(rng.randint(2, 4), 2))
        kept = sp.Mul(number, s, evaluate=False) if number != 1 and s.is_Add else number * s
        assert tree(mul_distinct(number, [s])) == tree(kept)
        harmonics = rng.sample(trig, rng.randint(0, 4))
        terms = [coefficient()] + [mul_distinct(sp.S.One, [coefficient(), h]) for h in harmonics]
        rng.shuffle(terms)
        assert tree(add_distinct(terms)) == tree(sp.Add(*terms)), terms
    assert mul_distinct(sp.S.Zero, [a]) == 0 and add_distinct([sp.S(2), sp.S(-2)]) == 0
