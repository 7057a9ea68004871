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
