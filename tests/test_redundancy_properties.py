"""Properties of the redundancy methods (solver/kinematics/resolution.py and the method path of the `redundancy`
ask) on robots no exercise uses: a planar 4R with unequal links and a spatial 7-dof arm (KUKA-LWR-like DH)."""
import numpy as np
import pytest
import sympy as sp
from scipy.optimize import linprog, minimize

from solver.kinematics import resolution as rs
from solver.solve import all_results, solve_problem
from solver.spec import load_problem_text

F = rs.LA(False)
E = rs.LA(True)
RNG = np.random.default_rng(11)

# ----------------------------------------------------------------------------------------------- robots
DH7 = [(0, np.pi / 2, 0.31), (0, -np.pi / 2, 0), (0, -np.pi / 2, 0.4), (0, np.pi / 2, 0),
       (0, np.pi / 2, 0.39), (0, -np.pi / 2, 0), (0, 0, 0.078)]  # (a, alpha, d)


def jac7(q: np.ndarray) -> np.ndarray:
    """6x7 geometric Jacobian (linear; angular) of the 7-dof arm."""
    T = np.eye(4)
    zs, ps = [], []
    for (a, al, d), th in zip(DH7, q):
        zs.append(T[:3, 2].copy())
        ps.append(T[:3, 3].copy())
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d],
                          [0, 0, 0, 1]])
    pe = T[:3, 3]
    return np.vstack([np.column_stack([np.cross(z, pe - p) for z, p in zip(zs, ps)]), np.column_stack(zs)])


L4 = (1.0, 0.7, 0.5, 0.3)


def jac4(q: np.ndarray) -> np.ndarray:
    c = np.cumsum(q)
    return np.array([[-sum(L4[k] * np.sin(c[k]) for k in range(j, 4)) for j in range(4)],
                     [sum(L4[k] * np.cos(c[k]) for k in range(j, 4)) for j in range(4)]])


def rand_q(n: int) -> np.ndarray:
    return RNG.uniform(-np.pi, np.pi, n)


# ----------------------------------------------------------------------------------------------- pseudoinverse
@pytest.mark.parametrize("trial", range(5))
def test_penrose_conditions_and_projector(trial):
    J = jac7(rand_q(7))
    for A in (J, J[:3], np.vstack([J[:3], J[:1]])):  # full rank 6x7, 3x7, and a rank-deficient 4x7
        Jp = F.pinv(A)
        assert np.allclose(A @ Jp @ A, A, atol=1e-10)
        assert np.allclose(Jp @ A @ Jp, Jp, atol=1e-10)
        P = rs.projector(F, A, Jp)
        assert np.allclose(P @ P, P, atol=1e-10) and np.allclose(P, P.T, atol=1e-10)
        assert np.allclose(A @ P, 0, atol=1e-10)
    assert F.rank(np.vstack([J[:3], J[:1]])) == 3


def test_exact_pinv_rational():
    J = sp.Matrix([[1, 2, 0, -1], [0, 1, 1, 1]]) / 3
    Jp = E.pinv(J)
    assert J * Jp * J == J and all(x.is_Rational for x in Jp)
    Jd = sp.Matrix.vstack(J, J[0, :] * 2)  # rank 2 of 3 rows
    assert E.rank(Jd) == 2
    Jdp = E.pinv(Jd)
    assert (Jd * Jdp * Jd - Jd).applyfunc(sp.simplify) == sp.zeros(3, 4)


def test_rank_tolerance_counts_roundoff_as_zero():
    """A projected Jacobian zero to rounding (σ ~ 1e-16) is rank deficient: its pseudoinverse is 0, not 1e16."""
    q1 = float(np.arccos((2 + np.sqrt(2)) / 4))
    J1 = np.array([[-np.sin(q1), 0.0, -np.sin(q1)], [np.cos(q1), 1.0, np.cos(q1)]])
    J2 = np.array([[0.0, 1.0, 0.0]])
    P1 = np.eye(3) - F.pinv(J1) @ J1
    JP = J2 @ P1
    assert 0 < np.linalg.svd(JP, compute_uv=False)[0] < 1e-12  # not exactly zero in floating point
    assert F.rank(JP) == 0 and np.allclose(F.pinv(JP), 0)
    assert np.abs(np.linalg.pinv(JP, rcond=1e-20)).max() > 1e6  # what a tolerance-free pinv would give
    v, levels = rs.task_priority(F, [J1, J2], [np.array([[0.0], [1.0]]), np.array([[0.0]])])
    assert levels[1].algorithmic and np.allclose(J1 @ v, [[0], [1]])


# ----------------------------------------------------------------------------------------------- DLS, weighted
@pytest.mark.parametrize("trial", range(3))
def test_dls_tends_to_pinv(trial):
    """J^T (J J^T + μ² I)⁻¹ − J^+ = −Σ μ²/(σᵢ(σᵢ² + μ²)) vᵢuᵢᵀ: decreasing with μ, about μ²/σ_min³ at the end
    (σ_min the smallest non-zero singular value; the draw is per trial, whatever tests ran before)."""
    rng = np.random.default_rng(100 + trial)
    J = jac7(rng.uniform(-np.pi, np.pi, 7))[:3]
    for A in (J, np.vstack([J[:2], J[:1] + J[1:2]])):  # full rank and rank deficient
        mus = (1e-1, 1e-2, 1e-3, 1e-4)
        errs = [np.abs(rs.dls(F, A, mu) - F.pinv(A)).max() for mu in mus]
        s = np.linalg.svd(A, compute_uv=False)
        s_min = s[s > 1e-9 * s[0]].min()
        assert all(b < a for a, b in zip(errs, errs[1:])) and errs[-1] < 2 * mus[-1] ** 2 / s_min ** 3


def test_dls_minimizes_damped_cost():
    J, r, mu = jac4(rand_q(4)), np.array([[0.3], [-0.2]]), 0.4
    v = rs.dls(F, J, mu) @ r
    cost = lambda x: 0.5 * np.sum((J @ x[:, None] - r) ** 2) + 0.5 * mu ** 2 * np.sum(x ** 2)
    best = minimize(cost, np.zeros(4), tol=1e-12).x
    assert np.allclose(v.ravel(), best, atol=1e-5)


def test_weighted_pinv_lagrange_conditions():
    J = jac7(rand_q(7))[:3]
    A = RNG.normal(size=(7, 7))
    W = A @ A.T + 7 * np.eye(7)
    r = RNG.normal(size=(3, 1))
    v = rs.weighted_pinv(F, J, W) @ r
    assert np.allclose(J @ v, r)
    lam = np.linalg.lstsq(J.T, W @ v, rcond=None)[0]  # W v = Jᵀ λ (stationarity)
    assert np.allclose(J.T @ lam, W @ v, atol=1e-9)


# ----------------------------------------------------------------------------------------------- task priority
@pytest.mark.parametrize("trial", range(5))
def test_task_priority_first_task_exact(trial):
    J = jac7(rand_q(7))
    J1, J2, J3 = J[:3], J[3:5], J[5:]
    r1, r2, r3 = (RNG.normal(size=(k, 1)) for k in (3, 2, 1))
    v, levels = rs.task_priority(F, [J1, J2, J3], [r1, r2, r3])
    assert np.allclose(J1 @ v, r1)  # 3 + 2 + 1 = 6 <= 7: all feasible, every task exact
    assert np.allclose(J2 @ v, r2) and np.allclose(J3 @ v, r3)
    # with more rows than joints below, the first task still exact, the second in least squares in N(J1)
    K = RNG.normal(size=(5, 7))
    v2, lv = rs.task_priority(F, [J1, K], [r1, RNG.normal(size=(5, 1))])
    assert np.allclose(J1 @ v2, r1) and lv[1].rank_JP == 4


def test_extended_equals_priority_when_compatible():
    q = rand_q(4)
    J1, J2 = jac4(q), np.array([[1.0, 1.0, 1.0, 1.0]])
    x1, x2 = np.array([[0.2], [0.1]]), np.array([[0.5]])
    vE, JE, _, rk = rs.extended(F, [J1, J2], [x1, x2])
    vT, _ = rs.task_priority(F, [J1, J2], [x1, x2])
    assert rk == 3 and np.allclose(JE @ vE, np.vstack([x1, x2])) and np.allclose(JE @ vT, np.vstack([x1, x2]))


# ----------------------------------------------------------------------------------------------- SNS
def _feasible(J: np.ndarray, x: np.ndarray, lo, hi) -> bool:
    res = linprog(np.zeros(J.shape[1]), A_eq=J, b_eq=x.ravel(), bounds=list(zip(lo, hi)), method="highs")
    return res.status == 0


@pytest.mark.parametrize("trial", range(40))
def test_sns_bounds_and_scaling_only_when_needed(trial):
    """Every bound respected; the (scaled) task executed exactly; the task scaled (s < 1) exactly when no feasible
    joint vector realizes it (decided by an LP). The last is the optimality of SNS's scaling for one task (Flacco,
    De Luca, Khatib 2012), checked on these seeded random data (none of 275 feasible draws was scaled)."""
    J = jac7(rand_q(7))[:3]
    x = RNG.normal(size=(3, 1)) * RNG.uniform(0.2, 3)
    hi = RNG.uniform(1.0, 4.0, 7)
    lo = -hi
    res = rs.sns(F, J, x, list(lo), list(hi))
    v = res.qdot.ravel()
    assert np.all(v <= hi + 1e-9) and np.all(v >= lo - 1e-9)
    assert np.allclose(J @ res.qdot, res.s * x, atol=1e-9)  # the (scaled) task is executed exactly
    assert (res.s == 1) == _feasible(J, x, lo, hi)
    ps = F.pinv(J) @ x
    if np.all(np.abs(ps).ravel() <= hi):  # PS feasible: SNS returns it unchanged, in one iteration
        assert res.s == 1 and np.allclose(res.qdot, ps) and len(res.steps) == 1
    if np.all(np.abs(F.pinv(J) @ x).ravel() <= hi):  # PS feasible: SNS returns it unchanged
        assert res.s == 1 and np.allclose(res.qdot, F.pinv(J) @ x) and len(res.steps) == 1


def test_sns_exact_printed_case():
    J = sp.Matrix([[-2, -2, -1, 0], [0, -1, -1, -1]]) / 5
    res = rs.sns(E, J, sp.Matrix([5, 0]), [-9, -6, -4, -2], [9, 6, 4, 2])
    assert list(res.qdot) == [-9, -5, 3, 2] and res.s == 1 and res.saturated == [0, 3]


def test_max_scaling_matches_lp():
    for _ in range(10):
        J = jac4(rand_q(4))
        d = RNG.normal(size=(2, 1))
        h = RNG.normal(size=(2, 1)) * 2
        Jp = F.pinv(J)
        a, b = Jp @ d, -(Jp @ h)
        U = RNG.uniform(1, 4, 4)
        ms = rs.max_scaling(F, a, b, list(-U), list(U))
        A_ub = np.vstack([a, -a])
        b_ub = np.concatenate([U - b.ravel(), U + b.ravel()])
        lp = linprog([-1.0], A_ub=A_ub, b_ub=b_ub, bounds=[(0, None)], method="highs")
        if lp.status == 2:
            assert ms.lam is None
        elif lp.status == 0:
            assert ms.lam is not None and abs(ms.lam - lp.x[0]) < 1e-7


# ----------------------------------------------------------------------------------------------- the ask
ASK_4R = """
id: t4r
title: planar 4R, unequal links
symbols: {l1: l1, l2: l2, l3: l3, l4: l4}
values: {l1: 1, l2: 0.7, l3: 0.5, l4: 0.3}
robot:
  joints: [R, R, R, R]
  dh:
    table: [{a: l1, theta: q1}, {a: l2, theta: q2}, {a: l3, theta: q3}, {a: l4, theta: q4}]
    links: [{}, {}, {}, {}]
asks:
  - kind: redundancy
    task:
      - l1*cos(q1) + l2*cos(q1 + q2) + l3*cos(q1 + q2 + q3) + l4*cos(q1 + q2 + q3 + q4)
      - l1*sin(q1) + l2*sin(q1 + q2) + l3*sin(q1 + q2 + q3) + l4*sin(q1 + q2 + q3 + q4)
"""


def _at(q) -> str:
    return "{" + ", ".join(f"q{i + 1}: {float(x)!r}" for i, x in enumerate(q)) + "}"


def test_acceleration_level_matches_finite_differences():
    q, qd = np.array([0.3, 0.9, -0.6, 1.1]), np.array([0.4, -0.7, 0.5, 0.2])
    rdd = np.array([0.3, -0.8])
    text = ASK_4R + f"""    level: acceleration
    at: {_at(q)}
    joint_velocity: {list(map(float, qd))}
    acceleration: {list(map(float, rdd))}
    damping: 2
    mu: 0.01
    methods: [pseudoinverse, null_space, dls]
"""
    res = all_results(solve_problem(load_problem_text(text)))
    for name in ("qddot_ps", "qddot"):
        qdd = np.array(sp.Matrix(res[name].value).evalf().tolist(), dtype=float).ravel()
        h = 1e-5

        def pdot(t):
            qt = q + qd * t + 0.5 * qdd * t ** 2
            return jac4(qt) @ (qd + qdd * t)

        assert np.allclose((pdot(h) - pdot(-h)) / (2 * h), rdd, atol=1e-6)  # d/dt (J q̇) = r̈
    Jd = np.array(sp.Matrix(res["Jdot_at"].value).evalf().tolist(), dtype=float)
    assert np.allclose(Jd, (jac4(q + qd * 1e-6) - jac4(q - qd * 1e-6)) / 2e-6, atol=1e-6)  # J̇ along q̇
    qn = np.array(sp.Matrix(res["qddot"].value).evalf().tolist(), dtype=float).ravel()
    qp = np.array(sp.Matrix(res["qddot_ps"].value).evalf().tolist(), dtype=float).ravel()
    J = jac4(q)
    P = np.eye(4) - np.linalg.pinv(J) @ J
    assert np.allclose(qn - qp, P @ (-2 * qd))  # the null-space term damps q̇
    # the velocity level at the same state
    res_v = all_results(solve_problem(load_problem_text(ASK_4R + f"""    at: {_at(q)}
    velocity: [0.3, -0.8]
    methods: [pseudoinverse]
""")))
    v = np.array(sp.Matrix(res_v["qdot_ps"].value).evalf().tolist(), dtype=float).ravel()
    assert np.allclose(J @ v, [0.3, -0.8])


def test_ask_sns_and_comparison_render():
    from solver.publish.render import render
    text = ASK_4R + """    level: acceleration
    at: {q1: 0.2, q2: 0.4, q3: 0.6, q4: 0.8}
    joint_velocity: [0, 0, 0, 0]
    acceleration: [3, -2]
    bounds: [3, 3, 3, 3]
"""
    p = load_problem_text(text)
    sols = solve_problem(p)
    res = all_results(sols)
    v = np.array(sp.Matrix(res["qddot_sns"].value).evalf().tolist(), dtype=float).ravel()
    assert np.all(np.abs(v) <= 3 + 1e-9)
    md = render(p, sols, "md")
    assert "Saturation in the Null Space" in md and "**Comparison.**" in md
    tex = render(p, sols, "tex")
    assert "Saturation in the Null Space" in tex and "Comparison" in tex
    assert "no preferred joint motion" not in md
    # with a damping q̈0 = −K_d q̇ (used by the null-space method), the report says the basic SNS does not use it
    p = load_problem_text(text.replace("    joint_velocity: [0, 0, 0, 0]\n", "    joint_velocity: [1, 0, 0, -1]\n"
                                       "    damping: 2\n"))
    sols = solve_problem(p)
    v2 = np.array(sp.Matrix(all_results(sols)["qddot_sns"].value).evalf().tolist(), dtype=float).ravel()
    md = render(p, sols, "md")
    assert "This basic SNS has no preferred joint motion" in md and "no preferred joint motion" in render(p, sols, "tex")


# ----------------------------------------------------------------------------------------------- issue 8, items 15-16
I15 = """
id: i15
title: planar 4R with symbolic masses
symbols: {m1: m1, m2: m2, m3: m3, m4: m4}
robot:
  joints: [R, R, R, R]
  links:
    - {mass: m1, com: [cos(q1)/2, sin(q1)/2], angle: q1, inertia: m1/12}
    - {mass: m2, com: [cos(q1) + cos(q1+q2)/2, sin(q1) + sin(q1+q2)/2], angle: q1+q2, inertia: m2/12}
    - {mass: m3, com: [cos(q1) + cos(q1+q2) + cos(q1+q2+q3)/2, sin(q1) + sin(q1+q2) + sin(q1+q2+q3)/2],
       angle: q1+q2+q3, inertia: m3/12}
    - {mass: m4, com: [cos(q1) + cos(q1+q2) + cos(q1+q2+q3) + cos(q1+q2+q3+q4)/2,
                       sin(q1) + sin(q1+q2) + sin(q1+q2+q3) + sin(q1+q2+q3+q4)/2], angle: q1+q2+q3+q4, inertia: m4/12}
asks:
  - kind: redundancy
    task:
      - cos(q1) + cos(q1+q2) + cos(q1+q2+q3) + cos(q1+q2+q3+q4)
      - sin(q1) + sin(q1+q2) + sin(q1+q2+q3) + sin(q1+q2+q3+q4)
    weight: inertia
    velocity: [1, 0]
    at: {q1: 0, q2: pi/2, q3: 0, q4: pi/2}
"""


def test_item15_symbolic_inertia_weighted_pinv_at_a_configuration():
    """2x4 task, symbolic masses, weight: inertia, at: given -> symbolic J_W^# and q̇, equal to numpy at random
    masses."""
    p = load_problem_text(I15)
    res = all_results(solve_problem(p))
    assert "J_pinv" in res and "qdot_ps" in res
    Jp, qd = res["J_pinv"].value, res["qdot_ps"].value
    assert Jp.free_symbols and {s.name for s in Jp.free_symbols} <= {"m1", "m2", "m3", "m4"}
    from solver.dynamics.model import derive
    B = derive(p.robot).B
    q = {p.robot.q[0]: 0, p.robot.q[1]: sp.pi / 2, p.robot.q[2]: 0, p.robot.q[3]: sp.pi / 2}
    for _ in range(3):
        ms = {s: sp.Float(RNG.uniform(0.5, 5)) for s in Jp.free_symbols}
        W = np.array(B.subs(q).subs({sp.Symbol(k.name, **k.assumptions0): v for k, v in ms.items()})
                     .subs(ms).evalf().tolist(), dtype=float)
        J = jac4_unit(np.array([0, np.pi / 2, 0, np.pi / 2]))
        ref = np.linalg.inv(W) @ J.T @ np.linalg.inv(J @ np.linalg.inv(W) @ J.T)
        got = np.array(Jp.subs(ms).evalf().tolist(), dtype=float)
        assert np.allclose(got, ref, atol=1e-9)
        assert np.allclose(np.array(qd.subs(ms).evalf().tolist(), dtype=float).ravel(), ref @ [1, 0], atol=1e-9)


def jac4_unit(q: np.ndarray) -> np.ndarray:
    c = np.cumsum(q)
    return np.array([[-sum(np.sin(c[k]) for k in range(j, 4)) for j in range(4)],
                     [sum(np.cos(c[k]) for k in range(j, 4)) for j in range(4)]])


def test_item15_too_big_says_why(monkeypatch):
    text = I15.replace("    at: {q1: 0, q2: pi/2, q3: 0, q4: pi/2}\n", "")
    from solver.publish.render import render
    p = load_problem_text(text)
    sols = solve_problem(p)
    md = render(p, sols, "md")
    assert "not given symbolically" in md and "(no at:)" in md
    text = I15.replace("q3: 0,", "q3: 0.7,")  # sin(7/10): the exact symbolic result is huge
    # (it takes seconds: a tiny budget tests the path, not the machine's speed)
    import solver.kinematics.redundancy as red
    monkeypatch.setattr(red, "EXACT_SECONDS", 0.3)
    p = load_problem_text(text)
    sols = solve_problem(p)
    md = render(p, sols, "md")
    assert "J_pinv" not in all_results(sols) and "did not finish within" in md


def test_item16_nested_radicals_go_numeric_and_say_so():
    from solver.publish.render import render
    text = """
id: i16
title: 3R, projected gradient at angles with nested radicals
symbols: {}
robot: {joints: [R, R, R]}
asks:
  - kind: redundancy
    task: [cos(q1) + cos(q1+q2) + cos(q1+q2+q3), sin(q1) + sin(q1+q2) + sin(q1+q2+q3)]
    velocity: [1, -1]
    gradient: sin(q2)^2 + sin(q3)^2
    at: {q1: 2*pi/5, q2: pi/2, q3: -pi/4}
"""
    p = load_problem_text(text)
    sols = solve_problem(p)
    res = all_results(sols)
    v = res["qdot"].value
    assert all(x.is_Float or x == 0 for x in v)
    q = np.array([2 * np.pi / 5, np.pi / 2, -np.pi / 4])
    c = np.cumsum(q)
    J = np.array([[-sum(np.sin(c[k]) for k in range(j, 3)) for j in range(3)],
                  [sum(np.cos(c[k]) for k in range(j, 3)) for j in range(3)]])
    Jp = np.linalg.pinv(J)
    g = np.array([0, np.sin(2 * q[1]), np.sin(2 * q[2])])
    ref = Jp @ [1, -1] + (np.eye(3) - Jp @ J) @ g
    assert np.allclose(np.array(v.evalf().tolist(), dtype=float).ravel(), ref, atol=1e-9)
    assert "floating point: nested radicals" in render(p, sols, "md")


def test_sns_property_check_accepts_feasible_solutions():
    from conftest import PROBLEMS

    from solver.kinematics.methods import check_sns
    from solver.spec import load_problem
    p = load_problem(PROBLEMS / "2018-07-11-ex2.yaml")
    res = all_results(solve_problem(p))
    ok = check_sns(p, res, "qddot_sns", [-9, -5, 3, 2], None, None)
    assert ok.correct and ok.fraction == 1.0
    alt = check_sns(p, res, "qddot_sns", [-9, -5.5, 4, 1.5], None, None)  # α = 1.5 of the printed family
    assert alt.correct and alt.fraction == 0.5
    assert not check_sns(p, res, "qddot_sns", [-25 / 3, -25 / 6, 0, 25 / 6], None, None).correct  # PS: q̈4 > 2
    assert not check_sns(p, res, "qddot_sns", [-4, -2, 0, 2], None, None).correct  # scaled: task not realized


def test_sns_reduced_problem_results_and_constant_jacobian_without_at():
    """A constant 2x4 Jacobian (no robot, no at:): every SNS iteration with saturated joints S exposes J_{-S},
    the residual task x - J_S v_S, its pseudoinverse and the active components, consistent with the iterate."""
    J = np.array([[1.0, 0.5, -0.3, 0.2], [0.1, 1.0, 0.4, -0.6]])
    x = np.array([2.0, 1.5])
    p = load_problem_text("""
id: sns-const
title: constant Jacobian
asks:
  - kind: redundancy
    jacobian: [[1, 0.5, -0.3, 0.2], [0.1, 1, 0.4, -0.6]]
    velocity: [2, 1.5]
    bounds: [1, 1, 1, 1]
    methods: [pseudoinverse, sns]
""")
    res = all_results(solve_problem(p))
    num = lambda k: np.array(sp.Matrix(res[k].value).evalf().tolist(), dtype=float)  # noqa: E731
    its = int(res["sns_iterations"].value)
    assert its >= 2 and "J_sns_1" not in res
    for k in range(2, its + 1):
        v = num(f"qdot_sns_{k}").ravel()
        Jr, xk = num(f"J_sns_{k}"), num(f"task_sns_{k}").ravel()
        va = num(f"qdot_sns_{k}_active").ravel()
        sat = [i for i in range(4) if not any(np.allclose(Jr[:, c], J[:, i]) for c in range(Jr.shape[1]))]
        assert Jr.shape[1] == 4 - len(sat) and 1 <= len(sat) <= k - 1
        assert np.allclose(xk, x * float(res["sns_scale"].value if k == its else 1) - J[:, sat] @ v[sat])
        assert np.allclose(num(f"J_sns_{k}_pinv"), np.linalg.pinv(Jr))
        assert np.allclose(va, np.delete(v, sat)) and np.allclose(Jr @ va, xk)
    v = num("qdot_sns").ravel()
    assert np.all(np.abs(v) <= 1 + 1e-9) and float(res["sns_scale"].value) < 1  # infeasible: scaled


@pytest.mark.parametrize("exact", [True, False])
def test_sns_rank_deficient_task_in_range_is_not_scaled(exact):
    """J of rank 1 < m = 2 with the task in its range: removing a column keeps the rank, so SNS goes on
    saturating and realizes the task in full when a feasible solution exists (an LP confirms one exists)."""
    la = E if exact else F
    Jn = np.array([[1.0, 0.5, 2.0, -1.0], [2.0, 1.0, 4.0, -2.0]])
    J = sp.Matrix([[1, sp.Rational(1, 2), 2, -1], [2, 1, 4, -2]]) if exact else Jn
    x = sp.Matrix([5, 10]) if exact else np.array([[5.0], [10.0]])
    hi = [2, 2, 1, sp.Rational(1, 2)] if exact else [2.0, 2.0, 1.0, 0.5]
    lo = [-h for h in hi]
    lp = linprog(np.zeros(4), A_eq=Jn, b_eq=[5, 10], bounds=[(-float(h), float(h)) for h in hi])
    assert lp.status == 0
    res = rs.sns(la, la.mat(J), la.mat(x), lo, hi)
    v = np.array(sp.Matrix(la.sym(res.qdot)).evalf().tolist(), dtype=float).ravel()
    assert float(res.s) == 1 and res.feasible
    assert np.allclose(Jn @ v, [5, 10]) and np.all(np.abs(v) <= np.array(hi, dtype=float) + 1e-9)
    assert len(res.steps) > 2


def test_motion_reaches_the_algorithmic_singularity_of_a_4r():
    """Planar 4R, tasks: end effector moving along x at constant speed, link 2 angle q1 + q2 fixed, and the angle of
    the last link fixed: the extended Jacobian (4x4) loses rank where the motion must stop; the configuration
    found satisfies the tasks (on the path) and det J_E = 0."""
    text = ASK_4R.replace("""    task:
      - l1*cos(q1) + l2*cos(q1 + q2) + l3*cos(q1 + q2 + q3) + l4*cos(q1 + q2 + q3 + q4)
      - l1*sin(q1) + l2*sin(q1 + q2) + l3*sin(q1 + q2 + q3) + l4*sin(q1 + q2 + q3 + q4)
""", """    tasks:
      - name: p
        task: [l1*cos(q1) + l2*cos(q1 + q2) + l3*cos(q1 + q2 + q3) + l4*cos(q1 + q2 + q3 + q4),
               l1*sin(q1) + l2*sin(q1 + q2) + l3*sin(q1 + q2 + q3) + l4*sin(q1 + q2 + q3 + q4)]
        velocity: [0.5, 0]
      - {name: a, task: q1 + q2, velocity: 0}
      - {name: e, task: q1 + q2 + q3 + q4, velocity: 0}
    at: {q1: 0.4, q2: 0.5, q3: -1.2, q4: 0.6}
    methods: [extended]
    motion: {start: {q1: 0.4, q2: 0.5, q3: -1.2, q4: 0.6}, duration: 5}
""")
    from solver.publish.render import render
    p = load_problem_text(text)
    sols = solve_problem(p)
    res = all_results(sols)
    assert "first singularity" in render(p, sols, "md") and "first singularity" in render(p, sols, "tex")
    assert bool(res["singularity_reached"].value)
    qs = np.array(res["q_s"].value.evalf().tolist(), dtype=float).ravel()
    q0 = np.array([0.4, 0.5, -1.2, 0.6])
    t = float(res["t_end"].value)
    J = np.vstack([jac4(qs), [[1, 1, 0, 0]], [[1, 1, 1, 1]]])
    assert abs(np.linalg.det(J)) < 1e-8
    c = np.cumsum(qs)
    c0 = np.cumsum(q0)
    p = np.array([sum(L4[k] * np.cos(c[k]) for k in range(4)), sum(L4[k] * np.sin(c[k]) for k in range(4))])
    p0 = np.array([sum(L4[k] * np.cos(c0[k]) for k in range(4)), sum(L4[k] * np.sin(c0[k]) for k in range(4))])
    assert np.allclose(p, p0 + np.array([0.5, 0]) * t, atol=1e-8)
    assert abs((qs[0] + qs[1]) - 0.9) < 1e-8 and abs(qs.sum() - 0.3) < 1e-8


def test_reduced_gradient_properties():
    """J q̇_RG = x; with x = 0, Ḣ = ∇Hᵀq̇ = step·‖∇'H‖² ≥ 0 (RG climbs H along the self-motion)."""
    for _ in range(5):
        J = jac7(rand_q(7))[:3]
        g = RNG.normal(size=(7, 1))
        x = RNG.normal(size=(3, 1))
        a = rs.best_partition(F, J)
        v, gr = rs.reduced_gradient(F, J, x, g, a, 0.7)
        assert np.allclose(J @ v, x)
        v0, gr0 = rs.reduced_gradient(F, J, np.zeros((3, 1)), g, a, 0.7)
        assert np.isclose((g.T @ v0)[0, 0], 0.7 * (gr0.T @ gr0)[0, 0])


def test_named_manipulability_gradient_by_finite_differences():
    q = np.array([0.2, 0.9, -0.4, 0.3])
    text = ASK_4R + f"""    at: {_at(q)}
    velocity: [1, 0]
    gradient: manipulability
    methods: [null_space, reduced_gradient]
"""
    res = all_results(solve_problem(load_problem_text(text)))
    g = np.array(sp.Matrix(res["grad_H_at"].value).evalf().tolist(), dtype=float).ravel()
    H = lambda qq: np.sqrt(np.linalg.det(jac4(qq) @ jac4(qq).T))
    fd = np.array([(H(q + e) - H(q - e)) / 2e-6 for e in np.eye(4) * 1e-6])
    assert np.allclose(g, fd, atol=1e-6)
    for name in ("qdot", "qdot_rg"):
        v = np.array(sp.Matrix(res[name].value).evalf().tolist(), dtype=float).ravel()
        assert np.allclose(jac4(q) @ v, [1, 0])


def test_acceleration_level_motion():
    """Integrated at acceleration level with q̈ = J^#(r̈ − J̇q̇): the task velocity grows as r̈ t; with SNS every
    joint acceleration stays within its bounds along the motion."""
    base = ASK_4R + """    level: acceleration
    at: {q1: 0.3, q2: 0.9, q3: -0.6, q4: 1.1}
    joint_velocity: [0.4, -0.7, 0.5, 0.2]
    acceleration: [0.3, -0.8]
    bounds: [1.5, 1.5, 1.5, 1.5]
"""
    ps = all_results(solve_problem(load_problem_text(base + """    methods: [pseudoinverse]
    motion: {start: {q1: 0.3, q2: 0.9, q3: -0.6, q4: 1.1}, duration: 0.5, method: pseudoinverse, steps: 100}
""")))
    q = np.array(ps["q_end"].value.evalf().tolist(), dtype=float).ravel()
    qd = np.array(ps["qdot_end"].value.evalf().tolist(), dtype=float).ravel()
    v0 = jac4(np.array([0.3, 0.9, -0.6, 1.1])) @ np.array([0.4, -0.7, 0.5, 0.2])
    assert np.allclose(jac4(q) @ qd, v0 + np.array([0.3, -0.8]) * 0.5, atol=1e-6)
    sns_ = all_results(solve_problem(load_problem_text(base + """    methods: [sns]
    motion: {start: {q1: 0.3, q2: 0.9, q3: -0.6, q4: 1.1}, duration: 0.5, method: sns, steps: 100}
""")))
    assert bool(sns_["motion_within_bounds"].value)
    from solver.publish.render import render
    p = load_problem_text(base + """    methods: [sns]
    motion: {start: {q1: 0.3, q2: 0.9, q3: -0.6, q4: 1.1}, duration: 0.1, method: sns, steps: 10}
""")
    assert "**Motion.**" in render(p, solve_problem(p), "md")


def test_variable_damping_only_near_singularity():
    q_far, q_near = np.array([0.3, 0.9, -0.6, 1.1]), np.array([0.3, 1e-3, 2e-3, -1e-3])
    for q, damped in ((q_far, False), (q_near, True)):
        res = all_results(solve_problem(load_problem_text(ASK_4R + f"""    at: {_at(q)}
    velocity: [0.3, -0.2]
    mu: {{epsilon: 0.1, max: 0.2}}
    methods: [pseudoinverse, dls]
""")))
        mu = float(res["mu_dls"].value)
        smin = np.linalg.svd(jac4(q), compute_uv=False)[-1]
        assert (mu > 0) == damped == (smin < 0.1)
        assert np.isclose(mu ** 2, 0.04 * (1 - (smin / 0.1) ** 2) if damped else 0.0)
        v = np.array(res["qdot_dls"].value.evalf().tolist(), dtype=float).ravel()
        ref = jac4(q).T @ np.linalg.solve(jac4(q) @ jac4(q).T + mu ** 2 * np.eye(2), [0.3, -0.2])
        assert np.allclose(v, ref, atol=1e-9)


def test_variable_damping_exact_data():
    res = all_results(solve_problem(load_problem_text(ASK_4R.replace("l2: 0.7", "l2: 1").replace("l3: 0.5", "l3: 1")
                                                      .replace("l4: 0.3", "l4: 1") + """    at: {q1: 0, q2: 0, q3: 0, q4: 0}
    velocity: [0, 1]
    mu: {epsilon: 0.1, max: 0.5}
    methods: [pseudoinverse, dls]
""")))
    assert float(res["mu_dls"].value) == 0.5  # stretched: σ_min = 0, full damping
    v = res["qdot_dls"].value
    assert all(x.is_Rational for x in v)
    J = np.array([[0, 0, 0, 0], [4, 3, 2, 1]], dtype=float)
    assert np.allclose(np.array(v.evalf().tolist(), dtype=float).ravel(),
                       J.T @ np.linalg.solve(J @ J.T + 0.25 * np.eye(2), [0, 1]))


def test_extended_optimal_keeps_h_stationary():
    """Baillieul's extended Jacobian on a planar 3R: starting where g = nᵀ∇H = 0 (found numerically), the joint
    velocity realizes the task and keeps ġ = 0 (finite differences along q̇)."""
    from scipy.optimize import brentq
    L = (1.0, 0.8, 0.5)

    def J3(q):
        c = np.cumsum(q)
        return np.array([[-sum(L[k] * np.sin(c[k]) for k in range(j, 3)) for j in range(3)],
                         [sum(L[k] * np.cos(c[k]) for k in range(j, 3)) for j in range(3)]])

    def g(q):  # H = sin(q2)^2 + sin(q3)^2, n = signed minors of J
        J = J3(q)
        n = np.array([np.linalg.det(J[:, [1, 2]]), -np.linalg.det(J[:, [0, 2]]), np.linalg.det(J[:, [0, 1]])])
        return n @ np.array([0, np.sin(2 * q[1]), np.sin(2 * q[2])])

    q3 = brentq(lambda x: g(np.array([0.3, 0.9, x])), -1.5, -0.05)
    q = np.array([0.3, 0.9, q3])
    assert abs(g(q)) < 1e-10
    text = f"""
id: xo
title: 3R
symbols: {{}}
robot: {{joints: [R, R, R]}}
asks:
  - kind: redundancy
    task: [cos(q1) + 0.8*cos(q1+q2) + 0.5*cos(q1+q2+q3), sin(q1) + 0.8*sin(q1+q2) + 0.5*sin(q1+q2+q3)]
    velocity: [0.2, -0.4]
    gradient: sin(q2)^2 + sin(q3)^2
    at: {_at(q)}
    methods: [extended_optimal]
"""
    res = all_results(solve_problem(load_problem_text(text)))
    v = np.array(res["qdot_xo"].value.evalf().tolist(), dtype=float).ravel()
    assert np.allclose(J3(q) @ v, [0.2, -0.4], atol=1e-9)
    h = 1e-6
    assert abs((g(q + h * v) - g(q - h * v)) / (2 * h)) < 1e-6


def test_sns_derived_bounds_acceleration_level():
    """Bounds from joint range, velocity and acceleration limits over T: the SNS q̈ keeps the next q̇ within V and the
    next q within the range (q + q̇T + q̈T²/2)."""
    q, qd = np.array([0.3, 0.9, -0.6, 1.1]), np.array([0.4, -0.7, 0.5, 0.2])
    text = ASK_4R + f"""    level: acceleration
    at: {_at(q)}
    joint_velocity: {list(map(float, qd))}
    acceleration: [3, -4]
    bounds: {{position: [[-2, 2], [-1, 1], [-0.62, 1], [-2, 1.11]], velocity: [1, 1, 1, 1], acceleration: [5, 5, 5, 5],
              T: 0.1}}
    methods: [sns]
"""
    res = all_results(solve_problem(load_problem_text(text)))
    a = np.array(res["qddot_sns"].value.evalf().tolist(), dtype=float).ravel()
    T = 0.1
    assert np.all(np.abs(a) <= 5 + 1e-9) and np.all(np.abs(qd + a * T) <= 1 + 1e-9)
    qn = q + qd * T + 0.5 * a * T ** 2
    assert np.all(qn >= np.array([-2, -1, -0.62, -2]) - 1e-9) and np.all(qn <= np.array([2, 1, 1, 1.11]) + 1e-9)
    hi = np.array(res["bounds_upper"].value.evalf().tolist(), dtype=float).ravel()
    assert np.isclose(hi[3], -2)  # joint 4 is 0.01 rad below its limit, moving up: it must decelerate


def test_reduced_gradient_realizes_the_task_and_is_the_gradient_along_self_motions():
    q = np.array([0.4, 0.7, -0.5, 0.9])
    H = "sin(q2)^2 + cos(q3) + q4^2/2"
    text = ASK_4R + f"""    at: {_at(q)}
    velocity: [0.5, -0.2]
    gradient: {H}
    step: 0.7
    methods: [reduced_gradient, null_space]
"""
    res = all_results(solve_problem(load_problem_text(text)))
    num = lambda k: np.array(sp.Matrix(res[k].value).evalf().tolist(), dtype=float)  # noqa: E731
    J = jac4(q)
    v = num("qdot_rg").ravel()
    assert np.allclose(J @ v, [0.5, -0.2])
    Ja, Jb, rg = num("Ja"), num("Jb"), num("grad_reduced").ravel()
    assert np.allclose(num("Ja_inv") @ Ja, np.eye(2))
    # the default J_a is the best-conditioned 2x2 minor (largest smallest singular value)
    smins = [np.linalg.svd(J[:, [i, j]], compute_uv=False)[-1] for i in range(4) for j in range(i + 1, 4)]
    assert np.isclose(np.linalg.svd(Ja, compute_uv=False)[-1], max(smins))
    a = [next(c for c in range(4) if np.allclose(J[:, c], Ja[:, k])) for k in range(2)]
    b = [c for c in range(4) if c not in a]
    grad = np.array([0.0, np.sin(2 * q[1]), -np.sin(q[2]), q[3]])
    for k in range(2):  # a unit change of q_b,k on the self-motion manifold changes H by rg_k (first order)
        dq = np.zeros(4)
        dq[b[k]] = 1.0
        dq[a] = -np.linalg.solve(Ja, Jb[:, k])
        assert np.isclose(grad @ dq, rg[k])
    assert np.allclose(v[b], 0.7 * rg)
