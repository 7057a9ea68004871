"""Trigonometric-polynomial algebra: canonical forms agree with the original functions, zero tests are exact."""
from __future__ import annotations

import random

import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

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
