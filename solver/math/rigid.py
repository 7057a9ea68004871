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


def dh_kinematics(rows: list[tuple[sp.Expr, sp.Expr, sp.Expr, sp.Expr]], convention: str, q: list[sp.Symbol],
                  dq: list[sp.Symbol], coms: list[sp.Matrix], base: sp.Matrix | None = None
                  ) -> tuple[list[sp.Matrix], list[sp.Matrix], list[sp.Matrix]]:
    """(⁰Aᵢ = base·⁰A₁…, ⁱωᵢ, ⁰p_cᵢ = ⁰pᵢ + ⁰Rᵢ rᵢ) for i = 1..n, each entry tidied: :func:`dh_chain`,
    :func:`dh_omegas` and the centres of mass ``coms`` (rᵢ in frame i), computed in the canonical
    trigonometric-polynomial form and written once at the end (tidy's form is canonical: the same entries as
    tidying each product), or entry by entry with tidy when the data leave that form (floats, √3, ...)."""
    from solver.math.trigpoly import NotTrigPolynomial
    try:
        forms = dh_forms(rows, convention, q, dq, coms, base)
        n = len(rows)
        return [forms.frame(i) for i in range(n)], [forms.omega(i) for i in range(n)], \
            [forms.centre(i) for i in range(n)]
    except NotTrigPolynomial:
        pass
    frames = dh_chain(rows, convention)
    if base is not None:
        frames = [(base * A).applyfunc(tidy) for A in frames]
    omegas = dh_omegas(rows, convention, q, dq)
    return frames, omegas, [(A[:3, 3] + A[:3, :3] * r).applyfunc(tidy) for A, r in zip(frames, coms)]


class DHForms:
    """⁰Aᵢ, ⁱωᵢ and ⁰p_cᵢ (i = 0..n−1 here for joints 1..n) of a DH chain in the canonical form of one
    :class:`solver.math.trigpoly.TrigAlgebra` (``algebra``; ``frames``, ``omegas``, ``centres``: its elements),
    written as sympy matrices on demand, each once."""

    def __init__(self, algebra, frames: list, omegas: list, centres: list) -> None:  # type: ignore[no-untyped-def]
        self.algebra, self.frames, self.omegas, self.centres = algebra, frames, omegas, centres
        self._written: dict[tuple[str, int], sp.Matrix] = {}

    def _write(self, what: str, i: int) -> sp.Matrix:
        hit = self._written.get((what, i))
        if hit is None:
            A = self.algebra
            hit = self._written[(what, i)] = A.to_matrix(self.frames[i]) if what == "frame" else \
                A.to_matrix([[x] for x in (self.omegas if what == "omega" else self.centres)[i]])
        return hit

    def frame(self, i: int) -> sp.Matrix:
        return self._write("frame", i)

    def omega(self, i: int) -> sp.Matrix:
        return self._write("omega", i)

    def centre(self, i: int) -> sp.Matrix:
        return self._write("centre", i)


def angle_rate(theta: sp.Expr, q: list[sp.Symbol], dq: list[sp.Symbol]) -> sp.Expr:
    """θ̇ = Σ_k ∂θ/∂q_k q̇_k; for θ = Σ c_k q_k + constant (c_k rational: a DH joint angle) read from its terms
    without sympy's differentiation."""
    index = dict(zip(q, dq))
    terms = []
    for term, c in theta.as_coefficients_dict().items():
        if term in index and c.is_Rational:
            terms.append(c * index[term])
        elif term.free_symbols & index.keys():
            return sum((sp.diff(theta, qk) * dqk for qk, dqk in zip(q, dq) if qk in theta.free_symbols),
                       sp.Integer(0))
    return sp.Add(*terms)


def dh_forms(rows, convention, q, dq, coms, base, extra=()) -> DHForms:  # type: ignore[no-untyped-def]
    """:func:`dh_kinematics` in a :class:`solver.math.trigpoly.TrigAlgebra`, not written yet (NotTrigPolynomial
    when the data leave the algebra), whose generators include the symbols ``extra`` (those of the masses, inertias,
    ...: the dynamic model then computes in the same algebra). ⁱ⁻¹Aᵢ written out: standard [[cθ, −sθcα, sθsα,
    a cθ], [sθ, cθcα, −cθsα, a sθ], [0, sα, cα, d]], modified [[cθ, −sθ, 0, a], [sθcα, cθcα, −sα, −sα d],
    [sθsα, cθsα, cα, cα d]]."""
    from solver.math.trigpoly import TrigAlgebra
    if convention not in ("standard", "modified"):
        raise ValueError(f"unknown DH convention {convention!r}")
    exprs: list = [x for row in rows for x in row] + list(coms) + ([base] if base is not None else [])
    symbols = set(q) | set(dq) | set(extra)
    for e in exprs:
        symbols |= sp.sympify(e).free_symbols
    A = TrigAlgebra({x for _, alpha, _, theta in rows for x in (alpha.free_symbols | theta.free_symbols)}, symbols)
    conv, mul, neg = A.conv, A.mul, (lambda x: A.scale(x, -1))
    zero, one = A.zero, A.one()
    T = A.matrix(base) if base is not None else [[one if i == j else zero for j in range(4)] for i in range(4)]
    # homogeneous frames [[R, p], [0, 1]]: R ← R ⁱ⁻¹Rᵢ, p ← R ⁱ⁻¹pᵢ + p (a base with another last row: 4x4 products)
    homogeneous = all(not x for x in T[3][:3]) and T[3][3] == one
    bottom = [zero, zero, zero, one]
    w: list = [zero, zero, zero]
    frames, omegas, centres = [], [], []
    for (a, alpha, d, theta), r in zip(rows, coms):
        (ct, st), (ca, sa) = A.cos_sin(theta), A.cos_sin(alpha)
        a_, d_ = conv(a), conv(d)
        if convention == "standard":
            R = [[ct, neg(mul(st, ca)), mul(st, sa)], [st, mul(ct, ca), neg(mul(ct, sa))], [zero, sa, ca]]
            p = [mul(a_, ct), mul(a_, st), d_]
        else:
            R = [[ct, neg(st), zero], [mul(st, ca), mul(ct, ca), neg(sa)], [mul(st, sa), mul(ct, sa), ca]]
            p = [a_, neg(mul(sa, d_)), mul(ca, d_)]
        if homogeneous:
            rows3 = [row[:3] for row in T[:3]]
            T = [r + [A.add(A.dot(rows3[i], p), T[i][3])] for i, r in enumerate(A.matmul(rows3, R))] + [bottom]
        else:
            T = A.matmul(T, [R[i] + [p[i]] for i in range(3)] + [bottom])
        rate = conv(angle_rate(theta, q, dq))
        Rt = A.T(R)
        if convention == "standard":  # ⁱωᵢ = Rᵀ(ω + z θ̇), modified: Rᵀω + z θ̇
            w = [A.dot(row, [w[0], w[1], A.add(w[2], rate)]) for row in Rt]
        else:
            w = [A.dot(row, w) for row in Rt]
            w[2] = A.add(w[2], rate)
        rc = [conv(x) for x in r]
        centre = [A.add(T[i][3], A.dot(T[i][:3], rc)) for i in range(3)]
        frames.append(T)
        omegas.append(list(w))
        centres.append(centre)
    return DHForms(A, frames, omegas, centres)


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
