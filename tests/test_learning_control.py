"""The `learning_control` ask: the lifted model against a direct simulation, convergence when |1 − γCB| < 1 and
divergence when not, the iteration bound, and the report."""
import numpy as np
import pytest
from conftest import error_found_without_solving

from solver.control.learning_control import free_response, lifted, run_ilc
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem_text

A = np.array([[0.9, 0.2], [-0.1, 0.7]])
B = np.array([[0.0], [1.0]])
C = np.array([[1.0, 0.5]])


def simulate(u, x0, N):
    x, ys = x0.copy(), []
    for t in range(N):
        x = A @ x + B[:, 0] * u[t]
        ys.append((C @ x).item())
    return np.array(ys)


def test_lifted_model_matches_simulation():
    rng = np.random.default_rng(0)
    N = 15
    u, x0 = rng.normal(size=N), rng.normal(size=2)
    G = lifted(A, B, C, N)
    assert np.allclose(G @ u + free_response(A, C, x0, N), simulate(u, x0, N))


@pytest.mark.parametrize("gamma,ok", [(1.0, True), (3.0, True), (4.5, False), (-0.5, False)])
def test_convergence_condition_in_simulation(gamma, ok):
    N = 20
    cb = (C @ B).item()  # 0.5: converges iff 0 < gamma < 4
    assert (abs(1 - gamma * cb) < 1) == ok
    G = lifted(A, B, C, N)
    yd = np.sin(np.linspace(0.3, 3, N))
    errs = run_ilc(G, np.zeros(N), yd, gamma * np.eye(N), 300)
    if ok:
        assert errs[-1] < 1e-3 * errs[0]
    else:
        assert errs[-1] > errs[0]


SPEC = """
id: t
title: ilc
symbols: {t: {meaning: sample index, sign: real}}
asks:
  - kind: learning_control
    A: [[0.9, 0.2], [-0.1, 0.7]]
    B: [0, 1]
    C: [[1, 0.5]]
    horizon: 20
    reference: sin(t/5)
    gain: {g}
    epsilon: 0.001
    iterations: 60
"""


def test_ask_bound_holds_and_report():
    p = load_problem_text(SPEC.replace("{g}", "1.5"))
    sols = solve_problem(p)
    res = all_results(sols)
    assert res["converges"].value is True
    errs = sols[0].steps[0].data["errs"]
    if "iterations_bound" in res:
        k = int(res["iterations_bound"].value)
        assert errs[k] <= 1e-3 + 1e-12
        assert int(res["iterations_actual"].value) <= k
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "learning converges" in md and "learning converges" in tex
    assert len(sols[0].figures[0].panels[0].curves[0].y) == 61


def test_ask_divergent_gain():
    res = all_results(solve_problem(load_problem_text(SPEC.replace("{g}", "5"))))
    assert res["converges"].value is False and "iterations_bound" not in res


@pytest.mark.parametrize("old, new, words", [
    ("    gain: {g}\n", "    gain: a\n", "gain: a number is needed (give values: for a)"),
    ("    reference: sin(t/5)\n", "    reference: [1, 2]\n", "reference: 20 values expected"),
    ("    epsilon: 0.001\n", "    epsilon: a\n", "epsilon: a number is needed"),
], ids=["gain", "reference", "epsilon"])
def test_a_symbol_left_in_a_number_is_a_spec_error(old, new, words):
    """The gain, the reference and ε are numbers: a symbol without a value was an internal error (float() of a
    symbol, a traceback); it is a spec error at its line, found by `check` (the validate hook) as by solving."""
    text = SPEC.replace("symbols: {t:", "symbols: {a: a gain, t:").replace(old, new).replace("{g}", "0.5")
    assert words in error_found_without_solving(text)
