"""Benchmark: the residual terms of a spatial 3R (issue 10), with robosolve and with plain sympy.

Robot: an anthropomorphic 3R (DH: alpha1 = pi/2, d1, a2, a3), gravity along -z0, symbolic masses, CoMs
(-a_i/2 on the link axis) and diagonal inertias, viscous friction. Timed parts of the `collision` ask:

- the model (B, Christoffel, S, g) that the residuals need;
- the momentum residual: p = B q̇, Sᵀq̇, the integrand u + Sᵀq̇ − g − F_v q̇, and ṙ = K_I(τ_ext − r) derived from
  the model (the check Ḃ = S + Sᵀ);
- the energy residual: E = T + U and σ̇ = k_E(q̇ᵀτ_ext − σ) derived from the model;
- one contact per link (points given in the DH frames): J_c, rank, N(J_cᵀ), isolation, the estimate F(r);
- a simulated collision (robot + both residuals, scipy solve_ivp) with numeric values.

Peer: the same Sᵀq̇ with plain sympy, from the Christoffel symbols of the untidied B and `simplify` of each entry
(what one writes without robosolve's trigonometric canonical forms), capped (--cap seconds, default 300).

    python benchmarks/collision.py [--cap 300]
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from solver.dynamics.model import derive  # noqa: E402
from solver.interaction.collision import (  # noqa: E402
    _dh_frames, energy_residual, momentum_residual, simulate_collision)
from solver.math.simplify import tidy  # noqa: E402
from solver.solve import all_results, solve_problem  # noqa: E402
from solver.spec import load_problem_text  # noqa: E402

SPEC = """
id: bench-s3r
title: spatial 3R, symbolic
symbols: {d1: d1, a2: a2, a3: a3, m1: m1, m2: m2, m3: m3, g0: g0, fv: fv,
          I1x: I1x, I1y: I1y, I1z: I1z, I2x: I2x, I2y: I2y, I2z: I2z, I3x: I3x, I3y: I3y, I3z: I3z}
values: {d1: 0.5, a2: 0.6, a3: 0.4, m1: 4, m2: 3, m3: 2, g0: 9.81, fv: 0.3, I1x: 0.05, I1y: 0.02, I1z: 0.05,
         I2x: 0.01, I2y: 0.09, I2z: 0.09, I3x: 0.005, I3y: 0.03, I3z: 0.03}
robot:
  joints: [R, R, R]
  gravity: [0, 0, -g0]
  friction: {viscous: [fv, fv, fv]}
  dh:
    table: [{alpha: pi/2, d: d1, theta: q1}, {a: a2, theta: q2}, {a: a3, theta: q3}]
    links:
      - {mass: m1, com: [0, -d1/2, 0], inertia: [I1x, I1y, I1z]}
      - {mass: m2, com: [-a2/2, 0, 0], inertia: [I2x, I2y, I2z]}
      - {mass: m3, com: [-a3/2, 0, 0], inertia: [I3x, I3y, I3z]}
asks:
  - kind: collision
    contacts:
      - {link: 1, point: [0.05, -0.2, 0], point_in: link}
      - {link: 2, point: [-0.3, 0, 0.02], point_in: link}
      - {link: 3, point: [-0.1, 0.05, 0], point_in: link}
"""


def timed(f):  # type: ignore[no-untyped-def]
    t = time.perf_counter()
    out = f()
    return out, time.perf_counter() - t


def _peer(out) -> None:  # type: ignore[no-untyped-def]
    """Sᵀq̇ with plain sympy: Christoffel symbols of the raw B, then simplify of every entry."""
    p = load_problem_text(SPEC)
    robot = p.robot
    q, dq = robot.q, robot.dq
    t = time.perf_counter()
    B = sp.zeros(3, 3)
    for b in robot.bodies:
        Jv = b.com.jacobian(q)
        Jw = b.omega.jacobian(dq)
        B += b.mass * Jv.T * Jv + Jw.T * b.inertia * Jw
    v = sp.Matrix(dq)
    S = sp.zeros(3, 3)
    for k, qk in enumerate(q):
        J = B[:, k].jacobian(q)
        Ck = (J + J.T - B.diff(qk)) / 2
        S[k, :] = v.T * Ck
    sp.Matrix([sp.simplify(x) for x in S.T * v])
    out.put(time.perf_counter() - t)


def peer(cap: float) -> float | None:
    ctx = mp.get_context("fork")
    qout = ctx.Queue()
    proc = ctx.Process(target=_peer, args=(qout,))
    proc.start()
    proc.join(cap)
    if proc.is_alive():
        proc.terminate()
        return None
    return qout.get() if not qout.empty() else None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cap", type=float, default=300.0)
    args = ap.parse_args()
    tidy.cache_clear()
    p = load_problem_text(SPEC)
    robot = p.robot
    q, dq = robot.q, robot.dq
    n = 3
    K = sp.diag(*sp.symbols("kI1:4", positive=True))
    r = sp.Matrix(sp.symbols("r1:4", real=True))
    tau = sp.Matrix(sp.symbols("tau_ext1:4", real=True))
    dm, t_model = timed(lambda: derive(robot))
    mr, t_mom = timed(lambda: momentum_residual(dm, q, dq, K, r, tau))
    er, t_en = timed(lambda: energy_residual(dm, q, dq, sp.Symbol("kE", positive=True), sp.Symbol("sigma"), tau))
    assert mr.check and er.check
    tidy.cache_clear()
    res, t_ask = timed(lambda: all_results(solve_problem(load_problem_text(SPEC))))
    pos, R = _dh_frames(p)[2]
    point = pos + R * sp.Matrix([-0.1, 0.05, 0])
    data, t_sim = timed(lambda: simulate_collision(dm, q, dq, point, p.values, np.array([2.0, -3.0, 5.0]), 0.5, 1.5,
                                                   3.0, np.full(n, 20.0), 20.0, np.array([0.3, 0.5, -0.8]),
                                                   np.zeros(n)))
    ops = sum(sp.count_ops(x) for x in mr.integrand)
    print(f"spatial 3R, symbolic (ops in the integrand u + S^T dq - g - Fv dq: {ops})")
    print(f"  model B, Christoffel, S, g          {t_model:7.2f} s")
    print(f"  momentum residual terms, rdot check {t_mom:7.2f} s")
    print(f"  energy residual, sigma-dot check    {t_en:7.2f} s")
    print(f"  whole ask (model, residuals, 3 contacts: J_c, rank, null space, F(r)) {t_ask:7.2f} s "
          f"({len(res)} results)")
    print(f"  simulated collision, 3 s, {len(data.t)} samples {t_sim:7.2f} s "
          f"(max |r - tau_ext| over the last 0.2 s of contact: "
          f"{np.abs(data.r - data.tau_ext)[(data.t > 1.3) & (data.t < 1.5)].max():.2e})")
    theirs = peer(args.cap)
    th = f"{theirs:.2f} s" if theirs is not None else f"> {args.cap:.0f} s (capped)"
    print(f"  peer: S^T dq with sympy simplify     {th}")


if __name__ == "__main__":
    main()
