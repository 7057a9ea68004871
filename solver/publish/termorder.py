"""The printing order of the terms of a sum, as sympy's ``Expr.as_ordered_terms`` gives it, computed faster.

sympy sorts the terms t = c·Π bᵢ^eᵢ of a sum by the key of ``Expr._parse_order`` (−monomial_key(e), then c) over
the generators bᵢ sorted by ``default_sort_key``, with c = re + i·im evaluated numerically by ``complex(c)``, which
goes through evalf: most of the printing time of a long sum. For the terms printed here (a rational coefficient
times commutative symbols, sines, cosines, sums and their integer powers) the key's input is built with
c = p/q in floating point (correctly rounded, as evalf's 53-bit value); a sum with any other term (a number
factor such as √2 or π, a noncommutative factor, a power with a symbolic or fractional exponent, exp) is left to
sympy. Same order, same ties (a stable sort of the terms as stored)."""
from __future__ import annotations

from typing import Any, Callable

import sympy as sp

_MEMO_LIMIT = 200_000
_PRINTING_ORDER: dict[tuple[Any, Any], tuple] = {}  # (sum, order) -> its terms in printing order
_SORT_KEYS: dict[sp.Basic, Any] = {}  # expression -> its sort_key (sympy's orders sums by evaluating coefficients)
_FLOAT_EXACT = 2 ** 53  # rationals whose parts are at most this size convert to the float evalf would give


class _Slow(Exception):
    """A term outside the fast path: the whole sum is ordered by sympy."""


def ordered_terms(expr: sp.Expr, order: Any = None) -> list[sp.Expr]:
    """``expr.as_ordered_terms(order)`` (see the module docstring)."""
    if not expr.is_Add or _special_case(expr, order):
        return expr.as_ordered_terms(order=order)
    try:
        return _ordered(expr, order)
    except _Slow:
        return expr.as_ordered_terms(order=order)


def cached(memo: dict, key: Any, make: Callable[[], Any]) -> Any:
    """``memo[key]``, computed by ``make()`` on a miss; the memo is emptied past _MEMO_LIMIT entries."""
    hit = memo.get(key)
    if hit is None:
        if len(memo) > _MEMO_LIMIT:
            memo.clear()
        hit = memo[key] = make()
    return hit


def printing_order(expr: sp.Expr, order: Any = None) -> tuple[sp.Expr, ...]:
    """:func:`ordered_terms`, memoized: the text and the LaTeX printers and :func:`sort_key` order the same sums
    (the order depends on the terms' values only, so equal sums share it)."""
    return cached(_PRINTING_ORDER, (expr, order), lambda: tuple(ordered_terms(expr, order)))


def sort_key(e: sp.Basic) -> Any:
    """``e.sort_key()`` (sympy's order of the factors of a product), memoized, with the terms of sums ordered by
    :func:`printing_order` (sympy's own key orders them by ``as_ordered_terms``, evaluating every coefficient):
    (class key, (len(args), args' keys), key of the exponent, coefficient)."""
    return cached(_SORT_KEYS, e, lambda: _sort_key(e))


def _sort_key(e: sp.Basic) -> Any:
    """sympy's ``Expr.sort_key`` for order None, as written there, for sums, products, powers, sin and cos."""
    if e.is_Atom or type(e) not in (sp.Add, sp.Mul, sp.Pow, sp.sin, sp.cos):
        return e.sort_key()
    coeff, expr = e.as_coeff_Mul()
    exp = sp.S.One
    if expr.is_Pow:
        base, exp = expr.as_base_exp()
        if base is sp.S.Exp1:
            return e.sort_key()
        expr = base
    if expr.is_Dummy:
        return e.sort_key()
    if expr.is_Atom:
        args: tuple = (str(expr),)
    elif expr.is_Add:
        args = tuple(sort_key(t) for t in printing_order(expr, None))
    elif expr.is_Mul:
        if any(a.is_Number or not a.is_commutative for a in expr.args):
            return e.sort_key()
        args = tuple(sorted(sort_key(a) for a in expr.args))
    else:
        args = tuple(sort_key(a) for a in expr.args)
    return expr.class_key(), (len(args), args), exp.sort_key(), coeff


def _special_case(expr: sp.Expr, order: Any) -> bool:
    """Whether the sum may meet sympy's own early return for order None (a positive number plus a product with a
    negative number, 1 - x, printed in stored order): any two-term sum with a number term is left to sympy."""
    if order is not None:
        return False
    args = expr.args
    if len(args) != 2:
        return False
    return any(isinstance(a, (sp.Number, sp.NumberSymbol)) for a in args)


def _split(term: sp.Expr) -> tuple[float, dict[sp.Basic, int]]:
    """(the coefficient as a float, {base: integer exponent}) of one term, or _Slow."""
    coeff, rest = term.as_coeff_Mul()
    if not coeff.is_Rational:
        raise _Slow
    p, q = int(coeff.p), int(coeff.q)
    if abs(p) > _FLOAT_EXACT or q > _FLOAT_EXACT:
        raise _Slow
    powers: dict[sp.Basic, int] = {}
    if rest is not sp.S.One:
        for factor in sp.Mul.make_args(rest):
            if isinstance(factor, sp.Pow):
                base, exp = factor.args
                if not exp.is_Integer or base.is_number:
                    raise _Slow
                powers[base] = int(exp)
            elif factor.is_Symbol and factor.is_commutative:
                powers[factor] = 1
            elif isinstance(factor, (sp.sin, sp.cos, sp.Add)) and not factor.is_number:
                powers[factor] = 1
            else:
                raise _Slow
    return p / q, powers


def _ordered(expr: sp.Expr, order: Any) -> list[sp.Expr]:
    """The terms sorted by sympy's own key (``Expr._parse_order``) over (term, ((re, im), monomial, ())), with
    the monomials over the generators in default_sort_key order, as ``Expr.as_terms`` builds them."""
    terms = [(t, *_split(t)) for t in expr.args]
    gens = {b for _, _, powers in terms for b in powers}
    index = {g: i for i, g in enumerate(sorted(gens, key=sort_key))}
    key, reverse = (_lex_key, False) if order is None or order == "lex" else sp.Expr._parse_order(order)
    rows = []
    for t, c, powers in terms:
        monom = [0] * len(index)
        for b, e in powers.items():
            monom[index[b]] = e
        rows.append((t, ((c, 0.0), tuple(monom), ())))
    return [t for t, _ in sorted(rows, key=key, reverse=reverse)]


def _lex_key(row: tuple) -> tuple:
    """sympy's key for order None/lex (``Expr._parse_order``: (−monomial, (), ((False, 0.0), (c, 0.0)))), without
    its constant parts."""
    _, ((c, _), monom, _) = row
    return tuple(-e for e in monom), c
