import subprocess
import sys

import pytest

from solver.spec import load_problem
from solver.spec.errors import UserError
from solver.spec.models import json_schema

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


def error_of(write, text, solve=False):
    """The message of the UserError that loading (and, with ``solve``, solving) the spec raises."""
    from solver.solve import solve_problem
    with pytest.raises(UserError) as exc:
        problem = load_problem(write(text))
        if solve:
            solve_problem(problem)
    return str(exc.value)


def test_good_spec_loads(write):
    p = load_problem(write(GOOD))
    assert p.robot.n == 2 and len(p.robot.bodies) == 2


SPEC_ERRORS = [  # (replace this, by that) in GOOD -> every piece of text expected in the message
    ("angle: q1 + q2", "angle: q1 + qq2", ["spec.yaml:19:19", "unknown name 'qq2'", "did you mean"]),
    ("angle: q1 + q2", 'angle: "q1 + qq2"', ["spec.yaml:19:20"]),  # column inside the quotes
    ("title: planar 2R\n", "", ["missing field 'title'"]),
    ("inertia: I2", "inertai: I2", ["unknown field 'inertai'", "did you mean 'inertia'", "spec.yaml:20"]),
    ("gravity: [0, -g0, 0]", "gravity: [0, -g0, 0, 1]", ["gravity must be a vector of 2 or 3 components",
                                                         "spec.yaml:14"]),
    ("joints: [R, R]", "joints: [R, R", ["YAML syntax", "spec.yaml:"]),
    ("[R, R]", "[R, X]", ["joints"]),
    ("kind: dynamic_model", "kind: dynamics", ["ask kind", "dynamic_model"]),
    ("  m1: mass 1\n", "  m1: mass 1\n  q1: bad\n", ["generalized coordinate"]),
    ("mass: m2", "mass: \"__import__('os').system('echo hacked')\"", ["unexpected character"]),
]


@pytest.mark.parametrize("old, new, expected", SPEC_ERRORS)
def test_spec_errors_say_where_and_what(write, old, new, expected):
    msg = error_of(write, GOOD.replace(old, new))
    assert all(part in msg for part in expected), msg


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
    msg = error_of(write, text.replace("kind: redundancy", "kind: dynamic_model").split("    task:")[0], solve=True)
    assert "no bodies and no model" in msg and "spec.yaml:5:" in msg

