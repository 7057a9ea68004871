"""The `redundancy` ask: (weighted) pseudoinverse joint velocities against independent numpy computations, the
null-space term, singular configurations, the symbolic path, and the encoded exam problems."""
import random
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, check_and_solve

from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem, describe

ROBOT_3R = """
id: t
title: planar 3R
symbols: {l1: link 1, l2: link 2, l3: link 3}
values: {l1: 1, l2: 0.8, l3: 0.5}
robot:
  joints: [R, R, R]
  dh:
    table: [{a: l1, theta: q1}, {a: l2, theta: q2}, {a: l3, theta: q3}]
    links: [{}, {}, {}]
asks:
  - kind: redundancy
    task:
      - l1*cos(q1) + l2*cos(q1 + q2) + l3*cos(q1 + q2 + q3)
      - l1*sin(q1) + l2*sin(q1 + q2) + l3*sin(q1 + q2 + q3)
"""
TASK_PY = lambda q, l=(1, 0.8, 0.5): np.array([  # noqa: E731
    [-l[0] * np.sin(q[0]) - l[1] * np.sin(q[0] + q[1]) - l[2] * np.sin(q.sum()),
     -l[1] * np.sin(q[0] + q[1]) - l[2] * np.sin(q.sum()), -l[2] * np.sin(q.sum())],
    [l[0] * np.cos(q[0]) + l[1] * np.cos(q[0] + q[1]) + l[2] * np.cos(q.sum()),
     l[1] * np.cos(q[0] + q[1]) + l[2] * np.cos(q.sum()), l[2] * np.cos(q.sum())]])


def solve_text(text: str) -> dict:
    return all_results(solve_problem(load_problem_text(text)))


def num(value) -> np.ndarray:
    return np.array(sp.Matrix(value).evalf(20).tolist(), dtype=float)


def at(q) -> str:
    return "{" + ", ".join(f"q{i + 1}: {float(x)!r}" for i, x in enumerate(q)) + "}"


def ask(**opts: str) -> str:
    return "".join(f"    {k}: {v}\n" for k, v in opts.items())


CONFIGS = [np.array([0.3, 0.7, -0.4]), np.array([1.1, -0.9, 1.6]), np.array([-2.0, 0.25, 0.5])]


# ------------------------------------------------------------------------------------- full rank, minimum norm
@pytest.mark.parametrize("q", CONFIGS, ids=lambda q: str([float(x) for x in q]))
def test_min_norm_velocity_realizes_task_and_matches_lstsq(q):
    r = solve_text(ROBOT_3R + ask(velocity="[0.4, -1.2]", at=at(q)))
    J = TASK_PY(q)
    assert np.allclose(num(r["J_at"].value), J, atol=1e-12)
    qps = num(r["qdot_ps"].value).ravel()
    rdot = np.array([0.4, -1.2])
    assert np.allclose(J @ qps, rdot, atol=1e-10)                      # J q̇_ps = ṙ
    ref = np.linalg.lstsq(J, rdot, rcond=None)[0]                      # numpy's minimum-norm solution
    assert np.allclose(qps, ref, atol=1e-10)
    assert np.allclose(num(r["J_pinv"].value), np.linalg.pinv(J), atol=1e-10)
    assert int(r["rank"].value) == 2 and r["singular"].value is False
    assert np.allclose(num(r["task_error"].value), 0, atol=1e-12)
    assert float(r["norm2_ps"].value) == pytest.approx(0.5 * qps @ qps)
    # any other solution q̇_ps + n (n in the null space) has a larger norm
    nvec = np.linalg.svd(J)[2][-1]
    for t in (0.1, -0.5, 2.0):
        assert np.linalg.norm(qps + t * nvec) > np.linalg.norm(qps)


def test_exact_configuration_gives_exact_values():
    r = solve_text(ROBOT_3R + ask(velocity="[1, 0]", at="{q1: 0, q2: pi/2, q3: -pi/2}"))
    J = r["J_at"].value
    assert all(x.is_Rational for x in J)                               # sin, cos of multiples of π/2: exact
    assert J * r["qdot_ps"].value == sp.Matrix([1, 0])                 # exactly, no rounding
    assert all(x.is_Rational for x in r["J_pinv"].value)


@pytest.mark.parametrize("weight", ["[1, 4, 9]", "[[3, 1, 0], [1, 2, 0.5], [0, 0.5, 1]]"])
def test_weighted_velocity_minimizes_weighted_norm(weight):
    q = CONFIGS[0]
    r = solve_text(ROBOT_3R + ask(velocity="[0.4, -1.2]", weight=weight, at=at(q)))
    W = np.diag([1.0, 4, 9]) if weight.count("[") == 1 else np.array([[3, 1, 0], [1, 2, 0.5], [0, 0.5, 1.0]])
    J, rdot = TASK_PY(q), np.array([0.4, -1.2])
    qps = num(r["qdot_ps"].value).ravel()
    # KKT system of min ½ q̇ᵀWq̇ s.t. J q̇ = ṙ, solved independently
    K = np.block([[W, J.T], [J, np.zeros((2, 2))]])
    ref = np.linalg.solve(K, np.concatenate([np.zeros(3), rdot]))[:3]
    assert np.allclose(qps, ref, atol=1e-10)
    assert np.allclose(J @ qps, rdot, atol=1e-10)
    # weighted cost below the unweighted solution's, and the other way round for the plain norm
    qmn = num(r["qdot_mn"].value).ravel()
    assert np.allclose(qmn, np.linalg.pinv(J) @ rdot, atol=1e-10)
    assert float(r["cost_ps"].value) == pytest.approx(0.5 * qps @ W @ qps)
    assert float(r["cost_ps"].value) <= float(r["cost_mn"].value) + 1e-12
    assert float(r["norm2_mn"].value) <= float(r["norm2_ps"].value) + 1e-12
    Wi = np.linalg.inv(W)
    assert np.allclose(num(r["J_pinv"].value), Wi @ J.T @ np.linalg.inv(J @ Wi @ J.T), atol=1e-10)


def test_inertia_weight_uses_the_robot_inertia_matrix():
    text = """
id: t
title: t
symbols: {a: coefficient}
values: {a: 2}
robot:
  joints: [R, R]
  model: {B: "[[a + cos(q2), 1], [1, 1]]"}
asks:
  - kind: redundancy
    jacobian: [[1, 1]]
    velocity: [1]
    weight: inertia
    at: {q2: 0}
"""
    r = solve_text(text)
    W = np.array([[3.0, 1], [1, 1]])
    qps = num(r["qdot_ps"].value).ravel()
    ref = np.linalg.solve(np.block([[W, np.ones((2, 1))], [np.ones((1, 2)), np.zeros((1, 1))]]),
                          [0, 0, 1])[:2]
    assert np.allclose(qps, ref) and np.allclose(qps, [0, 1])


# ------------------------------------------------------------------------------------------------ null space
@pytest.mark.parametrize("q", CONFIGS[:2], ids=lambda q: str([float(x) for x in q]))
def test_null_space_term_leaves_task_velocity_unchanged(q):
    r = solve_text(ROBOT_3R + ask(velocity="[0.4, -1.2]", qdot0="[1, -2, 0.5]", at=at(q)))
    J, rdot = TASK_PY(q), np.array([0.4, -1.2])
    qps, qn, qd = (num(r[k].value).ravel() for k in ("qdot_ps", "qdot_null", "qdot"))
    assert np.allclose(J @ qn, 0, atol=1e-10)
    assert np.allclose(J @ qd, rdot, atol=1e-10)
    P = np.eye(3) - np.linalg.pinv(J) @ J
    assert np.allclose(qn, P @ np.array([1, -2, 0.5]), atol=1e-10)
    assert np.allclose(qd, qps + qn, atol=1e-12)
    assert np.linalg.norm(qd - qps) > 1e-3                             # the term is really there


def test_quoted_null_key_is_the_same_as_qdot0():
    a = solve_text(ROBOT_3R + ask(velocity="[0.4, -1.2]", qdot0="[1, -2, 0.5]", at=at(CONFIGS[0])))
    b = solve_text(ROBOT_3R + ask(velocity="[0.4, -1.2]", at=at(CONFIGS[0])) + '    "null": [1, -2, 0.5]\n')
    assert np.allclose(num(a["qdot"].value), num(b["qdot"].value))


@pytest.mark.parametrize("step", [1, -1, 0.5])
def test_gradient_step_changes_objective_in_the_right_direction(step):
    q = CONFIGS[1]
    r = solve_text(ROBOT_3R + ask(velocity="[0.4, -1.2]", gradient="sin(q2)^2 + q3^2", step=step, at=at(q)))
    grad = np.array([0, np.sin(2 * q[1]), 2 * q[2]])
    assert np.allclose(num(r["grad_H_at"].value).ravel(), grad)
    qn = num(r["qdot_null"].value).ravel()
    J = TASK_PY(q)
    assert np.allclose(qn, (np.eye(3) - np.linalg.pinv(J) @ J) @ (step * grad), atol=1e-10)
    assert np.sign(grad @ qn) == np.sign(step)                         # ∇Hᵀ P ∇H ≥ 0: H moves with the step
    assert np.allclose(J @ num(r["qdot"].value).ravel(), [0.4, -1.2], atol=1e-10)


# ------------------------------------------------------------------------------------------------ singular
def test_singular_configuration_with_reachable_velocity():
    # stretched arm: J has rank 1; a velocity orthogonal to the arm is still realizable
    r = solve_text(ROBOT_3R + ask(velocity="[0, 1]", at="{q1: 0, q2: 0, q3: 0}"))
    assert int(r["rank"].value) == 1 and r["singular"].value is True
    J = num(r["J_at"].value)
    qps = num(r["qdot_ps"].value).ravel()
    assert np.allclose(qps, np.linalg.lstsq(J, [0, 1], rcond=None)[0])
    assert np.allclose(num(r["task_error"].value), 0)


def test_singular_configuration_with_unreachable_velocity_reports_task_error():
    r = solve_text(ROBOT_3R + ask(velocity="[1, 1]", at="{q1: 0, q2: 0, q3: 0}"))
    assert r["singular"].value is True
    J = num(r["J_at"].value)
    qps = num(r["qdot_ps"].value).ravel()
    ref = np.linalg.lstsq(J, [1, 1], rcond=None)[0]                    # least squares, then minimum norm
    assert np.allclose(qps, ref)
    err = num(r["task_error"].value).ravel()
    assert np.allclose(err, J @ ref - [1, 1]) and np.allclose(err, [-1, 0])
    assert np.allclose(num(r["J_pinv"].value), np.linalg.pinv(J))


def test_singular_weighted_is_least_squares_with_minimum_weighted_norm():
    W = np.array([[2.0, 1, 0], [1, 2, 0], [0, 0, 1]])
    r = solve_text(ROBOT_3R + ask(velocity="[1, 0.5]", weight="[[2, 1, 0], [1, 2, 0], [0, 0, 1]]",
                                  at="{q1: 0, q2: 0, q3: 0}"))
    assert r["singular"].value is True
    J = num(r["J_at"].value)
    qps = num(r["qdot_ps"].value).ravel()
    # the x-row of J vanishes; the y-row a·q̇ = 0.5 is solved with minimum ½q̇ᵀWq̇: q̇ = W⁻¹aᵀ λ
    a = J[1]
    lam = 0.5 / (a @ np.linalg.solve(W, a))
    assert np.allclose(qps, lam * np.linalg.solve(W, a), atol=1e-10)
    assert np.allclose(num(r["task_error"].value).ravel(), [-1, 0], atol=1e-10)


def test_more_task_rows_than_joints():
    text = """
id: t
title: t
asks:
  - kind: redundancy
    jacobian: [[1, 0], [0, 1], [1, 1]]
    velocity: [1, 0, 0]
"""
    r = solve_text(text)
    J = np.array([[1.0, 0], [0, 1], [1, 1]])
    assert r["singular"].value is True and int(r["rank"].value) == 2
    assert np.allclose(num(r["qdot_ps"].value).ravel(), np.linalg.lstsq(J, [1, 0, 0], rcond=None)[0])
    assert np.linalg.norm(num(r["task_error"].value)) > 0.1


# ------------------------------------------------------------------------------------------------ symbolic
PPR = """
id: t
title: PPR
symbols: {l: link 3, w: weight}
robot:
  joints: [P, P, R]
  links: [{com: [q1, 0]}, {com: [q1, q2]}, {com: [q1 + l*cos(q3), q2 + l*sin(q3)]}]
asks:
  - kind: redundancy
    task: [q1 + l*cos(q3), q2 + l*sin(q3)]
    velocity: [-1, 1]
"""


@pytest.mark.parametrize("weight", [None, "[1, 1, w]"])
def test_symbolic_pseudoinverse_without_configuration(weight):
    r = solve_text(PPR + (ask(weight=weight) if weight else ""))
    Jp, J, qps = r["J_pinv"].value, r["J"].value, r["qdot_ps"].value
    assert Jp == r["J_pinv_sym"].value and J.free_symbols
    rng = random.Random(3)
    for _ in range(3):
        pt = {s: sp.Rational(rng.randint(1, 97), rng.randint(5, 40)) for s in (J.free_symbols | Jp.free_symbols)}
        Jn, Jpn = num(J.subs(pt)), num(Jp.subs(pt))
        assert np.allclose(Jn @ Jpn, np.eye(2))                        # right inverse
        W = np.diag([1, 1, float(pt.get(sp.Symbol("w", positive=True), 1))])
        Wi = np.linalg.inv(W)
        assert np.allclose(Jpn, Wi @ Jn.T @ np.linalg.inv(Jn @ Wi @ Jn.T))
        assert np.allclose(num(qps.subs(pt)).ravel(), Jpn @ [-1, 1])
    l = sp.Symbol("l", positive=True)
    if weight is None:
        assert sp.simplify(r["det_JJt_sym"].value - (1 + l ** 2)) == 0
    assert all(x == 0 for x in r["task_error"].value)


def test_symbolic_path_skipped_for_large_tasks():
    text = ROBOT_3R.replace("      - l1*sin(q1)", "      - q1 + q2 + q3\n      - l1*sin(q1)")
    sols = solve_problem(load_problem_text(text))
    res = all_results(sols)
    assert "J" in res and "J_pinv" not in res and "J_pinv_sym" not in res
    assert "not given symbolically" in render(load_problem_text(text), sols, "md")


# ------------------------------------------------------------------------------------------------ suffix, errors
def test_suffix_keeps_several_asks_apart():
    text = ROBOT_3R + ask(velocity="[1, 0]", at="{q1: 0, q2: 1, q3: 1}") + """  - kind: redundancy
    jacobian: [[1, 0, 0], [0, 1, 0]]
    velocity: [1, 0]
    suffix: _b
"""
    r = solve_text(text)
    assert "qdot_ps" in r and "qdot_ps_b" in r and r["qdot_ps_b"].value == sp.Matrix([1, 0, 0])


@pytest.mark.parametrize("extra, message", [
    ("    jacobian: [[1, 0, 0], [0, 1, 0]]\n", "exactly one of task"),
    ("    velocity: [1, 2, 3]\n", "velocity must have 2 components"),
    ("    velocity: [1, 2]\n    at: {q7: 1}\n", "'q7' in at: is not a coordinate"),
    ("    velocity: [1, 2]\n    weight: [[1, 2, 0], [0, 1, 0], [0, 0, 1]]\n", "must be symmetric"),
    ("    velocity: [1, 2]\n    weight: [1, -1, 1]\n    at: {q1: 0, q2: 1, q3: 1}\n", "not positive definite"),
    ("    gradient: q1^2\n", "needs velocity"),
    ("    velocity: [1, 2]\n    gradient: q1^2\n    qdot0: [1, 0, 0]\n", "only one of"),
    ("    velocity: [1, 2]\n    weight: [1, 1]\n", "weight must be 3x3"),
])
def test_spec_errors_point_at_the_ask(extra, message):
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem_text(ROBOT_3R + extra))
    assert message in str(exc.value) and exc.value.place and exc.value.place.line >= 12


# ------------------------------------------------------------------------------------------------ exam problems
ENCODED = ["2016-04-13-midterm-ex3", "2017-03-29-midterm-ex4", "2018-04-26-midterm-ex4", "2019-04-29-midterm-ex5",
           "2020-07-15-remote-ex2"]


@pytest.mark.parametrize("name", ENCODED)
def test_encoded_problem_reproduces_printed_values(name):
    rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
    assert len(rep.checks) >= 7 and rep.ok, "\n".join(describe(rep))


def test_2019_minimum_kinetic_energy_values():
    r = all_results(solve_problem(load_problem(PROBLEMS / "2019-04-29-midterm-ex5.yaml")))
    assert np.allclose(num(r["qdot_ps"].value).ravel(), [0.1179, -0.7071], atol=1e-4)     # printed (18)
    assert np.allclose(num(r["qdot_mn"].value).ravel(), [0, -0.7071], atol=1e-4)          # printed (19)
    assert float(r["cost_ps"].value) == pytest.approx(25 / 72) and float(r["cost_mn"].value) == pytest.approx(5 / 12)
    assert r["qdot_ps"].value == sp.Matrix([sp.sqrt(2) / 12, -sp.sqrt(2) / 2])           # exact


def test_2016_projected_gradient_values():
    r = all_results(solve_problem(load_problem(PROBLEMS / "2016-04-13-midterm-ex3.yaml")))
    assert r["J_pinv"].value == sp.Matrix([[sp.Rational(1, 3), 1, sp.Rational(1, 6)],
                                           [sp.Rational(-2, 3), 0, sp.Rational(-1, 3)],
                                           [sp.Rational(-5, 3), -1, sp.Rational(-5, 6)], [2, 0, 2]])
    assert np.allclose(num(r["qdot"].value).ravel(), [0.4126, -0.8252, -2.0874, 3], atol=1e-4)


def test_2018_erratum_is_confirmed():
    rep = check_problem(load_problem(PROBLEMS / "2018-04-26-midterm-ex4.yaml"))
    errata = [c for c in rep.checks if c.erratum]
    assert [c.name for c in errata] == ["qdot_ps_l2cm"] and errata[0].printed_differs and errata[0].verdict.ok


def test_2020_algorithmic_singularity():
    r = all_results(solve_problem(load_problem(PROBLEMS / "2020-07-15-remote-ex2.yaml")))
    assert r["singular"].value is False and r["singular_s"].value is True and int(r["rank_s"].value) == 2
    assert r["qdot_s"].value == sp.Matrix([-1, 0, 1, 1]) / 3 and all(x == 0 for x in r["task_error_s"].value)


def test_report_reads_like_a_solution():
    p = load_problem(PROBLEMS / "2020-07-15-remote-ex2.yaml")
    md = render(p, solve_problem(p), "md")
    for part in ["**Rank.**", "**Pseudoinverse.**", "**Joint velocity.**", "Moore-Penrose", "**singular**",
                 "still executed exactly", "Check: $J\\,\\dot q_{ps}"]:
        assert part in md


@pytest.mark.skipif(not shutil.which("pdflatex"), reason="pdflatex not installed")
@pytest.mark.parametrize("name", ["2019-04-29-midterm-ex5", "2016-04-13-midterm-ex3"])
def test_latex_compiles(tmp_path, name):
    p = load_problem(PROBLEMS / f"{name}.yaml")
    (tmp_path / "r.tex").write_text(render(p, solve_problem(p), "tex"))
    r = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "r.tex"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stdout[-2000:]


def test_symbolic_false_gives_only_the_jacobian_and_its_generic_rank():
    r = solve_text(PPR + ask(symbolic="false"))
    assert "J_pinv" not in r and "J_pinv_sym" not in r
    assert int(r["rank"].value) == 2 and r["singular"].value is False
    assert r["J"].value == sp.Matrix([[1, 0, -sp.Symbol("l", positive=True) * sp.sin(sp.Symbol("q3", real=True))],
                                      [0, 1, sp.Symbol("l", positive=True) * sp.cos(sp.Symbol("q3", real=True))]])


@pytest.mark.parametrize("shape", [(2, 4), (3, 2), (1, 3)])
def test_exact_pseudoinverse_in_a_number_field_meets_the_penrose_conditions(shape) -> None:  # type: ignore[no-untyped-def]
    """Exact mode computes J^+ of full-rank matrices with entries in Q(√2, √3) by J^T (J J^T)^-1 in the number
    field: A P A = A, P A P = P, A P and P A symmetric, exactly; a rank-deficient matrix takes sympy's pinv."""
    from solver.kinematics.redundancy import Arith
    ar = Arith("exact")
    r2, r3 = sp.sqrt(2), sp.sqrt(3)
    pool = [1, r2, r3, sp.Rational(1, 2), -r2 / 2, 3 - r3, r2 * r3, sp.Rational(-7, 5)]
    m, n = shape
    A = sp.Matrix(m, n, lambda i, j: pool[(3 * i + 5 * j + i * j) % len(pool)])
    P = ar.pinv_mp(A)
    for E in (A * P * A - A, P * A * P - P, (A * P).T - A * P, (P * A).T - P * A):
        assert all(sp.expand(sp.radsimp(x)) == 0 for x in E)
    assert all(not x.has(sp.Pow) or all(p.exp == sp.Rational(1, 2) for p in x.atoms(sp.Pow)) for x in P)
    D = sp.Matrix([[1, r2, 0], [r2, 2, 0]])  # rank 1
    Q = ar.pinv_mp(D)
    assert all(sp.expand(sp.radsimp(x)) == 0 for x in D * Q * D - D)
    assert ar.rank(D) == 1 and ar.det(sp.Matrix([[1, r2], [r2, 2]])) == 0


def test_the_check_writes_j_qdot_as_rdot_when_the_task_is_exact():
    """J q̇_ps with q̇_ps = J_W^# ṙ (W the inertia matrix, symbolic) is ṙ exactly: the report's check shows ṙ, not
    the uncancelled product (a fraction of about 300 terms before); its task error is exactly zero."""
    p = load_problem(PROBLEMS / "2018-01-11-ex1.yaml")
    checks = [st.data for sol in solve_problem(p) for st in sol.steps if st.name == "qdot"]
    assert len(checks) == 3 and all(d["exact_task"] for d in checks)
    for d in checks:
        assert d["r"]["Jq"] == d["r"]["rdot"] and sp.count_ops(d["r"]["Jq"]) < 12


# ------------------------------------------------------------------------------------- check = solve's errors
@pytest.mark.parametrize("ask, words", [
    ("    at: {q1: 0, q2: 1, q4: 0}\n    velocity: [1, 0]\n", "'q4' in at: is not a coordinate"),
    ("    at: {q1: 0, q2: 1, q3: 0}\n    velocity: [1, 0]\n    weight: [1, 2]\n", "weight must be 3x3"),
    ("    at: {q1: 0, q2: 1, q3: 0, q4: 0}\n    velocity: [1, 0]\n    methods: [pseudoinverse, dls]\n    mu: 0.1\n",
     "'q4' in at: is not a coordinate"),
    ("    at: {q1: 0, q2: 1, q3: 0}\n    velocity: [1, 0]\n    methods: [sns]\n", "sns and scaled need bounds:"),
], ids=["at-q4", "weight-shape", "methods-at-q4", "sns-without-bounds"])
def test_check_reports_the_error_solve_raises(write, ask, words):
    """`check` reads the options as `solve` does, on both paths (one task, the methods): the same message, exit 2
    (before: ok, nothing was solved without expected: values)."""
    path = write(ROBOT_3R.replace("      - l1*sin(q1) + l2*sin(q1 + q2) + l3*sin(q1 + q2 + q3)\n",
                                  "      - l1*sin(q1) + l2*sin(q1 + q2) + l3*sin(q1 + q2 + q3)\n" + ask))
    check, solve = check_and_solve(path)
    assert check.returncode == solve.returncode == 2, check.stdout + check.stderr
    assert check.stderr == solve.stderr and words in check.stderr and "spec.yaml:" in check.stderr, check.stderr


def _tidy_rational_reference(e: sp.Expr) -> sp.Expr:
    """_tidy_rational as it was before the pair screen: the subs of every cos atom, always."""
    from solver.kinematics.redundancy import _hide_radicals
    from solver.math.opcount import count_ops
    from solver.math.simplify import factor_within, tidy
    e, back = _hide_radicals(e)
    t = tidy(e)
    if t.free_symbols and not t.is_polynomial() and count_ops(t) <= 150:
        f = factor_within(sp.expand_trig(t))
        for _ in range(2):
            g = f
            for c in f.atoms(sp.cos):
                g = g.subs((c - 1) * (c + 1), -sp.sin(c.args[0]) ** 2)
            if g == f:
                break
            f = factor_within(g)
        if count_ops(f) < count_ops(t):
            t = f
    return t.xreplace(back) if back else t


def test_tidy_rational_pair_screen_matches_general_path():
    """The (cos x − 1)(cos x + 1) → −sin² x substitution runs only when both factors occur (sympy's subs walked the
    whole factored form once per cos and was most of the redundancy asks' time); same forms as always running it,
    with and without a pair to replace, a constant to distribute in the denominator."""
    from solver.kinematics.redundancy import _sine_square_pair, _tidy_rational
    q1, q2, a, b = sp.symbols("q1 q2 a b", real=True)
    c1, c2, s1 = sp.cos(q1), sp.cos(q2), sp.sin(q1)
    cases = [(s1 * c2 + 2 * c1) / (2 * (c1**2 * c2**2 - c2**2 + a)),
             (c2**2 - 1) / (a * s1 + c2),
             a * (c1**2 - 1) * c2 / (b * s1**2 * c2 + a * c1)]
    got = [_tidy_rational(e) for e in cases]
    assert got == [_tidy_rational_reference(e) for e in cases]
    hits = _tidy_rational.cache_info().hits  # memoized: minimum_norm's asks tidy the same entries again
    assert [_tidy_rational(e) for e in cases] == got and _tidy_rational.cache_info().hits == hits + len(cases)
    assert got[1] == (c2**2 - 1) / (a * s1 + c2)
    assert got[2] == -a * s1**2 * c2 / (a * c1 - b * c1**2 * c2 + b * c2)
    assert _sine_square_pair((c2 - 1) * (c2 + 1) / (a * s1 + c2))
    assert not _sine_square_pair((s1 * c2 + 2 * c1) / (2 * (a + c1**2 * c2**2 - c2**2)))
