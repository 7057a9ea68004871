"""The `time_scaling` ask: inverse dynamics along a motion against an independent numpy model, the uniformly
scaled motion touching a torque bound and never exceeding one, no shorter time feasible (on a grid), minimum time
under velocity/acceleration bounds, time-optimal bang(-coast)-bang motions, peak-torque scaling, bad input at the
spec line, and the encoded exam problems."""
import json

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, error_found_without_solving

from solver.planning.time_scaling import _depends_on, y_exact, y_limit
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem

# A planar RR arm in a vertical plane that no exercise uses: links 0.9 and 0.6 m, masses 4 and 2.5 kg, CoMs at
# 0.4 and 0.25 m, barycentric inertias 0.3 and 0.1, viscous friction on joint 2 (optional).
L1, D1, D2, M1, M2, I1, I2, G0 = 0.9, 0.4, 0.25, 4.0, 2.5, 0.3, 0.1, 9.81
ROBOT = f"""id: t
title: t
robot:
  joints: [R, R]
  gravity: [0, -{G0}]
  links:
    - {{mass: {M1}, com: [{D1}*cos(q1), {D1}*sin(q1)], angle: q1, inertia: {I1}}}
    - mass: {M2}
      com: [{L1}*cos(q1) + {D2}*cos(q1 + q2), {L1}*sin(q1) + {D2}*sin(q1 + q2)]
      angle: q1 + q2
      inertia: {I2}
FRICTION
asks:
"""
MOTION = "{law: quintic, T: 1.2, initial: {q: [-0.5, 0.3]}, final: {q: [1.4, -0.9]}}"
QI, QF, T0 = np.array([-0.5, 0.3]), np.array([1.4, -0.9]), 1.2


def robot(friction: float = 0.0) -> str:
    return ROBOT.replace("FRICTION", f"  friction: {{viscous: [0, {friction}]}}" if friction else "")


def ask(**opts: str) -> str:
    return "  - kind: time_scaling\n" + "".join(f"    {k}: {v}\n" for k, v in opts.items())


def solve_text(text: str) -> dict:
    return all_results(solve_problem(load_problem_text(text)))


def quintic(t: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    s = t / T
    sig, dsig, ddsig = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5, (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T, \
        (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2
    D = QF - QI
    return QI + np.outer(sig, D), np.outer(dsig, D), np.outer(ddsig, D)


def torque(q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, fv: float = 0.0) -> np.ndarray:
    """Inverse dynamics of the RR arm, written out independently of robosolve (textbook 2R model)."""
    c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
    a1 = I1 + M1 * D1 ** 2 + I2 + M2 * (L1 ** 2 + D2 ** 2)
    a2, a3 = M2 * L1 * D2, I2 + M2 * D2 ** 2
    b11, b12, b22 = a1 + 2 * a2 * c2, a3 + a2 * c2, a3
    h = a2 * s2
    t1 = b11 * ddq[:, 0] + b12 * ddq[:, 1] - h * (2 * dq[:, 0] * dq[:, 1] + dq[:, 1] ** 2)
    t2 = b12 * ddq[:, 0] + b22 * ddq[:, 1] + h * dq[:, 0] ** 2 + fv * dq[:, 1]
    g1 = (M1 * D1 + M2 * L1) * G0 * np.cos(q[:, 0]) + M2 * D2 * G0 * np.cos(q[:, 0] + q[:, 1])
    g2 = M2 * D2 * G0 * np.cos(q[:, 0] + q[:, 1])
    return np.column_stack([t1 + g1, t2 + g2])


def scaled_peaks(k: float, fv: float = 0.0, n: int = 40001) -> np.ndarray:
    """max_t |τ_i| of the motion q(t/k), by the independent model on a dense grid."""
    t = np.linspace(0, T0, n)
    q, dq, ddq = quintic(t, T0)
    return np.max(np.abs(torque(q, dq / k, ddq / k ** 2, fv)), axis=0)


def test_torque_along_the_motion_matches_an_independent_model():
    r = solve_text(robot() + ask(find="torque", motion=MOTION, at="[0, 0.37, T]"))
    for j, tt in enumerate([0.0, 0.37, T0], 1):
        q, dq, ddq = quintic(np.array([tt]), T0)
        ref = torque(q, dq, ddq)[0]
        assert np.allclose(np.array(r[f"tau_at{j}"].value.evalf(), dtype=float).ravel(), ref, rtol=1e-12)
    peaks = np.array(r["tau_peak"].value.evalf(), dtype=float).ravel()
    assert np.allclose(peaks, scaled_peaks(1.0), rtol=1e-6)


@pytest.mark.parametrize("bounds, friction", [("[60, 12]", 0.0), ("[60, 12]", 3.0), ("[50, 30]", 0.0)])
def test_scaled_motion_touches_a_bound_and_no_faster_one_is_feasible(bounds, friction):
    """With k from robosolve, the torques of q(t/k) (independent model, dense grid) stay within the bounds and
    one of them reaches its bound; every shorter scaling on a grid of k violates some bound."""
    U = np.array(json.loads(bounds), dtype=float)
    r = solve_text(robot(friction) + ask(find="scaling", motion=MOTION, torque_max=bounds))
    k = float(r["k"].value)
    ratio = scaled_peaks(k, friction) / U
    assert ratio.max() <= 1 + 1e-7
    assert ratio.max() >= 1 - 1e-6
    for kk in np.linspace(0.5 * k, k * (1 - 1e-4), 25):
        assert (scaled_peaks(kk, friction, 8001) / U).max() > 1
    kj = np.array(r["k_joint"].value.evalf(), dtype=float).ravel()
    assert k == pytest.approx(kj.max())
    assert float(r["T_scaled"].value) == pytest.approx(k * T0)
    assert r["feasible"].value == bool((scaled_peaks(1.0, friction) <= U * (1 + 1e-9)).all())


def test_y_limit_is_the_largest_feasible_inverse_scaling():
    rng = np.random.default_rng(3)
    for _ in range(200):
        a, f, g = rng.normal(size=3) * [5, 2, 1]
        U = abs(g) + rng.uniform(0.1, 3)
        y = y_limit(a, f, g, U)
        ys = np.linspace(0, min(y, 50), 400)
        assert np.all(np.abs(a * ys ** 2 + f * ys + g) <= U * (1 + 1e-9))
        if np.isfinite(y):
            yy = y * (1 + 1e-6)
            assert abs(a * yy ** 2 + f * yy + g) > U


def test_y_exact_is_the_root_sympy_would_simplify_and_choose():
    """Only the chosen root of a y² + f y + g = ±U is simplified: the same expression as choosing among the roots
    sp.solve simplifies (and filters by the sign of y), on a row no exercise uses."""
    b, u, c = sp.symbols("b u c", positive=True)
    y = sp.Symbol("y", positive=True)
    a, f, g, vals = b, sp.Integer(0), c, {b: 2, u: 5, c: sp.Rational(1, 4)}
    roots = [r for rhs in (u, -u) for r in sp.solve(a * y ** 2 + f * y + g - rhs, y)]
    real = [r for r in roots if abs(complex(r.subs(vals)).imag) < 1e-12 and complex(r.subs(vals)).real > 0]
    assert y_exact(a, f, g, u, vals) == min(real, key=lambda r: complex(r.subs(vals)).real)


def test_dependence_on_the_duration_as_simplify_decides_it():
    """The shape test: q(σT; T) independent of T by the exact test of the derivative (π as a symbol), radicals by
    simplify; each as T left after sp.simplify says, on laws no exercise uses."""
    T, s, a = sp.Symbol("T", positive=True), sp.Symbol("sigma_", positive=True), sp.Symbol("a", positive=True)
    cases = [sp.pi * a - 5 * sp.pi * (T - T * s) ** 3 / (7 * T ** 3), sp.cos(3 * sp.pi * T * s / T) + a * T * s / T,
             sp.pi * (T * s) ** 2 / T, sp.sqrt(a * T ** 2) / T, sp.sqrt(a) * T + 1]
    assert [_depends_on(e, T) for e in cases] == [T in sp.simplify(e).free_symbols for e in cases] \
        == [False, False, True, False, True]


def test_gravity_beyond_the_bound_is_a_user_error():
    text = robot() + ask(find="scaling", motion=MOTION, torque_max="[20, 12]")
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem_text(text))
    assert "no time scaling" in exc.value.message


def test_minimum_time_under_torque_bounds_on_a_grid():
    """A rest-to-rest quintic has the same shape for every T: at T_min the torques reach a bound, and any
    shorter T (grid) exceeds one."""
    motion = "{law: quintic, initial: {q: [-0.5, 0.3]}, final: {q: [1.4, -0.9]}}"
    r = solve_text(robot() + ask(find="minimum_time", motion=motion, torque_max="[60, 12]"))
    Tm = float(r["T_min"].value)
    U = np.array([60.0, 12.0])
    k = Tm / T0
    assert (scaled_peaks(k) / U).max() == pytest.approx(1.0, abs=1e-6)
    for kk in np.linspace(0.6 * k, k * (1 - 1e-4), 20):
        assert (scaled_peaks(kk, 0.0, 8001) / U).max() > 1


def test_minimum_time_under_velocity_and_acceleration_bounds():
    """Cubic rest-to-rest: T = max(3|Δ|/(2V), sqrt(6|Δ|/A)) per joint, all joints ending together."""
    motion = "{law: cubic, T: 3, initial: {q: [0, 1]}, final: {q: [2, -2]}}"
    r = solve_text(robot() + ask(find="minimum_time", motion=motion, vmax="[1, 2]", amax="[3, 3]"))
    T1 = max(3 * 2 / (2 * 1), np.sqrt(6 * 2 / 3))
    T2 = max(3 * 3 / (2 * 2), np.sqrt(6 * 3 / 3))
    assert float(r["T_min"].value) == pytest.approx(max(T1, T2))
    assert float(r["k"].value) == pytest.approx(max(T1, T2) / 3)


def test_minimum_time_trapezoids_from_bounds():
    motion = "{law: trapezoidal, initial: {q: [0, 0]}, final: {q: [2, 0.5]}}"
    r = solve_text(robot() + ask(find="minimum_time", motion=motion, vmax="[1, 1]", amax="[2, 4]"))
    assert r["T_min"].value == sp.Rational(5, 2)  # joint 1: 2/1 + 1/2
    V = r["V"].value
    assert V[0] == 1 and float(V[1]) < 1  # the other joint cruises slower


@pytest.mark.parametrize("D, U, c, expected", [
    ("1", "4", None, 2 * np.sqrt(1 / 2)),                    # bang-bang: T = 2 sqrt(Δ/A), A = U/m = 2
    ("3", "4", "1", 3 / 1 + 1 / 2),                          # coast: V = sqrt(U2/c) = 1 (c = 4): T = Δ/V + V/A
])
def test_time_optimal_double_integrator(D, U, c, expected):
    """A point mass m = 2 on a rail, with (optionally) a second, held joint whose force grows with q̇²:
    the time-optimal rest-to-rest motion against brute force over bang-coast-bang profiles."""
    text = f"""id: t
title: t
robot:
  joints: [P, P]
  model: {{B: "[[2, 0], [0, 1]]", c: "[0, -4*dq1^2]"}}
asks:
  - kind: time_scaling
    find: time_optimal
    moving: q1
    initial: 0
    final: {D}
    hold: {{q2: 0}}
    torque_max: [{U}, {4 if c else 100}]
"""
    r = solve_text(text)
    Tm = float(r["T_min"].value)
    assert Tm == pytest.approx(expected)
    # brute force: trapezoids with A <= 2 and, with the velocity bound, V <= 1
    Vb = 1.0 if c else np.inf
    best = np.inf
    for V in np.linspace(0.01, min(Vb, np.sqrt(float(D) * 2)), 400):
        if V ** 2 / 2 > float(D):
            continue
        best = min(best, float(D) / V + V / 2)
    assert Tm <= best + 1e-9


def test_time_optimal_checks_the_other_rows():
    """A row depending on the configuration is checked along the motion: feasible when its peak is within."""
    text = """id: t
title: t
symbols: {m: m, d: d, J: J, U1: U1, U2: U2}
values: {m: 3, d: 0.4, J: 0.5, U1: 50, U2: 2}
robot:
  joints: [P, R]
  links:
    - {mass: m, com: [q1, 0]}
    - {mass: m, com: [q1 + d*cos(q2), d*sin(q2)], angle: q2, inertia: J}
asks:
  - kind: time_scaling
    find: time_optimal
    moving: q2
    initial: 0
    final: pi/2
    hold: {q1: 0}
    torque_max: [U1, U2]
"""
    r = solve_text(text)
    assert r["feasible"].value is True
    A = 2 / (0.5 + 3 * 0.16)
    assert float(r["T_min_num"].value) == pytest.approx(2 * np.sqrt((np.pi / 2) / A))
    tight = text.replace("U1: 50", "U1: 1")
    assert solve_text(tight)["feasible"].value is False


def test_peaks_formula():
    text = """id: t
title: t
symbols: {U: U, g1: g1}
asks:
  - kind: time_scaling
    find: scaling
    peaks: [{joint: 1, tau: 2*U}]
    torque_max: U
    T: 5
"""
    r = solve_text(text)
    assert r["k"].value == sp.sqrt(2) and r["T_scaled"].value == 5 * sp.sqrt(2)


BAD = [
    (ask(find="scaling", motion=MOTION, torque_max="[60, -1]"), "torque_max", "positive"),
    (ask(find="scaling", motion=MOTION), "find:", "needs torque_max"),
    (ask(find="minimum_time", motion=MOTION, torque_max="[60, 12]", vmax="1"), "torque_max", "not both"),
    (ask(find="time_optimal", moving="q3", initial="0", final="1", torque_max="[1, 1]"), "moving", "not a coordinate"),
    (ask(find="time_optimal", moving="q1", initial="0", final="1", torque_max="[100, 100]", hold="{q2: 0}"),
     "moving", "not an analytic case"),
    (ask(find="scaling", torque_max="[60, 12]", motion="{law: spline, T: 2, initial: {q: [0, 0]}, final: {q: [1, 1]}, "
         "via: [{t: 1.5, q: [1, 0]}, {t: 0.5, q: [0, 1]}]}"), "{t: 0.5", "not after"),
]


@pytest.mark.parametrize("body, where, words", BAD, ids=[b[2] for b in BAD])
def test_bad_input_is_one_user_error_at_its_line(body, where, words):
    text = robot() + body
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem_text(text))
    assert words in exc.value.message
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if where in ln and i > 12)
    assert exc.value.place.line == line



@pytest.mark.parametrize("body, where, words", [b for b in BAD if "find: scaling" in b[0]],
                         ids=[b[2] for b in BAD if "find: scaling" in b[0]])
def test_check_finds_bad_scaling_input_without_solving(body, where, words):
    """`find: scaling` along a motion: the motion and the bounds read by the validate hook (`check`), the same
    error as solving."""
    assert words in error_found_without_solving(robot() + body)


# a point mass on a rail and a held joint (the time-optimal motion is analytic), without dynamics: no robot
RAIL = """id: t
title: t
robot:
  joints: [P, P]
  model: {B: "[[2, 0], [0, 1]]", c: "[0, -4*dq1^2]"}
asks:
"""
NO_ROBOT = "id: t\ntitle: t\nasks:\n"
SQUARE = robot().replace("asks:", "  input_map: [[1], [0]]\nasks:")   # one input for two coordinates
PEAK = "[{joint: 1, tau: 10, q: [0, 0]}]"
OPTIMAL = dict(find="time_optimal", moving="q1", initial="0", final="1", torque_max="[4, 100]", hold="{q2: 0}")

BAD_FIND = [
    (SQUARE + ask(find="torque", motion=MOTION), "torque bounds need a square input map G"),
    (SQUARE + ask(find="scaling", motion=MOTION, torque_max="[60, 12]"), "torque bounds need a square input map G"),
    (robot() + ask(find="scaling", motion=MOTION, torque_max="[60, 12]", at="5"),
     "the instant 5 is outside the motion [0, 6/5]"),
    (robot() + ask(find="scaling", torque_max="[60, 12]", peaks="[{joint: 3, tau: 10, q: [0, 0]}]"),
     "joint 3 does not exist (n = 2)"),
    (robot() + ask(find="scaling", torque_max="[60, 12]", peaks="[{joint: 1, tau: 10}]"),
     "with gravity, a peak needs its configuration q:"),
    (robot() + ask(find="scaling", torque_max="[60, 12]", peaks="[{joint: 1, tau: 10, q: [0]}]"), "q needs 2 values"),
    (robot() + ask(find="scaling", torque_max="[60, 12, 3]", peaks=PEAK), "torque_max needs one bound or a list of 2"),
    (robot() + ask(find="scaling", torque_max="[60, 12]", peaks=PEAK, T="zz"), "unknown name 'zz'"),
    (NO_ROBOT + ask(find="scaling", torque_max="[60, 12, 3]", peaks="[{joint: 2, tau: 10}]"),
     "torque_max needs one bound or a list of 2"),
    (NO_ROBOT + ask(find="minimum_time", motion=MOTION, vmax="1"), "minimum_time needs the robot"),
    (robot() + ask(find="minimum_time", vmax="1"), "find: minimum_time needs motion:"),
    (robot() + ask(find="minimum_time", motion=MOTION, torque_max="[60, 12]", vmax="1"),
     "give kinematic bounds (vmax/amax) or torque bounds, not both"),
    (robot() + ask(find="minimum_time", motion=MOTION), "minimum_time needs bounds: vmax/amax or torque_max"),
    (robot() + ask(find="minimum_time", motion=MOTION, vmax="[1, 2, 3]"), "vmax needs one bound or a list of 2"),
    (robot() + ask(find="minimum_time", motion=MOTION, vmax="1", amax="-2"), "the bounds of amax must be positive"),
    (robot() + ask(find="minimum_time", vmax="1", amax="2",
                   motion="{law: trapezoidal, V: 1, initial: {q: [0, 0]}, final: {q: [1, 1]}}"),
     "the bounds define the trapezoidal law: remove Ts/V/A from it"),
    (robot() + ask(find="minimum_time", vmax="1",
                   motion="{law: quintic, initial: {q: [0, 0, 1]}, final: {q: [1, 1]}}"), "lists of different lengths"),
    (robot() + ask(find="minimum_time", motion=MOTION, torque_max="[60, 12, 3]"),
     "torque_max needs one bound or a list of 2"),
    (robot() + ask(find="minimum_time", torque_max="[60, 12]",
                   motion="{law: trapezoidal, T: 2, V: 1, initial: {q: [0, 0]}, final: {q: [1, 1]}}"),
     "a law whose shape does not change with T"),
    (SQUARE + ask(find="minimum_time", motion=MOTION, torque_max="[60, 12]"), "torque bounds need a square input map"),
    (robot() + ask(find="minimum_time", motion=MOTION, torque_max="[60, 12]", at="zz"), "unknown name 'zz'"),
    (RAIL + ask(**{k: v for k, v in OPTIMAL.items() if k != "initial"}), "find: time_optimal needs initial:"),
    (RAIL + ask(**{**OPTIMAL, "hold": "{q3: 0}"}), "'q3' is not a coordinate held still"),
    (RAIL + ask(**{**OPTIMAL, "hold": "{}"}), "give the values of the coordinates held still: q2"),
    (RAIL + ask(**{**OPTIMAL, "final": "0"}), "the final value equals the initial one"),
    (RAIL + ask(**{**OPTIMAL, "torque_max": "[1, 2, 3]"}), "torque_max needs one bound or a list of 2"),
    (RAIL + ask(**{**OPTIMAL, "at": "[0, -1]"}), "the instant -1 is outside the motion [0, T]"),
]


@pytest.mark.parametrize("text, words", BAD_FIND, ids=[f"{k}-{b[1][:24]}" for k, b in enumerate(BAD_FIND)])
def test_check_reads_every_find_as_solve_does(text, words):
    """Each `find` is read by the `_Job.read_<find>` its solver runs first (the motion, instants, bounds, peaks,
    the moving and held coordinates, a square input map), and the validate hook (`check`) runs it without the
    model: solving's error (each of these passed check and failed solve)."""
    assert words in error_found_without_solving(text)


@pytest.mark.parametrize("name", ["2019-07-11-ex3", "2019-09-11-ex2", "2020-07-15-remote-ex4",
                                  "2020-04-15-remote-midterm-ex9", "2021-04-14-remote-midterm-ex3",
                                  "2009-09-10-ex2", "2021-02-04-ex2", "2018-04-26-midterm-ex2b"])
def test_library_problems_verify(name):
    rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
    assert rep.ok, [(c.name, c.verdict) for c in rep.checks if not c.verdict.ok]


def test_report_of_a_scaling_in_both_formats():
    p = load_problem(PROBLEMS / "2020-04-15-remote-midterm-ex9.yaml")
    sols = solve_problem(p)
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "not feasible" in md and "1.105" in md
    assert "\\paragraph{Uniform time scaling.}" in tex and "\\begin{itemize}" in tex


def test_light_tidying_does_not_spread_a_denominator() -> None:
    """A sum in a denominator (or under a root) is not expanded over the numerator: the time-optimal torque of
    2019-09-11-ex2 once grew from 53 to 4685 operations."""
    from solver.math.opcount import count_ops
    from solver.planning.time_scaling import _light
    t, m, R, d, I, a = sp.symbols("t m_2 R d I_c alpha", positive=True)
    J = I + m * (R - d) ** 2
    x = -m * (R - d) * (2 * t - 2 * (a * m * (R - d) + J) / sp.sqrt(m * (R - d))) ** 2 / (4 * J ** 2)
    y = _light(x)
    assert sp.simplify(y - x) == 0 and count_ops(y) <= count_ops(x)
    p = _light((t + 1) ** 2 * m)  # a polynomial is still expanded, its common factor pulled out
    assert p == m * (t ** 2 + 2 * t + 1)


def test_torques_shown_only_when_each_row_fits_the_page():
    """The time-optimal torques are written only when every row (the piece and its interval's ends) is short:
    2021-02-04-ex2's are; 2019-09-11-ex2's τ₂ pieces are short but their intervals (T* − V/A in the parameters)
    make rows too wide for the page, so its report gives the bounds and the figure instead."""
    from solver.publish.render import render
    from solver.solve import solve_problem
    from solver.spec import load_problem
    for name, shown in (("2021-02-04-ex2", True), ("2019-09-11-ex2", False)):
        p = load_problem(PROBLEMS / f"{name}.yaml")
        text = render(p, solve_problem(p), "tex")
        assert ("The time-optimal torques:" in text) is shown, name


FRICTION_1R = """
id: ts-friction
title: time scaling with viscous friction
symbols:
  m: mass of the link
  d: distance of the center of mass from the joint axis
  I: inertia of the link about the joint axis
  g0: gravity acceleration
  U: maximum absolute motor torque
  fv: viscous friction coefficient
values: {m: 3, d: 0.5, I: 1, g0: 9.81, U: 25, fv: 2}
robot:
  joints: [R]
  coordinates: [theta]
  model: {B: "[[I]]", U: "-m*g0*d*cos(theta)"}
  friction: {viscous: [fv]}
asks:
  - kind: time_scaling
    find: scaling
    motion: {law: bang_bang, T: 1, initial: {q: 0}, final: {q: pi}}
    torque_max: U
"""


def test_uniform_scaling_with_viscous_friction_explains_the_friction_term():
    """With F_v q̇ the scaled torque is a/k² + f/k + g: the report writes that form (not the frictionless one), and
    k solves the quadratic in 1/k at the binding instant: at t = 1/2 of the bang-bang motion a = 4πI, f = 2π f_v,
    g = m g0 d, so 1/k = (−f + √(f² + 4a(U − g)))/(2a), k ≈ 1.874."""
    p = load_problem_text(FRICTION_1R)
    sols = solve_problem(p)
    res = all_results(sols)
    a, f, g, U = 4 * np.pi * 1, 2 * np.pi * 2, 3 * 9.81 * 0.5, 25
    k = 2 * a / (-f + np.sqrt(f * f + 4 * a * (U - g)))
    assert float(res["k"].value.xreplace(p.values)) == pytest.approx(k, rel=1e-9)
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    for text in (md, tex):
        assert "+ \\frac{F_v\\dot q}{k} + g(q)" in text and "friction by $1/k$" in text
        assert "would scale by" not in text
