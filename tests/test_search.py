"""Golden-section search (solver.math.search), which replaced scipy's bounded minimize_scalar."""
from __future__ import annotations

import math

import numpy as np

import pytest

from solver.math.search import golden_min


@pytest.mark.parametrize("x0", [0.3, 0.0001, 0.9999, 0.5])
def test_golden_min_finds_the_minimum_of_a_unimodal_function(x0: float) -> None:
    x, fx = golden_min(lambda x: (x - x0) ** 2 + 1.0, 0.0, 1.0, 1e-12)
    assert abs(x - x0) < 1e-6 and abs(fx - 1.0) < 1e-12


def test_golden_min_at_an_end_and_on_a_grid_cell() -> None:
    x, fx = golden_min(lambda x: x, 2.0, 3.0, 1e-12)          # monotone: the left end
    assert x == 2.0 and fx == 2.0
    # |sin| on a cell around its peak (the use in planning.laws: maximize |q(t)| near the best grid sample)
    x, fx = golden_min(lambda t: -abs(math.sin(t)), 1.5, 1.65, 1e-12)
    assert abs(x - math.pi / 2) < 1e-6 and abs(fx + 1.0) < 1e-12


# ---------------------------------------------------------------------------------------------- lp_max
def test_lp_max_small_programs_by_hand():
    from fractions import Fraction as Fr

    from solver.math.search import lp_max
    # max x + y, x + 2y <= 4, 3x + y <= 6: the vertex (8/5, 6/5)
    assert lp_max([1, 1], [[1, 2], [3, 1]], [4, 6]) == (0, [Fr(8, 5), Fr(6, 5)])
    # a negative right-hand side (phase one): x >= 1 written -x <= -1, with x <= 3
    assert lp_max([1], [[-1], [1]], [-1, 3]) == (0, [Fr(3)])
    assert lp_max([-1], [[-1], [1]], [-1, 3]) == (0, [Fr(1)])  # the least x is 1, not 0
    assert lp_max([1], [[-1], [1]], [-3, 2])[0] == 2             # x >= 3 and x <= 2: infeasible
    assert lp_max([1, 0], [[0, 1]], [1])[0] == 3                 # x free of any bound: unbounded
    assert lp_max([0, 1], [[1, 1], [-1, -1]], [1, -1]) == (0, [Fr(0), Fr(1)])  # x + y = 1 (degenerate)
    with pytest.raises(ValueError):
        lp_max([1], [[float("nan")]], [1])


@pytest.mark.parametrize("seed", range(40))
def test_lp_max_agrees_with_highs(seed):
    """The optimum of random programs (feasible, infeasible and unbounded ones) equals scipy's HiGHS."""
    from scipy.optimize import linprog

    from solver.math.search import lp_max
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 5)), int(rng.integers(1, 9))
    A = rng.integers(-5, 6, size=(m, n)).astype(float)
    b = rng.integers(-4, 10, size=m).astype(float)
    c = rng.integers(-3, 4, size=n).astype(float)
    status, x = lp_max(c.tolist(), A.tolist(), b.tolist())
    res = linprog(-c, A_ub=A, b_ub=b, bounds=[(0, None)] * n, method="highs")
    assert status == res.status
    if status == 0:
        xv = np.array([float(v) for v in x])
        assert np.all(A @ xv <= b + 1e-12) and np.all(xv >= 0)
        assert c @ xv == pytest.approx(-res.fun, abs=1e-9)


# ------------------------------------------------------------------------------------------ pattern_max
def test_pattern_max_smooth_bounded_and_kinked():
    from solver.math.search import pattern_max

    def f(p):  # a smooth bump with its top at (0.3, -0.7)
        return 2 - (p[:, 0] - 0.3) ** 2 - 3 * (p[:, 1] + 0.7) ** 2 + 0.5 * (p[:, 0] - 0.3) * (p[:, 1] + 0.7)
    inf = np.inf
    x, v = pattern_max(f, np.array([0.0, 0.0]), np.array([0.5, 0.5]), np.array([-inf, -inf]), np.array([inf, inf]))
    assert np.allclose(x, [0.3, -0.7], atol=1e-8) and v == pytest.approx(2, abs=1e-14)
    # the same top outside the box: the maximum is on its edge y = -0.5, at x solving ∂f/∂x = 0 there
    x, v = pattern_max(f, np.array([0.0, 0.0]), np.array([0.5, 0.5]), np.array([-1, -0.5]), np.array([1, 1]))
    assert x[1] == -0.5 and x[0] == pytest.approx(0.35, abs=1e-8)  # -2 (x - 0.3) + 0.5 (0.2) = 0

    def kink(p):  # max of two planes' minimum: a ridge along x = y, top at (1, 1) in [0, 1]^2
        return np.minimum(p[:, 0], p[:, 1])
    x, v = pattern_max(kink, np.array([0.2, 0.6]), np.array([0.25, 0.25]), np.zeros(2), np.ones(2))
    assert v == pytest.approx(1, abs=1e-9)
    # six coordinates (axis directions only): a separable concave function
    x, v = pattern_max(lambda p: -np.sum((p - np.arange(6)) ** 2, axis=1), np.zeros(6), np.ones(6),
                       np.full(6, -inf), np.full(6, inf))
    assert np.allclose(x, np.arange(6), atol=1e-8)


# ------------------------------------------------------------------------------------------ bisect_root
@pytest.mark.parametrize("f, a, b, z", [
    (lambda x: x * x - 2, 0.0, 3.0, math.sqrt(2)),
    (lambda x: math.cos(x), 1.0, 2.0, math.pi / 2),
    (lambda x: (x - 0.1) ** 3, -1.0, 1.0, 0.1),       # a triple zero: no derivative to follow
    (lambda x: 1e-300 * (x - 5), 0.0, 7.0, 5.0),      # tiny values keep their signs
])
def test_bisect_root_to_adjacent_doubles(f, a, b, z):
    from solver.math.search import bisect_root
    x = bisect_root(f, a, b)
    assert abs(x - z) <= 4 * math.ulp(z) + (1e-5 if z == 0.1 else 0)


# ------------------------------------------------------------------------------------------ newton_root
def test_newton_root_two_equations_and_a_damped_start():
    """x² + y² = 4, x = y from (3, 0.5): (√2, √2); a pendulum's equilibrium m g l sin q + k q = u, started far
    away (the damping keeps ‖f‖ decreasing), equals the bracketed root."""
    from solver.math.search import bisect_root, newton_root
    x = newton_root(lambda z: np.array([z[0] ** 2 + z[1] ** 2 - 4, z[0] - z[1]]),
                    lambda z: np.array([[2 * z[0], 2 * z[1]], [1.0, -1.0]]), np.array([3.0, 0.5]))
    assert np.allclose(x, [math.sqrt(2), math.sqrt(2)], atol=1e-14)

    def f(z):
        return np.array([9.81 * math.sin(z[0]) + 20 * z[0] - 7.0])
    z = newton_root(f, lambda z: np.array([[9.81 * math.cos(z[0]) + 20]]), np.array([4.0]))
    assert abs(f(z)[0]) < 1e-12
    assert z[0] == pytest.approx(bisect_root(lambda t: f(np.array([t]))[0], 0.0, 1.0), abs=1e-14)
    # a singular Jacobian at the start (f = z² − 1 from z = 0, where J = 0): least squares, no exception
    z = newton_root(lambda z: np.array([z[0] ** 2 - 1]), lambda z: np.array([[2 * z[0]]]), np.array([0.0]))
    assert z.shape == (1,)


# --------------------------------------------------------------------------- gravity_bound.maximize (grid + refine)
def test_maximize_refines_off_the_grid_periodic_and_random_modes():
    """The grid's best points refined by pattern_max: a periodic maximum between grid angles (q = 0.4321, on no
    multiple of π/12), a bounded one on an edge, and seven coordinates (random samples) with the top at 0.3·i."""
    from solver.control.gravity_bound import maximize
    pi = math.pi

    def f(p):  # periodic in q1, q2: top where cos(q1 − 0.4321) = 1 and cos(2(q2 + 1)) = 1
        return np.cos(p[:, 0] - 0.4321) + 0.5 * np.cos(2 * (p[:, 1] + 1.0))
    v, x = maximize(f, [(-pi, pi), (-pi, pi)], [True, True])
    assert v == pytest.approx(1.5, abs=1e-12)
    assert math.cos(x[0] - 0.4321) == pytest.approx(1, abs=1e-12) and math.cos(2 * (x[1] + 1)) == pytest.approx(1, abs=1e-12)
    v, x = maximize(lambda p: -(p[:, 0] - 3.0) ** 2, [(0.0, 2.0)], [False])  # the top outside: the edge x = 2
    assert x[0] == 2.0 and v == -1.0                                          # (a negative maximum)
    with np.errstate(invalid="ignore"):  # undefined (NaN) on half the box: never the maximum
        v, x = maximize(lambda p: np.sqrt(p[:, 0]) - p[:, 0], [(-1.0, 1.0)], [False])
    assert v == pytest.approx(0.25, abs=1e-12) and x[0] == pytest.approx(0.25, abs=1e-6)
    top = 0.3 * np.arange(1, 8)
    v, x = maximize(lambda p: -np.sum((p - top) ** 2, axis=1), [(0.0, 3.0)] * 7, [False] * 7)
    assert v == pytest.approx(0, abs=1e-12) and np.allclose(x, top, atol=1e-6)


def test_newton_roots_batched_equals_one_by_one():
    """Every start at once gives the end points of newton_root started one by one (a circle and a line, starts
    on a grid, some far or on the singular point of the Jacobian)."""
    from solver.math.search import newton_root, newton_roots

    def f(z):
        return np.array([z[0] ** 2 + z[1] ** 2 - 4, z[0] - 2 * z[1] + 1])

    def jac(z):
        return np.array([[2 * z[0], 2 * z[1]], [1.0, -2.0]])
    starts = np.array([[a, b] for a in np.linspace(-5, 5, 7) for b in np.linspace(-5, 5, 7)] + [[0.0, 0.0]])
    batch = newton_roots(lambda X: np.stack([f(x) for x in X]), lambda X: np.stack([jac(x) for x in X]), starts)
    single = np.array([newton_root(f, jac, x) for x in starts])
    assert np.allclose(batch, single, atol=1e-12, equal_nan=True)
    ok = [x for x in batch if np.max(np.abs(f(x))) < 1e-12]
    assert len(ok) >= 0.8 * len(starts)  # (a start may stop where the Newton step cannot decrease ‖f‖)
    roots = {tuple(np.round(x, 9)) for x in ok}
    assert len(roots) == 2 and all(abs(a - 2 * b + 1) < 1e-8 for a, b in roots)


def test_find_equilibria_of_a_2r_and_a_3r_without_scipy():
    """The zeros of φ(q) = g(q) − K_P (q_d − q) for a 2R under gravity with a weak K_P (five equilibria) and a 3R
    (three): each a zero to 1e-9, pairwise distinct; the search imports no scipy.optimize."""
    import subprocess
    import sys
    code = """
import sys, numpy as np, sympy as sp
from solver.control.regulation import find_equilibria
q1, q2, q3 = sp.symbols('q1 q2 q3', real=True)
g2 = sp.Matrix([30*sp.cos(q1) + 10*sp.cos(q1 + q2), 10*sp.cos(q1 + q2)])
phi2 = g2 - 5*sp.Matrix([0.5 - q1, 0.3 - q2])
g3 = sp.Matrix([20*sp.cos(q1) + 8*sp.cos(q1+q2) + 2*sp.cos(q1+q2+q3), 8*sp.cos(q1+q2) + 2*sp.cos(q1+q2+q3),
                2*sp.cos(q1+q2+q3)])
phi3 = g3 - 6*sp.Matrix([0.2 - q1, 0.1 - q2, -0.3 - q3])
out = []
for phi, q in ((phi2, [q1, q2]), (phi3, [q1, q2, q3])):
    sols = find_equilibria(phi, q, [(-np.pi, np.pi)] * len(q), [True] * len(q))
    f = sp.lambdify(q, list(phi))
    shifts = [np.array(k) * 2 * np.pi for k in __import__('itertools').product((-1, 0, 1), repeat=len(q))]
    assert all(min(max(abs(v) for v in f(*(s + k))) for k in shifts) < 1e-9 for s in sols)  # (q wrapped)
    assert all(np.max(np.abs(a - b)) > 1e-3 for i, a in enumerate(sols) for b in sols[:i])
    out.append(len(sols))
print(out, 'scipy.optimize' in sys.modules)
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                       cwd=str(__import__("pathlib").Path(__file__).resolve().parent.parent))
    assert r.stdout.split("\n")[0] == "[5, 3] False", r.stdout + r.stderr
