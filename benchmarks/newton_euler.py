"""Benchmark: symbolic recursive Newton–Euler (robosolve's ``newton_euler``) vs the Euler–Lagrange model
(``derive``) on the same DH robots, with symbolic lengths, CoMs, masses and inertias:

- planar 2R..6R in a vertical plane, S3R (anthropomorphic), PUMA (the PUMA-560 DH table with its real offsets
  a2, a3, d3, d4 and centres of mass off the axes) and G6R (the same table, generic centres of mass and diagonal
  inertias): the robots of ``benchmarks/dynamics.py``, built by its ``describe``/``spec_text``;
- S4R, S5R, S6R: an anthropomorphic arm with a spherical wrist (d1, a2, d4, d6; CoM offsets c_i on the link x
  axes), its first 4, 5 or all 6 joints; S6Rn the same arm with numeric data (q, q̇, q̈ symbolic only).

NE: u = NE(q, q̇, q̈) with every ω, ω̇, a, a_c, f, τ of the report written out (what the ask prints); "u only":
the same recursion writing only u (NE as a routine). Lagrange:
B, the Christoffel matrices, c, S with the skew check, g and the model. Both from the loaded spec (loading is not
timed). Each run is a forked process capped at --cap wall seconds; times are CPU seconds of the computation. Then
both models are evaluated at --points random states and parameter values (exact substitution): `agree` is the
largest relative difference of the torques (0: equal to double precision). With --raw, also NE with the
recursion expanded but not simplified (the general path).

    python benchmarks/newton_euler.py [--cap 60] [--robots 2R,3R,4R,5R,6R,S3R,S4R,S5R,S6R,S6Rn,PUMA,G6R] [--raw]
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import queue
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from dynamics import _values, agreement, describe, parameters, spec_text  # noqa: E402  (benchmarks/dynamics.py)

clock = time.process_time
DEFAULT = "2R,3R,4R,5R,6R,S3R,S4R,S5R,S6R,S6Rn,PUMA,G6R"
LABELS = {"S3R": "spatial 3R (anthropomorphic)", "PUMA": "PUMA-like 6R (real offsets, DH)",
          "G6R": "6R, generic CoMs (PUMA table)", "S6Rn": "spatial 6R, numeric data"}


def description(name: str) -> dict:
    """A DH description as benchmarks/dynamics.py writes them (rows, links, gravity as strings)."""
    if not name.startswith("S") or name == "S3R":
        return describe(name)
    rows = [("0", "pi/2", "d1", "q1"), ("a2", "0", "0", "q2"), ("0", "pi/2", "0", "q3"), ("0", "-pi/2", "d4", "q4"),
            ("0", "pi/2", "0", "q5"), ("0", "0", "d6", "q6")]
    if name == "S6Rn":  # numeric lengths, masses, inertias and CoMs
        rows = [(a, al, {"d1": "1/2", "d4": "3/5", "d6": "1/10"}.get(d, d), th) for a, al, d, th in rows]
        rows[1] = ("7/10", "0", "0", "q2")
        links = [(str(6 - i), ["-7/20" if i == 1 else "0", "0", "0"],
                  [f"{k + 1}/{10 * (i + 1)}" for k in range(3)]) for i in range(6)]
        return dict(rows=rows, links=links, gravity=["0", "0", "-981/100"])
    k = int(name[1])
    links = [(f"m{i}", [f"c{i}", "0", "0"], [f"I{i}xx", f"I{i}yy", f"I{i}zz"]) for i in range(1, k + 1)]
    return dict(rows=rows[:k], links=links, gravity=["0", "0", "-g0"])


def points(desc: dict, k: int, seed: int) -> list[dict]:
    """Random states and parameter values {name: value}."""
    rng = random.Random(seed)
    out = []
    for _ in range(k):
        p = {x: rng.uniform(0.5, 1.5) for x in parameters(desc)}
        for i in range(1, len(desc["rows"]) + 1):
            p[f"q{i}"], p[f"dq{i}"], p[f"ddq{i}"] = rng.uniform(-3.1, 3.1), rng.uniform(-1, 1), rng.uniform(-1, 1)
        out.append(p)
    return out


def run(which: str, name: str, npoints: int, seed: int, out: mp.Queue) -> None:
    try:
        _run(which, name, npoints, seed, out)
    except Exception as exc:  # reported in the table instead of waiting for the cap
        out.put(("error", f"{type(exc).__name__}: {exc}"[:80]))


def _run(which: str, name: str, npoints: int, seed: int, out: mp.Queue) -> None:
    from solver.dynamics.model import derive
    from solver.dynamics.newton_euler import newton_euler
    from solver.spec import load_problem_text
    desc = description(name)
    text = spec_text(name, desc).replace("symbols:\nrobot:", "symbols: {}\nrobot:")  # numeric data: no symbols
    r = load_problem_text(text).robot
    t = clock()
    if which == "ne":
        u = newton_euler(r, r.dq, r.ddq).u
    elif which == "ne_u":
        u = newton_euler(r, r.dq, r.ddq, links=False).u
    elif which == "ne_raw":
        u = newton_euler(r, r.dq, r.ddq, simplify=False).u
    else:
        u = derive(r).lhs
    out.put(("time", clock() - t))
    out.put(("values", _values(u, points(desc, npoints, seed))))


def timed(which: str, name: str, cap: float, npoints: int, seed: int) -> tuple[float | None, list | None]:
    """(CPU seconds or None past the cap, the torques at the random points or None)."""
    ctx = mp.get_context("fork")
    q: mp.Queue = ctx.Queue()
    p = ctx.Process(target=run, args=(which, name, npoints, seed, q))
    p.start()
    deadline = time.monotonic() + cap
    got: dict = {}
    while len(got) < 2 and "error" not in got:
        try:
            k, v = q.get(timeout=max(deadline - time.monotonic(), 0.01))
            got[k] = v
        except queue.Empty:
            break
    if "error" in got:
        print(f"{which} {name}: {got['error']}", file=sys.stderr)
    if p.is_alive():
        p.kill()
    p.join()
    return got.get("time"), got.get("values")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cap", type=float, default=60.0, help="wall seconds per run (computation + evaluation)")
    ap.add_argument("--robots", default=DEFAULT)
    ap.add_argument("--points", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--raw", action="store_true", help="also NE with expansion only (no simplification)")
    args = ap.parse_args()
    print(f"CPU seconds; each run capped at {args.cap:.0f} s wall; agree = largest relative difference of the "
          f"torques NE vs Lagrange at {args.points} random points")
    print("| robot | Newton–Euler [s] | NE, u only [s] | Lagrange [s] | Lagrange / NE | agree |"
          + (" NE expanded only [s] |" if args.raw else ""))
    print("|---|---:|---:|---:|---:|---:|" + ("---:|" if args.raw else ""))
    fmt = lambda v: f"{v:.2f}" if v is not None else f"> {args.cap:.0f}"  # noqa: E731
    for name in args.robots.split(","):
        ne, ne_vals = timed("ne", name, args.cap, args.points, args.seed)
        ne_u = timed("ne_u", name, args.cap, 0, args.seed)[0]
        lag, lag_vals = timed("lagrange", name, args.cap, args.points, args.seed)
        ratio = f"{lag / ne:.1f}x" if ne and lag else (f"> {args.cap / ne:.1f}x" if ne else "–")
        agree = f"{agreement(lag_vals, ne_vals):.0e}" if ne_vals and lag_vals else "–"
        label = LABELS.get(name, f"spatial {name[1:]} (DH)" if name.startswith("S") else f"planar {name}")
        raw = f" {fmt(timed('ne_raw', name, args.cap, 0, args.seed)[0])} |" if args.raw else ""
        print(f"| {label} | {fmt(ne)} | {fmt(ne_u)} | {fmt(lag)} | {ratio} | {agree} |{raw}", flush=True)


if __name__ == "__main__":
    main()
