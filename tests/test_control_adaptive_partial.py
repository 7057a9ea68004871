"""Partly adaptive laws and the Lyapunov function of the adaptive law (control_law, law: adaptive): the split of the
reference regressor into a known and an estimated part reproduces the model, the closed loop B ṡ + S s + K_D s =
Y_U ã_U holds exactly for any estimates, V̇ along the closed loop (computed here by solving the model for q̈) is the
printed negative semidefinite form, a wrong V or V̇ is rejected, a simulation tracks with bounded estimates, the
grader accepts a right u by property and a V by equivalence. The robot is a planar PR arm under gravity (a cart and
a pendulum link, both actuated), which no exercise uses; the library problems are checked by verify."""
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS

from solver.control import adaptive as ad
from solver.control.laws import check_control_law
from solver.dynamics.model import derive
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem

PR = """
id: tpr
title: planar PR arm under gravity (cart and actuated pendulum link)
symbols: {m1: m1, m2: m2, d2: d2, I2: I2, g0: g0}
values: {m1: 4, m2: 1.5, d2: 0.3, I2: 0.04, g0: 9.81}
robot:
  joints: [P, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [q1, 0]}
    - {mass: m2, com: [q1 + d2*cos(q2), d2*sin(q2)], angle: q2, inertia: I2}
known: [g0]
asks:
  - kind: linear_parametrization
    coefficients: [m1, m2, m2*d2, I2 + m2*d2^2]
"""
PARTIAL = "  - kind: control_law\n    law: adaptive\n    known_coefficients: [m1]\n"


def solved(text):
    p = load_problem_text(text)
    sols = solve_problem(p)
    return p, sols, all_results(sols)


def syms(p, base, n):
    return sp.Matrix([p.names[f"{base}{i + 1}"] for i in range(n)])


def zero(x):
    return sp.simplify(sp.expand(x)) == 0


def state_defs(p, res, n):
    """q̇_r, q̈_r in the state, from the law's own results (checked against their definitions below)."""
    return dict(zip(syms(p, "dqr", n), res["dqr"].value)) | dict(zip(syms(p, "ddqr", n), res["ddqr"].value))


def test_split_regressor_reproduces_the_model_on_the_reference_signals():
    p, _, res = solved(PR + PARTIAL)
    dm, n = derive(p.robot), p.robot.n
    dqr, ddqr = syms(p, "dqr", n), syms(p, "ddqr", n)
    m1, m2, d2, I2 = (p.names[k] for k in ("m1", "m2", "d2", "I2"))
    YU, YK, aU, aK = res["Y_U"].value, res["Y_K"].value, res["a_adapt"].value, res["a_K"].value
    assert list(aK) == [m1] and list(aU) == [m2, m2 * d2, I2 + m2 * d2 ** 2]
    assert res["p_U"].value == 3 and YU.shape == (2, 3) and YK.shape == (2, 1)
    target = dm.B * ddqr + dm.S * dqr + dm.g
    assert all(zero(x) for x in YU * aU + YK * aK - target)
    # the columns are those of the whole reference regressor, in the order of a
    Yr = res["Y_r"].value
    assert YK == Yr[:, 0] and YU == Yr[:, 1:]
    assert all(zero(x) for x in res["tau_K"].value - YK * aK)
    # free of the dynamic parameters; B_U = dB/d(unknown part), S_U its Christoffel factorization, skew
    assert not any(x.free_symbols & {m1, m2, d2, I2} for x in YU)
    BU = res["B_U"].value
    assert all(zero(x) for x in BU - dm.B.xreplace({m1: 0}))
    Bdot = sum((BU.diff(q) * v for q, v in zip(p.robot.q, p.robot.dq)), sp.zeros(2, 2))
    N = Bdot - 2 * res["S_U"].value
    assert all(zero(x) for x in N + N.T) and res["skew_U"].value is True
    assert res["Yr_check"].value is True


@pytest.mark.parametrize("gains", ["", "    lambda: [2, 3]\n    kd: 5\n    gamma: [1, 2, 3]\n"], ids=["symbolic", "numeric"])
def test_partly_adaptive_closed_loop_is_exact_for_any_estimates(gains):
    p, _, res = solved(PR + PARTIAL + gains)
    dm, r, n = derive(p.robot), p.robot, p.robot.n
    q, dq, ddq = sp.Matrix(r.q), sp.Matrix(r.dq), sp.Matrix(r.ddq)
    qd, dqd, ddqd = syms(p, "qd", n), syms(p, "dqd", n), syms(p, "ddqd", n)
    ahat = sp.Matrix([p.names[f"ahat{j}"] for j in (2, 3, 4)])     # estimates keep the index of a_j
    s_state = res["s"].value
    Lam = sp.diag(*[(dqr - dqd[i]).coeff(qd[i]) for i, dqr in enumerate(res["dqr"].value)])
    assert all(zero(x) for x in res["dqr"].value - (dqd + Lam * (qd - q)))
    assert all(zero(x) for x in res["ddqr"].value - (ddqd + Lam * (dqd - dq)))
    defs = state_defs(p, res, n)
    u = res["u"].value.xreplace(defs)
    sdot = res["ddqr"].value - ddq
    YU = res["Y_U"].value.xreplace(defs)
    atil = res["a_adapt"].value - ahat
    # the model under u: B q̈ + c + g - u, against B ṡ + S s + K_D s - Y_U ã (K_D: the diagonal gains of the law)
    kd = [5, 5] if gains else [p.names["kd1"], p.names["kd2"]]
    cl = dm.B * sdot + dm.S * s_state + sp.diag(*kd) * s_state - YU * atil
    lhs = dm.B * ddq + dm.c + dm.g - u
    assert all(zero(x + y) for x, y in zip(lhs, cl))
    assert res["closed_loop_check"].value is True
    # the update law updates only the unknown coefficients: Γ Y_Uᵀ s
    gam = sp.diag(*([1, 2, 3] if gains else [p.names[f"gamma{j}"] for j in (2, 3, 4)]))
    ref = gam * res["Y_U"].value.T * (syms(p, "dqr", n) - dq)
    assert all(zero(x - y) for x, y in zip(res["a_hat_dot"].value, ref))


@pytest.mark.parametrize("form", ["slotine_li", "with_e"])
def test_lyapunov_derivative_along_the_closed_loop(form):
    """V̇ computed here from q̈ = B⁻¹(u − c − g) and the update law equals the law's V_dot, exactly."""
    p, _, res = solved(PR + PARTIAL + f"    lyapunov: {form}\n")
    dm, r, n = derive(p.robot), p.robot, p.robot.n
    qd, dqd, ddqd = syms(p, "qd", n), syms(p, "dqd", n), syms(p, "ddqd", n)
    ahat = [p.names[f"ahat{j}"] for j in (2, 3, 4)]
    defs = state_defs(p, res, n)
    u = res["u"].value.xreplace(defs)
    qdd = dm.B.LUsolve(u - dm.c - dm.g)
    adot = res["a_hat_dot"].value.xreplace(defs)
    V = res["V"].value
    dV = sum(sp.diff(V, x) * v for x, v in zip(list(r.q) + list(r.dq) + list(qd) + list(dqd) + ahat,
                                                list(r.dq) + list(qdd) + list(dqd) + list(ddqd) + list(adot)))
    assert zero(sp.together(dV - res["V_dot"].value))
    assert res["V_check"].value is True
    e, de = qd - sp.Matrix(r.q), dqd - sp.Matrix(r.dq)
    kd, lam = syms(p, "kd", n), syms(p, "lambda", n)
    if form == "with_e":
        want = -sum(kd[i] * de[i] ** 2 + kd[i] * lam[i] ** 2 * e[i] ** 2 for i in range(n))
    else:
        want = -sum(kd[i] * (de[i] + lam[i] * e[i]) ** 2 for i in range(n))
    assert zero(res["V_dot"].value - want)
    # V >= 0: zero at e = de = 0 with exact estimates, positive elsewhere (sampled)
    a_true = res["a_adapt"].value
    rng = np.random.default_rng(3)
    vals = {s: sp.Float(rng.uniform(0.2, 2)) for s in V.free_symbols}
    at_zero = V.xreplace({**{x: y for x, y in zip(ahat, a_true)}}).xreplace(
        {**{a: b for a, b in zip(r.q, qd)}, **{a: b for a, b in zip(r.dq, dqd)}})
    assert zero(at_zero)
    assert float(V.xreplace(vals)) > 0


def test_a_wrong_lyapunov_function_or_rate_is_rejected(monkeypatch):
    """Each case decided the same in the trigonometric algebra (γ ι = 1 for the inverses of the gains) and by
    sympy's derivatives with the randomized zero test."""
    p, _, res = solved(PR + PARTIAL + "    lyapunov: with_e\n")
    dm, r, n = derive(p.robot), p.robot, p.robot.n
    defs = state_defs(p, res, n)
    qd, dqd, ddqd = syms(p, "qd", n), syms(p, "dqd", n), syms(p, "ddqd", n)
    ahat = [p.names[f"ahat{j}"] for j in (2, 3, 4)]
    rates = dict(zip(ahat, res["a_hat_dot"].value.xreplace(defs))) | dict(zip(qd, dqd)) | dict(zip(dqd, ddqd))
    forces = res["u"].value.xreplace(defs) - dm.c - dm.g
    s = res["s"].value
    V, Vd = res["V"].value, res["V_dot"].value
    # the rate of the other form (−sᵀK_D s) is not the derivative of this V
    kd = syms(p, "kd", n)
    other = -sum(kd[i] * s[i] ** 2 for i in range(n))
    # Γ instead of Γ⁻¹ in the estimation term (the slip of 2017-05-29 #3, line 8832)
    gam = [p.names[f"gamma{j}"] for j in (2, 3, 4)]
    atil = [a - h for a, h in zip(res["a_adapt"].value, ahat)]
    wrong = V - sum(x ** 2 / (2 * g) for x, g in zip(atil, gam)) + sum(g * x ** 2 / 2 for x, g in zip(atil, gam))
    # a V without the kinetic term: its q̇-gradient is not −B s
    cases = [(V, Vd, True), (V, other, False), (wrong, Vd, False), (V - (s.T * dm.B * s)[0] / 2, Vd, False)]
    for Vx, Vdx, want in cases:
        assert ad._derivative_in_algebra(Vx, Vdx, r, dm.B, s, forces, rates) is want
        assert ad.lyapunov_derivative_check(Vx, Vdx, r, dm.B, s, forces, rates) is want
    monkeypatch.setattr(ad, "_derivative_in_algebra", lambda *args: None)   # sympy's derivatives
    for Vx, Vdx, want in cases:
        assert ad.lyapunov_derivative_check(Vx, Vdx, r, dm.B, s, forces, rates) is want


def test_printed_vg_of_2017_fails_the_check_and_the_corrected_one_passes():
    """The erratum of 2017-05-29 #3b (line 8832): with Γ_g (not Γ_g⁻¹) V̇_g along the closed loop is not the
    printed −eᵀK_P K_D⁻¹K_P e − ėᵀK_D ė."""
    p = load_problem(PROBLEMS / "2017-05-29-final-ex3b.yaml")
    res = all_results(solve_problem(p))
    r, n = p.robot, p.robot.n
    dm = derive(r)
    defs = state_defs(p, res, n)
    qd, dqd, ddqd = syms(p, "qd", n), syms(p, "dqd", n), syms(p, "ddqd", n)
    ahat = [p.names["ahatg1"], p.names["ahatg2"]]
    gam = [p.names["gammag1"], p.names["gammag2"]]
    rates = dict(zip(ahat, res["a_hat_dot_red"].value.xreplace(defs))) | dict(zip(qd, dqd)) | dict(zip(dqd, ddqd))
    forces = res["u_red"].value.xreplace(defs) - dm.c - dm.g
    s, V, Vd = res["s_red"].value, res["V_red"].value, res["V_dot_red"].value
    atil = [a - h for a, h in zip(res["a_adapt_red"].value, ahat)]
    printed = V - sum(x ** 2 / (2 * g) for x, g in zip(atil, gam)) + sum(g * x ** 2 / 2 for x, g in zip(atil, gam))
    assert ad.lyapunov_derivative_check(V, Vd, r, dm.B, s, forces, rates)
    assert not ad.lyapunov_derivative_check(printed, Vd, r, dm.B, s, forces, rates)
    assert res["tau_K_red"].value.xreplace(defs) != sp.zeros(3, 1)
    # the known part is the inertial one: tau_K = B q̈_r + S q̇_r (gravity is all estimated)
    dqr, ddqr = syms(p, "dqr", n), syms(p, "ddqr", n)
    assert all(zero(x) for x in res["tau_K_red"].value - (dm.B * ddqr + dm.S * dqr))


def test_gravity_and_inertia_parametrizations_as_the_estimated_part():
    head = PR + """  - kind: linear_parametrization
    part: gravity
    suffix: _g
  - kind: linear_parametrization
    part: inertia
    coefficients: [m1 + m2, m2*d2, I2 + m2*d2^2]
    suffix: _i
"""
    p, _, res = solved(head + "  - kind: control_law\n    law: adaptive\n    parametrization: _g\n    suffix: _G\n"
                      "  - kind: control_law\n    law: adaptive\n    parametrization: _i\n    suffix: _I\n"
                      "  - kind: control_law\n    law: adaptive\n    parametrization: _i\n"
                      "    known_coefficients: [m1 + m2]\n    suffix: _IK\n")
    dm, n = derive(p.robot), p.robot.n
    dqr, ddqr = syms(p, "dqr", n), syms(p, "ddqr", n)
    g0, m2, d2 = (p.names[k] for k in ("g0", "m2", "d2"))
    # gravity: a_U = (m2 d2), Y_U = Y_g(q), tau_K = B q̈_r + S q̇_r
    assert list(res["a_adapt_G"].value) == [m2 * d2] and res["p_U_G"].value == 1
    assert all(zero(x) for x in res["Y_U_G"].value - sp.Matrix([[0], [g0 * sp.cos(p.robot.q[1])]]))
    assert all(zero(x) for x in res["tau_K_G"].value - (dm.B * ddqr + dm.S * dqr))
    # inertia: the regressor is completed with the Coriolis terms of each column (B_j q̈_r + S_j q̇_r)
    YU, aU = res["Y_U_I"].value, res["a_adapt_I"].value
    assert all(zero(x) for x in YU * aU - (dm.B * ddqr + dm.S * dqr))
    assert all(zero(x) for x in res["tau_K_I"].value - dm.g)
    # a part with known coefficients: only the others are estimated, the known ones join tau_K
    m1, I2 = p.names["m1"], p.names["I2"]
    assert list(res["a_adapt_IK"].value) == [m2 * d2, I2 + m2 * d2 ** 2]
    YK = res["Y_U_I"].value[:, 0]
    assert all(zero(x) for x in res["tau_K_IK"].value - (dm.g + YK * (m1 + m2)))
    for sfx in ("_G", "_I", "_IK"):
        assert res["closed_loop_check" + sfx].value is True and res["V_check" + sfx].value is True
        assert res["Yr_check" + sfx].value is True
    assert "ahatg1" in p.names and "ahati3" in p.names


def test_simulation_of_the_partly_adaptive_law_tracks_with_bounded_estimates():
    text = PR + PARTIAL + """    lambda: 4
    kd: 15
    gamma: [2, 2, 2]
  - kind: simulate
    qd: ["0.3*sin(t)", "0.5 + 0.4*sin(2*t)"]
    q0: [0.2, 0]
    T: 10
"""
    p, sols, res = solved(text)
    assert res["completed"].value is True
    e_fin, e_max = float(res["e_final_norm"].value), float(res["e_max_norm"].value)
    assert e_max > 0.3 and e_fin < 0.02 * e_max, (e_fin, e_max)
    ah = [float(x) for x in res["ahat_final"].value]
    assert len(ah) == 3 and all(abs(x) < 20 for x in ah), ah   # true (1.5, 0.45, 0.175); estimates bounded
    # the figure draws the estimates against the true unknown coefficients only
    assert len(sols[-1].figures[0].panels[2].hlines) == 3


def test_grading_partly_adaptive_u_by_property_and_v_by_equivalence():
    from solver.grading.grader import grade, prepare
    from solver.grading.submission import Submission
    text = PR + PARTIAL + "    lyapunov: with_e\ngrading:\n  items:\n    u: {points: 2}\n    V: {points: 2}\n"
    p = load_problem_text(text)
    ref = prepare(p)
    res, r, n = ref.results, p.robot, p.robot.n
    u, V = res["u"].value, res["V"].value
    defs = state_defs(p, res, n)
    qd, dqd = syms(p, "qd", n), syms(p, "dqd", n)
    kd, lam = syms(p, "kd", n), syms(p, "lambda", n)
    e, de = qd - sp.Matrix(r.q), dqd - sp.Matrix(r.dq)
    # property: u = Y_K a_K + Y_U â_U + K_P e + K_D ė with K_P = 2 K_D Λ (≥ K_D Λ): accepted
    base = (res["Y_K"].value * res["a_K"].value + res["Y_U"].value * sp.Matrix([p.names[f"ahat{j}"] for j in (2, 3, 4)]))
    alt = base + sp.Matrix([2 * kd[i] * lam[i] * e[i] + kd[i] * de[i] for i in range(n)])
    v = check_control_law(p, res, "u", list(alt.xreplace(defs)), lambda x: None, None)
    assert v is not None and v.correct, v.feedback
    v = check_control_law(p, res, "u", [sp.expand(x) for x in u], lambda x: None, None)
    assert v is not None and v.correct and "known part" in v.feedback[0], v.feedback
    # the known part left out: rejected, with the diagnosis
    no_known = u - res["Y_K"].value * res["a_K"].value
    v = check_control_law(p, res, "u", list(no_known), lambda x: None, None)
    assert v is not None and not v.correct and any("known part" in f for f in v.feedback), v.feedback
    # the known part evaluated on the actual velocity and acceleration (not the reference ones): rejected
    ddq_sub = dict(zip(syms(p, "ddqr", n), p.robot.ddq))
    wrong = u - res["Y_K"].value * res["a_K"].value + (res["Y_K"].value * res["a_K"].value).xreplace(ddq_sub)
    v = check_control_law(p, res, "u", list(wrong), lambda x: None, None)
    assert v is not None and not v.correct
    # through the grader: V by equivalence (expanded: right; without the e-term: wrong)
    item = lambda rep, name: next(i for i in rep.items if i.name == name)  # noqa: E731
    good = Submission("ann", "ann.yaml", {"u": [sp.sstr(sp.expand(x)) for x in u], "V": sp.sstr(sp.expand(V))})
    eterm = sum(kd[i] * lam[i] * e[i] ** 2 for i in range(n))
    bad = Submission("bob", "bob.yaml", {"u": [sp.sstr(x) for x in no_known], "V": sp.sstr(V - eterm)})
    ok_r, ko_r = grade(ref, good), grade(ref, bad)
    assert item(ok_r, "u").score == item(ok_r, "u").max_score > 0
    assert item(ok_r, "V").score == item(ok_r, "V").max_score > 0
    assert item(ko_r, "u").score < item(ko_r, "u").max_score
    assert item(ko_r, "V").score < item(ko_r, "V").max_score


def test_spec_errors():
    with pytest.raises(UserError, match="not a coefficient"):
        solved(PR + "  - kind: control_law\n    law: adaptive\n    known_coefficients: [m1 + m2]\n")
    with pytest.raises(UserError, match="nothing is estimated"):
        solved(PR + "  - kind: control_law\n    law: adaptive\n    known_coefficients: [m1, m2, m2*d2, I2 + m2*d2^2]\n")
    with pytest.raises(UserError, match="listed twice"):
        solved(PR + "  - kind: control_law\n    law: adaptive\n    known_coefficients: [m1, m1]\n")
    with pytest.raises(UserError, match="not the suffix"):
        solved(PR + "  - kind: control_law\n    law: adaptive\n    parametrization: _x\n")
    with pytest.raises(UserError, match="is not an option of law: computed_torque"):
        solved(PR + "  - kind: control_law\n    law: computed_torque\n    known_coefficients: [m1]\n")
    with pytest.raises(UserError, match="is not an option of law: pd_gravity"):
        solved(PR + "  - kind: control_law\n    law: pd_gravity\n    lyapunov: with_e\n")


def test_library_problems_verify():
    for name in ("2021-07-12-ex3", "2018-06-11-ex2", "2008-09-11-ex1"):
        rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
        assert rep.ok, (name, [(c.name, c.verdict) for c in rep.checks if not c.verdict.ok])
        names = {c.name for c in rep.checks}
        assert names & {"V", "V_p", "p_U_1"}


def test_report_renders_partly_adaptive_law_and_lyapunov_argument():
    p, sols, _ = solved(PR + PARTIAL + "    lyapunov: with_e\n")
    md = render(p, sols, "md")
    assert "Known and unknown coefficients" in md and "Control law (partly adaptive)" in md
    assert "Y_K(q,\\dot q,\\dot q_r,\\ddot q_r)\\,a_K + Y_U(q,\\dot q,\\dot q_r,\\ddot q_r)\\,\\hat a_U" in md
    assert "e^T K_P e + \\frac12\\tilde a_U^T\\Gamma^{-1}\\tilde a_U" in md and "Barbalat" in md
    assert "-\\dot e^T K_D\\dot e - e^T\\Lambda K_D\\Lambda e" in md
    tex = render(p, sols, "tex")
    assert "Control law (partly adaptive)" in tex and "Lyapunov analysis" in tex and "Barbalat" in tex


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed")
def test_latex_report_compiles(tmp_path):
    p, sols, _ = solved(PR + """  - kind: linear_parametrization
    part: gravity
    suffix: _g
""" + PARTIAL + "    lyapunov: with_e\n  - kind: control_law\n    law: adaptive\n    parametrization: _g\n    suffix: _G\n")
    out = tmp_path / "ad.tex"
    out.write_text(render(p, sols, "tex"))
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", out.name], cwd=tmp_path,
                         capture_output=True, text=True, timeout=180)
    assert run.returncode == 0, run.stdout[-2000:]
