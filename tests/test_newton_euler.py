"""The `newton_euler` ask: the recursive Newton–Euler algorithm equals the Euler–Lagrange model on every library
robot given by DH and on spatial robots no exercise uses (both DH conventions, prismatic joints, a base
transform); NE as a routine gives g, c, the columns of B and T; the report renders."""
import pytest
import sympy as sp
from conftest import PROBLEMS, error_found_without_solving

from solver.dynamics.model import derive
from solver.dynamics.newton_euler import newton_euler
from solver.math.simplify import is_zero
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError

DH_PROBLEMS = sorted(str(f) for f in PROBLEMS.glob("*.yaml") if "\n  dh:" in f.read_text())

SPATIAL = """
id: t
title: spatial RRP (standard DH, base transform)
symbols: {l1: l1, d1: d1, m1: m1, m2: m2, m3: m3, c2: c2, c3: c3, g0: g0, Ia: Ia, Ib: Ib, Ic: Ic}
robot:
  joints: [R, R, P]
  gravity: [0, 0, -g0]
  dh:
    convention: {conv}
    base: [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, d1], [0, 0, 0, 1]]
    table:
      - {a: 0, alpha: pi/2, d: l1, theta: q1}
      - {a: l1, alpha: -pi/2, d: 0, theta: q2}
      - {a: 0, alpha: 0, d: q3, theta: 0}
    links:
      - {mass: m1, com: [0, c2, 0], inertia: [Ia, Ib, Ic]}
      - {mass: m2, com: [c2, 0, c3], inertia: [[Ia, 0, Ic], [0, Ib, 0], [Ic, 0, Ia]]}
      - {mass: m3, com: [0, 0, -c3], inertia: [Ib, Ib, Ic]}
asks:
  - kind: newton_euler
    routines: [gravity, coriolis, static, inertia, kinetic_energy]
"""


def lagrange_equal(robot) -> bool:
    res = newton_euler(robot, robot.dq, robot.ddq)
    dm = derive(robot)
    return all(is_zero(sp.expand(x)) for x in res.u - dm.lhs)


@pytest.mark.parametrize("path", DH_PROBLEMS, ids=lambda p: p.rsplit("/", 1)[-1])
def test_ne_equals_lagrange_on_library_dh_robots(path):
    robot = load_problem(path).robot
    assert robot.frames and robot.bodies
    assert lagrange_equal(robot)


def test_library_has_dh_robots():
    assert len(DH_PROBLEMS) >= 5


@pytest.mark.parametrize("conv", ["standard", "modified"])
def test_spatial_robot_and_routines(conv):
    p = load_problem_text(SPATIAL.replace("{conv}", conv))
    assert lagrange_equal(p.robot)
    r = all_results(solve_problem(p))
    assert r["ne_equals_lagrange"].value is True
    dm = derive(p.robot)
    assert all(is_zero(x) for x in r["ne_g"].value - dm.g)
    assert all(is_zero(sp.expand(x)) for x in r["ne_B"].value - dm.B)
    assert all(is_zero(sp.expand(x)) for x in r["ne_c"].value - dm.c)
    assert is_zero(sp.expand(r["ne_T"].value - dm.T))


def test_forward_recursion_by_differentiation():
    """ω_i and the CoM acceleration from NE equal those from differentiating the frames along a motion."""
    p = load_problem_text(SPATIAL.replace("{conv}", "standard"))
    robot = p.robot
    t = sp.Symbol("t")
    traj = {robot.q[0]: sp.sin(t), robot.q[1]: 2 * t ** 2, robot.q[2]: 1 + t}
    vals = {s: sp.Rational(k + 2, 3) for k, s in enumerate(sorted(p.symbols.values(), key=lambda s: s.name))}
    res = newton_euler(robot, robot.dq, robot.ddq, gravity=False)
    state = {}
    for q, dq, ddq in zip(robot.q, robot.dq, robot.ddq):
        state[dq] = sp.diff(traj[q], t)
        state[ddq] = sp.diff(traj[q], t, 2)
    t0 = sp.Rational(3, 10)
    for i, s in enumerate(res.links, 1):
        A = robot.frames[i].xreplace(traj)
        R = A[:3, :3]
        S = (R.T * R.diff(t))
        w = sp.Matrix([S[2, 1], S[0, 2], S[1, 0]])
        pc = robot.bodies[i - 1].com.xreplace(traj)
        ac = R.T * pc.diff(t, 2)
        ne_w = s.w.xreplace(state).xreplace(traj)
        ne_ac = s.ac.xreplace(state).xreplace(traj)
        for x, y in zip(list(w) + list(ac), list(ne_w) + list(ne_ac)):
            assert abs(float((x - y).subs(vals).subs(t, t0))) < 1e-9


def test_calls_and_at_and_render():
    text = SPATIAL.replace("{conv}", "standard").replace("    routines: [gravity, coriolis, static, inertia, kinetic_energy]\n", """    calls:
      - {name: y, dq: 0, ddq: [dq1/2, dq2/2, dq3/2], gravity: false, dot_with: [dq1, dq2, dq3]}
    at: {q1: 0, q2: pi/2, q3: 1, dq1: 1, dq2: 0, dq3: 0, ddq1: 0, ddq2: 0, ddq3: 0}
""")
    p = load_problem_text(text)
    sols = solve_problem(p)
    r = all_results(sols)
    assert is_zero(sp.expand(r["y_dot"].value - derive(p.robot).T))
    at = r["ne_u_at"].value
    dm = derive(p.robot)
    st = {p.robot.q[0]: 0, p.robot.q[1]: sp.pi / 2, p.robot.q[2]: 1, p.robot.dq[0]: 1}
    want = dm.lhs.xreplace({**{v: 0 for v in p.robot.dq + p.robot.ddq}, **st})
    assert all(is_zero(sp.expand(x)) for x in at - want)
    md = render(p, sols, "md")
    assert "Forward recursion" in md and "Backward recursion" in md and "coincides" in md
    tex = render(p, sols, "tex")
    assert "\\textbf{Forward recursion}" in tex and "$$" not in tex


def test_needs_dh_robot():
    text = """
id: t
title: explicit
symbols: {m1: m1}
robot:
  joints: [R]
  links: [{mass: m1, com: [cos(q1), sin(q1)], angle: q1}]
asks: [{kind: newton_euler}]
"""
    with pytest.raises(UserError, match="dh"):
        solve_problem(load_problem_text(text))


def test_wrong_frames_detected():
    """A test that can fail: NE with one mass changed differs from the model."""
    p = load_problem_text(SPATIAL.replace("{conv}", "standard"))
    robot = p.robot
    dm = derive(robot)
    robot.bodies[2].mass = robot.bodies[2].mass * 2
    res = newton_euler(robot, robot.dq, robot.ddq)
    assert not all(is_zero(sp.expand(x)) for x in res.u - dm.lhs)


@pytest.mark.parametrize("old, new, words", [
    ("    routines: [gravity, coriolis, static, inertia, kinetic_energy]\n",
     "    calls: [{name: y, dq: [dq1, dq2], ddq: 0}]\n", "dq must be a list of 3 expressions or 0"),
    ("    routines: [gravity, coriolis, static, inertia, kinetic_energy]\n",
     "    calls: [{name: y, dq: 0, ddq: [1, 0, q4]}]\n", "unknown name 'q4'"),
    ("    routines: [gravity, coriolis, static, inertia, kinetic_energy]\n", "    at: {q1: 0, dq7: 1}\n",
     "'dq7' in at: is not a coordinate"),
])
def test_check_finds_bad_calls_and_states_without_solving(old, new, words):
    """The calls' arguments and the state are read by the kind's validate hook (`check`): solving's error,
    without the recursions."""
    text = SPATIAL.replace("{conv}", "standard").replace(old, new)
    assert words in error_found_without_solving(text)


# --- a planar 2R in modified DH with friction or a spring (no exercise uses it) -------------------------------------

MOD2R = """
id: mod2r
title: planar 2R in modified DH frames
symbols: {l1: l1, d1: d1, d2: d2, m1: m1, m2: m2, I1: I1, I2: I2, g0: g0, fv1: fv1, fv2: fv2, k: k}
robot:
  joints: [R, R]
  gravity: [0, -g0, 0]
  dh:
    convention: modified
    table:
      - {a: 0, alpha: 0, d: 0, theta: q1}
      - {a: l1, alpha: 0, d: 0, theta: q2}
    links:
      - {mass: m1, com: [d1, 0, 0], inertia: I1}
      - {mass: m2, com: [d2, 0, 0], inertia: I2}
EXTRA
asks:
  - kind: newton_euler
    routines: [gravity, coriolis, static, inertia, kinetic_energy]
"""


def _hand_2r():
    """B, c, g of the planar 2R (CoM of link i at d_i from joint i on the link, gravity along −y), written by hand."""
    l1, d1, d2, m1, m2, I1, I2, g0 = sp.symbols("l1 d1 d2 m1 m2 I1 I2 g0")
    q1, q2, dq1, dq2 = sp.symbols("q1 q2 dq1 dq2")
    b12 = I2 + m2 * (d2 ** 2 + l1 * d2 * sp.cos(q2))
    B = sp.Matrix([[I1 + m1 * d1 ** 2 + I2 + m2 * (l1 ** 2 + d2 ** 2 + 2 * l1 * d2 * sp.cos(q2)), b12],
                   [b12, I2 + m2 * d2 ** 2]])
    h = m2 * l1 * d2 * sp.sin(q2)
    c = sp.Matrix([-h * (2 * dq1 * dq2 + dq2 ** 2), h * dq1 ** 2])
    g = sp.Matrix([(m1 * d1 + m2 * l1) * g0 * sp.cos(q1) + m2 * d2 * g0 * sp.cos(q1 + q2),
                   m2 * d2 * g0 * sp.cos(q1 + q2)])
    return B, c, g


def _plain(m):
    return sp.sympify(m).xreplace({x: sp.Symbol(x.name) for x in sp.sympify(m).free_symbols})


def _equal(a, b) -> bool:
    return all(sp.simplify(x) == 0 for x in sp.Matrix(_plain(a)) - sp.Matrix(b))


def test_modified_dh_2r_with_friction_report_and_ne_c_label():
    """Modified DH: u = NE(q, q̇, q̈) equals the hand-written B q̈ + c + g + F_v q̇, and the report writes the
    modified recursion (ω_i = ⁱR_{i−1}ω_{i−1} + q̇_i ẑ_i, a_i = ⁱR_{i−1}(a_{i−1} + ω̇_{i−1} × P_i + ...), moments about
    O_i) instead of the standard one; ne_c = NE₀(q, q̇, 0) carries the friction and is labelled c + F_v q̇ (it said
    c)."""
    p = load_problem_text(MOD2R.replace("EXTRA", "  friction: {viscous: [fv1, fv2]}"))
    sols = solve_problem(p)
    r = all_results(sols)
    B, c, g = _hand_2r()
    ddq, dq = sp.Matrix(sp.symbols("ddq1 ddq2")), sp.Matrix(sp.symbols("dq1 dq2"))
    Fv = sp.diag(*sp.symbols("fv1 fv2"))
    assert r["ne_equals_lagrange"].value is True
    assert _equal(r["ne_u"].value, B * ddq + c + g + Fv * dq)
    assert _equal(r["ne_c"].value, c + Fv * dq)
    assert _equal(r["ne_B"].value, B) and _equal(r["ne_g"].value, g)
    assert r["ne_c"].label == "c(q,\\dot q) + F_v\\dot q"
    for text in (render(p, sols, "md"), render(p, sols, "tex", fragment=True)):
        assert "c(q,\\dot q) + F_v\\dot q = NE_0(q, \\dot q, 0) =" in text
        assert "\\omega_i = {}^{i}R_{i-1}\\,\\omega_{i-1} + \\sigma_i \\dot q_i \\hat z_i" in text
        assert ("a_i = {}^{i}R_{i-1}\\left(a_{i-1} + \\dot\\omega_{i-1} \\times {}^{i-1}P_i + \\omega_{i-1} \\times "
                "(\\omega_{i-1} \\times {}^{i-1}P_i)\\right)") in text
        assert "{}^{i}P_{i+1} \\times ({}^{i}R_{i+1} f_{i+1}) + r_{i,ci} \\times m_i a_{ci}" in text
        assert "r_{i-1,i}" not in text and "{}^{i-1}R_i^T a_{i-1}" not in text   # no standard-DH formula
        assert "g(q) + F_v\\dot q$ derived independently" in text
    # the standard robot keeps its text and its label c
    std = load_problem_text(MOD2R.replace("EXTRA", "").replace("convention: modified", "convention: standard")
                            .replace("- {a: 0, alpha: 0, d: 0, theta: q1}", "- {a: l1, alpha: 0, d: 0, theta: q1}")
                            .replace("- {a: l1, alpha: 0, d: 0, theta: q2}", "- {a: l2, alpha: 0, d: 0, theta: q2}")
                            .replace("[d1, 0, 0]", "[d1 - l1, 0, 0]").replace("[d2, 0, 0]", "[d2 - l2, 0, 0]")
                            .replace("k: k}", "k: k, l2: l2}"))
    s2 = solve_problem(std)
    r2 = all_results(s2)
    assert r2["ne_equals_lagrange"].value is True and _equal(r2["ne_c"].value, c)
    assert r2["ne_c"].label == "c(q,\\dot q)"
    md = render(std, s2, "md")
    assert "{}^{i-1}R_i^T a_{i-1} + \\dot\\omega_i \\times r_{i-1,i}" in md and "{}^{i}P_{i+1}" not in md


def test_ne0_routines_leave_out_springs():
    """A spring ½ k q2² is part of g(q) but not of c, B or T: NE₀ leaves out all of g(q), so ne_c = c, ne_B = B and
    ne_T = T (they carried k q2, and the check said "differs"); ne_g and ne_static keep it."""
    p = load_problem_text(MOD2R.replace("EXTRA", '  extra: {potential: ["1/2*k*q2^2"]}'))
    sols = solve_problem(p)
    r = all_results(sols)
    B, c, g = _hand_2r()
    k, q2 = sp.symbols("k q2")
    gk = g + sp.Matrix([0, k * q2])
    dq, ddq = sp.Matrix(sp.symbols("dq1 dq2")), sp.Matrix(sp.symbols("ddq1 ddq2"))
    assert r["ne_equals_lagrange"].value is True
    assert _equal(r["ne_c"].value, c) and _equal(r["ne_B"].value, B)
    assert sp.simplify(_plain(r["ne_T"].value) - (dq.T * B * dq)[0] / 2) == 0
    assert _equal(r["ne_g"].value, gk) and _equal(r["ne_static"].value, B * ddq + gk)
    assert _equal(r["ne_u"].value, B * ddq + c + gk)
    assert "without all of $g(q)$" in render(p, sols, "md")
