"""The JSON text printed directly (solver.publish.textprint) is sympy's str(), character for character, and the
factor order (termorder.sort_key) is sympy's sort_key."""
from __future__ import annotations

import random

import pytest
import sympy as sp

from solver.publish import termorder, textprint
from solver.publish.textprint import OutsideText, text

q1, q2, q3, m1, l1, dq1, dq2, I3 = sp.symbols("q1 q2 q3 m1 l1 dq1 dq2 I3")
SYMS = [q1, q2, q3, m1, l1, dq1, dq2, I3]


def _random_expr(rng: random.Random, depth: int = 0) -> sp.Expr:
    """Sums of products of symbols, sin/cos of sums, sums and their positive integer powers, with rational
    coefficients: the shapes of a model's entries, nested up to three levels."""
    def factor() -> sp.Expr:
        kind = rng.random()
        if kind < 0.45 or depth >= 2:
            return rng.choice(SYMS)
        if kind < 0.75:
            arg = sp.Add(*[rng.choice([-2, -1, 1, 1, 2]) * rng.choice(SYMS[:3]) for _ in range(rng.randint(1, 3))])
            return rng.choice([sp.sin, sp.cos])(arg if arg != 0 else q1)
        return _random_expr(rng, depth + 1)

    terms = []
    for _ in range(rng.randint(1, 6)):
        c = sp.Rational(rng.choice([-7, -3, -1, 1, 1, 2, 5]), rng.choice([1, 1, 1, 2, 3]))
        terms.append(c * sp.Mul(*[factor() ** rng.choice([1, 1, 1, 2, 3]) for _ in range(rng.randint(0, 4))]))
    return sp.Add(*terms)


@pytest.fixture(autouse=True)
def _fresh_memos():
    textprint._MEMO.clear()
    termorder._SORT_KEYS.clear()
    termorder._PRINTING_ORDER.clear()


def test_text_is_sympys_str_on_random_expressions() -> None:
    rng = random.Random("textprint")
    checked = 0
    for _ in range(400):
        e = _random_expr(rng)
        assert text(e) == sp.sstr(e), e
        checked += not e.is_Atom
    assert checked > 300


def test_sort_key_is_sympys_on_random_expressions() -> None:
    rng = random.Random("sortkey")
    for _ in range(300):
        e = _random_expr(rng)
        for sub in sp.preorder_traversal(e):
            assert termorder.sort_key(sub) == sub.sort_key(), sub


@pytest.mark.parametrize("e, printed", [
    (sp.Mul(2, q1 + q2, evaluate=False), "2*(q1 + q2)"),      # nice_poly keeps a number times a sum unexpanded
    (sp.Mul(-1, q1 - l1, evaluate=False), "-(-l1 + q1)"),
    (-sp.Rational(3, 2) * m1 * (q1 + l1) ** 2 * sp.cos(q1 - q2), "-3*m1*(l1 + q1)**2*cos(q1 - q2)/2"),
    (m1 * l1 / 2 - sp.Rational(1, 3), "l1*m1/2 - 1/3"),
    (1 - q1, "1 - q1"),                                          # sympy's special case of a two-term sum
    (sp.sin(q1) ** 2 * dq1 + sp.cos(2 * q1 + q3), "dq1*sin(q1)**2 + cos(2*q1 + q3)"),
])
def test_text_of_model_shapes(e: sp.Expr, printed: str) -> None:
    assert text(e) == printed == sp.sstr(e)


@pytest.mark.parametrize("e", [
    sp.Float(0.5) * q1 + q2, sp.sqrt(2) * q1, q1 / q2, 1 / (q1 + q2), sp.pi * q1, sp.exp(q1) * q2,
    sp.tan(q1), sp.Dummy("x") + q1, sp.Mul(2, 3, q1, evaluate=False), sp.I * q1, sp.sqrt(q1 + q2),
])
def test_other_expressions_are_left_to_sympy(e: sp.Expr) -> None:
    with pytest.raises(OutsideText):
        text(e)
    from solver.publish.render import _expr_str
    assert _expr_str(e) == sp.sstr(e)


def test_latex_bracket_rules_are_sympys() -> None:
    """The LaTeX printer's bracket decisions for plain expressions (taken directly) are sympy's LatexPrinter's,
    and has_float is has(Float), on random expressions and every subexpression."""
    from sympy.printing.latex import LatexPrinter

    from solver.publish.render import _Printer, has_float
    rng = random.Random("brackets")
    ours = _Printer({}, {})
    exprs = [_random_expr(rng) for _ in range(150)] + [sp.Float(0.5) * q1 * sp.cos(q2) - sp.Mod(q1, 2) * q2,
                                                      sp.Integral(q1, q1) * q2 - sp.Rational(-3, 2)]
    for e in exprs:
        for sub in sp.preorder_traversal(e):
            for first, last in ((False, False), (True, False), (False, True)):
                assert ours._needs_mul_brackets(sub, first, last) == \
                    LatexPrinter._needs_mul_brackets(ours, sub, first, last), sub
            assert ours._needs_add_brackets(sub) == LatexPrinter._needs_add_brackets(ours, sub), sub
            assert has_float(sub) == sub.has(sp.Float), sub
