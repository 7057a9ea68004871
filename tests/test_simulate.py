"""The `simulate` ask: closed loops of control_law and regulation laws integrated with solve_ivp on library robots
(the RP of 2004-03-25, the 2R of the control tests, the crane of 2018-03-27) and on robots no exercise uses (a 3R,
a cart-pole, an elastic joint): errors decay, estimates stay bounded, budgets stop the integration, figures and
reports render, spec errors point at their lines."""
import numpy as np
import pytest

from conftest import R2_ROBOT, RP_ROBOT
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
    assert "solve_ivp" in md and "settling time" in md
    tex = render(p, sols, "tex")
    assert "\\paragraph{Simulation.}" in tex
