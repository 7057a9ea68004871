"""The `trajectory` ask: boundary conditions met exactly, spline continuity, trapezoidal and cycloidal profiles,
maxima against dense sampling, Cartesian paths (arc length, axis-angle, angular velocity by finite differences),
the joint motion through a robot's kinematics, bad input at the spec line, and the reports."""
import random

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, error_found_without_solving

from solver.planning import laws
from solver.planning.laws import Cond, piecewise_polynomial, rest_defaults
from solver.planning.paths import axis_angle, rot_axis_angle
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem

t = sp.Symbol("t", real=True)


def solve_text(text: str) -> dict:
    return all_results(solve_problem(load_problem_text(text)))


def spec(body: str, symbols: str = "{}", values: str = "{}", robot: str = "") -> str:
    return (f"id: t\ntitle: t\nsymbols: {symbols}\nvalues: {values}\n{robot}asks:\n  - kind: trajectory\n"
            + "".join(f"    {line}\n" for line in body.strip().splitlines()))


def error_line(text: str) -> tuple[str, int]:
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem_text(text))
    return exc.value.message, exc.value.place.line if exc.value.place else 0


def line_of(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


# ------------------------------------------------------------------------------------------------ polynomials
@pytest.mark.parametrize("seed", range(6))
def test_polynomial_meets_random_boundary_conditions_exactly(seed):
    """Random exact conditions on q, q̇, q̈ at 0, T and one inner instant: every one holds exactly."""
    rng = random.Random(seed)
    T = sp.Rational(rng.randint(2, 9), rng.randint(1, 3))
    conds = [Cond(sp.Integer(0), k, sp.Rational(rng.randint(-9, 9), rng.randint(1, 5))) for k in range(3)]
    conds += [Cond(T, k, sp.Rational(rng.randint(-9, 9), rng.randint(1, 5))) for k in range(3)]
    conds.append(Cond(T / 3, 0, sp.Rational(rng.randint(-9, 9), 7)))
    law = piecewise_polynomial(t, [sp.Integer(0), T], 6, 0, conds)
    for c in conds:
        assert sp.diff(law.pieces[0], t, c.order).subs(t, c.time) == c.value


def test_symbolic_quintic_rest_to_rest():
    """Rest-to-rest quintic from the spec: q(T) = q_f, zero velocity and acceleration at both ends, exactly."""
    r = solve_text(spec("law: quintic\nT: T\ninitial: {q: qi}\nfinal: {q: qf}\nat: [0, T/2, T]",
                        symbols="{T: T, qi: {meaning: qi, sign: real}, qf: {meaning: qf, sign: real}}"))
    T, qi, qf = sp.symbols("T", positive=True), sp.Symbol("qi", real=True), sp.Symbol("qf", real=True)
    assert sp.simplify(r["q_at1"].value - qi) == 0 and sp.simplify(r["q_at3"].value - qf) == 0
    assert r["dq_at1"].value == 0 and r["dq_at3"].value == 0 and r["ddq_at1"].value == 0 and r["ddq_at3"].value == 0
    assert sp.simplify(r["q_at2"].value - (qi + qf) / 2) == 0
    # the textbook maxima: 15Δ/(8T) at T/2 and 10Δ/(√3 T²)
    assert sp.simplify(r["max_dq"].value - 15 * sp.Abs(qf - qi) / (8 * T)) == 0
    assert sp.simplify(r["max_ddq"].value - 10 * sp.sqrt(3) * sp.Abs(qf - qi) / (3 * T ** 2)) == 0


def test_cubic_with_initial_velocity_and_vectors():
    """A vector cubic (two joints) with initial velocities, stopping with zero velocity and acceleration."""
    r = solve_text(spec("law: cubic\nT: 2\ninitial: {q: [1, -1], dq: [3/2, 0]}\nfinal: {dq: 0, ddq: 0}\n"
                        "at: [0, 2]"))
    assert r["q_at1"].value == sp.Matrix([1, -1]) and r["dq_at1"].value == sp.Matrix([sp.Rational(3, 2), 0])
    assert r["dq_at2"].value == sp.zeros(2, 1) and r["ddq_at2"].value == sp.zeros(2, 1)
    assert r["q_at2"].value == sp.Matrix([2, -1])  # q0 + T dq0/3


def test_rest_defaults_fill_lowest_orders_first():
    conds = rest_defaults([Cond(0, 0, 1), Cond(2, 0, 3)], sp.Integer(0), sp.Integer(2), 6)
    assert [(c.time, c.order) for c in conds[2:]] == [(0, 1), (2, 1), (0, 2), (2, 2)]


# ------------------------------------------------------------------------------------------------ splines
def test_cubic_spline_is_c2_and_interpolates():
    text = spec("law: spline\nT: 5\ninitial: {q: 0}\nfinal: {q: 1}\n"
                "via: [{t: 1, q: 2}, {t: 2.5, q: -1}, {t: 4, q: 3/2}]")
    sol = solve_problem(load_problem_text(text))[0]
    law = sol.steps[0].data["motion"].laws[0]
    knots = [0, 1, sp.Rational(5, 2), 4, 5]
    values = [0, 2, -1, sp.Rational(3, 2), 1]
    for k, p in enumerate(law.pieces):  # interpolation at both ends of every piece
        assert p.subs(t, knots[k]) == values[k] and p.subs(t, knots[k + 1]) == values[k + 1]
    for k in range(1, 4):  # continuity of q, q̇, q̈ at the inner knots
        for order in range(3):
            assert law.diff(order).jump(k) == 0 if order else law.jump(k) == 0
    assert law.diff(3).jump(1) != 0  # a cubic spline is not C³ in general
    assert sp.diff(law.pieces[0], t).subs(t, 0) == 0 and sp.diff(law.pieces[-1], t).subs(t, 5) == 0


def test_c1_spline_with_given_velocities():
    text = spec("law: spline\nT: 3\ncontinuity: 1\ninitial: {q: 0, dq: 1}\nfinal: {q: 2, dq: 0}\n"
                "via: [{t: 1, q: 1, dq: 1/2}, {t: 2, q: 3, dq: -1}]")
    law = solve_problem(load_problem_text(text))[0].steps[0].data["motion"].laws[0]
    d = law.diff(1)
    assert [d.at(x) for x in (0, 1, 2, 3)] == [1, sp.Rational(1, 2), -1, 0]
    assert all(law.jump(k) == 0 and d.jump(k) == 0 for k in (1, 2))


# ------------------------------------------------------------------------------------------------ profiles
def test_trapezoidal_relations_and_continuity():
    r = solve_text(spec("law: trapezoidal\nT: 4\nTs: 1\ninitial: {q: 0}\nfinal: {q: 6}\nat: [0, 1, 2, 4]"))
    assert r["A"].value == 2 and r["V"].value == 2 and r["Ts"].value == 1  # A = Δ/(Ts(T − Ts)), V = A Ts
    assert r["q_at1"].value == 0 and r["q_at4"].value == 6 and r["dq_at4"].value == 0
    assert r["q_at2"].value == 1 and r["dq_at3"].value == 2
    law = solve_problem(load_problem_text(spec("law: trapezoidal\nT: 4\nV: 2\ninitial: {q: 0}\nfinal: {q: 6}")))[0] \
        .steps[0].data["motion"].laws[0]
    assert all(law.jump(k) == 0 and law.diff(1).jump(k) == 0 for k in (1, 2))


def test_trapezoid_from_bounds_is_minimum_time():
    """V and A without T: T = Δ/V + V/A when the cruise speed is reached, else 2 sqrt(Δ/A); no faster law within
    the bounds exists (a bang-bang at the bound is the fastest)."""
    r = solve_text(spec("law: trapezoidal\nV: 2\nA: 4\ninitial: {q: 1}\nfinal: {q: 4}"))
    assert r["T"].value == sp.Rational(3, 2) + sp.Rational(1, 2)
    r = solve_text(spec("law: trapezoidal\nV: 10\nA: 4\ninitial: {q: 1}\nfinal: {q: 4}"))
    assert r["T"].value == 2 * sp.sqrt(sp.Rational(3, 4))
    assert r["max_dq"].value <= 10 and r["max_ddq"].value == 4


def test_coordinated_trapezoids_end_together_within_bounds():
    r = solve_text(spec("law: trapezoidal\nV: [1, 2]\nA: [2, 2]\ninitial: {q: [0, 0]}\nfinal: {q: [3, 1]}\nat: T"))
    assert r["T"].value == 3 + sp.Rational(1, 2)  # joint 1 is the slowest
    assert r["q_at"].value == sp.Matrix([3, 1]) and r["dq_at"].value == sp.zeros(2, 1)
    vmax, amax = r["max_dq"].value, r["max_ddq"].value
    assert vmax[0] == 1 and vmax[1] <= 2 and amax[0] == 2 and amax[1] == 2


def test_cycloidal_acceleration_vanishes_at_the_ends():
    r = solve_text(spec("law: cycloidal\nT: 2\ninitial: {q: 0}\nfinal: {q: 1}\nat: [0, 2]"))
    assert r["ddq_at1"].value == 0 and r["ddq_at2"].value == 0 and r["dq_at2"].value == 0
    assert sp.simplify(r["max_ddq"].value - sp.pi / 2) == 0 and r["t_max_ddq"].value == sp.Rational(1, 2)


@pytest.mark.parametrize("law", ["cubic", "quintic", "cycloidal", "harmonic", "bang_bang"])
def test_maxima_agree_with_dense_sampling(law):
    text = spec(f"law: {law}\nT: 1.7\ninitial: {{q: -0.4}}\nfinal: {{q: 1.3}}")
    sol = solve_problem(load_problem_text(text))[0]
    r = sol.results
    law_ = sol.steps[0].data["motion"].laws[0]
    grid = np.linspace(0, 1.7, 20001)
    for k in (1, 2):
        fns, _ = law_.diff(k).numeric_pieces({})
        best = max(np.max(np.abs(fn(grid[(grid >= float(a)) & (grid <= float(b))])))
                   for fn, a, b in zip(fns, law_.breaks, law_.breaks[1:]))
        assert float(r[f"max_{'d' * k}q"].value) == pytest.approx(best, rel=1e-6)


def test_linear_root_at_an_end_is_no_interior_root_as_the_general_search_finds():
    """A derivative linear in t with radicals in its coefficients, zero at an end: no root inside, decided without
    simplifying it in σ; the general search (simplify in σ, solve) finds the same root σ = 1, and a root inside
    still goes the general way."""
    m, k = sp.symbols("m k", positive=True)
    b = sp.sqrt(k) * m
    f1 = (t - b) * sp.sqrt(m) / (m + k)
    assert laws._linear_root_at_end(f1, t, 0, b) and laws._linear_root_at_end(f1, t, b, 3 * b)
    assert laws._interior_roots(f1, t, 0, b) == [] and laws._interior_roots(f1, t, b, 3 * b) == []
    s = sp.Symbol("s", real=True)
    assert sp.solve(sp.simplify(f1.subs(t, b * s)), s) == [1]
    assert not laws._linear_root_at_end(f1, t, 0, 2 * b) and not laws._linear_root_at_end(t ** 2 - b ** 2, t, 0, b)
    assert sp.simplify(laws._interior_roots(f1, t, 0, 2 * b)[0] - b) == 0


def test_less_decides_as_on_the_simplified_difference():
    """a < b from the assumptions on b − a as written, else simplified: the same answers as simplify first."""
    T, m, k = sp.symbols("T m k", positive=True)
    x = sp.Symbol("x", real=True)
    pairs = [(T / 4, T), (T, T), (sp.sqrt(k) * m, sp.sqrt(k) * (m + T)), ((T + m) ** 2, T ** 2 + 2 * T * m + m ** 2),
             (x, T), (-m, sp.pi / 3)]

    def general(a, b):
        d = sp.simplify(b - a)
        return True if d.is_positive else False if d.is_nonpositive else None
    assert [laws.less(a, b) for a, b in pairs] == [general(a, b) for a, b in pairs] == \
        [True, False, True, False, None, True]


def test_assume_positive_is_memoized_for_exact_expressions():
    """|x| → x with the listed positives: a result refined again (when reported) is not refined twice; floats
    are not memoized (equal at different precisions)."""
    from solver.planning import trajectory
    R, d, m = sp.symbols("R d m", positive=True)
    e = sp.Abs(m * (R - d)) / sp.sqrt(m)
    r = trajectory.assume_positive(e, [R - d])
    assert r == sp.sqrt(m) * (R - d)
    hits = trajectory._assume_positive.cache_info().hits
    assert trajectory.assume_positive(e, [R - d]) is r and trajectory._assume_positive.cache_info().hits == hits + 1
    assert trajectory.assume_positive(sp.Float(0.5) * e, [R - d]) == sp.Float(0.5) * r
    assert trajectory._assume_positive.cache_info().hits == hits + 1


def test_expression_law_derivatives():
    r = solve_text(spec("law: expression\nq: a*sin(w*t)^2\nT: 1", symbols="{a: a, w: w}"))
    a, w = sp.symbols("a w", positive=True)
    assert sp.simplify(r["dq_t"].value - 2 * a * w * sp.sin(w * t) * sp.cos(w * t)) == 0


# ------------------------------------------------------------------------------------------------ paths
def test_arc_is_on_the_circle_and_parametrized_by_length():
    r = solve_text(spec("path: {type: arc, center: [1, 2], radius: 0.5, phase: pi/4, angle: -2*pi/3}\n"
                        "law: cubic\nT: 1\nat: [0, 1/3, 1]", symbols="{s: {meaning: s, sign: nonnegative}}"))
    s = sp.Symbol("s", nonnegative=True)
    p = r["p_s"].value
    for sv in (0, sp.Rational(3, 10), 1):  # on the circle, at unit speed in s
        assert abs(sp.N(((p - sp.Matrix([1, 2])).norm() ** 2).subs(s, sv) - sp.Rational(1, 4), 30)) < 1e-25
        assert abs(sp.N((p.diff(s).norm() ** 2).subs(s, sv) - 1, 30)) < 1e-25
    assert r["L"].value == sp.pi / 3
    assert sp.simplify(r["p_at1"].value - sp.Matrix([1 + sp.sqrt(2) / 4, 2 + sp.sqrt(2) / 4])) == sp.zeros(2, 1)
    assert r["v_at3"].value == sp.zeros(2, 1)
    # the end point: phase − 2π/3 (clockwise)
    end = sp.Matrix([1 + sp.cos(sp.pi / 4 - 2 * sp.pi / 3) / 2, 2 + sp.sin(sp.pi / 4 - 2 * sp.pi / 3) / 2])
    assert sp.simplify(r["p_at3"].value - end) == sp.zeros(2, 1)


@pytest.mark.parametrize("seed", range(4))
def test_axis_angle_inverse_problem(seed):
    rng = np.random.default_rng(seed)
    r = sp.Matrix(rng.integers(-3, 4, 3).tolist())
    if r.norm() == 0:
        r = sp.Matrix([1, 2, 2])
    r = r / r.norm()
    th = sp.pi * sp.Rational(int(rng.integers(1, 11)), 12)
    R = rot_axis_angle(r, th).applyfunc(sp.simplify)
    aa = axis_angle(R)
    assert sp.simplify(rot_axis_angle(aa.axis, aa.theta) - R) == sp.zeros(3, 3)
    assert sp.simplify(aa.theta - th) == 0


def test_axis_angle_of_a_half_turn():
    R = sp.diag(1, -1, -1)
    aa = axis_angle(R)
    assert aa.theta == sp.pi and aa.case == "pi" and sp.simplify(rot_axis_angle(aa.axis, sp.pi) - R) == sp.zeros(3, 3)


def test_angular_velocity_matches_finite_differences():
    """ω from the axis-angle path equals vee(Ṙ Rᵀ) of R(t) = R_A Rot(r, θ s(t)/L), differentiated numerically."""
    text = spec("path:\n  type: line\n  start: [1, 0, 0]\n  end: [0, 2, 1]\n"
                "  orientation: {start: [[0, -1, 0], [1, 0, 0], [0, 0, 1]], end: [[1, 0, 0], [0, 0, -1], [0, 1, 0]]}\n"
                "law: quintic\nT: 3\nat: 1.1")
    r = solve_text(text)
    R_A = sp.Matrix([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    axis, th, L = r["axis_AB"].value, r["theta_AB"].value, r["L"].value

    def R(tt: float) -> np.ndarray:
        s = float(L) * (10 * (tt / 3) ** 3 - 15 * (tt / 3) ** 4 + 6 * (tt / 3) ** 5)
        return np.array((R_A * rot_axis_angle(axis, th * s / L)).evalf(), dtype=float)

    h = 1e-6
    W = (R(1.1 + h) - R(1.1 - h)) / (2 * h) @ R(1.1).T
    omega = np.array([W[2, 1], W[0, 2], W[1, 0]])
    assert np.allclose(np.array(r["omega_at"].value.evalf(), dtype=float).ravel(), omega, atol=1e-7)
    # the final orientation is reached
    R_end = (R_A * rot_axis_angle(axis, th)).applyfunc(sp.simplify)
    assert R_end == sp.Matrix([[1, 0, 0], [0, 0, -1], [0, 1, 0]])


def test_joint_motion_follows_the_path_on_a_robot_no_exercise_uses():
    """A planar 2R with links 1.2 and 0.7 tracing a segment: f(q(t)) = p(t) to the IK tolerance, and q̇ = J⁻¹ṗ
    agrees with finite differences of q(t)."""
    robot = "robot:\n  joints: [R, R]\n"
    task = "[1.2*cos(q1) + 0.7*cos(q1 + q2), 1.2*sin(q1) + 0.7*sin(q1 + q2)]"
    base = "path: {type: line, start: [1.5, 0.2], end: [0.6, 1.1]}\nlaw: cubic\nT: 2\n" \
           f"task: {task}\nq_start: [0, 1]\n"
    pts = [0.5, 0.5 + 1e-5, 0.5 - 1e-5, 1.4]
    r = solve_text(spec(base + f"at: {pts}", robot=robot))
    q = [np.array(r[f"q_at{k}"].value.evalf(), dtype=float).ravel() for k in range(1, 5)]
    f = lambda q: np.array([1.2 * np.cos(q[0]) + 0.7 * np.cos(q.sum()), 1.2 * np.sin(q[0]) + 0.7 * np.sin(q.sum())])  # noqa: E731
    for k, tt in enumerate(pts):
        s = (3 * (tt / 2) ** 2 - 2 * (tt / 2) ** 3)
        p = np.array([1.5, 0.2]) + s * np.array([-0.9, 0.9])
        assert np.allclose(f(q[k]), p, atol=1e-9)
    dq_fd = (q[1] - q[2]) / 2e-5
    assert np.allclose(np.array(r["dq_at1"].value.evalf(), dtype=float).ravel(), dq_fd, atol=1e-5)


def test_joint_motion_from_the_dh_table_matches_the_task_function():
    """task: dh (a planar RRR, links 0.5, 0.4, 0.3, tracing an arc) gives the same joint motion as the task
    function written out."""
    robot = ("robot:\n  joints: [R, R, R]\n  dh:\n    table: [{a: 0.5, theta: q1}, {a: 0.4, theta: q2}, "
             "{a: 0.3, theta: q3}]\n    links: [{}, {}, {}]\n")
    base = "path: {type: arc, center: [0.6, 0.2], radius: 0.25, phase: 0, angle: pi}\nlaw: quintic\nT: 1\n" \
           "q_start: [0.3, 0.4, 0.2]\nat: [0.5, 1]\n"
    f = "[0.5*cos(q1) + 0.4*cos(q1 + q2) + 0.3*cos(q1 + q2 + q3), 0.5*sin(q1) + 0.4*sin(q1 + q2) + 0.3*sin(q1 + q2 + q3)]"
    r1 = solve_text(spec(base + "task: dh", robot=robot))
    r2 = solve_text(spec(base + f"task: {f}", robot=robot))
    for k in ("q_at1", "dq_at1", "ddq_at2"):
        assert np.allclose(np.array(r1[k].value.evalf(), dtype=float), np.array(r2[k].value.evalf(), dtype=float),
                           atol=1e-8)


# ------------------------------------------------------------------------------------------------ bad input
BAD = [
    ("law: cubic\nT: 1\ninitial: {q: 0, dddq: 1}\nfinal: {q: 1, dddq: 2}", "law:", "dependent"),
    ("law: polynomial\ndegree: 2\nT: 1\ninitial: {q: 0, dq: 0}\nfinal: {q: 1, dq: 0}", "law:",
     "4 conditions for a polynomial of degree 2"),
    ("law: cubic\nT: -2\ninitial: {q: 0}\nfinal: {q: 1}", "T: -2", "positive"),
    ("law: spline\nT: 3\ninitial: {q: 0}\nfinal: {q: 1}\nvia: [{t: 2, q: 1}, {t: 1, q: 0}]", "{t: 1, q: 0}",
     "not after"),
    ("law: spline\nT: 3\ninitial: {q: 0}\nfinal: {q: 1}\nvia: [{t: 4, q: 1}]", "{t: 4", "not before"),
    ("law: trapezoidal\nT: 2\nV: 0.2\ninitial: {q: 0}\nfinal: {q: 1}", "V: 0.2", "no trapezoidal profile"),
    ("law: trapezoidal\nT: 2\nA: -1\ninitial: {q: 0}\nfinal: {q: 1}", "A: -1", "positive"),
    ("law: quintic\nT: 1\ninitial: {q: [0, 1, 2]}\nfinal: {q: [1, 2]}", "final:", "different lengths"),
    ("law: cubic\ninitial: {q: 0}\nfinal: {q: 1}", "law:", "needs its duration"),
    ("path: {type: line, start: [1, 1], end: [1, 1]}\nlaw: cubic\nT: 1", "path:", "coincide"),
    ("path: {type: line, start: [1, 0, 0], end: [0, 1, 0], orientation: {start: [[1, 1, 0], [0, 1, 0], [0, 0, 1]], "
     "end: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}}\nlaw: cubic\nT: 1", "path:", "not a rotation"),
    ("law: cubic\nT: 1\ninitial: {q: 0}\nfinal: {q: 1}\nat: 2", "at: 2", "outside"),
]


@pytest.mark.parametrize("body, where, words", BAD, ids=[b[2] for b in BAD])
def test_bad_input_is_one_user_error_at_its_line(body, where, words):
    text = spec(body)
    msg, line = error_line(text)
    assert words in msg
    assert line == line_of(text, where)



@pytest.mark.parametrize("body, where, words", BAD, ids=[b[2] for b in BAD])
def test_check_finds_the_bad_input_without_solving(body, where, words):
    """The kind's validate hook (`check`) reads the path, the law and the instants as solving does: the same
    error (a line's length is not simplified there: only points that coincide as written are refused)."""
    assert words in error_found_without_solving(spec(body))


# ------------------------------------------------------------------------------------------------ library
@pytest.mark.parametrize("name", ["R1-2009-07-10-ex2", "2022-01-11-ex2", "2018-02-05-ex2"])
def test_library_problems_verify(name):
    rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
    assert rep.ok, [c for c in rep.checks if not c.verdict.ok]


def test_reports_render_in_both_formats():
    p = load_problem(PROBLEMS / "R1-2009-07-10-ex2.yaml")
    sols = solve_problem(p)
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "axis-angle" in md and "\\theta_{AB}" in tex and "\\begin{itemize}" not in tex.split("Cartesian")[1][:50]
    assert "0.9069" in md  # the corrected angular velocity, as a number


def test_motion_figure_legends_name_several_coordinates_only():
    """One coordinate: its axes name it (q, q̇, q̈), no legend repeating it on every panel; several: one labelled
    curve each."""
    one = solve_problem(load_problem(PROBLEMS / "2022-01-11-ex2.yaml"))
    fig = next(f for s in one for f in s.figures if f.name == "law")
    assert [[c.label for c in p.curves] for p in fig.panels] == [[""]] * 3
    assert [p.ylabel for p in fig.panels][0] == "$q$"
    two = solve_problem(load_problem(PROBLEMS / "2019-09-11-ex2.yaml"))
    fig = next(f for s in two for f in s.figures if f.name == "motion")
    assert [[c.label for c in p.curves] for p in fig.panels] == [["$q_{1}$", "$q_{2}$"]] * 3
