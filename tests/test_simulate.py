"""The `simulate` ask: closed loops of control_law and regulation laws integrated with solve_ivp on library robots
(the RP of 2004-03-25, the 2R of the control tests, the crane of 2018-03-27) and on robots no exercise uses (a 3R,
a cart-pole, an elastic joint): errors decay, estimates stay bounded, budgets stop the integration, figures and
reports render, spec errors point at their lines."""
import numpy as np
import pytest
import sympy as sp
from conftest import R2_ROBOT, RP_ROBOT, error_found_without_solving
from test_control_laws import CARTPOLE, ELASTIC1, R3

from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem_text
from solver.spec.errors import UserError

RPV = RP_ROBOT.replace("robot:", "values: {m1: 5, m2: 3, d1: 0.25, l1: 0.5, I1: 0.1, I2: 0.05, g0: 9.81}\nrobot:") + \
    "known: [l1, g0]\nasks:\n"
R2 = """
id: t2r
title: planar 2R in a vertical plane
symbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, l2: l2, I1: I1, I2: I2, g0: g0}
values: {m1: 2, m2: 1.5, d1: 0.25, d2: 0.2, l1: 0.5, l2: 0.4, I1: 0.05, I2: 0.03, g0: 9.81}
""" + R2_ROBOT + "asks:\n"


def run(text):
    p = load_problem_text(text)
    sols = solve_problem(p)
    return p, sols, all_results(sols)


def fnum(x):
    return float(x)


def test_adaptive_law_tracks_and_estimates_stay_bounded():
    text = RPV + """  - kind: control_law
    law: adaptive
    lambda: 5
    kd: 20
    gamma: 2
  - kind: simulate
    qd: ["0.5*sin(t)", "0.2 + 0.1*t^2 - 0.01*t^3"]
    q0: [0.2, 0]
    T: 8
"""
    p, sols, res = run(text)
    assert res["completed"].value is True
    assert fnum(res["e_final_norm"].value) < 0.02 * fnum(res["e_max_norm"].value)
    assert np.isfinite(fnum(res["settling_time"].value)) and fnum(res["settling_time"].value) < 8
    ah = [fnum(x) for x in res["ahat_final"].value]
    assert all(abs(x) < 50 for x in ah)
    fig = sols[1].figures[0]
    assert len(fig.panels) == 3 and len(fig.panels[2].hlines) == 3
    for fmt in ("md", "tex"):    # â(T) and the true a as vectors in math, not "($ 0.56, 3.04$)"
        out = render(p, sols, fmt)
        assert "$\\hat a(T) = \\begin{bmatrix} 0.5" in out and "(true values $a = \\begin{bmatrix} 1.212 \\\\ 3 " \
            "\\\\ 2.75 \\end{bmatrix}$:" in out


@pytest.mark.parametrize("head,qd", [(R2, ["0.5*sin(2*t)", "1 - cos(t)"]), (R3, ["0.3*t^2/(1 + t^2)", "0.5", "-0.2*sin(t)"])],
                         ids=["2R sinusoid", "3R polynomial-rational"])
def test_computed_torque_errors_decay(head, qd):
    n = len(qd)
    text = head + f"""  - kind: control_law
    law: computed_torque
    kp: 25
    kd: 10
  - kind: simulate
    qd: {qd}
    q0: {[0.3] * n}
    T: 4
"""
    _, _, res = run(text)
    assert res["completed"].value
    # ë + 10 ė + 25 e = 0 (double pole at -5): e(4) ≈ |e0| (1 + 5t) e^{-5t} < 1e-6 relative
    assert fnum(res["e_final_norm"].value) < 1e-4


def test_regulation_pd_gravity_and_pd_constant():
    text = R2 + """  - kind: regulation
    law: pd_gravity
    qd: [1, 0.5]
    kp: 50
    kd: 15
  - kind: control_law
    law: pd_constant
    qd: [1, 0.5]
    kp: 200
    kd: 30
    suffix: _c
  - kind: simulate
    ask: 1
    T: 6
  - kind: simulate
    ask: 2
    T: 6
    suffix: _c
"""
    _, _, res = run(text)
    assert fnum(res["e_final_norm"].value) < 1e-3
    assert fnum(res["e_final_norm_c"].value) < 1e-3
    assert res["u_max"].value[0] > 0


def test_elastic_cartpole_and_cartesian():
    el = ELASTIC1.replace("symbols:", "values: {m: 1, d: 0.3, I: 0.05, Im: 0.02, K: 100, g0: 9.81}\nsymbols:") + \
        """  - kind: control_law
    law: elastic
    gains: [256, 256, 96, 16]
  - kind: simulate
    qd: ["0.5*sin(t)"]
    q0: [0.2, 0]
    T: 6
"""
    _, _, res = run(el)
    assert res["completed"].value and fnum(res["e_final_norm"].value) < 5e-3
    cp = CARTPOLE + "  - kind: control_law\n    law: partial_fbl\n    kp: 4\n    kd: 4\n    qd: [0]\n" \
        "  - kind: simulate\n    q0: [1, 0.1]\n    T: 6\n"
    _, _, res = run(cp)
    assert fnum(res["e_final_norm"].value) < 0.02   # the cart is regulated; the pendulum swings freely
    ca = R2 + """  - kind: control_law
    law: cartesian_computed_torque
    task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]
    kp: [100, 50]
    kd: [20, 10]
    regulation: true
    rd: [0.5, 0.3]
  - kind: simulate
    q0: [0.3, 1.2]
    T: 3
"""
    p, _, res = run(ca)
    assert fnum(res["e_final_norm"].value) < 1e-3
    # K_P = diag(100, 50), K_D = diag(20, 10): e_x has the double root -10 (no sign change), e_y the roots -5 ± 5i
    assert list(res["oscillatory"].value) == [0, 1] and res["e_sign_changes"].value[1] >= 1


def test_budget_and_errors():
    base = RPV + "  - kind: control_law\n    law: computed_torque\n    kp: 25\n    kd: 10\n"
    _, _, res = run(base + "  - kind: simulate\n    qd: [1, 0]\n    max_steps: 100\n    T: 5\n")
    assert res["completed"].value is False and fnum(res["t_end"].value) < 5
    with pytest.raises(UserError, match="needs numbers for"):
        run(RPV + "  - kind: control_law\n    law: computed_torque\n  - kind: simulate\n    qd: [1, 0]\n")
    with pytest.raises(UserError, match="only t"):
        run(base + "  - kind: simulate\n    qd: [zz, 0]\n".replace("zz", "m1*q1"))
    with pytest.raises(UserError, match="needs the reference"):
        run(base + "  - kind: simulate\n")
    with pytest.raises(UserError, match="not a control_law"):
        run(base + "  - kind: simulate\n    ask: 2\n    qd: [1, 0]\n")
    # set: gives missing gains
    _, _, res = run(RPV + "  - kind: control_law\n    law: computed_torque\n  - kind: simulate\n    qd: [1, 0]\n"
                    "    set: {kp1: 16, kp2: 16, kd1: 8, kd2: 8}\n    T: 5\n")
    assert fnum(res["e_final_norm"].value) < 1e-3


def test_report_renders_with_figure(tmp_path):
    from solver.publish.figures import write_figures
    text = RPV + "  - kind: control_law\n    law: computed_torque\n    kp: 25\n    kd: 10\n" \
        "  - kind: simulate\n    qd: [1, 0]\n    T: 2\n"
    p, sols, _ = run(text)
    paths = write_figures(sols, tmp_path / "r.md", "png")
    assert paths and all(x.exists() for x in paths)
    md = render(p, sols, "md")
    assert "Dormand–Prince 5(4) pair and adaptive steps" in md and "settling time" in md
    tex = render(p, sols, "tex")
    assert "\\paragraph{Simulation.}" in tex and "Dormand--Prince" in tex


def test_methods_of_scipy_on_request_and_the_same_motion():
    """method: LSODA integrates with scipy's solve_ivp and says so; the final error agrees with the default
    integrator's (Dormand–Prince) to the tolerance."""
    base = RPV + "  - kind: control_law\n    law: computed_torque\n    kp: 25\n    kd: 10\n" \
        "  - kind: simulate\n    qd: ['1 + sin(t)', 0]\n    T: 2\n"
    p1, s1, _ = run(base)
    p2, s2, _ = run(base + "    method: LSODA\n")
    assert "solve_ivp` (LSODA," in render(p2, s2, "md")
    e1, e2 = (np.array(s.results["e_final"].value.tolist(), dtype=float).ravel() for s in (s1[1], s2[1]))
    assert np.abs(e1 - e2).max() < 1e-5 and s1[1].results["nfev"].value != s2[1].results["nfev"].value


def test_a_stiff_closed_loop_goes_to_lsoda_and_the_report_says_so():
    """K_D = 1000, K_P = 25000: error poles at about −26 and −974, a stiff loop for an explicit method."""
    text = RPV + "  - kind: control_law\n    law: computed_torque\n    kp: 25000\n    kd: 1000\n" \
        "  - kind: simulate\n    q0: [0.5, 0.2]\n    qd: [1, 0]\n    T: 3\n"
    p, sols, _ = run(text)
    assert "proving stiff, with scipy's `solve_ivp` (LSODA)" in render(p, sols, "md")
    assert fnum(sols[1].results["e_final_norm"].value) < 1e-6


def test_latex_report_with_simulation_compiles(tmp_path):
    import shutil
    import subprocess
    if shutil.which("pdflatex") is None:
        pytest.skip("pdflatex not installed")
    text = RPV + "  - kind: control_law\n    law: computed_torque\n    kp: 25\n    kd: 10\n" \
        "  - kind: simulate\n    qd: [1, 0]\n    T: 1\n"
    p, sols, _ = run(text)
    out = tmp_path / "s.tex"
    out.write_text(render(p, sols, "tex"))
    r = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", out.name], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout[-2000:]


# ------------------------------------------------------------------------------------------------ library robots
def _library_head(name, values):
    from conftest import PROBLEMS
    text = (PROBLEMS / f"{name}.yaml").read_text()
    head = text[:text.index("\nasks:") + len("\nasks:\n")]
    if "\nvalues:" not in head:
        head = head.replace("\nrobot:", f"\nvalues: {values}\nrobot:", 1)
    return head


LIB = [("2004-03-25-ex1", "{m1: 5, m2: 3, d1: 0.25, l1: 0.5, I1: 0.1, I2: 0.05, g0: 9.81}", 2),
       ("2016-09-12-ex1", "{m1: 4, m2: 3, m3: 2, I1: 0.1, I2: 0.08, I3: 0.05, d1: 0.2, d2: 0.1, d3: 0.2, "
                          "l1: 0.5, g0: 9.81}", 3),
       ("2020-07-15-remote-ex4", "{}", 2)]


@pytest.mark.parametrize("name,values,n", LIB, ids=[x[0] for x in LIB])
@pytest.mark.parametrize("law", ["computed_torque", "lyapunov_tracking", "adaptive", "pd_constant"])
def test_laws_on_library_robots(name, values, n, law):
    ref = ["0.3*sin(t)", "0.1 + 0.05*t^2/(1 + t^2)", "0.2*cos(t)"][:n]
    gains = {"computed_torque": "    kp: 25\n    kd: 10\n", "lyapunov_tracking": "    kp: 100\n    kd: 30\n",
             "adaptive": "    lambda: 5\n    kd: 30\n    gamma: 200\n",
             "pd_constant": f"    kp: 400\n    kd: 60\n    qd: {[0.3] * n}\n"}[law]
    T = 10 if law == "adaptive" else 6   # adaptive: asymptotic, slower while the estimates settle
    sim = f"  - kind: simulate\n    T: {T}\n    q0: {[0.1] * n}\n" + ("" if law == "pd_constant" else f"    qd: {ref}\n")
    text = _library_head(name, values) + f"  - kind: control_law\n    law: {law}\n" + gains + sim
    _, _, res = run(text)
    assert res["closed_loop_check"].value is True
    assert res["completed"].value is True
    tol = 0.1 if law == "adaptive" else 0.05
    assert fnum(res["e_final_norm"].value) < tol * fnum(res["e_max_norm"].value) + 1e-6
    if law == "adaptive":
        assert all(abs(fnum(x)) < 1e3 for x in res["ahat_final"].value)


def test_iterative_gravity_compensation_iterations():
    text = R2 + """  - kind: regulation
    law: iterative
    qd: [1, 0.5]
    kp: 60
    kd: 15
    q0: [0, 0]
    epsilon: 0.001
  - kind: simulate
    T: 3
    q0: [0, 0]
"""
    p, sols, res = run(text)
    errs = [fnum(x) for x in res["iteration_errors"].value]
    assert errs[-1] < 1e-3 <= errs[-2]
    assert "\n\n**Iterations.**" in render(p, sols, "md")   # its own paragraph, not glued to the results
    # the same count as the static iteration of the regulation ask (equilibria solved exactly), and a contraction
    assert int(res["iterations_sim"].value) == int(res["iterations_actual"].value) == len(errs)
    rho = float(sp.N(res["rho"].value))
    assert all(b < rho * a for a, b in zip(errs, errs[1:]))


# ------------------------------------------------------------------------------------------------ regulation laws
# the reference values below come from an independent numpy/scipy simulation of the same closed loops (the 2R model
# B, c, g written by hand, LSODA with rtol 1e-10)
ELV = ELASTIC1.replace("symbols:", "values: {m: 1, d: 0.3, I: 0.05, Im: 0.02, K: 100, g0: 9.81}\nsymbols:")


@pytest.mark.parametrize("where", ["regulation", "simulate"], ids=["qd in the law", "qd in simulate"])
def test_regulation_elastic_integrates_links_and_motors(where):
    """The state is (q1, theta1, dq1, dtheta1) from q0/dq0 (all coordinates); the error is on the link q1."""
    qd_law, qd_sim = ("    qd: [0.5]\n", "") if where == "regulation" else ("", "    qd: [0.5]\n")
    text = ELV + "  - kind: regulation\n    law: elastic\n" + qd_law + "    kp: 20\n    kd: 2\n" \
        "  - kind: simulate\n    T: 10\n" + qd_sim
    _, sols, res = run(text)
    assert res["condition"].value is True and res["completed"].value is True
    assert len(res["e_final"].value) == 1 and fnum(res["e_final_norm"].value) < 1e-9
    assert abs(fnum(res["e_max_norm"].value) - 0.501921) < 1e-5   # e1(0) = 0.5, a small overshoot (on the samples)
    assert str(sols[1].steps[-1].data["tracked"]) == "Matrix([[q1]])"
    # a start off the rest state: both coordinates and velocities are initial conditions
    _, _, res = run(text + "    q0: [0.2, 0.3]\n    dq0: [0, 1]\n")
    assert fnum(res["e_final_norm"].value) < 1e-9 and abs(fnum(res["e_max_norm"].value) - 0.3) < 1e-6   # e1(0)
    with pytest.raises(UserError, match="qd must list 1 values"):
        run(ELV + "  - kind: regulation\n    law: elastic\n    kp: 20\n    kd: 2\n"
            "  - kind: simulate\n    qd: [0.5, 1]\n")


PID = R2 + """  - kind: regulation
    law: pid
    qd: [1, 0.5]
    kp: 50
    kd: KD
    ki: KI
  - kind: simulate
"""


def test_regulation_pid_integrates_the_controller_state():
    """ξ̇ = e, ξ(0) = 0: with gravity and a constant q_d the error goes to 0 and ξ to K_I⁻¹ g(q_d)."""
    text = PID.replace("KD", "15").replace("KI", "20") + "    T: 10\n"
    p, sols, res = run(text)
    assert res["locally_stable"].value is True and res["completed"].value is True
    e = [fnum(x) for x in res["e_final"].value]
    assert abs(e[0] - 9.08269e-5) < 1e-7 and abs(e[1] + 7.13546e-4) < 1e-7
    xi = [fnum(x) for x in res["xi_final"].value]
    assert abs(xi[0] - 0.341424) < 1e-5 and abs(xi[1] - 0.0118317) < 1e-6
    # ξ_eq = K_I⁻¹ g(q_d) = (0.34168, 0.01041): ξ1 is there, ξ2 still on its way (a slow integral mode)
    xi_eq = [float(x.xreplace(p.values)) for x in res["xi_eq"].value]
    assert abs(xi[0] - xi_eq[0]) < 1e-3 and abs(xi_eq[0] - 0.341682) < 1e-5
    md = render(p, sols, "md")
    assert "\\dot\\xi = e" in md and "$\\xi(T) = \\begin{bmatrix} 0.3414 \\\\ 0.01183 \\end{bmatrix}$." in md
    assert "$\\xi(T) = \\begin{bmatrix} 0.3414 \\\\ 0.01183 \\end{bmatrix}$." in render(p, sols, "tex")
    assert "The largest inputs are $|u_{1}| \\le 50$, $|u_{2}| \\le 25$." in md


def test_regulation_pid_unstable_gains_diverge():
    """K_D = 2, K_I = 500 violate the Routh condition: the linearization has eigenvalues 2.51 ± ..i and e grows."""
    _, _, res = run(PID.replace("KD", "2").replace("KI", "500") + "    T: 2\n")
    assert res["locally_stable"].value is False
    e = [fnum(x) for x in res["e_final"].value]   # e(0) = (1, 0.5), e(2) = (1.74339, 0.48368)
    assert abs(e[0] - 1.74339) < 1e-3 and abs(e[1] - 0.48368) < 1e-3
    assert fnum(res["e_max_norm"].value) > 5


CART = R2 + """  - kind: regulation
    law: cartesian_pd
    task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]
    kp: 50
    kd: 15
PD  - kind: simulate
    q0: [0.3, 1.2]
    T: 10
"""


@pytest.mark.parametrize("where", ["regulation", "simulate"], ids=["pd in the law", "qd in simulate"])
def test_regulation_cartesian_pd_error_in_task_space(where):
    """e = p_d − f(q) (2 components), from the independent run: e(10) = (−0.0101178, −0.0098846)."""
    text = CART.replace("PD", "    pd: [0.5, 0.3]\n" if where == "regulation" else "") + \
        ("    qd: [0.5, 0.3]\n" if where == "simulate" else "")
    _, _, res = run(text)
    e = [fnum(x) for x in res["e_final"].value]
    assert abs(e[0] + 0.0101178) < 1e-6 and abs(e[1] + 0.0098846) < 1e-6
    # e(0) = p_d − f(0.3, 1.2): the largest error is the initial one
    f0 = np.array([0.5 * np.cos(0.3) + 0.4 * np.cos(1.5), 0.5 * np.sin(0.3) + 0.4 * np.sin(1.5)])
    assert abs(fnum(res["e_max_norm"].value) - np.linalg.norm([0.5, 0.3] - f0)) < 1e-6


def test_reference_with_parameters():
    """A reference may use parameters with values (qd: [l1, 0.5]); the error is evaluated with them."""
    _, _, res = run(R2 + "  - kind: regulation\n    law: pd_gravity\n    kp: 50\n    kd: 15\n"
                    "  - kind: simulate\n    qd: [l1, 0.5]\n    T: 5\n")
    assert fnum(res["e_final_norm"].value) < 1e-6 and abs(fnum(res["e_max_norm"].value) - np.hypot(0.5, 0.5)) < 1e-6


def test_check_finds_a_simulated_ask_that_is_no_law():
    """The simulated ask is found by the validate hook (`check`) as by solving (the rest needs the law)."""
    base = RPV + "  - kind: control_law\n    law: computed_torque\n    kp: 25\n    kd: 10\n"
    assert "ask: 2 is not a control_law" in error_found_without_solving(
        base + "  - kind: simulate\n    ask: 2\n    qd: [1, 0]\n")


# ------------------------------------------------------------------------------------------------ external forces
# a constant force F = (3, −2) at the tip of the 2R of R2 (l2 = 0.4): the plant feels τ_ext = J(q)ᵀF whatever the
# law compensates (−J(q)ᵀF̂); the reference equilibria are solved independently below (fsolve, J and g by hand)
TIP = "[l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]"
EXTF = np.array([3.0, -2.0])


def _ext(law, comp="", gains="    qd: [0.5, 0.3]\n    kp: [40, 30]\n    kd: [10, 8]\n", sim="    T: 10\n"):
    return R2 + f"  - kind: regulation\n    law: {law}\n" + gains + \
        f"    external:\n      - {{point: {TIP}, force: [3, -2]{comp}}}\n  - kind: simulate\n" + sim


def _tip_jacobian(q):
    s1, s12, c1, c12 = np.sin(q[0]), np.sin(q[0] + q[1]), np.cos(q[0]), np.cos(q[0] + q[1])
    return np.array([[-0.5 * s1 - 0.4 * s12, -0.4 * s12], [0.5 * c1 + 0.4 * c12, 0.4 * c12]])


def _gravity(q):   # m1 = 2, m2 = 1.5, d1 = 0.25, d2 = 0.2, l1 = 0.5, g0 = 9.81
    return 9.81 * np.array([1.25 * np.cos(q[0]) + 0.3 * np.cos(q[0] + q[1]), 0.3 * np.cos(q[0] + q[1])])


@pytest.mark.parametrize("comp,Fh", [("", EXTF), (", compensated: 0", np.zeros(2)),
                                     (", compensated: [1, -1]", np.array([1.0, -1.0]))],
                         ids=["compensated exactly", "not compensated", "compensated wrongly"])
def test_regulation_external_force_acts_on_the_plant(comp, Fh):
    """pd_gravity with −JᵀF̂: at rest K_P e + Jᵀ(F − F̂) = 0, so e → 0 only when F̂ = F; otherwise q(T) is the
    equilibrium the regulation ask finds (and fsolve). The plant used to miss τ_ext: e(T) was 0.09 with F̂ = F."""
    from scipy.optimize import fsolve
    kp, qd = np.array([40.0, 30.0]), np.array([0.5, 0.3])
    ref = fsolve(lambda q: kp * (qd - q) + _tip_jacobian(q).T @ (EXTF - Fh), qd, xtol=1e-12)
    p, sols, res = run(_ext("pd_gravity", comp))
    assert res["completed"].value is True
    qT = qd - np.array([fnum(x) for x in res["e_final"].value])
    eq = [np.array([fnum(x) for x in c]) for c in res["equilibria"].value]
    assert len(eq) == 1 and np.max(np.abs(eq[0] - ref)) < 1e-6
    assert np.max(np.abs(qT - ref)) < 1e-5
    if not comp:
        assert fnum(res["e_final_norm"].value) < 1e-6
    else:
        assert fnum(res["e_final_norm"].value) > 0.05     # (0.0727, 0.0459) and (0.0430, 0.0277)
    md = render(p, sols, "md")
    assert "= u(t, q, \\dot q) + \\tau_{ext}(q)$" in md


def test_external_force_with_other_regulation_laws():
    """The same plant for every regulation law: pd_constant without compensation stops where
    K_P e + g(q_d) − g(q) + J(q)ᵀF = 0; cartesian_pd where J(q)ᵀ(K_P e_p + F) = 0, i.e. e_p = −K_P⁻¹F; the
    iterative scheme updates û ← g(q) − τ_ext(q) (what the plant needs at rest) and reaches ε."""
    from scipy.optimize import fsolve
    kp, qd = np.array([40.0, 30.0]), np.array([0.5, 0.3])
    ref = fsolve(lambda q: kp * (qd - q) + _gravity(qd) - _gravity(q) + _tip_jacobian(q).T @ EXTF, qd, xtol=1e-12)
    _, _, res = run(_ext("pd_constant", ", compensated: 0", sim="    T: 15\n"))
    qT = qd - np.array([fnum(x) for x in res["e_final"].value])
    assert np.max(np.abs(qT - ref)) < 1e-5 and abs(ref[0] - 0.4085945) < 1e-6
    # the regulation ask's own equilibrium: unique by the α condition, but not q_d (it said [q_d])
    eq = [np.array([fnum(x) for x in c]) for c in res["equilibria"].value]
    assert len(eq) == 1 and np.max(np.abs(eq[0] - ref)) < 1e-6
    _, _, res = run(_ext("cartesian_pd", ", compensated: 0", "    task: " + TIP + "\n    pd: [0.6, 0.5]\n"
                         "    kp: [200, 200]\n    kd: [10, 8]\n", "    q0: [0.4, 0.5]\n    T: 15\n"))
    e = np.array([fnum(x) for x in res["e_final"].value])
    assert np.max(np.abs(e + EXTF / 200)) < 1e-6
    p, sols, res = run(_ext("iterative", "", "    qd: [0.5, 0.3]\n    kp: [100, 80]\n    kd: [10, 8]\n"
                                          "    epsilon: 0.0001\n", "    T: 5\n"))
    errs = [fnum(x) for x in res["iteration_errors"].value]
    assert res["iterations_sim"].value == 3 and errs[-1] < 1e-4 and errs[0] > errs[1] > errs[2]
    md = render(p, sols, "md")
    assert "\\hat u \\leftarrow (g - \\tau_{ext})(q)$" in md and "\n\n**Iterations.**" in md


def test_time_and_band_are_parsed_expressions():
    """T and settle are read with the spec's parser (parameters with values allowed), never sympify'd as raw text:
    a coordinate or an unknown name in them was an internal TypeError, now a spec error at the line."""
    base = RPV + "  - kind: control_law\n    law: computed_torque\n    kp: 25\n    kd: 10\n" \
        "  - kind: simulate\n    qd: [1, 0]\n"
    _, sols, res = run(base + "    T: l1\n    settle: l1/50\n")
    assert fnum(res["t_end"].value) == 0.5 and sols[1].steps[-1].data["band"] == 0.01
    with pytest.raises(UserError, match="T must be a number") as exc:
        run(base + "    T: q1 + 1\n")
    assert exc.value.place.line == 20   # the T: line
    with pytest.raises(UserError, match="settle must be a positive"):
        run(base + "    settle: -1\n")


# a constant force F = (1, −2) at p = 0.5 (cos q1, sin q1) on the link of the elastic joint of ELV (m = 1, d = 0.3,
# I = 0.05, Im = 0.02, K = 100, g0 = 9.81): the plant's link equation at rest is m g0 d cos q + K(q − θ) − J(q)ᵀF = 0
ELF = np.array([1.0, -2.0])


def _elastic_jtf(q, F):
    return F[0] * (-0.5 * np.sin(q)) + F[1] * (0.5 * np.cos(q))


@pytest.mark.parametrize("comp,Fh", [("", ELF), (", compensated: 0", np.zeros(2)),
                                     (", compensated: [2, 1]", np.array([2.0, 1.0]))],
                         ids=["compensated exactly", "not compensated", "compensated wrongly"])
def test_regulation_elastic_external_force_law_uses_the_estimate(comp, Fh):
    """θ_d and u_d balance the compensated F̂ (∇_q U_F̂(q_d, θ_d) = 0): with F̂ = F the link reaches q_d; otherwise
    the rest point solves the plant's equations with the true F (fsolve below), and is the ask's equilibrium. The law
    used to balance the true F whatever compensated: said (the link reached q_d even with F̂ = 0)."""
    from scipy.optimize import fsolve
    kp, qd, K, mgd = 20.0, 0.5, 100.0, 9.81 * 0.3
    thd = qd + (mgd * np.cos(qd) - _elastic_jtf(qd, Fh)) / K     # the law's θ_d and u_d, from F̂
    ud = K * (thd - qd)

    def rest(x):
        q, th = x
        return [mgd * np.cos(q) + K * (q - th) - _elastic_jtf(q, ELF), K * (th - q) - kp * (thd - th) - ud]
    ref = fsolve(rest, [qd, thd], xtol=1e-13)
    text = ELV + "  - kind: regulation\n    law: elastic\n    qd: [0.5]\n    kp: 20\n    kd: 2\n    external:\n" \
        f"      - {{point: [0.5*cos(q1), 0.5*sin(q1)], force: [1, -2]{comp}}}\n  - kind: simulate\n    T: 20\n"
    p, sols, res = run(text)
    assert abs(float(res["thetad"].value[0].xreplace(p.values)) - thd) < 1e-12
    assert abs(float(res["ud"].value[0].xreplace(p.values)) - ud) < 1e-10
    eq = [np.array([float(sp.sympify(x).xreplace(p.values)) for x in c]) for c in res["equilibria"].value]
    assert len(eq) == 1 and np.max(np.abs(eq[0] - ref)) < 1e-7
    qT = qd - fnum(res["e_final"].value[0])
    assert abs(qT - ref[0]) < 1e-7
    if not comp:
        assert fnum(res["e_final_norm"].value) < 1e-9
    else:
        assert fnum(res["e_final_norm"].value) > 0.07    # 0.0728 (F̂ = 0) and 0.0702 (F̂ = (2, 1))


# ------------------------------------------------------------------------------------------------ the simulated plant
def _balanced(values, extra=""):
    """The 2R of R2, balanced by assume: (d2 = 0, d1 = −m2 l1/m1: g ≡ 0), with ``values`` and robot lines ``extra``."""
    return R2.replace("values: {m1: 2, m2: 1.5, d1: 0.25, d2: 0.2,", "values: {" + values + " m1: 2, m2: 1.5,") \
        .replace("robot:\n", "robot:\n" + extra) + """  - kind: regulation
    law: pd_gravity
    assume: {d2: 0, d1: -m2*l1/m1}
    qd: [1, 0.5]
    kp: 50
    kd: 15
  - kind: simulate
    T: 10
"""


def test_simulated_plant_satisfies_the_assumptions():
    """The ask's assume: relations describe the controlled robot: the plant satisfies them too, overriding values:
    for the same parameters. pd_gravity compensates g ≡ 0 of the balanced robot, so e → 0 only on that plant; with
    the values d1 = 0.25, d2 = 0.2 the plant kept its gravity and the simulation stopped short of q_d (‖e(10)‖ =
    0.184); without them it asked for numbers for d1, d2."""
    for values in ("d1: 0.25, d2: 0.2,", ""):
        p, sols, res = run(_balanced(values))
        assert res["completed"].value is True and fnum(res["e_final_norm"].value) < 1e-9
        md = render(p, sols, "md")
        assert "under the assumptions of part 1 ($d_{2} = 0$" in md
        assert ("$d_{1} = - \\frac{l_{1} m_{2}}{m_{1}} = -0.375$ instead of the value $0.25$" in md) == bool(values)
        assert "$d_{2} = 0$ instead of the value $0.2$" in render(p, sols, "tex") or not values


def test_closed_loop_sentence_is_the_integrated_plant():
    """With viscous friction and an input map the plant is B q̈ + c + g + F_v q̇ = G u: the report wrote
    B q̈ + c + g = u; the motion is that of the model (e → 0: G⁻¹ in the law matches the G of the plant)."""
    text = _balanced("d1: 0.25, d2: 0.2,", "  input_map: [[1, 0], [1, 1]]\n  friction: {viscous: [0.5, 0.3]}\n") \
        .replace("    assume: {d2: 0, d1: -m2*l1/m1}\n", "")
    p, sols, res = run(text)
    assert fnum(res["e_final_norm"].value) < 1e-9
    for fmt in ("md", "tex"):
        out = render(p, sols, fmt)
        assert "The closed loop $B(q)\\ddot q + c(q,\\dot q) + g(q) + F_v\\dot q = G\\,u(t, q, \\dot q)$" in out
    p, sols, _ = run(_ext("pd_gravity", sim="    T: 1\n"))     # neither: unchanged
    assert "The closed loop $B(q)\\ddot q + c(q,\\dot q) + g(q) = u(t, q, \\dot q) + \\tau_{ext}(q)$" in \
        render(p, sols, "md")


def test_iterative_starts_from_the_asks_feedforward():
    """û₀ is the regulation ask's (g(q₀) at its q0, or its u0), whatever q(0) the simulation starts from: the
    simulated iterations then match the ask's static iterates q_i (g(q) = K_P(q_d − q) + û_{i−1}, solved exactly).
    It used to be g at the simulation's q(0) = (0.3, −0.2): ‖e_1‖ = 0.1815 instead of 0.19358."""
    base = R2 + "  - kind: regulation\n    law: iterative\n    qd: [1, 0.5]\n    kp: 60\n    kd: 15\n    q0: [0, 0]\n" \
        "U0    epsilon: 0.001\n  - kind: simulate\n    T: 3\n    q0: [0.3, -0.2]\n"
    for u0, start in (("", "$g(q_0)$ at the initial configuration $q_0 = \\begin{bmatrix} 0 \\\\ 0 \\end{bmatrix}$ "
                           "of part 1, as there"), ("    u0: [1, 2]\n", "the $u_0$ given in part 1")):
        p, sols, res = run(base.replace("U0", u0))
        sim = [fnum(x) for x in res["iteration_errors"].value]
        static = [np.linalg.norm(np.array([1, 0.5]) - np.array([fnum(v) for v in x])) for x in res["iterates"].value]
        assert len(sim) == int(res["iterations_actual"].value)
        assert np.max(np.abs(np.array(sim) - static[:len(sim)])) < 2e-5
        assert start in render(p, sols, "md")
    # no q0 in the ask: g at the simulation's start, and said so
    p, sols, res = run(base.replace("    q0: [0, 0]\n", "").replace("U0", ""))
    assert abs(fnum(res["iteration_errors"].value[0]) - 0.181539) < 1e-5
    assert "at the simulation's initial configuration (part 1 gives no $q_0$)" in render(p, sols, "tex")


def test_options_are_numbers_of_the_simulated_plant():
    """qd, q0, T and settle are numbers with the plant's values (the ask's assume: d2 = 0, d1 = −m2 l1/m1 = −0.375 on
    top of values:), as the law and the plant: q_d = (−2d1, 0.5) = (0.75, 0.5), q(0) = (d1, 0), T = 40 d1 + 20 = 5,
    band −d1/100. They were read with values: only: with d1 = 0.25 given the band was −0.0025 (refused; q(0) would
    start at 0.25, T = 30), without it qd was refused (d1 has no value). Reference: an independent solve_ivp of the
    same closed loop (2R model by hand, rtol 1e-10): max‖e‖ = 1.231107, e(5) ≈ 0, ‖e‖ < 0.00375 from t ≈ 1.525 on."""
    text = _balanced("VALS").replace("  - kind: simulate\n    T: 10\n", """  - kind: simulate
    qd: ['-2*d1', 0.5]
    q0: ['d1', 0]
    T: '40*d1 + 20'
    settle: '-d1/100'
""").replace("    qd: [1, 0.5]\n", "")
    for values in ("d1: 0.25, d2: 0.2,", ""):
        p, sols, res = run(text.replace("VALS", values))
        st = next(s.data for s in sols[1].steps if s.name == "simulate")
        assert [fnum(x) for x in st["q0"]] == [-0.375, 0] and st["T"] == 5 and abs(st["band"] - 0.00375) < 1e-12
        assert abs(fnum(res["e_max_norm"].value) - 1.231107) < 2e-5 and fnum(res["e_final_norm"].value) < 1e-6
        assert abs(fnum(res["settling_time"].value) - 1.525) < 0.02


def test_iterative_starts_from_the_asks_q0():
    """Without q0 here, the simulation of law: iterative starts from the regulation ask's q0 (where its û₀ = g(q₀)
    belongs), and the report says so; it started from q = 0. Independent solve_ivp of the first iteration: max‖e‖ =
    ‖q_d − q₀‖ = 0.989949 (at t = 0), ‖e(2)‖ = 0.181124."""
    text = R2 + "  - kind: regulation\n    law: iterative\n    qd: [1, 0.5]\n    kp: 60\n    kd: 15\n" \
        "    q0: [0.3, -0.2]\n    epsilon: 0.1\n  - kind: simulate\n    T: 2\n"
    p, sols, res = run(text)
    st = next(s.data for s in sols[1].steps if s.name == "simulate")
    assert [fnum(x) for x in st["q0"]] == [0.3, -0.2] and st["q0_from"] == "ask"
    assert abs(fnum(res["e_max_norm"].value) - 0.989949) < 1e-5
    assert abs(fnum(res["iteration_errors"].value[0]) - 0.181124) < 1e-5
    assert "\\end{bmatrix}$ (the $q_0$ of part 1), $\\dot q(0)" in render(p, sols, "md")
