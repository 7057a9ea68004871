"""solver.math.ode: Dormand–Prince 5(4) against exact solutions and scipy, its continuous extension, the hand-over
of stiff problems to LSODA, failures, and the closed loops the library integrates with it."""
from __future__ import annotations

import numpy as np
import pytest

from solver.math.ode import B, P, solve


def oscillator(t: float, y: np.ndarray) -> np.ndarray:
    return np.array([y[1], -y[0]])


def test_coefficients_are_consistent():
    """Each row of the continuous extension sums to the weight of its stage (y(t + h) is the step's y_new); the
    weights sum to 1 (order 1), Σ bᵢcᵢ = 1/2, Σ bᵢcᵢ² = 1/3 (orders 2, 3)."""
    from solver.math.ode import C
    assert np.allclose(P.sum(axis=1), B, atol=1e-15)
    assert B.sum() == pytest.approx(1.0, abs=1e-15)
    assert B @ C == pytest.approx(1 / 2, abs=1e-15)
    assert B @ C ** 2 == pytest.approx(1 / 3, abs=1e-15)
    assert B @ C ** 4 == pytest.approx(1 / 5, abs=1e-15)


def test_oscillator_matches_the_exact_solution_at_the_requested_times():
    te = np.linspace(0, 10, 101)
    r = solve(oscillator, (0, 10), [1.0, 0.0], t_eval=te, rtol=1e-9, atol=1e-11)
    assert r.success and r.method == "DOPRI5"
    assert np.array_equal(r.t, te)
    assert np.abs(r.y[0] - np.cos(te)).max() < 1e-8
    assert np.abs(r.y[1] + np.sin(te)).max() < 1e-8


def test_continuous_extension_is_fourth_order():
    """Between the steps of a loose tolerance the interpolated values are as accurate as the steps themselves
    (error ≤ 10 × tolerance), and the error falls with the tolerance."""
    te = np.linspace(0, 10, 1001)
    errs = []
    for rtol in (1e-4, 1e-6):
        r = solve(oscillator, (0, 10), [1.0, 0.0], t_eval=te, rtol=rtol, atol=rtol * 1e-2)
        errs.append(np.abs(r.y[0] - np.cos(te)).max())
    assert errs[0] < 10 * 1e-4 * 10 and errs[1] < errs[0] / 20


def test_steps_without_t_eval_and_backwards():
    r = solve(oscillator, (0, 10), [1.0, 0.0], rtol=1e-8, atol=1e-10)
    assert r.t[0] == 0 and r.t[-1] == 10 and np.all(np.diff(r.t) > 0)
    assert np.abs(r.y[0] - np.cos(r.t)).max() < 1e-6
    back = solve(oscillator, (10, 0), [np.cos(10), -np.sin(10)], t_eval=[10, 5, 0], rtol=1e-10, atol=1e-12)
    assert back.success and np.allclose(back.y[0], np.cos([10, 5, 0]), atol=1e-8)


def test_agrees_with_scipy_on_a_nonlinear_pendulum():
    from scipy.integrate import solve_ivp

    def pendulum(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], -9.81 * np.sin(y[0]) - 0.3 * y[1] + np.cos(2 * t)])
    te = np.linspace(0, 8, 81)
    ours = solve(pendulum, (0, 8), [2.5, 0.0], t_eval=te, rtol=1e-10, atol=1e-12)
    ref = solve_ivp(pendulum, (0, 8), [2.5, 0.0], t_eval=te, method="DOP853", rtol=1e-12, atol=1e-14)
    assert np.abs(ours.y - ref.y).max() < 1e-7


def test_stiff_problem_goes_to_lsoda():
    """y' = −1000 (y − cos t): y = (10⁶ cos t + 10³ sin t)/(10⁶ + 1) once the transient has died."""
    r = solve(lambda t, y: -1000 * (y - np.cos(t)), (0, 10), [0.0], t_eval=[5.0, 10.0], rtol=1e-8, atol=1e-10)
    assert r.success and r.method == "LSODA"
    t = np.array([5.0, 10.0])
    exact = (1e6 * np.cos(t) + 1e3 * np.sin(t)) / (1e6 + 1)
    assert np.abs(r.y[0] - exact).max() < 1e-7


def test_blow_up_and_non_finite_states_stop_with_what_was_integrated():
    r = solve(lambda t, y: y * y, (0, 2), [1.0], rtol=1e-8, atol=1e-10)   # y = 1/(1 − t)
    assert not r.success and 0.99 < r.t[-1] < 1.0001 and len(r.t) == r.y.shape[1]
    r = solve(lambda t, y: np.array([np.nan if t > 0.5 else 1.0]), (0, 1), [0.0], t_eval=np.linspace(0, 1, 11))
    assert not r.success and list(r.t) == pytest.approx([0, 0.1, 0.2, 0.3, 0.4])
    assert np.allclose(r.y[0], r.t)


def test_max_step_and_a_zero_span():
    seen: list[float] = []

    def f(t: float, y: np.ndarray) -> np.ndarray:
        seen.append(t)
        return np.zeros(1)
    r = solve(f, (0, 1), [3.0], max_step=0.1)
    assert r.success and np.all(np.diff(r.t) <= 0.1 + 1e-12) and np.all(r.y == 3.0)
    r = solve(f, (2, 2), [1.0], t_eval=[2.0])
    assert r.success and list(r.t) == [2.0] and r.y.shape == (1, 1)


def test_a_budget_raised_by_the_right_hand_side_propagates():
    class Stop(Exception):
        pass

    def f(t: float, y: np.ndarray) -> np.ndarray:
        if t > 0.3:
            raise Stop
        return -y
    with pytest.raises(Stop):
        solve(f, (0, 1), [1.0])
