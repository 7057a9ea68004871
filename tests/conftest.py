import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ROOT / "problems"

RP_ROBOT = """
id: trp
title: planar RP (2004-03-25)
symbols: {m1: m1, m2: m2, d1: d1, l1: l1, I1: I1, I2: I2, g0: g0}
robot:
  joints: [R, P]
  gravity: [g0, 0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) - q2*sin(q1), l1*sin(q1) + q2*cos(q1)], angle: q1, inertia: I2}
"""  # the planar RP robot of 2004-03-25 (tests append known:/asks:)

R2_ROBOT = """robot:
  joints: [R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) + d2*cos(q1 + q2), l1*sin(q1) + d2*sin(q1 + q2)], angle: q1 + q2, inertia: I2}
"""  # a planar 2R in a vertical plane (tests prepend id/title/symbols, append the rest)


@pytest.fixture
def write(tmp_path):
    """Write a spec text to a temporary file and return its path."""

    def _write(text: str, name: str = "spec.yaml") -> Path:
        p = tmp_path / name
        p.write_text(text)
        return p

    return _write


def check_and_solve(path: Path) -> tuple[subprocess.CompletedProcess, subprocess.CompletedProcess]:
    """`robosolve check` and `robosolve solve` of one spec file (a spec error: both exit 2, the same message)."""
    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "solver", *args, str(path)], capture_output=True, text=True,
                              cwd=ROOT, timeout=600)
    return run("check"), run("solve", "--format", "json")


def error_found_without_solving(text: str) -> str:
    """The UserError solving the spec raises, which the asks' validate hooks (what `check` runs, no solving) give
    too, alone and with the same message: that message."""
    from solver.solve import solve_problem, validate_problem
    from solver.spec import load_problem_text
    from solver.spec.errors import UserError
    with pytest.raises(UserError) as exc:
        solve_problem(load_problem_text(text))
    assert [str(e) for e in validate_problem(load_problem_text(text))] == [str(exc.value)]
    return str(exc.value)
