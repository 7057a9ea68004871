"""Benchmark: the adaptive (Slotine-Li) law on a 3-dof robot (planar 3R in a vertical plane, link lengths and g0
known), simulated for 10 s with the `simulate` ask. Prints the seconds of the symbolic design (model, regressor,
law) and of the simulation, and the wall seconds per simulated second; with --figure PATH draws the simulation.

    python benchmarks/simulate.py [--repeat 3] [--T 10] [--method auto|LSODA|RK45|...]
                                  [--figure docs/figures/simulate_adaptive.png]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

SPEC = """
id: bench-adaptive-3r
title: adaptive control of a planar 3R
symbols: {m1: m1, m2: m2, m3: m3, l: l, g0: g0}
values: {m1: 3, m2: 2, m3: 1, l: 0.5, g0: 9.81}
robot:
  joints: [R, R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [l/2*cos(q1), l/2*sin(q1)], angle: q1, inertia: m1*l^2/12}
    - {mass: m2, com: [l*cos(q1) + l/2*cos(q1 + q2), l*sin(q1) + l/2*sin(q1 + q2)], angle: q1 + q2, inertia: m2*l^2/12}
    - {mass: m3, com: [l*cos(q1) + l*cos(q1 + q2) + l/2*cos(q1 + q2 + q3), l*sin(q1) + l*sin(q1 + q2) + l/2*sin(q1 + q2 + q3)], angle: q1 + q2 + q3, inertia: m3*l^2/12}
known: [l, g0]
asks:
  - kind: control_law
    law: adaptive
    lambda: 5
    kd: 20
    gamma: 20
  - kind: simulate
    qd: ["0.5*sin(t)", "0.3*cos(2*t)", "0.2*t^2/(1 + t^2)"]
    q0: [0.2, 0, 0]
    T: {T}
    points: 500
    method: {method}
"""


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--T", type=float, default=10.0)
    ap.add_argument("--figure", type=Path, default=None)
    ap.add_argument("--method", default="auto", help="the simulate ask's integrator")
    a = ap.parse_args()
    from solver.registry import load_all
    from solver.spec import load_problem_text
    kinds = load_all()
    best_law = best_sim = float("inf")
    for _ in range(a.repeat):
        p = load_problem_text(SPEC.replace("{T}", str(a.T)).replace("{method}", a.method))
        t0 = time.perf_counter()
        law = kinds["control_law"].solve(p, p.asks[0].options, p.asks[0].ctx)
        t1 = time.perf_counter()
        sim = kinds["simulate"].solve(p, p.asks[1].options, p.asks[1].ctx)
        t2 = time.perf_counter()
        best_law, best_sim = min(best_law, t1 - t0), min(best_sim, t2 - t1)
    r = sim.results
    p_coef = len(law.results["a_adapt"].value)
    used = next(st.data["method"] for st in sim.steps if st.name == "simulate")
    print(f"coefficients p = {p_coef}; completed = {r['completed'].value}; evaluations = {r['nfev'].value} "
          f"({used})")
    print(f"|e(T)| = {float(r['e_final_norm'].value):.3g}, max |e| = {float(r['e_max_norm'].value):.3g}, "
          f"settling = {float(r['settling_time'].value):.3g} s")
    print(f"symbolic design (model, regressor, law) [s]: {best_law:.2f}")
    print(f"simulation of {a.T:g} s [s]: {best_sim:.2f}  ->  {best_sim / a.T:.3f} wall s per simulated s")
    if a.figure is not None:
        from solver.publish.figures import draw
        a.figure.parent.mkdir(parents=True, exist_ok=True)
        draw(sim.figures[0], a.figure)
        print(f"wrote {a.figure}")


if __name__ == "__main__":
    main()
