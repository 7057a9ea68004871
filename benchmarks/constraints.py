"""Benchmark: reduced dynamics of the planar 3R with two constraints of 2020-09-11-remote#4 (last link parallel to
y0, tip of link 2 on x = k), with the printed complement D(q) = (l1 c1 + l2 c12, l2 c12, 0).

Cases:
  exam   the exercise: inertia matrix with the generic symbolic elements m_ij (reduced inertia only asked);
  full   a full planar 3R model in a horizontal plane with symbolic lengths, CoM distances, masses and inertias:
         E, F, Ḟ, the reduced inertia FᵀBF, FᵀBḞ, Fᵀn and the reduced model along the constraint.
robosolve: ``reduce_model`` (the core of the ask kind: adjugates, numerators over powers of det [A; D], the
canonical trigonometric form): E, F, Ḟ, FᵀBF, FᵀBḞ, Fᵀn, FᵀGu, the E-side terms, the reduced model and λ along
the constraint (q̇ = F v). Peer: the same quantities with plain sympy, [A; D].inv() then ``simplify`` of every
entry (the readable forms a solution prints), each run capped (--cap seconds) in a subprocess.

    python benchmarks/constraints.py [--cap 300] [--cases exam,full]
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
from solver.interaction.constraints import reduce_model, time_derivative  # noqa: E402
from solver.math.simplify import tidy  # noqa: E402
from solver.spec.robot import Body, Robot  # noqa: E402

q = list(sp.symbols("q1:4", real=True))
dq = list(sp.symbols("dq1:4", real=True))
ddq = list(sp.symbols("ddq1:4", real=True))
l1, l2, k = sp.symbols("l1 l2 k", positive=True)


def constraint() -> tuple[sp.Matrix, sp.Matrix]:
    """(A, D) of the exercise."""
    h = sp.Matrix([q[0] + q[1] + q[2] - sp.pi / 2, l1 * sp.cos(q[0]) + l2 * sp.cos(q[0] + q[1]) - k])
    A = h.jacobian(q)
    D = sp.Matrix([[l1 * sp.cos(q[0]) + l2 * sp.cos(q[0] + q[1]), l2 * sp.cos(q[0] + q[1]), 0]])
    return A, D


def model(case: str) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """(B, c, g) of the case."""
    if case == "exam":
        m = sp.symbols("m11 m12 m13 m22 m23 m33", real=True)
        B = sp.Matrix([[m[0], m[1], m[2]], [m[1], m[3], m[4]], [m[2], m[4], m[5]]])
        return B, sp.zeros(3, 1), sp.zeros(3, 1)
    d1, d2, d3, l3 = sp.symbols("d1 d2 d3 l3", positive=True)
    m1, m2, m3, I1, I2, I3 = sp.symbols("m1 m2 m3 I1 I2 I3", positive=True)
    th = [q[0], q[0] + q[1], q[0] + q[1] + q[2]]
    L, dd, mm, II = [l1, l2, l3], [d1, d2, d3], [m1, m2, m3], [I1, I2, I3]
    bodies = []
    for i in range(3):
        x = sum(L[j] * sp.cos(th[j]) for j in range(i)) + dd[i] * sp.cos(th[i])
        y = sum(L[j] * sp.sin(th[j]) for j in range(i)) + dd[i] * sp.sin(th[i])
        bodies.append(Body(f"l{i}", mm[i], sp.Matrix([x, y, 0]), sp.Matrix([0, 0, sum(dq[:i + 1])]),
                           sp.diag(0, 0, II[i])))
    dm = derive(Robot(q, dq, ddq, ["R"] * 3, bodies, None, inputs=list(sp.symbols("u1:4"))))
    return dm.B, dm.c, dm.g


def robosolve(case: str) -> float:
    B, c, g = model(case)
    A, D = constraint()
    u = sp.Matrix(sp.symbols("u1:4", real=True))
    t = time.perf_counter()
    reduce_model(B, c, g, None, u, A, D, q, dq, ddq, sp.Matrix([sp.Symbol("v")]), sp.Matrix([sp.Symbol("dv")]))
    return time.perf_counter() - t


def plain_sympy(case: str) -> float:
    """The same quantities as ``reduce_model`` with plain sympy: [A; D]⁻¹, then simplify of each entry."""
    B, c, g = model(case)
    A, D = constraint()
    u = sp.Matrix(sp.symbols("u1:4", real=True))
    v, dv = sp.symbols("v dv")
    t = time.perf_counter()
    inv = A.col_join(D).inv()
    E, F = inv[:, :2].applyfunc(sp.simplify), inv[:, 2:].applyfunc(sp.simplify)
    Fdot = time_derivative(F, q, dq).applyfunc(sp.simplify)
    n = c + g
    for M in (F.T * B * F, F.T * B * Fdot, F.T * n, F.T * u, E.T * B * F, E.T * B * Fdot, E.T * n, E.T * u):
        M.applyfunc(sp.simplify)
    on_v = dict(zip(dq, F * v))
    (F.T * B * F * dv + F.T * (B * Fdot * v + n - u)).xreplace(on_v).applyfunc(sp.simplify)
    (E.T * (B * F * dv + B * Fdot * v + n - u)).xreplace(on_v).applyfunc(sp.simplify)
    return time.perf_counter() - t


def _worker(case: str, out) -> None:  # type: ignore[no-untyped-def]
    out.put(plain_sympy(case))


def peer(case: str, cap: float) -> float | None:
    ctx = mp.get_context("fork")
    qout = ctx.Queue()
    p = ctx.Process(target=_worker, args=(case, qout))
    p.start()
    p.join(cap)
    if p.is_alive():
        p.terminate()
        return None
    return qout.get() if not qout.empty() else None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cap", type=float, default=300.0)
    ap.add_argument("--cases", default="exam,full")
    args = ap.parse_args()
    print(f"{'case':<8}{'robosolve [s]':>15}{'sympy inv+simplify [s]':>26}{'ratio':>10}")
    for case in args.cases.split(","):
        tidy.cache_clear()
        ours = robosolve(case)
        theirs = peer(case, args.cap)
        th = f"{theirs:.2f}" if theirs is not None else f">{args.cap:.0f}"
        ratio = f"{theirs / ours:.1f}x" if theirs is not None else f">{args.cap / ours:.0f}x"
        print(f"{case:<8}{ours:>15.2f}{th:>26}{ratio:>10}", flush=True)


if __name__ == "__main__":
    main()
