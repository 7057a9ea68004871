"""Benchmark: a 3-problem solutions handout (PDF), with the solve and LaTeX phases timed separately.

Target (issue 4): under 15 s in total on the 2-core machine.

    python benchmarks/handout.py [--problems id1,id2,id3] [--runs 3]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from solver.math.simplify import tidy  # noqa: E402
from solver.publish.handout import build, latex_tool, load_sources  # noqa: E402

DEFAULT = "2004-03-25-ex1,2016-09-12-ex1,2020-07-15-remote-ex1"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--problems", default=DEFAULT)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    paths = [ROOT / "problems" / f"{p}.yaml" for p in args.problems.split(",")]
    print(f"LaTeX: {' '.join(latex_tool() or ['none'])}")
    print(f"{'run':<5}{'load [s]':>10}{'solve+figures [s]':>20}{'LaTeX [s]':>12}{'total [s]':>12}")
    for k in range(args.runs):
        tidy.cache_clear()
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            hand = load_sources(paths)
            t_load = time.perf_counter() - t0
            r = build(hand, "solutions", "pdf", Path(d) / "sol.pdf")
            total = time.perf_counter() - t0
            print(f"{k + 1:<5}{t_load:>10.2f}{total - t_load - r['latex']:>20.2f}{r['latex']:>12.2f}{total:>12.2f}")


if __name__ == "__main__":
    main()
