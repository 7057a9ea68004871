"""The worker prestarted with `robosolve solve` (solver.sandbox.prestart, solver.__main__): it warms up while the
command line is parsed, then runs the job bounded like any forked child; unused, it is stopped."""
import os
import subprocess
import sys
import time
from functools import partial

import pytest
from conftest import PROBLEMS, ROOT

from solver import sandbox
from solver.sandbox import TIME, USER, Limits, discard_prestarted, prestart, run_one
from solver.spec.errors import UserError

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="POSIX only")

WARMED: list[str] = []


def _warm_up() -> None:
    WARMED.append("warm")


def _report(tag: str) -> tuple[int, list[str], str]:
    return os.getpid(), list(WARMED), tag


def _sleep(seconds: float) -> None:
    time.sleep(seconds)


def _refuse() -> None:
    raise UserError("bad spec", None, "fix it")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie not yet reaped counts as gone
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.fixture(autouse=True)
def _clean():
    yield
    discard_prestarted()


def test_the_job_runs_in_the_prestarted_worker_after_its_warm_up():
    prestart(_warm_up)
    pid = sandbox._PRESTARTED.pid
    out = run_one(partial(_report, "x"))
    assert out.ok and out.value == (pid, ["warm"], "x")  # its warm-up's effects are there; not in this process
    assert WARMED == [] and sandbox._PRESTARTED is None and not _alive(pid)
    again = run_one(partial(_report, "y"))  # the next job: a fresh fork, as before
    assert again.ok and again.value[0] not in (pid, os.getpid()) and again.value[1:] == ([], "y")


def test_a_closure_is_run_by_a_fork_and_the_prestarted_worker_is_stopped():
    prestart(_warm_up)
    pid = sandbox._PRESTARTED.pid
    out = run_one(lambda: (os.getpid(), list(WARMED)))  # cannot be pickled
    assert out.ok and out.value[0] != pid and out.value[1] == []
    assert not _alive(pid)


def test_limits_and_user_errors_hold_in_the_prestarted_worker():
    prestart(_warm_up)
    t0 = time.monotonic()
    out = run_one(partial(_sleep, 30.0), Limits(1.0, 512))
    assert out.failure == TIME and time.monotonic() - t0 < 10
    prestart(_warm_up)
    out = run_one(_refuse)
    assert out.failure == USER and "bad spec" in out.message and "fix it" in out.message


def test_an_unused_prestarted_worker_is_stopped():
    prestart(_warm_up)
    pid = sandbox._PRESTARTED.pid
    discard_prestarted()
    assert sandbox._PRESTARTED is None and not _alive(pid)


@pytest.mark.parametrize("args", [["--help"], ["-f", "nope"], ["/no/such/spec.yaml"]])
def test_robosolve_solve_ends_at_once_when_the_job_never_comes_or_fails(args):
    """Usage errors exit 2 from typer, a missing spec from the worker; no worker is left behind (the command
    would otherwise wait for it: its output pipe stays open)."""
    r = subprocess.run([sys.executable, "-m", "solver", "solve", *args], capture_output=True, text=True, cwd=ROOT,
                       timeout=60)
    if args == ["--help"]:
        assert r.returncode == 0 and "Solve a problem" in r.stdout
    else:
        assert r.returncode == 2 and "Traceback" not in r.stderr


def test_robosolve_solve_with_a_report_file_and_figures(tmp_path):
    """`python -m solver solve` (the console script's path: the worker and the painter prestarted) writes the same
    report and figures as the CLI run in-process."""
    from typer.testing import CliRunner

    from solver.cli import app
    spec = PROBLEMS / "2004-03-25-ex1.yaml"
    r = subprocess.run([sys.executable, "-m", "solver", "solve", str(spec), "-o", str(tmp_path / "a" / "r.md")],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "2 figure(s)" in r.stderr
    res = CliRunner().invoke(app, ["solve", str(spec), "-o", str(tmp_path / "b" / "r.md")])
    assert res.exit_code == 0
    a, b = tmp_path / "a", tmp_path / "b"
    assert sorted(p.name for p in a.iterdir()) == sorted(p.name for p in b.iterdir()) == [
        "r-1-gravity.png", "r-1-inertia.png", "r.md"]
    assert (a / "r.md").read_text() == (b / "r.md").read_text()


def test_warm_up_prestarts_the_painter_only_for_a_written_report(monkeypatch):
    from solver.publish.report import warm_up
    from solver.publish import figures
    started: list[str] = []

    class Fake:
        def __init__(self, fmt: str) -> None:
            self.fmt, self.cancelled = fmt, False
            started.append(fmt)

        def cancel(self) -> None:
            self.cancelled = True
    monkeypatch.setattr(figures, "Painter", Fake)
    for argv, want in [(["p.yaml"], []), (["p.yaml", "-f", "json", "-o", "r.json"], []),
                       (["p.yaml", "-o", "r.md"], ["md"]), (["p.yaml", "--format=tex", "--output", "r.tex"], ["tex"])]:
        started.clear()
        warm_up(argv)
        assert started == want, argv
        pre = figures._PRESTARTED
        if want:
            assert figures.painter_for(want[0]) is pre and figures._PRESTARTED is None  # handed to the job
    warm_up(["p.yaml", "-o", "r.md"])
    pre = figures._PRESTARTED
    other = figures.painter_for("tex")  # the job wants another format: a new painter, the prestarted one stopped
    assert other is not pre and other.fmt == "tex" and pre.cancelled
