"""sympy's ``str()`` of a polynomial-like expression, printed directly: the JSON text of a model's entries.

For sums, products, positive integer powers, rational numbers, plain symbols, sin and cos (what a dynamic model
is made of), :func:`text` writes exactly what ``sympy.printing.str.StrPrinter`` writes, without its generic
dispatch, precedence lookups and factor sorting at every node:

- a sum: its terms in sympy's printing order (:func:`solver.publish.termorder.printing_order`), a leading minus
  of a term's text turned into the separator, ``a + b - c``;
- a product c·f₁⋯f_k: sign, then the factors sorted by ``sort_key`` (the number first), a sum in parentheses,
  the denominator of c after ``/``: ``-3*m2*(q1 + q2)/2``;
- a power b**e (e a positive integer): b in parentheses when it is a sum.

Anything else (floats, negative or fractional powers, other functions, unevaluated products) raises
:class:`OutsideText`, and the caller prints the whole expression with sympy. ``tests/test_textprint.py`` checks
the equality with sympy on random expressions.
"""
from __future__ import annotations

import sympy as sp

from solver.publish.termorder import cached, printing_order, sort_key

__all__ = ["OutsideText", "text"]

_MEMO: dict[sp.Basic, str] = {}  # compound subexpression -> its text (a model's results share most of them)
_TRIG = (sp.sin, sp.cos)


class OutsideText(Exception):
    """A node :func:`text` does not print: print the expression with sympy."""


def text(e: sp.Basic) -> str:
    """``str(e)`` for the expressions described in the module docstring, else :class:`OutsideText`."""
    if e.is_Atom:
        return _atom(e)
    return cached(_MEMO, e, lambda: _compound(e))


def _atom(e: sp.Basic) -> str:
    if type(e) is sp.Symbol:
        return e.name
    if e.is_Rational:
        return str(e.p) if e.q == 1 else f"{e.p}/{e.q}"
    raise OutsideText(e)


def _compound(e: sp.Basic) -> str:
    t = type(e)
    if t is sp.Add:
        out = []
        for term in printing_order(e, None):
            s = text(term)
            if s.startswith("-"):
                out += ["-", s[1:]]
            else:
                out += ["+", s]
        sign = out.pop(0)
        return ("" if sign == "+" else sign) + " ".join(out)
    if t is sp.Mul:
        return _product(e)
    if t is sp.Pow:
        base, exp = e.args
        if not (exp.is_Integer and exp > 1) or not (base.is_Add or type(base) is sp.Symbol or type(base) in _TRIG):
            raise OutsideText(e)
        b = text(base)
        return f"({b})**{exp.p}" if base.is_Add else f"{b}**{exp.p}"
    if t in _TRIG:
        return f"{t.__name__}({text(e.args[0])})"
    raise OutsideText(e)


def _product(e: sp.Mul) -> str:
    args = e.args
    if args[0] is sp.S.One or any(a.is_Number or (a.is_Pow and a.base.is_Integer and a.exp.is_Integer)
                                  for a in args[1:]):
        raise OutsideText(e)  # an unevaluated product: sympy prints every argument as stored
    coeff, rest = e.as_coeff_Mul()
    if not coeff.is_Rational:
        raise OutsideText(e)
    sign = ""
    if coeff < 0:
        sign, coeff = "-", -coeff
    factors = []
    for f in sp.Mul.make_args(rest):
        if not (f.is_Add or f.is_Pow or type(f) is sp.Symbol or type(f) in _TRIG) or not f.is_commutative:
            raise OutsideText(e)
        factors.append((sort_key(f), f))
    factors.sort(key=lambda kf: kf[0])
    parts = [] if coeff.p == 1 else [str(coeff.p)]
    for _, f in factors:
        s = text(f)
        parts.append(f"({s})" if f.is_Add else s)
    body = sign + "*".join(parts)
    return body if coeff.q == 1 else f"{body}/{coeff.q}"
