"""Cartesian paths p(s) parametrized by arc length s ∈ [0, L], orientation by axis-angle, and the joint motion
that follows them through a robot's kinematics (ask kind ``trajectory``).

    line      p(s) = p_A + (s/L)(p_B − p_A),                 L = ‖p_B − p_A‖
    arc       p(s) = c + ρ (cos φ(s) u + sin φ(s) v),  φ(s) = φ_0 + sgn(α) s/ρ,  L = ρ|α|   (circle: α = 2π)
    rotation  ᴬR_B = ⁰R_Aᵀ ⁰R_B = Rot(r, θ):  θ = atan2(√((r32−r23)² + (r13−r31)² + (r21−r12)²), r11+r22+r33−1),
              r = (r32−r23, r13−r31, r21−r12)/(2 sin θ);   R(s) = ⁰R_A Rot(r, θ s/L)
    velocity  ṗ = p'(s) ṡ,  p̈ = p''(s) ṡ² + p'(s) s̈,  ᴬω = r θ ṡ/L,  ⁰ω = ⁰R_A ᴬω
    joints    f(q(t)) = p(s(t)) solved by damped Newton (tolerance IK_TOL on ‖f(q) − p‖), q̇ = J⁺ṗ,
              q̈ = J⁺(p̈ − J̇ q̇)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np
import sympy as sp

from solver.math.numeric import lambdify_np
from solver.math.simplify import simplified

IK_TOL = 1e-10
IK_ITER = 100


def skew(r: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])


def rot_axis_angle(r: sp.Matrix, theta: sp.Expr) -> sp.Matrix:
    """Rot(r, θ) = I cos θ + (1 − cos θ) r rᵀ + sin θ [r]×  (Rodrigues)."""
    return sp.eye(3) * sp.cos(theta) + (1 - sp.cos(theta)) * r * r.T + sp.sin(theta) * skew(r)


@dataclass
class AxisAngle:
    theta: sp.Expr
    axis: Optional[sp.Matrix]  # None when θ = 0 (any axis)
    case: str                  # regular | zero | pi


def axis_angle(R: sp.Matrix) -> AxisAngle:
    """The inverse axis-angle problem for a rotation matrix (exact), with θ ∈ [0, π]."""
    w = sp.Matrix([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s2 = sp.sqrt(simplified(sum(x ** 2 for x in w)))
    c2 = simplified(R.trace() - 1)
    theta = simplified(sp.atan2(s2, c2))
    if simplified(s2) != 0:
        return AxisAngle(theta, (w / (2 * sp.sin(theta))).applyfunc(simplified), "regular")
    if simplified(c2 - 2) == 0:
        return AxisAngle(sp.Integer(0), None, "zero")
    M = (R + sp.eye(3)) / 2  # = r rᵀ for θ = π
    k = max(range(3), key=lambda i: float(M[i, i]) if M[i, i].is_number else 0.0)
    r = (M[:, k] / sp.sqrt(M[k, k])).applyfunc(simplified)
    return AxisAngle(sp.pi, r, "pi")


@dataclass
class Path:
    """p(s) for s in [0, L], and optionally the orientation R(s) = R_A Rot(r, θ s/L)."""

    s: sp.Symbol
    kind: str
    p: sp.Matrix
    L: sp.Expr
    data: dict = field(default_factory=dict)
    R_A: Optional[sp.Matrix] = None
    R_B: Optional[sp.Matrix] = None
    R_AB: Optional[sp.Matrix] = None
    rot: Optional[AxisAngle] = None

    @property
    def dp(self) -> sp.Matrix:
        return self.p.diff(self.s)

    @property
    def ddp(self) -> sp.Matrix:
        return self.p.diff(self.s, 2)

    def R(self, s_val: sp.Expr) -> Optional[sp.Matrix]:
        if self.R_A is None or self.rot is None:
            return None
        if self.rot.axis is None:
            return self.R_A
        return (self.R_A * rot_axis_angle(self.rot.axis, self.rot.theta * s_val / self.L)).applyfunc(simplified)

    def omega_A(self, ds: sp.Expr) -> Optional[sp.Matrix]:
        """Angular velocity in frame A: r θ ṡ/L."""
        if self.rot is None:
            return None
        if self.rot.axis is None:
            return sp.zeros(3, 1)
        return (self.rot.axis * self.rot.theta * ds / self.L).applyfunc(simplified)


def line(s: sp.Symbol, pA: sp.Matrix, pB: sp.Matrix, simplify: bool = True) -> Path:
    """The segment from pA to pB, p(s) = pA + s/L (pB − pA), 0 ≤ s ≤ L. ``simplify=False`` (validation): L and
    p(s) as written, and only points that coincide as written are refused."""
    d = pB - pA
    if not simplify:
        if all(x == 0 for x in d):
            raise ValueError("the two points coincide (a path of length 0)")
        L = sp.sqrt(sum(x ** 2 for x in d))
        return Path(s, "line", pA + s / L * d, L, {"from": pA, "to": pB})
    L = sp.sqrt(simplified(sum(x ** 2 for x in d)))
    if simplified(L) == 0:
        raise ValueError("the two points coincide (a path of length 0)")
    return Path(s, "line", (pA + s / L * d).applyfunc(simplified), simplified(L), {"from": pA, "to": pB})


def arc(s: sp.Symbol, center: sp.Matrix, radius: sp.Expr, start: sp.Expr, angle: sp.Expr,
        axes: Optional[tuple[sp.Matrix, sp.Matrix]] = None) -> Path:
    """Arc of radius ρ about ``center`` from the angle φ_0 = ``start`` by ``angle`` α (signed), in the plane of
    the orthonormal ``axes`` (u, v) (default the x-y plane)."""
    dim = center.shape[0]
    if axes is None:
        u = sp.Matrix([1, 0] + [0] * (dim - 2))
        v = sp.Matrix([0, 1] + [0] * (dim - 2))
    else:
        u, v = axes
    sgn = sp.sign(angle) if angle.is_number else sp.Integer(1)
    phi = start + sgn * s / radius
    L = simplified(radius * sp.Abs(angle)) if angle.is_number else simplified(radius * angle)
    p = center + radius * (sp.cos(phi) * u + sp.sin(phi) * v)
    return Path(s, "arc", p, L, {"center": center, "radius": radius, "start": start, "angle": angle})


def with_orientation(path: Path, R_A: sp.Matrix, R_B: sp.Matrix) -> Path:
    path.R_A, path.R_B = R_A, R_B
    path.R_AB = (R_A.T * R_B).applyfunc(simplified)
    path.rot = axis_angle(path.R_AB)
    return path


def is_rotation(R: sp.Matrix) -> bool:
    """RᵀR = I and det R = 1 (exactly, or within 1e-9 for floats)."""
    E = (R.T * R - sp.eye(3)).applyfunc(simplified)
    d = simplified(R.det() - 1)
    vals = list(E) + [d]
    if all(x.is_number for x in vals):
        return all(abs(complex(sp.N(x))) < 1e-9 for x in vals)
    return all(x == 0 for x in vals)


# ------------------------------------------------------------------------------------------------ joints
@dataclass
class JointMotion:
    """Sampled joint motion following a path: times, q, q̇, q̈ (rows per sample) and the worst task error."""

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    error: float


def inverse_kinematics(f, J, p: np.ndarray, q0: np.ndarray, tol: float = IK_TOL) -> tuple[np.ndarray, float]:  # type: ignore[no-untyped-def]
    """q with ‖f(q) − p‖ <= tol by damped Newton from q0 (Levenberg-Marquardt steps, λ adapted)."""
    q = np.array(q0, dtype=float)
    lam = 1e-6
    err = np.linalg.norm(f(q) - p)
    for _ in range(IK_ITER):
        if err <= tol:
            break
        Jq = J(q)
        e = p - f(q)
        step = Jq.T @ np.linalg.solve(Jq @ Jq.T + lam * np.eye(Jq.shape[0]), e)
        qn = q + step
        en = np.linalg.norm(f(qn) - p)
        if en < err:
            q, err, lam = qn, en, max(lam / 10, 1e-12)
        else:
            lam *= 10
    return q, float(err)


def follow(task: sp.Matrix, q: list[sp.Symbol], dq: list[sp.Symbol], values: dict, ts: np.ndarray,
           pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, q_start: np.ndarray) -> JointMotion:
    """Joint motion with f(q(t)) = p(t) at the sample times (continuation from ``q_start``)."""
    task = task.subs(values)
    Jsym = task.jacobian(q)
    Jdot_dq = (Jsym * sp.Matrix(dq)).jacobian(q) * sp.Matrix(dq)
    f = lambdify_np([q], task)
    Jf = lambdify_np([q], Jsym)
    Jd = lambdify_np([q, dq], Jdot_dq)
    fv = lambda x: np.asarray(f(x), dtype=float).ravel()  # noqa: E731
    Jv = lambda x: np.asarray(Jf(x), dtype=float).reshape(len(task), len(q))  # noqa: E731
    cur = np.array(q_start, dtype=float)
    Q, DQ, DDQ, worst = [], [], [], 0.0
    for k in range(len(ts)):
        cur, err = inverse_kinematics(fv, Jv, pos[k], cur)
        worst = max(worst, err)
        Jp = np.linalg.pinv(Jv(cur))
        dqk = Jp @ vel[k]
        ddqk = Jp @ (acc[k] - np.asarray(Jd(cur, dqk), dtype=float).ravel())
        Q.append(cur.copy())
        DQ.append(dqk)
        DDQ.append(ddqk)
    return JointMotion(ts, np.array(Q), np.array(DQ), np.array(DDQ), worst)
