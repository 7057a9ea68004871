"""Kinematic quantities of a serial robot as pure functions (sympy in, sympy out): the joint axes and geometric
Jacobian from DH frames, analytic Jacobians and their time derivative, determinants and minors, the configurations
where a Jacobian loses rank, null and range space bases, manipulability, and the planar skeleton of a robot (the
points a sketch joins).

Conventions. Joint i of a standard DH chain moves about/along z_{i-1} through o_{i-1} (frame i-1); of a modified
(Craig) chain, about/along z_i through o_i. The geometric Jacobian of a point p_e is

    J = [J_L; J_A],  column i:  revolute  [z × (p_e - o); z],   prismatic  [z; 0],

in the base frame; expressed in frame k it is diag(ᵏR₀, ᵏR₀) J. Its determinant (square J) does not depend on the
frame nor on the reference point (moving the point multiplies J by [[I, -S(r)], [0, I]], of determinant 1).
"""
from __future__ import annotations

import itertools
import random
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Sequence

import numpy as np
import sympy as sp

from solver.math.simplify import tidy
from solver.math.trigsolve import Family, Solver, check_families, trig_factors

if TYPE_CHECKING:
    from solver.spec.robot import Robot

MAX_MINORS = 10      # m×m minors of a non-square Jacobian computed symbolically
MAX_DET_OPS = 1500   # determinants (or sums of minors) larger than this are not solved for singularities


# ------------------------------------------------------------------------------------------------ frames
def hinv(A: sp.Matrix) -> sp.Matrix:
    """Inverse of a homogeneous transform: [Rᵀ, -Rᵀ p]."""
    R, p = A[:3, :3], A[:3, 3]
    return (R.T.row_join(-R.T * p)).col_join(sp.Matrix([[0, 0, 0, 1]]))


def relative(frames: Sequence[sp.Matrix], k: int, m: int) -> sp.Matrix:
    """ᵏA_m = (⁰A_k)⁻¹ ⁰A_m, tidied."""
    if k == m:
        return sp.eye(4)
    return (hinv(frames[k]) * frames[m]).applyfunc(tidy)


def joint_axes(frames: Sequence[sp.Matrix], convention: str, n: int) -> list[tuple[sp.Matrix, sp.Matrix]]:
    """(z, o) of each joint axis in the base frame."""
    idx = [i - 1 if convention != "modified" else i for i in range(1, n + 1)]
    return [(frames[j][:3, 2], frames[j][:3, 3]) for j in idx]


def axis_frames(convention: str, n: int) -> list[int]:
    """Index of the frame whose z axis is joint i's axis (i = 1..n)."""
    return [i - 1 if convention != "modified" else i for i in range(1, n + 1)]


def geometric_jacobian(frames: Sequence[sp.Matrix], joints: Sequence[str], convention: str,
                       point: sp.Matrix | None = None, express: int | None = None) -> sp.Matrix:
    """6×n geometric Jacobian of the point ``point`` (base coordinates; default the origin of the last frame),
    expressed in the base frame or in frame ``express``. Computed with the transforms relative to that frame
    (shorter expressions than rotating the base-frame Jacobian)."""
    n = len(joints)
    k = 0 if express is None else express
    base_to_k = hinv(frames[k]).applyfunc(tidy) if k else sp.eye(4)
    if point is None:
        pk = relative(frames, k, n)[:3, 3]
    else:
        pk = (base_to_k * point.col_join(sp.Matrix([1])))[:3, 0].applyfunc(tidy)
    cols = []
    for i, j in enumerate(axis_frames(convention, n)):
        A = relative(frames, k, j)
        z, o = A[:3, 2], A[:3, 3]
        if joints[i] == "R":
            lin = z.cross(pk - o).applyfunc(tidy)
            cols.append(lin.col_join(z))
        else:
            cols.append(z.col_join(sp.zeros(3, 1)))
    return sp.Matrix.hstack(*cols).applyfunc(tidy)


def analytic_jacobian(r: sp.Matrix, wrt: Sequence[sp.Symbol]) -> sp.Matrix:
    """∂r/∂x, entries tidied."""
    return r.jacobian(list(wrt)).applyfunc(lambda e: sp.factor_terms(tidy(e)))


def jacobian_dot(J: sp.Matrix, q: Sequence[sp.Symbol], dq: Sequence[sp.Symbol]) -> sp.Matrix:
    """J̇ = Σ_k ∂J/∂q_k q̇_k (entry by entry: Matrix.diff builds the same entries through sympy's array
    derivatives, at several times the cost)."""
    out = sp.zeros(*J.shape)
    for qk, dqk in zip(q, dq):
        out += J.applyfunc(lambda e: e.diff(qk)) * dqk
    return out.applyfunc(lambda e: sp.factor_terms(tidy(e)))


def planar_angle(R: sp.Matrix) -> sp.Expr | None:
    """φ with R = Rot_z(φ) (a planar orientation), or None."""
    if tidy(R[2, 2] - 1) != 0:
        return None
    c, s = tidy(R[0, 0]), tidy(R[1, 0])
    if isinstance(c, sp.cos) and isinstance(s, sp.sin) and sp.expand(c.args[0] - s.args[0]) == 0:
        return sp.expand(c.args[0])
    if c == 1 and s == 0:
        return sp.Integer(0)
    return sp.atan2(s, c)


# ------------------------------------------------------------------------------------------------ determinants
def _blocks(M: sp.Matrix) -> tuple[list[int], list[int]] | None:
    """Rows R and columns C (|R| = |C| < n) with M[R, not C] = 0: M is block triangular after permutation."""
    n = M.shape[0]
    nz = [{j for j in range(n) if M[i, j] != 0} for i in range(n)]
    for size in range(1, n):
        for rows in itertools.combinations(range(n), size):
            cols = set().union(*[nz[i] for i in rows])
            if len(cols) == size:
                return list(rows), sorted(cols)
    return None


def _signature(p: list[int]) -> int:
    """Sign of a permutation (number of inversions)."""
    inv = sum(1 for i in range(len(p)) for j in range(i + 1, len(p)) if p[i] > p[j])
    return -1 if inv % 2 else 1


def det(M: sp.Matrix) -> sp.Expr:
    """det M, exploiting block-triangular structure (det = det(A) det(D)) and zeros; entries and result tidied."""
    n = M.shape[0]
    if n == 0:
        return sp.Integer(1)
    if n == 1:
        return tidy(M[0, 0])
    blk = _blocks(M)
    if blk is not None:
        rows, cols = blk
        orows = [i for i in range(n) if i not in rows]
        ocols = [j for j in range(n) if j not in cols]
        perm = _signature(rows + orows) * _signature(cols + ocols)
        return tidy(perm * det(M.extract(rows, cols)) * det(M.extract(orows, ocols)))
    if n == 2:
        return tidy(M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0])
    if n == 3:  # the rule of Sarrus, unexpanded: tidy's canonical form does the algebra
        a = M
        return tidy(a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]) - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
                    + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))
    # Laplace expansion along the sparsest row or column
    zr = [(sum(1 for j in range(n) if M[i, j] == 0), ("r", i)) for i in range(n)]
    zc = [(sum(1 for i in range(n) if M[i, j] == 0), ("c", j)) for j in range(n)]
    _, (kind, k) = max(zr + zc)
    total = sp.Integer(0)
    for t in range(n):
        i, j = (k, t) if kind == "r" else (t, k)
        if M[i, j] == 0:
            continue
        minor = M.copy()
        minor.row_del(i)
        minor.col_del(j)
        total += (-1) ** (i + j) * M[i, j] * det(minor)
    return tidy(total)


def geometric_det(frames: Sequence[sp.Matrix], joints: Sequence[str], convention: str) -> tuple[sp.Expr, int, int]:
    """det of the square geometric Jacobian, taken in the frame k and at the reference point o_j (both near the
    middle of the chain) where it has the most zero entries: the determinant does not depend on them, and a
    zero block (a spherical wrist seen from its centre) splits it into a product. Returns (det, k, j)."""
    n = len(joints)
    mid = n // 2
    best = None
    for k in sorted({max(0, mid - 1), mid, min(n, mid + 1)}):
        for j in range(n + 1):
            Jk = geometric_jacobian(frames, joints, convention, frames[j][:3, 3], k)
            key = (-sum(1 for x in Jk if x == 0), sp.count_ops(Jk))
            if best is None or key < best[0]:
                best = (key, Jk, k, j)
    return det(best[1]), best[2], best[3]


def minors(J: sp.Matrix) -> dict[tuple[int, ...], sp.Expr]:
    """The maximal minors of a non-square J: {kept columns (or rows), 1-based: det}."""
    m, n = J.shape
    out = {}
    if m < n:
        for cols in itertools.combinations(range(n), m):
            out[tuple(c + 1 for c in cols)] = det(J.extract(list(range(m)), list(cols)))
    else:
        for rows in itertools.combinations(range(m), n):
            out[tuple(r + 1 for r in rows)] = det(J.extract(list(rows), list(range(n))))
    return out


def n_minors(m: int, n: int) -> int:
    from math import comb
    return comb(max(m, n), min(m, n))


# ------------------------------------------------------------------------------------------------ singularities
@dataclass
class Singular:
    """The configurations where J loses rank: ``factors`` (each vanishing factor of det J, or of the gcd of the
    minors), the ``systems`` of reduced minors, and the ``families`` of solutions (values of q, free coordinates
    mapped to themselves); ``complete`` when every condition was solved in closed form."""

    det: sp.Expr | None
    constant: sp.Expr
    factors: list[sp.Expr]
    systems: list[list[sp.Expr]] = field(default_factory=list)
    families: list[Family] = field(default_factory=list)
    complete: bool = True
    multiplicity: list[int] = field(default_factory=list)

    @property
    def product(self) -> sp.Expr | None:
        """det J as constant · Π factors (square J), for display."""
        if self.det is None:
            return None
        return factored(self.constant, list(zip(self.factors, self.multiplicity or [1] * len(self.factors))))


def factored(const: sp.Expr, facs: list[tuple[sp.Expr, int]]) -> sp.Expr:
    """const · Π f^k kept as a product (not expanded)."""
    parts = [f**k for f, k in facs]
    if const != 1 or not parts:
        parts = [const] + parts
    return sp.Mul(*parts, evaluate=False) if len(parts) > 1 else parts[0]


def _param_point(rng: random.Random, syms: Sequence[sp.Symbol], values: dict) -> dict[sp.Symbol, float]:
    pt = {}
    for s in syms:
        if s in values and values[s].is_number:
            pt[s] = float(values[s])
        elif s.is_positive or s.is_nonnegative:
            pt[s] = rng.uniform(0.3, 2.5)
        elif s.is_negative:
            pt[s] = -rng.uniform(0.3, 2.5)
        else:
            pt[s] = rng.uniform(-2.5, 2.5)
    return pt


def _dependent_minors(sysm: list[sp.Expr], q: Sequence[sp.Symbol], prismatic: list[sp.Symbol],
                      sampler) -> list[Family] | None:  # type: ignore[no-untyped-def]
    """The common zeros of minors that are not independent (3R with absolute angles: sin(q1 − q2) = sin(q1 − q3)
    = 0 implies sin(q2 − q3) = 0, three equations with two degrees of freedom, which the elimination cannot take
    as a square system): the smallest subset of the minors solved in closed form whose every family zeroes all
    of them (checked numerically) gives the set. None when no subset does (bounded: at most 8 minors)."""
    if len(sysm) > 8:
        return None
    unknowns = set().union(*[e.free_symbols for e in sysm]) & set(q)
    for k in range(1, len(sysm)):
        for sub in itertools.combinations(sysm, k):
            if set().union(*[e.free_symbols for e in sub]) & set(q) != unknowns:
                continue  # an unknown left free by the subset would have to zero the other minors identically
            fams = Solver(q, prismatic).solve(list(sub))
            if not fams or any(f.pending for f in fams):
                continue
            if all(check_families([f], sysm, q, sampler) for f in fams):
                return fams
    return None


def _atan2_angle(y: sp.Expr, x: sp.Expr) -> sp.Expr:
    """atan2(±sin a, ±cos a) (a factor √(sin² a + cos² a) read as 1) as a, a + π: equal modulo
    2π, which is how configurations are compared."""
    rep = {sp.sin(a)**2 + sp.cos(a)**2: 1 for f in y.atoms(sp.sin) for a in f.args}
    y2, x2 = y.subs(rep), x.subs(rep)
    for sign, shift in ((1, 0), (-1, sp.pi)):
        if isinstance(sign * y2, sp.sin) and isinstance(sign * x2, sp.cos) and (sign * y2).args == (sign * x2).args:
            return (sign * y2).args[0] + shift
    return sp.atan2(y, x)


def singular_configurations(J: sp.Matrix, q: Sequence[sp.Symbol], joints: Sequence[str],
                            values: dict | None = None, dmat: sp.Expr | None = None,
                            mins: dict | None = None) -> Singular:
    """Closed-form singular set of J(q): det J = 0 (square; factored, one family per factor) or all maximal minors
    zero (non-square: the common factors, then the system of the remaining minors)."""
    values = values or {}
    prismatic = [x for x, j in zip(q, joints) if j == "P"]
    m, n = J.shape
    if m == n:
        d = dmat if dmat is not None else det(J)
        if d == 0:
            return Singular(d, sp.Integer(0), [], [], [], True)
        const, facs = trig_factors(d)
        const = const * sp.Mul(*[f**k for f, k in facs if not f.free_symbols & set(q)])
        mult = [k for f, k in facs if f.free_symbols & set(q)]
        factors = [f for f, _ in facs if f.free_symbols & set(q)]
        systems = [[f] for f in factors]
        checks = [d]
    else:
        mins = mins if mins is not None else minors(J)
        facs_each = [trig_factors(v) for v in mins.values()]
        nonzero = [fe for fe, v in zip(facs_each, mins.values()) if v != 0]
        if not nonzero:
            return Singular(None, sp.Integer(0), [], [], [], True)
        common = [f for f, _ in nonzero[0][1] if f.free_symbols & set(q)
                  and all(any(sp.expand(f - g) == 0 or sp.expand(f + g) == 0 for g, _ in fe[1]) for fe in nonzero)]
        const = sp.Integer(1)
        factors = list(common)
        reduced = []
        for fe in nonzero:
            rest = [g for g, k in fe[1] if not any(sp.expand(g - f) == 0 or sp.expand(g + f) == 0 for f in common)
                    for _ in range(k)]
            rest = [g for g in rest if g.free_symbols & set(q)]
            reduced.append(sp.Mul(*rest) if rest else sp.Integer(1))
        systems = [[f] for f in common]
        if all(r != 1 for r in reduced):
            systems.append(reduced)
        checks = list(mins.values())
        d = None
    families: list[Family] = []
    complete = True
    params = sorted(set().union(*[c.free_symbols for c in checks]) - set(q), key=lambda s: s.name)

    def sampler(rng: random.Random) -> dict:
        return _param_point(rng, params, values)

    for sysm in systems:
        fams = Solver(q, prismatic).solve(sysm)
        if any(f.pending for f in fams) and len(sysm) > 1:
            fams = _dependent_minors(sysm, q, prismatic, sampler) or fams
        complete = complete and all(not f.pending for f in fams)
        families += fams
    for fam in families:  # atan2(sin q2, cos q2) -> q2 (configurations are angles modulo 2π)
        fam.values = {x: v.replace(sp.atan2, _atan2_angle) if v.has(sp.atan2) else v for x, v in fam.values.items()}

    closed = [f for f in families if not f.pending]
    kept = check_families(closed, [c for c in checks if c != 0][:8], q, sampler)
    kept += [f for f in families if f.pending]
    return Singular(d, const, factors, systems, kept, complete, mult if m == n else [])


# ------------------------------------------------------------------------------------------------ at a configuration
_TRANSCENDENTAL = (sp.sin, sp.cos, sp.tan, sp.atan, sp.atan2, sp.asin, sp.acos, sp.exp, sp.log)


def is_exact(M: sp.Matrix) -> bool:
    """Exact algebraic numbers (rationals, radicals; π only inside trig functions that evaluate away): rank decisions
    are then exact. A transcendental entry (cos(1/10)) or a float goes to the SVD with a tolerance."""
    return all(not x.free_symbols and not x.atoms(sp.Float) and not x.atoms(*_TRANSCENDENTAL) and not x.has(sp.pi)
               for x in M)


_X = sp.Dummy("x")


def number_is_zero(e: sp.Expr) -> bool:
    """e = 0 for an exact algebraic number (rationals, radicals): |e| to 30 digits above 10⁻²⁰ proves it non-zero
    (evalf's error is far smaller), and below that its minimal polynomial decides (x iff e = 0). The same answer as
    ``simplify(e) == 0``, without simplify (whose first call also imports sympy.physics.units, ~0.15 s)."""
    if e.is_Rational:
        return e == 0
    if abs(sp.N(e, 30)) > 1e-20:
        return False
    return sp.minimal_polynomial(e, _X) == _X


def to_np(M: sp.Matrix) -> np.ndarray:
    return np.array(M.evalf(30).tolist(), dtype=float).reshape(M.shape)


def from_np(a: np.ndarray, scale: float | None = None) -> sp.Matrix:
    a = np.atleast_2d(a)
    scale = scale or (max(1.0, float(np.max(np.abs(a)))) if a.size else 1.0)
    return sp.Matrix(a.shape[0], a.shape[1],
                     lambda i, j: sp.Integer(0) if abs(a[i, j]) < 1e-12 * scale else sp.Float(float(a[i, j]), 15))


@dataclass
class Spaces:
    """Rank of J at a configuration and bases of its null and range spaces (columns); ``exact`` (sympy) or from the
    SVD with the tolerance ``tol`` (singular values ``sigma``)."""

    rank: int
    null: sp.Matrix
    range: sp.Matrix
    exact: bool
    tol: float
    sigma: list[float]


def spaces(J: sp.Matrix, tol: float = 1e-9, exact_size: int = 36) -> Spaces:
    """Exact when J's entries are exact numbers (rank by exact elimination, null space with the free variables
    set to 1, range spanned by the pivot columns); otherwise from the SVD: rank = #{σ_i > tol·max(1, σ_1)},
    orthonormal bases."""
    m, n = J.shape
    sigma = list(np.linalg.svd(to_np(J), compute_uv=False)) if m and n else []
    if is_exact(J) and m * n <= exact_size:
        Jc = J.applyfunc(lambda x: sp.radsimp(x) if x.is_number and not x.is_Rational else x)
        rank = Jc.rank(iszerofunc=number_is_zero)
        ns = Jc.nullspace(iszerofunc=number_is_zero, simplify=True)
        null = sp.Matrix.hstack(*[v.applyfunc(sp.radsimp) for v in ns]) if ns else sp.zeros(n, 0)
        _, piv = Jc.rref(iszerofunc=number_is_zero)
        rng = Jc.extract(list(range(m)), list(piv)) if piv else sp.zeros(m, 0)
        return Spaces(rank, null, rng, True, tol, sigma)
    a = to_np(J)
    U, s, Vt = np.linalg.svd(a)
    rank = int(np.sum(s > tol * max(1.0, s[0]))) if s.size else 0
    null = from_np(Vt[rank:].T) if rank < n else sp.zeros(n, 0)
    rng = from_np(U[:, :rank]) if rank else sp.zeros(m, 0)
    return Spaces(rank, null, rng, False, tol, sigma)


def manipulability(J: sp.Matrix) -> sp.Expr:
    """w = √det(J Jᵀ) (|det J| for square J)."""
    m, n = J.shape
    if m == n:
        return sp.Abs(det(J)) if J.free_symbols else sp.Abs(J.det())
    return sp.sqrt(det((J * J.T).applyfunc(tidy))) if J.free_symbols else sp.sqrt((J * J.T).det())


# ------------------------------------------------------------------------------------------------ sketch skeleton
def dh_skeleton(robot: "Robot") -> list[sp.Matrix] | None:
    """The origins o_0, o_1, ..., o_n of a planar DH robot (x, y), or None when the robot is not planar (an origin
    leaves the plane z = const or a revolute axis is not normal to it)."""
    if not robot.frames:
        return None
    pts = [F[:3, 3] for F in robot.frames]
    z0 = tidy(pts[0][2])
    if any(tidy(p[2] - z0) != 0 for p in pts):
        return None
    for i, j in enumerate(axis_frames(robot.dh_convention or "standard", robot.n)):
        z = robot.frames[j][:3, 2]
        if robot.joints[i] == "R" and (tidy(z[0]) != 0 or tidy(z[1]) != 0):
            return None
    return [sp.Matrix([tidy(p[0]), tidy(p[1])]) for p in pts]


def task_skeleton(r: sp.Matrix, q: Sequence[sp.Symbol]) -> list[sp.Matrix] | None:
    """Points P_0..P_n of a planar chain read off a position task p = (r_1, r_2) written as a sum of link
    contributions: P_k collects the terms that depend on no joint after k (l1 c1 + l2 c12 -> P_1 = l1 c1). None when
    the task has fewer than two components."""
    if r.shape[0] < 2:
        return None
    idx = {x: i + 1 for i, x in enumerate(q)}
    comps = []
    for e in (r[0], r[1]):
        terms: dict[int, list[sp.Expr]] = {}
        for t in sp.Add.make_args(sp.expand(e)):
            k = max([idx[s] for s in t.free_symbols if s in idx], default=0)
            terms.setdefault(k, []).append(t)
        comps.append(terms)
    if not any(k > 0 for c in comps for k in c):
        return None
    pts = []
    for k in range(len(q) + 1):
        pts.append(sp.Matrix([sp.Add(*[t for j, ts in c.items() if j <= k for t in ts]) for c in comps]))
    return pts
