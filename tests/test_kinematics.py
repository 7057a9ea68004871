"""The `kinematics` ask: Jacobians against finite differences of the direct kinematics, the angular velocity from
Ṙ Rᵀ, J̇q̇ against d/dt(J) q̇, singular sets where the rank drops, inverse kinematics that reproduces the target,
null/range bases, sketches, error cases; on robots no exercise uses (a spatial 4R with offsets, a planar 4R,
a PUMA-like 6R), and the trigonometric factorization and elimination underneath."""
import math
import random
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import check_and_solve

from solver.kinematics import geometry as geo
from solver.math.simplify import tidy
from solver.math.trigsolve import Solver, check_families, trig_factors
from solver.publish.figures import write_figures
from solver.publish.render import render
from solver.registry import PROPERTY_CHECKS
from solver.solve import all_results, solve_problem
from solver.spec import load_problem_text
from solver.spec.errors import UserError

SPATIAL_4R = """
id: s4r
title: spatial 4R with offsets
symbols: {d1: base height, a2: upper arm, a3: forearm, d4: wrist offset, b: tool offset}
values: {d1: 0.4, a2: 0.7, a3: 0.5, d4: 0.15, b: 0.1}
robot:
  joints: [R, R, R, R]
  dh:
    table:
      - {d: d1, alpha: pi/2, theta: q1}
      - {a: a2, theta: q2}
      - {a: a3, alpha: -pi/2, theta: q3}
      - {d: d4, a: b, alpha: pi/2, theta: q4}
    links: [{}, {}, {}, {}]
asks:
  - kind: kinematics
"""

MODIFIED_3R = """
id: m3r
title: spatial RPR, modified DH
symbols: {a1: offset, d3: tool}
values: {a1: 0.3, d3: 0.2}
robot:
  joints: [R, P, R]
  dh:
    convention: modified
    table:
      - {theta: q1}
      - {a: a1, alpha: pi/2, d: q2}
      - {alpha: -pi/2, d: d3, theta: q3}
    links: [{}, {}, {}]
asks:
  - kind: kinematics
"""

PLANAR_4R = """
id: p4r
title: planar 4R
symbols: {l1: l1, l2: l2, l3: l3, l4: l4}
values: {l1: 1, l2: 0.8, l3: 0.6, l4: 0.3}
robot:
  joints: [R, R, R, R]
  dh:
    table: [{a: l1, theta: q1}, {a: l2, theta: q2}, {a: l3, theta: q3}, {a: l4, theta: q4}]
    links: [{}, {}, {}, {}]
asks:
"""


def solve_text(text: str) -> dict:
    return all_results(solve_problem(load_problem_text(text)))


def f(expr, subs) -> np.ndarray:
    return np.array(sp.Matrix(expr).subs(subs).evalf(30).tolist(), dtype=float)


def values_of(problem) -> dict:
    return {k: v for k, v in problem.values.items()}


def rand_q(n, rng):
    return [rng.uniform(-2.5, 2.5) for _ in range(n)]


# ------------------------------------------------------------------------------------- Jacobians vs finite differences
@pytest.mark.parametrize("text", [SPATIAL_4R, MODIFIED_3R], ids=["spatial4R", "modifiedRPR"])
def test_jacobians_match_finite_differences(text):
    prob = load_problem_text(text)
    r = all_results(solve_problem(prob))
    q = prob.robot.q
    T, J, Jg = r["T"].value, r["J"].value, r["Jg"].value
    assert J.shape == (3, len(q)) and Jg.shape == (6, len(q))
    rng = random.Random(3)
    vals = values_of(prob)
    for _ in range(3):
        qs = rand_q(len(q), rng)
        qd = np.array(rand_q(len(q), rng))
        sub = {**vals, **dict(zip(q, qs))}
        h = 1e-6
        num = np.zeros((3, len(q)))
        for k in range(len(q)):
            plus = {**sub, q[k]: qs[k] + h}
            minus = {**sub, q[k]: qs[k] - h}
            num[:, k] = (f(T[:3, 3], plus) - f(T[:3, 3], minus)).ravel() / (2 * h)
        assert np.allclose(f(J, sub), num, atol=1e-7)                   # analytic J = ∂p/∂q
        assert np.allclose(f(Jg[:3, :], sub), num, atol=1e-7)           # linear part of the geometric J
        # angular part: ω from Ṙ Rᵀ along q(t) = q + t q̇
        plus = {**vals, **{x: v + h * w for x, v, w in zip(q, qs, qd)}}
        minus = {**vals, **{x: v - h * w for x, v, w in zip(q, qs, qd)}}
        R = f(T[:3, :3], sub)
        Rdot = (f(T[:3, :3], plus) - f(T[:3, :3], minus)) / (2 * h)
        S = Rdot @ R.T
        omega = np.array([S[2, 1], S[0, 2], S[1, 0]])
        assert np.allclose(f(Jg[3:, :], sub) @ qd, omega, atol=1e-7)


def test_geometric_jacobian_in_end_effector_frame():
    prob = load_problem_text(SPATIAL_4R.replace("  - kind: kinematics", "  - kind: kinematics\n    expressed_in: end_effector"))
    r = all_results(solve_problem(prob))
    base = all_results(solve_problem(load_problem_text(SPATIAL_4R)))
    q = prob.robot.q
    sub = {**values_of(prob), **dict(zip(q, [0.3, -0.7, 1.1, 0.4]))}
    R = f(base["R"].value, sub)
    Jb, Je = f(base["Jg"].value, sub), f(r["Jg"].value, sub)
    assert np.allclose(Je[:3], R.T @ Jb[:3], atol=1e-12)
    assert np.allclose(Je[3:], R.T @ Jb[3:], atol=1e-12)


def test_jdot_qdot_is_time_derivative_of_J():
    r = solve_text(SPATIAL_4R.replace("  - kind: kinematics", "  - kind: kinematics\n    jdot: true"))
    prob = load_problem_text(SPATIAL_4R)
    q, dq = prob.robot.q, prob.robot.dq
    J, Jd, Jdq = r["J"].value, r["Jdot"].value, r["Jdot_qdot"].value
    vals = values_of(prob)
    rng = random.Random(5)
    for _ in range(3):
        qs, qd = rand_q(4, rng), rand_q(4, rng)
        h = 1e-6
        plus = {**vals, **{x: v + h * w for x, v, w in zip(q, qs, qd)}}
        minus = {**vals, **{x: v - h * w for x, v, w in zip(q, qs, qd)}}
        dJ = (f(J, plus) - f(J, minus)) / (2 * h)
        sub = {**vals, **dict(zip(q, qs)), **dict(zip(dq, qd))}
        assert np.allclose(f(Jd, sub), dJ, atol=1e-6)
        assert np.allclose(f(Jdq, sub).ravel(), dJ @ np.array(qd), atol=1e-6)


# ------------------------------------------------------------------------------------- singularities
def _family_points(configs, q, vals, rng, k=3):
    """Numeric configurations of each singular family (free coordinates at random)."""
    for c in configs:
        for _ in range(k):
            free = {x: rng.uniform(-2.5, 2.5) for x in q if c.has(x)}
            yield {**vals, **dict(zip(q, [float(sp.N(e.subs(free).subs(vals))) for e in c]))}


def test_planar_4r_pose_singularities_drop_rank():
    r = solve_text(PLANAR_4R + "  - {kind: kinematics, task: pose}\n")
    prob = load_problem_text(PLANAR_4R + "  - {kind: kinematics, task: pose}\n")
    q, vals = prob.robot.q, values_of(prob)
    sing = r["singularities"].value
    assert len(sing) == 4                       # q2, q3 ∈ {0, π}
    rng = random.Random(1)
    J = r["J"].value
    for pt in _family_points(sing, q, vals, rng):
        assert np.linalg.matrix_rank(f(J, pt), tol=1e-9) < 3
    for _ in range(5):                          # and away from them the rank is full
        pt = {**vals, **dict(zip(q, rand_q(4, rng)))}
        assert np.linalg.matrix_rank(f(J, pt), tol=1e-9) == 3


ABSOLUTE_4R = """
id: abs4r
title: planar 4R with absolute link angles
symbols: {a: a, b: b, c: c, d: d}
values: {a: 1, b: 0.7, c: 0.5, d: 0.2}
robot:
  joints: [R, R, R, R]
asks:
  - kind: kinematics
    task: [a*cos(q1) + b*cos(q2) + c*cos(q3) + d*cos(q4), a*sin(q1) + b*sin(q2) + c*sin(q3) + d*sin(q4)]
    sketch: false
"""


def test_dependent_minors_absolute_angles_solved():
    """The six minors l_i l_j sin(q_j - q_i) are not independent (two of them imply a third): the singular set,
    all links on one line through the base, is still found in closed form (before: left implicit)."""
    prob = load_problem_text(ABSOLUTE_4R)
    r = all_results(solve_problem(prob))
    q, vals = prob.robot.q, values_of(prob)
    sing = r["singularities"].value
    assert len(sing) == 8                       # q2, q3, q4 ∈ {q1, q1 + π}
    assert all(len(c.free_symbols) == 1 for c in sing)
    rng = random.Random(2)
    J = r["J"].value
    for pt in _family_points(sing, q, vals, rng):
        assert np.linalg.matrix_rank(f(J, pt), tol=1e-9) < 2
    for _ in range(5):
        pt = {**vals, **dict(zip(q, rand_q(4, rng)))}
        assert np.linalg.matrix_rank(f(J, pt), tol=1e-9) == 2


def test_spatial_singularities_make_det_vanish():
    text = SPATIAL_4R.replace("  - kind: kinematics", "  - kind: kinematics\n    task: [(a2*cos(q2) + a3*cos(q2 + q3))*cos(q1), (a2*cos(q2) + a3*cos(q2 + q3))*sin(q1), d1 + a2*sin(q2) + a3*sin(q2 + q3)]\n    wrt: [q1, q2, q3]")
    # an anthropomorphic 3R position task: det J = a2 a3 s3 (a2 c2 + a3 c23)
    prob = load_problem_text(text.replace("    wrt: [q1, q2, q3]\n", "").replace("joints: [R, R, R, R]", "joints: [R, R, R]").replace("      - {d: d4, a: b, alpha: pi/2, theta: q4}\n", "").replace("links: [{}, {}, {}, {}]", "links: [{}, {}, {}]"))
    r = all_results(solve_problem(prob))
    d = r["det_J"].value
    q, vals = prob.robot.q, values_of(prob)
    assert sp.simplify(tidy(d - prob.symbols["a2"] * prob.symbols["a3"] * sp.sin(q[2]) *
                            (prob.symbols["a2"] * sp.cos(q[1]) + prob.symbols["a3"] * sp.cos(q[1] + q[2])))) == 0 \
        or sp.simplify(tidy(d + prob.symbols["a2"] * prob.symbols["a3"] * sp.sin(q[2]) *
                            (prob.symbols["a2"] * sp.cos(q[1]) + prob.symbols["a3"] * sp.cos(q[1] + q[2])))) == 0
    rng = random.Random(2)
    fams = r["singularities"].value
    assert len(fams) >= 4                       # elbow q3 ∈ {0, π}, shoulder: wrist point on the axis z0
    for pt in _family_points(fams, q, vals, rng):
        assert abs(float(sp.N(d.subs(pt)))) < 1e-9
        assert np.linalg.matrix_rank(f(r["J"].value, pt), tol=1e-9) < 3


def test_puma_geometric_determinant_factors():
    q = list(sp.symbols("q1:7", real=True))
    a2, a3, d3, d4 = sp.symbols("a2 a3 d3 d4", positive=True)
    h = sp.pi / 2
    rows = [(0, -h, 0, q[0]), (a2, 0, d3, q[1]), (a3, h, 0, q[2]), (0, -h, d4, q[3]), (0, h, 0, q[4]), (0, 0, 0, q[5])]
    from solver.math.rigid import dh_chain
    frames = [sp.eye(4)] + dh_chain(rows, "standard")
    d, k, j = geo.geometric_det(frames, ["R"] * 6, "standard")
    const, facs = trig_factors(d)
    names = {str(tidy(fct)) for fct, _ in facs}
    assert "sin(q5)" in names                                         # wrist singularity
    assert any("q3" in nm and "q2" not in nm for nm in names)          # elbow
    assert any("q2" in nm for nm in names)                             # shoulder
    Jb = geo.geometric_jacobian(frames, ["R"] * 6, "standard")          # det of the base-frame J, numerically
    rng = random.Random(4)
    for _ in range(3):
        pt = {**{x: rng.uniform(-2, 2) for x in q}, a2: 0.43, a3: 0.02, d3: 0.15, d4: 0.43}
        assert float(sp.N(d.subs(pt))) == pytest.approx(np.linalg.det(f(Jb, pt)), rel=1e-8, abs=1e-12)


@pytest.mark.parametrize("expr", [
    "l1*l2*sin(q2)", "cos(q2)*cos(q2 + q3)", "sin(2*q1)", "(q2 + l1)*cos(q1)",
    "(a*sin(q3) - b*cos(q3))*(sin(q1) + 2*cos(q1 + q2))", "1 + cos(q1)"])
def test_trig_factors_reconstruct(expr):
    names = {s: sp.Symbol(s, real=True) for s in ("q1", "q2", "q3")}
    names.update({s: sp.Symbol(s, positive=True) for s in ("l1", "l2", "a", "b")})
    e = sp.sympify(expr, locals=names)
    const, facs = trig_factors(tidy(sp.expand(e)))
    assert tidy(sp.expand(const * sp.Mul(*[g**k for g, k in facs]) - e)) == 0
    if "*" in expr and "(" in expr and expr.count(")*(") == 1:
        assert len(facs) >= 2


# ------------------------------------------------------------------------------------- inverse kinematics
@pytest.mark.parametrize("target", [(1.2, 0.6, 0.5), (-0.4, 1.1, 2.0), (0.2, -1.3, -1.0)])
def test_ik_planar_3r_reproduces_pose(target):
    text = PLANAR_4R.replace("joints: [R, R, R, R]", "joints: [R, R, R]").replace(
        ", {a: l4, theta: q4}", "").replace("links: [{}, {}, {}, {}]", "links: [{}, {}, {}]")
    text += f"  - {{kind: kinematics, task: pose, target: [{target[0]}, {target[1]}, {target[2]}]}}\n"
    prob = load_problem_text(text)
    r = all_results(solve_problem(prob))
    sols = r["ik"].value
    assert int(r["n_ik"].value) == len(sols) == 2              # elbow up and down
    p = r["p"].value
    for s in sols:
        sub = {**values_of(prob), **dict(zip(prob.robot.q, s))}
        got = f(p, sub).ravel()
        assert np.allclose(got[:2], target[:2], atol=1e-9)
        assert np.isclose(np.angle(np.exp(1j * (got[2] - target[2]))), 0, atol=1e-9)


def test_ik_out_of_reach_has_no_solution():
    text = PLANAR_4R.replace("joints: [R, R, R, R]", "joints: [R, R]").replace(
        ", {a: l3, theta: q3}, {a: l4, theta: q4}", "").replace("links: [{}, {}, {}, {}]", "links: [{}, {}]")
    r = solve_text(text + "  - {kind: kinematics, target: [3, 0]}\n")
    assert r["ik"].value == [] and int(r["n_ik"].value) == 0


def test_ik_symbolic_2r_all_solutions_at_random_targets():
    text = """
id: ik2r
title: 2R
symbols: {l1: l1, l2: l2, px: {meaning: x, sign: real}, py: {meaning: y, sign: real}}
robot: {joints: [R, R]}
asks:
  - kind: kinematics
    task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]
    target: [px, py]
"""
    prob = load_problem_text(text)
    r = all_results(solve_problem(prob))
    sols = r["ik"].value
    assert len(sols) == 2
    S = prob.symbols
    rng = random.Random(8)
    for _ in range(4):
        l1, l2 = rng.uniform(0.5, 1.5), rng.uniform(0.5, 1.5)
        q1, q2 = rng.uniform(-3, 3), rng.uniform(-3, 3)
        x, y = l1 * np.cos(q1) + l2 * np.cos(q1 + q2), l1 * np.sin(q1) + l2 * np.sin(q1 + q2)
        pt = {S["l1"]: l1, S["l2"]: l2, S["px"]: x, S["py"]: y}
        found = [tuple(float(sp.N(e.subs(pt))) for e in s) for s in sols]
        for a, b in found:      # each solution reproduces the target, and one of them is the configuration used
            assert np.isclose(l1 * np.cos(a) + l2 * np.cos(a + b), x) and np.isclose(l1 * np.sin(a) + l2 * np.sin(a + b), y)
        assert any(np.isclose(np.angle(np.exp(1j * (a - q1))), 0, atol=1e-8) and
                   np.isclose(np.angle(np.exp(1j * (b - q2))), 0, atol=1e-8) for a, b in found)


def test_elimination_solver_rp_and_families():
    q1, q2 = sp.symbols("q1 q2", real=True)
    l, px, py = sp.Symbol("l", positive=True), sp.Symbol("px", real=True), sp.Symbol("py", real=True)
    eqs = [l * sp.cos(q1) - q2 * sp.sin(q1) - px, l * sp.sin(q1) + q2 * sp.cos(q1) - py]
    fams = Solver([q1, q2], [q2]).solve(eqs)
    kept = check_families(fams, eqs, [q1, q2], lambda rng: (lambda a, b, ll: {
        l: ll, px: ll * np.cos(a) - b * np.sin(a), py: ll * np.sin(a) + b * np.cos(a)})(
        rng.uniform(-3, 3), rng.uniform(-2, 2), rng.uniform(0.5, 2)))
    assert len(kept) == 2
    assert {st.method for st in kept[0].stages} >= {"squares", "quadratic", "pair"}


# ------------------------------------------------------------------------------------- configuration analysis
def test_rank_null_and_range_at_singular_configuration_exact():
    r = solve_text(PLANAR_4R + "  - {kind: kinematics, task: pose, at: {q1: 0, q2: 0, q3: 0, q4: pi/2}}\n")
    J = r["J_at"].value
    assert int(r["rank"].value) == 2 and r["singular"].value is True
    N, R = r["null_basis"].value, r["range_basis"].value
    assert N.shape == (4, 2) and R.shape == (3, 2)
    assert (J * N).applyfunc(sp.simplify) == sp.zeros(3, 2)
    assert sp.Matrix.hstack(J, R).rank() == 2 and R.rank() == 2
    assert r["manipulability_at"].value == 0


def test_rank_with_floats_uses_tolerance():
    text = PLANAR_4R.replace("l2: 0.8", "l2: 0.8123456789") + \
        "  - {kind: kinematics, task: pose, at: {q1: 0.1, q2: 1.0e-13, q3: 0.0, q4: 0.3}, tol: 1.0e-9}\n"
    r = solve_text(text)
    assert int(r["rank"].value) == 2                  # q2 ≈ 0, q3 = 0: singular within the tolerance
    r2 = solve_text(text.replace("tol: 1.0e-9", "tol: 1.0e-15"))
    assert int(r2["rank"].value) == 3


def test_property_checks_accept_any_basis():
    prob = load_problem_text(PLANAR_4R + "  - {kind: kinematics, task: pose, at: {q1: 0, q2: 0, q3: 0, q4: pi/2}}\n")
    res = all_results(solve_problem(prob))
    N = res["null_basis"].value
    other = (2 * N[:, 0] + N[:, 1]).row_join(-N[:, 1])
    check = PROPERTY_CHECKS["null_basis"]
    assert check(prob, res, "null_basis", other.tolist(), None, None).correct
    assert check(prob, res, "null_basis", [[1, 0, 0, 0], [0, 1, 0, 0]], None, None).correct is False
    assert check(prob, res, "null_basis", N[:, 0].T.tolist(), None, None).fraction == 0.5   # one vector short
    Rb = res["range_basis"].value
    check = PROPERTY_CHECKS["range_basis"]
    assert check(prob, res, "range_basis", (Rb * sp.Matrix([[1, 1], [0, 3]])).tolist(), None, None).correct
    assert not check(prob, res, "range_basis", [[1, 0], [0, 1], [0, 0]], None, None).correct


# ------------------------------------------------------------------------------------- sketches and reports
def test_sketch_of_planar_robot_drawn(tmp_path):
    prob = load_problem_text(PLANAR_4R + "  - {kind: kinematics, task: pose, at: {q1: 0.3, q2: 0.5, q3: -0.4, q4: 1}}\n")
    sols = solve_problem(prob)
    fig = sols[0].figures[0]
    pose = fig.panels[0].sketch.poses[0]
    assert len(pose.points) == 5 and pose.joints == ["R"] * 4
    assert pose.points[-1] == pytest.approx(tuple(f(all_results(sols)["p_at"].value[:2, 0], {}).ravel()), abs=1e-9)
    files = write_figures(sols, tmp_path / "r.md", "md")
    assert files and files[0].stat().st_size > 5000


def test_no_sketch_for_spatial_robot():
    sols = solve_problem(load_problem_text(SPATIAL_4R))
    assert sols[0].figures == []


def test_prismatic_sketch_slides_along_axis():
    text = """
id: ppr
title: PPR
symbols: {l: l}
robot: {joints: [P, P, R]}
asks:
  - {kind: kinematics, task: [q1 + l*cos(q3), q2 + l*sin(q3)], at: {q1: 0, q2: 0.5, q3: 1}}
"""
    sols = solve_problem(load_problem_text(text))
    pose = sols[0].figures[0].panels[0].sketch.poses[0]
    assert pose.slides[0] == pytest.approx((1.0, 0.0)) and pose.slides[1] == pytest.approx((0.0, 1.0))


@pytest.mark.parametrize("fmt", ["md", "tex"])
def test_report_renders(fmt):
    prob = load_problem_text(PLANAR_4R.replace("joints: [R, R, R, R]", "joints: [R, R, R]").replace(
        ", {a: l4, theta: q4}", "").replace("links: [{}, {}, {}, {}]", "links: [{}, {}, {}]") +
        "  - {kind: kinematics, task: pose, jdot: true, velocities: true, at: {q1: 0, q2: 0, q3: 1}, "
        "target: [1, 1, 0.5]}\n")
    out = render(prob, solve_problem(prob), fmt)
    for word in ("Singular configurations", "Inverse kinematics", "Rank", "Jacobian"):
        assert word in out
    assert "\\sin" in out


def test_spherical_arm_ik_at_a_decimal_target():
    """Spherical RRP arm, target (0.5, 0.5, 1.5): four solutions (q3 = ±√3/2), each on the target; the steps are
    written with the numbers to 4 digits but integer exponents and coefficients exact (q₃², not q₃^{2.0})."""
    prob = load_problem_text("""
id: rrp
title: spherical arm
robot:
  joints: [R, R, P]
asks:
  - kind: kinematics
    task: [q3*cos(q1)*sin(q2), q3*sin(q1)*sin(q2), 1 - q3*cos(q2)]
    singularities: false
    target: [0.5, 0.5, 1.5]
""")
    sols = solve_problem(prob)
    r = all_results(sols)
    assert r["n_ik"].value == 4
    for s_ in r["ik"].value:
        a, b, c = (float(sp.N(v)) for v in s_)
        assert np.allclose([c * np.cos(a) * np.sin(b), c * np.sin(a) * np.sin(b), 1 - c * np.cos(b)], [0.5, 0.5, 1.5])
        assert abs(abs(c) - np.sqrt(3) / 2) < 1e-12
    md = render(prob, sols, "md")
    assert "q_{3}^{2} - 0.75 = 0" in md and "2.0}" not in md and "1.0 q" not in md


def test_state_at_angles_off_pi_is_evaluated_numerically():
    """At q = (3/10, 7/10, -2/5) (not rational multiples of π) J⁻¹, w and the values at the state are floats, not
    exact products of sin(3/10) (the manipulability of a spatial arm ran to 300 KB of LaTeX and 90 s)."""
    prob = load_problem_text("""
id: rrp3
title: spatial RRR arm
robot:
  joints: [R, R, R]
  dh:
    table:
      - {a: 0, alpha: pi/2, d: 1, theta: q1}
      - {a: 1, alpha: 0, d: 0, theta: q2}
      - {a: 1, alpha: 0, d: 0, theta: q3}
    links: [{}, {}, {}]
asks:
  - kind: kinematics
    task: position
    at: {q1: 3/10, q2: 7/10, q3: -2/5}
    singularities: false
""")
    r = all_results(solve_problem(prob))
    q = (0.3, 0.7, -0.4)
    J = np.zeros((3, 3))
    def pos(v):  # noqa: E306  the tip of the arm (DH above)
        a, b = np.cos(v[1]) + np.cos(v[1] + v[2]), np.sin(v[1]) + np.sin(v[1] + v[2])
        return np.array([np.cos(v[0]) * a, np.sin(v[0]) * a, 1 + b])
    for k in range(3):
        dv = np.zeros(3)
        dv[k] = 1e-6
        J[:, k] = (pos(np.array(q) + dv) - pos(np.array(q) - dv)) / 2e-6
    w = r["manipulability_at"].value
    assert w.is_Float and abs(float(w) - abs(np.linalg.det(J))) < 1e-8
    assert all(x.is_Float or x == 0 for x in r["J_inv_at"].value)


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="LaTeX not installed")
def test_report_compiles(tmp_path):
    prob = load_problem_text(SPATIAL_4R.replace("  - kind: kinematics", "  - kind: kinematics\n    jdot: true\n    velocities: true\n    at: {q1: 0, q2: 0.5, q3: 1, q4: 0}"))
    tex = render(prob, solve_problem(prob), "tex")
    (tmp_path / "k.tex").write_text(tex)
    res = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "k.tex"], cwd=tmp_path,
                         capture_output=True, timeout=120)
    assert res.returncode == 0, res.stdout.decode(errors="replace")[-2000:]


# ------------------------------------------------------------------------------------- errors
@pytest.mark.parametrize("ask, line, words", [
    ("  - {kind: kinematics, task: [[q1, q2], [q2, q1]]}\n", 12, "must be a vector"),
    ("  - {kind: kinematics, at: {q9: 1}}\n", 12, "not a coordinate"),
    ("  - {kind: kinematics, task: [q1, q2], target: [1, 2, 3]}\n", 12, "target must have 2 components"),
    ("  - {kind: kinematics, task: [q1 + q2, q3], target: [1, 2]}\n", 12, "as many task components"),
    ("  - {kind: kinematics, wrt: [zz]}\n", 12, "unknown variable"),
    ("  - {kind: kinematics, frame: 7}\n", 12, "frame must be between"),
    ("  - {kind: kinematics, task: [l1, l2]}\n", 12, "does not depend on the joint coordinates"),
])
def test_bad_specs_are_user_errors_at_the_line(ask, line, words):
    text = PLANAR_4R + ask
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem_text(text))
    assert words in str(exc.value)
    assert exc.value.place is not None and exc.value.place.line == line


def test_explicit_robot_needs_a_task():
    text = "id: x\ntitle: x\nrobot: {joints: [R, R]}\nasks:\n  - {kind: kinematics}\n"
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem_text(text))
    assert "no DH frames" in str(exc.value)


def test_a_task_that_is_not_a_trigonometric_polynomial_is_solved_not_crashed():
    """A distance (a square root of a function of q) as the task: the Jacobian is its gradient (finite
    differences) and the singular set is stated as the equations it cannot solve, no internal error."""
    from solver.spec import load_problem_text
    p = load_problem_text("""
id: sq
title: distance task
robot: {joints: [R, R]}
asks:
  - kind: kinematics
    task: [sqrt((cos(q1) + cos(q1+q2) - 2)^2 + (sin(q1) + sin(q1+q2))^2)]
""")
    res = all_results(solve_problem(p))
    q1, q2 = p.robot.q
    f = lambda a, b: math.hypot(math.cos(a) + math.cos(a + b) - 2, math.sin(a) + math.sin(a + b))  # noqa: E731
    a, b, h = 0.3, 1.1, 1e-6
    J = res["J"].value.subs({q1: a, q2: b}).evalf()
    assert abs(J[0, 0] - (f(a + h, b) - f(a - h, b)) / (2 * h)) < 1e-6
    assert abs(J[0, 1] - (f(a, b + h) - f(a, b - h)) / (2 * h)) < 1e-6


# ------------------------------------------------------------------------------------- check = solve's errors
SPATIAL_3R = """robot:
  joints: [R, R, R]
  dh:
    table: [{d: d1, alpha: pi/2, theta: q1}, {a: a2, theta: q2}, {a: a3, theta: q3}]
    links: [{}, {}, {}]
"""


@pytest.mark.parametrize("robot, ask, words", [
    ("robot: {joints: [R, R, R]}\n", "  - {kind: kinematics, task: [cos(q1) + cos(q1 + q2) + q4, sin(q1)]}\n",
     "unknown name 'q4'"),
    (SPATIAL_3R, "  - {kind: kinematics, task: pose}\n", "task: pose is for planar robots"),
    ("robot: {joints: [R, R, R]}\n", "  - {kind: kinematics, task: [q1, q2], sketch: {at: [{q4: 1}]}}\n",
     "'q4' is not a coordinate"),
], ids=["q4-in-task", "pose-of-a-spatial-arm", "q4-in-sketch"])
def test_check_reports_the_error_solve_raises(write, robot, ask, words):
    """`check` reads each ask's options as `solve` does (the kind's validate hook): the same message at the ask's
    line, exit 2 — before, `check` said ok for these (no expected: values, so nothing was solved)."""
    head = "id: x\ntitle: x\nsymbols: {d1: base height, a2: upper arm, a3: forearm}\n" + robot + "asks:\n"
    check, solve = check_and_solve(write(head + ask))
    assert check.returncode == solve.returncode == 2, check.stdout + check.stderr
    assert check.stderr == solve.stderr and words in check.stderr, check.stderr
    assert f"spec.yaml:{head.count(chr(10)) + 1}:" in check.stderr and "Traceback" not in check.stderr


def test_jacobian_dot_entry_by_entry(monkeypatch: pytest.MonkeyPatch) -> None:
    """J̇ is differentiated entry by entry (Matrix.diff goes through sympy's array derivatives, several times
    slower): the same entries as Σ_k (∂J/∂q_k) q̇_k with Matrix.diff, on a planar RP arm with an offset."""
    q1, q2, dq1, dq2, a = sp.symbols("q1 q2 dq1 dq2 a", real=True)
    J = sp.Matrix([[-(a + q2) * sp.sin(q1) - sp.cos(2 * q1), sp.cos(q1)], [(a + q2) * sp.cos(q1), sp.sin(q1)]])
    want = (J.diff(q1) * dq1 + J.diff(q2) * dq2).applyfunc(lambda e: sp.factor_terms(tidy(e)))

    def refuse(*args: object, **kw: object) -> None:
        raise AssertionError("Matrix.diff called")
    monkeypatch.setattr(sp.MatrixBase, "diff", refuse)
    assert geo.jacobian_dot(J, [q1, q2], [dq1, dq2]) == want
    assert want[0, 1] == -sp.sin(q1) * dq1


def test_number_is_zero_agrees_with_simplify():
    """The zero test of exact rank decisions gives simplify(e) == 0's answer: zeros written with radicals that do not
    cancel as written, and non-zero numbers, some very close to zero."""
    r2, r3, r6 = sp.sqrt(2), sp.sqrt(3), sp.sqrt(6)
    zeros = [sp.Integer(0), (1 + r2) ** 2 - 3 - 2 * r2, r2 * r3 - r6, sp.sqrt(3 + 2 * r2) - 1 - r2,
             (r2 / 2 + sp.Rational(7, 20)) * (r2 / 2) - sp.Rational(7, 20) * r2 / 2 - sp.Rational(1, 2),
             sp.Mul(sp.sqrt(8), sp.Rational(1, 2), evaluate=False) - r2]
    nonzeros = [sp.Rational(1, 7), r2 - sp.Rational(99, 70), (1 + r2) ** 2 - 3 - r2, sp.sqrt(3 + 2 * r2) - r2,
                (r2 - 1) ** 20, -7 * r2 / 20 + sp.Rational(1, 10**12)]
    for e in zeros + nonzeros:
        assert geo.number_is_zero(e) == (sp.simplify(e) == 0), e
    assert all(geo.number_is_zero(e) for e in zeros) and not any(geo.number_is_zero(e) for e in nonzeros)
    # (r2 - 1)^40 ~ 5e-16 and tiny numbers of that kind are decided exactly, not by their magnitude
    assert not geo.number_is_zero((r2 - 1) ** 60)
