"""The figure helper process (solver.publish.figures.Painter) and the compiled-template cache of the renderer."""
import os
import sys
import time
from pathlib import Path

import pytest
from conftest import PROBLEMS

from solver.publish.figures import Painter, write_figures
from solver.publish.render import render
from solver.results import Curve, Figure, Panel, Solution
from solver.solve import solve_problem
from solver.spec import load_problem


def _solution(name: str = "demo") -> Solution:
    sol = Solution("demo")
    panel = Panel("$t$ [s]", "", [Curve("$q_1$", [0.0, 0.5, 1.0], [0.0, 0.25, 1.0])])
    sol.figures.append(Figure(name, "caption", lambda: [panel]))
    return sol


def test_painter_draws_the_same_files_as_in_process(tmp_path):
    sols = solve_problem(load_problem(PROBLEMS / "2004-03-25-ex1.yaml"))
    (tmp_path / "a").mkdir()
    here = write_figures(sols, tmp_path / "a" / "r.md", "md")
    painter = Painter("md")
    (tmp_path / "b").mkdir()
    there = painter.write(sols, tmp_path / "b" / "r.md", "md")
    assert [f.path for f in sols[0].figures] == ["r-1-gravity.png", "r-1-inertia.png"]  # set before drawing
    painter.wait()
    assert [p.name for p in here] == [p.name for p in there] == ["r-1-gravity.png", "r-1-inertia.png"]
    for a, b in zip(here, there):
        assert a.read_bytes() == b.read_bytes() and len(a.read_bytes()) > 10_000


def test_painter_failure_is_reported(tmp_path):
    painter = Painter("md")
    painter.write([_solution()], tmp_path / "missing-folder" / "r.md", "md")  # cannot be written
    with pytest.raises(RuntimeError, match="drawing the figures failed"):
        painter.wait()


def test_painter_without_figures_and_cancel(tmp_path):
    painter = Painter("tex")
    helper = painter.pid
    assert painter.write([Solution("empty")], tmp_path / "r.tex", "tex") == []
    # nothing to draw: the helper is stopped at once (not waited for through its warm-up) and reaped
    assert painter.pid == 0 and helper and not Path(f"/proc/{helper}").exists()
    painter.wait()
    other = Painter("md")
    pid = other.pid
    other.cancel()
    assert other.pid == 0 and pid and not Path(f"/proc/{pid}").exists()  # killed and reaped


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_painter_keeps_no_inherited_descriptor():
    """A parent that reads a pipe to its end (the sandbox) must not wait for the helper: the helper closes every
    descriptor it inherited but its own two pipes."""
    r, w = os.pipe()
    painter = Painter("md")
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:  # the helper closes them first thing (then its warm-up opens files
            fds = set(os.listdir(f"/proc/{painter.pid}/fd"))  # for a moment: fonts, modules)
            if len(fds - {"0", "1", "2"}) == 2:
                break
            time.sleep(0.005)
        assert len(fds - {"0", "1", "2"}) == 2
        assert str(w) not in fds and str(r) not in fds
    finally:
        painter.cancel()
        os.close(r)
        os.close(w)


def test_compiled_templates_follow_their_source(tmp_path):
    """The compiled-template cache gives the same text as a fresh compilation, and an edited template is compiled
    again (its source checksum is part of the entry)."""
    problem = load_problem(PROBLEMS / "2004-03-25-ex1.yaml")
    sols = solve_problem(problem)
    assert render(problem, sols, "tex") == render(problem, sols, "tex")
    (tmp_path / "md").mkdir()
    page = tmp_path / "md" / "page.md.j2"
    page.write_text("ONE {{ problem.id }}\n")
    assert render(problem, sols, "md", template_dir=tmp_path) == "ONE 2004-03-25-ex1\n"
    page.write_text("TWO {{ problem.id }}\n")
    assert render(problem, sols, "md", template_dir=tmp_path) == "TWO 2004-03-25-ex1\n"


@pytest.mark.parametrize("bad", [0, 1])
def test_painter_failure_in_either_half_is_reported(tmp_path, bad):
    """With several figures the painter draws every other one in a forked copy: a failure on either side is
    reported, and no process is left behind."""
    sols = [_solution("one"), _solution("two")]
    painter = Painter("md")
    pid = painter.pid
    jobs = painter.write(sols, tmp_path / "r.md", "md")
    (tmp_path / "r-1-one.png" if bad == 0 else tmp_path / "r-2-two.png").mkdir()  # a folder where a file goes
    assert len(jobs) == 2
    with pytest.raises(RuntimeError, match="drawing the figures failed"):
        painter.wait()
    assert not Path(f"/proc/{pid}").exists()


def test_sweep_on_the_grid_equals_lambdify():
    """sweep evaluates node by node with numpy (no generated code); the values are lambdify's, and a function
    it does not know goes to lambdify."""
    import numpy as np
    import sympy as sp

    from solver.math.sweep import sweep
    x, a, b = sp.symbols("x a b")
    grid = np.linspace(-3, 3, 41)
    fixed = {a: 0.7, b: -1.3}
    for e in [a * sp.cos(x) ** 2 + b * sp.sin(2 * x) / (2 + sp.cos(x)), sp.sqrt(1 + x ** 2) * sp.exp(-x / 4),
              sp.atan2(b * sp.sin(x), a + sp.cos(x)) + sp.Abs(x - a) ** sp.Rational(3, 2), 1 / sp.sqrt(a + x ** 2),
              sp.Max(x, a) + sp.pi * x, a * b + 0 * x]:
        ref = sp.lambdify(x, e.subs(fixed), "numpy")(grid)
        got = sweep(e, x, grid, fixed)
        assert np.allclose(got, np.broadcast_to(ref, grid.shape), rtol=1e-13, atol=1e-13), e


def test_painter_draws_each_ask_as_it_is_sent(tmp_path):
    """send() per ask (the CLI calls it from solve_problem's callback, as each ask is solved): the figure of an
    early ask is drawn before the last is sent, also a message larger than a pipe's buffer, and the files equal
    write()'s."""
    calls = []
    sols = solve_problem(load_problem(PROBLEMS / "2004-03-25-ex1.yaml"), lambda k, s: calls.append((k, s.kind)))
    assert [k for k, _ in calls] == list(range(1, len(sols) + 1))
    painter = Painter("md")
    big = Solution("demo")
    xs = [i / 20000 for i in range(20001)]
    big.figures.append(Figure("big", "", lambda: [Panel("$t$", "", [Curve("$y$", xs, [x * x for x in xs])])]))
    first = painter.send([big], tmp_path / "r.md", "md", first=1)  # (its pickled panels exceed a pipe's buffer)
    deadline = time.monotonic() + 60
    while not first[0].exists() and time.monotonic() < deadline:  # drawn before the last ask is sent
        time.sleep(0.05)
    assert first[0].exists()
    rest = painter.send(sols, tmp_path / "r.md", "md", first=2, last=True)
    painter.wait()
    assert [p.name for p in first + rest] == ["r-1-big.png", "r-2-gravity.png", "r-2-inertia.png"]
    (tmp_path / "a").mkdir()
    here = write_figures(sols, tmp_path / "a" / "r.md", "md")
    assert [p.read_bytes() for p in here] == [p.read_bytes() for p in rest]
