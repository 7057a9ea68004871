"""Symbolic Newton–Euler in the canonical trigonometric-polynomial form, on a spatial arm no exercise uses (four
joints, a π/2 offset, generic centres of mass, one non-diagonal inertia): it takes the canonical path (no
step-by-step tidy), equals the Lagrangian model exactly and at random points, equals an independent numeric
Newton–Euler, and its ω_i are the bodies' angular velocities; the large-recursion report defines each
parameter grouping once."""
import math
import random

import numpy as np
import pytest
import sympy as sp
from test_dynamics_canonical import rne

import solver.dynamics.newton_euler as ne
from solver.dynamics.model import derive
from solver.spec import load_problem_text

ARM = """
id: t4
title: spatial 4R, generic centres of mass
symbols: {a1: a1, a2: a2, d1: d1, d3: d3, d4: d4, g0: g0, m1: m1, m2: m2, m3: m3, m4: m4,
          r1x: r1x, r1y: r1y, r1z: r1z, r2x: r2x, r2y: r2y, r2z: r2z, r3x: r3x, r3y: r3y, r3z: r3z,
          r4x: r4x, r4y: r4y, r4z: r4z, I1x: I1x, I1y: I1y, I1z: I1z, I2x: I2x, I2y: I2y, I2z: I2z,
          I3x: I3x, I3y: I3y, I3z: I3z, I4x: I4x, I4y: I4y, I4z: I4z, I4xy: I4xy}
robot:
  joints: [R, R, R, R]
  gravity: [0, 0, -g0]
  dh:
    table:
      - {a: a1, alpha: pi/2, d: d1, theta: q1}
      - {a: a2, alpha: 0, d: 0, theta: q2 + pi/2}
      - {a: 0, alpha: -pi/2, d: d3, theta: q3}
      - {a: 0, alpha: pi/2, d: d4, theta: q4}
    links:
      - {mass: m1, com: [r1x, r1y, r1z], inertia: [I1x, I1y, I1z]}
      - {mass: m2, com: [r2x, r2y, r2z], inertia: [I2x, I2y, I2z]}
      - {mass: m3, com: [r3x, r3y, r3z], inertia: [I3x, I3y, I3z]}
      - {mass: m4, com: [r4x, r4y, r4z], inertia: [[I4x, I4xy, 0], [I4xy, I4y, 0], [0, 0, I4z]]}
asks:
  - kind: newton_euler
    check: false
"""
ROWS = [("a1", math.pi / 2, "d1", 0.0), ("a2", 0.0, "0", math.pi / 2), ("0", -math.pi / 2, "d3", 0.0),
        ("0", math.pi / 2, "d4", 0.0)]


@pytest.fixture(scope="module")
def arm():
    problem = load_problem_text(ARM)
    robot = problem.robot
    return problem, robot, ne.newton_euler(robot, robot.dq, robot.ddq), derive(robot)


def test_takes_the_canonical_path(arm, monkeypatch):
    """No step-by-step simplification: NE runs with tidy unavailable and gives the same u."""
    problem, robot, res, _ = arm

    def boom(*_):  # pragma: no cover - reached only on the general path
        raise AssertionError("step-by-step tidy called")

    monkeypatch.setattr(ne, "tidy", boom)
    monkeypatch.setattr(ne, "tidy_matrix", boom)
    again = ne.newton_euler(robot, robot.dq, robot.ddq)
    assert again.u == res.u
    assert ne._canonical(robot, robot.dq, robot.ddq, True, None, False, True) is not None


def test_equals_lagrange_exactly_and_at_random_points(arm):
    problem, robot, res, dm = arm
    assert ne.same_function(res.u, dm.lhs)
    params = sorted((res.u.free_symbols | dm.lhs.free_symbols) - set(robot.q + robot.dq + robot.ddq),
                    key=lambda s: s.name)
    args = robot.q + robot.dq + robot.ddq + params
    f_ne, f_lag = sp.lambdify(args, list(res.u), "math"), sp.lambdify(args, list(dm.lhs), "math")
    rng = random.Random(7)
    for _ in range(5):
        x = [rng.uniform(-3, 3) for _ in range(12)] + [rng.uniform(0.5, 1.5) for _ in params]
        a, b = np.array(f_ne(*x)), np.array(f_lag(*x))
        assert np.allclose(a, b, rtol=1e-10, atol=1e-10)
        assert np.linalg.norm(a) > 1e-3  # a real comparison, not 0 = 0


def test_equals_numeric_newton_euler(arm):
    """Against an independent numeric recursion (tests/test_dynamics_canonical.rne) at random points."""
    problem, robot, res, _ = arm
    names = problem.names
    rng = random.Random(11)
    f = sp.lambdify(robot.q + robot.dq + robot.ddq + sorted(res.u.free_symbols - set(robot.q + robot.dq + robot.ddq),
                                                            key=lambda s: s.name), list(res.u), "math")
    params = sorted(res.u.free_symbols - set(robot.q + robot.dq + robot.ddq), key=lambda s: s.name)
    for _ in range(3):
        val = {name: rng.uniform(0.5, 1.5) for name in names}  # d1 does not enter u: every symbol gets a value
        val["0"] = 0.0
        q, dq, ddq = ([rng.uniform(-3, 3) for _ in range(4)] for _ in range(3))
        rows = [(val[a], al, val[d], th) for a, al, d, th in ROWS]
        links = []
        for i in range(1, 5):
            inertia = np.diag([val[f"I{i}x"], val[f"I{i}y"], val[f"I{i}z"]])
            if i == 4:
                inertia[0, 1] = inertia[1, 0] = val["I4xy"]
            links.append((val[f"m{i}"], np.array([val[f"r{i}{c}"] for c in "xyz"]), inertia))
        want = rne(rows, links, [0, 0, -val["g0"]], q, dq, ddq)
        got = np.array(f(*q, *dq, *ddq, *[val[s.name] for s in params]))
        assert np.allclose(got, want, rtol=1e-10, atol=1e-10), (got, want)


def test_link_angular_velocities_are_the_bodies(arm):
    """ω_i of the forward recursion (frame i) equals the body's ω used by the Lagrangian model (frame i)."""
    _, robot, res, _ = arm
    for s, body in zip(res.links, robot.bodies):
        assert ne.same_function(s.w, body.omega)
    assert any(ne.same_function(s.dw, sp.zeros(3, 1)) is False for s in res.links)


def test_large_recursion_report_defines_groupings_once(arm, monkeypatch):
    """Past LARGE_MODEL nodes the report writes every quantity with K_j (each sum of parameters once) and says so;
    substituting the K_j back gives the full expressions."""
    from solver.publish.render import render
    from solver.solve import solve_problem
    problem, robot, _, _ = arm
    monkeypatch.setattr(ne, "LARGE_MODEL", 200)
    sols = solve_problem(problem)
    data = next(st.data for st in sols[0].steps if st.name == "model")
    abbr, res = data["abbr"], data["res"]
    assert abbr is not None and abbr["defs"]
    defs = dict(abbr["defs"])
    assert len(set(defs.values())) == len(defs)
    assert all(not (e.free_symbols & set(robot.q)) for e in defs.values())
    assert (abbr["u"].xreplace(defs) - res.u).applyfunc(sp.expand) == sp.zeros(4, 1)
    assert (abbr["links"][0].tau.xreplace(defs) - res.links[0].tau).applyfunc(sp.expand) == sp.zeros(3, 1)
    md = render(problem, sols, "md")
    assert "This computation is large" in md and "Parameter groupings" in md and "K_{1}" in md
    tex = render(problem, sols, "tex")
    assert "Parameter groupings" in tex and "$$" not in tex


def test_data_outside_the_algebra_take_the_step_by_step_path():
    """A float mass and a parameter in a denominator (the arm's first two joints): the canonical path declines, NE
    still equals Lagrange."""
    lines = ARM.replace("joints: [R, R, R, R]", "joints: [R, R]").splitlines()
    text = "\n".join(x for x in lines if not any(f"{k}: d{j}" in x or f"mass: m{j}" in x
                                                  for j in (3, 4) for k in ("d",)))
    text = text.replace("{mass: m1,", "{mass: 0.5,").replace("com: [r2x, r2y, r2z]", "com: [r2x/a1, r2y, r2z]")
    robot = load_problem_text(text).robot
    assert robot.n == 2
    assert ne._canonical(robot, robot.dq, robot.ddq, True, None, False, True) is None
    res = ne.newton_euler(robot, robot.dq, robot.ddq)
    assert ne.same_function(res.u, derive(robot).lhs)
