"""The problem library reproduces the printed solutions (this is robosolve's main correctness measure)."""
from pathlib import Path

import pytest
from conftest import PROBLEMS

from solver.spec import load_problem
from solver.verify import check_problem, describe

FILES = sorted(PROBLEMS.glob("*.yaml"))


def test_library_has_the_required_exercises():
    ids = {f.stem for f in FILES}
    required = ["2004-03-25-ex1", "2005-04-05-ex1", "2007-04-19-ex1", "2009-06-10-ex1", "2010-06-15-ex1",
                "2010-09-15-ex1", "2016-06-06-ex1", "2016-07-11-ex1", "2016-09-12-ex1", "2016-10-28-ex1",
                "2017-07-11-ex1", "2019-09-11-ex1", "2020-07-15-remote-ex1", "2021-01-12-ex3", "2021-09-10-ex2",
                "2021-04-14-remote-midterm-ex1"]
    assert not [r for r in required if r not in ids]


@pytest.mark.parametrize("path", FILES, ids=[f.stem for f in FILES])
def test_problem_reproduces_printed_results(path: Path):
    rep = check_problem(load_problem(path))
    assert rep.checks, "a library problem must check at least one printed result"
    assert rep.ok, "\n".join(describe(rep))


SPEC = (PROBLEMS / "2004-03-25-ex1.yaml").read_text() if (PROBLEMS / "2004-03-25-ex1.yaml").exists() else ""


def test_wrong_expected_value_fails(write):
    bad = SPEC.replace('c: {value: "[2*m2*q2*dq1*dq2, -m2*q2*dq1^2]"', 'c: {value: "[m2*q2*dq1*dq2, -m2*q2*dq1^2]"')
    assert bad != SPEC
    rep = check_problem(load_problem(write(bad)))
    assert not rep.ok
    c = next(ch for ch in rep.checks if ch.name == "c")
    assert c.verdict.verdict == "incorrect" and c.verdict.wrong == [(1, 1)]


def test_unconfirmed_erratum_fails(write):
    """An erratum whose printed value actually matches the solver is reported, not silently accepted."""
    bad = SPEC.replace('B: {value: "[[I0 + m2*q2^2, m2*l1], [m2*l1, m2]]", line: 37}',
                       'B: {value: "[[I0 + m2*q2^2, m2*l1], [m2*l1, m2]]", line: 37, erratum: "claimed", '
                       'corrected: "[[I0 + m2*q2^2, m2*l1], [m2*l1, m2]]"}')
    assert bad != SPEC
    rep = check_problem(load_problem(write(bad)))
    assert not rep.ok and any("NOT CONFIRMED" in line for line in describe(rep))


RP_CT = """id: rp-ct
title: RP with a computed-torque law
symbols: {m1: m1, m2: m2, d1: d1, l1: l1, I1: I1, I2: I2, g0: g0}
robot:
  joints: [R, P]
  gravity: [g0, 0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) - q2*sin(q1), l1*sin(q1) + q2*cos(q1)], angle: q1, inertia: I2}
asks:
  - kind: dynamic_model
  - kind: control_law
    law: computed_torque
"""


def test_every_entry_is_checked_and_every_failure_reported(write):
    """A missing result, an unreadable value and a wrong value each fail alone; the other entries are checked."""
    spec = RP_CT + """expected:
  Bx: {value: "0", line: 1}
  g: {value: "[(m1*d1 + m2*l1)*g0*sin(q1) + m2*g0*q2*cos(q1), m2*g0*sin(q1)]", line: 2}
  c: {value: "[m2*q2*dq1*dq2, -m2*q2*dq1^2]", line: 3}
  T1: {value: "m1 +* 2", line: 4}
"""
    rep = check_problem(load_problem(write(spec)))
    by = {c.name: c for c in rep.checks}
    assert set(by) == {"Bx", "g", "c", "T1"} and not rep.ok
    assert by["g"].verdict.ok
    assert by["c"].verdict.verdict == "incorrect"
    assert by["Bx"].verdict.verdict == "error" and "no result of that name" in by["Bx"].verdict.detail
    assert "results of this problem:" in by["Bx"].verdict.detail and "B," in by["Bx"].verdict.detail
    assert by["T1"].verdict.verdict == "error" and "spec.yaml:18:20: error: unexpected" in by["T1"].verdict.detail
    text = "\n".join(describe(rep))
    assert all(f"{n} (line {k})" in text for n, k in (("Bx", 1), ("c", 3), ("T1", 4)))


def test_check_names_every_unknown_result(write):
    from test_cli import run
    spec = RP_CT + """expected:
  Bx: {value: "0", line: 1}
  cc: {value: "0", line: 2}
  B: {value: "[[1, 0], [0, 1]]", line: 3}
"""
    r = run("check", str(write(spec)))
    assert r.returncode == 2
    assert "expected.Bx: no result of that name" in r.stderr and "expected.cc: no result of that name" in r.stderr
    assert "results of this problem: " in r.stderr and ", T1, " in r.stderr  # the names to choose from
    assert "Traceback" not in r.stderr


def test_a_result_printed_twice_is_checked_twice(write):
    spec = RP_CT + """expected:
  c:
    - {value: "[2*m2*q2*dq1*dq2, -m2*q2*dq1^2]", line: 10}
    - {value: "[2*m2*q2*dq2*dq1, -m2*dq1^2*q2]", line: 11}
    - {value: "[m2*q2*dq1*dq2, -m2*q2*dq1^2]", line: 12}
"""
    rep = check_problem(load_problem(write(spec)))
    assert [(c.name, c.line, c.verdict.verdict) for c in rep.checks] == [
        ("c", 10, "correct"), ("c", 11, "correct"), ("c", 12, "incorrect")]


def test_expected_values_use_the_names_the_solvers_create(write):
    """Gains and the desired trajectory of a control law (kp1, kd1, qd1, dqd1, ddqd1) need no declaration."""
    spec = RP_CT + """expected:
  closed_loop:
    value: "[ddqd1 - ddq1 + kd1*(dqd1 - dq1) + kp1*(qd1 - q1), ddqd2 - ddq2 + kd2*(dqd2 - dq2) + kp2*(qd2 - q2)]"
    line: 5
"""
    rep = check_problem(load_problem(write(spec)))
    assert rep.ok and [c.name for c in rep.checks] == ["closed_loop"], describe(rep)
    wrong = check_problem(load_problem(write(spec.replace("kp2*(qd2 - q2)", "kp1*(qd2 - q2)"), "w.yaml")))
    assert not wrong.ok


COND = """id: eqcond
title: equilibria that exist only when |a5| <= a4
symbols: {a4: a4, a5: a5}
robot:
  joints: [R]
  model: {B: "[[1]]", g: "[a4*cos(q1) + a5]"}
asks:
  - kind: equilibria
expected:
  equilibria: {value: "[[pi - acos(a5/a4)], [pi + acos(a5/a4)]]", line: 1}
"""


def test_verify_is_reproducible_where_results_exist_under_a_condition(write):
    """π ± acos(a5/a4) and robosolve's atan2 form are the same set wherever they exist (|a5| <= a4): the random
    points are drawn there, and every run (any string-hash seed) gives the same verdict, with the seed printed."""
    import subprocess
    import sys

    from conftest import ROOT
    path = write(COND)
    outs = set()
    for hashseed in ("1", "2", "3"):
        r = subprocess.run([sys.executable, "-m", "solver", "verify", str(path)], capture_output=True, text=True,
                           cwd=ROOT, env={**__import__("os").environ, "PYTHONHASHSEED": hashseed}, timeout=300)
        outs.add((r.returncode, r.stdout))
    assert len(outs) == 1
    code, out = outs.pop()
    assert code == 0 and "1/1 problems ok" in out and "seed 2024" in out
    wrong = write(COND.replace("pi - acos(a5/a4)", "pi - acos(a5/a4) + 1/10"), "wrong.yaml")
    assert not check_problem(load_problem(wrong)).ok


def test_a_value_of_the_wrong_kind_fails_its_entry_only(write):
    spec = RP_CT + """expected:
  christoffel: {value: "[1, 2]", line: 1}
  g: {value: "[(m1*d1 + m2*l1)*g0*sin(q1) + m2*g0*q2*cos(q1), m2*g0*sin(q1)]", line: 2}
"""
    rep = check_problem(load_problem(write(spec)))
    by = {c.name: c for c in rep.checks}
    assert not by["christoffel"].verdict.ok and by["g"].verdict.ok


def test_a_result_produced_by_two_asks_with_different_values_is_not_checked_silently():
    """Two asks giving `qdot_ps` for different task velocities: an expected qdot_ps is an error naming both asks
    (all_results keeps only the later one), while a name produced once is still checked."""
    from solver.spec import load_problem_text
    text = """
id: shadow
title: two tasks on a 3R
robot: {joints: [R, R, R]}
asks:
  - kind: redundancy
    task: [cos(q1) + cos(q1+q2) + cos(q1+q2+q3), sin(q1) + sin(q1+q2) + sin(q1+q2+q3)]
    velocity: [1, 0]
    at: {q1: 0, q2: pi/2, q3: 0}
  - kind: redundancy
    task: [cos(q1) + cos(q1+q2) + cos(q1+q2+q3), sin(q1) + sin(q1+q2) + sin(q1+q2+q3)]
    velocity: [0, 1]
    at: {q1: 0, q2: pi/2, q3: 0}
expected:
  qdot_ps: {value: "[0, 0, 0]", line: 1}
"""
    rep = check_problem(load_problem_text(text), compare=False)
    (c,) = rep.checks
    assert not c.verdict.ok and "asks 1 and 2" in c.verdict.detail and "suffix" in c.verdict.detail
    same = text.replace("velocity: [0, 1]", "velocity: [1, 0]")  # the same value twice: nothing to report
    assert check_problem(load_problem_text(same), compare=False).checks == []
