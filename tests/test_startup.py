"""Start-up (issue 11): `check` and `solve` import only the modules of the ask kinds a file uses, with the same
diagnostics as the union of every kind; `--help` imports no sympy. No timed assertions: what is imported is what
the start-up costs."""
import json
import subprocess
import sys

import pytest

from conftest import PROBLEMS, ROOT
from solver.registry import _declared_modules, _registered_modules, kind_modules, load_all
from solver.spec import load_problem
from solver.spec.errors import UserError
from solver.spec.models import json_schema

# The CLI in this process: without os.fork, solver.sandbox runs the work in-process, so that what the work
# imported is in sys.modules at the end.
PROBE = """
import json, os, sys
del os.fork
sys.argv = ["robosolve"] + sys.argv[1:]
from solver.cli import main
code = 0
try:
    main()
except SystemExit as exc:
    code = exc.code
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""

HEAVY = ("scipy", "matplotlib")


def imported(*args: str) -> tuple[int, set[str], str]:
    """Exit code, imported modules and output of `robosolve <args>` run in one process."""
    r = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, cwd=ROOT, timeout=600)
    lines = r.stdout.strip().splitlines()
    assert lines, r.stderr
    out = json.loads(lines[-1])
    return out["code"], set(out["modules"]), "\n".join(lines[:-1]) + r.stderr


def kind_modules_in(modules: set[str]) -> set[str]:
    return set(kind_modules().values()) & modules


def test_the_index_names_what_importing_registers():
    """kind_modules() (source search, no import) == what load_all() registers, with the module of each."""
    index = kind_modules()
    kinds = load_all()
    assert len(index) >= 15
    assert index == {name: kind.solve.__module__ for name, kind in kinds.items()}
    # once every module is imported, the index is read from the registrations: the same, in the same order
    assert list(_registered_modules().items()) == list(_declared_modules().items())


def test_check_of_a_dynamics_problem_imports_its_kind_only():
    code, modules, out = imported("check", str(PROBLEMS / "2007-04-19-ex1.yaml"))  # asks: dynamic_model
    assert code == 0 and "2007-04-19-ex1.yaml: ok" in out
    assert kind_modules_in(modules) == {"solver.dynamics.model"}
    for chapter in ("kinematics", "control", "interaction", "planning"):
        assert not any(m.startswith(f"solver.{chapter}.") for m in modules), chapter
    for m in (*HEAVY, "numpy", "jinja2", "solver.grading.grader", "solver.publish.handout", "solver.publish.render"):
        assert m not in modules, m
    assert "sympy" in modules  # the problem is solved: its expected: entries must name results


def test_check_of_a_multi_kind_problem_imports_those_kinds():
    code, modules, out = imported("check", str(PROBLEMS / "2016-09-12-ex1.yaml"))
    assert code == 0 and out.strip().endswith("ok")
    assert kind_modules_in(modules) == {"solver.dynamics.model", "solver.dynamics.equilibria",
                                        "solver.dynamics.parametrization"}
    assert not any(m in modules for m in HEAVY)


def test_check_of_a_kinematics_problem_and_of_an_exam():
    code, modules, out = imported("check", str(PROBLEMS / "2014-10-27-ex2.yaml"))  # asks: kinematics
    assert code == 0 and out.strip().endswith("ok")
    assert kind_modules_in(modules) == {"solver.kinematics.analysis"}
    assert not any(m in modules for m in HEAVY)
    code, modules, out = imported("check", str(ROOT / "exams" / "2020-07-15-remote.yaml"))
    assert code == 0 and "ok (exam file, 2 problem(s))" in out


def test_solve_imports_its_kinds_and_no_plotting_without_figures():
    code, modules, out = imported("solve", str(PROBLEMS / "2007-04-19-ex1.yaml"), "--format", "json")
    assert code == 0 and "B" in json.loads(out[out.index("{"):])["results"]
    assert kind_modules_in(modules) == {"solver.dynamics.model"}
    assert not any(m in modules for m in (*HEAVY, "numpy"))  # numpy only to sample figures


def test_solve_of_a_control_law_problem_imports_no_numpy():
    """control_law needs numpy only to check a numeric Γ and gains: not to derive a law (numpy's import is ~0.1 s
    of a 2 s command)."""
    code, modules, out = imported("solve", str(PROBLEMS / "2004-03-25-ex1.yaml"), "--format", "json")
    assert code == 0 and "control_law" in out
    assert kind_modules_in(modules) == {"solver.dynamics.model", "solver.dynamics.parametrization",
                                        "solver.control.laws"}
    assert not any(m in modules for m in (*HEAVY, "numpy"))


def test_solve_does_not_import_sympy_units_for_simplify():
    """sympy's simplify and solve import sympy.physics.units (0.1 s) to look for physical quantities: solve and
    render answer that import with a stub (solver.math.nounits). These two problems call sp.simplify and
    sp.solve."""
    for name in ("2009-09-10-ex2.yaml", "2005-04-05-ex1.yaml"):
        code, modules, out = imported("solve", str(PROBLEMS / name), "--format", "tex")
        assert code == 0 and "\\begin{document}" in out, out[-500:]
        assert not any(m == "sympy.physics" or m.startswith("sympy.physics.") for m in modules), name


LAMBDIFY_NP = """
import sys
import numpy as np
import sympy as sp
from solver.math.numeric import lambdify_np
x = sp.Symbol("x")
f = lambdify_np([x], sp.Matrix([[sp.sin(x) + sp.Heaviside(x - 1), sp.sqrt(x)]]))
assert np.allclose(f(2.0), [[np.sin(2.0) + 1, np.sqrt(2.0)]])
print(sorted(m for m in ("numpy.testing", "numpy.f2py", "numpy.ma", "numpy.random") if m in sys.modules))
"""


def test_lambdify_np_imports_none_of_numpys_extras():
    """lambdify_np runs sympy's NumPy code in numpy's own namespace: no `from numpy import *` (which imports
    numpy.testing, numpy.f2py, ...: about 45 ms of a `solve` that samples a curve without scipy)."""
    r = subprocess.run([sys.executable, "-c", LAMBDIFY_NP], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stdout + r.stderr


NOUNITS = """
import sys
import sympy as sp
from solver.math.nounits import without_units
x = sp.Symbol("x")
with without_units():
    assert sp.simplify(sp.sin(x)**2 + sp.cos(x)**2) == 1
    assert sp.solve(x**2 - 4, x) == [-2, 2]
    assert "sympy.physics" not in sys.modules
assert "sympy.physics.units" not in sys.modules
with without_units():
    from sympy.physics import units as inside  # sympy.physics imported inside the block: unloaded on leaving
    assert "stand-in" in inside.__doc__
assert not any(m.startswith("sympy.physics") for m in sys.modules) and not hasattr(sp, "physics")
from sympy.physics.units import Quantity, meter
assert isinstance(meter, Quantity) and sp.simplify(2 * meter - meter) == meter
with without_units():  # the real package is loaded: left alone
    assert sys.modules["sympy.physics.units"].Quantity is Quantity
    assert sp.simplify(2 * meter - meter) == meter
print("ok")
"""


def test_without_units_is_undone_on_leaving_the_block():
    r = subprocess.run([sys.executable, "-c", NOUNITS], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stdout + r.stderr


def test_heavy_imports_run_without_the_collector_and_are_frozen():
    """frozen_imports: no cyclic collection while importing, the imported objects frozen after (a full collection
    then skips them), the collector enabled again; `solve` imports sympy inside it."""
    code = ("import gc, sys; from solver.registry import frozen_imports\n"
            "with frozen_imports():\n"
            "    inside = gc.isenabled()\n"
            "    import sympy\n"
            "print(inside, gc.isenabled(), gc.get_freeze_count() > 100000)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.stdout.split() == ["False", "True", "True"], r.stdout + r.stderr
    src = (ROOT / "solver" / "publish" / "report.py").read_text()
    body = src[src.index("def solve_job("):]
    assert body.index("with frozen_imports():") < body.index("from solver.publish.render import render")


def test_the_figure_helper_is_forked_before_sympy_is_imported():
    """`solve -o` forks the figure helper first thing in the worker, so that it warms matplotlib up while the
    worker imports sympy: importing the Painter (solver.publish.figures, solver.results) must not import sympy."""
    r = subprocess.run([sys.executable, "-c", "import sys; from solver.publish.figures import Painter; "
                        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('sympy', 'numpy')))"],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stdout + r.stderr
    src = (ROOT / "solver" / "publish" / "report.py").read_text()
    body = src[src.index("def solve_job("):]
    assert body.index("painter_for(") < body.index("from solver.spec import load_problem")
    warm = src[src.index("def warm_up("):]
    assert warm.index("prestart_painter(") < warm.index("frozen_imports()")


def test_help_imports_no_maths():
    code, modules, out = imported("--help")
    assert code == 0 and "check" in out
    assert not any(m in modules for m in ("sympy", "numpy", "pydantic", *HEAVY))


ASK_ERRORS = [  # an error inside an ask, the kinds the spec uses all known: same message with the union of all kinds
    "  - kind: dynamic_model\n    figures: maybe\n",
    "  - kind: dynamic_model\n    figurs: true\n",
    "  - kind: equilibria\n  - kind: dynamic_model\n    blah: 1\n",
    "  - kind: kinematics\n    task: [q1]\n    jacobian: 3\n",
    "  - kind: redundancy\n",
    "  - kind: dynamic_model\n  - 3\n",
    "  - kind: dynamic_modle\n",
    "  - {}\n",
    "  - kind: dynamic_model\n    title: [1, 2]\n",
]

SPEC = """\
id: t
title: planar 2R
symbols: {m1: mass 1, m2: mass 2, l1: length 1, d1: com 1, d2: com 2, I1: inertia 1, I2: inertia 2, g0: gravity}
robot:
  joints: [R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) + d2*cos(q1 + q2), l1*sin(q1) + d2*sin(q1 + q2)], angle: q1 + q2, inertia: I2}
asks:
"""


def message(write, text: str) -> str:
    with pytest.raises(UserError) as exc:
        load_problem(write(text))
    return str(exc.value)


@pytest.mark.parametrize("asks", ASK_ERRORS)
def test_ask_errors_are_those_of_the_union_of_every_kind(write, monkeypatch, asks):
    import solver.spec.models as models
    lazy = message(write, SPEC + asks)
    monkeypatch.setattr(models, "spec_kinds", lambda data: None)  # the union of every kind, as before
    assert message(write, SPEC + asks) == lazy
    assert "spec.yaml:1" in lazy  # at the ask's line (10 and after)


@pytest.mark.parametrize("path", sorted(PROBLEMS.glob("*.yaml")), ids=lambda p: p.stem)
def test_spec_validated_ask_by_ask_equals_the_union_model(path):
    """validate_spec (SpecBase, then each ask by its kind's model) reads every library spec as the union does."""
    from solver.spec.models import spec_kinds, spec_model, validate_spec
    from solver.spec.yamlpos import load_file
    data = load_file(path).data
    fast, union = validate_spec(data), spec_model(spec_kinds(data)).model_validate(data)
    assert type(fast).__name__ == "SpecBase"  # (the fast path was taken)
    assert [type(a) for a in fast.asks] == [type(a) for a in union.asks] and fast.asks == union.asks
    assert fast.model_dump() == union.model_dump()


def test_unknown_field_of_an_ask_is_matched_against_its_own_kind(write):
    msg = message(write, SPEC + "  - kind: dynamic_model\n    plot: false\n")
    assert "unknown field 'plot'" in msg and "did you mean 'plots'?" in msg
    msg = message(write, SPEC + "  - kind: dynamic_model\n  - kind: equilibria\n    solv: x\n")
    assert "spec.yaml:13:" in msg and "did you mean 'solve_for'?" in msg


def test_unknown_kind_lists_every_kind_at_its_line(write):
    msg = message(write, SPEC + "  - kind: dynamic_model\n  - kind: dynamics\n")
    assert "spec.yaml:12:5: error: unknown or missing ask kind" in msg and ", ".join(sorted(kind_modules())) in msg


def test_schema_is_the_union_of_every_kind_after_a_lazy_load(write):
    load_problem(write(SPEC + "  - kind: equilibria\n"))  # one kind imported on demand first
    schema = json_schema()
    variants = schema["properties"]["asks"]["items"]["oneOf"]
    names = [v["$ref"].rsplit("/", 1)[-1] for v in variants]
    assert len(names) == len(kind_modules())
    kinds = load_all()
    assert names == [kinds[k].options.__name__ for k in kind_modules()]


ANTHROPOMORPHIC = """\
id: s3r
title: spatial RRR by DH
symbols: {d1: base height, a2: link 2, a3: link 3, m1: mass 1, m2: mass 2, m3: mass 3, g0: gravity,
          I1xx: i, I1yy: i, I1zz: i, I2xx: i, I2yy: i, I2zz: i, I3xx: i, I3yy: i, I3zz: i}
robot:
  joints: [R, R, R]
  gravity: [0, 0, -g0]
  dh:
    table:
      - {a: 0, alpha: pi/2, d: d1, theta: q1}
      - {a: a2, alpha: 0, d: 0, theta: q2}
      - {a: a3, alpha: 0, d: 0, theta: q3}
    links:
      - {mass: m1, com: [0, 0, 0], inertia: [I1xx, I1yy, I1zz]}
      - {mass: m2, com: [-a2/2, 0, 0], inertia: [I2xx, I2yy, I2zz]}
      - {mass: m3, com: [-a3/2, 0, 0], inertia: [I3xx, I3yy, I3zz]}
asks:
  - kind: dynamic_model
    plots: false
"""


def test_a_dh_model_imports_nothing_once_the_chapters_are_loaded(tmp_path):
    """Loading, solving and printing a DH arm's model (without figures: their samples evaluate sin and cos at
    numbers) imports no module (sympy's first evaluated sin or cos imports sympy.sets.setexpr and more: ~12 ms of
    a small solve, which the canonical form does not need)."""
    spec = tmp_path / "s3r.yaml"
    spec.write_text(ANTHROPOMORPHIC)
    probe = ("import sys, json\n"
             "from solver.registry import load_all\n"
             "from solver.spec import load_problem\n"
             "from solver.solve import solve_problem\n"
             "from solver.publish.render import render\n"
             "load_all(); import sympy.tensor.tensor\n"
             "before = set(sys.modules)\n"
             f"p = load_problem({str(spec)!r}); s = solve_problem(p); out = render(p, s, 'json')\n"
             "new = sorted(set(sys.modules) - before)\n"
             "print(json.dumps({'new': new, 'model': 'model' in json.loads(out)['results']}))")
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert got["model"] and [m for m in got["new"] if m not in ("solver.sandbox", "solver.solve")] == []
