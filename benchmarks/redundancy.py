"""Benchmark: SNS (Saturation in the Null Space) at acceleration level on a 7-dof arm (KUKA-LWR-like DH table) over
random states: q, q̇, a desired 6-D end-effector acceleration and joint-acceleration bounds, J̇q̇ by central finite
differences. Times each SNS solve (floating point, rank tolerance 1e-9) and reports the iterations and how often the
task had to be scaled.

    python benchmarks/redundancy.py [--states 1000] [--seed 1] [--rows 6|3]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from solver.kinematics import resolution as rs

DH7 = [(0, np.pi / 2, 0.31), (0, -np.pi / 2, 0), (0, -np.pi / 2, 0.4), (0, np.pi / 2, 0),
       (0, np.pi / 2, 0.39), (0, -np.pi / 2, 0), (0, 0, 0.078)]  # (a, alpha, d)


def jacobian(q: np.ndarray) -> np.ndarray:
    """6x7 geometric Jacobian in the base frame."""
    T = np.eye(4)
    zs, ps = [], []
    for (a, al, d), th in zip(DH7, q):
        zs.append(T[:3, 2].copy())
        ps.append(T[:3, 3].copy())
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d],
                          [0, 0, 0, 1]])
    pe = T[:3, 3]
    return np.vstack([np.column_stack([np.cross(z, pe - p) for z, p in zip(zs, ps)]), np.column_stack(zs)])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--states", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rows", type=int, default=6, choices=(3, 6), help="6: pose task; 3: position task")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    la = rs.LA(False)
    times, iters, scaled, saturated = [], [], 0, []
    h = 1e-6
    for _ in range(args.states):
        q = rng.uniform(-np.pi, np.pi, 7)
        qd = rng.uniform(-1, 1, 7)
        J = jacobian(q)[:args.rows]
        h_vec = (((jacobian(q + h * qd) - jacobian(q - h * qd)) / (2 * h)) @ qd)[:args.rows]
        a = rng.normal(size=args.rows) * 2.0
        A = rng.uniform(2, 10, 7)
        x = (a - h_vec).reshape(args.rows, 1)
        t0 = time.perf_counter()
        res = rs.sns(la, J, x, list(-A), list(A))
        times.append(time.perf_counter() - t0)
        v = res.qdot.ravel()
        assert np.all(np.abs(v) <= A + 1e-8), "bound violated"
        iters.append(len(res.steps))
        saturated.append(len(res.saturated))
        scaled += res.s < 1
    ms = [t * 1e3 for t in times]
    print(f"SNS at acceleration level, 7-dof arm, {args.rows}-D task, {args.states} random states (seed {args.seed})")
    print(f"time per solve: mean {statistics.mean(ms):.3f} ms, median {statistics.median(ms):.3f} ms, "
          f"p95 {sorted(ms)[int(0.95 * len(ms))]:.3f} ms, max {max(ms):.3f} ms")
    print(f"iterations: mean {statistics.mean(iters):.2f}, max {max(iters)}; saturated joints: mean "
          f"{statistics.mean(saturated):.2f}; task scaled in {scaled} of {args.states} states; every bound respected")


if __name__ == "__main__":
    main()
