"""The printing order of sums (solver.publish.termorder) is sympy's as_ordered_terms, term for term."""
from __future__ import annotations

import random

import pytest
import sympy as sp

from solver.publish import termorder
from solver.publish.termorder import ordered_terms

q1, q2, q3, m1, l1, dq1, dq2 = sp.symbols("q1 q2 q3 m1 l1 dq1 dq2")
ATOMS = [q1, q2, m1, l1, dq1, dq2, sp.sin(q1), sp.cos(q2), sp.sin(q1 + q2), sp.cos(2 * q1 + q3), l1 + m1]


def _random_sum(rng: random.Random) -> sp.Expr:
    """A sum of up to 12 terms: a rational coefficient (ties in the monomial are ordered by it) times powers of
    symbols, sines, cosines and a sum, with exponents in -2..3."""
    terms = []
    for _ in range(rng.randint(2, 12)):
        c = sp.Rational(rng.choice([-7, -3, -1, 1, 2, 5, 9]), rng.choice([1, 1, 2, 3, 8]))
        mono = sp.Mul(*[rng.choice(ATOMS) ** rng.choice([-2, -1, 1, 1, 2, 3]) for _ in range(rng.randint(0, 4))])
        terms.append(c * mono)
    return sp.Add(*terms)


@pytest.mark.parametrize("order", [None, "lex", "grlex", "grevlex", "rev-lex", "rev-grlex"])
def test_same_order_as_sympy_on_random_sums(order: str | None) -> None:
    rng = random.Random(f"termorder-{order}")
    checked = 0
    for _ in range(300):
        e = _random_sum(rng)
        if not e.is_Add:
            continue
        assert ordered_terms(e, order) == e.as_ordered_terms(order=order), e
        checked += 1
    assert checked > 250


def test_fast_path_taken_for_model_entries() -> None:
    """A Christoffel-like entry is ordered without sympy's evalf of each coefficient (and in its order)."""
    e = -m1 * l1 * dq1 ** 2 * sp.sin(q2) / 2 + 3 * l1 ** 2 * dq2 * sp.cos(q1 + q2) - dq1 * dq2 / 7 + m1
    assert termorder._ordered(e, None) == e.as_ordered_terms()
    assert ordered_terms(e) == e.as_ordered_terms()


@pytest.mark.parametrize("e", [
    sp.sqrt(2) * q1 + q2,                        # a number factor other than the coefficient
    sp.pi * q1 - q2 ** 2,                        # a number symbol
    sp.Float(0.5) * q1 + q2,                     # a float coefficient
    sp.I * q1 + q2,                              # an imaginary coefficient
    sp.sqrt(q1) + q1 * q2,                       # a fractional exponent
    q1 ** q2 + q1,                               # a symbolic exponent
    sp.exp(q1) + sp.exp(2 * q1) + q2,            # exp: sympy decomposes its exponent
    sp.Symbol("A", commutative=False) * sp.Symbol("B", commutative=False) + q1,
    1 - q1,                                      # sympy's special case (number plus a negative product)
    3 - 2 * q1 * q2,
    sp.Integer(2) ** 60 * q1 + q2,               # a coefficient beyond exact floats
])
def test_other_sums_are_left_to_sympy(e: sp.Expr) -> None:
    assert ordered_terms(e) == e.as_ordered_terms()
    assert ordered_terms(e, "grlex") == e.as_ordered_terms(order="grlex")


def test_printed_text_unchanged(monkeypatch: pytest.MonkeyPatch) -> None:
    """The JSON text and the LaTeX of the reports print sums in this order: the same strings as with sympy's."""
    from solver.publish import render
    rng = random.Random(7)
    sums = [_random_sum(rng) for _ in range(60)]

    from solver.publish import textprint

    def printed() -> list[tuple[str, str, str]]:
        termorder._PRINTING_ORDER.clear()
        termorder._SORT_KEYS.clear()
        textprint._MEMO.clear()
        tex = render.Latex({})
        return [(render._Str().doprint(e), tex(e), render._expr_str(e)) for e in sums]

    fast = printed()
    sympys = lambda e, order=None: e.as_ordered_terms(order=order)  # noqa: E731
    monkeypatch.setattr(render, "ordered_terms", sympys)
    monkeypatch.setattr(termorder, "ordered_terms", sympys)
    monkeypatch.setattr(termorder, "_sort_key", lambda e: e.sort_key())
    assert fast == printed()
    assert [text for text, _, _ in fast] == [sp.sstr(e) for e in sums]
    assert [text for _, _, text in fast] == [sp.sstr(e) for e in sums]
