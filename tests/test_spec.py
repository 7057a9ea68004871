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
    # a list or a mapping where one number or expression goes: one message, not "Input should be a valid string"
    ("    - mass: m2", "    - mass: [m2]", ["spec.yaml:17:13", "robot.links[1].mass: expected one number or "
                                           "expression, got a list", "fix: write one value, e.g. mass: 0.1"]),
    ("inertia: I1}", "inertia: {z: I1}}", ["links[0].inertia: expected one number or expression, got a mapping"]),
]


def test_scalar_errors_are_counted_by_place(write):
    msg = error_of(write, GOOD.replace("mass: m1", "mass: [m1]").replace("mass: m2", "mass: [m2]"))
    assert "links[0].mass: expected one number or expression, got a list (and 1 more problem(s))" in msg
    assert "valid string" not in msg


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



def test_fast_yaml_reader_equals_the_round_trip_loader():
    """Plain YAML is read by libyaml (ruamel.yaml.clib, about 6x faster); its values, their types and their
    positions equal the round-trip loader's; anything else (a duplicate key, a tag, a merge key, a non-text key,
    what libyaml cannot parse) is read by the round-trip loader, with its results and messages."""
    from ruamel.yaml.main import CParser

    from solver.spec import yamlpos
    if CParser is None:
        pytest.skip("ruamel.yaml.clib is not installed")
    text = """# a comment
id: 'quoted'
title: "double \\u00e9"
base: &b {a: 1, b: [x, 'y', 2.5e-3]}
copy: *b
when: 2020-01-02
numbers: [0x1F, 0o17, -7, 1_000, .inf, -.5, 1e3, true, false, null, ~]
clock: 12:30
text: |
  first line
  second
folded: >-
  one
  two
nested:
  - {kind: dynamic_model, plots: false}
  -
    kind: trajectory
    values: {"a b": 3}
"""
    fast = yamlpos._load_fast(text, "f.yaml")
    assert fast is not None
    saved = yamlpos._load_fast
    try:
        yamlpos._load_fast = lambda t, f: None
        rt = yamlpos.load_text(text, "f.yaml")
        refused = {}
        for bad in ("a: 1\na: 2\n", "a: !foo 1\n", "a: &x {b: 1}\nc: {<<: *x}\n", "1: a\n", "a: [1\n",
                    "a: [12:30]\n"):   # (libyaml refuses ':' in a flow scalar, YAML 1.2 does not)
            try:
                refused[bad] = str(yamlpos.load_text(bad, "g.yaml").data)
            except Exception as exc:  # noqa: BLE001  (the round-trip loader's message)
                refused[bad] = f"{type(exc).__name__}: {exc}"
    finally:
        yamlpos._load_fast = saved
    assert fast.data == rt.data and fast.positions == rt.positions and fast.lines == rt.lines

    def leaves(x):  # noqa: ANN001, ANN202
        if isinstance(x, dict):
            return [y for v in x.values() for y in leaves(v)]
        return [y for v in x for y in leaves(v)] if isinstance(x, list) else [x]
    assert all(isinstance(a, type(b)) or isinstance(b, type(a)) for a, b in zip(leaves(fast.data), leaves(rt.data)))
    assert fast.data["numbers"][:4] == [31, 15, -7, 1000] and fast.place(("nested", 1, "kind")).line == 18
    for bad, expected in refused.items():   # the fast reader leaves them to the round-trip loader
        assert yamlpos._load_fast(bad, "g.yaml") is None
        try:
            got = str(yamlpos.load_text(bad, "g.yaml").data)
        except Exception as exc:  # noqa: BLE001
            got = f"{type(exc).__name__}: {exc}"
        assert got == expected
