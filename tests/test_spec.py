import subprocess
import sys

import pytest

from solver.errors import UserError
from solver.spec import json_schema, load_problem

GOOD = """\
id: t
title: planar 2R
symbols:
  m1: mass 1
  m2: mass 2
  l1: length 1
  d1: com 1
  d2: com 2
  I1: inertia 1
  I2: inertia 2
  g0: gravity
robot:
  joints: [R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - mass: m2
      com: [l1*cos(q1) + d2*cos(q1 + q2), l1*sin(q1) + d2*sin(q1 + q2)]
      angle: q1 + q2
      inertia: I2
asks:
  - kind: dynamic_model
"""


def error_of(write, text):
    with pytest.raises(UserError) as exc:
        load_problem(write(text))
    return str(exc.value)


def test_good_spec_loads(write):
    p = load_problem(write(GOOD))
    assert p.robot.n == 2 and len(p.robot.bodies) == 2


def test_unknown_name_has_file_line_column(write):
    msg = error_of(write, GOOD.replace("angle: q1 + q2", "angle: q1 + qq2"))
    assert "spec.yaml:19:19" in msg and "unknown name 'qq2'" in msg and "did you mean" in msg


def test_quoted_expression_column(write):
    msg = error_of(write, GOOD.replace("angle: q1 + q2", 'angle: "q1 + qq2"'))
    assert "spec.yaml:19:20" in msg


def test_missing_field(write):
    msg = error_of(write, GOOD.replace("title: planar 2R\n", ""))
    assert "missing field 'title'" in msg


def test_unknown_field_suggests(write):
    msg = error_of(write, GOOD.replace("inertia: I2", "inertai: I2"))
    assert "unknown field 'inertai'" in msg and "did you mean 'inertia'" in msg and "spec.yaml:20" in msg


def test_wrong_dimension(write):
    msg = error_of(write, GOOD.replace("gravity: [0, -g0, 0]", "gravity: [0, -g0, 0, 1]"))
    assert "gravity must be a vector of 2 or 3 components" in msg and "spec.yaml:14" in msg


def test_yaml_syntax_error(write):
    msg = error_of(write, GOOD.replace("joints: [R, R]", "joints: [R, R"))
    assert "YAML syntax" in msg and "spec.yaml:" in msg


def test_bad_joint_type_and_ask_kind(write):
    assert "joints" in error_of(write, GOOD.replace("[R, R]", "[R, X]"))
    msg = error_of(write, GOOD.replace("kind: dynamic_model", "kind: dynamics"))
    assert "ask kind" in msg and "dynamic_model" in msg


def test_symbol_clash_with_coordinate(write):
    msg = error_of(write, GOOD.replace("  m1: mass 1\n", "  m1: mass 1\n  q1: bad\n"))
    assert "generalized coordinate" in msg


def test_injection_is_refused(write):
    msg = error_of(write, GOOD.replace("mass: m2", "mass: \"__import__('os').system('echo hacked')\""))
    assert "unexpected character" in msg


def test_cli_exit_code_2_without_traceback(write):
    path = write(GOOD.replace("angle: q1 + q2", "angle: q1 + qq2"))
    r = subprocess.run([sys.executable, "-m", "solver", "check", str(path)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and "unknown name 'qq2'" in r.stderr


def test_schema_lists_ask_kinds():
    s = json_schema()
    text = str(s)
    assert "dynamic_model" in text and "equilibria" in text and "robot" in s["properties"]


def test_point_mass_without_inertia(write):
    p = load_problem(write("id: p\ntitle: point mass\nsymbols: {m: mass}\nrobot:\n  joints: [P]\n"
                           "  links:\n    - mass: m\n      com: [q1, 0]\nasks:\n  - kind: dynamic_model\n"))
    assert p.robot.bodies[0].inertia.is_zero_matrix


def test_kinematics_only_robot(write):
    """joints alone describe a robot for kinematics; a dynamics ask on it is a spec error at robot:."""
    text = """id: k
title: K
symbols: {l: link length}
robot:
  joints: [R, R]
asks:
  - kind: redundancy
    task: "[l*cos(q1) + l*cos(q1 + q2)]"
    at: {q1: 0, q2: pi/2}
    velocity: [1]
"""
    from solver.solve import all_results, solve_problem
    res = all_results(solve_problem(load_problem(write(text))))
    assert res["qdot_ps"].value.shape == (2, 1)
    msg = error_of_solve(write, text.replace("kind: redundancy", "kind: dynamic_model").split("    task:")[0])
    assert "no bodies and no model" in msg and "spec.yaml:5:" in msg


def error_of_solve(write, text):
    from solver.solve import solve_problem
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem(write(text)))
    return str(exc.value)
