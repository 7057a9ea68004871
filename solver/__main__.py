"""``python -m solver`` and the ``robosolve`` console script. For ``robosolve solve ...`` the worker that will
solve is forked first and imports sympy and the solvers (~1.2 s on a slow core) while this process imports typer
and pydantic and parses the command line (~0.35 s): on two cores the two overlap (:func:`solver.sandbox.prestart`).
Everything else goes straight to :mod:`solver.cli`."""
from __future__ import annotations

import sys


def main() -> None:
    argv = sys.argv[1:]
    if argv[:1] == ["solve"] and "--help" not in argv:
        from solver.publish.report import warm_up
        from solver.sandbox import prestart
        prestart(lambda: warm_up(argv[1:]))
    from solver.cli import main as cli_main
    cli_main()


if __name__ == "__main__":
    main()
