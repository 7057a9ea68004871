"""The memoized operation count equals sympy's count_ops on random expressions of every node kind it handles."""
import random

import sympy as sp

from solver.math.opcount import count_ops

x, y, z, q = sp.symbols("x y z q")
ATOMS = [x, y, z, sp.Integer(2), sp.Rational(-3, 4), sp.Integer(-1), sp.sin(q), sp.cos(2 * q), sp.sqrt(2), sp.pi,
         sp.Float(1.5), sp.exp(x), sp.E, sp.I]


def _random_expr(rng: random.Random, depth: int) -> sp.Expr:
    if depth == 0:
        return rng.choice(ATOMS)
    a, b = _random_expr(rng, depth - 1), _random_expr(rng, depth - 1)
    op = rng.choice(["add", "sub", "mul", "pow", "neg", "div", "sin"])
    if op == "add":
        return a + b
    if op == "sub":
        return a - b
    if op == "mul":
        return a * b
    if op == "pow":
        return a ** rng.choice([2, 3, -1, -2, sp.Rational(1, 2), sp.Rational(-3, 2)])
    if op == "neg":
        return -a
    if op == "div":
        return a / b if b != 0 else a
    return sp.sin(a)


def test_equals_sympy_count_ops() -> None:
    rng = random.Random(7)
    exprs = [_random_expr(rng, rng.randint(1, 5)) for _ in range(3000)]
    assert all(count_ops(e) == sp.count_ops(e) for e in exprs)
    # the forms factor_terms and factor print: unevaluated −(a + b), 2(a + b), where sympy counts no ADD under −
    forms = [sp.factor_terms(e) for e in exprs[:600]] + [sp.factor(e) for e in exprs[:300] if not e.has(sp.Float)]
    assert all(count_ops(f) == sp.count_ops(f) for f in forms)
    assert count_ops(-x - y) == sp.count_ops(-x - y) == 2            # NEG + SUB
    assert count_ops(-sp.Rational(1, 3) * x) == sp.count_ops(-x / 3) == 2
    minus = sp.Mul(-1, x + 1 / y, evaluate=False)
    assert count_ops(minus) == sp.count_ops(minus) == 2                 # NEG, DIV: sympy counts no ADD under −


def test_products_with_a_fraction_counted_as_sympy_does() -> None:
    """p/q·f₁⋯f_k counted without building sympy's fraction (the spatial arms' coefficients): the same integer,
    including a single sum, which sympy's fraction distributes (3/4·(a + b) -> 3a + 3b)."""
    cases = [sp.Rational(3, 8) * x**2 * y, -x * y / 2, sp.Rational(-5, 4) * sp.sin(q) * sp.cos(q) ** 2 * z,
             sp.Mul(sp.Rational(3, 4), x + y, evaluate=False), sp.Mul(sp.Rational(1, 2), x + y, evaluate=False),
             sp.Mul(sp.Rational(3, 4), x + y, z, evaluate=False), sp.Rational(7, 3) * (x + 2 * y) ** 2 * z,
             x / 2, sp.Rational(-1, 2) * sp.cos(2 * q)]
    assert [count_ops(e) for e in cases] == [sp.count_ops(e) for e in cases]
