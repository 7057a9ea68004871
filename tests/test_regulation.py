"""The `regulation` ask: each law's closed loop checked exactly (equilibrium where the report says, V̇ ≤ 0 as claimed,
recomputed independently from the model and u) and by simulation (scipy solve_ivp: the errors decay to the
predicted equilibrium, also a different one when the gains are below the α condition) on a 2R, the RP of
2004-03-25 and a PR robot no exercise uses; the iterative scheme converges within the predicted iterations; α;
the property checks; spec errors; the reports; the encoded exam problems."""
import json
import math
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, R2_ROBOT, RP_ROBOT, error_found_without_solving
from scipy.integrate import solve_ivp

from solver.control.gravity_bound import gradient_bound
from solver.control.regulation import check_alpha, check_alpha_q, check_lyapunov, check_param_max, contraction
from solver.dynamics.model import derive
from solver.grading.grader import ItemSpec
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem

R2 = """
id: t2r
title: planar 2R in a vertical plane
symbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, g0: g0}
values: {m1: 2, m2: 1.5, d1: 0.25, d2: 0.2, l1: 0.5, I1: 0.05, I2: 0.03, g0: 9.81}
""" + R2_ROBOT + "asks:\n"

RP = RP_ROBOT.replace("title: planar RP (2004-03-25)", "title: planar RP (2004-03-25)\nvalues: {m1: 3, m2: 2, "
                      "d1: 0.3, l1: 0.6, I1: 0.08, I2: 0.05, g0: 9.81}") + "asks:\n"

PR = """
id: tpr
title: PR robot (a vertical prismatic joint carrying a revolute arm) -- used by no exercise
symbols: {m1: m1, m2: m2, d2: d2, I2: I2, g0: g0}
values: {m1: 4, m2: 1.2, d2: 0.35, I2: 0.02, g0: 9.81}
robot:
  joints: [P, R]
  gravity: [0, -g0]
  links:
    - {mass: m1, com: [0, q1]}
    - {mass: m2, com: [d2*cos(q2), q1 + d2*sin(q2)], angle: q2, inertia: I2}
asks:
"""

ROBOTS = {"2R": R2, "RP": RP, "PR": PR}
QD = {"2R": "[0.8, -0.5]", "RP": "[0.6, 0.3]", "PR": "[0.4, 1.0]"}
Q0 = {"2R": [-0.4, 0.9, 0, 0], "RP": [-0.3, 0.8, 0, 0], "PR": [-0.2, -1.2, 0, 0]}


def regulation(law: str, **opts: str) -> str:
    return f"  - kind: regulation\n    law: {law}\n" + "".join(f"    {k}: {v}\n" for k, v in opts.items())


def solved(text: str):
    p = load_problem_text(text)
    return p, all_results(solve_problem(p))


def num(x, vals):
    return float(sp.sympify(x).xreplace(vals))


def simulate(p, res, x0, T=12.0, states=(), state_rates=()):
    """Integrate B q̈ = u + τ_ext − c − g − F_v q̇ (model from derive, u the ask's result; external forces
    recomputed here) from x0 = (q, q̇[, ξ])."""
    r = p.robot
    dm = derive(r)
    vals = p.values
    n = r.n
    q, dq = list(r.q), list(r.dq)
    u = res["u"].value.xreplace(vals)
    G = dm.G if dm.G is not None else sp.eye(n)
    rhs = (G * u - dm.c - dm.g - (dm.Fv * sp.Matrix(dq) if dm.Fv is not None else sp.zeros(n, 1))).xreplace(vals)
    args = q + dq + list(states)
    fB = sp.lambdify(args, dm.B.xreplace(vals).tolist(), "numpy")
    fr = sp.lambdify(args, list(rhs), "numpy")
    fs = sp.lambdify(args, [sp.sympify(x).xreplace(vals) for x in state_rates], "numpy") if states else None

    def f(t, x):
        acc = np.linalg.solve(np.array(fB(*x), dtype=float), np.array(fr(*x), dtype=float))
        out = list(x[n:2 * n]) + list(acc)
        if fs:
            out += list(np.array(fs(*x), dtype=float))
        return out

    sol = solve_ivp(f, (0, T), x0, rtol=1e-8, atol=1e-10, method="LSODA")
    assert sol.success
    return sol


# ------------------------------------------------------------------------------------------------ exact closed loop
@pytest.mark.parametrize("robot", ["2R", "RP", "PR"])
@pytest.mark.parametrize("law", ["pd_gravity", "pd_constant", "pd", "saturated_pd"])
def test_closed_loop_exact(robot, law):
    """(q_d, 0) is an equilibrium where the law compensates gravity (φ(q_d) = 0), −∇P = φ, and V̇ recomputed from
    the model, u and V at random states equals the reported V̇ (≤ 0)."""
    p, res = solved(ROBOTS[robot] + regulation(law))
    r = p.robot
    q, dq = list(r.q), list(r.dq)
    qd = [p.names[f"qd{i + 1}"] for i in range(r.n)]
    kd = [p.names[f"kd{i + 1}"] for i in range(r.n)]
    phi = res["equilibrium_eq"].value
    at_d = dict(zip(q, qd))
    if law != "pd":
        assert all(sp.simplify(x.xreplace(at_d)) == 0 for x in phi)
    else:  # without compensation q_d is an equilibrium only where g(q_d) = 0
        assert sp.simplify(phi.xreplace(at_d) + derive(r).g.xreplace(at_d)) == sp.zeros(r.n, 1)
    P = res["P"].value
    assert all(sp.simplify(sp.diff(P, x) + ph) == 0 for x, ph in zip(q, phi))
    assert res["V_check"].value is True
    dm = derive(r)
    V = res["V"].value
    acc_force = res["u"].value - dm.c - dm.g
    rng = np.random.default_rng(1)
    syms = (V.free_symbols | acc_force.free_symbols | dm.B.free_symbols) - set(q + dq)
    for _ in range(3):
        sub = {s: sp.Float(rng.uniform(0.5, 2.0)) for s in syms}
        sub.update({x: sp.Float(rng.uniform(-2, 2)) for x in q + dq})
        acc = dm.B.xreplace(sub).LUsolve(acc_force.xreplace(sub))
        vdot = sum(sp.diff(V, x).xreplace(sub) * sub[v] for x, v in zip(q, dq)) + \
            sum(sp.diff(V, v).xreplace(sub) * a for v, a in zip(dq, acc))
        assert float(vdot) == pytest.approx(float(res["V_dot"].value.xreplace(sub)), abs=1e-9)
        damping = [sub[k] * (sp.tanh(sub[v]) if law == "saturated_pd" else sub[v]) for k, v in zip(kd, dq)]
        assert float(vdot) == pytest.approx(-float(sum(d * sub[v] for d, v in zip(damping, dq))), abs=1e-9)
        assert float(vdot) <= 1e-12


def test_cartesian_and_pid_and_elastic_closed_loops_exact():
    p, res = solved(R2 + regulation("cartesian_pd", task="[l1*cos(q1) + 0.4*cos(q1 + q2), l1*sin(q1) + 0.4*sin(q1 + q2)]"))
    r = p.robot
    J, f = res["J"].value, res["f"].value
    pd = sp.Matrix([p.names["pd1"], p.names["pd2"]])
    KP = sp.diag(p.names["kp1"], p.names["kp2"])
    assert sp.simplify(res["equilibrium_eq"].value - J.T * KP * (pd - f)) == sp.zeros(2, 1)
    assert res["V_check"].value is True
    p, res = solved(R2 + regulation("pid"))
    xi = res["controller_state"].value
    qd = sp.Matrix([p.names["qd1"], p.names["qd2"]])
    at = {**dict(zip(p.robot.q, qd)), **dict(zip(xi, res["xi_eq"].value))}
    assert all(sp.simplify(x.xreplace(at)) == 0 for x in res["equilibrium_eq"].value)
    assert res["controller_rate"].value == qd - sp.Matrix(p.robot.q)
    p, res = solved(ELASTIC + regulation("elastic", qd="[pi/4]", kp=20, kd=3))
    xd = res["equilibria"].value[0]
    assert all(abs(float(x.xreplace(dict(zip(p.robot.q, xd))).xreplace(p.values))) < 1e-6
               for x in res["equilibrium_eq"].value)
    assert res["V_check"].value is True and res["V_dot"].value == -3 * p.robot.dq[1] ** 2


# ------------------------------------------------------------------------------------------------ simulation
@pytest.mark.parametrize("robot", ["2R", "RP", "PR"])
def test_pd_gravity_converges_in_simulation(robot):
    p, res = solved(ROBOTS[robot] + regulation("pd_gravity", qd=QD[robot], kp=40, kd=12))
    sol = simulate(p, res, Q0[robot], T=15)
    qd = np.array([float(x) for x in res["equilibria"].value[0]])
    e = np.abs(sol.y[:2, -1] - qd)
    assert e.max() < 1e-3 and np.abs(sol.y[2:, -1]).max() < 1e-3
    assert np.abs(sol.y[:2, 0] - qd).max() > 0.5  # it did have to move


@pytest.mark.parametrize("robot", ["2R", "RP", "PR"])
def test_saturated_and_cartesian_converge_in_simulation(robot):
    p, res = solved(ROBOTS[robot] + regulation("saturated_pd", qd=QD[robot], kp=15, kd=8))
    sol = simulate(p, res, Q0[robot], T=25)
    assert np.abs(sol.y[:2, -1] - np.array(json.loads(QD[robot]))).max() < 1e-3
    assert float(res["u_bound"].value[0]) == 23


def test_cartesian_pd_reaches_the_desired_position():
    task = "[l1*cos(q1) + 0.4*cos(q1 + q2), l1*sin(q1) + 0.4*sin(q1 + q2)]"
    p, res = solved(R2 + regulation("cartesian_pd", task=task, pd="[0.3, 0.5]", kp=60, kd=4))
    sol = simulate(p, res, [0.2, 1.2, 0, 0], T=15)
    f = sp.lambdify(p.robot.q, list(res["f"].value.xreplace(p.values)))
    assert np.allclose(f(*sol.y[:2, -1]), [0.3, 0.5], atol=1e-4)
    # its equilibria: two inverse kinematic solutions and the singular stuck ones (q2 = 0 or pi)
    eqs = res["equilibria"].value
    assert res["n_equilibria"].value == len(eqs) >= 4
    assert any(abs(float(c[1])) < 1e-6 for c in eqs) and any(abs(abs(float(c[1])) - np.pi) < 1e-6 for c in eqs)


@pytest.mark.parametrize("robot", ["2R", "RP", "PR"])
def test_pd_constant_above_alpha_converges_to_qd(robot):
    extra = {"ranges": "{q2: [-1, 1]}"} if robot == "RP" else {}   # α needs the range of the prismatic joint
    p, res = solved(ROBOTS[robot] + regulation("pd_constant", qd=QD[robot], kp=80, kd=15, **extra))
    assert res["condition"].value is True
    alpha = float(res["alpha"].value.xreplace(p.values))
    assert alpha < 80
    assert len(res["equilibria"].value) == 1
    sol = simulate(p, res, Q0[robot], T=15)
    assert np.abs(sol.y[:2, -1] - np.array(json.loads(QD[robot]))).max() < 1e-3


def test_pd_constant_below_alpha_another_equilibrium():
    """A pendulum (m d g0 = 98.1) with k_P = 20 < α: besides q_d, stable equilibria far from it, and a simulation
    started in their basin ends there, as predicted by the `equilibria` result."""
    p, res = solved(PENDULUM + regulation("pd_constant", qd="[pi/2]", kp=20, kd=30))
    assert res["condition"].value is False
    eqs = [float(c[0]) for c in res["equilibria"].value]
    assert len(eqs) > 1 and any(abs(x - np.pi / 2) < 1e-6 for x in eqs)
    step = next(s for s in solve_problem(p)[0].steps if s.name == "equilibria")
    stable = [x for x, s in zip(eqs, step.data["stable"]) if s and abs(x - np.pi / 2) > 0.1]
    assert stable
    target = stable[0]
    sol = simulate(p, res, [target + 0.3, 0], T=30)
    assert sol.y[0, -1] == pytest.approx(target, abs=1e-4)
    # and from close to q_d it stays at q_d
    sol = simulate(p, res, [np.pi / 2 + 0.05, 0], T=30)
    assert sol.y[0, -1] == pytest.approx(np.pi / 2, abs=1e-4)


def test_pd_without_compensation_predicted_offset():
    p, res = solved(R2 + regulation("pd", qd="[0.8, -0.5]", kp=[200, 120], kd=10))
    assert res["condition"].value is True
    (qbar,) = res["equilibria"].value
    assert abs(float(qbar[0]) - 0.8) > 1e-3  # the gravity offset
    sol = simulate(p, res, [0.0, 0.0, 0, 0], T=15)
    assert np.allclose(sol.y[:2, -1], [float(x) for x in qbar], atol=1e-5)


def test_pid_converges_locally():
    p, res = solved(R2 + regulation("pid", qd="[0.8, -0.5]", kp=60, kd=15, ki=20))
    assert res["locally_stable"].value is True
    xi = list(res["controller_state"].value)
    sol = simulate(p, res, [0.6, -0.3, 0, 0, 0, 0], T=40, states=xi, state_rates=list(res["controller_rate"].value))
    assert np.allclose(sol.y[:2, -1], [0.8, -0.5], atol=1e-4)
    xi_eq = [float(x.xreplace(p.values)) for x in res["xi_eq"].value]
    assert np.allclose(sol.y[4:, -1], xi_eq, rtol=1e-3)


def test_pid_routh_single_joint():
    p, res = solved(PENDULUM + regulation("pid", qd="[pi/3]"))
    b, kd, kp, ki = (p.names[n] for n in ("I0", "kd1", "kp1", "ki1"))
    routh = res["routh"].value
    assert len(routh) == 4 and routh[0] == kd and routh[2] == ki
    # the last condition is k_D (k_P + a) - b k_I with a = m d g0 cos(q_d), b = I0 + m d^2
    m, d, g0 = (p.names[n] for n in ("m", "d", "g0"))
    want = kd * (kp + m * d * g0 * sp.cos(sp.pi / 3)) - (b + m * d ** 2) * ki
    assert sp.simplify(routh[3] - want) == 0


def test_elastic_energy_shaping_converges():
    p, res = solved(ELASTIC + regulation("elastic", qd="[pi/4]", kp=60, kd=5))
    assert res["condition"].value is True
    thd = float(res["thetad"].value[0].xreplace(p.values))
    K, m, d, g0 = (float(p.values[p.names[n]]) for n in ("K", "m", "d", "g0"))
    assert thd == pytest.approx(np.pi / 4 + m * d * g0 * np.cos(np.pi / 4) / K)
    sol = simulate(p, res, [0.0, 0.0, 0, 0], T=30)
    assert np.allclose(sol.y[:2, -1], [np.pi / 4, thd], atol=1e-4)


def test_external_force_mismatch_moves_the_equilibrium():
    """2012-06-11: with the force doubled and the law unchanged, the robot leaves q_d (B q̈ = J^T F ≠ 0) and
    settles where K_P (q_d − q) + J^T(q) F = 0, joint 3 back at q_d3 (a numeric check on the 3R)."""
    p = load_problem(PROBLEMS / "2012-06-11-ex2.yaml")
    res = all_results(solve_problem(p))
    eq = res["equilibrium_eq_2"].value
    vals = {p.names["m1"]: 2, p.names["m2"]: 1.5, p.names["m3"]: 1, p.names["g0"]: 9.81, p.names["Fcy"]: 15,
            **{p.names[f"kp{i}"]: 50 for i in (1, 2, 3)}, **{p.names[f"kd{i}"]: 10 for i in (1, 2, 3)},
            p.names["qd1"]: 0.7, p.names["qd2"]: -0.4, p.names["qd3"]: 0.9}
    p.values.update(vals)
    u = res["u_2"].value
    F = sp.Matrix([0, 2 * p.names["Fcy"]])
    pc = res["pF1_2"].value
    tau_ext = pc.jacobian(p.robot.q).T * F
    res2 = {"u": type(res["u_2"])("u", u + tau_ext, "vector")}
    sol = simulate(p, res2, [0.7, -0.4, 0.9, 0, 0, 0], T=80)
    qf = sol.y[:3, -1]
    assert np.abs(qf[:2] - [0.7, -0.4]).max() > 1e-2 and qf[2] == pytest.approx(0.9, abs=1e-5)
    resid = [float(x.xreplace(vals).xreplace(dict(zip(p.robot.q, qf)))) for x in eq]
    assert np.abs(resid).max() < 1e-5


# ------------------------------------------------------------------------------------------------ iterative scheme
PENDULUM = """
id: pend
title: pendulum (2018-02-05)
symbols: {m: m, d: d, I0: I0, g0: g0}
values: {m: 10, d: 1, I0: 10/3, g0: 9.81}
robot:
  joints: [R]
  gravity: [g0, 0]
  links:
    - {mass: m, com: [d*cos(q1), d*sin(q1)], angle: q1, inertia: I0}
asks:
"""

ELASTIC = """
id: el
title: one link with an elastic joint
symbols: {m: m, d: d, I: I, Bm: Bm, K: K, g0: g0}
values: {m: 2, d: 0.5, I: 0.1, Bm: 0.2, K: 50, g0: 9.81}
robot:
  coordinates: [q1, theta1]
  joints: [R, R]
  gravity: [0, -g0]
  links:
    - {mass: m, com: [d*cos(q1), d*sin(q1)], angle: q1, inertia: I}
  extra:
    kinetic: ["1/2*Bm*dtheta1^2"]
    potential: ["1/2*K*(q1 - theta1)^2"]
  input_map: [[0], [1]]
asks:
"""


def test_iterative_scheme_2018_02_05_numbers():
    """β = 1/5: contraction 1/4, bounds π/3·4^-i, i_min = 4 (printed); the iterates of the printed table."""
    _, res = solved(PENDULUM + regulation("iterative", qd="[pi/3]", kp=500, kd=45, q0="[0]", epsilon=0.01,
                                          beta="1/5"))
    assert res["rho"].value == sp.Rational(1, 4)
    assert res["iterations"].value == 4
    assert res["error_bounds"].value == [sp.pi / 3 * sp.Rational(1, 4) ** i for i in range(5)]
    q = [float(x[0]) for x in res["iterates"].value]
    u = [float(x[0]) for x in res["feedforward"].value]
    assert q[:4] == pytest.approx([0.8942, 1.0318, 1.0458, 1.0471], abs=1e-4)
    assert u[:4] == pytest.approx([76.4904, 84.1916, 84.888, 84.9510], abs=2e-3)
    assert res["iterations_actual"].value == 3


def test_iterative_scheme_with_symbolic_beta_and_epsilon():
    """β and ε may be parameters without values: ρ = β/(1 − β), ê₁ = ρ‖e₀‖ symbolic, and the first iteration
    with ‖e_i‖ < ε is given by i > 1 + ln(ε/ê₁)/ln ρ (checked at β = 1/5, ε = 0.01: i_min = 4, the printed
    value)."""
    text = PENDULUM.replace("g0: g0}", "g0: g0, b: contraction parameter, eps: accuracy}") + \
        regulation("iterative", qd="[pi/3]", kp=500, kd=45, q0="[0]", epsilon="eps", beta="b")
    p = load_problem_text(text)
    sols = solve_problem(p)
    res = all_results(sols)
    b, eps = p.names["b"], p.names["eps"]
    assert res["beta"].value == b and sp.simplify(res["rho"].value - b / (1 - b)) == 0
    step = next(st for st in sols[0].steps if st.name == "iterative")
    bound = step.data["i_formula"].xreplace({b: sp.Rational(1, 5), eps: sp.Rational(1, 100)})
    assert math.floor(float(bound)) + 1 == 4
    md = render(p, sols, "md")
    assert "is guaranteed from the first iteration $i >" in md and "iterations" not in res


@pytest.mark.parametrize("kp, eps", [(150, "eps"), (60, "eps"), (60, "0.01")])
def test_iterative_scheme_without_contraction(kp, eps):
    """β = α/K_P,m ≥ ½ on the 2018-02-05 pendulum (α = m g0 d = 98.1): K_P = 150 gives ρ = α/(K_P − α) ≈ 1.89,
    K_P = 60 < α gives ρ ≈ −2.57 (β > 1). No iteration count is given, not even as a formula (symbolic ε), and no
    negative "bound" on a norm: the report says the gains do not contract."""
    text = PENDULUM.replace("g0: g0}", "g0: g0, eps: accuracy}") + \
        regulation("iterative", qd="[pi/3]", kp=kp, kd=45, q0="[0]", epsilon=eps)
    p = load_problem_text(text)
    sols = solve_problem(p)
    step = next(st for st in sols[0].steps if st.name == "iterative")
    assert not 0 <= float(step.data["rho"].xreplace(p.values)) < 1
    assert step.data.get("no_contraction") and "i_formula" not in step.data and "imin" not in step.data
    assert "do not guarantee a contraction" in render(p, sols, "md")


@pytest.mark.parametrize("beta, words", [("1/2 + m", "beta must be in (0, 1/2), got m + 1/2"),
                                         ("-d", "beta must be in (0, 1/2), got -d"),
                                         ("q1/10", "beta must be in (0, 1/2)")])
def test_symbolic_beta_known_out_of_range_is_an_error(beta, words):
    text = PENDULUM.replace("values: {m: 10, d: 1, I0: 10/3, g0: 9.81}", "values: {I0: 10/3, g0: 9.81}") + \
        regulation("iterative", qd="[pi/3]", kp=500, kd=45, beta=beta)
    assert words in error_found_without_solving(text)


def test_iterative_scheme_simulated_within_the_predicted_iterations():
    """The outer loop with real transients (solve_ivp until rest): each error below its bound, below ε from the
    predicted i_min on (default β = α/K_P,m)."""
    p, res = solved(R2 + regulation("iterative", qd="[1.0, -0.6]", kp=[60, 40], kd=[12, 8], q0="[0, 0]",
                                    epsilon=0.001))
    alpha = float(res["alpha"].value.xreplace(p.values))
    assert 40 > 2 * alpha
    imin, bounds = int(res["iterations"].value), [float(b.xreplace(p.values)) for b in res["error_bounds"].value]
    uh = list(res["u"].value.free_symbols & {p.names["uhat1"], p.names["uhat2"]})
    uh.sort(key=lambda s: s.name)
    g = derive(p.robot).g.xreplace(p.values)
    ff = [float(x) for x in g.xreplace(dict(zip(p.robot.q, [0, 0])))]
    x = [0.0, 0.0, 0, 0]
    qd = np.array([1.0, -0.6])
    for i in range(1, imin + 1):
        sub = dict(zip(uh, ff))
        r = {"u": type(res["u"])("u", res["u"].value.xreplace(sub), "vector")}
        sol = simulate(p, r, x, T=25)
        x = list(sol.y[:2, -1]) + [0, 0]
        e = qd - np.array(x[:2])
        assert np.linalg.norm(e) <= bounds[i] + 1e-6
        ff = [a + k * b for a, k, b in zip(ff, [60, 40], e)]
    assert np.linalg.norm(e) < 0.001


def test_contraction_formula():
    beta, rho = contraction(sp.Integer(98), sp.Integer(500))
    assert beta == sp.Rational(98, 500) and rho == sp.Rational(98, 402)


# ------------------------------------------------------------------------------------------------ alpha
def test_alpha_exact_numeric_and_termwise():
    q1, q2 = sp.symbols("q1 q2", real=True)
    M, g0 = sp.symbols("M g0", positive=True)
    g = M * g0 * sp.Matrix([sp.cos(q1) + sp.cos(q1 + q2), sp.cos(q1 + q2)])
    b = gradient_bound(g, [q1, q2], {q1, q2})
    assert b.method == "exact" and sp.simplify(b.alpha - (3 + sp.sqrt(5)) / 2 * M * g0) == 0
    assert sp.simplify(b.frobenius - sp.sqrt(7) * M * g0) == 0
    A = sp.lambdify([q1, q2], b.A.xreplace({M: 1, g0: 1}).tolist())
    rng = np.random.default_rng(0)
    norms = [np.linalg.norm(np.array(A(*x)), 2) for x in rng.uniform(-np.pi, np.pi, (500, 2))]
    assert max(norms) <= float((3 + sp.sqrt(5)) / 2) + 1e-12
    assert np.linalg.norm(np.array(A(*[float(v) for v in b.q_max])), 2) == pytest.approx(float((3 + sp.sqrt(5)) / 2))
    # a prismatic coordinate with its range, symbolic parameters: the termwise bound is above the true maximum
    m1, m2, d, L = sp.symbols("m1 m2 d L", positive=True)
    g = sp.Matrix([(m1 * d + m2 * q2) * g0 * sp.sin(q1), -m2 * g0 * sp.cos(q1)])
    b = gradient_bound(g, [q1, q2], {q1}, {q2: (d, L)})
    assert b.method == "termwise"
    vals = {m1: 2, m2: 3, d: sp.Rational(1, 5), L: sp.Rational(13, 10), g0: sp.Rational(981, 100)}
    bn = gradient_bound(g, [q1, q2], {q1}, {q2: (d, L)}, vals)
    assert bn.method in ("exact", "numeric")
    assert float(b.alpha.xreplace(vals)) >= float(bn.alpha_max) - 1e-9
    with pytest.raises(UserError, match="range of the prismatic coordinate q2"):
        solved(RP + regulation("pd_constant", alpha="true"))



R3_POTENTIAL = """
id: t3
title: three joints with the gravity of a planar 3R (U given), numeric values -- used by no exercise
symbols: {g0: g0}
values: {g0: 10}
robot:
  joints: [R, R, R]
  model:
    B: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    U: g0*(6*sin(q1) + 3*sin(q1 + q2) + sin(q1 + q2 + q3))
asks:
  - kind: regulation
    law: pd_constant
    kp: 500
    kd: 20
    suffix: _c
  - kind: regulation
    law: pd
    kp: [100, 150, 200]
    kd: 20
    suffix: _p
  - kind: dynamic_properties
    find: [alpha]
"""


def test_alpha_of_a_cubic_with_three_real_roots():
    """At the maximizing q = (π/2, 0, 0), ∂g/∂q = −g0 [[10, 4, 1], [4, 4, 1], [1, 1, 1]]: its characteristic cubic has
    three real roots, whose radicals need I (casus irreducibilis). α was 1 500 characters with I that no float()
    accepts, so condition_c / condition_p were missing; now α is the root's value (a float), the same as numpy's
    eigenvalue there and the maximum of ‖∂g/∂q‖ over a grid, and the conditions are given."""
    p, res = solved(R3_POTENTIAL)
    want = float(np.abs(np.linalg.eigvalsh(np.array([[10, 4, 1], [4, 4, 1], [1, 1, 1.0]]))).max())
    for name in ("alpha_c", "alpha_max_c", "kp_threshold_c", "alpha_p", "alpha"):
        a = res[name].value
        assert not a.has(sp.I) and len(str(a)) < 40
        assert float(a.xreplace(p.values)) == pytest.approx(10 * want, rel=1e-13)
    assert [float(x) for x in res["alpha_q_c"].value] == pytest.approx([np.pi / 2, 0, 0])
    assert res["condition_c"].value is True          # K_P = 500 > α ≈ 121.6
    assert res["condition_p"].value is False         # K_P,m = 100 < α
    # independently: ‖∂²U/∂q²‖ (second differences of U) is at most α everywhere on a grid and reaches it
    U = lambda x: 10 * (6 * np.sin(x[0]) + 3 * np.sin(x[0] + x[1]) + np.sin(x.sum()))  # noqa: E731
    E, h = np.eye(3), 1e-4

    def hess_norm(x):
        Hm = np.array([[(U(x + h * E[i] + h * E[j]) - U(x + h * E[i] - h * E[j]) - U(x - h * E[i] + h * E[j])
                         + U(x - h * E[i] - h * E[j])) / (4 * h * h) for j in range(3)] for i in range(3)])
        return np.linalg.norm(Hm, 2)

    grid = np.linspace(-np.pi, np.pi, 13)
    norms = [hess_norm(np.array([a, b, c])) for a in grid for b in grid for c in grid]
    assert max(norms) <= 10 * want * (1 + 1e-6) and max(norms) == pytest.approx(10 * want, rel=1e-6)

# ------------------------------------------------------------------------------------------------ grading
def _opts():
    return ItemSpec()


def test_property_checks_accept_alternatives_and_reject_wrong_answers():
    p = load_problem(PROBLEMS / "2011-09-12-ex1.yaml")
    res = all_results(solve_problem(p))
    M, g0 = p.names["M"], p.names["g0"]
    ok = check_alpha(p, res, "alpha", sp.sqrt(7) * g0 * M, None, _opts())        # the trace bound: valid
    assert ok.correct and any("conservative" in f for f in ok.feedback)
    assert check_alpha(p, res, "alpha", (3 + sp.sqrt(5)) / 2 * g0 * M, None, _opts()).correct
    assert not check_alpha(p, res, "alpha", 2 * g0 * M, None, _opts()).correct  # below the maximum
    assert check_alpha_q(p, res, "alpha_q", [-sp.pi / 2, 0], None, _opts()).correct   # another maximizer
    assert not check_alpha_q(p, res, "alpha_q", [0, 0], None, _opts()).correct
    assert check_param_max(p, res, "param_max", sp.Float(0.6267), None, _opts()).correct  # conservative
    assert not check_param_max(p, res, "param_max", sp.Integer(4), None, _opts()).correct


def test_lyapunov_property_check():
    p, res = solved(R2 + regulation("pd_gravity", qd="[0.8, -0.5]", kp=40, kd=12))
    V = res["V"].value
    q, dq = p.robot.q, p.robot.dq
    dm = derive(p.robot)
    T = (sp.Matrix(dq).T * dm.B * sp.Matrix(dq))[0] / 2
    e = sp.Matrix([0.8 - q[0], -0.5 - q[1]])
    assert check_lyapunov(p, res, "V", V + 7, None, _opts()).correct          # up to a constant
    alt = 3 * T + 3 * 20 * (e.T * e)[0] + sp.Rational(1, 2)                   # 3 V + const: also valid
    assert check_lyapunov(p, res, "V", alt, None, _opts()).correct
    bad1 = T + (e.T * e)[0] / 2                                               # K_P replaced by I
    v1 = check_lyapunov(p, res, "V", bad1, None, _opts())
    assert not v1.correct and "V̇" in v1.feedback[0]
    assert not check_lyapunov(p, res, "V", 20 * (e.T * e)[0], None, _opts()).correct  # no kinetic energy


# ------------------------------------------------------------------------------------------------ spec errors
@pytest.mark.parametrize("opts, words", [
    ({"kp": "[10, -5]"}, "negative"),
    ({"kd": "-3"}, "negative"),
    ({"kp": 0}, "zero"),
    ({"qd": "[0.1, 0.2, 0.3]"}, "list of 2"),
    ({"ki": 3}, "option of law: pid"),
])
def test_bad_input_is_one_user_error_at_its_line(opts, words):
    text = PR + regulation("pd_gravity", **opts)
    with pytest.raises(UserError) as exc:
        solved(text)
    msg = str(exc.value)
    want_line = text.splitlines().index(next(x for x in text.splitlines() if x.strip().startswith(list(opts)[0] + ":"))) + 1
    assert f":{want_line}:" in msg and words in msg


# ------------------------------------------------------------------------------------------------ reports
def test_reports_render_and_compile(tmp_path):
    p = load_problem_text(PENDULUM + regulation("iterative", qd="[pi/3]", kp=500, kd=45, q0="[0]", epsilon=0.01)
                          + regulation("pid", qd="[pi/3]", kp=500, kd=45, ki=100, suffix="_pid")
                          + regulation("pd_constant", qd="[pi/2]", kp=20, kd=30, suffix="_c"))
    sols = solve_problem(p)
    md = render(p, sols, "md")
    for words in ("Convergence of the iterations", "i_{\\min} = 4", "Routh", "Lyapunov function", "LaSalle",
                  "unstable: not a minimum of", "Bound on the gravity gradient"):
        assert words in md
    tex = render(p, sols, "tex")
    assert "\\paragraph{LaSalle.}" in tex and "tabular" in tex
    if shutil.which("latexmk"):
        (tmp_path / "r.tex").write_text(tex)
        out = subprocess.run(["latexmk", "-pdf", "-interaction=nonstopmode", "-halt-on-error", "r.tex"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=240)
        assert out.returncode == 0, out.stdout[-2000:]



def test_pid_report_breaks_the_gravity_jacobian(tmp_path):
    """With symbolic parameters A(q_d) = ∂g/∂q at q_d was an inline matrix 132 pt wider than the page; now A(q_d) and
    B(q_d) are displayed and a wide one is written entry by entry (symmetric: the upper triangle), like other long
    matrices."""
    p = load_problem_text(R2.replace("values: {m1: 2, m2: 1.5, d1: 0.25, d2: 0.2, l1: 0.5, I1: 0.05, I2: 0.03, "
                                     "g0: 9.81}\n", "") + regulation("pid"))
    sols = solve_problem(p)
    tex = render(p, sols, "tex")
    part = tex[tex.index("\\paragraph{Local analysis.}"):tex.index("differentiating once:")]
    assert "$A(q_d)" not in part and "\\[A(q_d) = \\partial g/\\partial q\\big|_{q_d} = \\begin{bmatrix} a_{ij}" in part
    assert "\\[a_{11} = - d_{2} g_{0} m_{2} \\sin{\\left(q_{d,1} + q_{d,2} \\right)} - g_{0} \\left(d_{1} m_{1} + l_{1} " \
        "m_{2}\\right) \\sin {q_{d,1}}\\]" in part and "a_{21}" not in part and "\\[b_{22} = I_{2} + d_{2}^{2} m_{2},\\]" in part
    md = render(p, sols, "md")
    assert "$$A(q_d) = \\partial g/\\partial q\\big|_{q_d} = \\begin{bmatrix}" in md
    if shutil.which("latexmk"):
        (tmp_path / "r.tex").write_text(tex)
        out = subprocess.run(["latexmk", "-pdf", "-interaction=nonstopmode", "-halt-on-error", "r.tex"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=240)
        assert out.returncode == 0, out.stdout[-2000:]
        assert "Overfull \\hbox" not in (tmp_path / "r.log").read_text(errors="replace")


# ------------------------------------------------------------------------------------------------ library
@pytest.mark.parametrize("name", ["2011-09-12-ex1", "2012-06-11-ex2", "2012-07-05-ex1", "2017-06-06-ex2",
                                  "2020-06-05-remote-ex3", "2022-02-03-ex1"])
def test_library_problem_verifies(name):
    rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
    assert rep.ok, [c for c in rep.checks if not c.verdict.ok]


@pytest.mark.parametrize("opts, words", [
    ({"ki": 3}, "ki: is an option of law: pid"),
    ({"ranges": "{q5: [0, 1]}"}, "'q5' in ranges: is not a coordinate"),
    ({"ranges": "{q2: [1, 0]}"}, "empty range for q2"),
    ({"assume": "{m7: 1}"}, "'m7' in assume: is not a parameter"),
    ({"limits": "{u_max: 1}"}, "limits: are checked at a state"),
    ({"external": "[{point: [0, q1], force: [1, 2, 3]}]"}, "external force 1: force has 3 components, point has 2"),
    ({"external": "[{point: [0, q1], force: [0, 1], compensated: [1]}]"},
     "external force 1: compensated has 1 components, point has 2"),
    ({"external": "[{point: [0, q1], force: [0, q2]}]"}, "external force 1: force must be constant"),
    ({"at": "{q7: 1}"}, "'q7' in at: is not a coordinate or velocity"),
    ({"at": "{q1: 0}", "limits": "{u_max: -1}"}, "limits.u_max must be a positive number"),
    ({"at": "{q1: 0}", "limits": "{u_max: 1, map: [[1, 0, 0]]}"}, "limits.map must be a matrix with 2 columns"),
])
def test_check_finds_bad_options_without_solving(opts, words):
    """The options every law shares are read by the kind's validate hook (`check`) as by solving, without the
    model."""
    assert words in error_found_without_solving(PR + regulation("pd_gravity", **opts))


LAW_BAD = [   # (law, the ask's options, words of the error): each passed check and failed only when solving
    ("pd_gravity", {"qd": "[1, 2, 3]"}, "qd must be a list of 2 expressions (one per coordinate), got 3 entries"),
    ("pd", {"qd": "[q2, 0]"}, "qd must be constant, free of the coordinates and velocities (it has q2)"),
    ("pd_constant", {"kp": "[1, 2, 3]"}, "kp must be one expression or a list of 2"),
    ("saturated_pd", {"kd": "[[1, 2]]"}, "kd must be one expression or a list of 2"),
    ("pid", {"ki": "[1, 2, 3]"}, "ki must be one expression or a list of 2"),
    ("pid", {"kp": "-g0"}, "kp: gain -g0 is negative"),
    ("cartesian_pd", {"task": "[q1, q2]", "pd": "[1, 2, 3]"}, "pd must be a list of 2 expressions (one per task"),
    ("cartesian_pd", {"task": "[q1, q2]", "pd": "[q1, 0]"}, "pd must be constant, free of the coordinates"),
    ("cartesian_pd", {"task": "[q1, q2, q1 + q2]", "kp": "[1, 2]"}, "kp must be one expression or a list of 3"),
    ("cartesian_pd", {"task": "[q1, q2]", "kd": "[1, 2, 3]"}, "kd must be one expression or a list of 2"),
    ("cartesian_pd", {"task": "[]"}, "task must list the task function's components"),    # was a TypeError
    ("cartesian_pd", {"task": "q1 + dq1"}, "task must be a function of the coordinates only (it has dq1)"),
    ("iterative", {"beta": "0.7"}, "beta must be in (0, 1/2), got 7/10"),
    ("iterative", {"beta": "-m1"}, "beta must be in (0, 1/2), got -m1"),
    ("iterative", {"q0": "[1, 2, 3]"}, "q0 must be a list of 2 expressions (one per coordinate), got 3 entries"),
    ("iterative", {"q0": "[0, dq1]"}, "q0 must be constant, free of the coordinates and velocities (it has dq1)"),
    ("iterative", {"u0": "[1]"}, "u0 must be a list of 2 expressions (feedforward), got 1 entry"),  # solved, unread
    ("iterative", {"epsilon": "-1"}, "epsilon must be a positive number, got -1"),    # solved without q0
    ("iterative", {"q0": "[0, 0]", "epsilon": "0"}, "epsilon must be a positive number, got 0"),
]


@pytest.mark.parametrize("law, opts, words", LAW_BAD, ids=[f"{k}-{b[0]}" for k, b in enumerate(LAW_BAD)])
def test_check_reads_each_laws_options_as_solve_does(law, opts, words):
    """q_d, the gains (n each; cartesian_pd: K_P one per task component), cartesian_pd's task and p_d, iterative's
    beta, q0, u0 and epsilon are read by the reader solve runs first, which `check` runs too: one error at the
    option's line, the same for both."""
    assert words in error_found_without_solving(PR + regulation(law, **opts))


ELASTIC_BAD = [   # (the robot's text replaced, by, the ask's options besides qd: [0.5], words of the error)
    ("", "", {"qd": "[1, 2]"}, "qd must be a list of 1 expressions (one per non-actuated coordinate), got 2 entries"),
    ("", "", {"kp": "[1, 2]"}, "kp must be one expression or a list of 1"),
    ("", "", {"kp": 2, "kd": "[1, 2]"}, "kd must be one expression or a list of 1"),
    ("", "", {"kp": "-K"}, "kp: gain -K is negative"),
    ("", "", {"at": "{q1: 0, theta1: 0}", "limits": "{u_max: 1, map: [[1, 0]]}"},
     "limits.map must be a matrix with 1 columns"),
    ("input_map: [[0], [1]]", "input_map: [[0], [2]]", {}, "needs an input map that selects the actuated coordinates"),
    ("input_map: [[0], [1]]", "input_map: [[1, 0], [0, 1]]", {}, "every coordinate is actuated"),
    ("  input_map: [[0], [1]]\n", "", {}, "every coordinate is actuated"),
    ("1/2*K*(q1 - theta1)^2", "1/4*K*(q1 - theta1)^4", {}, "law: elastic needs linear springs"),
]


@pytest.mark.parametrize("old, new, opts, words", ELASTIC_BAD,
                         ids=[f"{k}-{b[3][:20]}" for k, b in enumerate(ELASTIC_BAD)])
def test_check_reads_the_elastic_law_as_solve_does(old, new, opts, words):
    """law: elastic: the input map that selects the motor coordinates, the linear springs, q_d (one per link), the
    gains and limits.map (one column per motor) are read by the reader solve runs first, which the validate hook
    (`check`) runs too, without the model: solving's error (each of these passed check and failed solve)."""
    text = ELASTIC.replace(old, new) if old else ELASTIC
    assert words in error_found_without_solving(text + regulation("elastic", **{"qd": "[0.5]", **opts}))
