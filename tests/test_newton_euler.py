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
