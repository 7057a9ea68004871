import json
import subprocess
import sys

from conftest import PROBLEMS, ROOT

RP = str(PROBLEMS / "2004-03-25-ex1.yaml")


def run(*args):
    return subprocess.run([sys.executable, "-m", "solver", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=600)


def test_solve_formats(tmp_path):
    r = run("solve", RP)
    assert r.returncode == 0 and "$$B(q) =" in r.stdout
    r = run("solve", RP, "--format", "json")
    assert r.returncode == 0 and "B" in json.loads(r.stdout)["results"]
    out = tmp_path / "o" / "rp.tex"
    r = run("solve", RP, "--format", "tex", "-o", str(out))
    assert r.returncode == 0 and out.read_text().startswith("\\documentclass")
    figures = sorted(p.name for p in out.parent.glob("rp-*.pdf"))  # plots beside the report, included by it
    assert figures == ["rp-1-gravity.pdf", "rp-1-inertia.pdf"]
    assert all("\\includegraphics[width=" in out.read_text() and name in out.read_text() for name in figures)
    md = tmp_path / "o" / "rp.md"
    assert run("solve", RP, "-o", str(md)).returncode == 0
    assert "](rp-1-gravity.png)" in md.read_text() and (md.parent / "rp-1-gravity.png").stat().st_size > 5000


def test_check_list_schema():
    assert run("check", RP).stdout.strip().endswith("ok")
    r = run("list", str(PROBLEMS))
    assert r.returncode == 0 and "2004-03-25-ex1" in r.stdout and "dynamic_model" in r.stdout
    assert "properties" in json.loads(run("schema").stdout)


def test_user_errors_exit_2(tmp_path):
    assert run("solve", str(tmp_path / "missing.yaml")).returncode == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text("id: x\ntitle: [unclosed\n")
    r = run("check", str(bad))
    assert r.returncode == 2 and "bad.yaml:" in r.stderr and "Traceback" not in r.stderr


def test_verify_exit_codes(tmp_path):
    r = run("verify", RP)
    assert r.returncode == 0 and "1/1 problems ok" in r.stdout
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(open(RP).read().replace("-m2*q2*dq1^2]", "m2*q2*dq1^2]"))
    r = run("verify", str(wrong))
    assert r.returncode == 1 and "FAIL" in r.stdout


def test_grade_and_answer_template(tmp_path):
    subs = ROOT / "examples" / "submissions" / "2004-03-25-ex1"
    r = run("grade", RP, str(subs / "bob.yaml"))
    assert r.returncode == 0 and "**Score: 8 / 12**" in r.stdout and "| `g` | incorrect | 1 / 2 |" in r.stdout
    out = tmp_path / "res"
    r = run("grade", RP, str(subs), "--out", str(out), "--gradescope", "-j", "2")
    assert r.returncode == 0, r.stderr
    assert (out / "summary.csv").read_text().count("\n") == 5  # header + 4 students
    assert json.loads((out / "gradescope" / "alice.yaml" / "results.json").read_text())["score"] == 12
    r = run("answer-template", RP)
    assert r.returncode == 0 and '\nB: ""' in r.stdout and "4 points" in r.stdout
    assert run("grade", RP, str(tmp_path / "nothing")).returncode == 2


def test_check_exam_files(tmp_path):
    r = run("check", str(ROOT / "exams" / "2020-07-15-remote.yaml"))
    assert r.returncode == 0 and "ok (exam file, 2 problem(s))" in r.stdout
    bad = tmp_path / "e.yaml"
    bad.write_text("title: X\nproblems:\n  - problem: nope\n")
    r = run("check", str(bad))
    assert r.returncode == 2 and "e.yaml:3:14: error: problem 'nope' not found" in r.stderr


# ------------------------------------------------------------------------------------------------ check: validation
def test_every_library_problem_validates_and_is_left_as_loaded():
    """The validate hooks (what `check` runs for each ask before solving) accept every shipped problem — no
    false error from reading an ask without the asks before it — and leave the problem as loaded."""
    from solver.registry import load_all
    from solver.solve import validate_problem
    from solver.spec import load_problem
    load_all()
    for path in sorted(PROBLEMS.glob("*.yaml")):
        problem = load_problem(path)
        names, latex, fields = dict(problem.names), dict(problem.latex_names), set(problem.__dict__)
        assert validate_problem(problem) == [], path
        assert (problem.names, problem.latex_names, set(problem.__dict__)) == (names, latex, fields), path


TWO_BAD = """id: two
title: two bad asks
robot: {joints: [R, R, R]}
asks:
  - {kind: kinematics, task: [q1 + q4, q2]}
  - {kind: kinematics, task: [q1, q2, q3]}
  - {kind: redundancy, task: [q1 + q2 + q3], at: {q5: 1}}
"""


def test_check_reports_every_bad_ask(tmp_path):
    """Each ask is validated: both errors, at their lines, exit 2 (solve stops at the first)."""
    spec = tmp_path / "two.yaml"
    spec.write_text(TWO_BAD)
    r = run("check", str(spec))
    assert r.returncode == 2 and r.stdout == "", r.stdout
    assert f"{spec}:5:36: error: unknown name 'q4'" in r.stderr
    assert f"{spec}:7:" in r.stderr and "'q5' in at: is not a coordinate" in r.stderr
    assert r.stderr.count("error:") == 2 and "Traceback" not in r.stderr


LATER_NAME = """id: later
title: a name a law registers when solved
symbols: {m1: m1, m2: m2, l1: l1, l2: l2}
robot:
  joints: [R, R]
  links:
    - {mass: m1, com: [l1*cos(q1), l1*sin(q1)]}
    - {mass: m2, com: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]}
asks:
  - kind: control_law
    law: computed_torque
  - {kind: kinematics, task: [q1 - qd1, q2 - qd2]}
  - {kind: kinematics, task: [q1 + qd2, q2], suffix: _b}
"""


def test_a_name_an_earlier_ask_registers_when_solved_is_not_an_error(tmp_path):
    """qd1, qd2 exist once the law of ask 1 is solved (solve reads ask 2 after it): validation looks the unknown
    name up again after solving the earlier asks, and still reports a name nobody registers."""
    from solver.solve import validate_problem
    from solver.spec import load_problem
    spec = tmp_path / "later.yaml"
    spec.write_text(LATER_NAME)
    problem = load_problem(spec)
    assert validate_problem(problem) == [] and "qd1" not in problem.names
    spec.write_text(LATER_NAME.replace("q2 - qd2", "q2 - qe2").replace("q1 + qd2", "q1 + qe1"))
    errors = validate_problem(load_problem(spec))
    assert [str(e).split(": error: ")[0] for e in errors] == [f"{spec}:12:46", f"{spec}:13:36"]
    assert "unknown name 'qe2'" in str(errors[0]) and "unknown name 'qe1'" in str(errors[1])
