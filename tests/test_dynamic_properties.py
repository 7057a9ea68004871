"""The `dynamic_properties` ask: eigenvalue bounds contain sampled eigenvalues, α bounds sampled ‖∂g/∂q‖, every
factorization satisfies S q̇ = c (skew / not skew as claimed), the inverse dynamics drives the model along q_d(t)
(simulated), the model in other coordinates, the conditions for a real robot, energy rates, property checks."""
import numpy as np
import pytest
import sympy as sp
from conftest import R2_ROBOT, error_found_without_solving
from scipy.integrate import solve_ivp

from solver.dynamics.model import derive
from solver.math.simplify import is_zero
from solver.publish.render import render
from solver.registry import PROPERTY_CHECKS, load_all
from solver.solve import all_results, solve_problem
from solver.spec import load_problem_text
from solver.spec.errors import UserError

# a spatial 3R (anthropomorphic-like, standard DH) with numeric data: no exercise uses it
R3 = """
id: t
title: spatial 3R
symbols: {l1: l1, l2: l2, l3: l3, m1: m1, m2: m2, m3: m3, g0: g0}
values: {l1: 0.5, l2: 0.7, l3: 0.4, m1: 3, m2: 2, m3: 1.5, g0: 9.81}
robot:
  joints: [R, R, R]
  gravity: [0, 0, -g0]
  dh:
    table:
      - {a: 0, alpha: pi/2, d: l1, theta: q1}
      - {a: l2, alpha: 0, d: 0, theta: q2}
      - {a: l3, alpha: 0, d: 0, theta: q3}
    links:
      - {mass: m1, com: [0, -l1/2, 0], inertia: [0.1, 0.05, 0.1]}
      - {mass: m2, com: [-l2/2, 0, 0.05], inertia: [0.02, 0.1, 0.1]}
      - {mass: m3, com: [-l3/2, 0, 0], inertia: [0.01, 0.05, 0.05]}
asks:
  - kind: dynamic_properties
    find: [eigenvalues, alpha, factorizations, momentum, power]
    state: {q1: 0.1, q2: 0.2, q3: -0.3, dq1: 1, dq2: -0.5, dq3: 0.25}
    u: [1, -2, 3]
"""

RP = """
id: t
title: planar RP
symbols: {m1: m1, m2: m2, d1: d1, I1: I1, g0: g0}
values: {m1: 2, m2: 1, d1: 0.4, I1: 0.3, g0: 9.81}
robot:
  joints: [R, P]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [q2*cos(q1), q2*sin(q1)], angle: q1}
asks:
  - kind: dynamic_properties
    find: [eigenvalues, inverse_dynamics, coordinates, feasibility]
    ranges: {q2: [0.2, 1.5]}
    trajectory: [0.5*sin(t), 1 + 0.2*t^2]
    times: [0, 1]
    transform: [[1, 0], [0, 2]]
    new_coordinates: [p1, p2]
"""


def results(text):
    p = load_problem_text(text)
    return p, all_results(solve_problem(p))


def lam(M):
    return np.linalg.eigvalsh(np.array(M, dtype=float))


def test_eigenvalue_and_alpha_bounds_contain_samples():
    p, r = results(R3)
    dm = derive(p.robot)
    B = sp.lambdify(p.robot.q, dm.B.xreplace(p.values))
    A = sp.lambdify(p.robot.q, dm.g.jacobian(p.robot.q).xreplace(p.values))
    lmin, lmax = float(r["lambda_min"].value), float(r["lambda_max"].value)
    alpha = float(r["alpha"].value.xreplace(p.values))
    rng = np.random.default_rng(3)
    for q in rng.uniform(-np.pi, np.pi, (300, 3)):
        ev = lam(B(*q))
        assert lmin - 1e-9 <= ev[0] and ev[-1] <= lmax + 1e-9
        assert np.linalg.norm(np.array(A(*q), dtype=float), 2) <= alpha + 1e-9
    # attained at the reported configurations
    assert abs(lam(B(*[float(x) for x in r["q_lambda_max"].value]))[-1] - lmax) < 1e-6
    assert abs(lam(B(*[float(x) for x in r["q_lambda_min"].value]))[0] - lmin) < 1e-6


def test_factorizations():
    p, r = results(R3)
    dm = derive(p.robot)
    v = sp.Matrix(p.robot.dq)
    for name in ("S_skew", "S_alt"):
        assert all(is_zero(sp.expand(x)) for x in r[name].value * v - dm.c)
    N1, N2 = r["N_skew"].value, r["N_alt"].value
    assert all(is_zero(sp.expand(x)) for x in N1 + N1.T)
    assert not all(is_zero(sp.expand(x)) for x in N2 + N2.T)
    assert r["skew_alt"].value is False
    assert all(is_zero(sp.expand(x)) for x in r["p"].value - dm.B * v)


def test_power():
    p, r = results(R3)
    dq = np.array([1, -0.5, 0.25])
    assert abs(float(r["Edot"].value) - dq @ np.array([1, -2, 3])) < 1e-9
    dm = derive(p.robot)
    st = dict(zip(p.robot.q, [0.1, 0.2, -0.3]))
    g = np.array(dm.g.xreplace(p.values).xreplace(st), dtype=float).ravel()
    assert abs(float(r["Udot"].value) - dq @ g) < 1e-9
    assert abs(float(r["Ldot"].value) - (float(r["Tdot"].value) - float(r["Udot"].value))) < 1e-9


def test_inverse_dynamics_drives_the_model_along_qd():
    p, r = results(RP)
    dm = derive(p.robot)
    t = sp.Symbol("t", real=True)
    ud = sp.lambdify(t, r["u_d"].value.xreplace(p.values))
    rob = p.robot
    Bf = sp.lambdify(rob.q, dm.B.xreplace(p.values))
    rest = sp.lambdify(rob.q + rob.dq, (dm.c + dm.g).xreplace(p.values))

    def f(tt, x):
        q, v = x[:2], x[2:]
        acc = np.linalg.solve(np.array(Bf(*q), float), np.array(ud(tt), float).ravel() - np.array(rest(*q, *v), float).ravel())
        return np.concatenate([v, acc])

    sol = solve_ivp(f, (0, 2), [0, 1, 0.5, 0], rtol=1e-10, atol=1e-12)
    T = sol.t[-1]
    assert abs(sol.y[0, -1] - 0.5 * np.sin(T)) < 1e-6 and abs(sol.y[1, -1] - (1 + 0.2 * T ** 2)) < 1e-6
    assert r["u_d_at1"].value.shape == (2, 1)


def test_other_coordinates():
    p, r = results(RP)
    dm = derive(p.robot)
    T = sp.Matrix([[1, 0], [0, 2]])
    th = sp.symbols("p1 p2", real=True)
    dth = sp.symbols("dp1 dp2", real=True)
    sub = dict(zip(p.robot.q, T * sp.Matrix(th)))
    vsub = dict(zip(p.robot.dq, T * sp.Matrix(dth)))
    Bt = r["B_new"].value
    assert all(is_zero(sp.expand(x)) for x in Bt - T.T * dm.B.xreplace(sub) * T)
    ct = T.T * dm.c.xreplace(sub).xreplace(vsub)
    assert all(is_zero(sp.expand(x)) for x in r["c_new"].value - ct)
    assert all(is_zero(sp.expand(x)) for x in r["g_new"].value - T.T * dm.g.xreplace(sub))


def given(B, g="[0, 0]", signs=""):
    return f"""
id: t
title: given
symbols: {{a1: {{meaning: a1{signs}}}, a2: a2, a3: a3}}
robot:
  joints: [R, R]
  model: {{B: "{B}", g: "{g}"}}
asks: [{{kind: dynamic_properties, find: [feasibility]}}]
"""


def test_feasibility():
    _, r = results(given("[[a1 + 2*a2*cos(q2), a3 + a2*cos(q2)], [a3 + a2*cos(q2), a3]]"))
    conds = r["pd_conditions"].value
    assert r["real_robot"].value is True and len(conds) == 2
    a1, a2 = sp.symbols("a1 a2", positive=True)
    assert any(is_zero(sp.expand(c.subs({s: sp.Symbol(s.name, positive=True) for s in c.free_symbols}) - (a1 - 2 * a2)))
               for c in conds)
    _, r = results(given("[[a1 + 2*a2*cos(q2), a1 + a2*cos(q2)], [a1 + a2*cos(q2), a1]]"))
    assert r["pd_possible"].value is False and r["real_robot"].value is False
    _, r = results(given("[[a1 + a2*q1^2, a2], [a2, a2]]"))
    assert r["B_indep_q1"].value is False and r["real_robot"].value is False
    _, r = results(given("[[a1, 0], [0, a2]]", g="[a3*q2, 0]"))
    assert r["g_conservative"].value is False


def test_property_checks_accept_alternatives_and_reject_wrong():
    load_all()
    p, r = results(R3.replace("[eigenvalues, alpha, factorizations, momentum, power]", "[factorizations]"))
    chk = PROPERTY_CHECKS["S_alt"]
    S1, S2 = r["S_skew"].value, r["S_alt"].value
    v = p.robot.dq
    S0 = sp.zeros(3, 3)
    S0[1, 1], S0[1, 2] = v[2], -v[1]          # S0 q̇ = 0, S0 + S0ᵀ ≠ 0
    other = S1 + S0
    assert chk(p, r, "S_alt", other.tolist(), None, None).correct
    assert not chk(p, r, "S_alt", S1.tolist(), None, None).correct           # skew: not what was asked
    assert chk(p, r, "S_alt", (S2 + sp.eye(3)).tolist(), None, None).fraction == 0.0
    assert PROPERTY_CHECKS["S_skew"](p, r, "S_skew", S1.tolist(), None, None).correct
    N = r["Bdot"].value - 2 * other
    assert PROPERTY_CHECKS["N_alt"](p, r, "N_alt", N.tolist(), None, None).correct
    own = lambda nm: other.tolist() if nm == "S_alt" else None
    assert PROPERTY_CHECKS["N_alt"](p, r, "N_alt", N.tolist(), own, None).correct
    theirs = lambda nm: S2.tolist() if nm == "S_alt" else None
    assert not PROPERTY_CHECKS["N_alt"](p, r, "N_alt", N.tolist(), theirs, None).correct   # N of another S


def test_render_and_errors():
    p = load_problem_text(RP)
    sols = solve_problem(p)
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "Inverse dynamics" in md and "p_{1}" in md
    assert "\\begin{itemize}" in tex and "$$" not in tex
    bad = RP.replace("    ranges: {q2: [0.2, 1.5]}\n", "")
    with pytest.raises(UserError, match="range"):
        solve_problem(load_problem_text(bad))


PRP = """
id: t
title: vertical RP with an unbounded prismatic joint
symbols: {m1: m1, m2: m2, d1: d1, g0: g0, I1: I1}
robot:
  joints: [R, P]
  gravity: [0, -g0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [q2*cos(q1), q2*sin(q1)], angle: q1}
asks:
  - kind: dynamic_properties
    find: [alpha, forward_dynamics]
    u: [u1, 0]
"""


def test_affine_gravity_bound_holds_and_beta_check():
    load_all()
    p, r = results(PRP)
    A = r["dg_dq"].value
    alpha, beta = r["alpha"].value, r["beta"].value
    rng = np.random.default_rng(1)
    for _ in range(5):
        vals = {s: sp.Float(rng.uniform(0.5, 2)) for s in p.symbols.values()}
        f = sp.lambdify(p.robot.q, A.xreplace(vals))
        a, b = float(alpha.xreplace(vals)), float(beta.xreplace(vals))
        for q1, q2 in zip(rng.uniform(-np.pi, np.pi, 100), rng.uniform(-50, 50, 100)):
            assert np.linalg.norm(np.array(f(q1, q2), float), 2) <= a + b * abs(q2) + 1e-9
    chk = PROPERTY_CHECKS["beta"]
    assert chk(p, r, "beta", beta, lambda n: None, None).correct
    assert not chk(p, r, "beta", beta / 3, lambda n: None, None).correct


def test_forward_dynamics():
    p, r = results(PRP)
    dm = derive(p.robot)
    u1 = p.robot.inputs[0]
    ddq = r["ddq"].value
    assert all(is_zero(sp.expand(sp.simplify(x))) for x in dm.B * ddq + dm.c + dm.g - sp.Matrix([u1, 0]))


BAL = """
id: t
title: planar 3R, CoM offsets along the links
symbols: {l1: l1, l2: l2, m1: m1, m2: m2, m3: m3, d1: {meaning: d1, sign: real}, d2: {meaning: d2, sign: real},
          d3: {meaning: d3, sign: real}, g0: g0}
robot:
  joints: [R, R, R]
  gravity: [0, -g0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1}
    - {mass: m2, com: [l1*cos(q1) + d2*cos(q1 + q2), l1*sin(q1) + d2*sin(q1 + q2)], angle: q1 + q2}
    - {mass: m3, com: [l1*cos(q1) + l2*cos(q1 + q2) + d3*cos(q1 + q2 + q3),
                       l1*sin(q1) + l2*sin(q1 + q2) + d3*sin(q1 + q2 + q3)], angle: q1 + q2 + q3}
asks:
  - kind: dynamic_properties
    find: [balancing]
    unknowns: UNK
"""


def test_balancing_solves_g_identically_zero_and_says_when_it_cannot():
    p, r = results(BAL.replace("UNK", "[d1, d2, d3]"))
    d1, d2, d3, m1, m2, m3, l1, l2 = (p.names[k] for k in ("d1", "d2", "d3", "m1", "m2", "m3", "l1", "l2"))
    vals = r["balancing"].value
    assert r["balanceable"].value is True
    assert sp.simplify(vals[2]) == 0 and sp.simplify(vals[1] + m3 * l2 / m2) == 0
    assert sp.simplify(vals[0] + (m2 + m3) * l1 / m1) == 0
    g = derive(p.robot).g.subs({d1: vals[0], d2: vals[1], d3: vals[2]})
    assert all(is_zero(x) for x in g)  # g ≡ 0 with the solution
    _, r2 = results(BAL.replace("UNK", "[d3]"))  # d1, d2 left free: the lower links still weigh
    assert r2["balanceable"].value is False and "balancing" not in r2
    with pytest.raises(UserError):
        results(BAL.replace("UNK", "[q1]"))


def test_nonlinear_change_of_coordinates_preserves_the_dynamics():
    """q = φ(θ) nonlinear: along a trajectory θ(t), B_θ θ̈ + c_θ + g_θ = J_φᵀ (B q̈ + c + g) at q = φ(θ(t))
    (virtual work), checked numerically at several instants."""
    text = RP.replace("find: [eigenvalues, inverse_dynamics, coordinates, feasibility]", "find: [coordinates]")
    text = text.replace("    transform: [[1, 0], [0, 2]]\n", "    map: [p1 + p2^2/4, p2 + sin(p1)/2]\n")
    p, r = results(text)
    dm = derive(p.robot)
    th = sp.symbols("p1 p2", real=True)
    dth = sp.symbols("dp1 dp2", real=True)
    t = sp.Symbol("t", real=True)
    phi = sp.Matrix([th[0] + th[1] ** 2 / 4, th[1] + sp.sin(th[0]) / 2])
    Jp = phi.jacobian(th)
    assert all(is_zero(sp.expand(x)) for x in r["J_map"].value - Jp)
    tht = sp.Matrix([0.3 * sp.sin(t) + 0.2, 0.8 + 0.1 * t ** 2])
    qt = phi.xreplace(dict(zip(th, tht)))
    vals = p.values
    q, dq, ddq = p.robot.q, p.robot.dq, p.robot.ddq
    for tk in (0.0, 0.7, 1.3):
        st = {t: tk}
        qn, dqn, ddqn = qt.subs(st), qt.diff(t).subs(st), qt.diff(t, 2).subs(st)
        sq = {**dict(zip(q, qn)), **dict(zip(dq, dqn)), **dict(zip(ddq, ddqn)), **vals}
        tau_q = (dm.B * sp.Matrix(ddqn) + dm.c + dm.g).subs(sq)
        thn, dthn, ddthn = tht.subs(st), tht.diff(t).subs(st), tht.diff(t, 2).subs(st)
        sth = {**dict(zip(th, thn)), **dict(zip(dth, dthn)), **vals}
        tau_th = (r["B_new"].value * ddthn + r["c_new"].value + r["g_new"].value).subs(sth)
        lhs = np.array((Jp.subs(dict(zip(th, thn))).T * tau_q).evalf(), dtype=float)
        assert np.allclose(np.array(tau_th.evalf(), dtype=float), lhs, atol=1e-9)


@pytest.mark.parametrize("task", ["[(q2 + 0.3)*cos(q1), (q2 + 0.3)*sin(q1)]", "(q2 + 0.3)*sin(q1)"])
def test_cartesian_inertia_is_the_task_space_kinetic_energy(task):
    """M_p = (J B⁻¹ Jᵀ)⁻¹ at a state (square and 1-row tasks); for a square J the symbolic M_p agrees and
    ½ṙᵀM_pṙ = ½q̇ᵀBq̇; M_p_inv_at is its inverse."""
    text = RP.replace("find: [eigenvalues, inverse_dynamics, coordinates, feasibility]", "find: [cartesian_inertia]")
    text += f"    task: {task}\n    state: {{q1: 0.3, q2: 0.8}}\n"
    p, r = results(text)
    dm = derive(p.robot)
    q1, q2 = p.robot.q
    st = {q1: sp.Rational(3, 10), q2: sp.Rational(4, 5), **p.values}
    fx = sp.sympify(task.replace("^", "**"), locals={"q1": q1, "q2": q2})
    f = sp.Matrix(fx if isinstance(fx, (list, tuple)) else [fx])
    J = np.array(f.jacobian([q1, q2]).subs(st).evalf(), dtype=float)
    B = np.array(dm.B.subs(st).evalf(), dtype=float)
    Mp = np.array(r["M_p_at"].value.evalf(), dtype=float)
    assert np.allclose(Mp, np.linalg.inv(J @ np.linalg.inv(B) @ J.T))
    assert np.allclose(np.array(r["M_p_inv_at"].value.evalf(), dtype=float) @ Mp, np.eye(Mp.shape[0]))
    assert np.allclose(sorted(np.array(r["eig_M_p_at"].value.evalf(), dtype=float).ravel()), sorted(lam(Mp)))
    if J.shape[0] == 2:
        assert np.allclose(np.array(r["M_p"].value.subs(st).evalf(), dtype=float), Mp)
        v = np.array([0.7, -1.1])
        rd = J @ v
        assert np.isclose(rd @ Mp @ rd, v @ B @ v)
    else:
        assert "M_p" not in r


def test_cartesian_inertia_of_a_planar_3r_with_orientation():
    """cartesian_inertia(J, B) = J⁻ᵀ B J⁻¹ on a robot no exercise uses (planar 3R, task (x, y, φ), its own B):
    equal to the numeric product at random configurations, and ½ṙᵀM_pṙ = ½q̇ᵀBq̇."""
    from solver.dynamics.properties import cartesian_inertia
    q1, q2, q3 = q = sp.symbols("q1 q2 q3")
    a1, a2, a3, m2, m3 = sp.symbols("a1 a2 a3 m2 m3", positive=True)
    f = sp.Matrix([a1 * sp.cos(q1) + a2 * sp.cos(q1 + q2) + a3 * sp.cos(q1 + q2 + q3),
                   a1 * sp.sin(q1) + a2 * sp.sin(q1 + q2) + a3 * sp.sin(q1 + q2 + q3), q1 + q2 + q3])
    J = f.jacobian(q)
    B = sp.Matrix([[3 + m2 * sp.cos(q2) + m3 * sp.cos(q2 + q3), 1 + m3 * sp.cos(q3), 0],
                   [1 + m3 * sp.cos(q3), 2 + m2, m3 * sp.cos(q3) / 2],
                   [0, m3 * sp.cos(q3) / 2, 1]])
    Mp = cartesian_inertia(J, B)
    assert Mp.is_symmetric()
    rng = np.random.default_rng(7)
    for _ in range(3):
        st = dict(zip(q, rng.uniform(-2, 2, 3))) | dict(zip((a1, a2, a3, m2, m3), rng.uniform(0.5, 2, 5)))
        Jn, Bn = (np.array(M.subs(st).evalf(), dtype=float) for M in (J, B))
        Mn = np.array(Mp.subs(st).evalf(), dtype=float)
        Ji = np.linalg.inv(Jn)
        assert np.allclose(Mn, Ji.T @ Bn @ Ji)
        v = rng.normal(size=3)
        assert np.isclose((Jn @ v) @ Mn @ (Jn @ v), v @ Bn @ v)


def test_fault_torque_imposes_the_acceleration():
    """With τ_f at joint 1, the forward dynamics of B q̈ + c + g = u − e₁ τ_f give q̈₁ = −λ q̇₁ (planar RP)."""
    text = PRP.replace("[alpha, forward_dynamics]", "[fault]").replace(
        "    u: [u1, 0]\n", "    u: [u1, u2]\n    fault: {joint: 1, ddq: -5*dq1}\n")
    p, r = results(text)
    dm = derive(p.robot)
    tf = r["tau_f"].value
    vals = {s: sp.Rational(k + 3, 4) for k, s in enumerate(sorted(p.symbols.values(), key=lambda s: s.name))}
    st = {**dict(zip(p.robot.q, [0.3, 1.1])), **dict(zip(p.robot.dq, [0.5, -1])),
          **dict(zip(p.robot.inputs, [2, -1])), **vals}
    B = dm.B.xreplace(st)
    rhs = (sp.Matrix(p.robot.inputs) - dm.c - dm.g - sp.Matrix([tf, 0])).xreplace(st)
    ddq = np.linalg.solve(np.array(B.evalf(), float), np.array(rhs.evalf(), float).ravel())
    assert abs(ddq[0] + 5 * 0.5) < 1e-9
    want = np.array(r["ddq_fault"].value.xreplace(st).evalf(), float).ravel()
    assert np.allclose(ddq, want)


def test_symbolic_inverse_is_bounded():
    text = """
id: t
title: symbolic 3R given model
symbols: {a1: a1, a2: a2, a3: a3}
robot:
  joints: [R, R, R]
  model: {B: "[[a1 + a2*cos(q2), a3, 0], [a3, a2 + a3*cos(q3), 0], [0, 0, a1]]"}
asks: [{kind: dynamic_properties, find: [forward_dynamics], u: [u1, u2, u3]}]
"""
    with pytest.raises(UserError, match="too large"):
        solve_problem(load_problem_text(text))
    _, r = results(text.replace("symbols: {a1: a1, a2: a2, a3: a3}", "symbols: {a1: a1, a2: a2, a3: a3}\nvalues: {a1: 3, a2: 1, a3: 0.5}"))
    assert r["ddq"].value.shape == (3, 1)


def test_torque_limits_vertices_and_zero_condition():
    text = PRP.replace("[alpha, forward_dynamics]", "[torque_limits]").replace("    u: [u1, 0]\n", "    limits: [5, 3]\n")
    p, r = results(text)
    dm = derive(p.robot)
    nv = dm.c + dm.g
    for k, v in enumerate(r["acc_vertices"].value):
        s1, s2 = (1, 1, -1, -1)[k], (1, -1, 1, -1)[k]
        assert all(is_zero(sp.expand(sp.simplify(x))) for x in dm.B * v + nv - sp.Matrix([5 * s1, 3 * s2]))
    conds = r["zero_acc_conditions"].value
    vals = {s: sp.Integer(1) for s in p.symbols.values()}
    st = {**vals, p.robot.q[0]: 0, p.robot.q[1]: 1, p.robot.dq[0]: 0, p.robot.dq[1]: 0}
    feasible = all(float(c.xreplace(st)) > 0 for c in conds)
    nn = [float(x.xreplace(st)) for x in nv]
    assert feasible == (abs(nn[0]) < 5 and abs(nn[1]) < 3)


def test_eigenvalues_of_a_three_by_three_inertia_matrix_are_reported():
    """PPP robot, B = [[6, 5, 0], [5, 5, 0], [0, 0, 3]] (no closed-form eigenvalue list past n = 2): the extreme
    eigenvalues (11 ∓ √101)/2 and both reports render (the template once required the n ≤ 2 list)."""
    p = load_problem_text("""
id: eig3
title: PPP
symbols: {m1: mass 1, m2: mass 2, m3: mass 3}
values: {m1: 1, m2: 2, m3: 3}
robot:
  joints: [P, P, P]
  links:
    - {mass: m1, com: [q1, 0]}
    - {mass: m2, com: [q1 + q2, 0]}
    - {mass: m3, com: [q1 + q2, q3]}
asks:
  - {kind: dynamic_properties, find: [eigenvalues]}
""")
    sols = solve_problem(p)
    r = all_results(sols)
    lo, hi = (11 - np.sqrt(101)) / 2, (11 + np.sqrt(101)) / 2
    assert abs(float(r["lambda_min"].value) - lo) < 1e-12 and abs(float(r["lambda_max"].value) - hi) < 1e-12
    for fmt in ("md", "tex"):
        assert "Eigenvalues of the inertia matrix" in render(p, sols, fmt)


def test_alternative_factorization_with_a_zero_component():
    """c₃ ≡ 0 (a 2R arm and a decoupled prismatic joint): the monomial factorization has a zero third row (it fell
    back to S₁ + S₀ because Poly(0) has no quadratic monomial)."""
    text = """
id: t
title: 2R with a decoupled prismatic joint (c3 = 0)
symbols: {a1: a1, a2: a2, a3: a3, m3: m3}
robot:
  joints: [R, R, P]
  model:
    B: [[a1 + 2*a2*cos(q2), a3 + a2*cos(q2), 0], [a3 + a2*cos(q2), a3, 0], [0, 0, m3]]
asks:
  - kind: dynamic_properties
    find: [factorizations]
"""
    p, r = results(text)
    a2 = sp.Symbol("a2", positive=True)
    q2, dq1, dq2 = sp.symbols("q2 dq1 dq2", real=True)
    s = sp.sin(q2)
    want = sp.Matrix([[-2 * a2 * dq2 * s, -a2 * dq2 * s, 0], [a2 * dq1 * s, 0, 0], [0, 0, 0]])
    S2 = r["S_alt"].value
    assert (S2 - want).applyfunc(sp.expand) == sp.zeros(3, 3)
    dm = derive(p.robot)
    assert (S2 * sp.Matrix(p.robot.dq) - dm.c).applyfunc(sp.expand) == sp.zeros(3, 1)
    assert r["skew_alt"].value is False
    N = r["N_alt"].value
    assert (N + N.T).applyfunc(sp.expand) != sp.zeros(3, 3)
    # numerically: S₂ q̇ = c with c from finite differences of B (c = Ḃ q̇ − ½ ∂(q̇ᵀ B q̇)/∂q)
    rng = np.random.default_rng(2)
    vals = {s_: rng.uniform(0.5, 2) for s_ in p.symbols.values()}
    Bf = sp.lambdify(p.robot.q, dm.B.xreplace(vals))
    S2f = sp.lambdify(p.robot.q + p.robot.dq, S2.xreplace(vals))
    for _ in range(3):
        x, v = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        h = 1e-6
        Bdot = (np.array(Bf(*(x + h * v)), float) - np.array(Bf(*(x - h * v)), float)) / (2 * h)
        dK = [(v @ np.array(Bf(*(x + h * e)), float) @ v - v @ np.array(Bf(*(x - h * e)), float) @ v) / (4 * h)
              for e in np.eye(3)]
        c = Bdot @ v - np.array(dK)
        assert np.allclose(np.array(S2f(*x, *v), float) @ v, c, atol=1e-6)


FD3 = """
id: t
title: planar PPR in a vertical plane with viscous friction and numeric values (B⁻¹ with the values)
symbols: {m1: m1, m2: m2, m3: m3, l3: l3, g0: g0, fv: fv, k: k, lam: lam}
values: {m1: 3, m2: 2, m3: 1, l3: 0.5, g0: 9.81, fv: 0.7, k: 2, lam: 4}
robot:
  joints: [P, P, R]
  gravity: [0, -g0]
  friction: {viscous: [fv, fv, fv]}
  links:
    - {mass: m1, com: [q1, 0]}
    - {mass: m2, com: [q1, q2]}
    - {mass: m3, com: [q1 + l3*cos(q3), q2 + l3*sin(q3)]}
asks:
  - kind: dynamic_properties
    find: [forward_dynamics]
    u: [k, 0, 1]
    state: {q1: 0.3, q2: -0.4, q3: 1.1, dq1: 0.5, dq2: -1, dq3: 2}
"""


def _fd3_numeric(q: np.ndarray, dq: np.ndarray, u: np.ndarray, ext: np.ndarray | None = None) -> np.ndarray:
    """q̈ of FD3 from its kinetic and potential energy (independent of the derivation): B = Σ mᵢ JᵢᵀJᵢ and g with
    Jacobians by complex steps, c = Ḃ q̇ − ½ ∂(q̇ᵀ B q̇)/∂q by central differences."""
    m, l3, g0, fv = [3, 2, 1], 0.5, 9.81, 0.7

    def pcs(x):
        a, b, c = x
        return [np.array([a, 0 * a]), np.array([a, b]), np.array([a + l3 * np.cos(c), b + l3 * np.sin(c)])]

    def jac(f, x, h):
        return np.array([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(len(x))]).T

    def B(x):
        out = np.zeros((3, 3))
        for i in range(3):
            J = np.array([pcs(x + 1e-30j * e)[i].imag / 1e-30 for e in np.eye(3)]).T   # complex step: exact
            out += m[i] * J.T @ J
        return out

    g = np.array([sum(m[i] * g0 * pcs(q + 1e-30j * e)[i][1].imag / 1e-30 for i in range(3)) for e in np.eye(3)])
    h = 1e-4
    c = (B(q + h * dq) - B(q - h * dq)) @ dq / (2 * h) - jac(lambda x: np.array([dq @ B(x) @ dq / 2]), q, h).ravel()
    return np.linalg.solve(B(q), u - c - g - fv * dq - (0 if ext is None else ext))


def test_forward_dynamics_substitutes_every_value():
    """n = 3: B⁻¹ needs the values, and c, g, F_v q̇ and u get them too (fv, m3 l3 in c, the masses and g0 in g and
    k in u were left symbolic next to the numeric B⁻¹): q̈ is a number, the one of the model by finite differences."""
    _, r = results(FD3)
    ddq = r["ddq"].value
    assert not set().union(*(x.free_symbols for x in ddq))
    want = _fd3_numeric(np.array([0.3, -0.4, 1.1]), np.array([0.5, -1, 2.0]), np.array([2, 0, 1.0]))
    assert np.allclose(np.array(ddq.evalf(), float).ravel(), want, rtol=1e-6, atol=1e-8)


def test_fault_substitutes_every_value():
    """The fault torque of the same PPR: τ_f at joint 2 imposing q̈₂ = −λ q̇₂ (λ = 4), at the state: a number, and
    with it the forward dynamics (finite differences) give q̈₂ = −4 · (−1) = 4 and the other q̈."""
    text = FD3.replace("[forward_dynamics]", "[fault]").replace("    u: [k, 0, 1]\n",
                                                                  "    u: [k, 0, 1]\n    fault: {joint: 2, ddq: -lam*dq2}\n")
    _, r = results(text)
    st = {sp.Symbol(n, real=True): v for n, v in
          {"q1": 0.3, "q2": -0.4, "q3": 1.1, "dq1": 0.5, "dq2": -1, "dq3": 2}.items()}
    tau = r["tau_f"].value.xreplace(st)
    assert not tau.free_symbols
    ddq = np.array(r["ddq_fault"].value.xreplace(st).evalf(), float).ravel()
    want = _fd3_numeric(np.array([0.3, -0.4, 1.1]), np.array([0.5, -1, 2.0]), np.array([2, 0, 1.0]),
                        np.array([0, float(tau), 0]))
    assert abs(want[1] - 4) < 1e-6 and np.allclose(ddq, want, rtol=1e-6, atol=1e-8)


def test_check_finds_bad_ranges_without_solving():
    """The ranges every `find` shares are read by the kind's validate hook (`check`): solving's error."""
    assert "'q7' in ranges: is not a coordinate" in error_found_without_solving(
        RP.replace("    ranges: {q2: [0.2, 1.5]}\n", "    ranges: {q7: [0.2, 1.5]}\n"))
    assert "empty range for q2" in error_found_without_solving(
        RP.replace("    ranges: {q2: [0.2, 1.5]}\n", "    ranges: {q2: [1.5, 0.2]}\n"))


# a planar 2R in a vertical plane with symbolic parameters: one `find` per ask, its options only
TWO_R = ("id: t2\ntitle: 2R\nsymbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, g0: g0}\n" + R2_ROBOT
         + "asks:\n  - kind: dynamic_properties\n")

BAD_FINDS = [
    ("forward_dynamics", "", "forward_dynamics needs u: [...]"),
    ("forward_dynamics", "    u: [1]\n", "u must be a list of 2 expressions"),
    ("forward_dynamics", "    u: [1, 0]\n    state: {q5: 1}\n", "'q5' in state: is not a coordinate or velocity"),
    ("fault", "    u: [1, 0]\n", "fault needs fault: {joint: i, ddq: ...} and u: [...]"),
    ("fault", "    u: [1, 0]\n    fault: {joint: 3, ddq: 0}\n", "joint must be between 1 and 2"),
    ("fault", "    u: [1, 0, 2]\n    fault: {joint: 2, ddq: 0}\n", "u must be a list of 2 expressions"),
    ("fault", "    u: [1, 0]\n    fault: {joint: 2, ddq: [0, 1]}\n", "ddq must be one expression"),
    ("power", "    u: [1, 0]\n", "power needs state: {q.., dq..} and u: [...]"),
    ("power", "    u: [1, 0]\n    state: {x: 1}\n", "'x' in state: is not a coordinate or velocity"),
    ("power", "    u: [1]\n    state: {q1: 1}\n", "u must be a list of 2 expressions"),
    ("torque_limits", "", "torque_limits needs limits: [T1, T2, ...]"),
    ("torque_limits", "    limits: [1, 2, 3]\n", "limits must be a list of 2 expressions"),
    ("torque_limits", "    limits: [1, 2]\n    cases: [{q1: 0}]\n", "'q1' in cases: is not a parameter"),
    ("inverse_dynamics", "", "inverse_dynamics needs trajectory: (q_d(t), n expressions in t)"),
    ("inverse_dynamics", "    trajectory: [t]\n", "trajectory must be a list of 2 expressions in t"),
    ("inverse_dynamics", "    trajectory: [t, t]\n    cases: [{zz: 1}]\n", "'zz' in cases: is not a parameter"),
    ("inverse_dynamics", "    trajectory: [t, t]\n    times: [zz]\n", "unknown name 'zz'"),
    ("balancing", "", "balancing needs unknowns: [the parameters to choose]"),
    ("balancing", "    unknowns: [q1]\n", "'q1' is not a parameter of g(q)"),
    ("balancing", "    unknowns: [zz]\n", "'zz' is not a parameter of g(q)"),
    ("cartesian_inertia", "", "cartesian_inertia needs task: [f1(q), ...]"),
    ("cartesian_inertia", "    task: [q1, q2, q1 + q2]\n", "the task has 3 components for 2 joints"),
    ("cartesian_inertia", "    task: [q1, q2]\n    state: {q9: 1}\n", "'q9' in state: is not a coordinate"),
    ("cartesian_inertia", "    task: [q1 + q2, q1 + q2]\n    state: {q1: 0, q2: 0}\n",
     "the task Jacobian is singular at this state"),
    ("coordinates", "", "coordinates needs transform: (q = T θ) or map: (q = φ(θ))"),
    ("coordinates", "    transform: [[1, 0], [0, 1]]\n    map: [th1, th2]\n", "coordinates needs transform:"),
    ("coordinates", "    transform: [[1, 0, 0], [0, 1, 0]]\n", "transform must be an invertible 2x2 matrix"),
    ("coordinates", "    transform: [[1, 1], [1, 1]]\n", "transform must be an invertible 2x2 matrix"),
    ("coordinates", "    transform: [[1, 0], [1, 1]]\n    new_coordinates: [a]\n", "1 names for 2 coordinates"),
    ("coordinates", "    transform: [[1, 0], [1, 1]]\n    new_coordinates: [m1, b]\n",
     "'m1' is already a name of the problem"),
    ("coordinates", "    map: [th1]\n", "map must list 2 expressions"),
    ("coordinates", "    map: [th1 + q2, th2]\n", "map must be written in the new coordinates, not in q2"),
    ("coordinates", "    map: [th1 + th2, th1 + th2]\n", "the map q = φ(θ) is singular"),
    ("feasibility", "    candidates: [{name: 'a b', B: [[1, 0], [0, 1]]}]\n", "candidate name 'a b' is not a plain"),
    ("feasibility", "    candidates: [{name: A, B: [[1, 0]]}]\n", "B must be a 2x2 matrix"),
    ("feasibility", "    candidates: [{name: A, B: [[1, 0], [0, 1]], g: [1, 2, 3]}]\n", "g must have 2 components"),
    ("factorizations", "    factorizations: [{name: S3, S: [[1, 0]]}]\n", "S must be a 2x2 matrix"),
]


@pytest.mark.parametrize("find, extra, words", BAD_FINDS, ids=[f"{b[0]}-{k}" for k, b in enumerate(BAD_FINDS)])
def test_check_reads_each_find_as_solve_does(find, extra, words):
    """Each `find`'s own options are read by its `_read_<find>`, which its solver and the validate hook (`check`)
    both run: solving's error, found without the model (each of these passed check and failed solve)."""
    assert words in error_found_without_solving(TWO_R + f"    find: [{find}]\n" + extra)


def test_check_of_coordinates_registers_no_name():
    """The validate hook reads new_coordinates: without registering them (solving does: expected: may use them)."""
    from solver.dynamics.properties import validate_dynamic_properties
    p = load_problem_text(TWO_R + "    find: [coordinates]\n    transform: [[1, 0], [1, 1]]\n")
    validate_dynamic_properties(p, p.asks[0].options, p.asks[0].ctx)
    assert "th1" not in p.names and "dth2" not in p.names
    solve_problem(p)
    assert p.names["th1"] == sp.Symbol("th1", real=True) and "dth2" in p.names


def test_forward_dynamics_of_a_spatial_3r_at_a_state_and_in_q():
    """B(q) q̈ = u − c − g on the spatial 3R: at the state of R3 (angles off the π grid, evaluated: the exact products
    of sin(1/10) ran for minutes in Gaussian elimination) and, without a state, as a function of q and q̇ (B⁻¹ by
    adjugate and determinant)."""
    text = R3.replace("[eigenvalues, alpha, factorizations, momentum, power]", "[forward_dynamics]")
    p, r = results(text)
    dm = derive(p.robot)
    x = dict(zip(p.robot.q + p.robot.dq, [0.1, 0.2, -0.3, 1, -0.5, 0.25]))
    B = np.array(dm.B.xreplace(p.values).xreplace(x).evalf(), float)
    n = np.array((dm.c + dm.g).xreplace(p.values).xreplace(x).evalf(), float).ravel()
    want = np.linalg.solve(B, np.array([1, -2, 3]) - n)
    got = r["ddq"].value
    assert not got.free_symbols and np.allclose(np.array(got.evalf(), float).ravel(), want, rtol=1e-9)
    md = render(p, solve_problem(p), "md")
    assert "at the given state ($q_{1} = 0.1$" in md and "\\frac{1}{10}" not in md
    p, r = results(text.replace("    state: {q1: 0.1, q2: 0.2, q3: -0.3, dq1: 1, dq2: -0.5, dq3: 0.25}\n", ""))
    ddq = r["ddq"].value
    assert ddq.free_symbols == set(p.robot.q[1:] + p.robot.dq)
    assert np.allclose(np.array(ddq.xreplace(x).evalf(), float).ravel(), want, rtol=1e-9)


def test_pd_conditions_take_each_entry_worst_cases_once(monkeypatch):
    """The diagonal entries are collected twice (alone, then with the minors) and a 1×1 block's minor is its entry:
    their worst configurations are computed once each, with the same conditions (B of an RP arm with a 1×1 and a
    2×2 block, not a library robot)."""
    import solver.dynamics.properties as P
    q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
    m, a, b, i1 = sp.symbols("m a b I1", positive=True)
    B = sp.Matrix([[i1 + m * q2 ** 2, 0, 0], [0, m + a * sp.cos(q3) ** 2, b * sp.cos(q3)], [0, b * sp.cos(q3), a]])
    calls: list = []
    real = P.worst_case
    monkeypatch.setattr(P, "worst_case", lambda e, *rest: calls.append(e) or real(e, *rest))
    conds, minors, possible, _, diag = P.pd_conditions(B, [q1, q2, q3], {q1, q3})
    assert len(calls) == len(set(calls)) == 4   # b11, b22, b33 and the 2×2 minor
    assert possible and diag == [] and len(minors) == 3 and conds   # (I1 > 0 holds: no diagonal condition)
