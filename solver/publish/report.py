"""The report of one problem, as ``robosolve solve`` makes it in its bounded worker: ``solve_job`` is a plain
function of picklable arguments (no typer), so that the worker prestarted before the command line is parsed
(``solver.__main__``) can be handed it; ``warm_up(argv)`` is what that worker does meanwhile: it starts the figure
painter when the command line asks for a written report with figures, then imports what ``solve_job`` needs.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from solver.results import Solution


def solve_job(spec: Path, fmt: str, output: Path | None, fragment: bool, templates: Path | None, details: bool,
              jobs: int) -> tuple[str, int]:
    """``robosolve solve``: load, solve and render ``spec``; figures drawn beside ``output`` by a painter process
    while the asks are solved. (The report's text, the number of figures written)."""
    from solver.publish.figures import painter_for
    painter = painter_for(fmt) if output and fmt != "json" else None
    try:
        from solver.registry import frozen_imports
        with frozen_imports():
            from solver.publish.render import render
            from solver.sandbox import cores
            from solver.solve import solve_problem
            from solver.spec import load_problem
        problem = load_problem(spec)
        figures: list[Path] = []
        sent: dict[int, Solution] = {}  # asks whose figures went to the painter ahead of an earlier ask

        def early(k: int, solution: Solution) -> None:  # solved before an earlier ask: its figures drawn now
            assert painter is not None and output is not None
            sent[k] = solution
            figures.extend(painter.send([solution], output, fmt, first=k))

        def solved(k: int, solution: Solution) -> None:  # its figures drawn while the next asks are solved
            assert painter is not None and output is not None
            last = k == len(problem.asks)
            todo = [] if sent.get(k) is solution else [solution]  # (a clash at the merge: solved again)
            figures.extend(painter.send(todo, output, fmt, first=k, last=last))
            if last and not figures:  # nothing to draw: do not wait for the warm-up
                painter.cancel()
        drawing = painter is not None and output is not None
        solutions = solve_problem(problem, solved if drawing else None, jobs=jobs or cores(),
                                  figures=painter is not None, early=early if drawing else None,
                                  optional=details)
        text = render(problem, solutions, fmt, fragment=fragment, template_dir=templates, details=details)
        if painter:
            painter.wait()
    except BaseException:
        if painter:
            painter.cancel()
        raise
    return text, len(figures)


def warm_up(argv: list[str]) -> None:
    """In a worker started with ``robosolve solve ...``, before its job comes: the painter (forked first, so that
    matplotlib warms up on the other core) when ``argv`` writes a report (-o) other than JSON, then the imports of
    :func:`solve_job`. The command line is only glanced at: the job brings the parsed options, and a painter for
    another format is replaced then."""
    from solver.publish.figures import prestart_painter
    fmt, out = "md", False
    for i, a in enumerate(argv):
        nxt = argv[i + 1] if i + 1 < len(argv) else ""
        if a in ("-o", "--output") or a.startswith("--output="):
            out = True
        elif a in ("-f", "--format"):
            fmt = nxt
        elif a.startswith("--format="):
            fmt = a.split("=", 1)[1]
    if out and fmt in ("md", "tex"):
        prestart_painter(fmt)
    import importlib

    from solver.registry import frozen_imports
    with frozen_imports():
        for name in ("solver.publish.render", "solver.solve", "solver.spec.loader"):
            importlib.import_module(name)
