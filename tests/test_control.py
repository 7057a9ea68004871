"""The `control_law` ask: computed torque gives exactly ë + K_D ė + K_P e = 0 (2R, RP), its tracking error decays
in simulation, PD + gravity compensation has (q_d, 0) as equilibrium, the property check on u, spec errors
(underactuated input map), the report (Markdown, LaTeX) and the encoded exam problem."""
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, R2_ROBOT, RP_ROBOT

from solver.control.laws import check_control_law
from solver.dynamics.model import derive
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

RP = RP_ROBOT + "asks:\n"

CT = "  - kind: control_law\n    law: computed_torque\n"
PD = "  - kind: control_law\n    law: pd_gravity\n"


def solved(text):
    p = load_problem_text(text)
    sols = solve_problem(p)
    return p, sols, all_results(sols)


def names(p, *ns):
    return [p.names[n] for n in ns]


def closed_loop_accel(p, u, at=None):
    """q̈ from B q̈ + c + g = u, solved exactly (at a state, if given)."""
    dm = derive(p.robot)
    B, rhs = dm.B, u - dm.c - dm.g
    if at:
        B, rhs = B.xreplace(at), rhs.xreplace(at)
    return B.LUsolve(rhs).applyfunc(sp.simplify)


@pytest.mark.parametrize("head", [R2, RP], ids=["2R", "RP"])
def test_computed_torque_closed_loop_is_linear_and_decoupled(head):
    p, _, res = solved(head + CT)
    r = p.robot
    qdd = closed_loop_accel(p, res["u"].value)
    for i in range(r.n):
        k = i + 1
        qd, dqd, ddqd, kp, kd = names(p, f"qd{k}", f"dqd{k}", f"ddqd{k}", f"kp{k}", f"kd{k}")
        e, de, dde = qd - r.q[i], dqd - r.dq[i], ddqd - qdd[i]
        assert sp.simplify(dde + kd * de + kp * e) == 0
        # the closed_loop result is ë + K_D ė + K_P e with ë = q̈_d − q̈
        cl = res["closed_loop"].value[i]
        assert sp.expand(cl - (ddqd - r.ddq[i] + kd * de + kp * e)) == 0
    assert res["closed_loop_check"].value is True


def test_computed_torque_tracking_error_decays_in_simulation():
    from scipy.integrate import solve_ivp
    p, _, res = solved(R2 + CT)
    r, dm = p.robot, derive(p.robot)
    t = sp.Symbol("t")
    traj = [0.5 * sp.sin(t), 1.0 + 0.3 * sp.cos(2 * t)]
    des = {}
    for i, x in enumerate(traj):
        k = i + 1
        qd, dqd, ddqd, kp, kd = names(p, f"qd{k}", f"dqd{k}", f"ddqd{k}", f"kp{k}", f"kd{k}")
        des.update({qd: x, dqd: sp.diff(x, t), ddqd: sp.diff(x, t, 2), kp: 25, kd: 10})
    u = res["u"].value.xreplace(des).xreplace(p.values)
    B = dm.B.xreplace(p.values)
    n = (dm.c + dm.g).xreplace(p.values)
    state = list(r.q) + list(r.dq)
    f_u = sp.lambdify([t] + state, u, "numpy")
    f_B = sp.lambdify(state, B, "numpy")
    f_n = sp.lambdify(state, n, "numpy")
    f_qd = sp.lambdify(t, sp.Matrix(traj), "numpy")

    def rhs(tt, x):
        qdd = np.linalg.solve(np.array(f_B(*x), float), (np.array(f_u(tt, *x), float) - np.array(f_n(*x), float)).ravel())
        return np.concatenate([x[2:], qdd])

    x0 = [1.0, -0.5, 0.0, 0.0]
    sol = solve_ivp(rhs, (0, 3), x0, rtol=1e-9, atol=1e-11, dense_output=True)
    assert sol.success
    err = lambda tt: np.linalg.norm(sol.sol(tt)[:2] - np.array(f_qd(tt), float).ravel())
    e0, e3 = err(0.0), err(3.0)
    assert e0 > 0.5
    assert e3 < 1e-3 * e0
    # the error follows ë + 10 ė + 25 e = 0: e(t) = e0 (1 + 5t) exp(-5t) for a start at rest with q̇_d(0) ≠ 0
    assert err(1.0) < 0.5 * e0


@pytest.mark.parametrize("head", [R2, RP], ids=["2R", "RP"])
def test_pd_gravity_equilibrium_at_qd(head):
    p, _, res = solved(head + PD)
    r = p.robot
    qd = names(p, *[f"qd{i + 1}" for i in range(r.n)])
    at = {**dict(zip(r.q, qd)), **{v: 0 for v in r.dq}}
    qdd = closed_loop_accel(p, res["u"].value, at)
    assert all(x == 0 for x in qdd)
    assert res["equilibrium_check"].value is True and res["closed_loop_check"].value is True
    # not an equilibrium elsewhere (a displaced configuration accelerates)
    off = {**{a: b + 1 for a, b in zip(r.q, qd)}, **{v: 0 for v in r.dq}}
    assert any(x != 0 for x in closed_loop_accel(p, res["u"].value, off))


def test_regulation_with_given_gains_and_qd():
    p, _, res = solved(R2.replace("g0: g0}", "g0: g0, qa: {meaning: a, sign: real}, qb: {meaning: b, sign: real}}")
                       + CT + "    regulation: true\n    kp: 100\n    kd: [20, 10]\n    qd: [qa, qb]\n")
    qa, qb = names(p, "qa", "qb")
    r = p.robot
    cl = res["closed_loop"].value
    assert sp.expand(cl[0] - (-r.ddq[0] - 20 * r.dq[0] + 100 * (qa - r.q[0]))) == 0
    assert sp.expand(cl[1] - (-r.ddq[1] - 10 * r.dq[1] + 100 * (qb - r.q[1]))) == 0
    assert "kp1" not in p.names and "dqd1" not in p.names


def test_created_names_avoid_the_problems_symbols():
    p, _, res = solved(R2.replace("g0: g0}", "g0: g0, kp1: {meaning: a spring, sign: real}}") + CT)
    assert "kp1c" in p.names and p.names["kp1"] in p.symbols.values()
    assert res["u"].value.free_symbols & {p.names["kp1c"]}
    assert not res["u"].value.free_symbols & {p.symbols["kp1"]}


def test_property_check_accepts_rewritten_u_and_rejects_missing_c():
    p, sols, res = solved(RP + CT)
    dm = derive(p.robot)
    u = res["u"].value
    expanded = [sp.expand(sp.expand_trig(x)) for x in u]
    v = check_control_law(p, res, "u", expanded, lambda n: None, None)
    assert v is not None and v.correct and v.fraction == 1.0
    wrong = [x - c for x, c in zip(u, dm.c)]
    v = check_control_law(p, res, "u", wrong, lambda n: None, None)
    assert v is not None and not v.correct and v.fraction == 0.0 and not v.final
    text = " ".join(v.feedback)
    assert "equation(s) 1, 2 fail" in text and "Coriolis/centrifugal term c(q, q̇) is missing" in text
    # only the gravity of joint 2 wrong: only... both closed-loop equations are coupled through B
    wrong2 = [u[0], u[1] + 1]
    v = check_control_law(p, res, "u", wrong2, lambda n: None, None)
    assert not v.correct and "fail" in v.feedback[0]
    # wrong size
    v = check_control_law(p, res, "u", [u[0]], lambda n: None, None)
    assert not v.correct
    # pd_gravity: reference comparison (None)
    p2, _, res2 = solved(RP + PD)
    assert check_control_law(p2, res2, "u", list(res2["u"].value), lambda n: None, None) is None


def test_property_check_through_the_grader():
    from solver.grading.grader import grade, prepare
    from solver.grading.submission import Submission
    p = load_problem(PROBLEMS / "2007-04-19-ex2.yaml")
    ref = prepare(p)
    u = ref.results["u"].value
    c = derive(p.robot).c
    good = Submission("ann", "ann.yaml", {"u": [sp.sstr(sp.expand(x)) for x in u]})
    bad = Submission("bob", "bob.yaml", {"u": [sp.sstr(sp.expand(x - ci)) for x, ci in zip(u, c)]})
    item = lambda rep: next(i for i in rep.items if i.name == "u")
    ok, ko = item(grade(ref, good)), item(grade(ref, bad))
    assert ok.score == ok.max_score > 0, ok.feedback
    assert ko.score == 0 and any("Coriolis" in f for f in ko.feedback), ko.feedback


def test_underactuated_input_map_is_a_spec_error():
    text = RP.replace("asks:", "  input_map: [[1], [0]]\nasks:") + CT
    with pytest.raises(UserError) as ei:
        solved(text)
    assert "square input map" in str(ei.value) and "underactuated" in str(ei.value)


def test_invertible_input_map():
    text = RP.replace("asks:", "  input_map: [[1, 1], [0, 2]]\nasks:") + CT
    p, _, res = solved(text)
    G = sp.Matrix([[1, 1], [0, 2]])
    dm = derive(p.robot)
    qdd = dm.B.LUsolve(G * res["u"].value - dm.c - dm.g).applyfunc(sp.simplify)
    r = p.robot
    for i in range(2):
        k = i + 1
        qd, dqd, ddqd, kp, kd = names(p, f"qd{k}", f"dqd{k}", f"ddqd{k}", f"kp{k}", f"kd{k}")
        assert sp.simplify(qdd[i] - (ddqd + kd * (dqd - r.dq[i]) + kp * (qd - r.q[i]))) == 0
    assert res["closed_loop_check"].value is True


def test_unknown_law_is_rejected():
    with pytest.raises(UserError):
        load_problem_text(RP + "  - kind: control_law\n    law: sliding_mode\n")


def test_markdown_report():
    p, sols, _ = solved(RP + CT + PD)
    md = render(p, sols, "md")
    assert "Control law: computed torque" in md and "PD with gravity compensation" in md
    assert "\\ddot e_{1} + k_{D,1}" in md and "globally asymptotically stable" in md
    assert "verified exactly" in md


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed")
def test_latex_report_compiles(tmp_path):
    p, sols, _ = solved(RP + CT + PD)
    out = tmp_path / "cl.tex"
    out.write_text(render(p, sols, "tex"))
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", out.name], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-2000:]


def test_encoded_exam_problem_verifies():
    p = load_problem(PROBLEMS / "2007-04-19-ex2.yaml")
    rep = check_problem(p)
    assert rep.ok, [(c.name, c.verdict) for c in rep.checks if not c.verdict.ok]
    keys = {c.name for c in rep.checks}
    assert {"u", "closed_loop", "closed_loop_check"} <= keys


# ------------------------------------------------------------------------------------------------ adaptive
AD = "  - kind: control_law\n    law: adaptive\n"


def _ref_subs(p, n):
    return ([p.names[f"dqr{i + 1}"] for i in range(n)], [p.names[f"ddqr{i + 1}"] for i in range(n)])


@pytest.mark.parametrize("head", [R2, RP], ids=["2R", "RP"])
def test_adaptive_regressor_is_exact(head):
    p, _, res = solved(head + AD)
    dm, n = derive(p.robot), p.robot.n
    dqr, ddqr = _ref_subs(p, n)
    Yr, a = res["Y_r"].value, res["a_adapt"].value
    assert Yr.shape == (n, a.rows)
    target = dm.B * sp.Matrix(ddqr) + dm.S * sp.Matrix(dqr) + dm.g
    assert all(sp.simplify(sp.expand(x)) == 0 for x in Yr * a - target)
    # Y_r is free of the dynamic parameters, and gives back Y(q, dq, ddq) a = model for dq_r = dq, ddq_r = ddq
    dyn = set(p.symbols.values()) - set(p.known)
    assert not any(x.free_symbols & dyn for x in Yr)
    back = Yr.xreplace(dict(zip(dqr, p.robot.dq)) | dict(zip(ddqr, p.robot.ddq))) * a - dm.lhs
    assert all(sp.simplify(sp.expand(x)) == 0 for x in back)
    assert res["Yr_check"].value is True and res["closed_loop_check"].value is True


@pytest.mark.parametrize("head", [R2, RP], ids=["2R", "RP"])
def test_adaptive_closed_loop_with_exact_estimates(head):
    p, _, res = solved(head + AD)
    r, dm, n = p.robot, derive(p.robot), p.robot.n
    dqr, ddqr = _ref_subs(p, n)
    a = res["a_adapt"].value
    ahat = [p.names[f"ahat{i + 1}"] for i in range(a.rows)]
    lam = [p.names[f"lambda{i + 1}"] for i in range(n)]
    kd = [p.names[f"kd{i + 1}"] for i in range(n)]
    qd = sp.Matrix([p.names[f"qd{i + 1}"] for i in range(n)])
    dqd = sp.Matrix([p.names[f"dqd{i + 1}"] for i in range(n)])
    ddqd = sp.Matrix([p.names[f"ddqd{i + 1}"] for i in range(n)])
    q, dq, ddq = sp.Matrix(r.q), sp.Matrix(r.dq), sp.Matrix(r.ddq)
    L = sp.diag(*lam)
    defs = dict(zip(dqr, dqd + L * (qd - q))) | dict(zip(ddqr, ddqd + L * (dqd - dq)))
    assert all(sp.expand(x - y.xreplace(defs)) == 0 for x, y in zip(res["dqr"].value, dqr))
    s = dqd - dq + L * (qd - q)
    sdot = ddqd + L * (dqd - dq) - ddq
    u = res["u"].value.xreplace(dict(zip(ahat, a))).xreplace(defs)
    # the model B ddq + c + g = u with ahat = a is exactly B sdot + S s + K_D s = 0
    lhs = dm.B * ddq + dm.c + dm.g - u
    cl = dm.B * sdot + dm.S * s + sp.diag(*kd) * s
    assert all(sp.simplify(sp.expand(x + y)) == 0 for x, y in zip(lhs, cl))
    assert all(sp.simplify(sp.expand(x - y)) == 0 for x, y in zip(res["closed_loop"].value, cl))
    # update law: Gamma Y_r^T (dq_r - dq)
    gam = sp.diag(*[p.names[f"gamma{i + 1}"] for i in range(a.rows)])
    ref = gam * res["Y_r"].value.T * (sp.Matrix(dqr) - dq)
    assert all(sp.expand(x - y) == 0 for x, y in zip(res["a_hat_dot"].value, ref))


def test_adaptive_reuses_the_given_coefficients_and_the_printed_regressor():
    """2004-03-25#1: with the printed a = (I0, m2, m d3) (line 75), Y_r is the printed regressor (line 83)."""
    text = (PROBLEMS / "2004-03-25-ex1.yaml").read_text().replace("expected:", AD + "expected:", 1)
    p, _, res = solved(text)
    n = names
    q1, q2, dq1, dq2, l1, g0 = n(p, "q1", "q2", "dq1", "dq2", "l1", "g0")
    dqr1, dqr2, ddqr1, ddqr2 = n(p, "dqr1", "dqr2", "ddqr1", "ddqr2")
    m1, m2, d1, I1, I2 = n(p, "m1", "m2", "d1", "I1", "I2")
    assert list(res["a_adapt"].value) == [I1 + m1 * d1**2 + I2 + m2 * l1**2, m2, m1 * d1 + m2 * l1]
    printed = sp.Matrix([[ddqr1, q2**2 * ddqr1 + l1 * ddqr2 + q2 * (dq1 * dqr2 + dq2 * dqr1) + g0 * q2 * sp.cos(q1),
                          g0 * sp.sin(q1)],
                         [0, l1 * ddqr1 + ddqr2 - q2 * dq1 * dqr1 + g0 * sp.sin(q1), 0]])
    assert (res["Y_r"].value - printed).applyfunc(sp.expand) == sp.zeros(2, 3)


def test_adaptive_given_gains_and_errors():
    p, _, res = solved(RP + AD + "    lambda: 5\n    kd: [10, 20]\n    gamma: 2\n")
    assert "lambda1" not in p.names and "gamma1" not in p.names and "kd1" not in p.names
    r = p.robot
    assert sp.expand(res["s"].value[1] - (p.names["dqd2"] - r.dq[1] + 5 * (p.names["qd2"] - r.q[1]))) == 0
    assert all(g.free_symbols <= set(r.q) | set(r.dq) | {p.names[f"dqr{i}"] for i in (1, 2)}
               | {p.names[f"ddqr{i}"] for i in (1, 2)} for g in res["a_hat_dot"].value)
    with pytest.raises(UserError):
        solved(RP + AD + "    kp: 3\n")
    with pytest.raises(UserError):
        solved(RP + CT + "    gamma: 3\n")
    with pytest.raises(UserError):
        solved(RP + AD + "    lambda: [1, 2, 3]\n")


def test_adaptive_tracking_error_decays_in_simulation():
    from scipy.integrate import solve_ivp
    p, _, res = solved(R2 + AD + "    lambda: 5\n    kd: 20\n    gamma: 2\n")
    r, dm, n = p.robot, derive(p.robot), p.robot.n
    a_true = res["a_adapt"].value.xreplace(p.values)
    pn = a_true.rows
    t = sp.Symbol("t")
    traj = [0.5 * sp.sin(t), 1.0 + 0.3 * sp.cos(2 * t)]
    des = {}
    for i, x in enumerate(traj):
        k = i + 1
        des.update({p.names[f"qd{k}"]: x, p.names[f"dqd{k}"]: sp.diff(x, t), p.names[f"ddqd{k}"]: sp.diff(x, t, 2)})
    dqr, ddqr = _ref_subs(p, n)
    ahat = [p.names[f"ahat{i + 1}"] for i in range(pn)]
    defs = {v: d.xreplace(des) for v, d in zip(dqr, res["dqr"].value)} | \
           {v: d.xreplace(des) for v, d in zip(ddqr, res["ddqr"].value)}
    u = res["u"].value.xreplace(defs)
    adot = res["a_hat_dot"].value.xreplace(defs)
    state = list(r.q) + list(r.dq)
    f_u = sp.lambdify([t] + state + ahat, u, "numpy")
    f_a = sp.lambdify([t] + state + ahat, adot, "numpy")
    f_B = sp.lambdify(state, dm.B.xreplace(p.values), "numpy")
    f_n = sp.lambdify(state, (dm.c + dm.g).xreplace(p.values), "numpy")
    f_qd = sp.lambdify(t, sp.Matrix(traj), "numpy")

    def rhs(tt, x):
        xs, ah = x[:2 * n], x[2 * n:]
        tau = np.array(f_u(tt, *xs, *ah), float).ravel()
        qdd = np.linalg.solve(np.array(f_B(*xs), float), tau - np.array(f_n(*xs), float).ravel())
        return np.concatenate([xs[n:], qdd, np.array(f_a(tt, *xs, *ah), float).ravel()])

    a0 = [0.5 * float(v) for v in a_true]          # wrong initial estimates (half the true values)
    sol = solve_ivp(rhs, (0, 5), [1.0, -0.5, 0.0, 0.0] + a0, rtol=1e-8, atol=1e-10, dense_output=True)
    assert sol.success
    err = lambda tt: np.linalg.norm(sol.sol(tt)[:2] - np.array(f_qd(tt), float).ravel())
    e0, e5 = err(0.0), err(5.0)
    assert e0 > 0.5 and e5 < 0.02 * e0, (e0, e5)


def test_adaptive_report_renders():
    p, sols, _ = solved(RP + AD)
    md = render(p, sols, "md")
    assert "Slotine-Li" in md and "Reference velocity" in md and "Update law" in md
    assert "\\frac12 s^T B(q) s + \\frac12\\tilde a^T\\Gamma^{-1}\\tilde a" in md and "= -s^T K_D s" in md
    assert "verified exactly" in md and "\\dot q_{r,1}" in md
    tex = render(p, sols, "tex")
    assert "Slotine--Li" in tex and "Lyapunov analysis" in tex


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed")
def test_adaptive_latex_report_compiles(tmp_path):
    p, sols, _ = solved(RP + AD)
    out = tmp_path / "ad.tex"
    out.write_text(render(p, sols, "tex"))
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", out.name], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-2000:]


def test_task_space_check_with_and_without_the_model() -> None:
    """cartesian._check: J q̈ + J̇ q̇ = a_r with q̈ = B⁻¹ rhs, or q̈ = rhs itself when B is None (a redundant task's
    u = B a + n, whose q̈ is a): true for the right acceleration, false for a perturbed one."""
    from solver.control.cartesian import _check
    q1, q2, dq1, dq2, l1, l2, m, ar1 = sp.symbols("q1 q2 dq1 dq2 l1 l2 m ar1")
    J = sp.Matrix([[-l1 * sp.sin(q1) - l2 * sp.sin(q1 + q2), -l2 * sp.sin(q1 + q2)]])
    Jdq = sp.Matrix([-l1 * sp.cos(q1) * dq1 ** 2 - l2 * sp.cos(q1 + q2) * (dq1 + dq2) ** 2])
    ar = sp.Matrix([ar1])
    a = J.T * (J * J.T).inv() * (ar - Jdq)          # the pseudoinverse solution
    assert _check(None, a, J, Jdq, ar)
    assert not _check(None, a + sp.Matrix([0, sp.Rational(1, 10)]), J, Jdq, ar)
    B = sp.Matrix([[m + 2, sp.cos(q2)], [sp.cos(q2), 1]])
    assert _check(B, B * a, J, Jdq, ar)
    assert not _check(B, B * a + sp.Matrix([1, 0]), J, Jdq, ar)
