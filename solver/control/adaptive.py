"""The math of the adaptive (Slotine–Li) law beyond the regressor: the split of the model into a known part and an
estimated part (partly adaptive laws) and the Lyapunov function of the closed loop with its derivative.

    model on the reference signals:  B q̈_r + S q̇_r + g (+ F_v q̇_r) = Y_r a = Y_K a_K + Y_U a_U
    partly adaptive law:             u = Y_K a_K + Y_U â_U + K_D s,    â̇_U = Γ Y_Uᵀ s
                                     (Y_K a_K = τ_K: the known part, compensated exactly with its true value)
    closed loop:                     B ṡ + S s (+ F_v s) + K_D s = Y_U ã_U,   ã_U = a_U − â_U,  s = ė + Λ e
    Lyapunov ("slotine_li"):         V = ½ sᵀ B s + ½ ã_Uᵀ Γ⁻¹ ã_U,              V̇ = −sᵀ (K_D + F_v) s
    Lyapunov ("with_e"):             V = ½ sᵀ B s + eᵀ K_D Λ e + ½ ã_Uᵀ Γ⁻¹ ã_U,   V̇ = −ėᵀ K_D ė − eᵀ Λ K_D Λ e − sᵀ F_v s
                                     (K_P = K_D Λ, diagonal gains: the form of u = Y â + K_P e + K_D ė)

V̇ uses ã̇ = −â̇ = −Γ Y_Uᵀ s and the skew-symmetry of Ḃ − 2S. ``lyapunov_derivative_check`` does not assume it: it
differentiates V along the closed loop (every state, the desired signals and the estimates) and compares exactly.
The full law is the case a_K = ∅ (Y_U = Y_r).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from solver.dynamics.model import christoffel, factorization, is_skew_bdot_2s
from solver.math.equivalence import identically_zero as _zero
from solver.math.simplify import tidy


@dataclass
class UnknownPart:
    """The estimated part of the model on the reference signals, Y_U a_U = B_U q̈_r + S_U q̇_r + g_U (+ F_U q̇_r)."""

    B_U: sp.Matrix
    S_U: sp.Matrix
    skew_U: bool | None        # Ḃ_U − 2 S_U skew-symmetric (None when B_U = 0)


def split_columns(Yr: sp.Matrix, a: sp.Matrix, known: list[int]) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix, sp.Matrix]:
    """(Y_U, a_U, Y_K, a_K): the columns and coefficients of the unknown and of the known coefficients (the known
    ones are the indices ``known``), each in the order of a."""
    unk = [j for j in range(Yr.cols) if j not in set(known)]
    kn = [j for j in range(Yr.cols) if j in set(known)]
    pick = lambda M, idx: M.extract(list(range(M.rows)), idx) if idx else sp.zeros(M.rows, 0)  # noqa: E731
    col = lambda idx: sp.Matrix([a[j] for j in idx]) if idx else sp.zeros(0, 1)  # noqa: E731
    return pick(Yr, unk), col(unk), pick(Yr, kn), col(kn)


def unknown_part(YU: sp.Matrix, aU: sp.Matrix, robot, ddqr: list[sp.Symbol]) -> UnknownPart:  # type: ignore[no-untyped-def]
    """B_U = ∂(Y_U a_U)/∂q̈_r and S_U its factorization by the Christoffel symbols (the velocity part of Y_U a_U on
    the reference signals is S_U q̇_r when the coefficients are independent functions of the parameters)."""
    n = robot.n
    v = (YU * aU).applyfunc(sp.expand) if YU.cols else sp.zeros(n, 1)
    BU = v.jacobian(sp.Matrix(ddqr)).applyfunc(tidy)
    if all(x == 0 for x in BU):
        return UnknownPart(BU, sp.zeros(n, n), None)
    SU = factorization(christoffel(BU, list(robot.q)), list(robot.dq))
    return UnknownPart(BU, SU, is_skew_bdot_2s(BU, SU, robot))


def christoffel_column(Y: sp.Matrix, robot) -> sp.Matrix:  # type: ignore[no-untyped-def]
    """Y(q, q̈) of the inertial term B q̈ completed column by column with the Coriolis terms of B_j = ∂y_j/∂q̈:
    the regressor of B q̈ + c (what a part: inertia parametrization leaves out)."""
    out = sp.Matrix(Y)
    for j in range(Y.cols):
        Bj = Y[:, j].jacobian(sp.Matrix(robot.ddq))
        if all(x == 0 for x in Bj):
            continue
        Sj = factorization(christoffel(Bj, list(robot.q)), list(robot.dq))
        out[:, j] = (Y[:, j] + Sj * sp.Matrix(robot.dq)).applyfunc(lambda x: tidy(sp.expand(x)))
    return out


def lyapunov_function(B: sp.Matrix, s: sp.Matrix, e: sp.Matrix, aU: sp.Matrix, ahat: list[sp.Symbol],
                      Gam: sp.Matrix, KD: sp.Matrix, Lam: sp.Matrix, with_e: bool) -> sp.Expr:
    """V = ½ sᵀ B s + ½ ã_Uᵀ Γ⁻¹ ã_U (+ eᵀ K_D Λ e), ã_U = a_U − â_U, in the state (s, e given in the state)."""
    at = aU - sp.Matrix(ahat)
    V = (s.T * B * s)[0] / 2
    if at.rows:
        V += (at.T * Gam.inv() * at)[0] / 2
    if with_e:
        V += (e.T * KD * Lam * e)[0]
    return V


def lyapunov_rate(s: sp.Matrix, e: sp.Matrix, de: sp.Matrix, KD: sp.Matrix, Lam: sp.Matrix,
                  Fv: sp.Matrix | None, with_e: bool) -> sp.Expr:
    """The negative semidefinite form of V̇: −sᵀ(K_D + F_v)s, or with the e-term −ėᵀK_Dė − eᵀΛK_DΛe − sᵀF_v s."""
    F = Fv if Fv is not None else sp.zeros(s.rows, s.rows)
    if with_e:
        return -(de.T * KD * de)[0] - (e.T * Lam * KD * Lam * e)[0] - (s.T * F * s)[0]
    return -(s.T * (KD + F) * s)[0]


def lyapunov_derivative_check(V: sp.Expr, V_dot: sp.Expr, robot, B: sp.Matrix, s: sp.Matrix,  # type: ignore[no-untyped-def]
                              forces: sp.Matrix, rates: dict[sp.Symbol, sp.Expr]) -> bool:
    """dV/dt along the closed loop ≡ V_dot, exactly. dV/dt = Σ ∂V/∂q_i q̇_i + ∂V/∂q̇ · q̈ + Σ ∂V/∂x ẋ over the other
    time-varying symbols x (q_d, q̇_d, â: ``rates``). With ∂V/∂q̇ = −B s (verified), ∂V/∂q̇ · q̈ = −sᵀ B q̈ =
    −sᵀ (G u − c − g − F_v q̇) = −sᵀ ``forces``: no inverse of B is needed."""
    exact = _derivative_in_algebra(V, V_dot, robot, B, s, forces, rates)
    if exact is not None:
        return exact
    q, dq = list(robot.q), list(robot.dq)
    w = sp.Matrix([sp.diff(V, v) for v in dq])
    if not all(_zero(x) for x in (w + B * s)):
        return False
    dV = sum((sp.diff(V, x) * v for x, v in zip(q, dq)), sp.Integer(0))
    dV += sum((sp.diff(V, x) * v for x, v in rates.items()), sp.Integer(0))
    dV -= (s.T * forces)[0]
    return _zero(dV - V_dot)


def _derivative_in_algebra(V: sp.Expr, V_dot: sp.Expr, robot, B: sp.Matrix, s: sp.Matrix,  # type: ignore[no-untyped-def]
                           forces: sp.Matrix, rates: dict[sp.Symbol, sp.Expr]) -> bool | None:
    """:func:`lyapunov_derivative_check` in the trigonometric-polynomial algebra (derivatives, products and the
    zero test exact on canonical forms, far faster than sympy's diff of V). The inverse 1/γ of a symbol that does
    not vary (an adaptation gain: Γ⁻¹ in V, Γ in the update law) is a symbol ι of its own, and γ ι = 1 is applied
    to the result (each monomial γᵃ ιᵇ becomes γ^(a−b) or ι^(b−a): a canonical Laurent form, zero iff the function
    is). None when an expression is not a trigonometric polynomial so (the caller differentiates with sympy)."""
    from solver.math.trigpoly import NotTrigPolynomial, TrigAlgebra
    q, dq = list(robot.q), list(robot.dq)
    varying = set(q) | set(dq) | set(rates)
    exprs = [sp.sympify(e) for e in [V, V_dot, *B, *s, *forces, *rates.values()]]
    names: dict[sp.Symbol, sp.Dummy] = {}
    inverses = {}
    for p in set().union(*(e.atoms(sp.Pow) for e in exprs)):
        if p.exp.is_Integer and p.exp < 0 and p.base.is_Symbol and p.base not in varying:
            inverses[p] = names.setdefault(p.base, sp.Dummy(f"inv_{p.base.name}")) ** int(-p.exp)
    exprs = [e.xreplace(inverses) for e in exprs]
    n = len(dq)
    try:
        alg = TrigAlgebra.of(exprs, varying | set(names))
        Vt, Vdt, *rest = [alg.conv(e) for e in exprs]
    except NotTrigPolynomial:
        return None
    Bt = [rest[i * n:(i + 1) * n] for i in range(n)]
    st, ft, rt = rest[n * n:n * n + n], rest[n * n + n:n * n + 2 * n], rest[n * n + 2 * n:]
    pairs = [(alg.gens.index(g), alg.gens.index(i)) for g, i in names.items() if g in alg.gens]

    def zero(a) -> bool:  # type: ignore[no-untyped-def]
        for c in a.values():
            out: dict = {}
            for m, k in c.terms():
                e = list(m)
                for gi, ii in pairs:
                    d = e[gi] - e[ii]
                    e[gi], e[ii] = max(d, 0), max(-d, 0)
                out[tuple(e)] = out.get(tuple(e), 0) + k
            if any(out.values()):
                return False
        return True

    # ∂V/∂q̇ = −B s, then dV/dt = Σ ∂V/∂q_i q̇_i + Σ ∂V/∂x ẋ − sᵀ (G u − c − g − F_v q̇)
    if not all(zero(alg.add(alg.diff(Vt, v), alg.dot(Bt[i], st))) for i, v in enumerate(dq)):
        return False
    dV = alg.add(*[alg.mul(alg.diff(Vt, x), alg.symbol(v)) for x, v in zip(q, dq)],
                 *[alg.mul(alg.diff(Vt, x), r) for x, r in zip(rates, rt)])
    return zero(alg.sub(alg.sub(dV, alg.dot(st, ft)), Vdt))


def compact_forms(n: int, idx: list[str], Gam: sp.Matrix, KD: sp.Matrix, Lam: sp.Matrix, Fv: sp.Matrix | None,
                  with_e: bool) -> tuple[sp.Expr, sp.Expr]:
    """V without its ½ sᵀBs term and V̇, in display symbols s_i, e_i, ė_i, ã_j (j in ``idx``: the indices of the
    estimated coefficients), for the report."""
    s = sp.Matrix([sp.Symbol(f"s_{i + 1}") for i in range(n)])
    e = sp.Matrix([sp.Symbol(f"e_{i + 1}") for i in range(n)])
    de = sp.Matrix([sp.Symbol(f"\\dot e_{i + 1}") for i in range(n)])
    at = sp.Matrix([sp.Symbol(f"\\tilde a_{{{j}}}") for j in idx])
    V = (at.T * Gam.inv() * at)[0] / 2 if idx else sp.Integer(0)
    if with_e:
        V += (e.T * KD * Lam * e)[0]
    return sp.expand(V), sp.expand(lyapunov_rate(s, e, de, KD, Lam, Fv, with_e))
