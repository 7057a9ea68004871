"""The Lagrangian model computed in the canonical trigonometric-polynomial form from start to end.

Every quantity (p_c, J_v, ω, B, C_k, c, S, g, the model) is a :class:`solver.math.trigpoly.TrigAlgebra`
element: sums, products and derivatives are exact and stay canonical, nothing is simplified in between, and each
result is written once at the end (the same form :func:`solver.math.simplify.tidy` gives). Robots whose data
are not trigonometric polynomials with rational coefficients (floats, fractions in the parameters, tan, ...)
return None and take the general path of :func:`solver.dynamics.model.derive`.
"""
from __future__ import annotations

from functools import cache, partial
from typing import Any

import sympy as sp
from sympy.polys.domains import QQ

from solver.math.trigpoly import NotTrigPolynomial, TrigAlgebra
from solver.results import Deferred
from solver.spec.robot import Robot

Vec = list  # list[TrigPoly]
Mat = list  # list[list[TrigPoly]]


def _energy(A: TrigAlgebra, V: Vec, m: Any, pairs: dict, half: Any) -> tuple:
    """(‖v_c‖², T_i) of one body from its products pairs[(i, j)] = (J_vᵢᵀJ_vⱼ, J_ωᵢᵀ I J_ωⱼ), i ≤ j:
    ‖v_c‖² = Σ q̇ᵢq̇ⱼ J_vᵢᵀJ_vⱼ, T_i = ½ m ‖v_c‖² + ½ Σ q̇ᵢq̇ⱼ J_ωᵢᵀ I J_ωⱼ."""
    v2, wIw = {}, {}
    for (i, j), (pv, pw) in pairs.items():
        vv = A.mul(V[i], V[j]) if i == j else A.scale(A.mul(V[i], V[j]), 2)
        v2, wIw = A.add(v2, A.mul(pv, vv)), A.add(wIw, A.mul(pw, vv))
    return v2, A.add(A.scale(A.mul(m, v2), half), A.scale(wIw, half))


def derive_canonical(robot: Robot):  # type: ignore[no-untyped-def]
    """:class:`solver.dynamics.model.DynamicModel` of ``robot``, or None when its data leave the algebra."""
    from solver.dynamics.model import BodyEnergy, DynamicModel
    n, q, dq, ddq = robot.n, robot.q, robot.dq, robot.ddq
    inputs: list = [robot.gravity] if robot.gravity is not None else []
    elements = []  # bodies whose p_c and ω the loader computed in the canonical form: taken as they are
    for b in robot.bodies:
        inputs += [b.mass, b.inertia]
        if b.trig is not None:
            elements.append((b.trig[0], list(b.trig[1]) + list(b.trig[2])))
        else:
            inputs += [b.com, b.omega]
    inputs += list(robot.kinetic_extra) + list(robot.potential_extra)
    inputs += [m for m in (robot.given_B, robot.given_U, robot.given_g, robot.given_c, robot.friction) if m is not None]
    try:
        shared = {id(src): src for src, _ in elements}  # the loader's algebra, when one holds every body
        A = TrigAlgebra.of(inputs, extra=list(q) + list(dq) + list(ddq), elements=elements,
                           within=next(iter(shared.values())) if len(shared) == 1 and len(elements) == n else None)
        conv, mat = A.conv, A.matrix
        half = A.R.ground_new(QQ(1, 2))
        V = [A.symbol(v) for v in dq]
        grav = [A.conv(x) for x in robot.gravity] if robot.gravity is not None else None
        bodies = []
        B: Mat = [[{} for _ in range(n)] for _ in range(n)]
        for body in robot.bodies:
            m = conv(body.mass)
            if body.trig is not None:
                src, pc, w = body.trig
                P, W = [A.take(src, x) for x in pc], [A.take(src, x) for x in w]
            else:
                P, W = [conv(x) for x in body.com], [conv(x) for x in body.omega]
            Jv = [[A.diff(p, qj) for qj in q] for p in P]
            Jw = [[A.diff(w, v) for v in dq] for w in W]
            I = mat(body.inertia)
            vc = [A.dot(row, V) for row in Jv]
            IJw = A.matmul(I, Jw)
            # J_vᵢᵀJ_vⱼ and J_ωᵢᵀ I J_ωⱼ once: they give both B and ‖v_c‖² = Σ q̇ᵢq̇ⱼ J_vᵢᵀJ_vⱼ, ωᵀIω likewise
            pairs = {}
            for i in range(n):
                for j in range(i, n):
                    pv = A.dot([r[i] for r in Jv], [r[j] for r in Jv])
                    pw = A.dot([r[i] for r in Jw], [r[j] for r in IJw])
                    B[i][j] = A.add(B[i][j], A.mul(m, pv), pw)
                    pairs[(i, j)] = (pv, pw)
            U = A.scale(A.mul(m, A.dot(grav, P)), -1) if grav is not None else None
            bodies.append((body, P, vc, cache(partial(_energy, A, V, m, pairs, half)), U))  # (when first read)
        T_extra = A.add(*[conv(t) for t in robot.kinetic_extra])
        for i in range(n):
            for j in range(i, n):
                B[i][j] = A.add(B[i][j], A.diff(A.diff(T_extra, dq[i]), dq[j]))
                if robot.given_B is not None:
                    B[i][j] = A.add(B[i][j], conv(robot.given_B[i, j]))
                B[j][i] = B[i][j]
        if robot.given_B is not None and any(A.sub(conv(robot.given_B[i, j]), conv(robot.given_B[j, i]))
                                             for i in range(n) for j in range(i)):
            return None  # a non-symmetric given B: the general path keeps it as given
        T_all = A.scale(A.add(*[A.mul(A.mul(V[i], B[i][j]), V[j]) for i in range(n) for j in range(n)]), half)
        dB = [[[A.diff(B[i][j], qk) for qk in q] for j in range(n)] for i in range(n)]  # dB[i][j][k] = ∂b_ij/∂q_k
        if robot.given_c is not None:
            C = S = None
            c = [conv(x) for x in robot.given_c]
            skew = None
        else:
            C = [[[{} for _ in range(n)] for _ in range(n)] for _ in range(n)]
            for k in range(n):
                for i in range(n):
                    for j in range(i, n):  # C_k is symmetric: one object for (i, j) and (j, i)
                        C[k][i][j] = C[k][j][i] = A.scale(A.add(dB[i][k][j], dB[j][k][i], A.scale(dB[i][j][k], -1)),
                                                          half)
            S = [[A.dot(V, [C[k][i][j] for i in range(n)]) for j in range(n)] for k in range(n)]
            c = [A.dot(S[k], V) for k in range(n)]
            Bdot = [[A.dot([dB[i][j][k] for k in range(n)], V) for j in range(n)] for i in range(n)]
            skew = not any(A.sub(A.add(Bdot[i][j], Bdot[j][i]), A.scale(A.add(S[i][j], S[j][i]), 2))
                           for i in range(n) for j in range(n))
        U_extra = A.add(*[conv(u) for u in robot.potential_extra])
        U = None
        if robot.given_g is not None:
            g = [A.add(conv(x), A.diff(U_extra, qk)) for x, qk in zip(robot.given_g, q)]
        else:
            U = A.add(*[b[4] for b in bodies if b[4] is not None], U_extra,
                      conv(robot.given_U) if robot.given_U is not None else {})
            g = [A.diff(U, qk) for qk in q]
        Fv = mat(robot.friction) if robot.friction is not None else None
        acc = [A.symbol(a) for a in ddq]
        lhs = [A.add(A.dot(B[i], acc), c[i], g[i], A.dot(Fv[i], V) if Fv is not None else {}) for i in range(n)]
    except NotTrigPolynomial:
        return None
    memo: dict[int, tuple[Any, sp.Expr]] = {}  # id -> (the element, kept alive so that its id is not reused; form)

    def ex(a) -> sp.Expr:  # type: ignore[no-untyped-def]
        hit = memo.get(id(a))
        if hit is None or hit[0] is not a:
            hit = memo[id(a)] = (a, A.expr(a))
        return hit[1]

    def mx(M: Mat) -> sp.Matrix:
        return sp.Matrix([[ex(x) for x in row] for row in M])

    def terms(a) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
        """``a`` as solver.math.simplify.velocity_terms writes it: Σ_e a_e q̇^e, highest degree first."""
        parts = A.by_monomial(a, dq)
        order = sorted(parts, key=lambda e: (-sum(e), [-d for d in e]))
        out = [A.expr(parts[e]) * sp.Mul(*[v ** d for v, d in zip(dq, e)]) for e in order]
        return [t for t in out if t != 0]

    # per-body quantities are computed (‖v_c‖², T_i) and printed when a report, a check or --details first reads them
    energies = [BodyEnergy(body, Deferred(lambda P=P: sp.Matrix([ex(p) for p in P])),
                           Deferred(lambda vc=vc: sp.Matrix([ex(v) for v in vc])), Deferred(lambda e=e: ex(e()[0])),
                           Deferred(lambda body=body: body.omega), Deferred(lambda e=e: ex(e()[1])),
                           Deferred(lambda U=U: ex(U)) if U is not None else None,
                           Deferred(lambda vc=vc, e=e: ([terms(v) for v in vc], terms(e()[0]),
                                                        terms(A.scale(e()[1], 2)))))
                for body, P, vc, e, U in bodies]
    Bm = mx(B)
    C_out = [mx(Ck) for Ck in C] if C is not None else None
    dm = DynamicModel(energies, ex(T_extra), ex(T_all), Bm, C_out, sp.Matrix([ex(x) for x in c]),
                      mx(S) if S is not None else None, skew, ex(U_extra), ex(U) if U is not None else None,
                      sp.Matrix([ex(x) for x in g]), robot.friction, robot.input_map, sp.Matrix(robot.inputs),
                      sp.Matrix([ex(x) for x in lhs]))
    memo.clear()  # (the deferred per-body values keep ex alive: not the whole derivation through its memo)
    return dm
