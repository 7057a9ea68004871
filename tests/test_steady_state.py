"""Steady states under a constant input (the `equilibria` ask with `input:`, `steady: velocity`, `velocity:`,
`solve_for:`, `deformations:`): the three masses of 2016-10-28-ex2 against the printed values, chains of 2 and 4
masses with different frictions (no exercise uses them) against the closed form and by simulation (solve_ivp from
rest: the velocities converge to v̄ and the deformations to the computed ones), a bead on a spinning rod (a steady
rotation with the centrifugal force on a spring), a pendulum whose gravity torque changes along the motion (no steady
velocity, said in the report), equilibria under a constant or unknown input, spec errors."""
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, error_found_without_solving
from scipy.integrate import solve_ivp

from solver.dynamics.model import derive
from solver.grading.grader import ItemSpec, grade, prepare
from solver.grading.submission import Submission
from solver.math.equivalence import CORRECT, INCORRECT
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError


def run(text):
    p = load_problem_text(text)
    sols = solve_problem(p)
    return p, sols, all_results(sols)


def S(name):
    return sp.Symbol(name, positive=True)


def plain(e):
    """The expression with every symbol replaced by the plain one of its name (assumptions aside)."""
    e = sp.sympify(e)
    return e.xreplace({x: sp.Symbol(x.name) for x in e.free_symbols})


def same(a, b) -> bool:
    return sp.simplify(plain(a) - plain(b)) == 0


def chain(n: int, forces: dict[int, str], ask: str, values: dict | None = None) -> str:
    """n masses on a line (q_i), springs k_i between i and i+1, viscous friction d_i on each, forces f on masses."""
    syms = {f"m{i}": f"m{i}" for i in range(1, n + 1)} | {f"d{i}": f"d{i}" for i in range(1, n + 1)}
    syms |= {f"k{i}": f"k{i}" for i in range(1, n)} | {"ubar": "ubar", "wbar": "wbar"}
    links = "\n".join(f"    - {{mass: m{i}, com: [q{i}, 0]}}" for i in range(1, n + 1))
    pot = ", ".join(f'"1/2*k{i}*(q{i} - q{i + 1})^2"' for i in range(1, n))
    cols = sorted(forces)
    G = "[" + ", ".join("[" + ", ".join("1" if i == c else "0" for c in cols) + "]" for i in range(1, n + 1)) + "]"
    vals = f"values: {values}\n" if values else ""
    return f"""
id: chain{n}
title: {n} masses in a chain
symbols: {{{", ".join(f"{k}: {v}" for k, v in syms.items())}}}
{vals}robot:
  joints: [{", ".join(["P"] * n)}]
  links:
{links}
  extra:
    potential: [{pot}]
  friction:
    viscous: [{", ".join(f"d{i}" for i in range(1, n + 1))}]
  input_map: {G}
  inputs: [{", ".join(f"f{c}" for c in cols)}]
asks:
{ask}"""


def chain_closed_form(n: int, forces: dict[int, sp.Expr]) -> tuple[sp.Expr, list[sp.Expr]]:
    """v̄ = Σ f_i / Σ d_i (the equations summed) and δ_j = q_j − q_{j+1} = Σ_{i≤j} (f_i − d_i v̄) / k_j (the balance of
    masses 1..j)."""
    d = [S(f"d{i}") for i in range(1, n + 1)]
    f = [forces.get(i, 0) for i in range(1, n + 1)]
    v = sum(f) / sum(d)
    return v, [sum(f[i] - d[i] * v for i in range(j)) / S(f"k{j}") for j in range(1, n)]


STEADY = """  - kind: equilibria
    steady: velocity
    input: {{{inputs}}}
    deformations: [{defs}]
"""


def steady_ask(n: int, inputs: str) -> str:
    return STEADY.format(inputs=inputs, defs=", ".join(f"q{i} - q{i + 1}" for i in range(1, n)))


# --- the exercise ---------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def three_masses():
    p = load_problem(PROBLEMS / "2016-10-28-ex2.yaml")
    sols = solve_problem(p)
    return p, sols, all_results(sols)


def test_three_masses_printed_speed_and_deformations(three_masses):
    """Line 2857: q̇1 = q̇2 = q̇3 = ū/(3d); line 2859: δ12 = 2ū/(3k1), δ23 = ū/(3k2)."""
    _, _, res = three_masses
    ubar, d, k1, k2 = S("ubar"), S("d"), S("k1"), S("k2")
    (v,) = res["steady_velocity"].value
    assert all(same(x, ubar / (3 * d)) for x in v)
    (delta,) = res["deformations"].value
    assert same(delta[0], 2 * ubar / (3 * k1)) and same(delta[1], ubar / (3 * k2))
    assert res["n_steady"].value == 1
    (qs,) = res["steady_state"].value
    q3 = sp.Symbol("q3", real=True)
    assert plain(qs[2]) == plain(q3) and same(qs[0] - qs[1], 2 * ubar / (3 * k1))   # one position arbitrary: along the motion


def test_three_masses_motion_satisfies_the_model(three_masses):
    """Along q = q̄ + v̄ t (q̈ = 0) the model's left-hand side equals G ū at every t."""
    p, _, res = three_masses
    robot = p.robot
    dm = derive(robot)
    (qs,), (v,) = res["steady_state"].value, res["steady_velocity"].value
    t = sp.Symbol("t")
    on = {x: qs[i] + v[i] * t for i, x in enumerate(robot.q)} | {d: v[i] for i, d in enumerate(robot.dq)}
    on |= {a: 0 for a in robot.ddq}
    resid = (dm.lhs.xreplace(on) - dm.G * sp.Matrix([p.names["ubar"]])).applyfunc(sp.simplify)
    assert resid == sp.zeros(3, 1)


def test_three_masses_report_explains_the_sum(three_masses):
    p, sols, _ = three_masses
    md = render(p, sols, "md")
    assert "**Steady motions with constant velocity.**" in md
    assert "K\\bar v = 0" in md and "w^T F_v \\dot q" in md
    assert "\\frac{\\bar u}{3 d}" in md and "\\frac{2 \\bar u}{3 k_{1}}" in md
    tex = render(p, sols, "tex", fragment=True)
    assert "\\textbf{Steady motions with constant velocity.}" in tex and "w^T F_v \\dot q" in tex
    assert "$$" not in tex and "**" not in tex


# --- chains no exercise uses ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("n,forces", [(2, {1: "ubar"}), (4, {1: "ubar"}), (4, {1: "ubar", 3: "wbar"})],
                         ids=["2 masses", "4 masses", "4 masses, two forces"])
def test_chain_matches_closed_form(n, forces):
    text = chain(n, forces, steady_ask(n, ", ".join(f"f{i}: {v}" for i, v in forces.items())))
    _, _, res = run(text)
    v_ref, delta_ref = chain_closed_form(n, {i: S(v) for i, v in forces.items()})
    (v,) = res["steady_velocity"].value
    assert all(same(x, v_ref) for x in v)
    (delta,) = res["deformations"].value
    assert len(delta) == n - 1 and all(same(a, b) for a, b in zip(delta, delta_ref))
    assert res["n_steady"].value == 1


def test_chain_at_rest_with_no_force_gives_the_equilibria():
    """ū = 0: the steady motions are the equilibria (v̄ = 0, every spring at rest length)."""
    _, _, res = run(chain(3, {1: "ubar"}, steady_ask(3, "f1: 0")))
    (v,) = res["steady_velocity"].value
    assert list(v) == [0, 0, 0]
    (delta,) = res["deformations"].value
    assert list(delta) == [0, 0]


def test_chain_without_friction_has_no_steady_velocity():
    """F_v = 0: summing the equations gives 0 = ū (the chain keeps accelerating): no steady motion."""
    text = chain(2, {1: "ubar"}, steady_ask(2, "f1: ubar")).replace("viscous: [d1, d2]", "viscous: [0, 0]")
    p, sols, res = run(text)
    assert res["n_steady"].value == 0 and res["steady_velocity"].value == []
    assert "**No steady motion with constant velocity** exists under this input" in render(p, sols, "md")


def simulate_chain(p, ubar: dict[str, float], T: float) -> np.ndarray:
    """B q̈ = G ū − c − g − F_v q̇ from rest (q = 0, q̇ = 0), integrated with solve_ivp; the final state."""
    robot = p.robot
    dm = derive(robot)
    num = dict(p.values) | {w: ubar[w.name] for w in robot.inputs}
    n = robot.n
    Bf = sp.lambdify([robot.q], dm.B.xreplace(num))
    rhs = (dm.G * sp.Matrix(robot.inputs) - dm.c - dm.g - dm.Fv * sp.Matrix(robot.dq)).xreplace(num)
    ff = sp.lambdify([robot.q, robot.dq], rhs)

    def f(_t, x):
        q, dq = x[:n], x[n:]
        return np.concatenate([dq, np.linalg.solve(np.array(Bf(q), float), np.array(ff(q, dq), float).ravel())])

    out = solve_ivp(f, (0, T), np.zeros(2 * n), rtol=1e-10, atol=1e-12, method="LSODA")
    assert out.success
    return out.y[:, -1]


def test_chain_simulation_converges_to_the_steady_state():
    """4 masses, different frictions, a force on mass 1 and one on mass 3: from rest, the velocities reach v̄ and the
    spring deformations the computed ones."""
    values = {"m1": 1, "m2": 2, "m3": 1.5, "m4": 0.5, "d1": 0.5, "d2": 1.0, "d3": 0.8, "d4": 0.3,
              "k1": 10, "k2": 20, "k3": 15, "ubar": 3, "wbar": -1}
    text = chain(4, {1: "ubar", 3: "wbar"}, steady_ask(4, "f1: ubar, f3: wbar"),
                 values="{" + ", ".join(f"{k}: {v}" for k, v in values.items()) + "}")
    p, _, res = run(text)
    num = dict(p.values)
    (v,) = res["steady_velocity"].value
    (delta,) = res["deformations"].value
    v = np.array([float(x.xreplace(num)) for x in v])
    delta = np.array([float(x.xreplace(num)) for x in delta])
    assert abs(v[0] - 2 / 2.6) < 1e-12   # Σ f / Σ d
    x = simulate_chain(p, {"f1": 3, "f3": -1}, T=80)
    q, dq = x[:4], x[4:]
    assert np.allclose(dq, v, atol=1e-6)
    assert np.allclose(q[:-1] - q[1:], delta, atol=1e-6)


# --- rotations and gravity ------------------------------------------------------------------------------------------

BEAD = """
id: bead
title: a bead on a spinning rod, held by a spring
symbols: {m: m, k: k, r0: r0, I0: I0, fv: fv, Omega: Omega, taubar: taubar}
robot:
  joints: [R, P]
  coordinates: [theta, r]
  friction: {viscous: [fv, 0]}
  inputs: [tau]
  input_map: [[1], [0]]
  links:
    - {name: shaft, mass: 0, com: [0, 0, 0], omega: [0, 0, dtheta], inertia: [0, 0, I0]}
    - {name: bead, mass: m, com: [r*cos(theta), r*sin(theta), 0]}
  extra:
    potential: ["1/2*k*(r - r0)^2"]
asks:
"""


def test_bead_steady_rotation_at_a_given_speed():
    """θ̇ = Ω given, τ unknown: τ = f_v Ω, and the spring balances the centrifugal force: k (r − r0) = m r Ω²."""
    _, _, res = run(BEAD + """  - kind: equilibria
    steady: velocity
    velocity: {theta: Omega}
    solve_for: [tau]
""")
    m, k, r0, fv, Om = S("m"), S("k"), S("r0"), S("fv"), S("Omega")
    (u,) = res["steady_input"].value
    assert same(u[0], fv * Om)
    (qs,) = res["steady_state"].value
    assert plain(qs[0]) == sp.Symbol("theta") and same(qs[1], k * r0 / (k - m * Om ** 2))
    (v,) = res["steady_velocity"].value
    assert same(v[0], Om) and v[1] == 0


def test_bead_steady_speed_under_a_constant_torque_and_simulation():
    """τ = τ̄ given: Ω = τ̄ / f_v; simulated from rest the shaft reaches that speed and the bead that radius."""
    p, _, res = run(BEAD.replace("symbols:", "values: {m: 0.5, k: 20, r0: 0.3, I0: 0.2, fv: 0.4, taubar: 1.2}\n"
                                 "symbols:") + """  - kind: equilibria
    steady: velocity
    input: {tau: taubar}
""")
    m, k, r0, fv, tb = S("m"), S("k"), S("r0"), S("fv"), S("taubar")
    (v,) = res["steady_velocity"].value
    Om = tb / fv
    assert same(v[0], Om) and v[1] == 0
    (qs,) = res["steady_state"].value
    assert same(qs[1], k * r0 / (k - m * Om ** 2))
    robot = p.robot
    dm = derive(robot)
    num = dict(p.values)
    Bf = sp.lambdify([robot.q], dm.B.xreplace(num))
    ff = sp.lambdify([robot.q, robot.dq], (dm.G * sp.Matrix([p.names["taubar"]]) - dm.c - dm.g
                                           - dm.Fv * sp.Matrix(robot.dq)).xreplace(num))

    def f(_t, x):
        return np.concatenate([x[2:], np.linalg.solve(np.array(Bf(x[:2]), float),
                                                      np.array(ff(x[:2], x[2:]), float).ravel())])

    # the radial motion has no damping of its own: it is damped through the shaft; start at the rest length
    out = solve_ivp(f, (0, 400), [0, 0.3, 0, 0], rtol=1e-10, atol=1e-12, method="LSODA")
    assert out.success
    Om_num, r_num = float(Om.xreplace(num)), float(qs[1].xreplace(num))
    assert abs(out.y[2, -1] - Om_num) < 1e-3 * Om_num
    assert abs(out.y[1, -1] - r_num) < 2e-3 * r_num


PENDULUM = """
id: pend
title: a pendulum with friction under a constant torque
symbols: {{d: d}}
robot:
  joints: [R]
  gravity: [0, -9.81, 0]
  friction: {{viscous: [d]}}
  links:
    - {{mass: 1, com: [cos(q1), sin(q1), 0]}}
asks:
  - kind: equilibria
    steady: velocity
    input: {{u1: {u}}}
"""


def test_gravity_along_the_motion_no_steady_velocity():
    """ū = 20 > m g0 l = 9.81: gravity's torque changes along any rotation and cannot be balanced at rest: no motion
    with constant velocity. The report says so; the simulated velocity keeps oscillating."""
    p, sols, res = run(PENDULUM.format(u=20))
    assert res["n_steady"].value == 0 and res["steady_state"].value == [] and res["steady_velocity"].value == []
    md = render(p, sols, "md")
    assert "**No steady motion with constant velocity** exists under this input" in md
    assert "\\textbf{No steady motion with constant velocity}" in render(p, sols, "tex", fragment=True)
    d = 5.0   # the mean speed about ū/d = 4 rad/s, the gravity torque swings it by about ±m g0 l/d
    out = solve_ivp(lambda t, x: [x[1], 20 - d * x[1] - 9.81 * np.cos(x[0])], (0, 200), [0, 0], rtol=1e-9,
                    atol=1e-11, max_step=0.05)
    late = out.y[1, out.t > 150]
    assert late.min() > 0 and late.max() - late.min() > 1.0   # the speed never settles


def test_gravity_balanced_steady_states_are_the_equilibria():
    """ū = 5 < 9.81: the only steady motions are at rest, cos q̄ = ū / (m g0 l)."""
    _, _, res = run(PENDULUM.format(u=5))
    assert res["n_steady"].value == 2
    assert [list(v) for v in res["steady_velocity"].value] == [[0]]
    cs = sorted(float(sp.cos(s[0])) for s in res["steady_state"].value)
    assert np.allclose(cs, [5 / 9.81, 5 / 9.81])
    ss = sorted(float(sp.sin(s[0])) for s in res["steady_state"].value)
    assert np.allclose(ss, [-np.sqrt(1 - (5 / 9.81) ** 2), np.sqrt(1 - (5 / 9.81) ** 2)])


def test_vertical_mass_constant_gravity_has_a_terminal_speed():
    """Gravity constant along the motion (a prismatic joint along it) does not prevent a steady velocity: the
    terminal speed (ū − m g0) / d."""
    text = """
id: fall
title: a mass on a vertical prismatic joint
symbols: {m: m, d: d, g0: g0, ubar: ubar}
robot:
  joints: [P]
  gravity: [0, -g0, 0]
  friction: {viscous: [d]}
  links:
    - {mass: m, com: [0, q1, 0]}
asks:
  - kind: equilibria
    steady: velocity
    input: {u1: ubar}
"""
    _, _, res = run(text)
    (v,) = res["steady_velocity"].value
    assert same(v[0], (S("ubar") - S("m") * S("g0")) / S("d"))


# --- equilibria under a constant input ------------------------------------------------------------------------------

SYM_PENDULUM = """
id: spend
title: a pendulum held by a constant torque
symbols: {m: m, l: l, g0: g0, ubar: ubar}
robot:
  joints: [R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m, com: [l*cos(q1), l*sin(q1), 0]}
asks:
"""


def test_equilibria_under_a_constant_input():
    """steady: rest (the default) with input: g(q) = G ū; the two solutions of m g0 l cos q = ū."""
    p, sols, res = run(SYM_PENDULUM + "  - kind: equilibria\n    input: {u1: ubar}\n")
    eqs = res["equilibria"].value
    assert len(eqs) == 2 and res["n_equilibria"].value == 2
    m, l, g0, ub = S("m"), S("l"), S("g0"), S("ubar")
    for e in eqs:
        assert same(m * g0 * l * sp.cos(e[0]), ub)
    assert "G\\bar u" in render(p, sols, "md")


def test_equilibrium_input_solved_for():
    """solve_for: [u1] at rest: every q is an equilibrium with u = m g0 l cos q."""
    _, _, res = run(SYM_PENDULUM + "  - kind: equilibria\n    solve_for: [u1]\n")
    q1 = sp.Symbol("q1", real=True)
    assert [[plain(x) for x in e] for e in res["equilibria"].value] == [[sp.Symbol("q1")]]
    (u,) = res["equilibrium_input"].value
    assert same(u[0], S("m") * S("g0") * S("l") * sp.cos(q1))


def test_default_equilibria_unchanged():
    """Without the new options the ask is the unforced equilibria g(q) = 0."""
    _, _, res = run(SYM_PENDULUM + "  - kind: equilibria\n")
    assert sorted(float(e[0]) for e in res["equilibria"].value) == pytest.approx([-np.pi / 2, np.pi / 2])


@pytest.mark.parametrize("ask,msg", [
    ("    input: {w: 1}\n", "input: w is not an input"),
    ("    solve_for: [w]\n", "solve_for: w is not an input"),
    ("    input: {u1: 1}\n    solve_for: [u1]\n", "also given in input"),
    ("    velocity: {q1: 1}\n", "velocity: needs steady: velocity"),
    ("    steady: velocity\n    velocity: {x: 1}\n", "velocity: x is not a coordinate"),
])
def test_spec_errors(ask, msg):
    with pytest.raises(UserError, match=msg):
        run(SYM_PENDULUM + "  - kind: equilibria\n" + ask)


def test_grading_steady_state_answers():
    """The steady results are graded as sets: a student's vector (one steady motion) in any written form is
    accepted, a wrong speed is not."""
    r = prepare(load_problem(PROBLEMS / "2016-10-28-ex2.yaml"))
    r.items = {"steady_velocity": ItemSpec(points=2), "deformations": ItemSpec(points=2)}

    def graded(answers):
        return {i.name: i for i in grade(r, Submission("t", "t.yaml", answers, {})).items}

    it = graded({"steady_velocity": "[ubar/(3*d), ubar/(d + 2*d), ubar/3/d]",
                 "deformations": "[[(ubar - d*ubar/(3*d))/k1, ubar/(3*k2)]]"})
    assert it["steady_velocity"].verdict == CORRECT and it["deformations"].verdict == CORRECT
    it = graded({"steady_velocity": "[ubar/d, ubar/d, ubar/d]", "deformations": "[ubar/k1, ubar/k2]"})
    assert it["steady_velocity"].verdict == INCORRECT and it["deformations"].verdict == INCORRECT


def motions_residual(p, sol, values: dict[str, float], times=(0.0, 0.7, 2.3)) -> float:
    """max |B q̈ + c + g + F_v q̇ − G ū| over the reported motions (q̄ + v̄ t, v̄, ū) at a few times, numerically."""
    robot = p.robot
    dm = derive(robot)
    num = {p.names[k]: v for k, v in values.items()}
    worst = 0.0
    for m in sol.steps[-1].data["motions"]:
        free = {x: 0.3 for x in m["q"].free_symbols | m["v"].free_symbols if x in robot.q}
        for t in times:
            on = {x: (m["q"][i] + m["v"][i] * t).xreplace(free) for i, x in enumerate(robot.q)}
            on |= {d: m["v"][i].xreplace(free) for i, d in enumerate(robot.dq)} | {a: 0 for a in robot.ddq}
            r = dm.lhs.xreplace(on) - dm.G * m["u"].xreplace(free) if dm.G is not None else dm.lhs.xreplace(on) - m["u"]
            worst = max(worst, max(abs(complex(sp.N(x.xreplace(num)))) for x in r))
    return worst


@pytest.mark.parametrize("name,ask,values", [
    ("2018-01-11-ex2", 2, {"Is": 0.1, "m": 1, "L": 0.5, "fv": 0.2, "g0": 9.81, "Omega": 10}),
    ("2021-01-12-ex4a", 1, {"m1": 1, "m2": 2, "dc2": 0.4, "I1yy": 0.1, "I2xx": 0.05, "I2yy": 0.2, "I2zz": 0.2,
                            "f1": 0.3, "f2": 0.2, "g0": 9.81, "Omega": 8}),
    # I2xx > I2yy + m2 dc2^2 (not a rigid body, but the algebra must hold for either sign of the denominator)
    ("2021-01-12-ex4a", 1, {"m1": 1, "m2": 2, "dc2": 0.4, "I1yy": 0.1, "I2xx": 0.9, "I2yy": 0.2, "I2zz": 0.2,
                            "f1": 0.3, "f2": 0.2, "g0": 9.81, "Omega": 8}),
], ids=["governor", "polar 2R", "polar 2R, a2 < 0"])
def test_every_reported_motion_satisfies_the_model(name, ask, values):
    """Each reported (q̄, v̄, ū) makes the model hold along q̄ + v̄ t (the angle names asin/acos pair with their
    inputs)."""
    p = load_problem(PROBLEMS / f"{name}.yaml")
    sols = solve_problem(p)
    assert motions_residual(p, sols[ask], values) < 1e-9


H2R = """
id: h2r
title: a planar 2R in a horizontal plane under constant torques
symbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, f1: f1, f2: f2, u1b: u1b, u2b: u2b}
robot:
  joints: [R, R]
  friction: {viscous: [f1, f2]}
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) + d2*cos(q1 + q2), l1*sin(q1) + d2*sin(q1 + q2)], angle: q1 + q2, inertia: I2}
asks:
  - kind: equilibria
    steady: velocity
    input: {u1: u1b, u2: u2b}
"""


def test_horizontal_2r_spins_with_the_elbow_held_by_the_centrifugal_force():
    """No gravity: joint 1 spins at ū1/f1 (q1 is cyclic), the elbow stays where the centrifugal torque
    m2 l1 d2 sin q2 q̇1² balances ū2 (two angles, q2 and π − q2); q2 cannot rotate (its Coriolis terms would
    change along the motion)."""
    p, sols, res = run(H2R)
    (v,) = res["steady_velocity"].value
    f1, u1b, u2b, m2, l1, d2 = (S(x) for x in ("f1", "u1b", "u2b", "m2", "l1", "d2"))
    assert same(v[0], u1b / f1) and v[1] == 0
    states = res["steady_state"].value
    assert len(states) == 2
    for st in states:
        assert same(m2 * l1 * d2 * sp.sin(st[1]) * (u1b / f1) ** 2, u2b)
    values = {"m1": 2, "m2": 1, "d1": 0.3, "d2": 0.25, "l1": 0.6, "I1": 0.1, "I2": 0.05, "f1": 0.5, "f2": 0.4,
              "u1b": 1.5, "u2b": 0.2}
    assert motions_residual(p, sols[0], values) < 1e-9


def test_rest_with_input_and_deformations():
    """Two masses, the first tied to a wall by k0, a force on the second: at rest both springs carry ū."""
    text = """
id: wall
title: two masses tied to a wall
symbols: {m1: m1, m2: m2, k0: k0, k1: k1, ubar: ubar}
robot:
  joints: [P, P]
  links:
    - {mass: m1, com: [q1, 0]}
    - {mass: m2, com: [q2, 0]}
  extra:
    potential: ["1/2*k0*q1^2 + 1/2*k1*(q2 - q1)^2"]
  input_map: [[0], [1]]
asks:
  - kind: equilibria
    input: {u1: ubar}
    deformations: [q1, q2 - q1]
"""
    p, sols, res = run(text)
    (qe,) = res["equilibria"].value
    ub, k0, k1 = S("ubar"), S("k0"), S("k1")
    assert same(qe[0], ub / k0) and same(qe[1], ub / k0 + ub / k1)
    (delta,) = res["deformations"].value
    assert same(delta[0], ub / k0) and same(delta[1], ub / k1)
    md = render(p, sols, "md")
    assert "G\\bar u" in md and "deformations" in md
    assert "\\[" in render(p, sols, "tex", fragment=True)


def test_set_of_speeds_compares_without_error():
    """Set entries that are not angles (speeds, deformations) compare as unequal when they differ (the modulo-2π
    fallback used to raise on them)."""
    from solver.math.equivalence import set_equiv
    ub, d = S("ubar"), S("d")
    assert set_equiv([sp.Matrix([ub / (3 * d)])], [sp.Matrix([ub / d / 3])]).ok
    v = set_equiv([sp.Matrix([ub / (3 * d)])], [sp.Matrix([ub / (2 * d)])])
    assert not v.ok and "not found" in v.detail


@pytest.mark.skipif(not shutil.which("pdflatex"), reason="pdflatex not installed")
@pytest.mark.parametrize("text", [PENDULUM.format(u=20), H2R, SYM_PENDULUM + "  - kind: equilibria\n    solve_for: [u1]\n"],
                         ids=["no steady motion", "spinning 2R", "input solved for"])
def test_latex_report_compiles(tmp_path, text):
    p, sols, _ = run(text)
    (tmp_path / "r.tex").write_text(render(p, sols, "tex"))
    r = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "r.tex"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stdout[-2000:]


# --- equilibria of a given g(q): distinct sets, families in the coordinates, conditions on the input -----------------

def model_robot(joints: str, g: str, inputs: str = "", symbols: str = "{a: a, b: b}") -> str:
    """A robot with B = I and g given in model: (no exercise uses these)."""
    n = len(joints.split(","))
    eye = "[" + ", ".join("[" + ", ".join("1" if i == j else "0" for j in range(n)) + "]" for i in range(n)) + "]"
    return f"""
id: model_g
title: g given in the model
symbols: {symbols}
robot:
  joints: [{joints}]
  model: {{B: "{eye}", g: "{g}"}}
asks:
  - kind: equilibria
{inputs}"""


def _covered(x: np.ndarray, configs: list, q: list) -> bool:
    """The numeric root x is in one of the reported configurations or families (angles modulo 2π)."""
    for c in configs:
        free = {s: x[i] for i, s in enumerate(q) if c[i] == s}
        pt = np.array([float(sp.N(e.xreplace(free))) for e in c])
        if np.max(np.abs((pt - x + np.pi) % (2 * np.pi) - np.pi)) < 1e-6:
            return True
    return False


@pytest.mark.parametrize("g, want", [
    # rows that cancel in a sum (the angles were looked for in g1 + g2 = 0: no solution was reported)
    ("[a*sin(q1 - q2), -a*sin(q1 - q2)]", [["q2", "q2"], ["q2 + pi", "q2"]]),
    # families in the coordinates (were atan2(s_q2, ±sqrt(1 - s_q2^2)) with the solver's sine symbol, 8 of them)
    ("[sin(q1 + q2), sin(q1 + q2)]", [["-q2", "q2"], ["pi - q2", "q2"]]),
    # the same family found on two branches, and points inside a family (were 8 entries)
    ("[sin(q1)*sin(q2), cos(q1)*sin(q2)]", [["q1", "0"], ["q1", "pi"]]),
])
def test_equilibria_families_are_distinct_sets(g, want):
    """Each set of equilibria is listed once: the families of the solver written in the coordinates (equal as sets,
    angles modulo 2π), the points inside a listed family dropped. Checked numerically: every listed configuration
    zeroes g at random values of its free coordinates, and every root found by least squares from random starts
    lies in a listed one."""
    from scipy.optimize import least_squares
    _, _, res = run(model_robot("R, R", g))
    q = [sp.Symbol("q1", real=True), sp.Symbol("q2", real=True)]
    got = res["equilibria"].value
    assert res["n_equilibria"].value == len(want) == len(got)
    names = {"q1": q[0], "q2": q[1], "pi": sp.pi}
    for w in want:
        wm = sp.Matrix([sp.sympify(x, locals=names) for x in w])
        assert any(sp.simplify(c - wm) == sp.zeros(2, 1) for c in got), (w, got)
    gf = sp.lambdify(q, sp.sympify(g.replace("a*", "").replace("^", "**"), locals=names))
    rng = np.random.default_rng(5)
    for c in got:
        assert not (set().union(*(e.free_symbols for e in c)) - set(q))   # no symbol of the solver left
        for _ in range(3):
            free = {s: rng.uniform(-3, 3) for s in q}
            assert np.abs(gf(*[float(e.xreplace(free)) for e in c])).max() < 1e-12
    found = 0
    for _ in range(60):
        r = least_squares(lambda x: gf(*x), rng.uniform(-np.pi, np.pi, 2), xtol=1e-15, ftol=1e-15, gtol=1e-15)
        if np.abs(gf(*r.x)).max() < 1e-12:
            found += 1
            assert _covered(r.x, got, q), r.x
    assert found > 30


def test_equilibria_three_angles_listed_once():
    """sin q3 cos q3 = 0 and two products: 2 families (q3 = 0, π) and 16 points (q3 = ±π/2) -- 48 were listed,
    each point four times."""
    _, _, res = run(model_robot("R, R, R", "[a*sin(q1)*cos(q2)*sin(q3), b*cos(q1)*sin(q2)*sin(q3), sin(q3)*cos(q3)]"))
    got = res["equilibria"].value
    assert len(got) == 18 and res["n_equilibria"].value == 18
    pts = [tuple(np.round(np.array([float(x) for x in c]) % (2 * np.pi), 9)) for c in got if all(x.is_number for x in c)]
    assert len(pts) == 16 == len(set(pts))


def test_equilibria_condition_on_a_constant_input():
    """A vertical prismatic joint under the input F: g(q) = m g0 = F at every q iff F = m g0 (the report said "no
    solution"): every configuration, with the condition as a result and in the text."""
    text = """
id: vert
title: a mass on a vertical prismatic joint, held by F
symbols: {m: m, g0: g0, F: F}
robot:
  joints: [P]
  gravity: [0, -g0, 0]
  links:
    - {mass: m, com: [0, q1, 0]}
asks:
  - kind: equilibria
    input: {u1: F}
"""
    p, sols, res = run(text)
    assert [[plain(x) for x in e] for e in res["equilibria"].value] == [[sp.Symbol("q1")]]
    assert res["n_equilibria"].value == sp.oo
    (cond,) = res["equilibrium_conditions"].value
    assert same(cond.subs(S("F"), S("m") * S("g0")), 0) and not same(cond, 0)
    md = render(p, sols, "md")
    assert "**every configuration** is an equilibrium if $- F + g_{0} m = 0$, and none is otherwise" in md
    assert "no solution" not in md
    assert "\\textbf{every configuration}" in render(p, sols, "tex", fragment=True)
    # without the input: m g0 = 0 never holds (positive symbols): no equilibrium, as before
    _, _, res0 = run(text.replace("    input: {u1: F}\n", ""))
    assert res0["equilibria"].value == [] and "equilibrium_conditions" not in res0


def test_equilibria_condition_with_other_rows():
    """A horizontal spring joint and a vertical prismatic one under (0, F): q1 = 0, any q2, iff F = m2 g0."""
    text = model_robot("R, P", "[k*q1, m2*g0]", "    input: {u2: F}\n", "{k: k, m2: m2, g0: g0, F: F}")
    p, sols, res = run(text)
    assert [[plain(x) for x in e] for e in res["equilibria"].value] == [[0, sp.Symbol("q2")]]
    (cond,) = res["equilibrium_conditions"].value
    assert same(cond, S("m2") * S("g0") - S("F")) or same(cond, S("F") - S("m2") * S("g0"))
    assert "free of $q$ require $- F + g_{0} m_{2} = 0$" in render(p, sols, "md")


@pytest.mark.parametrize("ask,msg", [
    ("    input: {w: 1}\n", "input: w is not an input"),
    ("    input: {u1: 1}\n    solve_for: [u1]\n", "also given in input"),
    ("    steady: velocity\n    velocity: {x: 1}\n", "velocity: x is not a coordinate"),
    ("    deformations: [q1 - q5]\n", "unknown name 'q5'"),
])
def test_check_finds_spec_errors_without_solving(ask, msg):
    """The inputs, velocity and deformations are read by the kind's validate hook (`check`) as by solving."""
    assert msg in error_found_without_solving(SYM_PENDULUM + "  - kind: equilibria\n" + ask)


def test_same_value_of_parametric_roots():
    """Two parametric roots compared as sets: parted by their values at a random real point (the exact test took
    seconds per pair on the singular set of a 2R with its tip on a circle), equal forms still found equal by the
    exact test (the screen passes them), and a point off the real domain (acos of a number above 1) never taken as proof."""
    from solver.dynamics.equilibria import _differ_at_a_point, _same_value
    l1, l2, x = sp.symbols("l1 l2 x", positive=True)
    q2 = sp.Symbol("q2", real=True)
    a = sp.atan2(l2 * sp.sin(q2), l1 + l2 * sp.cos(q2))
    assert _differ_at_a_point(a, -a, True) and not _same_value(a, -a, True)
    assert _same_value(a, a + 2 * sp.pi, True) and not _differ_at_a_point(a, a + 2 * sp.pi, True)
    assert _same_value(sp.atan2(l1 * sp.sin(q2), l1 * sp.cos(q2)), q2, True)
    assert _same_value(sp.cos(q2) ** 2 * l1, l1 - l1 * sp.sin(q2) ** 2, False)
    assert not _differ_at_a_point(sp.acos(1 + x), sp.pi / 2 - sp.asin(1 + x), False)


# --- conditions on the parameters in the steady-motion and solve_for paths ------------------------------------------

RP_SLIDER = """
id: rp_slider
title: a planar RP arm whose slider stays vertical at the tip of link 1, pushed up by a constant force
symbols: {m1: m1, m2: m2, r1: r1, l1: l1, I1: I1, g0: g0, F: F, fv1: fv1}
robot:
  joints: [R, P]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [r1*cos(q1), r1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1), l1*sin(q1) + q2]}
  friction: {viscous: [fv1, 0]}
asks:
  - kind: equilibria
    input: {u2: F}
  - kind: equilibria
    steady: velocity
    input: {u2: F}
    suffix: _v
  - kind: equilibria
    solve_for: [u1]
    input: {u2: F}
    suffix: _s
  - kind: equilibria
    steady: velocity
    velocity: {q1: 0}
    solve_for: [u1]
    input: {u2: F}
    suffix: _vs
"""
RP_VALUES = {"m1": 1.5, "m2": 0.8, "r1": 0.3, "l1": 0.7, "I1": 0.2, "g0": 9.81, "fv1": 0.4}


def _steady_residual(p, sol, values: dict[str, float], seed: int = 1) -> float:
    """max |B q̈ + c + g + F_v q̇ − G ū| over the reported motions along q̄ + v̄ t (t = 0, 1.3), the coordinates and
    velocities left free (arbitrary) at random values."""
    robot, dm, rng = p.robot, derive(p.robot), np.random.default_rng(seed)
    num = {p.names[k]: v for k, v in values.items()}
    worst, d = 0.0, sol.steps[-1].data
    if "motions" not in d:   # the rest path: g(q) = G ū at each configuration
        for c in d["configs"]:
            free = {x: rng.uniform(-2, 2) for x in c.free_symbols if x in robot.q}
            r = dm.g.xreplace(dict(zip(robot.q, c.xreplace(free)))) - d["rhs"]
            worst = max(worst, max(abs(complex(sp.N(x.xreplace(num)))) for x in r))
        return worst
    for m in d["motions"]:
        free = {x: rng.uniform(-2, 2) for x in m["q"].free_symbols | m["v"].free_symbols if x in robot.q + robot.dq}
        for t in (0.0, 1.3):
            on = {x: (m["q"][i] + m["v"][i] * t).xreplace(free) for i, x in enumerate(robot.q)}
            on |= {d: m["v"][i].xreplace(free) for i, d in enumerate(robot.dq)} | {a: 0 for a in robot.ddq}
            u = m["u"].xreplace(free).xreplace(on)
            r = dm.lhs.xreplace(on) - (dm.G * u if dm.G is not None else u)
            worst = max(worst, max(abs(complex(sp.N(x.xreplace(num)))) for x in r))
    return worst


def test_steady_and_solve_for_report_a_row_free_of_the_unknowns_as_a_condition():
    """The slider's row m2 g0 = F is free of q, q̇ and u1: every path reports it as the condition F = m2 g0 (the
    steady-motion and solve_for paths said "no steady motion" / "no equilibrium"). Rest: q1 = ±π/2, any q2; steady
    velocity: the same with the slider at any speed; solve_for: any q with u1 = (m1 r1 + m2 l1) g0 cos q1. Checked by
    substituting each motion in the model with F = m2 g0 (residual 0) and F ≠ m2 g0 (not 0), and by simulation."""
    p, sols, res = run(RP_SLIDER)
    m2, g0, F = S("m2"), S("g0"), S("F")
    for sfx in ("", "_v", "_s", "_vs"):
        (cond,) = res["equilibrium_conditions" + sfx].value
        assert same(cond, m2 * g0 - F) or same(cond, F - m2 * g0), sfx
    q1, q2 = sp.Symbol("q1"), sp.Symbol("q2")
    dq2 = sp.Symbol("dq2")
    assert sorted([[plain(x) for x in e] for e in res["equilibria"].value], key=str) == \
        [[-sp.pi / 2, q2], [sp.pi / 2, q2]]
    assert sorted([[plain(x) for x in e] for e in res["steady_state_v"].value], key=str) == \
        [[-sp.pi / 2, q2], [sp.pi / 2, q2]]
    assert [[plain(x) for x in v] for v in res["steady_velocity_v"].value] == [[0, dq2]]
    assert [[plain(x) for x in e] for e in res["equilibria_s"].value] == [[q1, q2]]
    (u,) = res["equilibrium_input_s"].value
    assert same(u[0], (S("m1") * S("r1") + m2 * S("l1")) * g0 * sp.cos(q1)) and same(u[1], F)
    assert [[plain(x) for x in v] for v in res["steady_velocity_vs"].value] == [[0, dq2]]
    held = RP_VALUES | {"F": RP_VALUES["m2"] * RP_VALUES["g0"]}
    for k in range(4):
        assert _steady_residual(p, sols[k], held) < 1e-9
        assert _steady_residual(p, sols[k], held | {"F": 5.0}) > 1.0   # the condition is needed
    md, tex = render(p, sols, "md"), render(p, sols, "tex", fragment=True)
    for text in (md, tex):
        assert "free of $q$ require $- F + g_{0} m_{2} = 0$: for any other value of the parameters there is no " \
               "equilibrium." in text
        assert "free of $q$ and $\\dot q$ require $- F + g_{0} m_{2} = 0$: for any other value of the parameters " \
               "there is no steady motion with constant velocity." in text
        assert "free of $q$ and $u_{1}$ require $- F + g_{0} m_{2} = 0$" in text
        assert "free of $q$, $\\dot q$ and $u_{1}$ require" in text
    assert "No steady motion" not in md and "No equilibrium" not in md
    # simulation with F = m2 g0, u1 = 0: from q1 = -pi/2 the slider keeps its speed, link 1 stays
    v = {k: held[k] for k in held}
    b11 = v["I1"] + v["m1"] * v["r1"] ** 2 + v["m2"] * v["l1"] ** 2
    a = (v["m1"] * v["r1"] + v["m2"] * v["l1"]) * v["g0"]

    def f(t, x):
        q1_, _, w1, w2 = x
        B = np.array([[b11, v["m2"] * v["l1"] * np.cos(q1_)], [v["m2"] * v["l1"] * np.cos(q1_), v["m2"]]])
        rhs = -np.array([a * np.cos(q1_) + v["fv1"] * w1, -v["m2"] * v["l1"] * np.sin(q1_) * w1 ** 2
                         + v["m2"] * v["g0"]]) + np.array([0.0, v["F"]])
        return [w1, w2, *np.linalg.solve(B, rhs)]
    out = solve_ivp(f, (0, 5), [-np.pi / 2, 0.1, 0.0, 0.7], rtol=1e-10, atol=1e-12)
    assert np.allclose(out.y[2:, -1], [0.0, 0.7], atol=1e-8) and np.isclose(out.y[0, -1], -np.pi / 2, atol=1e-8)


def test_steady_conditions_that_differ_between_motions_are_said_per_motion():
    """An unbalanced rotor (CoM offset rc of either sign): at rest at ±π/2, or spinning at any speed iff
    g0 m rc = 0 (was dropped as "an equation of the parameters alone"); the condition is said on that motion only."""
    text = """
id: rotor
title: an unbalanced rotor in a vertical plane
symbols: {m: m, rc: {meaning: CoM offset, sign: real}, g0: g0}
robot:
  joints: [R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m, com: [rc*cos(q1), rc*sin(q1)]}
asks:
  - kind: equilibria
    steady: velocity
"""
    p, sols, res = run(text)
    q1, dq1 = sp.Symbol("q1"), sp.Symbol("dq1")
    got = [([plain(x) for x in m["q"]], [plain(x) for x in m["v"]], [plain(r) for r in m.get("requires", [])])
           for m in sols[0].steps[-1].data["motions"]]
    rc_m_g0 = sp.Symbol("g0") * sp.Symbol("m") * sp.Symbol("rc")
    assert sorted(map(str, got)) == sorted(map(str, [([-sp.pi / 2], [0], []), ([sp.pi / 2], [0], []),
                                                     ([q1], [dq1], [rc_m_g0])]))
    assert [plain(x) for x in res["equilibrium_conditions"].value] == [rc_m_g0]
    vals = {"m": 2.0, "g0": 9.81}
    assert _steady_residual(p, sols[0], vals | {"rc": 0.0}) < 1e-12
    md = render(p, sols, "md")
    assert "\\quad (\\text{if } g_{0} m rc = 0)$$" in md and "free of $q$" not in md


def test_equilibria_family_of_a_repeated_row_and_a_solver_failure():
    """g = (a c12 − b s12) twice: the family q1 + q2 = atan2(a, b) (+ π) was reported as "no solution" (sympy's
    solve returned [] for the repeated equation; now each equation once, and an empty answer is checked by least
    squares before it is believed: roots found, the equations are solved again each once). U = a s2 + b c1 c2 made
    sympy's Gröbner basis divide by zero: an internal error, now a message at the ask."""
    p, sols, res = run(model_robot("R, R", "[a*cos(q1 + q2) - b*sin(q1 + q2), a*cos(q1 + q2) - b*sin(q1 + q2)]"))
    q1, q2 = p.robot.q
    got = res["equilibria"].value
    assert len(got) == 2
    phis = set()
    for c in got:
        for v in (0.3, -1.1, 2.0):
            pt = {q2: v, p.names["a"]: 1.3, p.names["b"]: 0.7}
            x = [float(sp.N(e.xreplace(pt))) for e in c]
            assert abs(1.3 * np.cos(x[0] + x[1]) - 0.7 * np.sin(x[0] + x[1])) < 1e-12
            phis.add(round((x[0] + x[1]) % (2 * np.pi), 9))
    assert len(phis) == 2   # the two families q1 + q2 = φ, φ + π
    a, b = p.names["a"], p.names["b"]
    assert sorted(sp.simplify(c[0] + q2 - sp.atan2(a, b)) for c in got) == [-sp.pi, 0]   # written as a teacher does
    assert [c[1] for c in got] == [q2, q2]
    assert "only through $\\varphi_1 = q_{1} + q_{2}$: writing" in render(p, sols, "md")
    with pytest.raises(UserError, match="not solved in closed form"):
        run(model_robot("R, R", "0").replace('g: "0"', 'U: "a*sin(q2) + b*cos(q1)*cos(q2)"'))


def test_equilibria_in_angle_sums():
    """g depending on the angles only through sums (q1 + q2, 2q1 + 2q2) is solved in φ = T q (T unimodular, the
    other angles kept free) and written back: a sin²(q1 + q2) + b > 0 took 20 s in sympy's solve to say "no
    solution"; a c123 on a 3R gives the two families q1 + q2 + q3 = ±π/2. g of q1 and q1 + q2 is solved in the
    absolute angles (one new angle per argument); g of q1, q2 and q1 + q2 (more arguments than angles) and g of
    the single angles are left alone."""
    from solver.dynamics.equilibria import angle_sums, conditional_equilibria
    q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
    a, b = sp.symbols("a b", positive=True)
    ch = angle_sums([a * sp.cos(2 * q1 + 2 * q2) + b], [q1, q2])
    assert ch.forms == [q1 + q2] and ch.kept == [q2] and abs(ch.T.det()) == 1
    absolute = angle_sums([a * sp.cos(q1) + b * sp.cos(q1 + q2), b * sp.cos(q1 + q2)], [q1, q2])
    assert absolute.forms == [q1, q1 + q2] and absolute.kept == []
    assert angle_sums([a * sp.cos(q1) + b * sp.cos(q1 + q2), b * sp.sin(q2)], [q1, q2]) is None
    assert angle_sums([a * sp.cos(q1) + b * sp.sin(q2)], [q1, q2]) is None
    assert angle_sums([a * sp.cos(q1 * q2)], [q1, q2]) is None
    assert conditional_equilibria(sp.Matrix([a * sp.sin(q1 + q2) ** 2 + b] * 2), [q1, q2]) == ([], [], False, [])
    configs, conditions, every, _ = conditional_equilibria(sp.Matrix([a * sp.cos(q1 + q2 + q3)] * 3), [q1, q2, q3])
    assert not every and not conditions
    assert sorted(sp.simplify(c[0] + q2 + q3) for c in configs) == [-sp.pi / 2, sp.pi / 2]
    assert all(list(c[1:]) == [q2, q3] for c in configs)


def test_ring_rows_are_the_expanded_trigonometric_rows(monkeypatch):
    """_to_polynomial's rows in c_θ, s_θ computed in a sparse ring (sympy's expand_trig forms of sums and of
    multiples 2θ, 3θ, 4θ, the rows cleared of their rational denominators) are node for node what the expansions
    give, on rows of a robot no library problem has; a row outside the ring (a float, an offset, a parameter angle)
    takes the expansions."""
    import solver.dynamics.equilibria as E
    q1, q2, x = sp.symbols("q1 q2 x", real=True)
    a, b, al = sp.symbols("a b alpha", positive=True)
    rows = [a * sp.sin(3 * q1 - q2) / 6 + b * sp.cos(2 * q1 + 2 * q2) * sp.sin(q2) ** 2 / 4 - x * sp.cos(4 * q2) / 3,
            (a * sp.cos(q1) + b * sp.sin(2 * q2 - q1)) ** 2 - b ** 2 * sp.sin(4 * q1) / 2 + x * a]
    fast, cs = E._to_polynomial(rows, [q1, q2])
    (c1, s1), (c2, s2) = cs[q1], cs[q2]
    assert E._ring_rows(rows, cs) is not None and fast[2:] == [c1 ** 2 + s1 ** 2 - 1, c2 ** 2 + s2 ** 2 - 1]
    assert sp.expand(fast[1] - (a * c1 + b * (2 * s2 * c2 * c1 - (2 * c2 ** 2 - 1) * s1)) ** 2
                     + b ** 2 * c1 * (4 * s1 - 8 * s1 ** 3) / 2 - x * a) == 0   # sin 4θ = cos θ U₃(sin θ)
    monkeypatch.setattr(E, "_ring_rows", lambda *args: None)
    slow, _ = E._to_polynomial(rows, [q1, q2])
    assert [sp.srepr(u) for u in fast] == [sp.srepr(v) for v in slow]
    monkeypatch.undo()
    for other in (sp.Float(0.5) * sp.sin(q1), sp.cos(q1 + sp.pi / 4), sp.sin(q1 + al)):
        assert E._ring_rows([other], cs) is None


def test_equilibria_under_a_constant_input_in_absolute_angles():
    """A 2R in a vertical plane with a constant torque ū2 at joint 2: g of q1 and q1 + q2 decouples in the absolute
    angles (cos(q1 + q2) = ū2/(d2 m2 g0), then cos q1); the four equilibria are written with arc cosines,
    q1 = ±(π − acos(ū2/a)) (sympy's solve in c1, s1, c2, s2 gave nested radicals after minutes), with the conditions
    a ≥ ū2, b ≥ ū2. Each satisfies g(q) = (0, ū2) at parameter values where it exists; angles in (−π, π]. An angle
    whose cosine alone is fixed, a cos q1 = x (x of any sign), is ±acos(x/a) with a² − x² ≥ 0."""
    from solver.dynamics.equilibria import conditional_equilibria
    q1, q2 = sp.symbols("q1 q2", real=True)
    a, b, u = sp.symbols("a b u", positive=True)    # a = g0 (d1 m1 + l1 m2), b = g0 d2 m2
    g = sp.Matrix([a * sp.cos(q1) + b * sp.cos(q1 + q2), b * sp.cos(q1 + q2) - u])
    configs, conditions, every, requires = conditional_equilibria(g, [q1, q2])
    assert len(configs) == 4 and not every and not requires
    assert all(x.atoms(sp.acos) and not any(p.exp.is_Rational and p.exp.q == 2 for p in x.atoms(sp.Pow))
               for c in configs for x in c)
    assert set(conditions) == {sp.GreaterThan(a - u, 0), sp.GreaterThan(b - u, 0)}
    assert sorted(sp.simplify(c[0] - sp.pi + sp.acos(u / a)) * sp.simplify(c[0] + sp.pi - sp.acos(u / a))
                  for c in configs) == [0] * 4
    point = {a: 3.0, b: 2.0, u: 1.2}
    for c in configs:
        vals = {q1: float(c[0].subs(point)), q2: float(c[1].subs(point))}
        assert max(abs(float(x.subs(point).subs(vals))) for x in g) < 1e-12
    exact = {a: 3, b: 2, u: 1}
    assert all(-sp.pi < sp.N(x.subs(exact)) <= sp.pi for c in configs for x in c)
    x = sp.Symbol("x", real=True)
    one, cond, _, _ = conditional_equilibria(sp.Matrix([a * sp.cos(q1) - x]), [q1])
    assert set(c[0] for c in one) == {sp.acos(x / a), -sp.acos(x / a)}
    assert [sp.expand(c.lhs) for c in cond] == [a ** 2 - x ** 2]


VERTICAL_2R = """
id: steady-2r
title: steady motions of a 2R in a vertical plane under constant torques
symbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, l2: l2, I1: I1, I2: I2, g0: g0, u2: u2}
robot:
  joints: [R, R]
  gravity: [0, -g0]
  dh:
    table:
      - {a: l1, alpha: 0, d: 0, theta: q1}
      - {a: l2, alpha: 0, d: 0, theta: q2}
    links:
      - {mass: m1, com: [d1 - l1, 0, 0], inertia: [0, 0, I1]}
      - {mass: m2, com: [d2 - l2, 0, 0], inertia: [0, 0, I2]}
asks:
"""


def test_steady_motions_of_a_vertical_2r_in_absolute_angles():
    """steady: velocity under ū = (0, ū2) on a 2R in a vertical plane: no angle can rotate (g would vary), and the
    rest subset is solved in the absolute angles q1, q1 + q2 like the equilibria (it took 3 minutes and printed
    nested radicals): the same four configurations, v̄ = 0, each satisfying c + g = G ū."""
    ask = "  - kind: equilibria\n    input: {u1: 0, u2: u2}\n    steady: velocity\n"
    p, sols, res = run(VERTICAL_2R + ask)
    steady = res["steady_state"].value
    assert len(steady) == 4 and res["steady_velocity"].value == [sp.Matrix([0, 0])]
    assert all(x.atoms(sp.acos) for m in steady for x in m)
    dm = derive(p.robot)
    point = {p.names[k]: v for k, v in dict(m1=3, m2=2, d1=0.4, d2=0.3, l1=0.8, g0=9.81, u2=2.5).items()}
    for m in steady:
        at = dict(zip(p.robot.q, [float(x.subs(point)) for x in m]))
        rows = (dm.g - sp.Matrix([0, p.names["u2"]])).subs(point).subs(at)
        assert max(abs(float(r)) for r in rows) < 1e-9


def test_input_solved_for_with_an_angle_sum_family():
    """solve_for: [u1] at rest with ū2 given: u1 drops out and only q1 + q2 = ±acos(ū2/(d2 m2 g0)) is fixed (q2
    free), written so instead of atan2 of radicals in q2 with |cos q2|; ū1 = g1(q) along the family."""
    p, sols, res = run(VERTICAL_2R + "  - kind: equilibria\n    input: {u2: u2}\n    solve_for: [u1]\n")
    q1, q2 = p.robot.q
    eqs = res["equilibria"].value
    d2, m2, g0, u2 = (p.names[k] for k in ("d2", "m2", "g0", "u2"))
    assert len(eqs) == 2 and all(m[1] == q2 for m in eqs)
    assert {sp.simplify(m[0] + q2) for m in eqs} == {sp.acos(u2 / (d2 * g0 * m2)), -sp.acos(u2 / (d2 * g0 * m2))}
    g1 = derive(p.robot).g[0]
    for m, u in zip(eqs, res["equilibrium_input"].value):
        at = {q1: m[0], q2: sp.Rational(1, 3)}
        point = {p.names[k]: v for k, v in dict(m1=3, m2=2, d1=0.4, d2=0.3, l1=0.8, g0=9.81, u2=2.5).items()}
        assert abs(float((g1.subs(at) - u[0].subs(q2, sp.Rational(1, 3))).subs(point))) < 1e-9
