"""The control_law variants: PD with constant gravity compensation, a general Γ, suffixes, the adaptive u graded by
property, Cartesian computed torque, partial feedback linearization (collocated and not), feedback linearization of
elastic joints and the linear approximation with its controllability. Each closed loop is checked by substituting
the law in the model (independently of the solver's own check), on library robots and on robots no exercise uses."""
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, R2_ROBOT, RP_ROBOT, error_found_without_solving

from solver.control.laws import check_control_law
from solver.dynamics.model import derive
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError

R2 = """
id: t2r
title: planar 2R in a vertical plane
symbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, g0: g0}
values: {m1: 2, m2: 1.5, d1: 0.25, d2: 0.2, l1: 0.5, I1: 0.05, I2: 0.03, g0: 9.81}
""" + R2_ROBOT + "asks:\n"
RP = RP_ROBOT + "asks:\n"
RPK = RP_ROBOT + "known: [l1, g0]\nasks:\n"  # 3 dynamic coefficients

# a planar 3R in a vertical plane (no exercise uses it)
R3 = """
id: t3r
title: planar 3R
symbols: {m: m, l: l, g0: g0}
values: {m: 1, l: 0.5, g0: 9.81}
robot:
  joints: [R, R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m, com: [l/2*cos(q1), l/2*sin(q1)], angle: q1, inertia: m*l^2/12}
    - {mass: m, com: [l*cos(q1) + l/2*cos(q1 + q2), l*sin(q1) + l/2*sin(q1 + q2)], angle: q1 + q2, inertia: m*l^2/12}
    - {mass: m, com: [l*cos(q1) + l*cos(q1 + q2) + l/2*cos(q1 + q2 + q3), l*sin(q1) + l*sin(q1 + q2) + l/2*sin(q1 + q2 + q3)], angle: q1 + q2 + q3, inertia: m*l^2/12}
asks:
"""

# a cart with an inverted pendulum on a spring-mounted... : cart-pole (underactuated, no exercise uses it)
CARTPOLE = """
id: cartpole
title: cart-pole
symbols: {mc: mc, mp: mp, L: L, g0: g0}
values: {mc: 1, mp: 0.3, L: 0.6, g0: 9.81}
robot:
  joints: [P, R]
  gravity: [0, -g0, 0]
  input_map: [[1], [0]]
  links:
    - {mass: mc, com: [q1, 0]}
    - {mass: mp, com: [q1 - L*sin(q2), L*cos(q2)]}
asks:
"""

# two elastic joints of a planar 2R in a horizontal plane (reduced model), no exercise uses it
ELASTIC2 = """
id: el2
title: 2R with elastic joints
symbols: {m1: m1, m2: m2, l1: l1, d1: d1, d2: d2, I1: I1, I2: I2, Im1: Im1, Im2: Im2, K1: K1, K2: K2}
robot:
  joints: [R, R, R, R]
  coordinates: [q1, q2, theta1, theta2]
  input_map: [[0, 0], [0, 0], [1, 0], [0, 1]]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) + d2*cos(q1 + q2), l1*sin(q1) + d2*sin(q1 + q2)], angle: q1 + q2, inertia: I2}
  extra:
    kinetic: ["1/2*Im1*dtheta1^2", "1/2*Im2*dtheta2^2"]
    potential: ["1/2*K1*(q1 - theta1)^2", "1/2*K2*(q2 - theta2)^2"]
asks:
"""

ELASTIC1 = """
id: el1
title: one elastic joint under gravity
symbols: {m: m, d: d, I: I, Im: Im, K: K, g0: g0}
robot:
  joints: [R, R]
  coordinates: [q1, theta1]
  gravity: [0, -g0, 0]
  input_map: [[0], [1]]
  links:
    - {mass: m, com: [d*cos(q1), d*sin(q1)], angle: q1, inertia: I}
  extra:
    kinetic: ["1/2*Im*dtheta1^2"]
    potential: ["1/2*K*(q1 - theta1)^2"]
asks:
"""


def solved(text):
    p = load_problem_text(text)
    sols = solve_problem(p)
    return p, sols, all_results(sols)


def accel(p, u):
    """q̈ solved from the full model B q̈ + c + g + F_v q̇ = G u."""
    dm = derive(p.robot)
    n = p.robot.n
    G = dm.G if dm.G is not None else sp.eye(n)
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    return dm.B.LUsolve(G * u - dm.c - dm.g - Fv * sp.Matrix(p.robot.dq))


def random_point(exprs, seed=3):
    rng = np.random.default_rng(seed)
    syms = set()
    for e in exprs:
        syms |= e.free_symbols
    return {s: sp.Rational(int(rng.integers(2, 19)), int(rng.integers(3, 9))) for s in syms}


def vanishes(exprs, seeds=(3, 5)):
    for sd in seeds:
        at = random_point(exprs, sd)
        for e in exprs:
            if abs(complex(sp.N(e.xreplace(at), 30))) > 1e-18:
                return False
    return True


# ---------------------------------------------------------------------------------------------- pd_constant
@pytest.mark.parametrize("head", [R2, RP, R3], ids=["2R", "RP", "3R"])
def test_pd_constant_closed_loop(head):
    p, _, res = solved(head + "  - kind: control_law\n    law: pd_constant\n")
    r = p.robot
    dm = derive(r)
    qd = sp.Matrix([p.names[f"qd{i + 1}"] for i in range(r.n)])
    u = res["u"].value
    gd = dm.g.xreplace(dict(zip(r.q, qd)))
    kp = sp.diag(*[p.names[f"kp{i + 1}"] for i in range(r.n)])
    kd = sp.diag(*[p.names[f"kd{i + 1}"] for i in range(r.n)])
    assert all(sp.simplify(x) == 0 for x in u - (kp * (qd - sp.Matrix(r.q)) - kd * sp.Matrix(r.dq) + gd))
    assert res["closed_loop_check"].value and res["equilibrium_check"].value
    # u does not depend on q through gravity: only through K_P e
    assert all(sp.diff(x + (kp * sp.Matrix(r.q))[i], r.q[j]) == 0 for i, x in enumerate(u) for j in range(r.n))


# ---------------------------------------------------------------------------------------------- suffix, Γ
def test_suffix_keeps_two_laws_apart():
    p, _, res = solved(RP + "  - kind: control_law\n    law: computed_torque\n"
                       "  - kind: control_law\n    law: pd_constant\n    suffix: _c\n")
    assert {"u", "u_c", "closed_loop_check_c", "equilibrium_check_c"} <= set(res)
    assert sp.simplify(res["u"].value[0] - res["u_c"].value[0]) != 0


def test_general_gamma_matrix():
    p, _, res = solved(RPK + "  - kind: control_law\n    law: adaptive\n"
                       "    gamma: [[2, 1, 0], [1, 2, 0], [0, 0, 3]]\n")
    Yr = res["Y_r"].value
    n = p.robot.n
    dqr = sp.Matrix([p.names[f"dqr{i + 1}"] for i in range(n)])
    s = dqr - sp.Matrix(p.robot.dq)
    G = sp.Matrix([[2, 1, 0], [1, 2, 0], [0, 0, 3]])
    assert all(sp.simplify(x) == 0 for x in res["a_hat_dot"].value - G * Yr.T * s)
    with pytest.raises(UserError, match="positive definite"):
        solved(RPK + "  - kind: control_law\n    law: adaptive\n    gamma: [[1, 2, 0], [2, 1, 0], [0, 0, 1]]\n")
    with pytest.raises(UserError, match="symmetric"):
        solved(RPK + "  - kind: control_law\n    law: adaptive\n    gamma: [[1, 1, 0], [0, 1, 0], [0, 0, 1]]\n")


# ---------------------------------------------------------------------------------------------- adaptive u
def test_adaptive_u_property_check():
    p = load_problem(PROBLEMS / "2004-03-25-ex1.yaml")
    sols = solve_problem(p)
    res = all_results(sols)
    u = res["u"].value
    # the solver's u, expanded: accepted
    v = check_control_law(p, res, "u", [sp.expand(x) for x in u], lambda n: None, None)
    assert v is not None and v.correct
    # the printed form u = Y a_hat + K_P e + K_D de with K_P = 2 K_D Lambda (>= K_D Lambda): accepted
    r = p.robot
    Yr = res["Y_r"].value
    ah = sp.Matrix([p.names[f"ahat{i + 1}"] for i in range(3)])
    lam = [p.names["lambda1"], p.names["lambda2"]]
    kd = [p.names["kd1"], p.names["kd2"]]
    e = [p.names[f"qd{i + 1}"] - r.q[i] for i in range(2)]
    de = [p.names[f"dqd{i + 1}"] - r.dq[i] for i in range(2)]
    alt = Yr * ah + sp.Matrix([2 * kd[i] * lam[i] * e[i] + kd[i] * de[i] for i in range(2)])
    v = check_control_law(p, res, "u", list(alt), lambda n: None, None)
    assert v is not None and v.correct, v.feedback
    # K_P < K_D Lambda: rejected (partial), a missing gravity term: rejected
    low = Yr * ah + sp.Matrix([kd[i] * lam[i] * e[i] / 2 + kd[i] * de[i] for i in range(2)])
    v = check_control_law(p, res, "u", list(low), lambda n: None, None)
    assert v is not None and not v.correct and v.fraction == 0.5
    g_wrong = [x - sp.Symbol("g0", positive=True) * 0 - ah[2] * p.names["g0"] * sp.sin(r.q[0]) for x in u]
    v = check_control_law(p, res, "u", g_wrong, lambda n: None, None)
    assert v is not None and not v.correct and "estimates" in v.feedback[0]


def test_adaptive_regressor_checked_by_verify():
    from solver.verify import check_problem
    rep = check_problem(load_problem(PROBLEMS / "2004-03-25-ex1.yaml"))
    assert rep.ok
    assert "Y_r" in {c.name for c in rep.checks}


# ---------------------------------------------------------------------------------------------- Cartesian
CART_2R = "  - kind: control_law\n    law: cartesian_computed_torque\n" \
          "    task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]\n"


def test_cartesian_computed_torque_gives_linear_task_dynamics():
    text = R2.replace("symbols: {", "symbols: {l2: l2, ") + CART_2R
    p, _, res = solved(text)
    r = p.robot
    f = res["r"].value
    J = f.jacobian(r.q)
    ddq = accel(p, res["u"].value)
    Jdot = sum((sp.diff(J, a) * b for a, b in zip(r.q, r.dq)), sp.zeros(2, 2))
    ddr = J * ddq + Jdot * sp.Matrix(r.dq)
    n = lambda s: p.names[s]  # noqa: E731
    want = [n(f"ddrd{i}") + n(f"kd{i}") * (n(f"drd{i}") - (J * sp.Matrix(r.dq))[i - 1])
            + n(f"kp{i}") * (n(f"rd{i}") - f[i - 1]) for i in (1, 2)]
    assert vanishes([ddr[i] - want[i] for i in range(2)])
    assert sp.simplify(res["det_J"].value - n("l1") * n("l2") * sp.sin(r.q[1])) == 0
    assert res["closed_loop_check"].value


def test_cartesian_regulation_with_numbers_and_errors():
    text = R2.replace("symbols: {", "symbols: {l2: l2, ") + CART_2R + \
        "    kp: [100, 50]\n    kd: [20, 10]\n    regulation: true\n    rd: [0.5, 0.3]\n"
    p, _, res = solved(text)
    assert res["closed_loop_check"].value
    with pytest.raises(UserError, match="task must list 1 to 2"):
        solved(R2 + "  - kind: control_law\n    law: cartesian_computed_torque\n    task: [q1, q2, q1 + q2]\n")
    _, _, res1 = solved(R2 + "  - kind: control_law\n    law: cartesian_computed_torque\n    task: [q1 + q2]\n")
    assert res1["closed_loop_check"].value and res1["J_pinv"].value.shape == (2, 1)   # m < n: the pseudoinverse
    with pytest.raises(UserError, match="needs task"):
        solved(R2 + "  - kind: control_law\n    law: cartesian_computed_torque\n")


# ---------------------------------------------------------------------------------------------- underactuated
@pytest.mark.parametrize("collocated", [True, False])
def test_partial_feedback_linearization_cartpole(collocated):
    p, _, res = solved(CARTPOLE + f"  - kind: control_law\n    law: partial_fbl\n    collocated: {str(collocated).lower()}\n")
    ddq = accel(p, res["u"].value)
    v = [s for s in res["u"].value[0].free_symbols if s.name.startswith("v")][0]
    i_lin = 0 if collocated else 1
    assert sp.simplify(ddq[i_lin] - v) == 0
    assert sp.simplify(ddq[1 - i_lin] - res["ddq_free"].value[0]) == 0
    if not collocated:
        L = p.names["L"]
        assert sp.simplify(res["coupling"].value + p.names["mp"] * L * sp.cos(p.robot.q[1])) == 0 or \
            sp.simplify(res["coupling"].value - p.names["mp"] * L * sp.cos(p.robot.q[1])) == 0


def test_partial_fbl_with_gains_zero_dynamics():
    p, _, res = solved(CARTPOLE + "  - kind: control_law\n    law: partial_fbl\n    kp: 4\n    kd: 4\n    qd: [0]\n")
    ddq = accel(p, res["u"].value)
    q1, dq1 = p.robot.q[0], p.robot.dq[0]
    assert sp.simplify(ddq[0] - (-4 * q1 - 4 * dq1)) == 0
    # at rest at q1 = 0 the pendulum moves freely: q̈2 = (g0/L) sin q2
    z = res["zero_dynamics"].value[0]
    assert sp.simplify(z - p.names["g0"] / p.names["L"] * sp.sin(p.robot.q[1])) == 0


def test_partial_fbl_needs_an_underactuated_robot():
    with pytest.raises(UserError, match="input_map"):
        solved(RP + "  - kind: control_law\n    law: partial_fbl\n")


# ---------------------------------------------------------------------------------------------- elastic
@pytest.mark.parametrize("head", [ELASTIC1, ELASTIC2], ids=["1 joint", "2R"])
def test_elastic_feedback_linearization(head):
    p, _, res = solved(head + "  - kind: control_law\n    law: elastic\n")
    assert res["closed_loop_check"].value
    r = p.robot
    m = len(res["ddy"].value)
    lnk, mot = list(range(m)), list(range(m, 2 * m))
    # independent check: differentiate ÿ = f2 twice along the model under u and compare with v
    u = res["u"].value
    vs = [p.names[f"v{i + 1}"] for i in range(m)]
    dm = derive(r)
    G = dm.G
    at = random_point(list(u) + list(dm.B) + list(dm.g), 7)
    at |= {v: sp.Rational(3 + i, 5) for i, v in enumerate(vs)}
    ddx = dm.B.xreplace(at).LUsolve(G * u.xreplace(at) - (dm.c + dm.g).xreplace(at))
    f3 = res["jerk"].value
    X, dX = list(r.q), list(r.dq)
    for k in range(m):
        d4 = sum(sp.diff(f3[k], a).xreplace(at) * at.get(b, b) for a, b in zip(X, dX))
        d4 += sum(sp.diff(f3[k], b).xreplace(at) * ddx[j] for j, b in enumerate(dX))
        assert abs(sp.N(d4 - at[vs[k]], 30)) < 1e-18
    # the jerk is the derivative of ÿ along the model
    f2 = res["ddy"].value
    for k in range(m):
        d3 = sum(sp.diff(f2[k], a) * b for a, b in zip(X, dX)) + \
            sum(sp.diff(f2[k], dX[j]) * f2[j] for j in lnk)
        assert vanishes([d3 - f3[k]])
    assert all(not sp.diff(res["beta"].value[i, j], s) == 0 or True for i in range(m) for j in range(m) for s in [])
    assert "theta_y" in res and mot


def test_elastic_spong_form():
    p, _, res = solved(ELASTIC1 + "  - kind: control_law\n    law: elastic\n")
    n = p.names
    q1, dq1 = p.robot.q[0], p.robot.dq[0]
    ddq, d4 = p.robot.ddq[0], n["ddddq1"]
    Bl = n["I"] + n["m"] * n["d"] ** 2
    gq = n["m"] * n["g0"] * n["d"] * sp.cos(q1)
    # u = Im/K (B q'''' + g'') + (B + Im) q'' + g
    g2 = sp.diff(gq, q1, 2) * dq1 ** 2 + sp.diff(gq, q1) * ddq
    want = n["Im"] / n["K"] * (Bl * d4 + g2) + (Bl + n["Im"]) * ddq + gq
    assert sp.simplify(res["u_y"].value[0] - want) == 0


def test_elastic_rejects_a_full_model():
    text = ELASTIC1.replace('"1/2*Im*dtheta1^2"', '"1/2*Im*(dq1 + dtheta1)^2"')
    with pytest.raises(UserError, match="reduced model"):
        solved(text + "  - kind: control_law\n    law: elastic\n")


# ---------------------------------------------------------------------------------------------- linearization
def test_linearization_cartpole_controllable():
    p, _, res = solved(CARTPOLE + "  - kind: control_law\n    law: linearization\n    equilibrium: {q1: 0, q2: 0}\n")
    A, Bl = res["A_lin"].value, res["B_lin"].value
    # finite differences of the nonlinear vector field at the numeric values
    r = p.robot
    dm = derive(r)
    vals = p.values
    x = list(r.q) + list(r.dq)
    u = sp.Symbol("u_fd")
    f = sp.Matrix(list(r.dq) + list(dm.B.LUsolve(dm.G * sp.Matrix([u]) - dm.c - dm.g)))
    fn = sp.lambdify([x, u], f.xreplace(vals), "numpy")
    h = 1e-6
    An = np.array(A.xreplace(vals), dtype=float)
    for j in range(4):
        xp = np.zeros(4)
        xp[j] = h
        col = (np.array(fn(list(xp), 0.0), dtype=float) - np.array(fn(list(-xp), 0.0), dtype=float)).ravel() / (2 * h)
        assert np.allclose(col, An[:, j], atol=1e-5)
    bcol = (np.array(fn([0] * 4, h), dtype=float) - np.array(fn([0] * 4, -h), dtype=float)).ravel() / (2 * h)
    assert np.allclose(bcol, np.array(Bl.xreplace(vals), dtype=float).ravel(), atol=1e-5)
    assert res["controllable"].value is True and res["rank_ctrb"].value == 4


ELASTIC_2R_LIN = (ELASTIC2.replace("K2: K2}", "K2: K2, g0: g0}")
                  .replace("  input_map:", "  gravity: [0, -g0, 0]\n  input_map:")
                  + "  - kind: control_law\n    law: linearization\n"
                    "    equilibrium: {q1: -pi/2, q2: 0, theta1: -pi/2, theta2: 0}\n")


def test_linearization_of_two_elastic_joints():
    """n = 4 (links and motors): the symbolic 8×8 Kalman matrix ran for minutes (rank with simplify); the rank is
    now the exact rank at random rational points and det(sI − A) = det(B_e s² + K_e)/det B_e. Checked with numpy
    at random parameter values: the characteristic polynomial's coefficients and the rank of [B, AB, ..., A⁷B]."""
    import random
    p, sols, res = solved(ELASTIC_2R_LIN)
    assert "ctrb" not in res and res["rank_ctrb"].value == 8 and res["controllable"].value is True
    A, Bl, cp = res["A_lin"].value, res["B_lin"].value, res["char_poly"].value
    s = sp.Symbol("s")
    rng = random.Random(3)
    for _ in range(2):
        pt = {x: sp.Rational(rng.randint(50, 500), 97) for x in (A.free_symbols | cp.free_symbols) - {s}}
        An, Bn = (np.array(M.xreplace(pt).evalf(), dtype=float) for M in (A, Bl))
        want = np.poly(An)
        got = np.array([float(sp.Poly(cp.xreplace(pt), s).coeff_monomial(s ** k)) for k in range(8, -1, -1)])
        assert np.allclose(got, want, rtol=1e-9, atol=1e-9)
        assert np.linalg.matrix_rank(np.hstack([np.linalg.matrix_power(An, k) @ Bn for k in range(8)])) == 8
    assert "too large to print" in render(p, sols, "md")


def test_kalman_rank_at_random_points_finds_a_rank_deficiency():
    """Two equal mass-spring systems driven by one force: rank 2 of 4, for every value of m and k."""
    from solver.control.linearization import kalman_rank
    m, k = sp.symbols("m k", positive=True)
    A = sp.Matrix([[0, 0, 1, 0], [0, 0, 0, 1], [-k / m, 0, 0, 0], [0, -k / m, 0, 0]])
    assert kalman_rank(A, sp.Matrix([0, 0, 1 / m, 1 / m])) == 2
    assert kalman_rank(A, sp.Matrix([0, 0, 1 / m, 0]).row_join(sp.Matrix([0, 0, 0, 1]))) == 4


def test_exact_controllability_is_sympys_kalman_matrix():
    """[B, AB, A²B, A³B] over the field of rational functions (rank and det exact, without converting the printed
    matrix) equals the sympy product, rank and det; None off the rational functions (√2: sympy's rank)."""
    from solver.control.linearization import controllability, exact_controllability
    m, k, b = sp.symbols("m k b", positive=True)
    A = sp.Matrix([[0, 0, 1, 0], [0, 0, 0, 1], [-2 * k / m, k / m, -b / m, 0], [k / m, -k / m, 0, 0]])
    for Bl, rank in ((sp.Matrix([0, 0, 1 / m, 0]), 4), (sp.Matrix([0, 0, 1 / m, 1 / m]) * 0, 0)):
        C, E = controllability(A, Bl), exact_controllability(A, Bl)
        assert E.to_Matrix().applyfunc(sp.cancel) == C.applyfunc(sp.cancel)
        assert E.rank() == C.rank(simplify=True) == rank
        assert sp.cancel(E.domain.to_sympy(E.det()) - C.det()) == 0
    assert exact_controllability(sp.Matrix([[0, 1], [sp.sqrt(2), 0]]), sp.Matrix([0, 1])) is None


def test_linearization_not_controllable_and_not_an_equilibrium():
    # two uncoupled masses, one actuated: the other cannot be reached
    text = """
id: two
title: two masses
symbols: {m1: m1, m2: m2, k: k}
robot:
  joints: [P, P]
  input_map: [[1], [0]]
  links:
    - {mass: m1, com: [q1, 0]}
    - {mass: m2, com: [0, q2]}
  extra: {potential: ["1/2*k*q2^2"]}
asks:
  - kind: control_law
    law: linearization
    equilibrium: {q1: 0, q2: 0}
"""
    _, _, res = solved(text)
    assert res["controllable"].value is False and res["rank_ctrb"].value == 2
    with pytest.raises(UserError, match="not an equilibrium"):
        solved(CARTPOLE + "  - kind: control_law\n    law: linearization\n    equilibrium: {q1: 0, q2: 1}\n")


def test_options_of_other_laws_are_errors():
    with pytest.raises(UserError, match="not an option"):
        solved(RP + "  - kind: control_law\n    law: linearization\n    equilibrium: {q1: 0, q2: 0}\n    kp: 3\n")
    with pytest.raises(UserError, match="one of law: cartesian"):
        solved(RP + "  - kind: control_law\n    law: computed_torque\n    task: [q1, q2]\n")


# ---------------------------------------------------------------------------------------------- reports
ALL = (CARTPOLE + "  - kind: control_law\n    law: partial_fbl\n    kp: 4\n    kd: 4\n    qd: [0]\n"
       "  - kind: control_law\n    law: partial_fbl\n    collocated: false\n    suffix: _nc\n"
       "  - kind: control_law\n    law: linearization\n    equilibrium: {q1: 0, q2: 0}\n    suffix: _l\n")


def test_reports_render():
    p, sols, _ = solved(ALL)
    md = render(p, sols, "md")
    assert "Collocated partial feedback linearization" in md and "strong inertial coupling" in md
    assert "Kalman" in md and "controllable" in md
    p2, sols2, _ = solved(ELASTIC1 + "  - kind: control_law\n    law: elastic\n")
    md2 = render(p2, sols2, "md")
    assert "relative degree 4" in md2 and "jerk" in md2


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed")
def test_latex_reports_compile(tmp_path):
    p, sols, _ = solved(ALL)
    p2, sols2, _ = solved(ELASTIC1 + "  - kind: control_law\n    law: elastic\n")
    text = R2.replace("symbols: {", "symbols: {l2: l2, ") + CART_2R + "  - kind: control_law\n    law: pd_constant\n    suffix: _c\n"
    p3, sols3, _ = solved(text)
    for i, (pp, ss) in enumerate(((p, sols), (p2, sols2), (p3, sols3))):
        out = tmp_path / f"r{i}.tex"
        out.write_text(render(pp, ss, "tex"))
        run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", out.name], cwd=tmp_path,
                             capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stdout[-2000:]


# ---------------------------------------------------------------------------------------------- Lyapunov tracking
@pytest.mark.parametrize("head", [R2, RP, R3], ids=["2R", "RP", "3R"])
def test_lyapunov_tracking_closed_loop(head):
    p, sols, res = solved(head + "  - kind: control_law\n    law: lyapunov_tracking\n")
    r = p.robot
    dm = derive(r)
    n = r.n
    N = lambda s: p.names[s]  # noqa: E731
    qd = sp.Matrix([N(f"qd{i + 1}") for i in range(n)])
    dqd = sp.Matrix([N(f"dqd{i + 1}") for i in range(n)])
    ddqd = sp.Matrix([N(f"ddqd{i + 1}") for i in range(n)])
    KP = sp.diag(*[N(f"kp{i + 1}") for i in range(n)])
    KD = sp.diag(*[N(f"kd{i + 1}") for i in range(n)])
    q, dq, ddq = sp.Matrix(r.q), sp.Matrix(r.dq), sp.Matrix(r.ddq)
    e, de, dde = qd - q, dqd - dq, ddqd - ddq
    # S from the Christoffel matrices, independently: S_k = dqᵀ C_k
    S = sp.Matrix([(dq.T * Ck) for Ck in dm.C])
    lhs = dm.B * ddq + dm.c + dm.g - res["u"].value            # model residual under the law
    want = -(dm.B * dde + S * de + KD * de + KP * e)
    assert vanishes(list(lhs - want))
    assert res["closed_loop_check"].value
    md = render(p, sols, "md")
    assert "Lyapunov-based tracking" in md


def test_u_at_a_state():
    p, _, res = solved(RP + "  - kind: control_law\n    law: computed_torque\n    kp: 4\n    kd: 4\n"
                       "    at: {q1: 0, q2: 1, dq1: 0, dq2: 0, qd1: 0, qd2: 1, dqd1: 0, dqd2: 0, ddqd1: 0, ddqd2: 0}\n")
    g = derive(p.robot).g.xreplace({p.robot.q[0]: 0, p.robot.q[1]: 1})
    assert all(sp.simplify(a - b) == 0 for a, b in zip(res["u_at"].value, g))
    with pytest.raises(UserError, match="not a name"):
        solved(RP + "  - kind: control_law\n    at: {zz9: 1}\n")


def test_linearization_solves_the_missing_coordinates():
    # 2016-09-12#2: theta from the cubic spring equation at q = 0.1, u = -m g0
    p = load_problem(PROBLEMS / "2016-09-12-ex2.yaml")
    res = all_results(solve_problem(p))
    th, q = [float(x) for x in res["q_eq"].value]
    d = q - th
    assert abs(10000 * d ** 3 + 1000 * d - 3 * 9.81) < 1e-8 and q == 0.1
    assert abs(float(res["u_eq"].value[0]) + 29.43) < 1e-9
    # the numeric linearization: K_e in floats (not 51277340087129/50000000000), det(sI − A) a polynomial in s
    # with the coefficients of numpy's characteristic polynomial (it was a ratio of two float polynomials)
    A = np.array(res["A_lin"].value, dtype=float)
    cp = sp.Poly(res["char_poly"].value, sp.Symbol("s"))
    assert np.allclose([float(c) for c in cp.all_coeffs()], np.poly(A), atol=1e-9)
    assert res["char_poly"].value.coeff(sp.Symbol("s"), 4) is sp.S.One and all(x.is_Float for x in res["K_e"].value)
    with pytest.raises(UserError, match="values for"):
        solved(CARTPOLE.replace("values: {mc: 1, mp: 0.3, L: 0.6, g0: 9.81}", "")
               + "  - kind: control_law\n    law: linearization\n    equilibrium: {q1: 0}\n")


def test_adaptive_u_through_the_grader_with_a_suffix():
    from solver.grading.grader import grade, prepare
    from solver.grading.submission import Submission
    text = RPK + "  - kind: control_law\n    law: adaptive\n    suffix: _ad\ngrading:\n  items:\n    u_ad: {points: 2}\n"
    p = load_problem_text(text)
    ref = prepare(p)
    u = ref.results["u_ad"].value
    good = Submission("ann", "ann.yaml", {"u_ad": [sp.sstr(sp.expand(x)) for x in u]})
    ah3 = p.names["ahat3"]
    bad = Submission("bob", "bob.yaml", {"u_ad": [sp.sstr(sp.expand(x.subs(ah3, 0))) for x in u]})
    item = lambda rep: next(i for i in rep.items if i.name == "u_ad")  # noqa: E731
    ok, ko = item(grade(ref, good)), item(grade(ref, bad))
    assert ok.score == ok.max_score > 0, ok.feedback
    assert ko.score < ko.max_score and any("estimates" in f for f in ko.feedback), ko.feedback


def test_exact_det_and_rational_matrix():
    """exact_det equals det on matrices of rational functions (a 4x4 s I - A with parameters in denominators, an
    integer matrix); entries with cos/sin (related by cos² + sin² = 1) or roots are not taken as independent
    generators: rational_matrix refuses them and exact_det is Matrix.det."""
    from solver.math.simplify import exact_det, rational_matrix
    s, m, k, b, g = sp.symbols("s m k b g0", positive=True)
    q = sp.Symbol("q", real=True)
    A = sp.Matrix([[0, 0, 1, 0], [0, 0, 0, 1], [-k / m, g / m, -b / m, 0], [k / (2 * m), -(k + g) / m, 0, -b / m]])
    M = s * sp.eye(4) - A
    assert sp.cancel(exact_det(M) - M.det()) == 0 and exact_det(M).free_symbols <= {s, m, k, b, g}
    assert exact_det(sp.Matrix([[2, 1], [7, 4]])) == 1
    trig = sp.Matrix([[sp.cos(q), sp.sin(q)], [-sp.sin(q), sp.cos(q)]])
    assert rational_matrix(trig) is None and sp.simplify(exact_det(trig)) == 1
    assert rational_matrix(sp.Matrix([[sp.sqrt(m), 1], [1, sp.sqrt(m)]])) is None
    assert rational_matrix(M) is not None


@pytest.mark.parametrize("ask, words", [
    ("  - kind: control_law\n    law: linearization\n    equilibrium: {q1: 0, q2: 0}\n    kp: 3\n",
     "kp: is not an option of law: linearization"),
    ("  - kind: control_law\n    law: computed_torque\n    qd: [1, 2]\n", "qd: (a constant desired configuration) needs"),
    ("  - kind: control_law\n    law: pd_gravity\n    qd: [1, 2, 3]\n", "qd must be a list of 2 expressions"),
    ("  - kind: control_law\n    law: computed_torque\n    kp: [1, 2, 3]\n", "kp must be one expression or a list of 2"),
    ("  - kind: control_law\n    law: adaptive\n    kp: 3\n", "law: adaptive has no K_P"),
    ("  - kind: control_law\n    law: pd_gravity\n    lambda: 3\n", "lambda: and gamma: are gains of law: adaptive"),
    ("  - kind: control_law\n    law: cartesian_computed_torque\n    task: [q1, q2, q1 + q2]\n",
     "task must list 1 to 2"),
    ("  - kind: control_law\n    law: cartesian_computed_torque\n    task: [q1 + q2]\n    rd: [1]\n",
     "rd: (a constant desired task value) needs regulation: true"),
])
def test_check_finds_bad_law_options_without_solving(ask, words):
    """The law's options, q_d and the gains (joint space and Cartesian) are read by the kind's validate hook
    (`check`) as by solving, without the model."""
    assert words in error_found_without_solving(RP + ask)


def law(name: str, **opts: str) -> str:
    return f"  - kind: control_law\n    law: {name}\n" + "".join(f"    {k}: {v}\n" for k, v in opts.items())


NO_MAP = CARTPOLE.replace("  input_map: [[1], [0]]\n", "")
FULL_MAP = CARTPOLE.replace("input_map: [[1], [0]]", "input_map: [[1, 0], [0, 1]]")
E1_FULL = ELASTIC1.replace("input_map: [[0], [1]]", "input_map: [[1, 0], [0, 1]]")
OTHER_LAWS_BAD = [
    (ELASTIC1.replace("  input_map: [[0], [1]]\n", "") + law("elastic"), "law: elastic needs robot.input_map"),
    (E1_FULL + law("elastic"), "law: elastic is for underactuated robots, but every coordinate is actuated"),
    (ELASTIC2.replace("input_map: [[0, 0], [0, 0], [1, 0], [0, 1]]", "input_map: [[0], [0], [1], [0]]")
     + law("elastic"), "law: elastic needs one motor per link coordinate (1 actuated, 3 passive coordinates)"),
    (ELASTIC1 + law("elastic", qd="[1, 2]"), "qd must list 1 values (one per link)"),
    (ELASTIC1 + law("elastic", gains="[1, 2]"), "gains must be [k0, k1, k2, k3]"),
    (ELASTIC1 + law("elastic", gains="[1, 2, [3, 4], 5]"), "gains[2] must be one expression or a list of 1"),
    (NO_MAP + law("partial_fbl"), "law: partial_fbl needs robot.input_map"),
    (FULL_MAP + law("partial_fbl"), "law: partial_fbl is for underactuated robots"),
    (CARTPOLE.replace("input_map: [[1], [0]]", "input_map: [[1, 1], [0, 0]]") + law("partial_fbl"),
     "law: partial_fbl needs the inputs to act one to one on 2 coordinates"),
    (ELASTIC2.replace("input_map: [[0, 0], [0, 0], [1, 0], [0, 1]]", "input_map: [[0], [0], [1], [0]]")
     + law("partial_fbl", collocated="false"), "with as many inputs as passive coordinates (1 inputs, 3 passive)"),
    (CARTPOLE + law("partial_fbl", kp="[1, 2]"), "kp must be one expression or a list of 1 (the diagonal of K_P)"),
    (CARTPOLE + law("partial_fbl", kp="1", kd="[1, 2]"), "kd must be one expression or a list of 1"),
    (CARTPOLE + law("partial_fbl", kp="1", qd="[0, 1]"), "qd must list 1 values (the linearized coordinates)"),
    (CARTPOLE + law("linearization"), "law: linearization needs equilibrium:"),
    (CARTPOLE + law("linearization", equilibrium="{q3: 0}"), "equilibrium: q3 is not a coordinate (q1, q2)"),
    (CARTPOLE + law("linearization", equilibrium="{q1: zz, q2: 0}"), "unknown name 'zz'"),
    (CARTPOLE + law("linearization", equilibrium="{}"),
     "equilibrium: 2 coordinates are not given, but the unactuated equations at rest are 1"),
    (FULL_MAP + law("linearization", equilibrium="{q1: 0}"),
     "equilibrium: 1 coordinates are not given, but the unactuated equations at rest are 0"),
]


@pytest.mark.parametrize("text, words", OTHER_LAWS_BAD, ids=[f"{k}-{b[1][:24]}" for k, b in enumerate(OTHER_LAWS_BAD)])
def test_check_reads_the_elastic_underactuated_and_linearization_laws_as_solve_does(text, words):
    """law: elastic (the input map, qd:, gains:), partial_fbl (the input map, collocated:, kp:/kd:/qd:) and
    linearization (equilibrium:) are read by the reader each solver runs first, which the validate hook (`check`)
    runs too, without the model: solving's error (each of these passed check and failed solve)."""
    assert words in error_found_without_solving(text)
