"""Benchmark: symbolic recursive Newton–Euler (robosolve's ``newton_euler``) vs the Euler–Lagrange model
(``derive``) on the same DH robots: planar 2R..6R (vertical plane) and a spatial 6R (anthropomorphic arm with a
spherical wrist; S4R, S5R its first joints), with symbolic lengths, CoMs, masses and diagonal inertias; S6Rn is the spatial 6R with
numeric data (q, q̇, q̈ symbolic).

NE: u = NE(q, q̇, q̈) with every recursion step simplified (what the report prints). Lagrange: B, the Christoffel
matrices, c, S with the skew check, g. Each run is capped (--cap seconds) in a subprocess; a run over the cap is
reported as "> cap". With --raw, also NE with the recursion expanded but not simplified. Both give the same u (tests/test_newton_euler.py checks it on every library DH robot).

    python benchmarks/newton_euler.py [--cap 60] [--robots 2R,3R,4R,5R,6R,S6Rn,S6R] [--raw]
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
from pathlib import Path

import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from solver.dynamics.model import derive
from solver.dynamics.newton_euler import newton_euler
from solver.math.rigid import dh_chain, omega_from_rotation
from solver.math.simplify import tidy
from solver.spec.robot import Body, Robot


def dh_robot(rows, com_x, n: int, gravity: sp.Matrix) -> Robot:
    """A DH robot with symbolic m_i, diag(I_ixx, I_iyy, I_izz) and the CoM of link i at (com_x[i], 0, 0) in frame i."""
    q = [r[3] for r in rows]
    dq = list(sp.symbols(f"dq1:{n + 1}", real=True))
    ddq = list(sp.symbols(f"ddq1:{n + 1}", real=True))
    frames = dh_chain(rows, "standard")
    bodies = []
    for i, A in enumerate(frames):
        R, p = A[:3, :3], A[:3, 3]
        Ixx, Iyy, Izz = sp.symbols(f"I{i + 1}xx I{i + 1}yy I{i + 1}zz", positive=True)
        com = (p + R * sp.Matrix([com_x[i], 0, 0])).applyfunc(tidy)
        bodies.append(Body(f"l{i}", sp.Symbol(f"m{i + 1}", positive=True), com, omega_from_rotation(R, q, dq),
                           sp.diag(Ixx, Iyy, Izz), R, "link"))
    return Robot(q, dq, ddq, ["R"] * n, bodies, gravity, inputs=list(sp.symbols(f"u1:{n + 1}")),
                 frames=[sp.eye(4)] + frames, dh_convention="standard")


def robot(name: str) -> Robot:
    g0 = sp.Symbol("g0", positive=True)
    if name.endswith("R") and name[0].isdigit():
        n = int(name[0])
        q = list(sp.symbols(f"q1:{n + 1}", real=True))
        a = sp.symbols(f"a1:{n + 1}", positive=True)
        d = sp.symbols(f"d1:{n + 1}", positive=True)
        rows = [(a[i], 0, 0, q[i]) for i in range(n)]
        return dh_robot(rows, [d[i] - a[i] for i in range(n)], n, sp.Matrix([0, -g0, 0]))
    q = list(sp.symbols("q1:7", real=True))
    d1, a2, d4, d6 = sp.symbols("d1 a2 d4 d6", positive=True)
    c = sp.symbols("c1:7", real=True)
    if name == "S6Rn":     # the same arm with numeric data (symbolic q, dq, ddq only)
        d1, a2, d4, d6 = sp.Rational(1, 2), sp.Rational(7, 10), sp.Rational(6, 10), sp.Rational(1, 10)
        c = [0, -sp.Rational(35, 100), 0, 0, 0, 0]
        r = dh_robot([(0, sp.pi / 2, d1, q[0]), (a2, 0, 0, q[1]), (0, sp.pi / 2, 0, q[2]),
                      (0, -sp.pi / 2, d4, q[3]), (0, sp.pi / 2, 0, q[4]), (0, 0, d6, q[5])], c, 6,
                     sp.Matrix([0, 0, -sp.Rational(981, 100)]))
        vals = {}
        for i, b in enumerate(r.bodies):
            vals[b.mass] = sp.Integer(6 - i)
            for k, x in enumerate(b.inertia.diagonal()):
                vals[x] = sp.Rational(k + 1, 10 * (i + 1))
        for b in r.bodies:
            b.mass, b.inertia = b.mass.xreplace(vals), b.inertia.xreplace(vals)
        return r
    rows = [(0, sp.pi / 2, d1, q[0]), (a2, 0, 0, q[1]), (0, sp.pi / 2, 0, q[2]), (0, -sp.pi / 2, d4, q[3]),
            (0, sp.pi / 2, 0, q[4]), (0, 0, d6, q[5])]
    k = int(name[1]) if name[1].isdigit() else 6      # S4R, S5R: the first joints of the spatial 6R
    return dh_robot(rows[:k], list(c)[:k], k, sp.Matrix([0, 0, -g0]))


def run(which: str, name: str, out: mp.Queue) -> None:
    r = robot(name)
    t = time.perf_counter()
    if which == "ne":
        newton_euler(r, r.dq, r.ddq)
    elif which == "ne_raw":
        newton_euler(r, r.dq, r.ddq, simplify=False)
    else:
        derive(r)
    out.put(time.perf_counter() - t)


def timed(which: str, name: str, cap: float) -> float | None:
    ctx = mp.get_context("fork")
    q: mp.Queue = ctx.Queue()
    p = ctx.Process(target=run, args=(which, name, q))
    p.start()
    p.join(cap)
    if p.is_alive():
        p.kill()
        p.join()
        return None
    return q.get() if not q.empty() else None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cap", type=float, default=60.0)
    ap.add_argument("--robots", default="2R,3R,4R,5R,6R,S6Rn,S6R")
    ap.add_argument("--raw", action="store_true", help="also NE with expansion only (no simplification)")
    args = ap.parse_args()
    print("| robot | Newton–Euler [s] | Lagrange [s] | Lagrange / NE |" + (" NE expanded only [s] |" if args.raw else ""))
    print("|---|---:|---:|---:|" + ("---:|" if args.raw else ""))
    for name in args.robots.split(","):
        ne = timed("ne", name, args.cap)
        lag = timed("lagrange", name, args.cap)
        fmt = lambda v: f"{v:.2f}" if v is not None else f"> {args.cap:.0f}"
        ratio = f"{lag / ne:.1f}x" if ne and lag else (f"> {args.cap / ne:.1f}x" if ne else "–")
        label = (f"spatial {name[1:]} (DH)" if name.startswith("S") and name != "S6Rn"
                 else "spatial 6R, numeric data" if name == "S6Rn" else f"planar {name}")
        raw = f" {fmt(timed('ne_raw', name, args.cap))} |" if args.raw else ""
        print(f"| {label} | {fmt(ne)} | {fmt(lag)} | {ratio} |{raw}", flush=True)


if __name__ == "__main__":
    main()
