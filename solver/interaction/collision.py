"""Collision detection, isolation and identification (ask kind ``collision``).

With a contact force F ∈ R^m at a point p_c(q) of link i (J_c = ∂p_c/∂q, columns i+1..n zero):

    B(q) q̈ + S(q, q̇) q̇ + g(q) + F_v q̇ = G u + τ_ext,        τ_ext = J_cᵀ(q) F
    p = B q̇,    ṗ = Ḃ q̇ + B q̈ = G u + Sᵀ q̇ − g − F_v q̇ + τ_ext          (Ḃ = S + Sᵀ, S from Christoffel)
    r = K_I (p − ∫₀ᵗ (G u + Sᵀ q̇ − g − F_v q̇ + r) ds − p(0))   ⇒   ṙ = K_I (τ_ext − r),   r → τ_ext = J_cᵀ F
    E = T + U,  σ = k_E (E − ∫₀ᵗ (q̇ᵀ (G u − F_v q̇) + σ) ds − E(0))   ⇒   σ̇ = k_E (q̇ᵀ τ_ext − σ) = k_E (v_cᵀ F − σ)

Per contact: the structure of J_cᵀ F (detection: F ∉ N(J_cᵀ); isolation: r_i = j_iᵀ F ≠ 0, j_i the i-th column;
identification of F: rank J_c = m; of F and an unknown location ρ of the point: rank ∂(J_cᵀF)/∂(F, ρ) = m + 1),
numbers at a state, F estimated from r (or from the torque balancing the contact at rest) by pseudoinversion, and
a simulation of the robot and both residuals during a collision (scipy ``solve_ivp``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field

from solver.dynamics.model import DynamicModel, derive, has_model
from solver.kinematics.redundancy import generic_rank
from solver.math.numeric import lambdify_np
from solver.math.rigid import dh_chain
from solver.math.simplify import (factor_within, is_zero, ring_fraction, tidy, tidy_matrix, velocity_terms,
                                  zero_or_simplified)
from solver.math.sweep import numeric_values
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
MAX_CONTACTS = 12          # result names carry the contact's index _1.._12 (property checks are registered for them)
EXACT_ENTRIES = 24         # numeric matrices with at most this many entries are handled exactly (sympy)
SYMBOLIC_OPS = 120         # beyond this size of J_c the symbolic estimate F(r) is not formed (numbers at a state are)


# ------------------------------------------------------------------------------------------------ options
class CartesianTerm(Strict):
    """A Cartesian force law F(q) acting at a point p(q): adds J_p(q)ᵀ F to the motor torque."""

    point: ExprT = Field(description="the point p(q) where the force acts (2 or 3 components, base frame)")
    force: ExprT = Field(description="the force F (same size), may depend on q, e.g. Kp*(pd - p(q))")


class TorqueLaw(Strict):
    """The motor torque u at a static equilibrium, built from its parts: u = joint + g(q) + Σ J_pᵀ F."""

    joint: Optional[ExprT] = Field(None, description="a joint-space part (n expressions)")
    gravity: bool = Field(False, description="the law includes the gravity compensation g(q)")
    cartesian: list[CartesianTerm] = Field([], description="Cartesian force laws, each adding J_p(q)ᵀ F(q)")


class Contact(Strict):
    """One contact (collision) case: a point of one link and, optionally, the force or the measured torque."""

    name: Optional[str] = Field(None, description="how the case is named in the report (results use its index _k)")
    link: int = Field(description="the link (1..number of joints) carrying the contact point")
    point: ExprT = Field(description="contact point p_c(q): 2 (planar) or 3 components, in the base frame "
                                     "(or in the DH frame of the link with point_in: link)")
    point_in: Literal["base", "link"] = Field("base", description="frame of point: (link: the link's DH frame)")
    location: Optional[str] = Field(None, description="the symbol locating the point along the link when it may be "
                                                      "unknown (e.g. rho3): F and it are identified together if possible")
    angle: Optional[Scalar] = Field(None, description="planar: absolute orientation of the link, for force components "
                                                      "in the link frame (default: the DH frame of the link, if any)")
    rotation: Optional[ExprT] = Field(None, description="spatial: the link's rotation matrix 0R_i(q) (same use)")
    force: Optional[ExprT] = Field(None, description="the contact force F (base frame, may be symbolic); "
                                                     "default: unknown components Fx, Fy(, Fz)")
    residual: Optional[ExprT] = Field(None, description="measured residual r (n numbers) at the at: state: "
                                                        "F is estimated from r = J_c^T F")
    torque: Optional[Union[ExprT, TorqueLaw]] = Field(
        None, description="the motor torque u holding the robot at rest at the at: state under the contact "
                          "(n numbers, or {joint, gravity, cartesian}): tau_ext = g(q) - u, then F estimated")


class Simulation(Strict):
    """A simulated collision: the robot and both residuals under a contact force profile."""

    contact: int = Field(1, description="index (1, 2, ...) of the contact that is hit")
    force: Optional[ExprT] = Field(None, description="numeric contact force (base frame); default the contact's force")
    start: float = Field(0.5, description="collision start time [s]")
    end: Optional[float] = Field(None, description="collision end time [s] (default start + 1)")
    profile: Literal["step", "pulse"] = Field("step", description="step: F constant on [start, end]; pulse: "
                                                                  "F sin(π (t - start)/(end - start)) (an impact)")
    duration: float = Field(3.0, description="simulated time [s]")
    gain: Optional[Union[float, list[float]]] = Field(None, description="K_I (number or diagonal list); default the "
                                                                        "ask's gain if numeric, else 20")
    gain_energy: Optional[float] = Field(None, description="k_E; default the ask's if numeric, else 20")
    q0: Optional[list[Scalar]] = Field(None, description="initial configuration (default: the at: state, else 0)")
    dq0: Optional[list[Scalar]] = Field(None, description="initial velocity (default: the at: state, else 0)")
    control: Literal["pd", "gravity", "none"] = Field(
        "pd", description="motor torque: pd: u = g(q) + kp (q0 - q) - kd q̇; gravity: u = g(q); none: u = 0")
    kp: float = Field(100.0, description="pd: proportional gain")
    kd: float = Field(20.0, description="pd: derivative gain")


class CollisionAsk(Strict):
    """Collision detection, isolation and identification with model-based residuals."""

    kind: Literal["collision"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    residuals: Optional[list[Literal["momentum", "energy"]]] = Field(
        None, description="residuals to derive (default both when the robot has a dynamic model, else none)")
    gain: Optional[ExprT] = Field(None, description="K_I: one expression or a diagonal list; default kI1..kIn")
    gain_energy: Optional[Scalar] = Field(None, description="k_E of the energy residual; default kE")
    contacts: list[Contact] = Field([], description="contact cases to analyze")
    at: Optional[dict[str, Scalar]] = Field(None, description="state {q1: .., dq1: ..} for numbers (parameter values "
                                                              "used)")
    simulate: Optional[Simulation] = Field(None, description="simulate a collision and plot the residuals")


# ------------------------------------------------------------------------------------------------ math
@dataclass
class MomentumResidual:
    p: sp.Matrix               # B q̇
    STdq: sp.Matrix            # Sᵀ q̇
    integrand: sp.Matrix       # β = G u + Sᵀ q̇ − g − F_v q̇
    pdot: sp.Matrix            # β + τ_ext
    check: bool                # d/dt(B q̇) along the model ≡ β + τ_ext  (Ḃ = S + Sᵀ)
    rdot: sp.Matrix            # K_I (τ_ext − r), derived
    K: sp.Matrix
    r: sp.Matrix
    tau: sp.Matrix             # τ_ext symbols


@dataclass
class EnergyResidual:
    E: sp.Expr
    integrand: sp.Expr         # q̇ᵀ (G u − F_v q̇)
    Edot: sp.Expr              # integrand + q̇ᵀ τ_ext
    check: bool
    sdot: sp.Expr              # k_E (q̇ᵀ τ_ext − σ)
    k: sp.Expr
    sigma: sp.Symbol


def generalized_input(dm: DynamicModel) -> sp.Matrix:
    """G u (u when there is no input map)."""
    return dm.G * dm.u if dm.G is not None else dm.u


def _bdot(B: sp.Matrix, q: list[sp.Symbol], dq: list[sp.Symbol]) -> sp.Matrix:
    return sum((B.diff(x) * v for x, v in zip(q, dq)), sp.zeros(*B.shape))


def momentum_residual(dm: DynamicModel, q: list[sp.Symbol], dq: list[sp.Symbol], K: sp.Matrix,
                      r: sp.Matrix, tau: sp.Matrix) -> MomentumResidual:
    """p = B q̇, β = G u + Sᵀ q̇ − g − F_v q̇ and ṙ = K_I (ṗ − β − r) with ṗ from the model (B q̈ replaced by
    G u + τ_ext − S q̇ − g − F_v q̇): ṙ = K_I ((Ḃ − S − Sᵀ) q̇ + τ_ext − r) = K_I (τ_ext − r)."""
    n = len(q)
    v = sp.Matrix(dq)
    fric = dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1)
    Gu = generalized_input(dm)
    p = tidy_matrix(dm.B * v)
    STdq = tidy_matrix(dm.S.T * v)
    beta = tidy_matrix(Gu + STdq - dm.g - fric)
    Bqdd = Gu + tau - dm.S * v - dm.g - fric
    pdot_model = _bdot(dm.B, q, dq) * v + Bqdd
    pdot = beta + tau
    check = all(is_zero(x) for x in (pdot_model - pdot))
    rdot = tidy_matrix(K * (pdot_model - beta - r))
    return MomentumResidual(p, STdq, beta, pdot, bool(check), rdot, K, r, tau)


def energy_residual(dm: DynamicModel, q: list[sp.Symbol], dq: list[sp.Symbol], k: sp.Expr, sigma: sp.Symbol,
                    tau: sp.Matrix) -> EnergyResidual:
    """E = T + U, Ė along the model = q̇ᵀ(G u − F_v q̇) + q̇ᵀ τ_ext (q̇ᵀ(½Ḃ q̇ − c) = 0), σ̇ = k_E (Ė − β_E − σ)."""
    n = len(q)
    v = sp.Matrix(dq)
    fric = dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1)
    Gu = generalized_input(dm)
    E = tidy(dm.T + dm.U)
    beta = tidy((v.T * (Gu - fric))[0])
    Bqdd = Gu + tau - dm.c - dm.g - fric
    Edot_model = (v.T * Bqdd)[0] + (v.T * _bdot(dm.B, q, dq) * v)[0] / 2 + (dm.g.T * v)[0]
    Edot = beta + (v.T * tau)[0]
    check = is_zero(Edot_model - Edot)
    return EnergyResidual(E, beta, tidy(Edot), bool(check), tidy(k * (Edot_model - beta - sigma)), k, sigma)


def contact_jacobian(point: sp.Matrix, q: list[sp.Symbol]) -> sp.Matrix:
    """J_c = ∂p_c/∂q."""
    return tidy_matrix(point.jacobian(q))


def _content_free(v: sp.Matrix) -> sp.Matrix:
    """A vector up to a scalar factor: denominators cleared, common factors removed, first non-zero entry
    without a leading minus sign."""
    v = v.applyfunc(sp.together)
    dens = [sp.fraction(x)[1] for x in v]
    L = sp.lcm(dens) if dens else 1
    v = (v * L).applyfunc(lambda x: sp.factor_terms(sp.expand(sp.cancel(x))))
    nz = [x for x in v if x != 0]
    if not nz:
        return v
    polys, back = _trig_polys(list(v))
    g = [p for p in polys if p != 0][0]
    for x in polys:
        g = sp.gcd(g, x) if x != 0 else g
    if g != 0 and g != 1:
        v = sp.Matrix([sp.cancel(x / g).xreplace(back) for x in polys])
    v = v.applyfunc(tidy)
    first = next(x for x in v if x != 0)
    if first.could_extract_minus_sign():
        v = -v
    return v


def null_basis(M: sp.Matrix, rank: int) -> list[sp.Matrix]:
    """A basis of N(M) (columns of length M.cols), each vector up to its scale; ``rank`` the generic rank of M.
    N(M) ⟂ R(Mᵀ): for M with 2 or 3 columns the basis follows from ``rank`` independent rows."""
    m = M.cols
    if rank >= m:
        return []
    rows = [M.row(i).T for i in range(M.rows) if not all(zero_or_simplified(x) for x in M.row(i))]
    if rank == 0 or not rows:
        return [sp.eye(m)[:, j] for j in range(m)]
    if m == 2:
        a = rows[0]
        return [_content_free(sp.Matrix([-a[1], a[0]]))]
    if m == 3 and rank == 2:
        for a, b in combinations(rows, 2):
            c = a.cross(b).applyfunc(tidy)
            if not all(zero_or_simplified(x) for x in c):
                return [_content_free(c)]
    ns = M.applyfunc(tidy).nullspace(simplify=True)
    return [_content_free(v) for v in ns]


def last_independent(M: sp.Matrix, count: int) -> list[int]:
    """Indices of ``count`` rows of M, independent at generic points, taken from the last rows first (the
    equations of the joints nearest to the contact, as a teacher solves them)."""
    rows = [i for i in range(M.rows) if not all(zero_or_simplified(x) for x in M.row(i))]
    for combo in combinations(sorted(rows, reverse=True), count):
        if generic_rank(M.extract(sorted(combo), list(range(M.cols)))) == count:
            return sorted(combo)
    return []


def estimate_symbolic(JcT: sp.Matrix, r: sp.Matrix, rank: int) -> tuple[sp.Matrix, sp.Expr] | None:
    """F̂ ∈ R(J_c) with J_cᵀ F̂ = r for a consistent r: with A the columns of J_c of ``rank`` independent rows of
    J_cᵀ (the last ones), F̂ = A (AᵀA)⁻¹ r_A (the minimum-norm solution; the unique one when rank = m)."""
    if rank == 0:
        return sp.zeros(JcT.cols, 1), sp.Integer(1)
    idx = last_independent(JcT, rank)
    if not idx:
        return None
    A = JcT.extract(idx, list(range(JcT.cols))).T
    AtA = (A.T * A).applyfunc(tidy)
    if rank == JcT.cols:  # square A: F = A^-T r_A = adj(Aᵀ) r_A / det(Aᵀ)
        At = A.T
        return (At.adjugate() * r.extract(idx, [0])).applyfunc(tidy), tidy(At.det())
    return (A * AtA.adjugate() * r.extract(idx, [0])).applyfunc(tidy), tidy(AtA.det())


def rational_nullspace(M: sp.Matrix) -> list[sp.Matrix]:
    """M.nullspace(simplify=True) when the basis is rational: the same Gauss-Jordan steps with every pivot and zero
    decided exactly (is_zero) instead of by sympy's simplify (0.2 s for a 2x3 of sin/cos), kept when each vector
    is rational (the basis from the unique reduced row echelon form, in its unique form); sympy's otherwise, and
    when a zero test does not decide."""
    undecided: list[sp.Expr] = []

    def zero(x: sp.Expr) -> bool | None:
        z = is_zero(x)
        if z is None:
            undecided.append(x)
        return z

    try:
        basis = M.nullspace(iszerofunc=zero)
    except (ValueError, TypeError, ZeroDivisionError, sp.PolynomialError):
        basis = None
    if basis is not None and not undecided and all(x.is_Rational for v in basis for x in v):
        return basis
    return M.nullspace(simplify=True)


def identify_with_location(point: sp.Matrix, q: list[sp.Symbol], F: sp.Matrix, rho: sp.Symbol, r: sp.Matrix,
                           link: int) -> tuple[sp.Matrix, sp.Expr] | None:
    """Solve J_c(q, ρ)ᵀ F = r for (F, ρ), for a point affine in ρ, p_c = a(q) + ρ b(q), J_c = J_a + ρ J_b:
    the combinations c of the first ``link`` equations with J_b c = 0 are free of ρ and give F (linear, the m
    last independent ones); then ρ = (r_k − j_{a,k}ᵀF)/(j_{b,k}ᵀF) from the last equation k with j_{b,k} ≠ 0.
    None when the point is not affine in ρ or the combinations do not determine F."""
    m = F.rows
    if any(not zero_or_simplified(x) for x in point.diff(rho, 2)):
        return None
    b = point.diff(rho)
    a = (point - rho * b).applyfunc(tidy)
    Ja = a.jacobian(q)[:, :link]
    Jb = b.jacobian(q)[:, :link].applyfunc(tidy)
    combos = rational_nullspace(Jb) if any(not zero_or_simplified(x) for x in Jb) else \
        [sp.eye(link)[:, j] for j in range(link)]
    if len(combos) < m:
        return None
    C = sp.Matrix.hstack(*combos).T.applyfunc(_factored)  # rows: ρ-free combinations
    A = (C * Ja.T).applyfunc(tidy)
    rows = last_independent(A, m)
    if not rows:
        return None
    A2, rhs = A.extract(rows, list(range(m))), (C * r[:link, 0]).extract(rows, [0])
    Fs = (A2.adjugate() * rhs / tidy(A2.det())).applyfunc(lambda x: _tidy_quotient(_factored(x)))
    ks = [k for k in range(link) if not all(zero_or_simplified(x) for x in Jb[:, k])]
    if not ks:
        return None
    k = ks[-1]
    den = (Jb[:, k].T * Fs)[0]
    if zero_or_simplified(den):
        return None
    loc = (r[k] - (Ja[:, k].T * Fs)[0]) / den
    return Fs, _tidy_quotient(_factored(loc, together=True))


def _factored(x: sp.Expr, together: bool = False) -> sp.Expr:
    """factor(cancel(x)) (of together(x) with ``together``): the canonical factors of the rational function x, read
    from x directly when it is one over QQ of its symbols, sines and cosines (cancel and together only multiply
    them out, and factor_within then gives factor_rational(x), within its CPU budget); through cancel otherwise."""
    if ring_fraction(x, opaque_trig=True) is not None:
        return factor_within(x)
    return factor_within(sp.cancel(sp.together(x) if together else x))


def collect_linear(e: sp.Expr, syms: list[sp.Symbol]) -> sp.Expr:
    """e = Σ c_k s_k + c_0 with each coefficient tidied (τ_c as the teacher writes it: grouped by F_x, F_y)."""
    e = sp.expand(e)
    if not any(s in e.free_symbols for s in syms):
        return tidy(e)
    parts = sp.collect(e, syms, evaluate=False)
    out = sp.Integer(0)
    for k, coef in parts.items():
        out += tidy(coef) * k
    return out


def _trig_polys(exprs: list[sp.Expr]) -> tuple[list[sp.Expr], dict]:
    """Expressions with sin/cos of single symbols replaced by dummies (after expanding sums of angles), so that
    polynomial gcds and cancellations apply; returns them and the map back."""
    ex = [sp.expand_trig(sp.expand(e)) for e in exprs]
    atoms = set().union(*[e.atoms(sp.sin, sp.cos) for e in ex]) if ex else set()
    back, fwd = {}, {}
    for a in sorted(atoms, key=str):
        if not a.args[0].is_Symbol:
            return exprs, {}
        dmy = sp.Dummy(f"{a.func.__name__}_{a.args[0]}")
        fwd[a], back[dmy] = dmy, a
    return [e.xreplace(fwd) for e in ex], back


def _quotient(n: sp.Expr, d: sp.Expr) -> sp.Expr:
    """n/d with common (trigonometric) polynomial factors cancelled, numerator and denominator tidied."""
    if n == 0:
        return sp.Integer(0)
    if d == 1:
        return n
    if sp.count_ops(n) + sp.count_ops(d) > 400:
        return n / d
    (pn, pd), back = _trig_polys([n, d])
    if back or not (n.atoms(sp.sin, sp.cos) or d.atoms(sp.sin, sp.cos)):
        g = sp.gcd(pn, pd)
        if g not in (0, 1):
            pn, pd = sp.cancel(pn / g), sp.cancel(pd / g)
        pn, pd = tidy(pn.xreplace(back)), tidy(pd.xreplace(back))
        num, den = sp.fraction(sp.together(pn / pd))
        return tidy(num) / tidy(den) if den != 1 else tidy(num)
    return n / d


def _tidy_quotient(e: sp.Expr) -> sp.Expr:
    """n/d with numerator and denominator in teacher form."""
    n, d = sp.fraction(sp.together(e))
    return tidy(n) / tidy(d) if d != 1 else tidy(n)


# ------------------------------------------------------------------------------------------------ numerics
def _algebraic(x: sp.Expr) -> bool:
    """An exact number without floats or unevaluated functions (sin(2/5) is not; sqrt(2)/4 and π/8 are)."""
    return bool(x.is_number) and not x.atoms(sp.Float) and not x.atoms(sp.Function)


def _exact(M: sp.Matrix) -> bool:
    return all(_algebraic(x) for x in M) and M.rows * M.cols <= EXACT_ENTRIES


def _num(x: sp.Expr) -> sp.Expr:
    """An exact number in a short form; a float kept as a float; an expression tidied."""
    if not x.is_number:
        return tidy(sp.expand(x)) if sp.count_ops(x) <= 80 else x
    if not _algebraic(x):
        return sp.Float(sp.N(x, 15), 15) if not x.is_Integer else x
    return sp.radsimp(sp.expand(x)) if sp.count_ops(x) > 0 else x


def _decimal(x: sp.Expr) -> sp.Expr:
    """A rational read from a decimal datum (0.7585 -> 1517/2000) back to a decimal for display."""
    return sp.Float(x, 15) if x.is_Rational and x.q > 12 else x


def _nice(x: sp.Expr) -> bool:
    """An exact number a student reads at a glance: a small fraction, possibly times one √k or π."""
    if not x.is_number or x.atoms(sp.Float):
        return True
    coeff, rest = x.as_coeff_Mul()
    if not coeff.is_Rational or coeff.q > 12:
        return False
    return rest == 1 or rest == sp.pi or (rest.is_Pow and rest.exp == sp.Rational(1, 2) and rest.base.is_Integer)


def _display(v: Any) -> Any:
    """A numeric value as the report shows it: exact when nice, else 5 significant digits."""
    if isinstance(v, sp.MatrixBase):
        if all(_nice(x) for x in v):
            return v
        return v.applyfunc(lambda x: sp.Float(sp.N(x, 15), 5) if x.is_number and x != 0 else x)
    if isinstance(v, sp.Expr) and not _nice(v):
        return sp.Float(sp.N(v, 15), 5)
    return v


def _num_matrix(M: sp.Matrix) -> sp.Matrix:
    if all(x.is_number for x in M) and not _exact(M):
        a = np.array(M.evalf(30).tolist(), dtype=float)
        scale = max(1.0, float(np.max(np.abs(a)))) if a.size else 1.0
        return sp.Matrix(*a.shape, lambda i, j: 0 if abs(a[i, j]) < 1e-12 * scale else sp.Float(a[i, j], 15))
    return M.applyfunc(_num)


def _algebraic_matrix(M: sp.Matrix) -> Any:
    """M as a DomainMatrix over QQ or an algebraic number field QQ<θ> (entries rationals and radicals, I), where
    arithmetic and zero tests are exact; None for other entries (π, e: no field sympy's domains decide in)."""
    from sympy.polys.matrices import DomainMatrix
    try:
        dM = DomainMatrix.from_Matrix(M, extension=True)
    except (sp.PolynomialError, NotImplementedError, ValueError, TypeError):
        return None
    K = dM.domain
    return dM if K.is_ZZ or K.is_QQ or K.is_AlgebraicField else None


def numeric_rank(M: sp.Matrix) -> int:
    """Rank of a numeric matrix: exact for exact entries (over their number field, else with sympy's simplify as
    the zero test), from the singular values otherwise."""
    if _exact(M):
        dM = _algebraic_matrix(M)
        if dM is not None:
            return int(dM.to_field().rank())
        return M.rank(iszerofunc=lambda x: sp.simplify(x) == 0)
    a = np.array(M.evalf(30).tolist(), dtype=float)
    if a.size == 0:
        return 0
    s = np.linalg.svd(a, compute_uv=False)
    return int(np.sum(s > 1e-9 * max(1.0, s[0])))


def numeric_pinv(M: sp.Matrix) -> sp.Matrix:
    """Moore-Penrose pseudoinverse of a numeric matrix (exact when its entries are)."""
    if _exact(M):
        return M.pinv().applyfunc(_num)
    a = np.array(M.evalf(30).tolist(), dtype=float)
    return _num_matrix(sp.Matrix(np.linalg.pinv(a, rcond=1e-10)))


# ------------------------------------------------------------------------------------------------ simulation
@dataclass
class SimData:
    """Numbers of a simulated collision."""

    t: np.ndarray
    q: np.ndarray              # (N, n)
    dq: np.ndarray
    r: np.ndarray              # momentum residual (N, n)
    tau_ext: np.ndarray        # true external torque J_cᵀ F(t) (N, n)
    sigma: np.ndarray | None   # energy residual (N,)
    power: np.ndarray          # q̇ᵀ τ_ext (N,)
    unit: list[str] = field(default_factory=list)  # parameters set to 1


def force_profile(t: float, F: np.ndarray, start: float, end: float, profile: str) -> np.ndarray:
    """F on [start, end): constant (step) or F sin(π (t − start)/(end − start)) (pulse); 0 outside."""
    if t < start or t >= end:
        return np.zeros_like(F)
    if profile == "pulse":
        return F * math.sin(math.pi * (t - start) / (end - start))
    return F


def simulate_collision(dm: DynamicModel, q: list[sp.Symbol], dq: list[sp.Symbol], point: sp.Matrix,
                       values: dict[sp.Symbol, sp.Expr], F: np.ndarray, start: float, end: float, duration: float,
                       K: np.ndarray, kE: float | None, q0: np.ndarray, dq0: np.ndarray, control: str = "pd",
                       kp: float = 100.0, kd: float = 20.0, profile: str = "step", samples: int = 600) -> SimData:
    """Integrate  B q̈ = G u + J_cᵀ F(t) − c − g − F_v q̇  together with the residuals
    r = K_I (p − I − p(0)), İ = G u + Sᵀ q̇ − g − F_v q̇ + r  and  σ = k_E (E − I_E − E(0)), İ_E = q̇ᵀ(G u − F_v q̇) + σ,
    piecewise on [0, start], [start, end], [end, duration] (the force profile is discontinuous there).
    The motor command u = G⁺ τ_u with τ_u = g(q) + kp (q0 − q) − kd q̇ (pd), g(q) (gravity) or 0 (none)."""
    from scipy.integrate import solve_ivp

    n = len(q)
    Jc = point.jacobian(q)
    v = sp.Matrix(dq)
    c = dm.S * v if dm.S is not None else dm.c
    exprs = [dm.B, c, dm.g, Jc] + ([dm.S] if dm.S is not None else []) + ([dm.Fv] if dm.Fv is not None else [])
    if dm.G is not None:
        exprs.append(dm.G)
    energy = kE is not None and dm.U is not None
    if energy:
        exprs.append(sp.Matrix([dm.T + dm.U]))
    state = set(q) | set(dq)
    fixed, unit = numeric_values([e for M in exprs for e in M], values, state | set(dm.u))
    num = {k: (float(v_) if not isinstance(v_, float) else v_) for k, v_ in fixed.items()}
    args = list(q) + list(dq)

    def lam(M: sp.Matrix):  # type: ignore[no-untyped-def]
        f = lambdify_np(args, M.subs(num))
        return lambda x, y: np.array(f(*x, *y), dtype=float).reshape(M.shape)

    Bf, cf, gf, Jf = lam(dm.B), lam(c), lam(dm.g), lam(Jc)
    Sf = lam(dm.S) if dm.S is not None else None
    Ff = lam(dm.Fv) if dm.Fv is not None else None
    Gf = lam(dm.G) if dm.G is not None else None
    Ef = lam(sp.Matrix([dm.T + dm.U])) if energy else None

    def torques(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The generalized motor force G u."""
        tau = np.zeros(n)
        if control in ("pd", "gravity"):
            tau = tau + gf(x, y).ravel()
        if control == "pd":
            tau = tau + kp * (q0 - x) - kd * y
        if Gf is not None:
            G = Gf(x, y)
            tau = G @ (np.linalg.pinv(G) @ tau)  # what the inputs can deliver
        return tau

    def text(t: float, x: np.ndarray) -> np.ndarray:
        return Jf(x, np.zeros(n)).T @ force_profile(t, F, start, end, profile)

    p0 = Bf(q0, dq0) @ dq0
    E0 = float(Ef(q0, dq0)[0, 0]) if energy else 0.0

    def parts(t: float, z: np.ndarray) -> tuple:
        x, y, integ = z[:n], z[n:2 * n], z[2 * n:3 * n]
        tau_u = torques(x, y)
        fric = Ff(x, y) @ y if Ff is not None else np.zeros(n)
        r = K * (Bf(x, y) @ y - integ - p0)
        return x, y, tau_u, fric, r

    def rhs(t: float, z: np.ndarray) -> np.ndarray:
        x, y, tau_u, fric, r = parts(t, z)
        te = text(t, x)
        ddq = np.linalg.solve(Bf(x, y), tau_u + te - cf(x, y).ravel() - gf(x, y).ravel() - fric)
        beta = tau_u + Sf(x, y).T @ y - gf(x, y).ravel() - fric if Sf is not None else np.zeros(n)
        out = [y, ddq, beta + r]
        if energy:
            sig = kE * (float(Ef(x, y)[0, 0]) - z[3 * n] - E0)
            out.append(np.array([y @ (tau_u - fric) + sig]))
        return np.concatenate(out)

    z0 = np.concatenate([q0, dq0, np.zeros(n)] + ([np.zeros(1)] if energy else []))
    edges = sorted({0.0, min(start, duration), min(end, duration), duration})
    ts, zs = [], []
    per = max(samples // max(1, len(edges) - 1), 20)
    for a, b in zip(edges[:-1], edges[1:]):
        if b <= a:
            continue
        grid = np.linspace(a, b, per)
        sol = solve_ivp(rhs, (a, b), z0, t_eval=grid, method="LSODA", rtol=1e-9, atol=1e-11,
                        max_step=(b - a) / 50)
        if not sol.success:
            raise RuntimeError(f"simulation failed: {sol.message}")
        ts.append(sol.t[:-1] if b < duration else sol.t)
        zs.append(sol.y[:, :-1] if b < duration else sol.y)
        z0 = sol.y[:, -1]
    t = np.concatenate(ts)
    Z = np.concatenate(zs, axis=1).T
    R, TE, SIG, PW = [], [], [], []
    for tk, zk in zip(t, Z):
        x, y, tau_u, fric, r = parts(tk, zk)
        te = text(tk, x)
        R.append(r)
        TE.append(te)
        PW.append(float(y @ te))
        if energy:
            SIG.append(kE * (float(Ef(x, y)[0, 0]) - zk[3 * n] - E0))
    return SimData(t, Z[:, :n], Z[:, n:2 * n], np.array(R), np.array(TE), np.array(SIG) if energy else None,
                   np.array(PW), [s.name for s in unit])


def first_order_filter(t: np.ndarray, u: np.ndarray, k: float, jumps: tuple[float, ...] = ()) -> np.ndarray:
    """y with ẏ = k (u − y), y(0) = 0, for a signal u sampled at t: exact for u piecewise linear between the
    samples, and held at its left value over a step ending at one of the ``jumps`` (where u is discontinuous)."""
    y = np.zeros_like(u)
    for j in range(1, len(t)):
        h = t[j] - t[j - 1]
        a = math.exp(-k * h)
        jump = any(abs(t[j] - tj) < 1e-12 for tj in jumps)
        slope = (u[j] - u[j - 1]) / h if (h > 0 and not jump) else 0.0
        # exact response over one step to u(t_{j-1}) + slope (t - t_{j-1})
        y[j] = a * y[j - 1] + (1 - a) * (u[j - 1] - slope / k) + slope * h
    return y


# ------------------------------------------------------------------------------------------------ the ask
class _Ctx:
    """Parsed inputs of one collision ask."""

    def __init__(self, problem, options: CollisionAsk, ctx) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.options, self.ctx = problem, options, ctx
        robot = problem.robot
        if robot is None:
            raise self.fail((), "a collision ask needs a robot", "add robot: {joints: [...], links: [...]}")
        self.robot = robot
        self.q, self.dq = list(robot.q), list(robot.dq)
        self.n = robot.n
        self.links = len(robot.joints)

    def fail(self, sub: tuple, message: str, hint: str | None = None) -> UserError:
        return UserError(message, self.problem.located.place(self.ctx.path + sub), hint)

    def symbol(self, name: str, tex: str, **assume: Any) -> sp.Symbol:
        """The problem's symbol of that name if declared (so it keeps its meaning), else a new one registered in
        the problem's names (answers and expected values may use it)."""
        s = self.problem.names.get(name)
        if isinstance(s, sp.Symbol):
            return s
        s = sp.Symbol(name, **(assume or {"real": True}))
        self.problem.names[name] = s
        self.problem.latex_names.setdefault(s, tex)
        return s

    def vector(self, sub: tuple, size: int | tuple[int, ...], what: str) -> sp.Matrix:
        val = self.ctx.expr(*sub)
        if not isinstance(val, list):
            val = [val]
        sizes = (size,) if isinstance(size, int) else size
        shp = shape_of(val)
        if len(shp) != 1 or shp[0] not in sizes:
            want = " or ".join(str(s) for s in sizes)
            raise self.fail(sub, f"{what} must have {want} components, got shape {shp or 'scalar'}",
                            f"write a list of {want} expressions")
        return sp.Matrix(val)

    def gains(self) -> sp.Matrix:
        if self.options.gain is None:
            return sp.diag(*[self.symbol(f"kI{i + 1}", f"k_{{I{i + 1}}}", positive=True) for i in range(self.n)])
        val = self.ctx.expr("gain")
        vals = val if isinstance(val, list) else [val] * self.n
        if len(vals) != self.n or any(isinstance(x, list) for x in vals):
            raise self.fail(("gain",), f"gain must be one expression or a list of {self.n} (the diagonal of K_I)")
        return sp.diag(*vals)

    def gain_energy(self) -> sp.Expr:
        if self.options.gain_energy is None:
            return self.symbol("kE", "k_{E}", positive=True)
        val = self.ctx.expr("gain_energy")
        if isinstance(val, list):
            raise self.fail(("gain_energy",), "gain_energy must be one expression (k_E)")
        return val

    def state(self) -> dict[sp.Symbol, sp.Expr]:
        out: dict[sp.Symbol, sp.Expr] = {}
        names = {s.name: s for s in self.q + self.dq}
        for name in self.options.at or {}:
            if name not in names:
                raise self.fail(("at", name), f"'{name}' in at: is not a coordinate or a velocity",
                                "use " + ", ".join(list(names)[:4]) + ", ...")
            v = self.ctx.expr("at", name)
            if isinstance(v, list) or (v.free_symbols - set(self.problem.symbols.values())):
                raise self.fail(("at", name), f"the value of {name} must be a number (or parameters)")
            out[names[name]] = v
        return out


def _dh_frames(problem) -> list[tuple[sp.Matrix, sp.Matrix]] | None:  # type: ignore[no-untyped-def]
    """(p_i, R_i) of every DH frame of the robot (None without a DH table)."""
    data = problem.located.data.get("robot", {}) if isinstance(problem.located.data, dict) else {}
    dh = data.get("dh") if isinstance(data, dict) else None
    if not dh:
        return None
    P = ("robot", "dh")
    rows = [tuple(problem.parse_at(P + ("table", i, k)) for k in ("a", "alpha", "d", "theta"))
            for i in range(len(dh["table"]))]
    frames = dh_chain(rows, dh.get("convention", "standard"))
    if dh.get("base") is not None:
        base = sp.Matrix(problem.parse_at(P + ("base",)))
        frames = [(base * A).applyfunc(tidy) for A in frames]
    return [(A[:3, 3], A[:3, :3]) for A in frames]


@dataclass
class ContactCase:
    index: int
    label: str
    link: int
    point: sp.Matrix
    m: int
    F: sp.Matrix
    force_given: bool
    location: sp.Symbol | None
    R: sp.Matrix | None
    Jc: sp.Matrix = field(default_factory=sp.Matrix)
    data: dict[str, Any] = field(default_factory=dict)


def _contact(c: _Ctx, k: int, spec: Contact) -> ContactCase:
    """Parse and validate one contact entry."""
    P = ("contacts", k)
    if not 1 <= spec.link <= c.links:
        raise c.fail(P + ("link",), f"contact on link {spec.link}, but the robot has {c.links} links "
                                    f"(one per joint)", f"use a link number from 1 to {c.links}")
    val = c.ctx.expr(*P, "point")
    shp = shape_of(val)
    if shp not in ((2,), (3,)):
        raise c.fail(P + ("point",), f"the contact point must have 2 (planar) or 3 (spatial) components, got "
                                     f"shape {shp or 'scalar'}", "write [x(q), y(q)] or [x(q), y(q), z(q)]")
    point = sp.Matrix(val)
    R = None
    if spec.point_in == "link":
        frames = _dh_frames(c.problem)
        if frames is None:
            raise c.fail(P + ("point_in",), "point_in: link needs a robot given by a DH table",
                         "give the point in the base frame")
        p_i, R_i = frames[spec.link - 1]
        if point.rows == 2:
            point = point.col_join(sp.Matrix([0]))
        point = (p_i + R_i * point).applyfunc(tidy)
        R = R_i
    m = point.rows
    later = [x for x in c.q if x not in c.q[:spec.link]]
    moving = sorted((point.free_symbols & set(later)), key=lambda s: s.name)
    if moving:
        raise c.fail(P + ("point",), f"a point of link {spec.link} moves only with the joints before it, but this "
                                     f"point depends on {', '.join(s.name for s in moving)}",
                     "check the link number or the point's expression")
    if point.free_symbols & set(c.dq):
        raise c.fail(P + ("point",), "the contact point must not depend on the velocities")
    location = None
    if spec.location is not None:
        location = c.problem.symbols.get(spec.location)
        if location is None or location not in point.free_symbols:
            raise c.fail(P + ("location",), f"location: '{spec.location}' must be a declared symbol appearing in the "
                                            f"contact point", "e.g. location: rho3 with point: [q1 + rho3*cos(q3), ...]")
    if spec.angle is not None and spec.rotation is not None:
        raise c.fail(P + ("rotation",), "give only one of angle: (planar) and rotation: (spatial)")
    if spec.angle is not None:
        a = c.ctx.expr(*P, "angle")
        if isinstance(a, list):
            raise c.fail(P + ("angle",), "angle must be one expression (the link's orientation in the plane)")
        R = sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]])
        if m == 3:
            R = sp.diag(R, 1)
    elif spec.rotation is not None:
        val = c.ctx.expr(*P, "rotation")
        if shape_of(val) != (3, 3):
            raise c.fail(P + ("rotation",), f"rotation must be a 3x3 matrix, got shape {shape_of(val)}")
        R = sp.Matrix(val)
    elif R is None:
        body = c.robot.bodies[spec.link - 1] if len(c.robot.bodies) >= spec.link else None
        if body is not None and body.rotation is not None:
            R = body.rotation
    if R is not None and m == 2:
        if R.shape == (3, 3):
            if any(not zero_or_simplified(x) for x in (R[2, 0], R[2, 1], R[0, 2], R[1, 2])):
                R = None  # not a rotation in the plane of motion: no planar link frame
            else:
                R = R[:2, :2]
    if spec.force is not None:
        F = c.vector(P + ("force",), m, "the contact force")
        given = True
    else:
        names = ("Fx", "Fy", "Fz")[:m]
        F = sp.Matrix([c.symbol(s, f"F_{{{s[1]}}}") for s in names])
        given = False
    if spec.residual is not None and spec.torque is not None:
        raise c.fail(P + ("torque",), "give either residual: or torque: (the data F is estimated from), not both")
    label = spec.name or f"contact {k + 1} on link {spec.link}"
    return ContactCase(k + 1, label, spec.link, tidy_matrix(point), m, F, given, location,
                       R.applyfunc(tidy) if R is not None else None)


def _analyze(c: _Ctx, cc: ContactCase, r: sp.Matrix, K: sp.Matrix, dm: DynamicModel | None) -> None:
    """Symbolic structure of a contact: J_c, τ_c = J_cᵀ F, detection, isolation, identification."""
    q, n, i, m = c.q, c.n, cc.link, cc.m
    Jc = contact_jacobian(cc.point, q)
    cc.Jc = Jc
    d = cc.data
    d["Jc"] = Jc
    d["JcT"] = Jc.T
    d["local"] = (cc.R.T * Jc).applyfunc(tidy) if cc.R is not None else None
    d["rank"] = rank = generic_rank(Jc)
    d["null"] = null_basis(Jc.T, rank)
    fsyms = sorted(cc.F.free_symbols, key=lambda s: s.name)
    d["tau"] = tau = (Jc.T * cc.F).applyfunc(lambda x: collect_linear(x, fsyms))
    d["rdot_tc"] = (K * tau).applyfunc(lambda x: collect_linear(x, fsyms))
    d["v"] = v = (Jc * sp.Matrix(c.dq)).applyfunc(lambda x: collect_linear(x, list(c.dq)))
    d["power"] = collect_linear((v.T * cc.F)[0], fsyms)
    d["minors"] = []
    if m == 2 and i >= 3 and rank == 2:
        J = d["local"] if d["local"] is not None else Jc
        d["minors"] = [((a + 1, b + 1), tidy(J[0, a] * J[1, b] - J[0, b] * J[1, a]))
                       for a, b in combinations(range(i), 2)]
        d["minors"] = [x for x in d["minors"] if x[1] != 0]
    d["zero_cols"] = list(range(i + 1, n + 1))
    nonzero = [j + 1 for j in range(n) if not zero_or_simplified(tau[j])]
    d["detected"] = bool(nonzero)
    d["isolated"] = max(nonzero) if nonzero else 0
    col = Jc[:, i - 1]
    d["col"] = col
    d["col_zero"] = all(zero_or_simplified(x) for x in col)
    d["misisolated"] = [] if (d["col_zero"] or i == 1) else null_basis(col.T, 1)
    d["identifiable"] = rank == m
    d["det"] = tidy(Jc.det()) if Jc.rows == Jc.cols else None
    d["gram"] = tidy((Jc * Jc.T).det()) if Jc.rows < Jc.cols and m <= 3 else None
    dg = d["det"] if d["det"] is not None else d["gram"]
    d["never_singular"] = dg is not None and not (dg.free_symbols & set(q)) and bool(dg.is_nonzero)
    # identification from r (steady state: r = τ_ext = J_cᵀ F)
    d["F_id"] = d["F_id_local"] = d["loc_id"] = None
    d["loc_rank"] = None
    if cc.location is not None:
        Fsym = sp.Matrix([c.symbol(s, f"F_{{{s[1]}}}") for s in ("Fx", "Fy", "Fz")[:m]])
        JF = (Jc.T * Fsym)[:i, 0]
        jac = sp.Matrix(JF).jacobian(list(Fsym) + [cc.location]) if i else sp.zeros(0, m + 1)
        d["loc_rank"] = lr = generic_rank(jac) if i else 0
        if lr == m + 1:
            sol = identify_with_location(cc.point, q, Fsym, cc.location, r, i)
            if sol is not None:
                d["F_id"], d["loc_id"] = sol
    d["too_big"] = sp.count_ops(Jc) > SYMBOLIC_OPS
    if d["F_id"] is None and rank > 0 and not d["too_big"]:
        est = estimate_symbolic(Jc.T, r, rank)
        if est is not None:
            N, D = est
            d["F_id"] = N.applyfunc(lambda x: _quotient(x, D))
            if cc.R is not None:
                d["F_id_local"] = (cc.R.T * N).applyfunc(lambda x: _quotient(tidy(x), D))
    elif d["F_id"] is not None and cc.R is not None:
        d["F_id_local"] = (cc.R.T * d["F_id"]).applyfunc(lambda x: _tidy_quotient(_factored(x)))
    if dm is not None and dm.G is None and cc.force_given:
        fric = dm.Fv * sp.Matrix(c.dq) if dm.Fv is not None else sp.zeros(n, 1)
        d["u_hold"] = tidy_matrix(dm.c + dm.g + fric - tau)
    else:
        d["u_hold"] = None


def _torque_law(c: _Ctx, cc: ContactCase, spec: Contact, dm: DynamicModel | None, subs: dict) -> sp.Matrix:
    """The motor torque u of a torque: entry, evaluated at the state."""
    P = ("contacts", cc.index - 1, "torque")
    t = spec.torque
    n = c.n
    if not isinstance(t, TorqueLaw):
        return c.vector(P, n, "torque").subs(subs).applyfunc(_decimal)
    u = sp.zeros(n, 1)
    if t.joint is not None:
        u += c.vector(P + ("joint",), n, "torque.joint")
    if t.gravity:
        if dm is None:
            raise c.fail(P + ("gravity",), "gravity: true needs the robot's dynamic model (masses and gravity)")
        u += dm.g
    for j, term in enumerate(t.cartesian):
        pt = c.vector(P + ("cartesian", j, "point"), (2, 3), "the point of a Cartesian law")
        Fl = c.vector(P + ("cartesian", j, "force"), pt.rows, "the force of a Cartesian law")
        u += pt.jacobian(c.q).T * Fl
    return u.subs(subs)


def _numbers(c: _Ctx, cc: ContactCase, spec: Contact, K: sp.Matrix, kE: sp.Expr | None, dm: DynamicModel | None,
             state: dict, values: dict) -> None:
    """Values at the at: state, and the estimate of F when the residual or the balancing torque is given."""
    d = cc.data
    subs = {**values, **state}
    at: dict[str, Any] = {}
    Jn = _num_matrix(d["Jc"].subs(subs))
    at["Jc"] = Jn
    at["p"] = _num_matrix(cc.point.subs(subs))
    if d["local"] is not None:
        at["local"] = _num_matrix(d["local"].subs(subs))
    numeric = all(x.is_number for x in Jn)
    at["rank"] = numeric_rank(Jn) if numeric else None
    if numeric and at["rank"] is not None and at["rank"] < cc.m:
        at["null"] = [_num_matrix(v) for v in null_basis(Jn.T, at["rank"])]
    at["J_numeric"] = not Jn.free_symbols
    at["has_dq"] = all(v in state for v in c.dq)
    if at["has_dq"]:
        at["v"] = _num_matrix(d["v"].subs(subs))
    if cc.force_given:
        at["tau"] = _num_matrix(d["tau"].subs(subs))
        at["rdot_tc"] = _num_matrix(d["rdot_tc"].subs(subs))
        tau_num = at["tau"]
        if all(x.is_number for x in tau_num):
            nz = [j + 1 for j in range(c.n) if abs(complex(tau_num[j])) > 1e-12]
            at["detected"] = bool(nz)
            at["isolated"] = max(nz) if nz else 0
        if at["has_dq"]:
            at["power"] = _num(d["power"].subs(subs))
            if kE is not None:
                at["sdot_tc"] = _num(kE.subs(subs) * at["power"])
            if at["power"].is_number:
                at["detected_energy"] = abs(complex(at["power"])) > 1e-12
    if d["u_hold"] is not None:
        at["u_hold"] = _num_matrix(d["u_hold"].subs(subs))
    # estimation
    P = ("contacts", cc.index - 1)
    text = None
    if spec.residual is not None:
        text = c.vector(P + ("residual",), c.n, "the residual").subs(subs).applyfunc(_decimal)
        at["source"] = "residual"
    elif spec.torque is not None:
        if any(not zero_or_simplified(state.get(v, 0)) for v in c.dq):
            raise c.fail(P + ("torque",), "torque: describes a static equilibrium, but the at: state has a non-zero "
                                          "velocity", "give residual: (the residual's value) instead")
        u = _torque_law(c, cc, spec, dm, subs)
        g = dm.g.subs(subs) if dm is not None else sp.zeros(c.n, 1)
        if dm is None and c.robot.gravity is not None:
            raise c.fail(P + ("torque",), "the robot is under gravity but has no masses: g(q) is unknown",
                         "add the links' masses (or model: {g: ...})")
        at["u_eq"] = _num_matrix(u)
        at["g"] = _num_matrix(g)
        text = g - u
        at["source"] = "torque"
    if text is not None:
        text = _num_matrix(text)
        if any(x.free_symbols for x in text):
            raise c.fail(P + (at["source"],), "the residual/torque must be numeric at the at: state",
                         "give every coordinate in at: and numeric values of the parameters")
        at["tau_ext"] = text
        nz = [j + 1 for j in range(c.n) if abs(complex(text[j])) > 1e-9 * max(1.0, max(abs(complex(x)) for x in text))]
        at["isolated_data"] = max(nz) if nz else 0
        loc = cc.location
        loc_known = loc is None or loc in values
        Jsub = d["Jc"].subs(subs)
        if not loc_known and d.get("loc_rank") == cc.m + 1:
            est = _estimate_with_location(cc.point, c.q, subs, text, loc, cc.m, cc.link)
            if est is not None:
                at["F_hat"], at["loc_hat"] = est
                Jsub = Jsub.subs(loc, at["loc_hat"])
        if "F_hat" not in at:
            if Jsub.free_symbols:
                at["unknown_location"] = sorted(Jsub.free_symbols, key=lambda s: s.name)
            else:
                Jn2 = _num_matrix(Jsub)
                at["F_hat"] = _num_matrix(numeric_pinv(Jn2.T) * text)
        if "F_hat" in at:
            Jn2 = _num_matrix(Jsub)
            at["Jc_used"] = Jn2
            at["residual_error"] = _num_matrix(Jn2.T * at["F_hat"] - text)
            at["consistent"] = all(abs(complex(x)) < 1e-6 * max(1.0, float(max(abs(complex(y)) for y in text)))
                                   for x in at["residual_error"])
            at["rank_used"] = numeric_rank(Jn2)
            if "loc_hat" in at:
                at["Jc_hat"] = Jn2
            at["F_norm"] = _num(sp.sqrt(sum(x ** 2 for x in at["F_hat"])))
            if cc.R is not None:
                Rn = _num_matrix(cc.R.subs(subs))
                if not Rn.free_symbols:
                    at["F_hat_local"] = _num_matrix(Rn.T * at["F_hat"])
    at["show"] = {k: _display(v) for k, v in at.items() if isinstance(v, (sp.MatrixBase, sp.Expr))}
    d["at"] = at


def _estimate_with_location(point: sp.Matrix, q: list[sp.Symbol], subs: dict, tau: sp.Matrix, loc: sp.Symbol,
                            m: int, link: int) -> tuple[sp.Matrix, sp.Expr] | None:
    """Numeric (F, ρ) with J_c(ρ)ᵀ F = τ_ext for a point affine in ρ (J_c = J_a + ρ J_b): F by least squares from
    the ρ-free combinations of the first ``link`` equations (the null space of J_b), then ρ by least squares."""
    if any(not zero_or_simplified(x) for x in point.diff(loc, 2)):
        return None
    b = point.diff(loc)
    a = point - loc * b
    Ja = np.array(a.jacobian(q)[:, :link].subs(subs).evalf(30).tolist(), dtype=float).reshape(m, link)
    Jb = np.array(b.jacobian(q)[:, :link].subs(subs).evalf(30).tolist(), dtype=float).reshape(m, link)
    t = np.array([float(x) for x in tau[:link, 0]])
    u, sv, vt = np.linalg.svd(Jb)
    rank = int(np.sum(sv > 1e-9 * max(1.0, sv[0] if sv.size else 1.0)))
    C = vt[rank:]  # rows c with J_b c = 0
    if C.shape[0] < m:
        return None
    A = C @ Ja.T
    if np.linalg.matrix_rank(A, tol=1e-9) < m:
        return None
    F = np.linalg.lstsq(A, C @ t, rcond=None)[0]
    w = Jb.T @ F
    if np.max(np.abs(w)) < 1e-12:
        return None
    rho = float(w @ (t - Ja.T @ F) / (w @ w))
    return sp.Matrix([sp.Float(x, 15) for x in F]), sp.Float(rho, 15)


def validate_collision(problem, options: CollisionAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_collision` reads them (gains, state, each contact), without
    the model (whether the residuals can be given is decided when solving)."""
    c = _Ctx(problem, options, ctx)
    if len(options.contacts) > MAX_CONTACTS:
        raise c.fail(("contacts",), f"at most {MAX_CONTACTS} contacts per ask")
    c.gains()
    for i in range(c.n):
        c.symbol(f"r{i + 1}", f"r_{{{i + 1}}}")
        c.symbol(f"tau_ext{i + 1}", f"\\tau_{{ext,{i + 1}}}")
    if "energy" in (options.residuals if options.residuals is not None else ["energy"]):
        c.gain_energy()
    state = c.state()
    for k, spec in enumerate(options.contacts):
        _contact(c, k, spec)
        if spec.torque is not None and not state:
            raise c.fail(("contacts", k, "torque"), "torque: needs the at: configuration of the equilibrium")
        if spec.residual is not None and not state:
            raise c.fail(("contacts", k, "residual"), "residual: needs the at: configuration")


@ask_kind("collision", CollisionAsk, "collision detection and isolation: momentum and energy residuals, contact "
                                     "Jacobians, identification of the contact force", validate=validate_collision)
def solve_collision(problem, options: CollisionAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: momentum, STdq, residual_integrand, pdot, rdot, rdot_check; energy, energy_integrand, rdot_energy,
    energy_check; per contact k: Jc_k, Jc_local_k, rank_Jc_k, det_Jc_k, null_JcT_k, tau_c_k, rdot_tc_k, v_c_k,
    power_k, detected_k, isolated_link_k, F_misisolated_k, identifiable_k, F_id_k, F_id_local_k, location_id_k,
    u_hold_k; at a state: *_at_k, tau_ext_k, r_ss_k, u_eq_k, F_hat_k, F_hat_local_k, F_hat_norm_k, location_hat_k."""
    c = _Ctx(problem, options, ctx)
    robot = c.robot
    dm = derive(robot) if has_model(robot) else None
    if dm is not None and all(x == 0 for x in dm.B):
        dm = None  # massless links: a kinematic description only
    model_ok = dm is not None
    wanted = options.residuals
    if wanted is None:
        wanted = ["momentum", "energy"] if model_ok else []
    if wanted and not model_ok:
        raise c.fail(("residuals",), "the residuals need the robot's dynamic model, but the robot has no bodies "
                                     "and no model", "add links: (with masses), dh: or model: {B: ...}")
    if options.simulate is not None and not model_ok:
        raise c.fail(("simulate",), "a simulation needs the robot's dynamic model (masses)")
    if len(options.contacts) > MAX_CONTACTS:
        raise c.fail(("contacts",), f"at most {MAX_CONTACTS} contacts per ask")
    if "momentum" in wanted and dm is not None and dm.S is None:
        raise UserError("the momentum residual needs the factorization S(q, q̇) from the Christoffel symbols, but "
                        "the model gives c(q, q̇) directly", problem.located.place(("robot", "model", "c")),
                        "give B (and U or g) and let robosolve derive c and S")
    if "energy" in wanted and dm is not None and dm.U is None:
        raise c.fail(("residuals",), "the energy residual needs the potential energy U(q), but the model gives g(q) "
                                     "directly", "give model: {U: ...} instead of g, or drop energy from residuals:")
    sol = Solution("collision", title=options.title or "Collision detection and isolation")
    n = c.n
    K = c.gains()
    r = sp.Matrix([c.symbol(f"r{i + 1}", f"r_{{{i + 1}}}") for i in range(n)])
    tau = sp.Matrix([c.symbol(f"tau_ext{i + 1}", f"\\tau_{{ext,{i + 1}}}") for i in range(n)])
    kE = c.gain_energy() if "energy" in wanted else None
    state = c.state()
    values = problem.values

    mr = er = None
    if "momentum" in wanted and dm is not None:
        mr = momentum_residual(dm, c.q, c.dq, K, r, tau)
        sol.add("momentum", mr.p, "vector", label="p = B(q)\\dot q")
        sol.add("STdq", mr.STdq, "vector", label="S^T(q,\\dot q)\\dot q")
        sol.add("residual_integrand", mr.integrand, "vector", label="u + S^T\\dot q - g")
        sol.add("pdot", mr.pdot, "vector", label="\\dot p")
        sol.add("rdot", mr.rdot, "vector", label="\\dot r")
        sol.add("rdot_check", mr.check, "bool", label="\\dot p = u + S^T\\dot q - g + \\tau_{ext}")
        v = sp.Matrix(c.dq)
        fric = dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1)
        Gu = generalized_input(dm)
        rows = [[x for x in (Gu[i], mr.STdq[i], -dm.g[i], -tidy(fric[i])) if x != 0] for i in range(n)]
        sol.step("momentum", mr=mr, dm=dm, robot=robot, n=n, rows=rows,
                 Kdiag=[K[i, i] for i in range(n)] if K.is_diagonal() else None)
    if "energy" in wanted and dm is not None and kE is not None:
        sigma = c.symbol("sigma", "\\sigma")
        er = energy_residual(dm, c.q, c.dq, kE, sigma, tau)
        sol.add("energy", er.E, "scalar", label="E = T + U")
        sol.add("energy_integrand", er.integrand, "scalar", label="\\dot q^T u")
        sol.add("rdot_energy", er.sdot, "scalar", label="\\dot\\sigma")
        sol.add("energy_check", er.check, "bool", label="\\dot E = \\dot q^T (u + \\tau_{ext})")
        v = sp.Matrix(c.dq)
        fric = dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1)
        Gu = generalized_input(dm)
        power = [sp.Mul(c.dq[j], sp.Add(Gu[j], -fric[j], tau[j]), evaluate=False) for j in range(n)]
        sol.step("energy", er=er, dm=dm, n=n, T2=velocity_terms(2 * dm.T, c.dq), U=dm.U, power=power)
    if mr is not None and state:
        subs = {**values, **state}
        at = {"p": _num_matrix(mr.p.subs(subs)), "STdq": _num_matrix(mr.STdq.subs(subs)),
              "beta": _num_matrix(mr.integrand.subs(subs))}
        sol.add("momentum_at", at["p"], "vector", label="p\\big|_{*}")
        sol.add("STdq_at", at["STdq"], "vector", label="S^T\\dot q\\big|_{*}")
        sol.add("residual_integrand_at", at["beta"], "vector", label="(u + S^T\\dot q - g)\\big|_{*}")
        sol.step("momentum_at", state=state, at=at)

    if dm is None and options.contacts:
        sol.step("generic")
    cases = []
    for k, spec in enumerate(options.contacts):
        cc = _contact(c, k, spec)
        _analyze(c, cc, r, K, dm)
        if state or spec.residual is not None or spec.torque is not None:
            if spec.torque is not None and not state:
                raise c.fail(("contacts", k, "torque"), "torque: needs the at: configuration of the equilibrium")
            if spec.residual is not None and not state:
                raise c.fail(("contacts", k, "residual"), "residual: needs the at: configuration")
            _numbers(c, cc, spec, K, kE, dm, state, values)
        _add_contact_results(sol, cc)
        sol.step("contact", cc=cc, d=cc.data, n=n, q=c.q, r=r, K=K, kE=kE,
                 momentum=mr is not None or dm is None, energy=er is not None or dm is None, state=state,
                 friction=dm is not None and dm.Fv is not None)
        cases.append(cc)

    if options.simulate is not None:
        _add_simulation(sol, c, options.simulate, dm, cases, K, kE, state)
    return sol


def _add_contact_results(sol: Solution, cc: ContactCase) -> None:
    d, k = cc.data, f"_{cc.index}"
    sol.add("Jc" + k, d["Jc"], "matrix", label=f"J_{{c}}(q)\\ ({cc.index})")
    if d["local"] is not None:
        sol.add("Jc_local" + k, d["local"], "matrix", label=f"{{}}^{{{cc.link}}}J_{{c}}(q)")
    sol.add("rank_Jc" + k, sp.Integer(d["rank"]), "number", label="\\operatorname{rank} J_c")
    if d["det"] is not None:
        sol.add("det_Jc" + k, d["det"], "scalar", label="\\det J_c")
    if d["null"]:
        sol.add("null_JcT" + k, sp.Matrix.hstack(*d["null"]), "matrix", label="\\mathcal{N}(J_c^T)")
    sol.add("tau_c" + k, d["tau"], "vector", label="\\tau_c = J_c^T F")
    sol.add("rdot_tc" + k, d["rdot_tc"], "vector", label="\\dot r(t_c)")
    sol.add("v_c" + k, d["v"], "vector", label="v_c = J_c\\dot q")
    sol.add("power" + k, d["power"], "scalar", label="v_c^T F")
    sol.add("detected" + k, d["detected"], "bool", label="\\text{detected}")
    sol.add("isolated_link" + k, sp.Integer(d["isolated"]), "number", label="\\text{isolated link}")
    if d["misisolated"]:
        sol.add("F_misisolated" + k, sp.Matrix.hstack(*d["misisolated"]), "matrix",
                label="F \\text{ with } r_i = 0")
    sol.add("identifiable" + k, d["identifiable"], "bool", label="F \\text{ identifiable}")
    if d["F_id"] is not None:
        sol.add("F_id" + k, d["F_id"], "vector", label="\\hat F(r)")
    if d["F_id_local"] is not None:
        sol.add("F_id_local" + k, d["F_id_local"], "vector", label=f"{{}}^{{{cc.link}}}\\hat F(r)")
    if d["loc_id"] is not None:
        sol.add("location_id" + k, d["loc_id"], "scalar", label="\\hat\\rho(r)")
    if d["u_hold"] is not None:
        sol.add("u_hold" + k, d["u_hold"], "vector", label="u \\text{ with } \\ddot q = 0")
    at = d.get("at")
    if not at:
        return
    for key, name, kind in (("p", "p_c_at", "vector"), ("Jc", "Jc_at", "matrix"), ("local", "Jc_local_at", "matrix"),
                            ("tau", "tau_c_at", "vector"), ("rdot_tc", "rdot_tc_at", "vector"),
                            ("v", "v_c_at", "vector"), ("power", "power_at", "number"),
                            ("sdot_tc", "rdot_energy_tc_at", "number"), ("u_hold", "u_hold_at", "vector"),
                            ("u_eq", "u_eq", "vector"), ("tau_ext", "tau_ext", "vector"),
                            ("F_hat", "F_hat", "vector"), ("F_hat_local", "F_hat_local", "vector"),
                            ("F_norm", "F_hat_norm", "number"), ("loc_hat", "location_hat", "number"),
                            ("Jc_hat", "Jc_hat", "matrix")):
        if at.get(key) is not None:
            sol.add(name + k, at[key], kind, label=name.replace("_", "\\_"))
    if at.get("tau_ext") is not None:
        sol.add("r_ss" + k, at["tau_ext"], "vector", label="r_\\infty")
    if at.get("rank") is not None:
        sol.add("rank_Jc_at" + k, sp.Integer(at["rank"]), "number", label="\\operatorname{rank} J_c\\big|_{*}")
    if at.get("null"):
        sol.add("null_JcT_at" + k, sp.Matrix.hstack(*at["null"]), "matrix", label="\\mathcal{N}(J_c^T)\\big|_{*}")
    if "isolated_data" in at:
        sol.add("isolated_link_data" + k, sp.Integer(at["isolated_data"]), "number",
                label="\\text{link from the data}")
    for key in ("detected", "isolated", "detected_energy"):
        if key in at:
            name = {"detected": "detected_at", "isolated": "isolated_link_at",
                    "detected_energy": "detected_energy_at"}[key]
            val = sp.Integer(at[key]) if key == "isolated" else bool(at[key])
            sol.add(name + k, val, "number" if key == "isolated" else "bool", label=name.replace("_", "\\_"))


def _numeric_list(c: _Ctx, sub: tuple, raw: list | None, n: int, default: np.ndarray) -> np.ndarray:
    if raw is None:
        return default
    vals = c.ctx.expr(*sub)
    if not isinstance(vals, list) or len(vals) != n or any(isinstance(v, list) for v in vals):
        raise c.fail(sub, f"{sub[-1]} must be a list of {n} numbers")
    out = []
    for v in vals:
        v = v.subs(c.problem.values)
        if v.free_symbols:
            raise c.fail(sub, f"{sub[-1]} must be numeric (or parameters with values)")
        out.append(float(v))
    return np.array(out)


def _add_simulation(sol: Solution, c: _Ctx, sim: Simulation, dm: DynamicModel | None, cases: list[ContactCase],
                    K: sp.Matrix, kE: sp.Expr | None, state: dict) -> None:
    """The figure of a simulated collision (sampled when drawn) and a step describing it."""
    S = ("simulate",)
    if dm is None:
        raise c.fail(S, "a simulation needs the robot's dynamic model")
    if not 1 <= sim.contact <= len(cases):
        raise c.fail(S + ("contact",), f"simulate.contact must be the index of one of the {len(cases)} contacts",
                     "add a contact under contacts: first" if not cases else None)
    cc = cases[sim.contact - 1]
    values = c.problem.values
    if sim.force is not None:
        Fv = c.vector(S + ("force",), cc.m, "simulate.force")
    elif cc.force_given:
        Fv = cc.F
    else:
        raise c.fail(S + ("force",), "the simulation needs a numeric force: give simulate.force or the contact's "
                                     "force:")
    Fv = Fv.subs(values)
    if Fv.free_symbols:
        raise c.fail(S + ("force",), "the simulated force must be numeric (parameters need values)")
    end = sim.end if sim.end is not None else sim.start + 1.0
    if not 0 <= sim.start < end or sim.duration <= 0:
        raise c.fail(S, "need 0 <= start < end and duration > 0")
    n = c.n
    Kd = np.array([float(K[i, i].subs(values)) if not K[i, i].subs(values).free_symbols else np.nan
                   for i in range(n)])
    if sim.gain is not None:
        g = sim.gain if isinstance(sim.gain, list) else [sim.gain] * n
        if len(g) != n:
            raise c.fail(S + ("gain",), f"simulate.gain must be a number or a list of {n}")
        Kd = np.array(g, dtype=float)
    elif np.isnan(Kd).any():
        Kd = np.full(n, 20.0)
    if sim.gain_energy is not None:
        kEn: float | None = float(sim.gain_energy)
    elif kE is not None and not kE.subs(values).free_symbols:
        kEn = float(kE.subs(values))
    else:
        kEn = 20.0 if dm.U is not None else None
    q0d = np.array([float(state.get(x, 0).subs(values)) if hasattr(state.get(x, 0), "subs") else 0.0
                    for x in c.q]) if state else np.zeros(n)
    dq0d = np.array([float(state.get(x, 0).subs(values)) if hasattr(state.get(x, 0), "subs") else 0.0
                     for x in c.dq]) if state else np.zeros(n)
    q0 = _numeric_list(c, S + ("q0",), sim.q0, n, q0d)
    dq0 = _numeric_list(c, S + ("dq0",), sim.dq0, n, dq0d)
    F = np.array([float(x) for x in Fv])
    point = cc.point.subs({cc.location: values.get(cc.location, 1)} if cc.location is not None else {})
    names = c.problem.latex_names

    def sample() -> list[Panel]:
        data = simulate_collision(dm, c.q, c.dq, point, values, F, sim.start, end, sim.duration, Kd, kEn, q0, dq0,
                                  sim.control, sim.kp, sim.kd, sim.profile)
        t = [float(x) for x in data.t]
        scale = max(1.0, float(np.max(np.abs(data.tau_ext))) if data.tau_ext.size else 1.0)
        for arr in (data.r, data.tau_ext):  # integration noise far below the signal plotted as the zero it is
            arr[np.abs(arr) < 1e-8 * scale] = 0.0
        if data.sigma is not None:
            for arr in (data.sigma, data.power):
                arr[np.abs(arr) < 1e-8 * max(1.0, float(np.max(np.abs(data.power))))] = 0.0
        panels = []
        for j in range(n):
            panels.append(Panel("$t$ [s]", f"joint {j + 1}", [
                Curve(f"$r_{{{j + 1}}}$", t, [float(x) for x in data.r[:, j]]),
                Curve(f"$\\tau_{{ext,{j + 1}}} = (J_c^T F)_{{{j + 1}}}$", t, [float(x) for x in data.tau_ext[:, j]])]))
        if data.sigma is not None:
            panels.append(Panel("$t$ [s]", "energy residual", [
                Curve("$\\sigma$", t, [float(x) for x in data.sigma]),
                Curve("$\\dot q^T \\tau_{ext}$", t, [float(x) for x in data.power])]))
        return panels

    params = sorted({s for M in (dm.B, dm.g, cc.point) for x in M for s in x.free_symbols} - set(c.q) - set(c.dq)
                    - set(values), key=lambda s: s.name)
    unit_tex = ", ".join(f"${names.get(s, sp.latex(s))}$" for s in params)
    ctrl = {"pd": f"$u = g(q) + {sim.kp:g}\\,(q_0 - q) - {sim.kd:g}\\,\\dot q$",
            "gravity": "$u = g(q)$", "none": "$u = 0$"}[sim.control]
    caption = (f"Simulated collision on link {cc.link} ({cc.label}): residual components $r_j$ against the true "
               f"$\\tau_{{ext}} = J_c^T F$" + (" and the energy residual $\\sigma$" if kEn is not None else "")
               + f"; {sim.profile} force from $t = {sim.start:g}$ to ${end:g}$ s, {ctrl}."
               + (f" Parameters without a value set to 1 ({unit_tex})." if params else ""))
    sol.figures.append(Figure("residuals", caption, sample))
    sol.step("simulation", cc=cc, F=sp.Matrix(F.tolist()), start=sim.start, end=end, duration=sim.duration,
             profile=sim.profile, K=[float(x) for x in Kd], kE=kEn, q0=sp.Matrix(q0.tolist()),
             dq0=sp.Matrix(dq0.tolist()), control=sim.control, kp=sim.kp, kd=sim.kd, unit=params)


# ------------------------------------------------------------------------------------------------ grading
def _tau_ext_symbols(problem, n: int) -> list[sp.Symbol]:  # type: ignore[no-untyped-def]
    return [problem.names.get(f"tau_ext{i + 1}", sp.Symbol(f"tau_ext{i + 1}", real=True)) for i in range(n)]


@property_check("residual_integrand")
def check_residual_integrand(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """A residual r = K_I (m − ∫(β + r)) is right when its dynamics are: with the student's momentum m (their
    `momentum` answer, else B q̇), ṁ − β ≡ τ_ext along the model, i.e. ṙ = K_I (τ_ext − r)."""
    from solver.math.equivalence import scalar_equiv
    robot, ref = problem.robot, results.get(name)
    if robot is None or ref is None or not isinstance(value, list):
        return None
    try:
        beta = sp.Matrix(value)
    except (ValueError, TypeError):
        return None
    n = robot.n
    if beta.shape != (n, 1) and beta.shape != (1, n):
        return None
    beta = beta.reshape(n, 1)
    dm = derive(robot)
    mom = other("momentum")
    m = sp.Matrix(mom).reshape(n, 1) if isinstance(mom, list) and len(sp.Matrix(mom)) == n else None
    v = sp.Matrix(robot.dq)
    if m is None:
        m = dm.B * v
    if any(not scalar_equiv(x, 0).ok for x in (m.jacobian(robot.dq) - dm.B)):
        return None  # not of the form B q̇ + h(q): compare with the reference
    tau = sp.Matrix(_tau_ext_symbols(problem, n))
    fric = dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1)
    mdot = m.jacobian(robot.q) * v + generalized_input(dm) + tau - dm.c - dm.g - fric
    bad = [i + 1 for i, x in enumerate(mdot - beta - tau) if not scalar_equiv(x, 0).ok]
    if not bad:
        return PropertyVerdict(True, 1.0, ["the residual's dynamics are ṙ = K_I(τ_ext − r): the integrand is right"])
    return PropertyVerdict(False, 0.0, [f"with this integrand ṙ ≠ K_I(τ_ext − r) in component(s) "
                                        f"{', '.join(map(str, bad))} (check Sᵀq̇ — S from the Christoffel symbols — "
                                        f"and the sign of g)"], final=False)


@property_check("energy_integrand")
def check_energy_integrand(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """σ = k_E (E − ∫(β_E + σ)) is right when Ė − β_E ≡ q̇ᵀ τ_ext along the model (E = T + U up to a constant)."""
    from solver.math.equivalence import scalar_equiv
    robot, ref = problem.robot, results.get(name)
    if robot is None or ref is None or isinstance(value, list):
        return None
    n = robot.n
    dm = derive(robot)
    if dm.U is None:
        return None
    v = sp.Matrix(robot.dq)
    tau = sp.Matrix(_tau_ext_symbols(problem, n))
    fric = dm.Fv * v if dm.Fv is not None else sp.zeros(n, 1)
    Edot = (v.T * (generalized_input(dm) + tau - fric))[0]
    if scalar_equiv(Edot - value - (v.T * tau)[0], 0).ok:
        return PropertyVerdict(True, 1.0, ["σ̇ = k_E(q̇ᵀτ_ext − σ): the integrand is right"])
    return PropertyVerdict(False, 0.0, ["with this integrand σ̇ ≠ k_E(q̇ᵀτ_ext − σ) (the power of the motors is "
                                        "q̇ᵀu, minus the friction losses q̇ᵀF_v q̇)"], final=False)


def _null_check(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Undetectable forces: any basis of N(J_cᵀ) (columns), with as many vectors as the reference."""
    from solver.math.equivalence import scalar_equiv
    k = name.rsplit("_", 1)[-1]
    J = results.get("Jc_" + k) if "_at_" not in name else results.get("Jc_at_" + k)
    ref = results.get(name)
    if J is None or ref is None or not isinstance(value, list):
        return None
    try:
        N = sp.Matrix(value)
    except (ValueError, TypeError):
        return None
    m = J.value.rows
    if N.rows != m and N.cols == m:
        N = N.T
    if N.rows != m:
        return None
    dim = ref.value.cols
    if any(not scalar_equiv(x, 0).ok for x in J.value.T * N):
        return PropertyVerdict(False, 0.0, ["a vector of the answer is not in the null space of J_cᵀ "
                                            "(J_cᵀ F ≠ 0: that force would be detected)"], final=False)
    if N.cols != dim or generic_rank(N) != dim:
        return PropertyVerdict(False, 0.5, [f"the null space of J_cᵀ has dimension {dim}: give {dim} independent "
                                            f"vector(s)"])
    return PropertyVerdict(True, 1.0, ["a basis of N(J_cᵀ): these forces are not detected"])


def _misisolated_check(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Forces isolated on an earlier link: F ≠ 0 orthogonal to the column of J_c of the contact's link."""
    from solver.math.equivalence import scalar_equiv
    ref = results.get(name)
    k = name.rsplit("_", 1)[-1]
    J = results.get("Jc_" + k)
    if ref is None or J is None or not isinstance(value, list):
        return None
    try:
        N = sp.Matrix(value)
    except (ValueError, TypeError):
        return None
    m = J.value.rows
    N = N.T if (N.rows != m and N.cols == m) else N
    if N.rows != m or all(scalar_equiv(x, 0).ok for x in N):
        return None
    cols = [j for j in range(J.value.cols) if not all(scalar_equiv(x, 0).ok for x in J.value[:, j])]
    if not cols:
        return None
    col = J.value[:, max(cols)]
    ok = all(scalar_equiv(x, 0).ok for x in col.T * N)
    if ok:
        return PropertyVerdict(True, 1.0, ["orthogonal to the last column of J_c: r_i = 0, the residual points at "
                                           "an earlier link"])
    return PropertyVerdict(False, 0.0, ["not orthogonal to the last non-zero column of J_c: such a force does "
                                        "affect r_i"], final=False)


def _estimate_check(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """An estimate F̂ consistent with the data (J_cᵀ F̂ = τ_ext) but not the minimum-norm one: half the points."""
    from solver.math.equivalence import scalar_equiv
    k = name.rsplit("_", 1)[-1]
    ref, J, t = results.get(name), results.get("Jc_at_" + k), results.get("tau_ext_" + k)
    if ref is None or J is None or t is None or not isinstance(value, list):
        return None
    try:
        F = sp.Matrix(value).reshape(J.value.rows, 1)
    except (ValueError, TypeError):
        return None
    if all(scalar_equiv(a, b, rel_tol=getattr(options, "rel_tol", 1e-3)).ok for a, b in zip(F, ref.value)):
        return None  # equal to the reference: the usual comparison gives full credit
    Jn = J.value
    if Jn.free_symbols:
        return None
    err = Jn.T * F - t.value
    scale = max(1.0, max(abs(float(x)) for x in t.value))
    if all(abs(float(x)) <= 1e-3 * scale for x in err):
        return PropertyVerdict(True, 0.5, ["consistent with the residual (J_cᵀF = r), but not the minimum-norm "
                                           "estimate (J_cᵀ)^# r: the component in N(J_cᵀ) is arbitrary"])
    return None


property_check(*[f"null_JcT_{k}" for k in range(1, MAX_CONTACTS + 1)],
               *[f"null_JcT_at_{k}" for k in range(1, MAX_CONTACTS + 1)])(_null_check)
property_check(*[f"F_misisolated_{k}" for k in range(1, MAX_CONTACTS + 1)])(_misisolated_check)
property_check(*[f"F_hat_{k}" for k in range(1, MAX_CONTACTS + 1)])(_estimate_check)
