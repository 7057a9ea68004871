"""Benchmark: full dynamic model (B, Christoffel, c, g) with robosolve vs sympy.physics.mechanics.

Robots: planar 2R, 3R, 4R (vertical plane, symbolic lengths/CoMs/masses/inertias) and a spatial 3R (DH, symbolic).
Peer: LagrangesMethod (mass matrix and forcing) followed by the simplification needed for readable forms
(trigsimp of every entry). Each peer run is capped (--cap seconds, default 300) in a subprocess.

    python benchmarks/dynamics.py [--cap 300] [--robots 2R,3R,4R,S3R]
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
from pathlib import Path

import sympy as sp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from solver.dynamics.model import derive  # noqa: E402
from solver.math.rigid import dh_chain, omega_from_rotation  # noqa: E402
from solver.math.simplify import tidy  # noqa: E402
from solver.spec.robot import Body, Robot  # noqa: E402


def planar(n: int):
    q = list(sp.symbols(f"q1:{n + 1}", real=True))
    dq = list(sp.symbols(f"dq1:{n + 1}", real=True))
    ddq = list(sp.symbols(f"ddq1:{n + 1}", real=True))
    l, d, m, I = (sp.symbols(f"{s}1:{n + 1}", positive=True) for s in ("l", "d", "m", "I"))
    g0 = sp.Symbol("g0", positive=True)
    coms, angles = [], []
    for i in range(n):
        th = [sum(q[:j + 1]) for j in range(i + 1)]
        x = sum(l[j] * sp.cos(th[j]) for j in range(i)) + d[i] * sp.cos(th[i])
        y = sum(l[j] * sp.sin(th[j]) for j in range(i)) + d[i] * sp.sin(th[i])
        coms.append(sp.Matrix([x, y, 0]))
        angles.append(th[-1])
    return dict(q=q, dq=dq, ddq=ddq, m=m, I=I, g0=g0, coms=coms, angles=angles, n=n)


def robosolve_planar(n: int) -> float:
    P = planar(n)
    t = time.perf_counter()
    bodies = [Body(f"l{i}", P["m"][i], P["coms"][i],
                   sp.Matrix([0, 0, sum(P["dq"][:i + 1])]), sp.diag(0, 0, P["I"][i])) for i in range(n)]
    derive(Robot(P["q"], P["dq"], P["ddq"], ["R"] * n, bodies, sp.Matrix([0, -P["g0"], 0]),
                 inputs=list(sp.symbols(f"u1:{n + 1}"))))
    return time.perf_counter() - t


def spatial3r_rows():
    q = list(sp.symbols("q1:4", real=True))
    d1, a2, a3 = sp.symbols("d1 a2 a3", positive=True)
    return q, [(0, sp.pi / 2, d1, q[0]), (a2, 0, 0, q[1]), (a3, 0, 0, q[2])], [0, a2, a3]


def robosolve_spatial() -> float:
    q, rows, a = spatial3r_rows()
    dq = list(sp.symbols("dq1:4", real=True))
    ddq = list(sp.symbols("ddq1:4", real=True))
    g0 = sp.Symbol("g0", positive=True)
    t = time.perf_counter()
    bodies = []
    for i, A in enumerate(dh_chain(rows, "standard")):
        R, p = A[:3, :3], A[:3, 3]
        Ixx, Iyy, Izz = sp.symbols(f"I{i + 1}xx I{i + 1}yy I{i + 1}zz", positive=True)
        com = (p + R * sp.Matrix([-a[i] / 2, 0, 0])).applyfunc(tidy)
        bodies.append(Body(f"l{i}", sp.Symbol(f"m{i + 1}", positive=True), com,
                           omega_from_rotation(R, q, dq), sp.diag(Ixx, Iyy, Izz), R, "link"))
    derive(Robot(q, dq, ddq, ["R"] * 3, bodies, sp.Matrix([0, 0, -g0]), inputs=list(sp.symbols("u1:4"))))
    return time.perf_counter() - t


# ---------------------------------------------------------------------------------------------- peer
def _mechanics(kind: str, n: int) -> float:
    from sympy.physics.mechanics import (
        LagrangesMethod,
        Lagrangian,
        Point,
        ReferenceFrame,
        RigidBody,
        dynamicsymbols,
        inertia,
    )
    t = time.perf_counter()
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    g0 = sp.Symbol("g0", positive=True)
    q = dynamicsymbols(f"q1:{n + 1}")
    bodies = []
    if kind == "planar":
        l, d, m, I = (sp.symbols(f"{s}1:{n + 1}", positive=True) for s in ("l", "d", "m", "I"))
        frame, joint = N, O
        for i in range(n):
            Fi = frame.orientnew(f"F{i}", "Axis", [q[i], frame.z])
            Ci = joint.locatenew(f"C{i}", d[i] * Fi.x)
            Ci.v2pt_theory(joint, N, Fi)
            b = RigidBody(f"B{i}", Ci, Fi, m[i], (inertia(Fi, 0, 0, I[i]), Ci))
            b.potential_energy = m[i] * g0 * Ci.pos_from(O).dot(N.y)
            bodies.append(b)
            nxt = joint.locatenew(f"J{i + 1}", l[i] * Fi.x)
            nxt.v2pt_theory(joint, N, Fi)
            frame, joint = Fi, nxt
    else:
        d1, a2, a3 = sp.symbols("d1 a2 a3", positive=True)
        F1 = N.orientnew("F1", "Body", [q[0], sp.pi / 2, 0], "ZXY")  # Rz(q1) Rx(pi/2)
        J1 = O.locatenew("J1", d1 * N.z)
        J1.set_vel(N, 0)
        F2 = F1.orientnew("F2", "Axis", [q[1], F1.z])
        F3 = F2.orientnew("F3", "Axis", [q[2], F2.z])
        J2 = J1.locatenew("J2", a2 * F2.x)
        J2.v2pt_theory(J1, N, F2)
        C = [J1.locatenew("C1", 0 * F1.x), J1.locatenew("C2", a2 / 2 * F2.x), J2.locatenew("C3", a3 / 2 * F3.x)]
        C[0].set_vel(N, 0)
        C[1].v2pt_theory(J1, N, F2)
        C[2].v2pt_theory(J2, N, F3)
        for i, (F, Ci) in enumerate(zip([F1, F2, F3], C)):
            Ixx, Iyy, Izz = sp.symbols(f"I{i + 1}xx I{i + 1}yy I{i + 1}zz", positive=True)
            mi = sp.Symbol(f"m{i + 1}", positive=True)
            b = RigidBody(f"B{i}", Ci, F, mi, (inertia(F, Ixx, Iyy, Izz), Ci))
            b.potential_energy = mi * g0 * Ci.pos_from(O).dot(N.z)
            bodies.append(b)
    L = Lagrangian(N, *bodies)
    lm = LagrangesMethod(L, q)
    lm.form_lagranges_equations()
    M = lm.mass_matrix.applyfunc(sp.trigsimp)
    f = lm.forcing.applyfunc(lambda e: sp.trigsimp(sp.expand(e)))
    del M, f
    return time.perf_counter() - t


def _worker(kind: str, n: int, out) -> None:  # type: ignore[no-untyped-def]
    out.put(_mechanics(kind, n))


def peer(kind: str, n: int, cap: float) -> float | None:
    ctx = mp.get_context("fork")
    qout = ctx.Queue()
    p = ctx.Process(target=_worker, args=(kind, n, qout))
    p.start()
    p.join(cap)
    if p.is_alive():
        p.terminate()
        return None
    return qout.get() if not qout.empty() else None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cap", type=float, default=300.0)
    ap.add_argument("--robots", default="2R,3R,4R,S3R")
    args = ap.parse_args()
    print(f"{'robot':<8}{'robosolve [s]':>15}{'mechanics+trigsimp [s]':>26}{'ratio':>10}")
    for name in args.robots.split(","):
        tidy.cache_clear()
        if name == "S3R":
            ours, theirs = robosolve_spatial(), peer("spatial", 3, args.cap)
        else:
            n = int(name[0])
            ours, theirs = robosolve_planar(n), peer("planar", n, args.cap)
        th = f"{theirs:.2f}" if theirs is not None else f">{args.cap:.0f}"
        ratio = f"{theirs / ours:.1f}x" if theirs is not None else f">{args.cap / ours:.0f}x"
        print(f"{name:<8}{ours:>15.2f}{th:>26}{ratio:>10}", flush=True)


if __name__ == "__main__":
    main()
