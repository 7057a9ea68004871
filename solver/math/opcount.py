"""``count_ops`` with memoized subtrees: the same integer as ``sympy.count_ops(e)`` (its visual count summed, SUB − ADD
counted 0, and its quirks kept: the Add under a negated Mul, −(a + b), counts no ADD), computed once per distinct
subexpression. Choosing between two printed forms (Fourier vs product form, factored vs expanded) counts both, and
they share most of their coefficients."""
from __future__ import annotations

from functools import lru_cache

import sympy as sp
from sympy.simplify.radsimp import fraction


def count_ops(e: sp.Basic) -> int:
    """Number of operations of ``e`` as :func:`sympy.count_ops` counts them (Add, Mul, Pow, sin/cos, numbers,
    symbols; an expression with any other node, a Python number or a mutable matrix is handed to sympy)."""
    if not isinstance(e, sp.Basic):
        return int(sp.count_ops(e))
    return _count_ops(e)


@lru_cache(maxsize=50000)
def _count_ops(e: sp.Basic) -> int:
    if e.is_Symbol:
        return 0
    if e.is_Rational:
        return 0 if e is sp.S.One else int(e.p < 0) + int(e.q != 1)
    if e.is_Add:
        negs = [_coeff_isneg(a) for a in e.args]
        n = len(e.args) - 1 + (1 if all(negs) else 0)
        return n + sum(_count_ops(-a if s else a) for a, s in zip(e.args, negs))
    if e.is_Mul:
        n = 0
        if _coeff_isneg(e):
            n += 1
            e = e.as_two_terms()[1] if e.args[0] is sp.S.NegativeOne else -e
        if e.is_Mul and not any((a.is_Pow and a.exp.is_negative) or (a.is_Rational and a.q != 1) or a.is_Mul
                                or isinstance(a, sp.exp) for a in e.args):
            num, den = e, sp.S.One      # fraction(e) without a denominator, the common case
        elif e.is_Mul and e.args[0].is_Rational and len(e.args) > 1 + e.args[1].is_Add and not any(
                (a.is_Pow and a.exp.is_negative) or a.is_Number or a.is_Mul or isinstance(a, sp.exp)
                for a in e.args[1:]):
            # p/q·f₁⋯f_k (k ≥ 2 when f₁ is a sum: p·(a + b) would be distributed): fraction(e) is
            # (p·f₁⋯f_k, q), counted without building it: the quotient's 1 (q is an integer), then the
            # numerator's products and factors
            c, rest = e.args[0], e.args[1:]
            return n + 1 + len(rest) - (c.p == 1) + sum(_count_ops(a) for a in rest)
        else:
            num, den = fraction(e)
        if num.is_Integer:
            return n + 1 + (1 if num < 0 else 0) + _count_ops(den)
        if den is not sp.S.One:
            return n + 1 + (0 if den.is_Integer else _count_ops(den)) + _count_ops(num)
        return n + _rest(e)
    return _rest(e)


def _coeff_isneg(a: sp.Basic) -> bool:
    """sympy's ``_coeff_isneg``: a number, or a product's leading number, that is negative (a rational's sign read
    from its numerator: ``is_extended_negative`` runs the assumptions system once per new number)."""
    if a.is_MatMul:
        a = a.args[0]
    if a.is_Mul:
        a = a.args[0]
    if a.is_Rational:
        return a.p < 0
    return bool(a.is_Number and a.is_extended_negative)


def _rest(e: sp.Basic) -> int:
    """sympy's count for a node past its Rational/Mul/Add cases (also a negated Mul's remaining factor)."""
    if e.is_Pow and e.exp is sp.S.NegativeOne:
        return 1 + _count_ops(e.base)
    if e is sp.S.Exp1:
        return 1
    if e.is_Pow and e.base is sp.S.Exp1:
        return 1 + _count_ops(e.exp)
    if not (e.is_Mul or e.is_Pow or e.is_Add or e.is_Symbol or e.is_Number or e.is_NumberSymbol
            or e is sp.S.ImaginaryUnit or isinstance(e, (sp.sin, sp.cos))):
        return int(sp.count_ops(e))
    n = 0
    if e.is_Mul:
        n += len(e.args) - 1
    elif e.args and (e.is_Pow or e.is_Function):
        n += 1
    if not e.is_Symbol:
        n += sum(_count_ops(a) for a in e.args)
    return n
