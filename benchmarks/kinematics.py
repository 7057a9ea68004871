"""Benchmark: symbolic 6×6 geometric Jacobian of a 6R arm (PUMA-like DH table, symbolic lengths) and the closed-form
factorization of its determinant (the singular configurations), with robosolve's kinematics functions; the naive
sympy route (base-frame Jacobian, Matrix.det, factor) as the peer, capped in a subprocess.

    python benchmarks/kinematics.py [--cap 300] [--repeat 3]
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
from pathlib import Path

import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from solver.kinematics import geometry as geo  # noqa: E402
from solver.math.rigid import dh_chain  # noqa: E402
from solver.math.trigsolve import trig_factors  # noqa: E402


def puma():
    """PUMA 560-like standard DH table: shoulder offset d2... here d3, elbow a2, a3, wrist d4, spherical wrist."""
    q = list(sp.symbols("q1:7", real=True))
    a2, a3, d3, d4 = sp.symbols("a2 a3 d3 d4", positive=True)
    h = sp.pi / 2
    rows = [(0, -h, 0, q[0]), (a2, 0, d3, q[1]), (a3, h, 0, q[2]), (0, -h, d4, q[3]), (0, h, 0, q[4]),
            (0, 0, 0, q[5])]
    return q, rows


def robosolve_run() -> dict:
    q, rows = puma()
    t0 = time.perf_counter()
    frames = [sp.eye(4)] + dh_chain(rows, "standard")
    t1 = time.perf_counter()
    Jg = geo.geometric_jacobian(frames, ["R"] * 6, "standard")
    t2 = time.perf_counter()
    t3 = time.perf_counter()
    d, k, j = geo.geometric_det(frames, ["R"] * 6, "standard")
    const, factors = trig_factors(d)
    t4 = time.perf_counter()
    return {"frames": t1 - t0, "Jg": t2 - t1, "det+factor": t4 - t3, "total": t4 - t0,
            "det": sp.Mul(const, *[f**m for f, m in factors]), "factors": factors, "frame": k, "point": j,
            "ops_Jg": sp.count_ops(Jg)}


def _naive(out) -> None:  # type: ignore[no-untyped-def]
    q, rows = puma()
    t0 = time.perf_counter()
    frames = [sp.eye(4)] + dh_chain(rows, "standard")
    Jg = geo.geometric_jacobian(frames, ["R"] * 6, "standard")
    d = sp.factor(sp.trigsimp(Jg.det(method="berkowitz")))
    out.put((time.perf_counter() - t0, str(d)[:200]))


def naive_run(cap: float) -> tuple[float | None, str]:
    ctx = mp.get_context("fork")
    qout = ctx.Queue()
    p = ctx.Process(target=_naive, args=(qout,))
    p.start()
    p.join(cap)
    if p.is_alive():
        p.terminate()
        p.join()
        return None, f"> {cap:.0f} s (stopped)"
    t, d = qout.get()
    return t, d


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cap", type=float, default=300.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    runs = []
    for _ in range(args.repeat):
        from solver.math.simplify import tidy
        tidy.cache_clear()
        runs.append(robosolve_run())
    best = min(runs, key=lambda r: r["total"])
    print("robosolve, PUMA-like 6R (symbolic a2, a3, d3, d4), best of", args.repeat)
    for k in ("frames", "Jg", "det+factor", "total"):
        print(f"  {k:12s} {best[k]:8.2f} s")
    print(f"  base-frame J_g: {best['ops_Jg']} operations; det taken in frame {best['frame']} at o_{best['point']}")
    print("  det J_g =", best["det"])
    print("  singular where:", ", ".join(f"{f} = 0" for f, _ in best["factors"]))
    t, d = naive_run(args.cap)
    print("naive sympy (base-frame J_g, Matrix.det, trigsimp, factor):",
          f"{t:.1f} s" if t is not None else d)


if __name__ == "__main__":
    main()
