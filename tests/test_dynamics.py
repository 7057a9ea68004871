"""The Lagrangian solver against independent derivations and structural properties."""
import random

import pytest
import sympy as sp
from conftest import R2_ROBOT, error_found_without_solving

import solver.dynamics.model as model
from solver.dynamics.model import derive
from solver.math.rigid import dh_chain
from solver.math.simplify import is_zero, tidy
from solver.solve import validate_problem
from solver.spec import load_problem_text
from solver.spec.robot import Body, Robot


def planar_nR(n: int) -> Robot:
    q = list(sp.symbols(f"q1:{n + 1}", real=True))
    dq = list(sp.symbols(f"dq1:{n + 1}", real=True))
    ddq = list(sp.symbols(f"ddq1:{n + 1}", real=True))
    l = sp.symbols(f"l1:{n + 1}", positive=True)
    d = sp.symbols(f"d1:{n + 1}", positive=True)
    m = sp.symbols(f"m1:{n + 1}", positive=True)
    I = sp.symbols(f"I1:{n + 1}", positive=True)
    g0 = sp.Symbol("g0", positive=True)
    bodies = []
    for i in range(n):
        th = [sum(q[:j + 1]) for j in range(i + 1)]
        x = sum(l[j] * sp.cos(th[j]) for j in range(i)) + d[i] * sp.cos(th[i])
        y = sum(l[j] * sp.sin(th[j]) for j in range(i)) + d[i] * sp.sin(th[i])
        bodies.append(Body(f"link {i+1}", m[i], sp.Matrix([x, y, 0]), sp.Matrix([0, 0, sum(dq[:i + 1])]),
                           sp.diag(0, 0, I[i])))
    return Robot(q, dq, ddq, ["R"] * n, bodies, sp.Matrix([0, -g0, 0]), inputs=list(sp.symbols(f"u1:{n+1}")))


def lagrange_residual(robot: Robot, dm) -> sp.Matrix:
    """d/dt ∂L/∂q̇ - ∂L/∂q computed directly from L = T - U, minus the solver's model."""
    L = dm.T - dm.U
    out = []
    for k, (qk, dqk) in enumerate(zip(robot.q, robot.dq)):
        p = sp.diff(L, dqk)
        dp = sum(sp.diff(p, a) * b for a, b in zip(robot.q + robot.dq, robot.dq + robot.ddq))
        out.append(sp.expand(dp - sp.diff(L, qk) - dm.lhs[k]))
    return sp.Matrix(out)


def test_planar_2r_matches_textbook():
    r = planar_nR(2)
    dm = derive(r)
    (q1, q2), (dq1, dq2) = r.q, r.dq
    l1, d2, m2 = sp.symbols("l1 d2 m2", positive=True)
    d1, m1, I1, I2, g0 = sp.symbols("d1 m1 I1 I2 g0", positive=True)
    b11 = I1 + m1 * d1**2 + I2 + m2 * (l1**2 + d2**2 + 2 * l1 * d2 * sp.cos(q2))
    b12 = I2 + m2 * (d2**2 + l1 * d2 * sp.cos(q2))
    assert is_zero(dm.B[0, 0] - b11) and is_zero(dm.B[0, 1] - b12) and is_zero(dm.B[1, 1] - I2 - m2 * d2**2)
    h = m2 * l1 * d2 * sp.sin(q2)
    assert is_zero(dm.c[0] + h * (2 * dq1 * dq2 + dq2**2)) and is_zero(dm.c[1] - h * dq1**2)
    g1 = (m1 * d1 + m2 * l1) * g0 * sp.cos(q1) + m2 * d2 * g0 * sp.cos(q1 + q2)
    assert is_zero(dm.g[0] - g1) and is_zero(dm.g[1] - m2 * d2 * g0 * sp.cos(q1 + q2))
    assert dm.skew is True


@pytest.mark.parametrize("n", [2, 3])
def test_model_equals_lagrange_equations(n):
    r = planar_nR(n)
    dm = derive(r)
    assert all(is_zero(x) for x in lagrange_residual(r, dm))


def test_spatial_dh_robot_properties():
    """Spatial 3R (DH, symbolic lengths): S q̇ = c, Ḃ - 2S skew at random states, B positive definite."""
    q = list(sp.symbols("q1:4", real=True)); dq = list(sp.symbols("dq1:4", real=True))
    ddq = list(sp.symbols("ddq1:4", real=True))
    d1, a2, a3, g0 = sp.symbols("d1 a2 a3 g0", positive=True)
    rows = [(0, sp.pi / 2, d1, q[0]), (a2, 0, 0, q[1]), (a3, 0, 0, q[2])]
    frames = dh_chain(rows, "standard")
    m = sp.symbols("m1:4", positive=True)
    bodies = []
    from solver.math.rigid import omega_from_rotation
    for i, A in enumerate(frames):
        R, p = A[:3, :3], A[:3, 3]
        r_c = sp.Matrix([-[0, a2, a3][i] / 2, 0, 0])
        Ixx, Iyy, Izz = sp.symbols(f"I{i+1}xx I{i+1}yy I{i+1}zz", positive=True)
        bodies.append(Body(f"l{i}", m[i], (p + R * r_c).applyfunc(tidy), omega_from_rotation(R, q, dq),
                           sp.diag(Ixx, Iyy, Izz), R, "link"))
    r = Robot(q, dq, ddq, ["R"] * 3, bodies, sp.Matrix([0, 0, -g0]), inputs=list(sp.symbols("u1:4")))
    dm = derive(r)
    assert dm.skew is True
    assert all(is_zero(x) for x in (dm.S * sp.Matrix(dq) - dm.c))
    rng = random.Random(3)
    syms = sorted(dm.B.free_symbols | dm.S.free_symbols, key=str)
    for _ in range(5):
        pt = {s: rng.uniform(0.2, 2.0) for s in syms}
        Bn = sp.matrix2numpy(dm.B.subs(pt), dtype=float)
        import numpy as np
        assert np.all(np.linalg.eigvalsh(Bn) > 0)
        Bdot = sum((dm.B.diff(a) * b for a, b in zip(q, dq)), sp.zeros(3, 3))
        N = sp.matrix2numpy((Bdot - 2 * dm.S).subs(pt), dtype=float)
        assert np.allclose(N, -N.T)
    assert all(is_zero(x) for x in lagrange_residual(r, dm))


def test_extra_terms_friction_and_input_map():
    """Elastic joint (motor coordinate, spring), viscous friction, and a non-identity input map."""
    q, th = sp.symbols("q theta", real=True)
    dq, dth = sp.symbols("dq dtheta", real=True)
    ddq, ddth = sp.symbols("ddq ddtheta", real=True)
    m, d, I, Bm, K, fv, g0 = sp.symbols("m d I Bm K fv g0", positive=True)
    link = Body("link", m, sp.Matrix([d * sp.cos(q), d * sp.sin(q), 0]), sp.Matrix([0, 0, dq]), sp.diag(0, 0, I))
    r = Robot([q, th], [dq, dth], [ddq, ddth], ["R"], [link], sp.Matrix([0, -g0, 0]),
              kinetic_extra=[Bm * dth**2 / 2], potential_extra=[K * (q - th)**2 / 2],
              friction=sp.diag(0, fv), input_map=sp.Matrix([0, 1]), inputs=[sp.Symbol("tau")])
    dm = derive(r)
    assert dm.B == sp.diag(I + m * d**2, Bm)
    assert is_zero(dm.g[0] - (m * g0 * d * sp.cos(q) + K * (q - th))) and is_zero(dm.g[1] + K * (q - th))
    assert is_zero(dm.lhs[1] - (Bm * ddth - K * (q - th) + fv * dth))


def test_one_derivation_per_robot_each_caller_its_copy(monkeypatch):
    """The asks of a problem share one derivation of its robot; each gets matrices it may change on its own."""
    import solver.dynamics.model as model
    calls = []
    real = model._derive
    monkeypatch.setattr(model, "_derive", lambda r: calls.append(r) or real(r))
    r = planar_nR(2)
    a, b = derive(r), derive(r)
    assert len(calls) == 1 and a.B == b.B and a.B is not b.B
    b00 = a.B[0, 0]
    b.B[0, 0] = 0
    b.notes.append("changed")
    c = derive(r)
    assert c.B[0, 0] == b00 == a.B[0, 0] and not c.notes and len(calls) == 1
    derive(planar_nR(2))                        # another robot object (equal data): derived again
    assert len(calls) == 2


@pytest.mark.parametrize("ask, words", [
    ("  - {kind: dynamic_model, at: {q1: 0, ddq3: 1}}\n", "'ddq3' in at: is not a coordinate"),
    ("  - {kind: dynamic_model, at: {q1: q3}}\n", "unknown name 'q3'"),
    ("  - {kind: dynamic_model, ranges: {q2: [1, 0]}}\n", "empty plot range for q2"),
    ("  - {kind: dynamic_model, plots: true, ranges: {x: [0, 1]}}\n", "'x' in ranges: is not a coordinate"),
])
def test_check_finds_bad_options_without_deriving(monkeypatch, ask, words):
    """`at:` and `ranges:` are read by the kind's validate hook (`check`) as by solving: the same error, and the
    model is not derived for it."""
    text = "id: x\ntitle: x\nsymbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, g0: g0}\n" + \
        R2_ROBOT + "asks:\n" + ask
    assert words in error_found_without_solving(text)
    monkeypatch.setattr(model, "derive", lambda robot: pytest.fail("derived"))
    assert len(validate_problem(load_problem_text(text))) == 1
