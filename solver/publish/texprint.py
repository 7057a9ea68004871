"""The LaTeX of a polynomial-like expression, printed directly: what the reports' printer writes, without sympy's
generic dispatch at every node.

For sums, products with a rational coefficient, positive integer powers, symbols, numbers, sin and cos (what a
dynamic model is made of), :class:`DirectLatex` writes exactly what ``render._Printer`` (sympy's LatexPrinter
with the teacher's order of factors) writes:

- a sum: its terms in sympy's printing order (stored order inside a product, as the printer sets order 'none'
  there), a term that can extract a minus sign written ``- t``, a sum term in ``\\left( \\right)``;
- a product c·f₁⋯f_k (c = ±1 or an integer, k ≥ 2): the factors sorted by the printer's key, a sum in
  ``\\left( \\right)``, separated by a space (sympy's number separator between a digit and a number); with
  c = ±p/q (q > 1; k ≥ 1, a single factor not a sum) ``± \\frac{p f₁⋯f_k}{q}``, as sympy's fraction() splits
  it;
- a power b^e (e a positive integer): ``\\sin^{e} {x}`` for sin and cos, a sum base in ``\\left( \\right)``, a
  symbol whose LaTeX has a superscript in parentheses, an even power of a sum that would start with a minus sign
  written with the opposite base (the printer's rule);
- sin and cos: ``\\sin {x}`` when sympy folds the brackets, else ``\\sin{\\left(x \\right)}``.

Every other node (quotients by symbols, negative or fractional powers, other functions, unevaluated products of
numbers) is printed by the printer itself, in the same order setting, and the printer hands the plain subexpressions
of what it prints back here (``_Printer._print``); ``tests/test_texprint.py`` checks the equality with the printer
on random expressions.
"""
from __future__ import annotations

import re
from typing import Any

import sympy as sp

from solver.publish.termorder import printing_order

__all__ = ["DirectLatex", "negative"]

_TRIG = (sp.sin, sp.cos)
_NUMBER_END = re.compile(r"[0-9][} ]*$")  # sympy's test for a number separator between two factors
_NUMBER_START = re.compile(r"(\d|\\frac{\d+}{\d+})")


class DirectLatex:
    """``printer.doprint(e)`` for the expressions of the module docstring; ``printer`` is a ``render._Printer``
    (its symbol names, its order of factors, its settings)."""

    _MEMO_LIMIT = 200_000

    def __init__(self, printer: Any) -> None:
        self.p = printer
        self.memo: dict[tuple[sp.Basic, Any], str] = {}
        self.atoms: dict[sp.Basic, str] = {}
        self.active: set[tuple[sp.Basic, Any]] = set()  # nodes the printer is printing itself (see _sympy)
        self.sep = printer._settings["mul_symbol_latex"]
        self.numbersep = printer._settings["mul_symbol_latex_numbers"]

    def doprint(self, e: sp.Basic) -> str:
        """The LaTeX of ``e`` (an expression of sums, products, powers, sin, cos, symbols and rationals)."""
        return self.tex(e, self.p._settings["order"])

    def tex(self, e: sp.Basic, order: Any) -> str:
        if e.is_Atom:
            hit = self.atoms.get(e)
            if hit is None:
                hit = self.atoms[e] = self.p._print(e)
            return hit
        key = (e, order)
        hit = self.memo.get(key)
        if hit is None:
            if len(self.memo) > self._MEMO_LIMIT:
                self.memo.clear()
            hit = self.memo[key] = self._compound(e, order)
        return hit

    def takes(self, e: sp.Basic, order: Any) -> bool:
        """Whether the printer, about to print the plain compound ``e``, hands it here (not a node it is printing
        itself on this printer's request: its subexpressions come back here)."""
        return (e, order) not in self.active

    def _sympy(self, e: sp.Basic, order: Any) -> str:
        """The printer's own LaTeX of ``e`` under the order setting ``order``."""
        p = self.p
        old_order, old_on = p._settings["order"], p._memo_on
        p._settings["order"], p._memo_on = order, True
        key = (e, order)
        self.active.add(key)
        try:
            return p._print(e)
        finally:
            self.active.discard(key)
            p._settings["order"], p._memo_on = old_order, old_on

    def _compound(self, e: sp.Basic, order: Any) -> str:
        t = type(e)
        if t is sp.Add:
            return self._sum(e, order)
        if t is sp.Mul:
            return self._product(e, order)
        if t is sp.Pow:
            return self._power(e, order)
        if t in _TRIG:
            return self._function(e, order, None)
        return self._sympy(e, order)

    def _sum(self, e: sp.Add, order: Any) -> str:
        if order == "old" or any(a.is_Add for a in e.args):
            return self._sympy(e, order)
        terms = list(e.args) if order == "none" else printing_order(e, order)
        out = ""
        for i, term in enumerate(terms):
            if i:
                if negative(term):
                    out += " - "
                    term = -term
                else:
                    out += " + "
            s = self.tex(term, order)
            out += f"\\left({s}\\right)" if term.is_Add else s
        return out

    def _product(self, e: sp.Mul, order: Any) -> str:
        coeff, rest = e.as_coeff_Mul()
        factors = sp.Mul.make_args(rest)
        if not coeff.is_Rational or any(f.is_Number or f.is_Mul or (f.is_Pow and f.exp.is_negative)
                                        for f in factors):
            return self._sympy(e, order)
        if len(factors) < 2:
            f = factors[0]
            if coeff.is_Integer or f.is_Add:
                return self._sympy(e, order)
            body = self.tex(f, order)  # (a single factor: printed in the printer's own order)
        else:
            body = ""
            for f in sorted(factors, key=self.p._factor_key):
                s = self.tex(f, "none")  # (the printer prints a product's factors with order 'none')
                body = self._joined(body, f"\\left({s}\\right)" if f.is_Add else s)
        sign = "- " if coeff < 0 else ""
        if coeff.q != 1:  # sympy's fraction(): \frac{|p| body}{q}
            num = body if abs(coeff.p) == 1 else self._joined(str(abs(coeff.p)), body)
            return f"{sign}\\frac{{{num}}}{{{coeff.q}}}"
        if coeff == 1:
            return body
        if coeff == -1:
            return "- " + body
        return sign + self._joined(str(abs(coeff.p)), body)

    def _joined(self, left: str, right: str) -> str:
        """Two factors' LaTeX side by side, as sympy's convert_args joins them: its number separator between a
        digit and a number, else the multiplication symbol."""
        if not left:
            return right
        number = _NUMBER_END.search(left) and _NUMBER_START.match(right)
        return left + (self.numbersep if number else self.sep) + right

    def _power(self, e: sp.Pow, order: Any) -> str:
        b, x = e.args
        if not (x.is_Integer and x > 0) or not (b.is_Add or b.is_Symbol or type(b) in _TRIG):
            return self._sympy(e, order)
        if b.is_Add and x.p % 2 == 0 and self.tex(b, order).startswith("-") \
                and not self.tex(-b, order).startswith("-"):
            b = -b
        if type(b) in _TRIG:
            return self._function(b, order, str(x.p))
        base = self.tex(b, order)
        if b.is_Add:
            base = f"\\left({base}\\right)"
        else:  # a symbol whose LaTeX has a superscript: in parentheses (or braces, by the printer's setting)
            base = self.p.parenthesize_super(base)
        return f"{base}^{{{x.p}}}"

    def _function(self, e: sp.Basic, order: Any, exp: str | None) -> str:
        """\\sin {x} / \\sin{\\left(x \\right)}, with ^{exp} after the name."""
        (arg,) = e.args
        name = f"\\{type(e).__name__}" + ("" if exp is None else f"^{{{exp}}}")
        s = self.tex(arg, order)
        if self.p._needs_function_brackets(arg):
            return f"{name}{{\\left({s} \\right)}}"
        return f"{name} {{{s}}}"


def negative(term: sp.Expr) -> bool:
    """``term.could_extract_minus_sign()``; for a product, the sign of its rational coefficient (sympy's
    ``Mul.could_extract_minus_sign`` first builds −term and compares the two trees, for zoo·x)."""
    if type(term) is sp.Mul:
        c = term.args[0]  # (a product's number, if any, comes first)
        if c.is_Rational:
            return c.p < 0
        if not c.is_Number:  # no number at all: −term has one, the trees differ, and sympy answers False
            return False
    return bool(term.could_extract_minus_sign())
