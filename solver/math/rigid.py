"""Rigid-body kinematics: DH transforms, rotations, angular velocities."""
from __future__ import annotations

import sympy as sp

from solver.math.simplify import tidy


def rot_x(a: sp.Expr) -> sp.Matrix:
    """Elementary rotation about x."""
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_z(a: sp.Expr) -> sp.Matrix:
    """Elementary rotation about z."""
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def homogeneous(R: sp.Matrix, p: sp.Matrix) -> sp.Matrix:
    """[[R, p], [0, 1]]."""
    return R.row_join(p).col_join(sp.Matrix([[0, 0, 0, 1]]))


def trans(x: sp.Expr, y: sp.Expr, z: sp.Expr) -> sp.Matrix:
    return homogeneous(sp.eye(3), sp.Matrix([x, y, z]))


def dh_transform(a: sp.Expr, alpha: sp.Expr, d: sp.Expr, theta: sp.Expr, convention: str = "standard") -> sp.Matrix:
    """ⁱ⁻¹Aᵢ. Standard (Denavit-Hartenberg): Rot_z(θ) Trans_z(d) Trans_x(a) Rot_x(α).
    Modified (Craig): Rot_x(α) Trans_x(a) Rot_z(θ) Trans_z(d), with a, α of the row the ones of axis i-1."""
    Rz = homogeneous(rot_z(theta), sp.zeros(3, 1))
    Rx = homogeneous(rot_x(alpha), sp.zeros(3, 1))
    if convention == "standard":
        return Rz * trans(0, 0, d) * trans(a, 0, 0) * Rx
    if convention == "modified":
        return Rx * trans(a, 0, 0) * Rz * trans(0, 0, d)
    raise ValueError(f"unknown DH convention {convention!r}")


def dh_chain(rows: list[tuple[sp.Expr, sp.Expr, sp.Expr, sp.Expr]], convention: str) -> list[sp.Matrix]:
    """⁰Aᵢ for i = 1..n, entries tidied (compact trig)."""
    T = sp.eye(4)
    out = []
    for a, alpha, d, theta in rows:
        T = (T * dh_transform(a, alpha, d, theta, convention)).applyfunc(tidy)
        out.append(T)
    return out


def vee(S: sp.Matrix) -> sp.Matrix:
    """ω from the skew-symmetric matrix S(ω)."""
    return sp.Matrix([S[2, 1], S[0, 2], S[1, 0]])


def omega_from_rotation(R: sp.Matrix, q: list[sp.Symbol], dq: list[sp.Symbol], frame: str = "link") -> sp.Matrix:
    """Angular velocity of a frame with orientation R(q): S(ω_link) = Rᵀ Ṙ, S(ω_base) = Ṙ Rᵀ (computed in the
    canonical trigonometric-polynomial form when R is a trigonometric polynomial)."""
    from solver.math.trigpoly import NotTrigPolynomial, TrigAlgebra
    try:
        A = TrigAlgebra.of([R], extra=list(q) + list(dq))
        Rt = A.matrix(R)
        acc: list = [{}, {}, {}]
        for qk, dqk in zip(q, dq):
            dR = [[A.diff(x, qk) for x in row] for row in Rt]
            if not any(x for row in dR for x in row):
                continue
            Sk = A.matmul(A.T(Rt), dR) if frame == "link" else A.matmul(dR, A.T(Rt))
            v = A.symbol(dqk)
            acc = [A.add(acc[i], A.mul(x, v)) for i, x in enumerate((Sk[2][1], Sk[0][2], Sk[1][0]))]
        return sp.Matrix([A.expr(x) for x in acc])
    except NotTrigPolynomial:
        pass
    w = sp.zeros(3, 1)
    for qk, dqk in zip(q, dq):
        dR = R.diff(qk)
        if dR == sp.zeros(3, 3):
            continue
        S = (R.T * dR) if frame == "link" else (dR * R.T)
        w += vee(S.applyfunc(tidy)) * dqk
    return w.applyfunc(tidy)


def dh_omegas(rows: list[tuple[sp.Expr, sp.Expr, sp.Expr, sp.Expr]], convention: str, q: list[sp.Symbol],
              dq: list[sp.Symbol]) -> list[sp.Matrix]:
    """Angular velocity of each DH link in its own frame, recursively (no derivative of the chain's rotations):
    standard ⁱωᵢ = ⁱ⁻¹Rᵢᵀ(ⁱ⁻¹ωᵢ₋₁ + z θ̇ᵢ), modified ⁱωᵢ = ⁱ⁻¹Rᵢᵀ ⁱ⁻¹ωᵢ₋₁ + z θ̇ᵢ, θ̇ᵢ = Σ_j ∂θᵢ/∂q_j q̇_j
    (the same vectors as Rᵀ Ṙ of the chain, the base's constant rotation aside)."""
    w = sp.zeros(3, 1)
    z = sp.Matrix([0, 0, 1])
    out = []
    for a, alpha, d, theta in rows:
        R = dh_transform(a, alpha, d, theta, convention)[:3, :3]
        rate = sum((sp.diff(theta, qk) * dqk for qk, dqk in zip(q, dq)), sp.Integer(0))
        w = R.T * (w + z * rate) if convention == "standard" else R.T * w + z * rate
        w = w.applyfunc(tidy)
        out.append(w)
    return out
