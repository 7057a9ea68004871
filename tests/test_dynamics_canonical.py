"""The model computed in the canonical trigonometric-polynomial form: a six-joint arm by DH with generic centres of
mass against a numeric recursive Newton-Euler at random points, and the same printed forms as the entry-by-entry
path on library robots."""
import math
import random
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import solver.dynamics.canonical as canonical
import solver.dynamics.model as model
from solver.dynamics.model import derive
from solver.math import simplify
from solver.spec import load_problem, load_problem_text

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / "benchmarks" / "specs"


def rne(rows, links, gravity, q, dq, ddq):
    """Joint torques by the recursive Newton-Euler algorithm (standard DH, revolute joints), numerically.
    rows: (a, alpha, d, theta offset); links: (m, r_i in frame i, inertia 3x3 about the CoM in frame i)."""
    n = len(rows)
    z = np.array([0.0, 0.0, 1.0])
    Rs, ps = [], []
    for (a, al, d, th0), qi in zip(rows, q):
        th = th0 + qi
        ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
        Rs.append(np.array([[ct, -st * ca, st * sa], [st, ct * ca, -ct * sa], [0, sa, ca]]))
        ps.append(np.array([a, d * sa, d * ca]))  # O_{i-1} -> O_i in frame i
    w, wd, vd = np.zeros(3), np.zeros(3), -np.asarray(gravity, float)
    F, N = [], []
    for i in range(n):
        R, p = Rs[i], ps[i]
        m, r, I = links[i]
        w_new = R.T @ (w + z * dq[i])
        wd = R.T @ (wd + z * ddq[i] + np.cross(w, z * dq[i]))
        w = w_new
        vd = np.cross(wd, p) + np.cross(w, np.cross(w, p)) + R.T @ vd
        vc = vd + np.cross(wd, r) + np.cross(w, np.cross(w, r))
        F.append(m * vc)
        N.append(I @ wd + np.cross(w, I @ w))
    f, nm = np.zeros(3), np.zeros(3)
    tau = np.zeros(n)
    for i in reversed(range(n)):
        Rn = Rs[i + 1] if i + 1 < n else np.eye(3)
        p, r = ps[i], links[i][1]
        fn = Rn @ f
        nm = Rn @ nm + np.cross(p, fn) + np.cross(p + r, F[i]) + N[i]
        f = fn + F[i]
        tau[i] = nm @ (Rs[i].T @ z)
    return tau


def _numeric_robot(problem, values):
    """DH rows and links of a benchmark spec with parameter values substituted."""
    data = problem.located.data["robot"]["dh"]
    ev = lambda s: float(sp.sympify(str(s), locals={k: sp.Symbol(k) for k in values}).subs(values))  # noqa: E731
    rows = []
    for row in data["table"]:
        th = sp.sympify(str(row.get("theta", 0)))
        rows.append((ev(row.get("a", 0)), ev(row.get("alpha", 0)), ev(row.get("d", 0)),
                     float(th.subs({s: 0 for s in th.free_symbols}))))
    links = []
    for lk in data["links"]:
        inertia = [ev(x) for x in lk["inertia"]]
        links.append((ev(lk["mass"]), np.array([ev(x) for x in lk["com"]]), np.diag(inertia)))
    return rows, links


@pytest.mark.parametrize("spec", ["generic6r.yaml"])
def test_six_joint_arm_equals_newton_euler(spec):
    problem = load_problem(SPECS / spec)
    robot = problem.robot
    dm = derive(robot)
    assert dm.skew is True
    params = sorted({s for s in dm.lhs.free_symbols} - set(robot.q + robot.dq + robot.ddq), key=lambda s: s.name)
    args = robot.q + robot.dq + robot.ddq + params
    f = sp.lambdify(args, list(dm.lhs), "math")
    rng = random.Random(7)
    declared = [sp.Symbol(name) for name in problem.located.data["symbols"]]  # some do not enter the model
    for _ in range(3):
        values = {s: rng.uniform(0.5, 1.5) for s in declared}
        values.update({s: values[sp.Symbol(s.name)] for s in params})
        q = [rng.uniform(-3, 3) for _ in robot.q]
        dq = [rng.uniform(-1, 1) for _ in robot.q]
        ddq = [rng.uniform(-1, 1) for _ in robot.q]
        rows, links = _numeric_robot(problem, {s.name: v for s, v in values.items()})
        g0 = next(v for s, v in values.items() if s.name == "g0")
        ours = np.array(f(*q, *dq, *ddq, *[values[s] for s in params]))
        ref = rne(rows, links, [0, 0, -g0], q, dq, ddq)
        assert np.max(np.abs(ours - ref)) < 1e-9 * max(1.0, np.max(np.abs(ref))), (ours, ref)


@pytest.mark.parametrize("name", ["spatial3r.yaml", "planar4r.yaml"])
def test_canonical_path_prints_what_tidy_prints(name, monkeypatch):
    """The canonical computation and the entry-by-entry tidy path give identical expressions (canonical forms)."""
    robot = load_problem(SPECS / name).robot
    fast = derive(robot)
    monkeypatch.setattr(canonical, "derive_canonical", lambda r: None)
    monkeypatch.setattr(model, "_DERIVED", {})  # (derive keeps one model per robot: derived again here)
    simplify.tidy.cache_clear()
    slow = derive(robot)
    for field in ("T", "B", "C", "c", "S", "skew", "U", "g", "lhs"):
        assert getattr(fast, field) == getattr(slow, field), field
    for a, b in zip(fast.bodies, slow.bodies):
        assert (a.pc, a.vc, a.v2, a.T, a.U) == (b.pc, b.vc, b.v2, b.T, b.U)
    # the report's velocity terms: split in the ring (canonical) = regrouped from the expressions (velocity_terms)
    assert all(b.given("terms") for b in fast.bodies) and not any(b.given("terms") for b in slow.bodies)
    fv, sv = model.ModelView(fast, robot), model.ModelView(slow, robot)
    assert (fv.vc, fv.v2, fv.T2) == (sv.vc, sv.v2, sv.T2)
    assert len(fv.T2[-1]) > 2  # several velocity monomials: the split is exercised


def test_data_outside_the_algebra_take_the_general_path():
    """Floats or a parameter in a denominator: derive_canonical declines, derive still works."""
    text = (SPECS / "planar4r.yaml").read_text().replace("com: [d1 - l1, 0, 0]", "com: [d1/l2 - l1, 0, 0.5]")
    robot = load_problem_text(text).robot
    assert canonical.derive_canonical(robot) is None
    dm = derive(robot)
    assert dm.skew is True and dm.B.shape == (4, 4)


def test_large_model_report_defines_parameter_groupings_once(monkeypatch):
    """Past LARGE_MODEL the report writes B, C_k and g with K_j (each sum of parameters defined once), says so, and
    B with the K_j substituted back is the model's B; the JSON keeps the full expressions."""
    import json

    from solver.publish.render import render
    from solver.solve import solve_problem
    monkeypatch.setattr(model, "LARGE_MODEL", 50)
    problem = load_problem(SPECS / "spatial3r.yaml")
    sols = solve_problem(problem)
    step = sols[0].steps[0].data
    abbr, dm = step["abbr"], step["dm"]
    assert abbr is not None and abbr["defs"]
    defs = dict(abbr["defs"])
    assert len(set(defs.values())) == len(defs)  # each sum once
    assert all(not (e.free_symbols & set(problem.robot.q)) for e in defs.values())
    assert (abbr["B"].xreplace(defs) - dm.B).applyfunc(sp.expand) == sp.zeros(3, 3)
    assert all((a.xreplace(defs) - b).applyfunc(sp.expand) == sp.zeros(3, 3) for a, b in zip(abbr["C"], dm.C))
    md = render(problem, sols, "md")
    assert "This model is large" in md and "Parameter groupings" in md and "K_{1}" in md
    assert "Kinetic energy" not in md  # per-body quantities: JSON with --details
    data = json.loads(render(problem, sols, "json"))
    assert "K_" not in data["results"]["B"]["expr"]


def test_per_body_quantities_are_printed_only_when_read(monkeypatch):
    """The per-body results (p_c, v_c, T_i, U_i: intermediate, in JSON only with --details) are Deferred: solving and
    the JSON without details never print them; reading one prints it once, equal to the general path's; pickling
    (results sent back by a worker) computes them."""
    import pickle

    from solver.publish.render import render
    from solver.results import Deferred, Result
    from solver.solve import solve_problem
    problem = load_problem(SPECS / "planar4r.yaml")
    made = []
    real = canonical.TrigAlgebra.expr
    monkeypatch.setattr(canonical.TrigAlgebra, "expr", lambda self, a: made.append(1) or real(self, a))
    sol = solve_problem(problem)[0]
    printed = len(made)
    render(problem, [sol], "json")
    assert len(made) == printed
    raw = {k: object.__getattribute__(r, "value") for k, r in sol.results.items()}
    assert all(type(raw[f"{x}{i}"]) is Deferred for x in ("pc", "vc", "T", "U") for i in range(1, 5))
    monkeypatch.setattr(canonical, "derive_canonical", lambda r: None)
    slow = derive(load_problem(SPECS / "planar4r.yaml").robot)
    assert sol.results["T2"].value == slow.bodies[1].T and len(made) > printed
    again = len(made)
    assert sol.results["T2"].value == slow.bodies[1].T and len(made) == again  # kept
    back = pickle.loads(pickle.dumps(sol.results["vc3"]))
    assert isinstance(back, Result) and back.value == slow.bodies[2].vc
    with pytest.raises(ValueError):
        sol.add("x", Deferred(lambda: 1))


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_dh_kinematics_canonical_equals_tidied_products(convention):
    """The loader's DH kinematics in the canonical form (frames, link angular velocities, centres of mass) equal
    the products tidied entry by entry, on a spatial R-P-R arm no exercise uses (a symbolic twist, π/2 offsets, a
    base), and ⁱωᵢ equals vee(Rᵀ Ṙ) of the chain numerically."""
    from solver.math.rigid import dh_chain, dh_forms, dh_omegas, vee
    from solver.math.simplify import tidy
    q = sp.symbols("q1:4")
    dq = sp.symbols("dq1:4")
    l1, l2, d1, al = sp.symbols("l1 l2 d1 alpha")
    rows = [(l1, sp.pi / 2, d1, q[0]), (l2, al, q[1], -sp.pi / 2), (0, -sp.pi / 2, 0, q[2] + sp.pi / 2)]
    rows = [tuple(sp.sympify(x) for x in r) for r in rows]
    coms = [sp.Matrix([d1 - l1, 0, l2]), sp.Matrix([0, d1 / 2, 0]), sp.Matrix([0, 0, l1])]
    base = sp.Matrix([[0, -1, 0, 1], [1, 0, 0, 0], [0, 0, 1, l1], [0, 0, 0, 1]])
    forms = dh_forms(rows, convention, q, dq, coms, base)
    F, W, C = ([get(i) for i in range(3)] for get in (forms.frame, forms.omega, forms.centre))
    F0 = [(base * A).applyfunc(tidy) for A in dh_chain(rows, convention)]
    assert F == F0
    assert W == dh_omegas(rows, convention, q, dq)
    assert C == [(A[:3, 3] + A[:3, :3] * r).applyfunc(tidy) for A, r in zip(F0, coms)]
    point = {x: v for x, v in zip([*q, *dq, l1, l2, d1, al], [0.3, -0.7, 1.1, 0.5, -1.3, 0.8, 1.2, 0.9, 0.4, 0.6])}
    for A, w in zip(F, W):
        R = A[:3, :3]
        Rdot = sum((R.diff(qk) * v for qk, v in zip(q, dq)), sp.zeros(3, 3))
        expect = vee(R.T * Rdot).xreplace(point)
        assert max(abs(float(x)) for x in (expect - w.xreplace(point))) < 1e-12


def test_dh_kinematics_falls_back_outside_the_canonical_form():
    """Floats and √3 leave the canonical form: the entry-by-entry path gives the kinematics."""
    from solver.math.rigid import dh_kinematics
    q, dq = sp.symbols("q1:3"), sp.symbols("dq1:3")
    rows = [tuple(sp.sympify(x) for x in r) for r in [(0.5, 0, 0, q[0]), (1, sp.pi / 3, 0, q[1])]]
    F, W, C = dh_kinematics(rows, "standard", q, dq, [sp.Matrix([-0.25, 0, 0]), sp.Matrix([0, 0, 0])])
    assert sp.simplify(F[1][2, 2] - sp.Rational(1, 2)) == 0
    assert sp.simplify(W[1][2] - (dq[0] + dq[1]) / 2) == 0  # ²ω₂ = R₂ᵀ(ω₁ + z q̇₂), R₂ = Rot_z(q₂) Rot_x(π/3)
    assert sp.simplify(C[0][0] - 0.25 * sp.cos(q[0])) == 0


def test_dh_bodies_are_written_when_read_and_taken_as_computed_by_the_model():
    """A DH robot's p_c, ω, rotations and frames are written when first read; the dynamic model takes the loader's
    canonical p_c and ω as they are (TrigAlgebra.take), which gives the model derived from the written ones; a
    pickled body carries the written values, not the canonical forms."""
    import pickle

    from solver.dynamics.canonical import derive_canonical
    from solver.results import Deferred
    from solver.solve import _dumps
    from solver.spec import load_problem_text
    text = """
id: lazy-dh
title: a spatial RRR arm by DH
symbols: {l1: length, l2: length, d1: distance, d2: distance, m1: mass, m2: mass, I2: inertia, g0: gravity}
robot:
  joints: [R, R, R]
  gravity: [0, 0, -g0]
  dh:
    table:
      - {a: 0, alpha: pi/2, d: l1, theta: q1}
      - {a: l2, alpha: 0, d: 0, theta: q2}
      - {a: d2, alpha: -pi/2, d: 0, theta: q3 + pi/2}
    links:
      - {mass: m1, com: [0, d1 - l1, 0], inertia: [0, 0, 0]}
      - {mass: m2, com: [d2 - l2, 0, 0], inertia: [0, I2, I2]}
      - {mass: m2, com: [0, 0, d1], inertia: [I2, 0, I2]}
asks:
  - kind: dynamic_model
"""
    robot = load_problem_text(text).robot
    raw = [object.__getattribute__(b, "__dict__") for b in robot.bodies]
    assert all(type(r[k]) is Deferred for r in raw for k in ("com", "omega", "rotation"))
    assert type(object.__getattribute__(robot, "__dict__")["frames"]) is Deferred
    fast = derive_canonical(robot)
    assert all(type(r["com"]) is Deferred for r in raw)  # the model did not write them
    plain = load_problem_text(text).robot
    for b in plain.bodies:
        b.trig = None  # the written p_c and ω, read into the model's algebra
    slow = derive_canonical(plain)
    for name in ("B", "c", "g", "lhs"):
        assert getattr(fast, name) == getattr(slow, name), name
    frames = robot.frames
    assert len(frames) == 4 and frames[0] == sp.eye(4)
    for b, A in zip(robot.bodies, frames[1:]):
        assert b.rotation == A[:3, :3]
    copy = pickle.loads(_dumps(robot.bodies[2]))  # (as a helper process sends it)
    assert copy.trig is None and copy.com == robot.bodies[2].com and copy.omega == robot.bodies[2].omega


def test_angle_rate_reads_linear_joint_angles_and_differentiates_the_rest():
    """θ̇ of a DH joint angle: read from the terms of a linear θ, by differentiation otherwise; always Σ ∂θ/∂q_k q̇_k."""
    from solver.math.rigid import angle_rate
    q, dq = sp.symbols("q1:4"), sp.symbols("dq1:4")
    a = sp.Symbol("a")
    for theta in (q[0], q[1] + sp.pi / 2, 2 * q[0] - q[2] / 3 + 1, sp.Integer(0), a, q[0] ** 2, a * q[0],
                  sp.sin(q[1]) + q[2]):
        expect = sum((sp.diff(theta, x) * v for x, v in zip(q, dq)), sp.Integer(0))
        assert sp.expand(angle_rate(theta, q, dq) - expect) == 0, theta
