"""The `minimum_norm` ask: each solution realizes the task, is optimal for its objective (scipy minimize on the
task manifold and the Lagrange conditions), the bounds and the feasible task fraction; on a planar 3R in a vertical
plane that no exercise uses."""
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import error_found_without_solving
from scipy.optimize import minimize

from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem_text
from solver.spec.errors import UserError

ROBOT = """
id: mn3
title: planar 3R in a vertical plane
symbols: {g0: gravity}
values: {g0: 9.81}
robot:
  joints: [R, R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: 3, com: [cos(q1)/2, sin(q1)/2], angle: q1, inertia: 1/4}
    - {mass: 2, com: [cos(q1) + cos(q1+q2)/2, sin(q1) + sin(q1+q2)/2], angle: q1+q2, inertia: 1/6}
    - {mass: 1, com: [cos(q1) + cos(q1+q2) + cos(q1+q2+q3)/2, sin(q1) + sin(q1+q2) + sin(q1+q2+q3)/2],
       angle: q1+q2+q3, inertia: 1/12}
asks:
  - kind: minimum_norm
    task: [cos(q1) + cos(q1+q2) + cos(q1+q2+q3), sin(q1) + sin(q1+q2) + sin(q1+q2+q3)]
    at: {q1: 0.3, q2: 0.8, q3: -0.5}
    joint_velocity: [0.5, -0.2, 0.4]
    acceleration: [1, -2]
    objectives: [acceleration, inertia, torque, weighted_torque]
    weight: [1, 4, 9]
"""


def arr(v) -> np.ndarray:
    return np.array(sp.Matrix(v).evalf().tolist(), dtype=float)


CASES = {"gravity dominates": ("9.81", [45, 30, 4]), "bounds bite on the task": ("1", [8, 1.7, 1.4])}


@pytest.fixture(scope="module", params=list(CASES))
def solved(request):
    g, hi = CASES[request.param]
    base = ROBOT.replace("values: {g0: 9.81}", f"values: {{g0: {g}}}") + f"    bounds: {hi}\n"
    p = load_problem_text(base)
    sols = solve_problem(p)
    return p, sols, all_results(sols), base, np.array(hi)


def test_task_realized_and_optimal(solved):
    _, _, r, _, _ = solved
    B, n, J = arr(r["B_at"].value), arr(r["n_at"].value).ravel(), arr(r["J_at"].value)
    x = np.array([1, -2]) - arr(r["Jdot_qdot"].value).ravel()
    W = np.diag([1, 4, 9])
    objectives = {"acc": lambda a: 0.5 * a @ a, "kin": lambda a: 0.5 * a @ B @ a,
                  "tau": lambda a: 0.5 * (B @ a + n) @ (B @ a + n),
                  "tauW": lambda a: 0.5 * (B @ a + n) @ W @ (B @ a + n)}
    for k, H in objectives.items():
        qdd = arr(r[f"qddot_{k}"].value).ravel()
        tau = arr(r[f"tau_{k}"].value).ravel()
        assert np.allclose(J @ qdd, x, atol=1e-9)  # the task acceleration is realized
        assert np.allclose(B @ qdd + n, tau, atol=1e-9)  # consistent with the model
        best = minimize(H, np.zeros(3), constraints=[{"type": "eq", "fun": lambda a: J @ a - x}],
                        method="SLSQP", options={"ftol": 1e-14, "maxiter": 500})
        assert np.allclose(qdd, best.x, atol=1e-5), k
        for other in objectives:  # each is the smallest in its own objective
            qo = arr(r[f"qddot_{other}"].value).ravel()
            assert H(qdd) <= H(qo) + 1e-9
    # Lagrange condition of min ½‖τ‖²: Bᵀτ ∈ range(Jᵀ)
    tau = arr(r["tau_tau"].value).ravel()
    lam = np.linalg.lstsq(J.T, B.T @ tau, rcond=None)[0]
    assert np.allclose(J.T @ lam, B.T @ tau, atol=1e-8)


def test_bounds_and_task_fraction(solved):
    _, _, r, base, hi = solved
    h = arr(r["Jdot_qdot"].value).ravel()
    x = np.array([1, -2]) - h
    scaled = {}
    for k in ("acc", "kin", "tau", "tauW"):
        tau = arr(r[f"tau_{k}"].value).ravel()
        assert bool(r[f"within_{k}"].value) == bool(np.all(np.abs(tau) <= hi + 1e-9))
        if f"scale_{k}" not in r:  # no fraction of the task in [0, 1] is feasible: check s = 0, 1/2, 1
            scaled[k] = None
            continue
        s = float(r[f"scale_{k}"].value)
        assert 0 <= s <= 1 and (s == 1) == bool(r[f"within_{k}"].value)
        scaled[k] = s
    assert any(s is None or s < 1 for s in scaled.values())  # the bounds bite (else the test proves nothing)
    for k, s in scaled.items():
        if s == 1:
            continue
        checks = [(s, True), (min(1.0, s + 1e-3), False)] if s is not None else \
            [(0.0, False), (0.5, False), (1.0, False)]
        for f, inside in checks:
            a = f * x + h  # the task acceleration whose x is f times the original one
            text = base.replace("acceleration: [1, -2]", f"acceleration: [{float(a[0])!r}, {float(a[1])!r}]")
            tau = arr(all_results(solve_problem(load_problem_text(text)))[f"tau_{k}"].value).ravel()
            assert bool(np.all(np.abs(tau) <= hi + 1e-7)) == inside, (k, f)


def test_render_both_formats(solved):
    p, sols, _, _, _ = solved
    md = render(p, sols, "md")
    assert "**Comparison.**" in md and "Minimizing" in md
    assert "Comparison" in render(p, sols, "tex")


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="LaTeX not installed")
def test_numeric_report_compiles(solved, tmp_path):
    """The LaTeX of the numeric solutions compiles (its per-objective lines once had unbalanced braces)."""
    p, sols, _, _, _ = solved
    (tmp_path / "m.tex").write_text(render(p, sols, "tex"))
    res = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "m.tex"], cwd=tmp_path,
                         capture_output=True, timeout=120)
    assert res.returncode == 0, res.stdout.decode(errors="replace")[-2000:]


SINGULAR = """
id: mn-sing
title: PR robot where the task Jacobian vanishes
symbols: {g0: gravity}
values: {g0: 9.81}
robot:
  joints: [P, R]
  gravity: [0, -g0]
  links:
    - {mass: 2, com: [q1, 0]}
    - {mass: 3/2, com: [q1 + 2/5*cos(q2), 2/5*sin(q2)], angle: q2, inertia: 1/10}
asks:
  - kind: minimum_norm
    task: 4/5*sin(q2)
    acceleration: [1]
    at: {q1: 1/5, q2: pi/2}
    joint_velocity: [3/10, 2]
    objectives: [acceleration, torque]
    bounds: [5, 5]
"""


def test_singular_state_reports_the_task_error_not_a_fraction():
    """At q2 = π/2, J = 0: the least-squares solutions are q̈ = 0 and miss x = r̈_d - J̇q̇ = 1 + 16/5 entirely;
    the report gives that error and no task fraction s (the task is not realized at any scale)."""
    p = load_problem_text(SINGULAR)
    sols = solve_problem(p)
    r = all_results(sols)
    for k in ("acc", "tau"):
        assert r[f"err_{k}"].value == sp.Matrix([sp.Rational(-21, 5)])
        assert f"scale_{k}" not in r
    md = render(p, sols, "md")
    assert "the configuration is singular" in md and "The task acceleration is not realized" in md
    assert "$J\\ddot q - x$" in md and "| yes | — |" in md
    tex = render(p, sols, "tex")
    assert "---" in tex and "\\textbf{The task acceleration is not realized}" in tex


def test_errors():
    with pytest.raises(UserError, match="needs weight"):
        solve_problem(load_problem_text(ROBOT.replace("    weight: [1, 4, 9]\n", "")))
    with pytest.raises(UserError, match="left symbolic"):
        solve_problem(load_problem_text(ROBOT.replace("values: {g0: 9.81}", "values: {}")))


ROBOT2 = """
id: mn2
title: planar 2R in a vertical plane
symbols: {g0: gravity, m2: mass 2}
values: {g0: 9.81}
robot:
  joints: [R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: 3, com: [cos(q1)/2, sin(q1)/2], angle: q1, inertia: 1/4}
    - {mass: m2, com: [cos(q1) + cos(q1+q2)/2, sin(q1) + sin(q1+q2)/2], angle: q1+q2, inertia: m2/12}
asks:
  - kind: minimum_norm
    task: sin(q1) + sin(q1 + q2)
    acceleration: 2
    objectives: [torque]
"""


def test_symbolic_generic_state_matches_numeric():
    """Without at: the solutions are symbolic in (q, q̇); at a state they equal the numeric path, M τ* = d."""
    rs_ = all_results(solve_problem(load_problem_text(ROBOT2 + "    null_torque: [-dq1, -2*dq2]\n")))
    M, d, tau, tns = (rs_[k].value for k in ("M", "d", "tau_tau", "tau_ns"))
    pt = {s: v for s, v in zip(sorted(tau.free_symbols | tns.free_symbols | d.free_symbols, key=str),
                               (0.3, 0.8, 1.7, 0.5, -0.2, 0.9, 0.4))}
    assert {s.name for s in pt} <= {"q1", "q2", "dq1", "dq2", "m2", "g0"}
    assert np.allclose(arr(M.subs(pt)) @ arr(tau.subs(pt)), arr(d.subs(pt)), atol=1e-9)
    assert np.allclose(arr(M.subs(pt)) @ arr(tns.subs(pt)), arr(d.subs(pt)), atol=1e-9)  # damping leaves the task
    vals = {s.name: float(v) for s, v in pt.items()}
    num_text = ROBOT2.replace("values: {g0: 9.81}", f"values: {{g0: {vals.get('g0', 9.81)}, m2: {vals['m2']}}}") \
        + f"    at: {{q1: {vals['q1']}, q2: {vals['q2']}}}\n    joint_velocity: [{vals['dq1']}, {vals['dq2']}]\n"
    num = all_results(solve_problem(load_problem_text(num_text)))
    assert np.allclose(arr(tau.subs(pt)).ravel(), arr(num["tau_tau"].value).ravel(), atol=1e-9)


@pytest.mark.parametrize("old, new, words", [
    ("    weight: [1, 4, 9]\n", "", "needs weight"),
    ("    weight: [1, 4, 9]\n", "    weight: [1, 4]\n", "weight must be 3x3 or 3 diagonal entries"),
    ("    acceleration: [1, -2]\n", "    acceleration: [1, -2, 3]\n", "acceleration must have 2 components"),
    ("    at: {q1: 0.3, q2: 0.8, q3: -0.5}\n", "    at: {q1: 0.3, q2: 0.8}\n", "at: must give every coordinate"),
])
def test_check_finds_bad_options_without_solving(old, new, words):
    """The task, state, acceleration and weight are read by the kind's validate hook (`check`) as by solving,
    without the model."""
    assert words in error_found_without_solving(ROBOT.replace(old, new))
