"""Benchmark: grading a class of 300 with and without hostile files (issue 8's acceptance point).

The hostile class adds an alias bomb, a where-chain, a 50 MB file, a binary file, links out of the folder, colliding
names and a folder named like a submission (tests/test_hostile.py builds it). Both classes are graded by the CLI
(`robosolve grade ... --out`, both cores); the wall time, the peak memory of a worker and the number of rows are
printed. The hostile class should take no longer than the clean one plus the time limits of the bad files that
reach a worker (those refused at once cost nothing).

    python benchmarks/hostile_class.py [--n 300]
"""
from __future__ import annotations

import argparse
import csv
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from test_hostile import RP, SECRET, SUBS, make_hostile_class  # noqa: E402


def grade(folder: Path, out: Path) -> tuple[float, float, int]:
    """(seconds, peak MB of any process of the run, rows)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "solver", "grade", str(RP), str(folder), "--out", str(out), "-j", "2"],
                       capture_output=True, text=True, cwd=ROOT)
    seconds = time.perf_counter() - t
    if r.returncode:
        raise SystemExit(r.stderr)
    peak = max(before, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss) / 1024
    with (out / "summary.csv").open(encoding="utf-8") as f:
        rows = sum(1 for _ in csv.DictReader(f))
    return seconds, peak, rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=300)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        base = Path(d)
        outside = base / "outside"
        outside.mkdir()
        (outside / "secret.txt").write_text(SECRET)
        (outside / "other.yaml").write_text(f"student: {SECRET}\n")
        clean = base / "clean"
        clean.mkdir()
        examples = sorted(SUBS.iterdir())
        for k in range(args.n):
            shutil.copy(examples[k % len(examples)], clean / f"s{k:03d}{examples[k % len(examples)].suffix}")
        hostile_names = make_hostile_class(base / "hostile", outside, args.n)
        t_clean, m_clean, rows_clean = grade(clean, base / "out-clean")
        t_host, m_host, rows_host = grade(base / "hostile", base / "out-hostile")
        leaked = any(SECRET in p.read_text(errors="replace") for p in (base / "out-hostile").rglob("*") if p.is_file())
    print("| class | submissions | rows | wall [s] | peak memory [MB] |\n|---|---:|---:|---:|---:|")
    print(f"| clean | {args.n} | {rows_clean} | {t_clean:.1f} | {m_clean:.0f} |")
    print(f"| hostile | {len(hostile_names)} | {rows_host} | {t_host:.1f} | {m_host:.0f} |")
    print(f"\nratio hostile/clean: {t_host / t_clean:.2f}; secret leaked: {leaked}")


if __name__ == "__main__":
    main()
