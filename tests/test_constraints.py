"""The `constrained_dynamics` ask on robots no exercise uses: a planar 3R in a vertical plane (numeric data) with its
tip at a constant height and its last link horizontal (k = 2), or with the height constraint only (k = 1), and a
planar 2R whose tip stays on a circle. Checked properties: A F = 0, D F = I, A E = I exactly; along a constrained
motion simulated with the Lagrange (KKT) system, independently of the formulas, the reduced model reproduces the full
one, λ(q, q̇, u) and λ in reduced form equal the reaction, and the full model driven by λ(q, q̇, u) keeps h(q) = 0
(without it h drifts); the inputs for a desired pseudo-acceleration and for equilibrium do what they say; freezing
coordinates; Pfaffian constraints; the property check of the grader under another complement; spec errors at their
line (exit 2, no traceback); the report in both formats."""
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, check_and_solve
from scipy.integrate import solve_ivp

from solver.dynamics.model import derive
from solver.interaction.constraints import check_equilibrium_inputs, check_reduction, time_derivative
from solver.math.equivalence import scalar_equiv
from solver.publish.render import render
from solver.solve import all_results, solve_problem, validate_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError

R3 = """
id: t3r
title: planar 3R in a vertical plane
robot:
  joints: [R, R, R]
  gravity: [0, -9.81]
  links:
    - {mass: 2, com: [0.5*cos(q1), 0.5*sin(q1)], angle: q1, inertia: 0.2}
    - {mass: 1.5, com: [cos(q1) + 0.4*cos(q1 + q2), sin(q1) + 0.4*sin(q1 + q2)], angle: q1 + q2, inertia: 0.1}
    - mass: 1
      com: [cos(q1) + 0.8*cos(q1 + q2) + 0.25*cos(q1 + q2 + q3), sin(q1) + 0.8*sin(q1 + q2) + 0.25*sin(q1 + q2 + q3)]
      angle: q1 + q2 + q3
      inertia: 0.05
asks:
"""
HEIGHT = "sin(q1) + 0.8*sin(q1 + q2) + 0.5*sin(q1 + q2 + q3) - 0.5"
R3_K2 = R3 + f"""  - kind: constrained_dynamics
    h: [{HEIGHT}, q1 + q2 + q3]
    dv_d: 0.7
    lambda_d: [1.5, -0.5]
"""
R2C = """
id: t2c
title: planar 2R with its tip on a circle
symbols: {r: circle radius}
values: {r: 0.8}
robot:
  joints: [R, R]
  gravity: [0, -9.81]
  links:
    - {mass: 3, com: [0.5*cos(q1), 0.5*sin(q1)], angle: q1, inertia: 0.1}
    - {mass: 2, com: [cos(q1) + 0.5*cos(q1 + q2), sin(q1) + 0.5*sin(q1 + q2)], angle: q1 + q2, inertia: 0.05}
asks:
  - kind: constrained_dynamics
    h: (cos(q1) + cos(q1 + q2) - 1)^2 + (sin(q1) + sin(q1 + q2))^2 - r^2
"""


_SOLVED: dict[str, tuple] = {}


def solved(text):
    """(problem, solutions, results), solved once per spec text (the tests only read them)."""
    if text not in _SOLVED:
        p = load_problem_text(text)
        sols = solve_problem(p)
        _SOLVED[text] = (p, sols, all_results(sols))
    return _SOLVED[text]


def value(res, name):
    v = res[name].value
    return v if isinstance(v, sp.MatrixBase) else sp.Matrix([v])


def zero(e) -> bool:
    return scalar_equiv(e, 0).ok


class Model:
    """Numeric B, n, G of a problem's robot and its constraint (h, A, Ȧq̇), lambdified once."""

    def __init__(self, p, h):
        r = p.robot
        dm = derive(r)
        self.q, self.dq, self.n = list(r.q), list(r.dq), r.n
        vals = p.values
        nvec = (dm.c + dm.g).xreplace(vals)
        A = h.jacobian(r.q)
        args = self.q + self.dq
        self.B = sp.lambdify(args, dm.B.xreplace(vals), "numpy")
        self.nv = sp.lambdify(args, nvec, "numpy")
        self.h = sp.lambdify(args, h.xreplace(vals), "numpy")
        self.A = sp.lambdify(args, A.xreplace(vals), "numpy")
        self.Adq = sp.lambdify(args, (time_derivative(A, r.q, r.dq) * sp.Matrix(r.dq)).xreplace(vals), "numpy")
        self.k = h.rows

    def mats(self, x):
        n, k = self.n, self.k
        return (np.array(self.B(*x), float).reshape(n, n), np.array(self.nv(*x), float).ravel(),
                np.array(self.A(*x), float).reshape(k, n), np.array(self.Adq(*x), float).ravel())

    def kkt(self, x, u):
        """(q̈, λ) of B q̈ + n = u + Aᵀλ, A q̈ + Ȧ q̇ = 0, solved as one linear system (no formula for λ)."""
        B, nv, A, Adq = self.mats(x)
        n, k = self.n, self.k
        K = np.block([[B, -A.T], [A, np.zeros((k, k))]])
        sol = np.linalg.solve(K, np.concatenate([u - nv, -Adq]))
        return sol[:n], sol[n:]


# ------------------------------------------------------------------------------------------------ identities
@pytest.mark.parametrize("text", [R3_K2, R3 + f"  - kind: constrained_dynamics\n    h: {HEIGHT}\n    multiplier: false\n"
                                  "    D: [[1, 0, 0], [0, 1, 1]]\n"], ids=["k2-chosen-D", "k1-given-D"])
def test_complement_blocks_are_the_inverse(text):
    p, _, res = solved(text)
    A, D, E, F = (value(res, x) for x in ("A", "D", "E", "F"))
    k, n = A.shape
    for M, want in ((A * F, sp.zeros(k, n - k)), (D * F, sp.eye(n - k)), (A * E, sp.eye(k)), (D * E, sp.zeros(n - k, k))):
        assert all(zero(x - y) for x, y in zip(M, want))
    assert zero(value(res, "det_AD")[0] - A.col_join(D).det())


def test_chosen_complement_selects_coordinates_with_a_constant_block():
    """With A = [[1, 1, 1], ...] the solver completes A with unit rows, preferring a constant invertible block."""
    p, sols, res = solved(R3_K2)
    D = value(res, "D")
    assert all(sorted(list(D.row(i))) == [0, 0, 1] for i in range(D.rows))
    step = next(s for s in sols[0].steps if s.name == "reduced")
    assert step.data["chosen"] and step.data["free"] == [p.names["q3"]]
    assert value(res, "v")[0] == p.names["dq3"]


# ------------------------------------------------------------------------------------------------ simulation
def start_k2(v0=0.4):
    """A configuration with h(q) = 0 for R3_K2 (q1 + q2 + q3 = 0, height 0.5) and q̇ = F v0."""
    q1 = 0.3
    q2 = np.arcsin((0.5 - np.sin(q1)) / 0.8) - q1
    return np.array([q1, q2, -q1 - q2])


def test_reduced_model_reproduces_the_full_model_along_a_constrained_motion():
    p, _, res = solved(R3_K2)
    h = value(res, "h")
    m = Model(p, h)
    q, dq = m.q, m.dq
    t = sp.Symbol("t")
    u_expr = derive(p.robot).g + sp.Matrix([2 * sp.sin(2 * t), sp.cos(t), 0.5])  # near gravity compensation
    fu = sp.lambdify([t] + q + dq, u_expr, "numpy")
    u = list(p.robot.inputs)
    v = value(res, "v")[0]  # D selects q3: v = q̇3, v̇ = q̈3
    F = value(res, "F")
    vdot = value(res, "vdot")[0]
    lam_red = value(res, "lambda_reduced")
    fF = sp.lambdify(q, F, "numpy")
    fvdot = sp.lambdify(q + [v] + u, vdot, "numpy")
    flam = sp.lambdify(q + [v, p.names["ddq3"]] + u, lam_red, "numpy")
    q0 = start_k2()
    dq0 = np.array(fF(*q0), float).ravel() * 0.4

    def full(tt, x):
        qdd, _ = m.kkt(x, np.array(fu(tt, *x), float).ravel())
        return np.concatenate([x[3:], qdd])

    def reduced(tt, y):  # state (q, v): q̇ = F(q) v, v̇ from the reduced model
        qq, vv = y[:3], y[3]
        dqq = np.array(fF(*qq), float).ravel() * vv
        uu = np.array(fu(tt, *qq, *dqq), float).ravel()
        return np.concatenate([dqq, [float(fvdot(*qq, vv, *uu))]])

    T = 1.5
    grid = np.linspace(0, T, 16)
    sf = solve_ivp(full, (0, T), np.concatenate([q0, dq0]), t_eval=grid, rtol=1e-10, atol=1e-12)
    sr = solve_ivp(reduced, (0, T), np.concatenate([q0, [0.4]]), t_eval=grid, rtol=1e-10, atol=1e-12)
    assert sf.success and sr.success
    assert np.max(np.abs(sf.y[:3] - sr.y[:3])) < 1e-6          # same motion
    assert np.max(np.abs(sf.y[:3, -1] - q0)) > 0.05             # and it moved
    for j, tt in enumerate(grid):
        x = sf.y[:, j]
        uu = np.array(fu(tt, *x), float).ravel()
        qdd, lam = m.kkt(x, uu)
        assert abs(x[5] - sr.y[3, j]) < 1e-6                    # v = D q̇
        assert abs(float(fvdot(*x[:3], x[5], *uu)) - qdd[2]) < 1e-6
        assert np.allclose(np.array(flam(*x[:3], x[5], qdd[2], *uu), float).ravel(), lam, atol=1e-6)
        B, nv, A, Adq = m.mats(x)  # λ = (A B⁻¹ Aᵀ)⁻¹ (A B⁻¹ (n − u) − Ȧ q̇) is the Lagrange reaction
        lam_f = np.linalg.solve(A @ np.linalg.solve(B, A.T), A @ np.linalg.solve(B, nv - uu) - Adq)
        assert np.allclose(lam_f, lam, atol=1e-8)


def test_lambda_formula_keeps_the_constraint_and_free_motion_leaves_it():
    """B q̈ = u − n + Aᵀ λ(q, q̇, u) with the symbolic λ of the ask keeps h(q) = 0; with λ = 0 h drifts."""
    p, _, res = solved(R2C)
    lam = value(res, "lambda")
    h = value(res, "h")
    m = Model(p, h)
    q, dq, u = m.q, m.dq, list(p.robot.inputs)
    flam = sp.lambdify(q + dq + u, lam.xreplace(p.values), "numpy")
    t = sp.Symbol("t")
    fu = sp.lambdify([t], sp.Matrix([8 * sp.sin(3 * t), 2 * sp.cos(t)]), "numpy")
    # q0 on the circle: tip at (1 + 0.8 cos 2, 0.8 sin 2), elbow up
    x, y = 1 + 0.8 * np.cos(2.0), 0.8 * np.sin(2.0)
    c2 = (x * x + y * y - 2) / 2
    q2 = np.arccos(c2)
    q1 = np.arctan2(y, x) - np.arctan2(np.sin(q2), 1 + c2)
    x0 = np.array([q1, q2, 0.0, 0.0])
    assert abs(float(np.ravel(m.h(*x0))[0])) < 1e-12

    def rhs(with_lambda):
        def f(tt, xx):
            uu = np.array(fu(tt), float).ravel()
            B, nv, A, _ = m.mats(xx)
            lm = np.array(flam(*xx, *uu), float).ravel() if with_lambda else np.zeros(1)
            return np.concatenate([xx[2:], np.linalg.solve(B, uu - nv + A.T @ lm)])
        return f

    grid = np.linspace(0, 2, 41)
    for with_lambda in (True, False):
        s = solve_ivp(rhs(with_lambda), (0, 2), x0, t_eval=grid, rtol=1e-10, atol=1e-12)
        drift = max(abs(float(np.ravel(m.h(*s.y[:, j]))[0])) for j in range(len(grid)))
        if with_lambda:
            assert s.success and drift < 1e-6
            # and λ is the reaction of the Lagrange system at every sample
            for j in range(0, len(grid), 8):
                uu = np.array(fu(grid[j]), float).ravel()
                assert np.allclose(np.array(flam(*s.y[:, j], *uu), float).ravel(), m.kkt(s.y[:, j], uu)[1], atol=1e-8)
        else:
            assert drift > 0.05  # the test can fail: without λ the tip leaves the circle


def test_simulation_figure_of_lambda():
    text = R2C + """    simulate:
      u: [8*sin(3*t), 2*cos(t)]
      q0: [Q1, Q2]
      time: 1
      points: 51
"""
    x, y = 1 + 0.8 * np.cos(2.0), 0.8 * np.sin(2.0)
    c2 = (x * x + y * y - 2) / 2
    q2 = np.arccos(c2)
    q1 = np.arctan2(y, x) - np.arctan2(np.sin(q2), 1 + c2)
    text = text.replace("q0: [Q1, Q2]", f"q0: [{float(q1):.15g}, {float(q2):.15g}]")  # on the circle (the check allows 1e-6)
    p, sols, res = solved(text)
    fig = sols[0].figures[0]
    lam_panel, q_panel, h_panel = fig.panels
    assert len(lam_panel.curves[0].y) == 51 and len(q_panel.curves) == 2
    assert max(abs(y) for y in h_panel.curves[0].y) < 1e-6
    assert max(abs(y) for y in lam_panel.curves[0].y) > 1.0  # a real reaction (gravity and the inputs)


# ------------------------------------------------------------------------------------------------ inputs
def random_states(fF, rng, count=4):
    for _ in range(count):
        q1 = rng.uniform(0.1, 0.6)
        q2 = np.arcsin((0.5 - np.sin(q1)) / 0.8) - q1
        q = np.array([q1, q2, -q1 - q2])
        vv = rng.uniform(-1, 1)
        yield q, np.array(fF(*q), float).ravel() * vv, vv


def test_inputs_for_a_desired_pseudo_acceleration_and_multiplier():
    p, _, res = solved(R3_K2)
    m = Model(p, value(res, "h"))
    q = m.q
    u_dv = value(res, "u_dv")
    fF = sp.lambdify(q, value(res, "F"), "numpy")
    fu = sp.lambdify(q + [p.names["dq3"]], u_dv, "numpy")
    assert res["u_dv_check"].value is True
    for qq, dqq, vv in random_states(fF, np.random.default_rng(3)):
        qdd, lam = m.kkt(np.concatenate([qq, dqq]), np.array(fu(*qq, vv), float).ravel())
        assert abs(qdd[2] - 0.7) < 1e-9                      # v̇ = q̈3 = v̇_d
        assert np.allclose(lam, [1.5, -0.5], atol=1e-9)     # λ = λ_d


def test_equilibrium_inputs_keep_the_robot_at_rest():
    p, _, res = solved(R3_K2)
    m = Model(p, value(res, "h"))
    q = m.q
    u = list(p.robot.inputs)
    u_eq, lam_eq, u0 = value(res, "u_eq"), value(res, "lambda_eq"), value(res, "u_eq_lambda0")
    free = [s for s in u if u_eq.has(s)]
    assert len(free) == 2  # three inputs, one equation F^T(u - g) = 0
    rng = np.random.default_rng(5)
    for qq, _, _ in random_states(sp.lambdify(q, value(res, "F"), "numpy"), rng, 3):
        pick = {s: rng.uniform(-5, 5) for s in free}
        uu = np.array(u_eq.xreplace(dict(zip(q, qq))).xreplace(pick).evalf(), float).ravel()
        qdd, lam = m.kkt(np.concatenate([qq, np.zeros(3)]), uu)
        assert np.allclose(qdd, 0, atol=1e-9)
        assert np.allclose(lam, np.array(lam_eq.xreplace(dict(zip(q, qq))).xreplace(pick).evalf(), float).ravel())
        qdd, lam = m.kkt(np.concatenate([qq, np.zeros(3)]), np.array(u0.xreplace(dict(zip(q, qq))).evalf(), float).ravel())
        assert np.allclose(qdd, 0, atol=1e-9) and np.allclose(lam, 0, atol=1e-9)


def test_state_values_and_minimum_norm_equilibrium():
    """At a state on the constraint: λ(q*, q̇*, u) from the formula equals the Lagrange reaction for any u."""
    q0 = start_k2()
    state = ", ".join(f"q{i + 1}: {float(x):.17g}" for i, x in enumerate(q0)) + ", dq1: 0, dq2: 0, dq3: 0"
    p, _, res = solved(R3_K2 + f"    at: {{{state}}}\n")
    m = Model(p, value(res, "h"))
    lam_at = value(res, "lambda_at")
    u = list(p.robot.inputs)
    for uu in ([30.0, 10.0, 1.0], [0.0, -3.0, 2.0]):
        lam = m.kkt(np.concatenate([q0, np.zeros(3)]), np.array(uu))[1]
        assert np.allclose(np.array(lam_at.xreplace(dict(zip(u, uu))).evalf(), float).ravel(), lam, atol=1e-8)
    umin = np.array(value(res, "u_eq_min_at").evalf(), float).ravel()
    qdd, _ = m.kkt(np.concatenate([q0, np.zeros(3)]), umin)
    assert np.allclose(qdd, 0, atol=1e-9)
    family = value(res, "u_eq_at")
    free = [s for s in u if family.has(s)]
    for pick in ({free[0]: 1.0, free[1]: -2.0}, {free[0]: -3.0, free[1]: 0.5}):
        assert np.linalg.norm(np.array(family.xreplace(pick).evalf(), float).ravel()) >= np.linalg.norm(umin) - 1e-9


# ------------------------------------------------------------------------------------------------ special cases
def test_frozen_coordinate_gives_the_block_of_the_inertia_matrix():
    p, _, res = solved(R3 + "  - kind: constrained_dynamics\n    freeze: {q3: 0.4}\n    multiplier: false\n")
    dm = derive(p.robot)
    q3 = p.names["q3"]
    at = {q3: sp.Rational(2, 5)}
    assert all(zero(a - b) for a, b in zip(value(res, "reduced_inertia"), dm.B[:2, :2].xreplace(at)))
    ddq = sp.Matrix(p.robot.ddq[:2])
    dq = {p.names["dq3"]: 0}
    n_b = (dm.c + dm.g)[2].xreplace(at).xreplace(dq)
    want = (dm.B[2, :2].xreplace(at) * ddq)[0] + n_b - p.robot.inputs[2]
    assert zero(value(res, "lambda_reduced")[0] - want)
    assert value(res, "F") == sp.Matrix([[1, 0], [0, 1], [0, 0]])


def test_pfaffian_constraint_equals_the_holonomic_one():
    base = R2C.replace("    h: (cos(q1) + cos(q1 + q2) - 1)^2 + (sin(q1) + sin(q1 + q2))^2 - r^2\n", "")
    _, _, hol = solved(base + "    h: q1 + q2\n")
    _, _, pf = solved(base + "    A: [1, 1]\n")
    assert "h" not in pf
    assert zero(value(pf, "lambda")[0] - value(hol, "lambda")[0])
    assert all(zero(a - b) for a, b in zip(value(pf, "reduced_model"), value(hol, "reduced_model")))


def test_underactuated_robot_gets_the_inputs_from_the_reduced_model():
    text = R2C.replace("  gravity: [0, -9.81]\n", "  gravity: [0, -9.81]\n  input_map: [[1], [0]]\n  inputs: [tau]\n") + \
        "    D: [[1, 2]]\n"
    p, _, res = solved(text)
    assert "lambda_dv" in res and res["u_dv_check"].value is True
    m = Model(p, value(res, "h"))
    x, y = 1 + 0.8 * np.cos(2.0), 0.8 * np.sin(2.0)
    c2 = (x * x + y * y - 2) / 2
    q2 = np.arccos(c2)
    q1 = np.arctan2(y, x) - np.arctan2(np.sin(q2), 1 + c2)
    v = next(s for s in value(res, "u_dv").free_symbols if s.name == "v")
    dvd = p.names["dvd"]
    subs = {p.names["q1"]: q1, p.names["q2"]: q2, v: 0.3, dvd: -0.2, **p.values}
    tau = float(value(res, "u_dv")[0].xreplace(subs))
    F = np.array(value(res, "F").xreplace(subs).evalf(), float).ravel()
    qdd, lam = m.kkt(np.array([q1, q2, *(F * 0.3)]), np.array([tau, 0.0]))
    D = np.array(value(res, "D").xreplace(subs).evalf(), float).ravel()
    dD = value(res, "D").applyfunc(lambda e: sum(sp.diff(e, s) * d for s, d in zip(m.q, m.dq)))
    ddot = float((dD * sp.Matrix(m.dq)).xreplace(subs).xreplace(dict(zip(m.dq, F * 0.3)))[0])
    assert abs(D @ qdd + ddot - (-0.2)) < 1e-9
    assert abs(lam[0] - float(value(res, "lambda_dv")[0].xreplace(subs))) < 1e-9


# ------------------------------------------------------------------------------------------------ grading
def test_grader_accepts_a_reduced_inertia_under_the_students_complement():
    p, _, res = solved(R2C)
    q1 = p.names["q1"]
    A = value(res, "A")
    D_ref = value(res, "D")
    D_student = sp.Matrix([[sp.cos(q1), sp.sin(q1)]])  # another complement
    assert D_student != D_ref and generic_rank_ok(A.col_join(D_student))
    AD = A.col_join(D_student)
    F = AD.inv()[:, 1:]
    B = derive(p.robot).B
    right = (F.T * B * F)[0]

    def other(name):
        return [[sp.cos(q1), sp.sin(q1)]] if name == "D" else None

    v = check_reduction(p, res, "reduced_inertia", right, other, None)
    assert v is not None and v.correct
    v = check_reduction(p, res, "reduced_inertia", 2 * right, other, None)
    assert v is not None and not v.correct
    v = check_reduction(p, res, "D", [[sp.cos(q1), sp.sin(q1)]], lambda n: None, None)
    assert v is not None and v.correct
    bad = [list(A)]  # a multiple of A does not complete it
    v = check_reduction(p, res, "D", bad, lambda n: None, None)
    assert v is not None and not v.correct
    assert check_reduction(p, res, "reduced_inertia", right, lambda n: None, None) is None  # no D: reference


def test_grader_accepts_any_parametrization_of_the_equilibrium_inputs():
    p, _, res = solved(R3_K2)
    u = list(p.robot.inputs)
    ref, g = value(res, "u_eq"), value(res, "u_eq_lambda0")
    F = value(res, "F")
    a, b = sp.symbols("a b", real=True)  # the student's own parameters: u = g + A^T (a, b)
    A = value(res, "A")
    family = g + A.T * sp.Matrix([a, b])
    assert all(zero(x) for x in F.T * (family - g))
    v = check_equilibrium_inputs(p, res, "u_eq", list(family), lambda n: None, None)
    assert v.correct and v.fraction == 1.0
    v = check_equilibrium_inputs(p, res, "u_eq", list(g), lambda n: None, None)
    assert v.correct is False and v.fraction == 0.5  # keeps the equilibrium, but only one input of the family
    v = check_equilibrium_inputs(p, res, "u_eq", list(g + sp.Matrix([1, 0, 0])), lambda n: None, None)
    assert v.correct is False and v.fraction == 0.0
    assert set(u) >= {s for s in ref.free_symbols if s in u}


def generic_rank_ok(M) -> bool:
    from solver.kinematics.redundancy import generic_rank
    return generic_rank(M) == M.rows


# ------------------------------------------------------------------------------------------------ bad input
BASE2 = R2C.replace("    h: (cos(q1) + cos(q1 + q2) - 1)^2 + (sin(q1) + sin(q1 + q2))^2 - r^2\n", "    h: q1 + q2\n")
BASE3 = R3 + "  - kind: constrained_dynamics\n    h: q1 + q2\n"
BAD = [  # (base, text replacing "    h: q1 + q2\n", pieces of the message, the text of the line it points at)
    (BASE3, "    h: [q1 + q2, 2*q1 + 2*q2]\n", ["dependent", "rank A(q) = 1 < 2"], "    h: [q1"),
    (BASE3, "    h: [q1 + q2, q2 + q3, q1 + 2*q2 + q3]\n", ["3 constraints on 3 coordinates"], "    h: [q1"),
    (BASE2, "    h: q1 + q2\n    D: [[2, 2]]\n", ["D does not complete A"], "    D:"),
    (BASE2, "    h: q1 + q2\n    D: [[1, 0, 0]]\n", ["D must be 1x2"], "    D:"),
    (BASE2, "    h: q3 - 1\n", ["unknown name 'q3'"], "    h: q3"),
    (BASE2, "    freeze: {q5: 0}\n", ["'q5' in freeze: is not a coordinate"], "    freeze:"),
    (BASE2, "    A: [[1, 1, 0]]\n", ["A must have 2 columns"], "    A:"),
    (BASE2, "    h: q1 + dq2\n", ["must not depend on velocities"], "    h: q1"),
    (BASE2, "    h: r\n", ["does not depend on the coordinates"], "    h: r"),
    (BASE2, "    h: q1 + q2\n    at: {q1: 1, q2: 1}\n", ["not on the constraints"], "    at:"),
    (BASE2, "    h: q1 + q2\n    at: {q1: 1, q2: -1, dq1: 1, dq2: 1}\n", ["velocity violates the constraints"],
     "    at:"),
    (BASE2, "    h: q1 + q2\n    at: {dq9: 1}\n", ["'dq9' in at: is not a coordinate or a velocity"], "    at:"),
    (BASE2, "    h: q1 + q2\n    simulate: {u: [0, 0], q0: [1, 1]}\n", ["q0 is not on the constraints"],
     "    simulate:"),
    (BASE2, "    h: q1 + q2\n    dv_d: [1, 2]\n", ["dv_d must have 1 component"], "    dv_d:"),
    (BASE2, "    h: q1 + q2\n    A: [1, 1]\n", ["exactly one of h:"], "  - kind: constrained"),
]


@pytest.mark.parametrize("base, new, expected, line", BAD, ids=[b[2][0] for b in BAD])
def test_bad_input_is_one_error_at_its_line(write, base, new, expected, line):
    text = base.replace("    h: q1 + q2\n", new)
    where = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith(line))
    path = write(text)
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem(path))
    msg = str(exc.value)
    assert all(part in msg for part in expected), msg
    assert f"spec.yaml:{where}:" in msg, msg


@pytest.mark.parametrize("base, new, expected, line", [b for b in BAD if "simulate:" not in b[1] and "A: [1" not in b[1]],
                         ids=[b[2][0] for b in BAD if "simulate:" not in b[1] and "A: [1" not in b[1]])
def test_validation_raises_what_solve_raises(write, base, new, expected, line):
    """The kind's validate hook (what `check` runs) gives the error of solving, without the model (the
    simulation's inputs, whose numbers depend on it, are left to solving)."""
    path = write(base.replace("    h: q1 + q2\n", new))
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem(path))
    errors = validate_problem(load_problem(path))
    assert [str(e) for e in errors] == [str(exc.value)]


def test_check_reports_undeclared_names_in_the_desired_inputs(write):
    """dv_d and lambda_d are read when the reduced model is derived: `check` read neither (ok); now it reports
    each undeclared name as `solve` does, and accepts names of the ask's own pseudo-velocities and inputs."""
    text = BASE2.replace("    h: q1 + q2\n", "    h: q1 + q2\n    dv_d: vdes\n    lambda_d: lamdes\n")
    check, solve = check_and_solve(write(text))
    assert check.returncode == solve.returncode == 2 and check.stderr == solve.stderr, check.stderr
    assert "error: unknown name 'vdes'" in check.stderr
    check, solve = check_and_solve(write(text.replace("vdes", "1")))
    assert check.returncode == solve.returncode == 2 and check.stderr == solve.stderr, check.stderr
    assert "error: unknown name 'lamdes'" in check.stderr
    fine = text.replace("    dv_d: vdes\n", "    v: [w]\n    dv_d: -w\n").replace("lamdes", "u1")
    problem = load_problem(write(fine))
    assert validate_problem(problem) == []
    assert "w" not in problem.names and "u1" not in problem.names  # the problem is left as loaded


@pytest.mark.parametrize("new", ["    h: q1 + q2\n    D: [[2, 2]]\n", "    freeze: {q5: 0}\n"])
def test_cli_exits_2_without_traceback(write, new):
    path = write(BASE2.replace("    h: q1 + q2\n", new))
    for command in ("solve", "verify"):
        r = subprocess.run([sys.executable, "-m", "solver", command, str(path)], capture_output=True, text=True,
                           timeout=300)
        out = r.stdout + r.stderr
        assert r.returncode != 0 and "Traceback" not in out and "spec.yaml:1" in out, out
    r = subprocess.run([sys.executable, "-m", "solver", "solve", str(path)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2
    with_expected = write(BASE2.replace("    h: q1 + q2\n", new) + "expected:\n  A: {value: '[[1, 1]]', line: 1}\n",
                          "spec2.yaml")
    r = subprocess.run([sys.executable, "-m", "solver", "check", str(with_expected)], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "spec2.yaml:1" in r.stderr, r.stdout + r.stderr


# ------------------------------------------------------------------------------------------------ report
def test_report_in_both_formats():
    p, sols, _ = solved(R2C + "    D: [[0, 1]]\n")
    md = render(p, sols, "md")
    for part in ("**Constraints.**", "**Multiplier.**", "dynamically consistent", "**Reduced model.**",
                 "**Static equilibrium.**", "Inputs for a desired pseudo-acceleration"):
        assert part.lower() in md.lower(), part
    assert "so the robot keeps 1 degree of freedom." in md and "$1$ degree" not in md  # (as the tex says it)
    tex = render(p, sols, "tex")
    assert "\\paragraph{Reduced dynamics.}" in tex and "\\begin{document}" in tex
    assert "so the robot keeps 1 degree of freedom." in tex


def test_solve_inputs_rows_over_one_denominator():
    """Rows of [M b] are multiplied by the lcm of their denominators before solving: the solution (pivot inputs,
    free inputs) and the minimum-norm one satisfy M u = b and equal those of the polynomial system δ M u = δ b;
    the minimum-norm u is orthogonal to the null space of M."""
    from solver.interaction.constraints import _clear_rows, solve_inputs
    q1, q2, a, m = sp.symbols("q1 q2 a m", positive=True)
    u = list(sp.symbols("u1:4"))
    d = a + sp.cos(q2) ** 2 + 1
    P = sp.Matrix([[sp.cos(q1), 2 * sp.sin(q2), a], [0, sp.cos(q2), 1]])
    c = sp.Matrix([m * sp.sin(q1), a * m])
    M, b = P / d, c / d
    assert _clear_rows(M, b) == (P, c)
    mixed = sp.Matrix([[1 / (2 * d), 1 / (3 * (d + 1)), 0]])
    X, y = _clear_rows(mixed, sp.Matrix([m / d ** 2]))  # times lcm = 6 d² (d + 1)
    want = [3 * d * (d + 1), 2 * d ** 2, 0, 6 * m * (d + 1)]
    assert all(sp.expand(x - w) == 0 for x, w in zip(list(X) + list(y), want))
    rational = solve_inputs(M, b, u)
    polynomial = solve_inputs(P, c, u)
    assert rational.exists and rational.free == polynomial.free == [u[2]]
    for x, y in zip(list(rational.u) + list(rational.u_min), list(polynomial.u) + list(polynomial.u_min)):
        assert sp.simplify(x - y) == 0
    rng = np.random.default_rng(3)
    for _ in range(3):
        st = dict(zip((q1, q2, a, m, u[2]), rng.uniform(0.2, 1.5, 5)))
        for sol in (rational.u, rational.u_min):
            res = (M * sol - b).subs(st).evalf()
            assert max(abs(float(x)) for x in res) < 1e-12
        null = np.array(P.nullspace()[0].subs(st).evalf(), dtype=float).ravel()
        assert abs(np.array(rational.u_min.subs(st).evalf(), dtype=float).ravel() @ null) < 1e-12


def test_long_fractions_read_as_products_in_latex():
    """A long c·(t1 + t2 + ...)/den is written lhs = \\frac{c}{den}\\Big(t1 + ...\\Big): one '=' before the
    bracket (the coefficient was once printed as 'lhs = \\frac{c}{den} = \\Big(...', which is false)."""
    import re

    from conftest import PROBLEMS
    p = load_problem(PROBLEMS / "2018-07-11-ex4.yaml")
    tex = render(p, solve_problem(p), "tex")
    heads = [line.split("\\Big(")[0] for line in tex.splitlines() if "\\Big(" in line]
    assert len(heads) >= 3
    for head in heads:
        assert len(re.findall(r"(?<![<>\\])=", head)) == 1, head
    assert "\\lambda = \\frac{1}{a_1 + 2 a_2 \\cos {q_{2}}}\\Big(a_3 u_{1}" in tex


@pytest.mark.parametrize("d", [
    "-l1*(cos(q2) - 1)*(cos(q2) + 1)",
    "(1 - cos(q2))*(cos(q2) + 1)*(p1**2 + p2**2)",
    "-L**2*(cos(q2) - 1)*(cos(q2) + 1)*sin(q2)",
    "a*(cos(q1) - 1)**2*(cos(q1) + 1)**2*sin(q2)",
    "-(1 - cos(q1))**3*(cos(q1) + 1)**3",
    "(cos(q1) - 1)*(cos(q1) + 1)*(cos(q2) - 1)*(cos(q2) + 1)*sin(q1)",
])
def test_paired_sines_is_the_trigsimp_form(d):
    """(cos x - 1)^k (cos x + 1)^k -> (-1)^k sin^{2k} x without trigsimp, as trigsimp writes it."""
    from solver.interaction.constraints import _paired_sines
    from solver.math.simplify import factor_within, tidy
    e = sp.sympify(d, locals={n: sp.Symbol(n, real=True) for n in ("q1", "q2")})
    assert _paired_sines(e) == factor_within(sp.trigsimp(tidy(sp.expand(e))))


@pytest.mark.parametrize("d", ["(cos(q2) - 1)*(cos(q2) + 1)**2", "(cos(q1) - 1)*(cos(q2) + 1)", "l1*sin(q2)",
                               "(cos(q1 + q2) - 1)*(cos(q1 + q2) + 1)", "(cos(q2) - 2)*(cos(q2) + 2)"])
def test_paired_sines_declines_other_products(d):
    from solver.interaction.constraints import _paired_sines
    assert _paired_sines(sp.sympify(d)) is None


@pytest.mark.parametrize("n, d", [
    ("a1*sin(q2)**3*cos(q1) + a2*sin(q2)*cos(q1 + q2)", "sin(q2)**2*sin(q1 + q2)"),
    ("v**2*(sin(q1)*cos(q2) + 2*sin(q1 + q2)) - tau*cos(q1)", "(128*sin(q2)**7*sin(q1 + q2))"),
    ("(a1 + a2*cos(q2))*cos(q1)", "-3*a2*cos(q1)*sin(q2)**2"),
    ("l1*sin(q2)**2 + l2*sin(q2)*cos(q2)", "2*l1*sin(q2)"),
    ("dq1**2*a2*sin(q2)", "a1*cos(q2)**2"),
])
def test_ratio_over_a_product_of_sines_keeps_it(n, d, monkeypatch):
    """A denominator c Π bᵉ (b a symbol, sin or cos) is already factored: ratio keeps it and cancels its factors
    without the Fourier form, factor_list or trigsimp, and gives what the general path gives (or a shorter form
    of it)."""
    import solver.interaction.constraints as C
    loc = {x: sp.Symbol(x, real=True) for x in ("q1", "q2", "a1", "a2", "l1", "l2", "v", "tau", "dq1")}
    ne, de = sp.sympify(n, locals=loc), sp.sympify(d, locals=loc)
    calls, trigsimp = [], sp.trigsimp
    monkeypatch.setattr(C, "factor_list_expr", lambda e: calls.append(e) or sp.factor_list(e))
    monkeypatch.setattr(C.sp, "trigsimp", lambda e, **kw: calls.append(e) or trigsimp(e, **kw))
    fast = C.ratio(ne, de)
    assert calls == []
    monkeypatch.setattr(C, "_monomial", lambda e: None)
    C._short_denominator.cache_clear()
    general = C.ratio(ne, de)
    rng = np.random.default_rng(7)
    for _ in range(5):
        at = {x: sp.Float(rng.uniform(0.2, 1.3)) for x in (ne / de).free_symbols}
        exact = float((ne / de).xreplace(at))
        assert abs(float(fast.xreplace(at)) - exact) < 1e-9 * max(1, abs(exact))
        assert abs(float(general.xreplace(at)) - exact) < 1e-9 * max(1, abs(exact))
    assert sp.count_ops(fast) <= sp.count_ops(general)
    assert sp.Mul.make_args(sp.fraction(fast)[1]) and all(
        not f.is_Add for f in sp.Mul.make_args(sp.fraction(fast)[1]))


@pytest.mark.parametrize("f", ["sin(q2)", "cos(q1 + q2)", "sin(q1 - 2*q2)", "a1 + a2*cos(q2)",
                               "l1*cos(q1) + l2*cos(q1 + q2) - k", "xA*cos(q2) - xB*sin(q2)"])
def test_divisibility_precheck_never_refuses_a_factor(f):
    """_divide_out skips the expansion when n is clearly non-zero at a point where f = 0: for n = f·g (any g)
    the pre-check must never say so, and for n = f·g + r (r not vanishing with f) it does."""
    from solver.interaction.constraints import _divide_out, _nonzero_where_zero, _zero_point
    loc = {x: sp.Symbol(x, real=True) for x in ("q1", "q2", "a1", "a2", "l1", "l2", "k", "xA", "xB", "m2")}
    fe = sp.sympify(f, locals=loc)
    q1, q2, a1, l1, m2 = (loc[x] for x in ("q1", "q2", "a1", "l1", "m2"))
    import random
    point = _zero_point(fe, random.Random(1))
    assert point is not None and abs(float(fe.xreplace(point))) < 1e-9
    for g in (sp.Integer(3), m2 * sp.cos(q1) ** 2 + l1 * sp.sin(q2), (a1 + sp.sin(q1 + q2)) ** 3 - q1 * l1):
        n = sp.expand(fe * g)
        assert not _nonzero_where_zero(n, fe)
        assert not _nonzero_where_zero(fe * g, fe)
    r = m2 * sp.cos(q1 - q2) + 2
    assert _nonzero_where_zero(sp.expand(fe * (l1 + q2) + r), fe)
    assert _divide_out(sp.expand(fe * (l1 + q2) + r), fe, 1)[1] == 0


def test_zero_point_skips_only_symbols_it_cannot_solve_for():
    """_zero_point tries ∂f/∂s only for the symbols f is linear in (by its ring degree): the same point as trying
    every symbol in turn (sympy's diff of each, the definition), for factors linear in none, some or all of them."""
    import random

    from solver.interaction.constraints import _NoValue, _value, _zero_point
    L, xA, xB, yA, k, q1, q2 = sp.symbols("L xA xB yA k q1 q2", real=True)

    def every_symbol(f: sp.Expr) -> dict | None:
        rng, g = random.Random(3), f
        if isinstance(f, (sp.sin, sp.cos)):
            g = f.args[0] - (0 if isinstance(f, sp.sin) else sp.pi / 2)
        for s in sorted(g.free_symbols, key=lambda x: x.name):
            g1 = sp.diff(g, s)
            if g1.has(s):
                continue
            point = {x: rng.uniform(0.3, 1.7) for x in sorted(g.free_symbols - {s}, key=lambda x: x.name)}
            try:
                den = _value(g1, point)
                if abs(den) < 1e-6:
                    continue
                point[s] = -_value(g.xreplace({s: sp.S.Zero}), point) / den
            except _NoValue:
                return None
            return point
        return None

    for f in (L**2 * xA**2 * sp.cos(q2)**2 - 2 * L**2 * xA * xB * sp.sin(q2) * sp.cos(q2) + yA**2,
              L**2 * (xA - xB) ** 2 + k * yA**2 * sp.cos(q2) + yA**3, xA * sp.cos(q2) - xB * sp.sin(q2),
              L * sp.cos(q1) + xA * sp.cos(q1 + q2) - k, sp.sin(q1 + 2 * q2), sp.cos(q1), sp.sqrt(xA**2 + yA**2) - k,
              (xA + 1) * (xA - 1) - xA**2 + k * xB):
        assert _zero_point(f, random.Random(3)) == every_symbol(f), f


def test_memoized_factor_terms_is_sympys():
    """constraints.factor_terms (sympy's recursion, memoized on subexpressions) equals sp.factor_terms on sums of
    products with contents, common factors, minus signs, sines of multiple angles, powers and fractions."""
    import random

    from solver.interaction.constraints import factor_terms
    a, b, c, q1, q2 = sp.symbols("a b c q1 q2", real=True)
    atoms = [a, b, c, a + b, 2 * a - 4 * c, sp.sin(2 * q1 - 2 * q2), sp.cos(q1 + 3 * q2), sp.sin(q2), (a - c) ** 2,
             sp.Rational(3, 4), -2, 1 / (a + b), sp.sqrt(2)]
    rng = random.Random(5)
    for _ in range(40):
        e = sp.Add(*[sp.Mul(*rng.sample(atoms, rng.randint(1, 4))) for _ in range(rng.randint(1, 6))])
        assert factor_terms(e) == sp.factor_terms(e), e
    assert factor_terms(sp.Sum(a * b + a * c, (b, 1, 3))) == sp.factor_terms(sp.Sum(a * b + a * c, (b, 1, 3)))


def test_ring_expansion_is_sympys_expand():
    """ring_expand (sparse ring over the symbols and the sines/cosines) gives sp.expand's terms, and with trig those
    of sp.expand(sp.expand(sp.expand_trig(.))), for printed Fourier and product forms with factored coefficients
    (2·(q₃ − d) unevaluated); None for an offset in an argument, a float or a fraction."""
    from solver.interaction.constraints import ring_expand
    from solver.math.simplify import tidy
    a, b, d, q1, q2, q3 = sp.symbols("a b d q1 q2 q3", real=True)
    forms = [tidy((a + b * sp.cos(q2)) ** 2 * sp.sin(q1 + q2) - a * d * sp.cos(2 * q1)),
             tidy(sp.expand((a * sp.sin(q1) + b * sp.cos(q1 + q2)) ** 3)),
             sp.Mul(2, q3 - d, evaluate=False) * sp.cos(q1 - 2 * q2) + (a + b) * (a - b) * sp.sin(3 * q2) / 4,
             a * sp.sin(q1) ** 2 * sp.cos(q1) + sp.Rational(3, 2)]
    for n in forms:
        for trig in (False, True):
            ref = sp.expand(sp.expand(sp.expand_trig(n))) if trig else sp.expand(n)
            assert sp.Add.make_args(ring_expand(n, trig)) == sp.Add.make_args(ref), (n, trig)
    assert ring_expand(sp.cos(q1 + 1) * a, False) is None
    assert ring_expand(0.5 * a * sp.cos(q1), False) is None
    assert ring_expand(a / b * sp.cos(q1), True) is None


def test_exact_division_in_the_sparse_ring_equals_sympys_div():
    """_exact_division (sparse ring, over QQ) gives sp.div's quotients and exponents: factors with a content (2 f),
    factors that divide n fewer times than asked, that do not divide it, radicals and sines as generators."""
    from solver.interaction.constraints import _exact_division
    a, b, c, q = sp.symbols("a b c q", real=True)
    f1 = a + b * sp.cos(q)
    f2 = 2 * a - 3 * c
    f3 = sp.sqrt(7) * a + sp.sin(q) * b
    cases = [(f1**2 * (c + 1), f1, 3), (f2 * a / 5, f2, 2), (f2 * f1 + 1, f2, 1), (f3**2 * c, f3, 1),
             (f3 * f1**2, f1, 2), (a * b, 2 * a, 1), (a + b, sp.Integer(2), 1)]
    for n, f, e in cases:
        n = sp.expand(n)
        out, j = n, 0
        while j < e:
            quo, rem = sp.div(out, f)
            if sp.expand(rem) != 0 or f.is_number:
                break
            out, j = quo, j + 1
        assert _exact_division(n, f, e) == (out if j else n, j), (n, f)


@pytest.mark.parametrize("n, f, e, j", [
    ("l1**2*l2*(m1*cos(q2) + m2*sin(q1 + q2)**2) - l1**3*m2*cos(q1)", "l1", 3, 2),
    ("l1**2*l2*(m1*cos(q2) + m2*sin(q1 + q2)**2) - l1**3*m2*cos(q1)", "l2", 1, 0),
    ("a*(b + cos(q1))**2*sin(q2)*a**3", "a", 2, 2),
    ("(l1*cos(q1) + l2*cos(q1 + q2))*l2**4", "l2", 9, 4),
])
def test_symbol_divided_out_on_the_fourier_coefficients(n, f, e, j):
    """n / f^j for a symbol f (and several at once), on the Fourier coefficients: the largest j <= e, the quotient in its tidy form (the
    one tidy_expanded prints), times f^j equal to n."""
    from solver.interaction.constraints import _divide_symbols
    from solver.math.simplify import tidy_expanded
    loc = {x: sp.Symbol(x, real=True) for x in ("q1", "q2", "l1", "l2", "m1", "m2", "a", "b")}
    ne, fe = tidy_expanded(sp.sympify(n, locals=loc)), loc[f]
    quotient, powers, tidy_form = _divide_symbols(ne, [(fe, e)])
    k = powers.get(fe, 0)
    assert (k, tidy_form) == (j, True)
    assert quotient == tidy_expanded(quotient)
    assert sp.expand(sp.expand_trig(quotient * fe ** k - ne)) == 0

    if f == "l1":  # l1 and l2 together: l1² only (l2 divides one term only)
        both, powers, _ = _divide_symbols(ne, [(loc["l1"], 3), (loc["l2"], 1)])
        assert powers == {loc["l1"]: 2, loc["l2"]: 0} and both == quotient


def test_entry_by_entry_vectors_say_zero_entries_only_when_there_are():
    """A long vector written entry by entry says "(entries not listed are zero)" only when some entry is zero (it
    said so for A_B^# and P of this problem, whose entries are all listed)."""
    from conftest import PROBLEMS
    p = load_problem(PROBLEMS / "2013-01-09-ex2.yaml")
    tex = render(p, solve_problem(p), "tex")
    assert "\\begin{bmatrix} p_{i} \\end{bmatrix},\\quad\\text{with}\\]" in tex
    assert "entries not listed are zero" not in tex


def test_default_desired_acceleration_is_not_written_twice():
    """With the default v̇_d (a symbol written v̇_d) the report says "To obtain v̇ = v̇_d", not "v̇ = v̇_d = v̇_d"; a
    given value is written after it."""
    p, sols, _ = solved(R2C + "    D: [[0, 1]]\n")
    for fmt in ("md", "tex"):
        text = render(p, sols, fmt)
        assert "To obtain $\\dot v = \\dot v_d$ " in text and "\\dot v_d = \\dot v_d" not in text, fmt
    p, sols, _ = solved(R2C + "    D: [[0, 1]]\n    dv_d: 2*r\n")
    assert "To obtain $\\dot v = \\dot v_d = 2 r$" in render(p, sols, "tex")


def test_at_state_where_the_chosen_complement_is_singular():
    """2R with its tip on y = k: D selects q1, det [A; D] = -l2 cos(q1 + q2) vanishes at (0, π/2), a state on the
    constraint with A q̇ = 0; the ask says so at the at: line (it crashed in an SVD of NaN entries)."""
    text = """
id: cd-sing
title: 2R with its tip on a horizontal line
symbols: {l1: length 1, l2: length 2, k: height of the line}
values: {l1: 1, l2: 4/5, k: 4/5}
robot:
  joints: [R, R]
  links:
    - {mass: 2, com: [l1/2*cos(q1), l1/2*sin(q1)], angle: q1, inertia: 1/6}
    - {mass: 1, com: [l1*cos(q1) + l2/2*cos(q1 + q2), l1*sin(q1) + l2/2*sin(q1 + q2)], angle: q1 + q2, inertia: 4/75}
asks:
  - kind: constrained_dynamics
    h: l1*sin(q1) + l2*sin(q1 + q2) - k
    multiplier: false
    at: {q1: 0, q2: pi/2, dq1: 0, dq2: 1}
"""
    with pytest.raises(UserError, match="singular at this state") as exc:
        solve_problem(load_problem_text(text))
    assert ":15:" in str(exc.value) and "give a D" in str(exc.value)
    r = all_results(solve_problem(load_problem_text(text.replace("q1: 0, q2: pi/2, dq1: 0, dq2: 1", "q1: pi/2, q2: acos(-1/4)"))))
    assert "F_at" in r and all(x.is_number for x in r["F_at"].value)


UNIT_2R = """robot:
  joints: [R, R]
  links:
    - {mass: 1, com: [cos(q1), sin(q1)], angle: q1, inertia: 0}
    - {mass: 1, com: [cos(q1) + cos(q1 + q2), sin(q1) + sin(q1 + q2)], angle: q1 + q2, inertia: 0}
"""   # point masses 1 at the ends of links of length 1

ORIENT = """
id: cd-orient
title: 2R whose last link keeps a horizontal orientation
""" + UNIT_2R + """asks:
  - kind: constrained_dynamics
    h: sin(q1 + q2)
    D: [[0, 1]]
    v: [w]
"""


def test_one_constraint_is_singular_in_the_text():
    """One constraint reads "The holonomic constraint ... gives" (it said "The 1 holonomic constraint", "The 1
    constraint is independent"), two read "The 2 holonomic constraints ... give"; the same for Pfaffian ones."""
    p, sols, _ = solved(ORIENT)
    for fmt in ("md", "tex"):
        text = render(p, sols, fmt)
        assert "The holonomic constraint $h(q) = 0$" in text and "The constraint is effective" in text, fmt
        assert "The 1 " not in text, fmt
    p, sols, _ = solved(ORIENT.replace("h: sin(q1 + q2)", "A: [cos(q1 + q2), cos(q1 + q2)]"))
    for fmt in ("md", "tex"):
        assert "The Pfaffian constraint on the velocities is $A(q)\\dot q = 0$" in render(p, sols, fmt), fmt
    p, sols, _ = solved(R3_K2)
    md = render(p, sols, "md")
    assert "The 2 holonomic constraints $h(q) = 0$" in md and "The 2 constraints are independent" in md


def test_qddot_is_simplified():
    """q̈ = F v̇ + Ḟ v with det [A; D] = cos(q1 + q2), F = (-1, 1), Ḟ = 0 is (-ẇ, ẇ); it was printed over the common
    denominator as ẇ (cos(2q1 + 2q2) + 1)/(2 cos²(q1 + q2)). Checked against F v̇ + Ḟ v of the results, and by
    differentiating q̇ = F(q) v along a motion on the constraint."""
    p, _, res = solved(ORIENT)
    w, dw = p.names["w"], p.names["dw"]
    assert value(res, "qddot") == sp.Matrix([-dw, dw])
    assert value(res, "F") == sp.Matrix([-1, 1]) and value(res, "Fdot") == sp.zeros(2, 1)
    # q1 + q2 = 0 on the constraint: q = (-s, s), q̇ = (-w, w), q̈ = (-ẇ, ẇ) for any s(t)
    t = sp.Symbol("t")
    s = sp.sin(t) + t ** 2
    q = {p.robot.q[0]: -s, p.robot.q[1]: s}
    dq = {p.robot.dq[0]: -s.diff(t), p.robot.dq[1]: s.diff(t)}
    got = value(res, "qddot").xreplace({w: s.diff(t), dw: s.diff(t, 2)}).xreplace(q).xreplace(dq)
    assert all(sp.simplify(a - b) == 0 for a, b in zip(got, [-s.diff(t, 2), s.diff(t, 2)]))


def test_qddot_is_f_dv_plus_fdot_v_on_a_height_constraint():
    """On the 3R with one height constraint, q̈ (now the shorter of the two forms, entry by entry) is still
    F v̇ + Ḟ v."""
    p, _, res = solved(R3 + f"  - kind: constrained_dynamics\n    h: {HEIGHT}\n    multiplier: false\n"
                            "    D: [[1, 0, 0], [0, 1, 1]]\n")
    v, dv = sp.Matrix([p.names["v1"], p.names["v2"]]), sp.Matrix([p.names["dv1"], p.names["dv2"]])
    want = value(res, "F") * dv + value(res, "Fdot") * v
    assert all(zero(a - b) for a, b in zip(value(res, "qddot"), want))


def test_simulation_prints_the_initial_state_as_written():
    """simulate.q0: [0.3333, -0.3333] is printed as written, not as 3333/10000; dq0 "1.5e-3" as 1.5 · 10^{-3}."""
    text = ORIENT + """    simulate:
      u: [0, 0]
      q0: [0.3333, -0.3333]
      dq0: ["-1.5e-3", 1.5e-3]
      time: 0.2
      points: 11
"""
    p, sols, _ = solved(text)
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        assert "q_0 = \\begin{bmatrix} 0.3333 \\\\ -0.3333 \\end{bmatrix}" in out, fmt
        assert "\\dot q_0 = \\begin{bmatrix} -1.5 \\cdot 10^{-3} \\\\ 0.0015 \\end{bmatrix}" in out, fmt
        assert "3333" not in out.replace("0.3333", ""), fmt


TIP_X = """
id: cd-det2
title: 2R with its tip on the vertical line x = 1/2, v = dq2
""" + UNIT_2R + """asks:
  - kind: constrained_dynamics
    h: cos(q1) + cos(q1 + q2) - 1/2
    D: [[0, 1]]
    multiplier: false
"""


def test_fdot_over_the_square_of_the_determinant():
    """det [A; D] = -(sin q1 + sin(q1 + q2)) is a sum: Ḟ = (Ṅ_F δ − N_F δ̇)/δ² is written over
    2 (sin q1 + sin(q1 + q2))², not over the expanded square (cos 2q1 + 2 cos q2 − 2 cos(2q1 + q2) + ...), and the
    terms over δ², δ³ keep the power too; Ḟ is the time derivative of F = [A; D]⁻¹[:, 1] computed here."""
    p, _, res = solved(TIP_X)
    q1, q2 = p.robot.q
    delta = sp.sin(q1) + sp.sin(q1 + q2)
    for name, e in (("Fdot", 2), ("reduced_inertia", 2), ("FtBFdot", 3), ("EtBF", 2), ("EtBFdot", 3)):
        den = sp.fraction(sp.together(value(res, name)[0]))[1]
        assert (den / delta ** e).is_Rational, (name, den)
    A, D = value(res, "A"), sp.Matrix([[0, 1]])
    F = A.col_join(D).inv()[:, 1]
    Fdot = time_derivative(F, p.robot.q, p.robot.dq)
    assert all(zero(a - b) for a, b in zip(value(res, "Fdot"), Fdot))
    assert zero(value(res, "Fdot")[0] - (
        (sp.sin(q2) * (2 * p.robot.dq[0] + p.robot.dq[1]) - p.robot.dq[1] * sp.sin(2 * q1 + q2)) / (2 * delta ** 2)))
    md = render(*solved(TIP_X)[:2], "md")
    assert "{2 \\left(\\sin {q_{1}} + \\sin{\\left(q_{1} + q_{2} \\right)}\\right)^{2}}" in md


TOY3 = """
id: cd-toy3
title: 3R with a given inertia matrix
symbols: {a: frozen q2, b: frozen q3}
values: {a: 0.3, b: 0.3}
robot:
  joints: [R, R, R]
  model:
    B: [[3 + cos(q2), 1, 0], [1, 2, 0], [0, 0, 1]]
    g: [0, 0, 0]
asks:
  - kind: constrained_dynamics
"""


def test_at_state_decimals_are_printed_as_written():
    """at: {q1: 0.4, q2: 0.3, ...} is printed as 0.4, 0.3 (it read q_1 = 2/5, q_2 = 3/10); an entry written as a
    fraction stays one; the results keep the exact values."""
    p, sols, res = solved(TOY3 + "    h: q1 + q2 + q3 - 1\n    at: {q1: 0.4, q2: 0.35, q3: 1/4}\n")
    assert value(res, "q_at") == sp.Matrix([sp.Rational(2, 5), sp.Rational(7, 20), sp.Rational(1, 4)])
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        shown = out[out.index("t the given state"):].split(";")[0]
        assert shown.endswith(" ($q_{1} = 0.4$, $q_{2} = 0.35$, $q_{3} = \\frac{1}{4}$"), (fmt, shown)


@pytest.mark.parametrize("time, shown", [(1, "1"), (0.5, "0.5"), (2.0, "2")])
def test_simulation_duration_without_a_trailing_zero(time, shown):
    """simulate.time: 1 is read as 1.0 and was printed "for 1.0 s": now 1 s (0.5 s stays)."""
    p, sols, _ = solved(TOY3 + "    h: q1 + q2 + q3 - 1\n    simulate: {u: [0, 0, 1], q0: [0.4, 0.3, 0.3], "
                        f"time: {time}, points: 11}}\n")
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        assert f"for {shown} s from" in out and ".0 s" not in out, fmt


K_TEXTS = {  # (k = 1, k = 2) sentences of the report that depend on the number of constraints (md; tex alike)
    "h": ("h: q1 + q2 + q3 - 1", "h: [q1 + q2 + q3 - 1, q2 - q3]"),
    "A": ("A: [[1, 1, 1]]", "A: [[1, 1, 1], [0, 1, -1]]"),
    "freeze": ("freeze: {q3: b}", "freeze: {q2: a, q3: b}"),
}


@pytest.mark.parametrize("kind", list(K_TEXTS))
def test_sentences_agree_with_the_number_of_constraints(kind):
    """Freezing two coordinates read "is the holonomic constraint" and the other sentences said "the constraint",
    "the multiplier ... is" for k = 2; the simulation said "the multipliers λ(t)" for k = 1 and named h(q(t)) for
    Pfaffian constraints (the figure has no such panel). Each sentence with k = 1 and k = 2, h, A and freeze."""
    sim = "    simulate: {u: [0, 0, 1], q0: [0.4, 0.3, 0.3], time: 1, points: 11}\n"
    for k, spec in enumerate(K_TEXTS[kind], 1):
        s = "s" if k > 1 else ""
        p, sols, _ = solved(TOY3 + f"    {spec}\n" + sim + ("    at: {q1: 0.4, q2: 0.3, q3: 0.3}\n"
                                                            if kind != "A" else ""))
        md, tex = render(p, sols, "md"), render(p, sols, "tex")
        want = [f"Along the constraint{s} ($\\dot q = F v$)", f"along the constraint{s}\n",
                f"keep the constraint{s})", f"(on the constraint{s})",
                f"the associated multiplier{s} {'are' if k > 1 else 'is'}",
                f"the multiplier{s} $\\lambda(t)$ needed to keep the constraint{s}"]
        if kind != "A":
            want.append(f"the multiplier{s} as a function of the input {'are' if k > 1 else 'is'}")
            want.append(f"the constraint{s} $h(q(t))$, which {'stay' if k > 1 else 'stays'} at zero")
        else:
            assert "h(q(t))" not in md + tex and "needed to keep the constraint" + s + " and the motion $q(t)$." in md
        if kind == "freeze":
            want.append("$q_{2} = a$ and $q_{3} = b$ gives the 2 holonomic constraints $h(q)" if k > 1 else
                        "Freezing $q_{3} = b$ is the holonomic constraint $h(q)")
        else:
            want.append("the 2 other columns of $A$ form" if k > 1 else "the other column of $A$ is")
        for text in want:
            assert text in md, (kind, k, text)
            assert text.replace("\n", "") in tex.replace("\n", ""), (kind, k, text)
        wrong = "s" if k == 1 else ""
        assert f"constraint{wrong} ($\\dot q" not in md and f"multiplier{wrong} $\\lambda(t)$" not in md


FROZEN3 = R3 + "  - kind: constrained_dynamics\n    freeze: {q3: 0.4}\n    multiplier: false\n"


FROZEN_AT = """
id: cd-frozen-at
title: 2R with q2 frozen at q2d, evaluated at a state that leaves q2 and dq2 out
symbols: {q2d: frozen value of q2}
values: {q2d: pi/2}
robot:
  joints: [R, R]
  model:
    B: [[3 + 2*cos(q2), 1/2 + cos(q2)], [1/2 + cos(q2), 1/2]]
    g: [10*cos(q1) + 4*cos(q1 + q2), 4*cos(q1 + q2)]
asks:
  - kind: constrained_dynamics
    freeze: {q2: q2d}
    multiplier: false
    at: {q1: 0, dq1: 1}
"""


def test_frozen_coordinates_at_a_state_that_omits_them():
    """An at: state without the frozen q2, dq2: they are q2d (its value) and 0 there, as the freeze says: n and
    λ at the state had dq2 in them (c1 = -a2 sin q2 (2 dq1 dq2 + dq2^2)) and the equilibrium inputs kept the
    symbol q2d. λ = (A B⁻¹ Aᵀ)⁻¹ A B⁻¹ (n - u) with B = [[3, 1/2], [1/2, 1/2]], n = (10, 1) by hand."""
    p, sols, res = solved(FROZEN_AT)
    dq2, q2d = p.names["dq2"], p.names["q2d"]
    u1, u2 = p.robot.inputs
    at = next(st for st in sols[0].steps if st.name == "at").data
    assert list(at["nvec"]) == [10, 1] and at["state"][dq2] == 0
    assert sp.simplify(res["lambda_at"].value - (u1 / 6 - u2 - sp.Rational(2, 3))) == 0
    assert not value(res, "u_eq_at").free_symbols & {q2d, dq2} and value(res, "u_eq_at")[0] == 10


def test_values_at_a_state_keep_whole_coefficients_whole():
    """_num evaluates a long value at a state with 15-digit floats; a whole coefficient stays an integer (2 a₂ τ,
    -u₂, not 2.0 a₂ τ, -1.0 u₂, also when the float is 1.0000000000000002), the others are floats."""
    from solver.interaction.constraints import _num
    a1, a2, u1, u2, tau = sp.symbols("a1 a2 u1 u2 tau", real=True)
    r3, c, s_ = sp.sqrt(3), sp.cos(sp.Rational(3, 10)), sp.sin(sp.Rational(1, 5))
    e = (r3 * a1 * a2 ** 2 + 2 * a2 * tau - u2 + r3 * u1 / 7 + c * a1 * u1 * tau + 5 * r3 * a1 ** 3 * u1 ** 2
         + s_ * a2 * u2 ** 2 + 3 * a1 * a2 * tau + c * s_ * a1 ** 2 * a2 ** 2 * tau ** 3 - r3 * c * u1 * u2 * a2 ** 4)
    out = _num(e).as_coefficients_dict()
    assert out[a2 * tau] == 2 and out[u2] == -1 and out[a1 * a2 * tau] == 3
    floats = [v for v in out.values() if v.is_Float]
    assert len(floats) == 7 and all(abs(f - round(f)) > 1e-9 for f in floats)
    assert _num(sp.Float(1.0000000000000002) * u1 * u2 + e).as_coefficients_dict()[u1 * u2] == 1


def test_frozen_velocities_are_zero_in_the_printed_reduced_terms():
    """With freeze: {q3: 0.4}, Fᵀn kept the velocity of the frozen joint (terms in q̇3) while the spec takes it
    on the constraint, n_a(q_a, q_b,d, q̇_a, 0): now Fᵀn, Eᵀn, FᵀBḞ, EᵀBḞ are free of q3 and q̇3, equal to the
    blocks of n at q3 = 0.4, q̇3 = 0, and along a motion simulated with the Lagrange (KKT) system the printed
    terms give the reduced model and the reaction."""
    p, sols, res = solved(FROZEN3)
    dm = derive(p.robot)
    q, dq, u, ddq = list(p.robot.q), list(p.robot.dq), list(p.robot.inputs), list(p.robot.ddq)
    at = {q[2]: sp.Rational(2, 5), dq[2]: 0}
    nvec = (dm.c + dm.g).xreplace(at)
    assert (dm.c + dm.g)[:2, 0].xreplace({q[2]: sp.Rational(2, 5)}).has(dq[2])  # (the test can fail)
    for name in ("Ftn", "Etn", "FtBFdot", "EtBFdot"):
        assert not value(res, name).free_symbols & {q[2], dq[2]}, name
    assert all(zero(a - b) for a, b in zip(value(res, "Ftn"), nvec[:2, 0]))
    assert zero(value(res, "Etn")[0] - nvec[2])
    m = Model(p, sp.Matrix([q[2] - sp.Rational(2, 5)]))
    t = sp.Symbol("t")
    fu = sp.lambdify([t] + q + dq, dm.g + sp.Matrix([3 * sp.sin(2 * t), sp.cos(t), 1]), "numpy")
    s = solve_ivp(lambda tt, x: np.concatenate([x[3:], m.kkt(x, np.ravel(fu(tt, *x)))[0]]), (0, 1.5),
                  [0.3, 0.2, 0.4, 0.5, -0.7, 0.0], t_eval=np.linspace(0, 1.5, 7), rtol=1e-10, atol=1e-12)
    assert s.success and np.max(np.abs(s.y[:2, -1] - [0.3, 0.2])) > 0.1 and np.max(np.abs(s.y[2] - 0.4)) < 1e-9
    v, dv = sp.Matrix(dq[:2]), sp.Matrix(ddq[:2])
    lhs = value(res, "reduced_inertia") * dv + value(res, "FtBFdot") * v + value(res, "Ftn") - value(res, "Ftu")
    lam = value(res, "EtBF") * dv + value(res, "EtBFdot") * v + value(res, "Etn") - value(res, "Etu")
    for j, tt in enumerate(s.t):
        x = s.y[:, j]
        uu = np.ravel(fu(tt, *x))
        qdd, reaction = m.kkt(x, uu)
        sub = dict(zip(q + dq + u + ddq, [*x, *uu, *qdd]))
        assert max(abs(float(e.xreplace(sub))) for e in lhs) < 1e-9
        assert abs(float(lam[0].xreplace(sub)) - reaction[0]) < 1e-9
    for fmt in ("md", "tex"):
        assert "at the frozen values, $q_b = q_{b,d}$ and $\\dot q_b = 0$)" in render(p, sols, fmt), fmt


def test_equilibrium_and_input_sentences_are_spaced():
    """';the associated' after u_eq,min (both formats) and, in md, 'solved for the input: $u$ $= …$,$$u = …'
    (broken math, the display glued to the text): now '…;' and 'the associated' on their own lines, and one
    formula '$u = …$ along the constraint:' before the display."""
    p, sols, _ = solved(TOY3 + "    h: q1 + q2 + q3 - 1\n")
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    for out in (md, tex):
        assert ";the associated" not in out and "$;\nthe associated" in out.replace(";\\]", "$;")
        assert "solved for the input, $u = B(F\\dot v_d + \\dot F v) + n - A^T\\lambda_d$ along the constraint:" in out
    assert "the constrained model is solved for the input, $u = B(F\\dot v_d + \\dot F v) + n - A^T\\lambda_d$ " \
           "along the constraint:\n$$u = " in md
    assert "($\\lambda = 0$) needs $u = g(q)$:" in tex  # (it said G u without an input map)


def test_lambda_d_symbol_is_not_repeated():
    """lambda_d: lambdad (printed \\lambda_d) read 'λ = λ_d = λ_d'; now 'λ = λ_d'."""
    from conftest import PROBLEMS
    p = load_problem(PROBLEMS / "2018-07-11-ex4.yaml")
    sols = solve_problem(p)
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        assert "\\lambda = \\lambda_d = \\lambda_d" not in out and "with $\\lambda = \\lambda_d$, the" in out, fmt
        assert "with $\\lambda = \\lambda_d = 0$, the" in out, fmt  # (the first ask: λ_d = 0 is said)


@pytest.mark.parametrize("spec, pfaffian", [("h: q1 + q2 + q3 - 1", False), ("A: [[1, 1, 1]]", True)])
def test_multiplier_paragraph_names_h_only_for_holonomic_constraints(spec, pfaffian):
    """'any motion started with h(q0) = 0' was said of Pfaffian constraints, which have no h."""
    p, sols, _ = solved(TOY3 + f"    {spec}\n")
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        assert "motion of this model started with " + ("" if pfaffian else "$h(q_0) = 0$, ") + \
            "$A(q_0)\\dot q_0 = 0$ keeps" in out, fmt


def test_rank_sentences_with_one_constraint():
    """k = 1 read 'every 1×1 minor of A' and 'no configuration makes all 1×1 minors of A vanish'; the note 'which
    depends on the parameters' was said of numeric h(q), and 'a coordinate left as itself is arbitrary' of
    configurations without one; a selected pseudo-velocity read 'q̇3 = q̇3'."""
    p, sols, _ = solved(TOY3 + "    h: q1 + q2 + q3 - 1\n")
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "The rank never drops (no configuration makes $A(q) = 0$)." in md
    assert "The rank never drops: the entries of $A$ never vanish together." in tex
    assert "1×1" not in md and "1$\\times$1" not in tex
    pseudo = "The pseudo-velocities and their derivatives are\n"
    assert pseudo + "$$v = D\\dot q = \\begin{bmatrix} \\dot{q}_{2}" in md
    assert pseudo + "\\[v = D\\dot q = \\begin{bmatrix} \\dot{q}_{2}" in tex
    assert md.count("\\dot v = D\\ddot q + \\dot D\\dot q = \\begin{bmatrix} \\ddot{q}_{2}") == 1
    p, sols, _ = solved(TOY3 + "    h: cos(q1) + cos(q1 + q2)\n    reduced: false\n")
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "The rank drops where $A(q) = 0$ (every entry vanishes):" in md
    assert "The rank drops where $A(q) = 0$ (every entry vanishes), at" in tex
    for out in (md, tex):  # q = (0, pi, q3), ...: h = 0 on two of them, a number on all
        assert "(a coordinate left as itself is arbitrary); only those with $h(q) = 0$ are on the constraint." in out
        assert "depends on the parameters" not in out
    p, sols, _ = solved(TOY3 + "    h: cos(q1) + cos(q1 + q2) - 3\n    reduced: false\n")
    for fmt in ("md", "tex"):
        assert "arbitrary); none of them satisfies $h(q) = 0$: on the constraint the rank never drops." in \
            render(p, sols, fmt)


def test_parameter_values_are_printed_as_written():
    """values: {a: 0.3} was printed 'parameters a = 3/10' in the at: paragraph; now 0.3, the value stays exact."""
    p, sols, res = solved(TOY3 + "    h: q1 + q2 + q3 - 1\n    at: {q1: 0.4, q2: 0.35, q3: 1/4}\n")
    assert p.values[p.names["a"]] == sp.Rational(3, 10)
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        assert "; parameters $a = 0.3$, $b = 0.3$)" in out, fmt


def test_equilibrium_input_at_the_state_in_the_singular_when_unique():
    """'At rest there, the equilibrium inputs are u_eq = (…)' was said of a unique input."""
    text = TOY3.replace("    g: [0, 0, 0]\n", "    g: [0, 0, sin(q3)]\n  input_map: [[1, 0], [0, 1], [0, 0]]\n"
                        "  inputs: [u1, u2]\n") + "    h: q3 - 1\n    D: [[1, 0, 0], [0, 1, 0]]\n    at: {q3: 1}\n"
    p, sols, res = solved(text)
    assert not value(res, "u_eq_at").free_symbols & set(p.robot.inputs)
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        assert "At rest there, the equilibrium input is" in out and "equilibrium inputs are" not in out, fmt
    assert "\\[\\lambda = \\sin {1}.\\]\nThe input giving" in out  # (tex: the sentence ended without a period)
    p, sols, _ = solved(TOY3 + "    h: q1 + q2 + q3 - 1\n    at: {q1: 0.4, q2: 0.35, q3: 1/4}\n")
    assert "At rest there, the equilibrium inputs are" in render(p, sols, "md")


def test_singular_skips_the_solver_when_the_zeros_move_with_the_parameters(monkeypatch):
    """_moving_zeros (the shortcut of _singular) proves only "not computed" answers, the ones the solver gives."""
    import solver.interaction.constraints as C
    a, b, c = sp.symbols("a b c", positive=True)
    q1, q2 = sp.symbols("q1 q2", real=True)
    moving = [a * sp.sin(q1) - b * sp.cos(q1)]                  # q1 = atan2(b, a): moves with a, b
    fixed = [a * b * sp.sin(q2)]                                # q2 = 0, pi for every a, b
    mixed = [a * sp.sin(q1) + c * sp.sin(q1 + q2), sp.sin(q2)]  # q1, q2 = 0 / pi: fixed
    assert C._moving_zeros(moving, [q1, q2]) is True
    assert C._moving_zeros(fixed, [q1, q2]) is False
    assert C._moving_zeros(mixed, [q1, q2]) is False
    fixed3 = [a * sp.sin(q1), a * sp.sin(q1) + c * sp.sin(q1 + q2), c * sp.sin(q1 + q2)]   # one-term minors
    assert C._moving_zeros(fixed3, [q1, q2]) is False   # (a rounding error there is not "far from zero")
    assert C._moving_zeros([a * q1 - b], [q1, q2]) is False      # a coordinate outside sin/cos: undecided
    assert C._moving_zeros([sp.sin(q1 - a)], [q1, q2]) is False  # a parameter inside sin: undecided
    fast = C._singular(sp.Matrix([moving]), [q1, q2], 1)
    monkeypatch.setattr(C, "_moving_zeros", lambda minors, q: False)
    assert fast == C._singular(sp.Matrix([moving]), [q1, q2], 1) == ([], False, False)   # the solver's answer


def test_factor_terms_without_common_factors_matches_sympy():
    """_coprime_terms skips gcd_terms only when it would return the sum as it is."""
    import solver.interaction.constraints as C
    a, b, x, y, q1, q2 = sp.symbols("a b x y q1 q2")
    cases = [
        a * sp.cos(q1) + 2 * b * sp.sin(q1 + q2) + 3 * x * y,            # coprime: the sum as it is
        3 * (2 * a + 2 * b) * x + y,                                      # a base with content: gcd_terms moves it
        a * x * sp.cos(q1) + 2 * a * y * sp.sin(q2) - 4 * a / x,          # a in every term
        x / y + a / y + sp.sqrt(y) * b,                                   # 1/y in two terms only
        (a + b) ** 2 * x + (a + b) * y + sp.sqrt(a + b) * b * x,          # a + b and sqrt(a + b)
        x * (a * sp.cos(q1) + b * sp.cos(q2)) + y * (2 * a * sp.cos(q1) + 2 * b * sp.cos(q2)),
        sp.Add(sp.Mul(-3, a + b, evaluate=False), x * sp.cos(q1), -(a - b) * sp.sin(q2)),   # rebuilt: -3a - 3b
    ]
    for e in cases:
        assert C.factor_terms(e) == sp.factor_terms(e), e
    assert C._coprime_terms(list(cases[0].args)) is True
    assert C._coprime_terms(list(sp.Add.make_args(3 * (2 * a + 2 * b) * x + y))) is False
    assert C._coprime_terms(list(cases[2].args)) is False


@pytest.mark.parametrize("name, G", [("2017-07-11-ex2", False), ("2022-02-03-ex3", True)])
def test_static_equilibrium_sentence_names_the_input_map_only_when_there_is_one(name, G):
    """Without an input map (G = I) the equilibrium condition reads Fᵀ(u − g) = 0 and λ = Eᵀ(g − u_eq); with
    one, Fᵀ(G u − g) = 0, in Markdown and LaTeX alike."""
    p = load_problem(PROBLEMS / f"{name}.yaml")
    sols = solve_problem(p)
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    if G:
        assert "F^T(G u - g) = 0" in md and "F^T(G u - g) = 0" in tex and "F^T G\\,u = F^T g" in md
    else:
        assert "F^T(u - g) = 0" in md and "F^T(u - g) = 0" in tex
        assert "G u" not in md.split("Static equilibrium")[1].split("**")[1]
        assert "E^T(g - u_{eq})" in md and "E^T(g - u_{eq})" in tex and "F^T G" not in tex


def test_values_at_a_state_exact_when_they_read_well_decimals_otherwise():
    """At an `at:` state: short exact values stay (2 − √51/10, acos(7/10), √3/12 (6 a4 + a1 q̇2²): the surd a
    common factor); long ones with surds inside become decimals with the symbols kept; a matrix with a decimal
    entry shows its other irrational numbers as decimals too (2022-01-11-ex3's u(0) = (185.8, 28.65))."""
    from solver.interaction.constraints import _num
    a1, a4, dq2, u2 = sp.symbols("a1 a4 dq2 u2")
    s51 = sp.sqrt(51)
    for keep in (2 - s51 / 10, sp.acos(sp.Rational(7, 10)), sp.sqrt(3) * (6 * a4 + a1 * dq2 ** 2) / 12):
        assert _num(keep) == keep
    long = (5000 * s51 * u2 + 624897 * s51 + 28767825) / (500 * (7 * s51 + 255))
    out = _num(long)
    assert out.atoms(sp.Float) and out.free_symbols == {u2} and not out.atoms(sp.Pow)
    assert float((out - long).subs(u2, 3)) == pytest.approx(0, abs=1e-9)
    short = -2 * s51 * (625 * u2 - 20601) / (125 * (7 * s51 + 255))   # few operations, a surd sum below
    assert _num(short).atoms(sp.Float) and not _num(short).atoms(sp.Pow)
    M = _num(sp.Matrix([long.subs(u2, 1), 5 * sp.sqrt(1326) / 663, sp.Rational(3, 4)]))
    assert M[0].is_Float and M[1].is_Float and M[2] == sp.Rational(3, 4)
    assert float(M[1]) == pytest.approx(float(5 * sp.sqrt(1326) / 663), rel=1e-14)


# ------------------------------------------------------------------ the terms of an unshown reduced model (lazy)
DEFERRED_TERMS = ["reduced_inertia", "FtBFdot", "Ftn", "Ftu", "EtBF", "EtBFdot", "Etn", "Etu", "reduced_model",
                  "vdot", "lambda_reduced"]


def test_terms_of_an_unshown_reduced_model_are_computed_when_read():
    """show without reduced_model: its terms are not computed by the solve (Deferred, JSON only with --details);
    read, they equal the terms of the ask that shows them, and u_dv (its check) and the report do not need them."""
    import json

    from solver.results import Deferred
    text = R2C + "    dv_d: 0.3\n    show: [reduced, u_dv]\n"
    p, sols, res = solved(text)
    full = solved(R2C + "    dv_d: 0.3\n")[2]
    for name in DEFERRED_TERMS:
        r = res[name]
        assert r.detail and type(object.__getattribute__(r, "value")) is Deferred, name
    assert res["u_dv_check"].value is True
    assert "F^T B F" not in render(p, sols, "md")
    plain, details = json.loads(render(p, sols, "json")), json.loads(render(p, sols, "json", details=True))
    assert not set(DEFERRED_TERMS) & set(plain["results"])
    for name in DEFERRED_TERMS:
        assert sp.simplify(res[name].value - full[name].value) == 0 if res[name].kind == "scalar" else \
            (res[name].value - full[name].value).applyfunc(sp.simplify) == sp.zeros(*full[name].value.shape)
        assert details["results"][name]["expr"] == str(full[name].value)


def test_check_of_the_inputs_fails_for_other_inputs_or_multipliers(monkeypatch):
    """u_dv_check tests the residual of the constrained model in double precision: an input off by 10⁻³ on one
    joint, or a multiplier off by 10⁻³, fails it."""
    import solver.interaction.constraints as C
    orig = C._inputs_check
    for bump in ("u", "lam"):
        def wrong(sm, redx, u, u_dv, dv_d, lam_d, bump=bump):
            if bump == "u":
                u_dv = u_dv + sp.Matrix([sp.Rational(1, 1000)] + [0] * (len(u_dv) - 1))
            else:
                lam_d = lam_d + sp.Matrix([sp.Rational(1, 1000)] * lam_d.rows)
            return orig(sm, redx, u, u_dv, dv_d, lam_d)
        monkeypatch.setattr(C, "_inputs_check", wrong)
        res = all_results(solve_problem(load_problem_text(R3_K2)))
        assert res["u_dv_check"].value is False, bump


def test_equilibrium_at_the_state_is_the_symbolic_one_substituted(monkeypatch):
    """At an `at:` state the equilibrium is the symbolic one with the state substituted (its pivot determinants
    are not 0 there); solved again at the state otherwise (here forced), with the same values."""
    import solver.interaction.constraints as C
    q0 = start_k2()
    state = ", ".join(f"q{i + 1}: {float(x):.17g}" for i, x in enumerate(q0)) + ", dq1: 0, dq2: 0, dq3: 0"
    text = R3_K2 + f"    at: {{{state}}}\n"
    names = ["u_eq_at", "u_eq_min_at", "lambda_eq_at", "u_eq_lambda0_at"]
    calls = []
    orig = C._equilibrium
    monkeypatch.setattr(C, "_equilibrium", lambda *a: calls.append(a[-1] is not None) or orig(*a))
    fast = all_results(solve_problem(load_problem_text(text)))
    assert calls == [False]                       # the symbolic one only
    monkeypatch.setattr(C, "_equilibrium", lambda *a: (calls.append(a[-1] is not None), orig(*a)[0], None)[1:])
    slow = all_results(solve_problem(load_problem_text(text)))   # (no determinants: not known to hold there)
    assert calls == [False, False, True]          # solved again at the state
    u = list(load_problem_text(text).robot.inputs)
    pick = dict(zip(u, [1.3, -0.7, 2.1]))
    for name in names:
        a, b = (np.array(sp.Matrix([r[name].value]).xreplace(pick).evalf(), float) for r in (fast, slow))
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12), name
