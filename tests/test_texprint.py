"""The LaTeX printed directly (solver.publish.texprint) is the reports' printer's (render._Printer: sympy's
LatexPrinter with the teacher's order of factors), character for character."""
from __future__ import annotations

import random

import sympy as sp

from solver.publish.render import Latex, _Printer
from solver.publish.texprint import DirectLatex, negative

q1, q2, q3, m1, l1, dq1, dq2, I3, a, b = sp.symbols("q1 q2 q3 m1 l1 dq1 dq2 I3 a b")
SYMS = [q1, q2, q3, m1, l1, dq1, dq2, I3, a, b]
NAMES = {dq1: r"\dot{q}_{1}", dq2: r"\dot{q}_{2}", I3: r"I_{3}", a: r"a^{\ast}", b: "2b"}
RANK = {q1: 2, q2: 2, q3: 2, dq1: 3, dq2: 3}


def _random_expr(rng: random.Random, depth: int = 0) -> sp.Expr:
    """Sums of products of symbols, numbers, sin/cos of sums and multiples, sums and their powers (positive,
    negative, fractional), rational coefficients, products kept unevaluated as the simplifier writes them
    (2 (q₃ − d)): nested up to three levels."""
    def factor() -> sp.Expr:
        kind = rng.random()
        if kind < 0.4 or depth >= 2:
            return rng.choice(SYMS)
        if kind < 0.7:
            arg = sp.Add(*[rng.choice([-2, -1, 1, 1, 2]) * rng.choice(SYMS[:3]) for _ in range(rng.randint(1, 3))])
            arg = rng.choice([arg, 2 * q1, q1 * q2, q1**2, sp.sin(q1) * q2, arg])
            return rng.choice([sp.sin, sp.cos])(arg if arg != 0 else q1)
        if kind < 0.75:
            return rng.choice([sp.sqrt(2), sp.sqrt(q1), 1 / (q1 + l1), sp.Rational(1, 2)])
        if kind < 0.8:
            return sp.Mul(rng.choice([2, -2, 3, -1]), _random_expr(rng, depth + 1), evaluate=False)
        return _random_expr(rng, depth + 1)

    terms = []
    for _ in range(rng.randint(1, 6)):
        c = sp.Rational(rng.choice([-7, -3, -1, 1, 1, 2, 5, 10]), rng.choice([1, 1, 1, 2, 3]))
        terms.append(c * sp.Mul(*[factor() ** rng.choice([1, 1, 1, 2, 3, 4]) for _ in range(rng.randint(0, 4))]))
    return sp.Add(*terms)


def _wired() -> tuple[_Printer, DirectLatex]:
    """A printer that hands plain subexpressions to its direct printer, which hands it the rest (as Latex)."""
    printer = _Printer(NAMES, RANK)
    direct = printer.direct = DirectLatex(printer)
    return printer, direct


def test_direct_latex_is_the_printers_on_random_expressions() -> None:
    rng = random.Random("texprint")
    checked = 0
    for k in range(600):
        e = _random_expr(rng)
        ref = _Printer(NAMES, RANK).doprint(e)  # (a fresh printer each: no memo shared with the direct one)
        assert DirectLatex(_Printer(NAMES, RANK)).doprint(e) == ref, e
        printer, direct = _wired()
        assert direct.doprint(e) == ref, e
        checked += e.is_Add or e.is_Mul
    assert checked > 400


def test_negative_is_could_extract_minus_sign() -> None:
    rng = random.Random("negative")
    seen = set()
    for _ in range(400):
        for t in sp.Add.make_args(_random_expr(rng)) + (-sp.zoo * q1, sp.Mul(-1, q1 + l1, evaluate=False)):
            assert negative(t) == t.could_extract_minus_sign(), t
            seen.add((type(t).__name__, negative(t)))
    assert {("Mul", True), ("Mul", False)} <= seen


def test_the_printer_with_its_direct_printer_on_other_expressions() -> None:
    """Expressions outside the direct printer (floats, exp, sqrt, fractions, matrices): the printer wired to it
    writes what it writes alone, the plain subexpressions printed directly."""
    rng = random.Random("texprint-wired")
    for k in range(200):
        e = _random_expr(rng)
        e = rng.choice([e * sp.Float("0.25"), sp.exp(e) + q1, e / (q1 + l1 * q2), sp.sqrt(e) * m1,
                        sp.Matrix([[e, q1], [0, e + 1]]), sp.Eq(e, q1)])
        printer, _ = _wired()
        assert printer.doprint(e) == _Printer(NAMES, RANK).doprint(e), e


def test_direct_latex_on_a_model_entry() -> None:
    """An entry of a 2R's inertia matrix and Coriolis vector as the reports write them: parameters, sums,
    velocities, functions; a sum inside a product in stored order."""
    d2, m2, l2 = sp.symbols("d2 m2 l2")
    lx = Latex(NAMES, RANK)
    e = 2 * d2 * l1 * m2 * sp.cos(q2) + d2**2 * m2 + l1**2 * m2 + I3
    assert lx(e) == r"I_{3} + d_{2}^{2} m_{2} + 2 d_{2} l_{1} m_{2} \cos {q_{2}} + l_{1}^{2} m_{2}"
    c = -d2 * l1 * m2 * dq2 * (2 * dq1 + dq2) * sp.sin(q2 + q1)
    assert lx(c) == (r"- d_{2} l_{1} m_{2} \left(\dot{q}_{2} + 2 \dot{q}_{1}\right) \dot{q}_{2} "
                     r"\sin{\left(q_{1} + q_{2} \right)}")


def test_direct_latex_of_products_with_a_fraction() -> None:
    """Products with a rational coefficient, as the spatial arms' models have them (m a²/8, -(I_xx - I_yy)/2 s c),
    written \\frac{p f₁⋯f_k}{q} directly; a sum over a number is left to the printer."""
    cases = [sp.Rational(3, 8) * a**2 * m1, -a / 2, sp.Rational(-1, 4) * sp.sin(q1) * sp.cos(q2) * dq1,
             sp.Rational(5, 3) * sp.cos(q1 + q2) ** 2, sp.Mul(sp.Rational(1, 2), a + l1, evaluate=False),
             sp.Rational(1, 2) * (a + l1) ** 2 * dq2, sp.Rational(7, 2) * b * (q1 - q2) * l1,
             I3 * dq1**2 / 2 + sp.Rational(3, 4) * m1 * l1**2 * dq1 * dq2 - a * b / 6]
    for e in cases:
        ref = _Printer(NAMES, RANK).doprint(e)
        assert DirectLatex(_Printer(NAMES, RANK)).doprint(e) == ref, e
        printer, direct = _wired()
        assert direct.doprint(e) == ref, e
    assert DirectLatex(_Printer(NAMES, RANK)).doprint(cases[0]) == r"\frac{3 \left(a^{\ast}\right)^{2} m_{1}}{8}"
    assert DirectLatex(_Printer(NAMES, RANK)).doprint(cases[1]) == r"- \frac{a^{\ast}}{2}"
