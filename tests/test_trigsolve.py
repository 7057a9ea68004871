"""trig_factors: the half-tangent factorization computed in a sparse ring gives exactly the factors (and their
order) of the general path through sympy expressions, and they multiply back to the input."""
from __future__ import annotations

import random

import pytest
import sympy as sp

import solver.math.trigsolve as T

q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
a, b, l = sp.symbols("a b l", positive=True)
ATOMS = [sp.cos(q1), sp.sin(q1), sp.cos(q2), sp.sin(q2), sp.cos(q1 + q2), sp.sin(q1 + q2), sp.cos(2 * q1),
         sp.sin(q2) ** 2, sp.cos(q3), a, b, l, sp.Rational(1, 2), 3]


def _cases(n: int, seed: int) -> list[sp.Expr]:
    rng = random.Random(seed)
    out = [sp.expand(l**2 * sp.sin(q2) * (a + b * sp.cos(q2))),             # monomial content in t and in l
           sp.expand((1 - sp.cos(q2)) * (1 + sp.cos(q2))),                   # sin²: factors paired at π
           sp.expand(a * sp.cos(q1) ** 2 / 3 + a * sp.sin(q1) ** 2 / 3)]   # a/3 (rational content)
    while len(out) < n:
        fs = [sum(rng.choice([-2, -1, 1, 2, sp.Rational(1, 3)]) * sp.Mul(*rng.sample(ATOMS, rng.randint(1, 2)))
                  for _ in range(rng.randint(1, 3))) for _ in range(rng.randint(1, 2))]
        e = sp.expand(sp.Mul(*fs))
        if e.free_symbols & {q1, q2, q3}:
            out.append(e)
    return out


@pytest.mark.parametrize("e", _cases(24, 5))
def test_ring_path_equals_general_path(e: sp.Expr, monkeypatch: pytest.MonkeyPatch) -> None:
    fast = T.trig_factors(e)
    const, facs = fast
    assert sp.expand(sp.expand_trig(const * sp.Mul(*[f**k for f, k in facs]) - e)) == 0 or \
        T.tidy(sp.expand(const * sp.Mul(*[f**k for f, k in facs]) - e)) == 0
    monkeypatch.setattr(T, "_half_tangent_numerator", lambda *args: None)
    assert T._trig_factors_uncached(e) == fast  # (trig_factors is memoized: the general path itself)


def test_sin_squared_is_one_factor() -> None:
    const, facs = T.trig_factors(sp.expand(l * (1 - sp.cos(q2) ** 2)))
    assert const * sp.Mul(*[f**k for f, k in facs]) == l * sp.sin(q2) ** 2


def test_spherical_arm_by_squares_of_two_then_three_equations() -> None:
    """Spherical RRP arm (q3 the radius): squaring x, y gives q3² sin²q2 = x² + y², squaring all three gives q3²;
    the same group is not squared again (it once looped until the node budget, and the system was left pending).
    The four families solve f(q) = r at a random reachable target."""
    r = sp.symbols("r1:4", real=True)
    f = [q3 * sp.cos(q1) * sp.sin(q2), q3 * sp.sin(q1) * sp.sin(q2), 1 - q3 * sp.cos(q2)]
    fams = T.Solver([q1, q2, q3], [q3]).solve([fi - ri for fi, ri in zip(f, r)])
    assert len(fams) == 4 and not any(fam.pending for fam in fams)
    methods = [st.method for st in fams[0].stages]
    assert methods.count("squares") == 2 and len(fams[0].stages) == 5
    q0 = {q1: 0.7, q2: 1.1, q3: 0.8}
    target = {ri: float(fi.subs(q0)) for fi, ri in zip(f, r)}
    found = 0
    for fam in fams:
        vals = {x: complex(fam.values[x].subs(target).evalf()) for x in (q1, q2, q3)}
        if any(abs(v.imag) > 1e-9 for v in vals.values()):
            continue
        real = {x: v.real for x, v in vals.items()}
        assert all(abs(float(fi.subs(real)) - target[ri]) < 1e-9 for fi, ri in zip(f, r))
        found += 1
    assert found == 4


def test_trig_factors_and_simple_memoized():
    """trig_factors and _simple's exact numbers are memoized (a problem's asks factor the same determinants and
    simplify the same angles again): a repeated call is a cache hit with the same value, and the caller gets its
    own list of factors (a caller mutating it leaves the memo intact)."""
    from solver.math import trigsolve as ts
    q1, q2, a, b = sp.symbols("q1 q2 a b", real=True)
    e = a * b * sp.sin(q2) * (a * sp.cos(q1) + 2 * b * sp.cos(q1 + q2))
    first = ts.trig_factors(e)
    hits = ts._trig_factors.cache_info().hits
    first[1].append((q1, 9))
    again = ts.trig_factors(e)
    assert ts._trig_factors.cache_info().hits == hits + 1
    assert again == ts._trig_factors_uncached(e)
    assert (q1, 9) not in again[1]
    v = sp.atan2(-sp.sqrt(3) / 2, sp.Rational(1, 2)) + 2 * sp.pi
    hits = ts._simple_exact.cache_info().hits
    assert ts._simple(v) == ts._simple(v) == sp.nsimplify(sp.simplify(v), [sp.pi]) == 5 * sp.pi / 3
    assert ts._simple_exact.cache_info().hits == hits + 1
    assert ts._simple(sp.Float(0.25) + sp.pi) == sp.Float(float(sp.N(sp.pi)) + 0.25, 15)


def _sympy_terms(e: sp.Expr, angles: list) -> dict:
    """The terms of sp.expand(sp.expand_trig(e)) keyed by their exponents (the general path's reading)."""
    gens = [sp.cos(x) for x in angles] + [sp.sin(x) for x in angles]
    params = sorted(e.free_symbols - set(angles), key=lambda s: s.name)
    return sp.Poly(sp.expand(sp.expand_trig(e)), *gens, *params).as_dict()


def test_expanded_terms_equal_sympys_expansion():
    """_expanded_terms (the half-tangent factorization's input, multiplied out in a ring) gives the terms of
    sp.expand(sp.expand_trig(e)) exactly: sympy's multiple-angle conventions (sin 3x = 3 sin x − 4 sin³ x, sin 4x =
    −cos x (8 sin³ x − 4 sin x)), negative multiples, sums of angles, products and powers; None (the sympy path)
    for a constant in an argument, a half angle, a float, a symbol in a denominator, an angle outside sin/cos."""
    a, b, x, y, z = sp.symbols("a b x y z", real=True)
    angles = [x, y, z]
    cases = [sp.sin(3 * x) * a - b * sp.cos(2 * y - x) ** 2,
             sp.sin(4 * x - 3 * y + z) + a * b * sp.cos(-2 * x + y) * sp.sin(2 * z),
             sp.Rational(3, 2) * a**2 * sp.cos(x + y) * sp.sin(x - y) - sp.cos(5 * z) + 7,
             (a * sp.sin(x) + b * sp.cos(x + 2 * z)) ** 3 - sp.sin(-3 * y) * sp.sin(-4 * y)]
    for e in cases:
        terms = T._expanded_terms(e, angles)
        params = sorted(e.free_symbols - set(angles), key=lambda s: s.name)
        got = {tuple(ca) + tuple(sb) + tuple(o.get(s, 0) for s in params): c for c, ca, sb, o in terms}
        assert got == _sympy_terms(e, angles)
    for e in (sp.sin(x + 1) * a, sp.cos(x / 2) + a, sp.Float(0.5) * sp.sin(x), sp.sin(x) / a, x * sp.cos(x)):
        assert T._expanded_terms(e, angles) is None
    e = a * sp.sin(y) * (b * sp.cos(2 * x) + a * sp.cos(x + y))  # the numerator's factors through either path
    ts = [sp.Dummy("t_x"), sp.Dummy("t_y")]
    assert T._half_tangent_numerator(None, [x, y], ts, T._expanded_terms(e, [x, y])) == \
        T._half_tangent_numerator(sp.expand(sp.expand_trig(e)), [x, y], ts)


def test_half_tangent_numerator_factored_by_gcds(monkeypatch: pytest.MonkeyPatch) -> None:
    """The numerator N(t) is factored by fourier.factor_list_fast (gcds where it is linear in a generator), not
    sympy's dense factorization: the same factors as the general path (sp.factor_list of together's numerator)."""
    e = sp.expand(l * (a + b * sp.cos(q2)) * (sp.sin(q1) + 2 * sp.cos(q1 + q2)) * sp.sin(q2))
    with monkeypatch.context() as m:
        m.setattr(T, "_half_tangent_numerator", lambda *args: None)
        want = T._trig_factors_uncached(e)

    def refuse(*args: object, **kw: object) -> None:
        raise AssertionError("sympy's Poly.factor_list called")
    monkeypatch.setattr(sp.Poly, "factor_list", refuse)
    assert T._trig_factors_uncached(e) == want
