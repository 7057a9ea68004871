"""The `collision` ask: the momentum residual converges to the simulated τ_ext (it is the first-order filter of
it), ṗ = u + Sᵀq̇ − g − F_v q̇ + τ_ext equals d/dt(B q̇) along a simulated motion, the energy residual, the structure
of J_cᵀ F (rank, null space, isolation, identification of F and of the contact location) on a planar 4R and a
spatial 3R, estimation from a measured torque, property checks for grading, spec errors, reports, encoded exams."""
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, error_found_without_solving

from solver.interaction.collision import _factored, first_order_filter, numeric_rank, simulate_collision
from solver.math.simplify import factor_within
from solver.dynamics.model import derive
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem

# a spatial 3R (anthropomorphic arm) with viscous friction, under gravity: used by no exercise
SPATIAL_3R = """
id: s3r
title: spatial 3R
symbols: {d1: d1, a2: a2, a3: a3, m1: m1, m2: m2, m3: m3, g0: g0, fv: fv}
values: {d1: 0.5, a2: 0.6, a3: 0.4, m1: 4, m2: 3, m3: 2, g0: 9.81, fv: 0.3}
robot:
  joints: [R, R, R]
  gravity: [0, 0, -g0]
  friction: {viscous: [fv, fv, fv]}
  dh:
    table: [{alpha: pi/2, d: d1, theta: q1}, {a: a2, theta: q2}, {a: a3, theta: q3}]
    links:
      - {mass: m1, com: [0, -d1/2, 0], inertia: [0.05, 0.02, 0.05]}
      - {mass: m2, com: [-a2/2, 0, 0], inertia: [0.01, 0.09, 0.09]}
      - {mass: m3, com: [-a3/2, 0, 0], inertia: [0.005, 0.03, 0.03]}
asks:
"""

# a planar 4R (kinematics only): used by no exercise
PLANAR_4R = """
id: p4r
title: planar 4R
symbols: {l1: l1, l2: l2, l3: l3, l4: l4, rho: location on link 4}
values: {l1: 1, l2: 0.8, l3: 0.6, l4: 0.5}
robot:
  joints: [R, R, R, R]
  links:
    - {com: [l1*cos(q1), l1*sin(q1)]}
    - {com: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]}
    - {com: [l1*cos(q1) + l2*cos(q1 + q2) + l3*cos(q1 + q2 + q3), l1*sin(q1) + l2*sin(q1 + q2) + l3*sin(q1 + q2 + q3)]}
    - {com: [0, 0]}
asks:
  - kind: collision
    contacts:
"""
P4 = ["l1*cos(q1)", "l1*sin(q1)"]


def point_4r(link: int, frac: str = "1/2") -> str:
    """The point at a fraction of link k of the planar 4R, as the spec writes it."""
    angles = ["q1", "q1 + q2", "q1 + q2 + q3", "q1 + q2 + q3 + q4"]
    lens = ["l1", "l2", "l3", "l4"]
    xs = [f"{lens[j]}*cos({angles[j]})" for j in range(link - 1)] + [f"{frac}*{lens[link - 1]}*cos({angles[link - 1]})"]
    ys = [f"{lens[j]}*sin({angles[j]})" for j in range(link - 1)] + [f"{frac}*{lens[link - 1]}*sin({angles[link - 1]})"]
    return f"[{' + '.join(xs)}, {' + '.join(ys)}]"


def solved(text):
    p = load_problem_text(text)
    sols = solve_problem(p)
    return p, sols, all_results(sols)


def num(M, subs=None) -> np.ndarray:
    M = sp.Matrix(M)
    if subs:
        M = M.subs(subs)
    return np.array(M.evalf(20).tolist(), dtype=float)


# ------------------------------------------------------------------------------------------------ simulation
@pytest.fixture(scope="module")
def spatial():
    text = SPATIAL_3R + """  - kind: collision
    contacts:
      - {link: 3, point: [-0.1, 0.05, 0], point_in: link}
"""
    p = load_problem_text(text)
    return p, derive(p.robot), all_results(solve_problem(p))


def _contact_point(p, link=3, local=(-0.1, 0.05, 0.0)):
    from solver.interaction.collision import _dh_frames
    pos, R = _dh_frames(p)[link - 1]
    return (pos + R * sp.Matrix(local))


def test_momentum_residual_is_the_filtered_external_torque(spatial):
    """r stays 0 while the robot moves without contact, then r = first-order filter of τ_ext = J_cᵀF(t) (computed
    independently from the simulated τ_ext), and converges to it under a steady contact."""
    p, dm, _ = spatial
    robot = p.robot
    K = 25.0
    data = simulate_collision(dm, robot.q, robot.dq, _contact_point(p), p.values, np.array([2.0, -3.0, 5.0]),
                              0.4, 1.4, 1.8, np.full(3, K), 20.0, np.array([0.3, 0.5, -0.8]),
                              np.array([0.4, -0.3, 0.6]), control="pd", kp=60, kd=15, samples=1800)
    before = data.t < 0.4
    assert np.abs(data.dq[before]).max() > 0.05                  # the robot moves ...
    assert np.abs(data.r[before]).max() < 1e-6                   # ... and the residual ignores it
    for j in range(3):
        ref = first_order_filter(data.t, data.tau_ext[:, j], K, jumps=(0.4, 1.4))
        assert np.abs(data.r[:, j] - ref).max() < 2e-3 * max(1.0, np.abs(data.tau_ext[:, j]).max())
    settle = (data.t > 1.2) & (data.t < 1.4)                     # 0.8 s into the contact = 20 time constants
    assert np.abs(data.r[settle] - data.tau_ext[settle]).max() < 0.02 * np.abs(data.tau_ext).max()
    assert np.abs(data.tau_ext[settle]).max() > 0.5             # a real contact torque was there to track
    after = data.t > 1.75
    assert np.abs(data.r[after]).max() < 0.01 * np.abs(data.tau_ext).max()


def test_energy_residual_filters_the_contact_power(spatial):
    p, dm, _ = spatial
    robot = p.robot
    kE = 30.0
    data = simulate_collision(dm, robot.q, robot.dq, _contact_point(p), p.values, np.array([0.0, 4.0, -2.0]),
                              0.3, 0.9, 1.2, np.full(3, 20.0), kE, np.array([0.0, 0.7, -0.5]),
                              np.array([0.5, 0.2, -0.4]), control="gravity", profile="pulse", samples=1500)
    assert np.abs(data.sigma[data.t < 0.3]).max() < 1e-6
    ref = first_order_filter(data.t, data.power, kE, jumps=(0.3, 0.9))
    assert np.abs(data.sigma - ref).max() < 3e-3 * max(1.0, np.abs(data.power).max())
    assert np.abs(data.power).max() > 0.1


def test_pdot_formula_equals_derivative_of_momentum_along_a_motion(spatial):
    """The symbolic ṗ = u + Sᵀq̇ − g − F_v q̇ + τ_ext (result `pdot`) against finite differences of B(q(t))q̇(t)
    along a motion simulated with an arbitrary u(t) and τ_ext(t)."""
    from scipy.integrate import solve_ivp
    p, dm, res = spatial
    robot = p.robot
    vals = {k: float(v) for k, v in p.values.items()}
    q, dq, u = robot.q, robot.dq, robot.inputs
    tau = [p.names[f"tau_ext{i + 1}"] for i in range(3)]
    B = sp.lambdify(q, dm.B.subs(vals), "numpy")
    rest = sp.lambdify(q + dq, (dm.c + dm.g + dm.Fv * sp.Matrix(dq)).subs(vals), "numpy")
    pdot = sp.lambdify(q + dq + u + tau, res["pdot"].value.subs(vals), "numpy")
    uf = lambda t: np.array([3 * np.sin(2 * t), 20 + np.cos(3 * t), 2 * np.sin(t)])  # noqa: E731
    tf = lambda t: np.array([0.5 * t, -np.sin(4 * t), 0.3])  # noqa: E731

    def rhs(t, z):
        x, v = z[:3], z[3:]
        a = np.linalg.solve(B(*x), uf(t) + tf(t) - np.asarray(rest(*x, *v), dtype=float).ravel())
        return np.concatenate([v, a])

    ts = np.linspace(0, 1.5, 301)
    sol = solve_ivp(rhs, (0, 1.5), [0.2, 0.4, -0.6, 0.3, -0.2, 0.5], t_eval=ts, rtol=1e-11, atol=1e-12)
    P = np.array([B(*z[:3]) @ z[3:] for z in sol.y.T])
    fd = np.gradient(P, ts, axis=0, edge_order=2)
    for k in range(5, len(ts) - 5, 25):
        z = sol.y[:, k]
        formula = np.asarray(pdot(*z, *uf(ts[k]), *tf(ts[k])), dtype=float).ravel()
        assert np.allclose(formula, fd[k], atol=2e-3 * max(1.0, np.abs(fd[k]).max())), (ts[k], formula, fd[k])
    assert res["rdot_check"].value is True and res["energy_check"].value is True


def test_residual_dynamics_are_derived_not_assumed(spatial):
    _, _, res = spatial
    r = res["rdot"].value
    assert all(sp.simplify(x - sp.Symbol(f"kI{i + 1}", positive=True) * (sp.Symbol(f"tau_ext{i + 1}", real=True)
                                                                       - sp.Symbol(f"r{i + 1}", real=True))) == 0
               for i, x in enumerate(r))


# ------------------------------------------------------------------------------------------------ structure
@pytest.fixture(scope="module")
def planar4():
    text = PLANAR_4R + "".join(f"      - {{link: {k}, point: {point_4r(k)}, angle: {' + '.join(f'q{j}' for j in range(1, k + 1))}}}\n"
                               for k in (1, 2, 3, 4))
    text += f"      - {{link: 4, point: {point_4r(4, 'rho/l4')}, location: rho}}\n"
    return solved(text)


def test_planar_4r_rank_and_zero_pattern(planar4):
    """A contact on link k: J_c has zero columns k+1..4, rank 1 on link 1 and 2 beyond; N(J_1ᵀ) is the direction of
    link 1; a force with J_cᵀF ≠ 0 is isolated on link k."""
    p, _, r = planar4
    rng = np.random.default_rng(3)
    for k in (1, 2, 3, 4):
        J = r[f"Jc_{k}"].value
        assert all(x == 0 for x in J[:, k:])
        assert int(r[f"rank_Jc_{k}"].value) == (1 if k == 1 else 2)
        assert r[f"isolated_link_{k}"].value == k and r[f"identifiable_{k}"].value is (k > 1)
        point = {s: float(v) for s, v in p.values.items()}
        point.update({x: float(rng.uniform(-2, 2)) for x in p.robot.q})
        Jn = num(J, point)
        F = rng.normal(size=2)
        tau = Jn.T @ F
        assert np.allclose(tau[k:], 0)
        if k > 1:   # the symbolic estimate from r = J_cᵀF gives F back
            Fhat = num(r[f"F_id_{k}"].value, {**point, **{p.names[f"r{i + 1}"]: tau[i] for i in range(4)}})
            assert np.allclose(Fhat.ravel(), F, atol=1e-9)
    N = r["null_JcT_1"].value
    assert all(sp.simplify(x) == 0 for x in r["Jc_1"].value.T * N)
    q1 = p.robot.q[0]
    assert sp.simplify(N[1] * sp.cos(q1) - N[0] * sp.sin(q1)) == 0   # along link 1: (c1, s1)


def test_planar_4r_location_identified_with_the_force(planar4):
    """On link 4 the 4 residual components determine F (2) and the location ρ: the formulas invert J_cᵀ(ρ)F."""
    p, _, r = planar4
    rho = p.symbols["rho"]
    rng = np.random.default_rng(5)
    for _ in range(3):
        point = {s: float(v) for s, v in p.values.items()}
        point.update({x: float(rng.uniform(-2, 2)) for x in p.robot.q})
        F, rho_v = rng.normal(size=2), 0.37
        J = num(r["Jc_5"].value, {**point, rho: rho_v})
        tau = J.T @ F
        rs = {p.names[f"r{i + 1}"]: tau[i] for i in range(4)}
        assert np.allclose(num(r["F_id_5"].value, {**point, **rs}).ravel(), F, atol=1e-9)
        assert float(r["location_id_5"].value.subs({**point, **rs})) == pytest.approx(rho_v, abs=1e-9)


def test_spatial_3r_rank_structure():
    """Spatial forces F ∈ R³: rank J_c = 1, 2, 3 on links 1, 2, 3 (generic), with null spaces of J_cᵀ of
    dimension 2, 1, 0 that J_cᵀ maps to zero."""
    text = SPATIAL_3R + """  - kind: collision
    residuals: []
    contacts:
      - {link: 1, point: [0.05, -0.2, 0], point_in: link}
      - {link: 2, point: [-0.3, 0, 0.02], point_in: link}
      - {link: 3, point: [-0.1, 0.05, 0], point_in: link}
"""
    p, _, r = solved(text)
    for k, rank in ((1, 1), (2, 2), (3, 3)):
        assert int(r[f"rank_Jc_{k}"].value) == rank
        assert r[f"identifiable_{k}"].value is (rank == 3)
        if rank < 3:
            N = r[f"null_JcT_{k}"].value
            assert N.shape == (3, 3 - rank)
            assert all(sp.simplify(x) == 0 for x in r[f"Jc_{k}"].value.T * N)
        else:
            assert f"null_JcT_{k}" not in r
        # the point is on link k: its Jacobian has zero columns after k
        assert all(x == 0 for x in r[f"Jc_{k}"].value[:, k:])


def test_estimate_from_torque_at_rest_matches_the_force_that_produced_it():
    """A force F on link 2 of a planar RRR in a vertical plane: the torque u = g(q) − J_cᵀF holds the robot at rest,
    and the ask recovers τ_ext = J_cᵀF (isolated on link 2) and F exactly."""
    text = """
id: rrr
title: planar RRR, vertical
symbols: {m: m, l: l, g0: g0}
values: {m: 2, l: 0.5, g0: 9.81}
robot:
  joints: [R, R, R]
  gravity: [0, -g0]
  links:
    - {mass: m, com: [l/2*cos(q1), l/2*sin(q1)], angle: q1, inertia: m*l^2/12}
    - {mass: m, com: [l*cos(q1) + l/2*cos(q1 + q2), l*sin(q1) + l/2*sin(q1 + q2)], angle: q1 + q2, inertia: m*l^2/12}
    - {mass: m, com: [l*cos(q1) + l*cos(q1 + q2) + l/2*cos(q1 + q2 + q3), l*sin(q1) + l*sin(q1 + q2) + l/2*sin(q1 + q2 + q3)], angle: q1 + q2 + q3, inertia: m*l^2/12}
asks:
  - kind: collision
    residuals: []
    at: {q1: 0.4, q2: 0.9, q3: -0.5}
    contacts:
      - link: 2
        point: [l*cos(q1) + 0.3*cos(q1 + q2), l*sin(q1) + 0.3*sin(q1 + q2)]
        angle: q1 + q2
        torque: {gravity: true, joint: [JT1, JT2, 0]}
"""
    q = np.array([0.4, 0.9, -0.5])
    J = np.array([[-0.5 * np.sin(q[0]) - 0.3 * np.sin(q[0] + q[1]), -0.3 * np.sin(q[0] + q[1]), 0],
                  [0.5 * np.cos(q[0]) + 0.3 * np.cos(q[0] + q[1]), 0.3 * np.cos(q[0] + q[1]), 0]])
    F = np.array([3.0, -7.0])
    tc = J.T @ F
    text = text.replace("JT1", repr(float(-tc[0]))).replace("JT2", repr(float(-tc[1])))
    _, _, r = solved(text)
    assert np.allclose(num(r["tau_ext_1"].value).ravel(), tc, atol=1e-9)
    assert np.allclose(num(r["F_hat_1"].value).ravel(), F, atol=1e-9)
    assert int(r["isolated_link_data_1"].value) == 2
    R = np.array([[np.cos(q[0] + q[1]), -np.sin(q[0] + q[1])], [np.sin(q[0] + q[1]), np.cos(q[0] + q[1])]])
    assert np.allclose(num(r["F_hat_local_1"].value).ravel(), R.T @ F, atol=1e-9)


def test_rank_deficient_estimate_is_the_minimum_norm_one():
    """On link 1 only the normal force is seen: F̂ = (J_cᵀ)^# τ_ext is orthogonal to the link, τ_ext is reproduced."""
    text = (PLANAR_4R + f"""      - {{link: 1, point: {point_4r(1)}, residual: [1.5, 0, 0, 0]}}
""").replace("asks:\n  - kind: collision\n", "asks:\n  - kind: collision\n    at: {q1: 0.7, q2: 0, q3: 0, q4: 0}\n")
    _, _, r = solved(text)
    F = num(r["F_hat_1"].value).ravel()
    J = num(r["Jc_at_1"].value)
    assert np.allclose(J.T @ F, [1.5, 0, 0, 0])
    assert abs(F @ np.array([np.cos(0.7), np.sin(0.7)])) < 1e-12     # no component along the link
    assert np.allclose(F, np.linalg.pinv(J.T) @ np.array([1.5, 0, 0, 0]))


# ------------------------------------------------------------------------------------------------ grading
def test_property_checks_for_the_residual_and_the_null_space():
    from solver.interaction.collision import _null_check, check_residual_integrand
    p = load_problem(PROBLEMS / "2019-07-11-ex2.yaml")
    res = all_results(solve_problem(p))
    n = p.names
    q1, q2, dq1, dq2, m2, dc2, g0 = (n[k] for k in ("q1", "q2", "dq1", "dq2", "m2", "dc2", "g0"))
    tau1, tau2 = n["tau1"], n["tau2"]
    # S^T q̇ written as Ḃq̇ − c: the same integrand in another form
    good = [tau1 - m2 * g0 * (q2 - dc2) * sp.cos(q1) + 2 * m2 * (q2 - dc2) * dq1 * dq2 - 2 * m2 * (q2 - dc2) * dq1 * dq2,
            tau2 + m2 * (q2 - dc2) * dq1 ** 2 - m2 * g0 * sp.sin(q1)]
    v = check_residual_integrand(p, res, "residual_integrand", good, lambda _: None, None)
    assert v.correct and v.fraction == 1.0
    # a non-skew factorization: S = [[0, 2 m2 (q2-dc2) dq1], [-m2 (q2-dc2) dq1, 0]] gives S^T q̇ = (-m2(q2-dc2)dq1^2, 2 m2(q2-dc2)dq1^2)... wrong
    bad = [tau1 - m2 * g0 * (q2 - dc2) * sp.cos(q1) - m2 * (q2 - dc2) * dq1 * dq2,
           tau2 + 2 * m2 * (q2 - dc2) * dq1 ** 2 - m2 * g0 * sp.sin(q1)]
    v = check_residual_integrand(p, res, "residual_integrand", bad, lambda _: None, None)
    assert not v.correct and "component(s) 1, 2" in v.feedback[0]

    p2 = load_problem(PROBLEMS / "2021-01-12-ex5.yaml")
    res2 = all_results(solve_problem(p2))
    assert _null_check(p2, res2, "null_JcT_1", [[0], [-7]], None, None).correct          # any scale
    assert not _null_check(p2, res2, "null_JcT_1", [[1], [0]], None, None).correct       # detected force


def test_grader_accepts_a_scaled_undetectable_force(tmp_path):
    from solver.grading.grader import grade, prepare
    from solver.grading.submission import load_submission
    p = load_problem(PROBLEMS / "2018-06-11-ex1.yaml")
    ref = prepare(p)
    sub = tmp_path / "s.yaml"
    sub.write_text('null_JcT_1: "[[-2*cos(q1)], [-2*sin(q1)]]"\nF_misisolated_2: "[[sin(q1)], [cos(q1)]]"\n')
    report = grade(ref, load_submission(sub))
    items = {i.name: i for i in report.items}
    assert items["null_JcT_1"].verdict == "correct"
    assert items["F_misisolated_2"].verdict == "incorrect"


# ------------------------------------------------------------------------------------------------ spec errors
BASE_2R = """
id: e
title: errors
symbols: {l1: l1, l2: l2}
robot:
  joints: [R, R]
  links:
    - {com: [l1*cos(q1), l1*sin(q1)]}
    - {com: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]}
asks:
  - kind: collision
    contacts:
"""


@pytest.mark.parametrize("entry, message, line", [
    ("      - {link: 3, point: [l1*cos(q1), l1*sin(q1)]}\n", "contact on link 3, but the robot has 2 links", 13),
    ("      - {link: 1, point: [l1*cos(q1), l1*sin(q1), 0, 1]}\n", "2 (planar) or 3 (spatial) components", 13),
    ("      - link: 1\n        point: l1*cos(q1)\n", "2 (planar) or 3 (spatial) components", 14),
    ("      - {link: 1, point: [l1*cos(q1) + l2*cos(q1 + q2), 0]}\n", "depends on q2", 13),
    ("      - {link: 2, point: [l1*cos(q1), l1*sin(q1)], force: [1, 2, 3]}\n", "must have 2 components", 13),
    ("      - {link: 2, point: [l1*cos(q1), l1*sin(q1)], location: l9}\n", "location: 'l9'", 13),
])
def test_bad_contacts_are_spec_errors_at_their_line(entry, message, line):
    with pytest.raises(UserError) as e:
        solve_problem(load_problem_text(BASE_2R + entry, "bad.yaml"))
    assert message in e.value.message
    assert e.value.place.line == line


def test_momentum_residual_needs_a_factorization():
    text = BASE_2R.replace("    - {com: [l1*cos(q1) + l2", "    - {mass: 1, com: [l1*cos(q1) + l2").replace(
        "asks:", "  model: {c: [0, 0]}\nasks:") + "      - {link: 1, point: [l1*cos(q1), l1*sin(q1)]}\n"
    with pytest.raises(UserError) as e:
        solve_problem(load_problem_text(text, "bad.yaml"))
    assert "Christoffel" in e.value.message


def test_torque_estimate_needs_rest():
    text = BASE_2R.replace("    contacts:", "    at: {q1: 0, q2: 1, dq1: 0.5}\n    contacts:") + \
        "      - {link: 2, point: [l1*cos(q1), l1*sin(q1)], torque: [1, 0]}\n"
    with pytest.raises(UserError) as e:
        solve_problem(load_problem_text(text, "bad.yaml"))
    assert "static equilibrium" in e.value.message


def test_check_exits_2_without_traceback(write):
    path = write(BASE_2R + "      - {link: 5, point: [l1*cos(q1), l1*sin(q1)]}\n")
    r = subprocess.run(["robosolve", "solve", str(path)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr + r.stdout and ":13:" in r.stderr + r.stdout


# ------------------------------------------------------------------------------------------------ reports, exams
COLLISION_PROBLEMS = ["2011-06-17-ex1", "2013-07-15-ex1", "2014-10-27-ex1", "2017-07-11-ex3", "2018-06-11-ex1",
                      "2019-07-11-ex2", "2020-06-05-remote-ex6", "2021-01-12-ex5"]


@pytest.mark.parametrize("name", COLLISION_PROBLEMS)
def test_encoded_exams_verify(name):
    rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
    assert rep.ok, [(c.name, c.verdict) for c in rep.checks if not c.verdict.ok]
    assert "COLLISION" in load_problem(PROBLEMS / f"{name}.yaml").topics


def test_markdown_report_explains_detection_and_isolation():
    p = load_problem(PROBLEMS / "2020-06-05-remote-ex6.yaml")
    md = render(p, solve_problem(p), "md")
    assert "isolated on link 1 (**wrong**)" in md
    assert "the energy residual does **not** detect the collision" in md
    assert "\\mathcal{N}(J_c^T)" in md


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="needs pdflatex")
def test_latex_report_with_the_simulation_figure_compiles(tmp_path):
    from solver.publish.figures import write_figures
    p = load_problem(PROBLEMS / "2017-07-11-ex3.yaml")
    sols = solve_problem(p)
    figs = write_figures(sols, tmp_path / "r.tex", "tex")
    assert any("residuals" in f.name for f in figs)
    panels = next(f for s in sols for f in s.figures if "residuals" in f.name).panels
    r1, tau1 = panels[0].curves
    assert abs(r1.y[-1]) < 1e-2 and max(tau1.y) == pytest.approx(1.887, rel=2e-2)  # r tracked J_c^T F, then left
    (tmp_path / "r.tex").write_text(render(p, sols, "tex"))
    out = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "r.tex"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=180)
    assert out.returncode == 0, out.stdout[-2000:]


@pytest.mark.parametrize("entry, message", [
    ("      - {link: 3, point: [l1*cos(q1), l1*sin(q1)]}\n", "contact on link 3, but the robot has 2 links"),
    ("      - {link: 1, point: [l1*cos(q1) + l2*cos(q1 + q2), 0]}\n", "depends on q2"),
    ("      - {link: 2, point: [l1*cos(q1), l1*sin(q1)], force: [1, 2, 3]}\n", "must have 2 components"),
    ("      - {link: 2, point: [l1*cos(q1), l1*sin(q1)], location: l9}\n", "location: 'l9'"),
    ("      - {link: 2, point: [l1*cos(q1), l1*sin(q1)], residual: [1, 0]}\n", "residual: needs the at: config"),
])
def test_check_finds_bad_contacts_without_solving(entry, message):
    """Each contact is read by the kind's validate hook (`check`) as by solving: the same error."""
    assert message in error_found_without_solving(BASE_2R + entry)


def test_rational_nullspace_is_sympys_simplified_nullspace():
    """identify_with_location's combinations: the exact Gauss-Jordan gives sympy's nullspace(simplify=True) where
    the basis is rational (the case it takes), and falls back to it for a symbolic basis."""
    import sympy as sp

    from solver.interaction.collision import rational_nullspace
    q1, q2, a = sp.symbols("q1 q2 a")
    th = q1 + q2
    # (sympy's simplify=True gives [-1, 1] here in 0.4 s; the exact route in milliseconds)
    assert rational_nullspace(sp.Matrix([[sp.sin(th), sp.sin(th)], [-sp.cos(th), -sp.cos(th)]])) == [sp.Matrix([-1, 1])]
    for M in (sp.Matrix([[sp.sin(q1) ** 2 + sp.cos(q1) ** 2, -1]]), sp.Matrix([[sp.sin(q1), a * sp.cos(q1), 1]])):
        assert rational_nullspace(M) == M.nullspace(simplify=True)


def test_numeric_rank_exact_over_number_field_matches_simplify():
    """The rank of exact matrices over QQ<θ> agrees with Gauss elimination using sympy's simplify as the zero test,
    including rank drops hidden in radicals (√(2 + √3)·(√6 − √2)/2 = 1) and entries with π (the simplify path)."""
    r2, r3, r6 = sp.sqrt(2), sp.sqrt(3), sp.sqrt(6)
    cases = [
        sp.Matrix([[-7 * r2 / 40, 3 * r2 / 40, 0], [13 * r2 / 40, 3 * r2 / 40, 0]]),
        sp.Matrix([[r3 / 2, sp.Rational(1, 2), 0], [r3, 1, 0]]),
        sp.Matrix([[sp.sqrt(2 + r3), 1], [1, (r6 - r2) / 2]]),
        sp.Matrix([[r2 + r3, 1], [1, r3 - r2]]),
        sp.Matrix([[sp.I, 1], [1, -sp.I]]),
        sp.Matrix([[1, 2, 3], [2, 4, 6]]),
        sp.Matrix([[sp.pi, 1], [2, 2 / sp.pi]]),
        sp.zeros(2, 3),
    ]
    for M in cases:
        assert numeric_rank(M) == M.rank(iszerofunc=lambda x: sp.simplify(x) == 0), M


def test_factored_is_factor_of_cancel():
    """_factored(x) reads the factors of x directly; the same expression as factor_within(cancel(x))."""
    import random
    q1, q2, q3, l1, l2, r1, r2, r3 = sp.symbols("q1 q2 q3 l1 l2 r1 r2 r3")
    atoms = [sp.sin(q1), sp.cos(q1 + q2), sp.sin(q1 + q2), sp.cos(q1 + q2 + q3), sp.sin(q2), l1, l2, r1, r2]
    rng = random.Random(3)

    def poly(k: int) -> sp.Expr:
        return sum(rng.randint(-2, 2) * sp.Mul(*rng.sample(atoms, rng.randint(1, 3))) for _ in range(k))
    cases = [(-l1 * r2 * sp.cos(q1) + l2 * r1 * sp.cos(q1 + q2)) / (l1 * l2 * sp.sin(q2)),
             l1 * l2 * r3 * sp.sin(q2) / (l1 * r2 * sp.sin(q1) * sp.cos(q1 + q2 + q3) - l2 * r1 * sp.sin(q1 + q2)),
             (r1 - r2) / (l1 * (r2 - r1)) + r3 / l2, sp.Rational(1, 2), sp.sqrt(2) * q1 / (q1 + q1 * q2)]
    cases += [poly(rng.randint(1, 3)) * poly(2) / (poly(rng.randint(1, 3)) or 1) for _ in range(30)]
    checked = 0
    for x in cases:
        if x.has(sp.zoo, sp.nan):
            continue
        assert sp.srepr(_factored(x)) == sp.srepr(factor_within(sp.cancel(x))), x
        assert sp.srepr(_factored(x, together=True)) == sp.srepr(factor_within(sp.cancel(sp.together(x)))), x
        checked += 1
    assert checked > 25
