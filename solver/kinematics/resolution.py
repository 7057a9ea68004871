"""Redundancy resolution methods on numbers (pure math, level-agnostic), for the ``redundancy`` ask.

Every function works on one linear-algebra backend :class:`LA`: ``exact`` (sympy matrices of rationals: ranks and
pseudoinverses exact) or ``float`` (numpy, ranks from the singular values with an explicit tolerance: a singular
value σ counts as zero when σ ≤ tol · max(1, σ_max)). At velocity level the task vector is ṙ; at acceleration level
the same formulas apply to q̈ with ṙ replaced by r̈ − J̇q̇ (and q̇₀ by q̈₀).

    pseudoinverse     J^# = Jᵀ(JJᵀ)⁻¹ (full row rank), Moore-Penrose otherwise
    weighted          J_W^# = W⁻¹Jᵀ(JW⁻¹Jᵀ)⁻¹
    damped LS         J_DLS = Jᵀ(JJᵀ + μ²I)⁻¹        minimizes ½‖Jq̇ − ṙ‖² + ½μ²‖q̇‖²
    null space        q̇ = J^#ṙ + (I − J^#J)q̇₀
    task priority     q̇_1 = J_1^#ṙ_1, P_1 = I − J_1^#J_1,
                      q̇_k = q̇_{k−1} + (J_kP_{k−1})^#(ṙ_k − J_kq̇_{k−1}),  P_k = P_{k−1} − (J_kP_{k−1})^#(J_kP_{k−1})
    extended          J_E = (J_1; …; J_N), q̇ = J_E^#ṙ_E (J_E⁻¹ when square and nonsingular)
    SNS               Flacco, De Luca, Khatib (2012): saturate the most critical joint at its bound, drop its column,
                      re-solve with the remaining ones; scale the task (s < 1) only when no feasible solution is left.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

DEFAULT_TOL = 1e-9


class LA:
    """Linear algebra on one backend: ``exact`` (sympy rationals) or ``float`` (numpy, 2-D arrays)."""

    def __init__(self, exact: bool, tol: float = DEFAULT_TOL) -> None:
        self.exact, self.tol = exact, tol

    # conversion
    def mat(self, M: Any) -> Any:
        if self.exact:
            return sp.Matrix(M)
        if isinstance(M, sp.MatrixBase):
            return np.array(M.evalf(30).tolist(), dtype=float).reshape(M.shape)
        return np.atleast_2d(np.asarray(M, dtype=float))

    def sym(self, A: Any) -> sp.Matrix:
        """The value as a sympy matrix (exact, or Floats with tiny entries set to 0)."""
        if self.exact:
            return sp.Matrix(A)
        a = np.atleast_2d(A)
        scale = max(1.0, float(np.max(np.abs(a)))) if a.size else 1.0
        return sp.Matrix(a.shape[0], a.shape[1], lambda i, j: sp.Integer(0) if abs(a[i, j]) < 1e-12 * scale
                         else sp.Float(float(a[i, j]), 15))

    def scalar(self, x: Any) -> sp.Expr:
        if self.exact:
            return sp.nsimplify(x) if not isinstance(x, sp.Basic) else x
        return sp.Float(float(x), 15)

    def eye(self, n: int) -> Any:
        return sp.eye(n) if self.exact else np.eye(n)

    def zeros(self, r: int, c: int) -> Any:
        return sp.zeros(r, c) if self.exact else np.zeros((r, c))

    def shape(self, A: Any) -> tuple[int, int]:
        return tuple(A.shape)  # type: ignore[return-value]

    def vstack(self, mats: Sequence[Any]) -> Any:
        return sp.Matrix.vstack(*mats) if self.exact else np.vstack(mats)

    def diag(self, d: Sequence[Any]) -> Any:
        return sp.diag(*d) if self.exact else np.diag(np.asarray(d, dtype=float))

    def f(self, x: Any) -> float:
        return float(x)

    # decompositions
    def svals(self, A: Any) -> np.ndarray:
        a = np.array(sp.Matrix(A).evalf(30).tolist(), dtype=float) if self.exact else np.atleast_2d(A)
        if a.size == 0:
            return np.zeros(0)
        return np.linalg.svd(a, compute_uv=False)

    def rank(self, A: Any) -> int:
        if self.exact:
            return sp.Matrix(A).rank() if sp.Matrix(A).shape[0] * sp.Matrix(A).shape[1] else 0
        s = self.svals(A)
        return int(np.sum(s > self.tol * max(1.0, s[0]))) if s.size else 0

    def inv(self, A: Any) -> Any:
        return A.inv() if self.exact else np.linalg.inv(A)

    def pinv(self, A: Any) -> Any:
        """Moore-Penrose pseudoinverse; the explicit formula at full row (column) rank."""
        r, c = self.shape(A)
        if self.exact:
            rk = self.rank(A)
            if rk == 0:
                return sp.zeros(c, r)
            if rk == r:
                return A.T * (A * A.T).inv()
            if rk == c:
                return (A.T * A).inv() * A.T
            return A.pinv()
        u, s, vt = np.linalg.svd(A, full_matrices=False)
        keep = s > self.tol * max(1.0, s[0] if s.size else 0.0)
        return (vt[keep].T / s[keep]) @ u[:, keep].T

    def norm(self, v: Any) -> sp.Expr:
        if self.exact:
            return sp.sqrt(sum(x ** 2 for x in v))
        x = float(np.linalg.norm(v))
        return sp.Integer(0) if x < 1e-12 else sp.Float(x, 15)


# ------------------------------------------------------------------------------------------------ single task
def weighted_pinv(la: LA, J: Any, W: Any | None = None) -> Any:
    """J_W^# = W⁻¹Jᵀ(JW⁻¹Jᵀ)⁻¹ at full row rank; R⁻¹(JR⁻¹)^+ (W = RᵀR) otherwise; J^+ when W is None."""
    if W is None:
        return la.pinv(J)
    m = la.shape(J)[0]
    Wi = la.inv(W)
    if la.rank(J) == m:
        return Wi @ J.T @ la.inv(J @ Wi @ J.T)
    if la.exact:
        R = W.cholesky(hermitian=False).T
    else:
        R = np.linalg.cholesky(W).T
    Ri = la.inv(R)
    return Ri @ la.pinv(J @ Ri)


def dls(la: LA, J: Any, mu: Any) -> Any:
    """J_DLS = Jᵀ(JJᵀ + μ²I)⁻¹ (μ ≠ 0), the minimizer of ½‖Jq̇ − ṙ‖² + ½μ²‖q̇‖² applied to ṙ; μ = 0: J^#."""
    m = la.shape(J)[0]
    if mu == 0:
        return la.pinv(J)
    return J.T @ la.inv(J @ J.T + mu ** 2 * la.eye(m))


def variable_damping(la: LA, J: Any, epsilon: float, mu_max: float) -> float:
    """The damping chosen from the smallest singular value σ of J: μ² = μ_max²(1 − (σ/ε)²) when σ < ε, 0 otherwise
    (DLS only near a singularity, the pseudoinverse elsewhere)."""
    s = la.svals(J)
    m = la.shape(J)[0]
    smin = float(s[m - 1]) if s.size >= m else 0.0
    return float(np.sqrt(mu_max ** 2 * (1 - (smin / epsilon) ** 2))) if smin < epsilon else 0.0


def projector(la: LA, J: Any, Jp: Any) -> Any:
    """I − J^#J, the orthogonal projector in the null space of J (for J^# the pseudoinverse)."""
    return la.eye(la.shape(J)[1]) - Jp @ J


# ------------------------------------------------------------------------------------------------ task priority
@dataclass
class PriorityLevel:
    k: int                  # 1-based priority
    P_prev: Any             # P_{k-1}
    JP: Any                 # J_k P_{k-1}
    JP_pinv: Any
    rank_J: int
    rank_JP: int
    algorithmic: bool       # rank(J_k P_{k-1}) < rank(J_k): algorithmic singularity
    smin_JP: float          # smallest of the min(m_k, n) singular values
    correction: Any         # ṙ_k − J_k q̇_{k-1}
    qdot: Any               # q̇_k


def task_priority(la: LA, Js: Sequence[Any], rs: Sequence[Any], q0: Any | None = None) -> tuple[Any, list]:
    """Recursive task-priority solution (Siciliano-Slotine); returns (q̇, levels)."""
    n = la.shape(Js[0])[1]
    P = la.eye(n)
    qd = la.zeros(n, 1)
    levels: list[PriorityLevel] = []
    for k, (J, r) in enumerate(zip(Js, rs), start=1):
        JP = J @ P
        JPp = la.pinv(JP)
        corr = r - J @ qd
        qd = qd + JPp @ corr
        s = la.svals(JP)
        mk = la.shape(J)[0]
        smin = float(s[min(mk, n) - 1]) if s.size >= min(mk, n) else 0.0
        rJ, rJP = la.rank(J), la.rank(JP)
        levels.append(PriorityLevel(k, P, JP, JPp, rJ, rJP, rJP < rJ, smin, corr, qd))
        P = P - JPp @ JP
    if q0 is not None:
        qd = qd + P @ q0
    return qd, levels


def extended(la: LA, Js: Sequence[Any], rs: Sequence[Any]) -> tuple[Any, Any, Any, int]:
    """Extended (stacked) Jacobian J_E = (J_1; …; J_N): q̇ = J_E^#ṙ_E. Returns (q̇, J_E, J_E^#, rank J_E)."""
    JE, rE = la.vstack(list(Js)), la.vstack(list(rs))
    rk = la.rank(JE)
    m, n = la.shape(JE)
    JEp = la.inv(JE) if (m == n and rk == n) else la.pinv(JE)
    return JEp @ rE, JE, JEp, rk


# ------------------------------------------------------------------------------------------------ SNS
@dataclass
class SNSStep:
    it: int                  # 1-based iteration
    saturated: list[int]     # joints (0-based) saturated before this iteration
    qdot: Any                # candidate solution of this iteration
    violating: list[int]     # joints out of bounds
    a: Any | None = None     # (JW)^# ẋ
    b: Any | None = None     # the rest of the solution
    scale: Any | None = None  # largest task scaling factor feasible with this W (the task scaling)
    critical: int | None = None  # the most critical joint, saturated next
    bound: Any | None = None     # its saturation value
    rank_JW: int | None = None   # rank after removing its column


@dataclass
class SNSResult:
    qdot: Any
    s: Any                   # task scaling factor applied (1: the task is executed in full)
    saturated: list[int]
    steps: list[SNSStep] = field(default_factory=list)
    feasible: bool = True    # the (unscaled) task is executed within the bounds


def _scaling(la: LA, a: Any, b: Any, lo: Sequence[Any], hi: Sequence[Any], active: Sequence[bool]) \
        -> tuple[Any, int | None]:
    """Largest s ∈ [0, 1] with lo ≤ a s + b ≤ hi on the active joints, and the joint that limits it."""
    eps = 0 if la.exact else 1e-12
    smax: Any = None
    smin: Any = None
    crit = None
    for i in range(len(lo)):
        if not active[i] or abs(a[i, 0]) <= eps:
            continue
        s1, s2 = (lo[i] - b[i, 0]) / a[i, 0], (hi[i] - b[i, 0]) / a[i, 0]
        if s1 > s2:
            s1, s2 = s2, s1
        if smax is None or s2 < smax:
            smax, crit = s2, i
        if smin is None or s1 > smin:
            smin = s1
    if smax is None:
        return (sp.Integer(1) if la.exact else 1.0), None
    if (smin is not None and smin > smax) or smax < 0 or (smin is not None and smin > 1):
        return (sp.Integer(0) if la.exact else 0.0), crit
    return smax, crit


def sns(la: LA, J: Any, x: Any, lo: Sequence[Any], hi: Sequence[Any], max_iter: int | None = None) -> SNSResult:
    """Saturation in the Null Space: the minimum-norm solution of J v = s x with lo ≤ v ≤ hi, s = 1 when
    feasible, else the largest s found; every iteration recorded."""
    m, n = la.shape(J)
    eps = 0 if la.exact else 1e-9
    Wd = [1] * n
    vN = la.zeros(n, 1)
    one = sp.Integer(1) if la.exact else 1.0
    s, s_star = one, (sp.Integer(0) if la.exact else 0.0)
    best = (list(Wd), vN, s_star)
    steps: list[SNSStep] = []
    r0 = la.rank(J)  # a joint can be removed while J_W keeps this rank (m at full row rank)
    for it in range(1, (max_iter or n + 1) + 1):
        JW = J @ la.diag(Wd)
        JWp = la.pinv(JW)
        v = vN + JWp @ (s * x - J @ vN)
        viol = [i for i in range(n) if v[i, 0] < lo[i] - eps or v[i, 0] > hi[i] + eps]
        st = SNSStep(it, [i for i in range(n) if Wd[i] == 0], v, viol)
        steps.append(st)
        if not viol:
            return SNSResult(v, s, st.saturated, steps, feasible=(s == one))
        a = JWp @ x
        b = v - s * a
        st.a, st.b = a, b
        sc, crit = _scaling(la, a, b, lo, hi, [w == 1 for w in Wd])
        st.scale = sc
        if sc > best[2]:
            best = (list(Wd), vN, sc)
        j = crit if crit is not None else max(viol, key=lambda i: max(v[i, 0] - hi[i], lo[i] - v[i, 0]))
        st.critical = j
        st.bound = hi[j] if v[j, 0] > hi[j] else lo[j]
        Wd[j] = 0
        vN = vN.copy() if not la.exact else sp.Matrix(vN)
        vN[j, 0] = st.bound
        st.rank_JW = la.rank(J @ la.diag(Wd))
        if st.rank_JW < r0:
            Wd, vN, s = best[0], best[1], min(best[2], one)
            JWp = la.pinv(J @ la.diag(Wd))
            v = vN + JWp @ (s * x - J @ vN)
            fin = SNSStep(it + 1, [i for i in range(n) if Wd[i] == 0], v, [])
            fin.scale = s
            steps.append(fin)
            return SNSResult(v, s, fin.saturated, steps, feasible=False)
    return SNSResult(v, s, [i for i in range(n) if Wd[i] == 0], steps, feasible=False)


def ps_scaling(la: LA, v: Any, lo: Sequence[Any], hi: Sequence[Any]) -> Any:
    """The factor k ≥ 1 dividing a solution v (and the task) to bring it within the bounds (1 when it is)."""
    k: Any = sp.Integer(1) if la.exact else 1.0
    for i in range(la.shape(v)[0]):
        x = v[i, 0]
        if x > 0 and hi[i] > 0:
            k = max(k, x / hi[i])
        elif x < 0 and lo[i] < 0:
            k = max(k, x / lo[i])
    return k


# ------------------------------------------------------------------------------------------------ largest scaling
@dataclass
class MaxScaling:
    lam: Any                          # the largest feasible λ ≥ 0 (None: no feasible λ; math.inf: unbounded)
    intervals: list[tuple[Any, Any] | None]  # per joint, the λ ≥ 0 it allows ([low, up], None if none)
    upper: list[Any]                  # per joint, its largest allowed λ (-inf if none, inf if unbounded)
    low: Any = 0                      # the smallest feasible λ (when lam is not None)


def max_scaling(la: LA, a: Any, b: Any, lo: Sequence[Any], hi: Sequence[Any]) -> MaxScaling:
    """max λ s.t. λ ≥ 0 and lo ≤ aλ + b ≤ hi (componentwise): each joint allows an interval of λ; λ* is the
    smallest upper end when the largest lower end does not exceed it, else the set is empty."""
    eps = 0 if la.exact else 1e-12
    inf = sp.oo if la.exact else float("inf")
    zero = sp.Integer(0) if la.exact else 0.0
    ivs: list[tuple[Any, Any] | None] = []
    for i in range(len(lo)):
        ai, bi = a[i, 0], b[i, 0]
        if abs(ai) <= eps:
            ivs.append((zero, inf) if lo[i] - eps <= bi <= hi[i] + eps else None)
            continue
        s1, s2 = (lo[i] - bi) / ai, (hi[i] - bi) / ai
        if s1 > s2:
            s1, s2 = s2, s1
        low = max(zero, s1)
        ivs.append((low, s2) if s2 >= low - eps else None)
    upper = [iv[1] if iv is not None else -inf for iv in ivs]
    if any(iv is None for iv in ivs):
        return MaxScaling(None, ivs, upper)
    lam = min(upper)
    low = max(iv[0] for iv in ivs if iv is not None)
    return MaxScaling(lam if low <= lam + eps else None, ivs, upper, low)


# ------------------------------------------------------------------------------------------------ reduced gradient
def best_partition(la: LA, J: Any) -> list[int]:
    """The m columns of J (0-based, lexicographically first among the best conditioned) forming J_a."""
    from itertools import combinations
    m, n = la.shape(J)
    best, best_s = None, -1.0
    for cols in combinations(range(n), m):
        s = la.svals(J[:, list(cols)])
        smin = float(s[-1]) if s.size else 0.0
        if smin > best_s + 1e-12:
            best, best_s = list(cols), smin
    return best or list(range(m))


def reduced_gradient(la: LA, J: Any, x: Any, grad: Any, a: Sequence[int], step: Any = 1) -> tuple[Any, Any]:
    """Reduced gradient: q = (q_a, q_b) with J_a (m×m) nonsingular; ∇'H = ∇_b H − (J_a⁻¹J_b)ᵀ∇_a H (the gradient of H
    along the task-preserving motions parametrized by q_b), q̇_b = step·∇'H, q̇_a = J_a⁻¹(x − J_b q̇_b).
    Returns (q̇, ∇'H)."""
    n = la.shape(J)[1]
    b = [j for j in range(n) if j not in a]
    Ja, Jb = J[:, list(a)], J[:, b]
    Jai = la.inv(Ja)
    ga = grad[list(a), :] if la.exact else grad[list(a)]
    gb = grad[b, :] if la.exact else grad[b]
    gr = gb - (Jai @ Jb).T @ ga
    vb = step * gr
    va = Jai @ (x - Jb @ vb)
    v = la.zeros(n, 1)
    for k, j in enumerate(a):
        v[j, 0] = va[k, 0]
    for k, j in enumerate(b):
        v[j, 0] = vb[k, 0]
    return v, gr
