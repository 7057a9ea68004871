"""Regulation to a constant set point (ask kind ``regulation``): the law, its closed loop, all its equilibria,
the Lyapunov function and the conditions on the gains.

Model B(q) q̈ + c(q, q̇) + g(q) + F_v q̇ = τ + τ_ext, τ = G u, τ_ext = Σ J_i(q)ᵀ F_i (constant forces F_i at points
p_i(q); a law compensates F̂_i, by default F̂_i = F_i), e = q_d − q, K_P, K_D, K_I diagonal > 0, γ(q) = g(q) − Σ J_iᵀF̂_i:

    pd_gravity    τ = K_P e − K_D q̇ + γ(q)               V = T + ½ eᵀK_P e                       unique (q_d, 0), GAS
    pd_constant   τ = K_P e − K_D q̇ + γ(q_d)             V = T + U(q) − U(q_d) + ½ eᵀK_P e + eᵀγ(q_d)   GAS if K_P,m > α
    pd            τ = K_P e − K_D q̇                      V = T + U(q) + ½ eᵀK_P e − min           equilibria K_P e = g(q)
    pid           τ = K_P e − K_D q̇ + K_I ξ, ξ̇ = e       local only: det(B(q_d)s³ + K_D s² + (K_P + A(q_d))s + K_I)
    saturated_pd  τ = K_P tanh(e) − K_D tanh(q̇) + γ(q)    V = T + Σ k_Pi ln cosh e_i,  |τ − γ| < K_P + K_D
    iterative     τ = K_P e − K_D q̇ + û_{i−1},  û_i = û_{i−1} + K_P e_i:   ‖e_i‖ ≤ β/(1 − β) ‖e_{i−1}‖, β = α/K_P,m < ½
    elastic       x = (q, θ), θ actuated (G selects them): u = K_P(θ_d − θ) − K_D θ̇ + u_d, ∇_q U(q_d, θ_d) = 0,
                  u_d = ∇_θ U(q_d, θ_d) (U with the compensated forces, −Σ F̂_iᵀp_i);  V = T + U + ½(θ_d − θ)ᵀK_P(θ_d − θ) − θᵀu_d − min,
                  unique if λ_min(∇²U_elastic + diag(0, K_P)) > α (α: gravity only)
    cartesian_pd  τ = J(q)ᵀK_P(p_d − f(q)) − K_D q̇ + γ(q)   V = T + ½ e_pᵀK_P e_p,  equilibria J(q)ᵀK_P e_p = 0

In every case V = T + P(q) with −∇P(q) = τ(q, 0) + τ_ext(q) − g(q) (the generalized force at rest, zero exactly at
the equilibria) and V̇ = −q̇ᵀK_D q̇ − q̇ᵀF_v q̇ ≤ 0 (since q̇ᵀ(½Ḃ − S)q̇ = 0); both identities are checked exactly.
Gains are symbolic (kp1.., kd1.., ki1..) unless given; numeric values (``values:``) are used for α, the search
of every equilibrium, the iterates and the gain limits.
"""
from __future__ import annotations

import math
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field, field_validator

from solver.control.gravity_bound import GradientBound, box_of, gradient_bound, matrix_function, maximize, spectral
from solver.dynamics.model import derive, require_model
from solver.math.equivalence import identically_zero as _zero
from solver.math.equivalence import real_value
from solver.math.numeric import lambdify_np, newton_zeros
from solver.math.search import bisect_root, lp_max, newton_root
from solver.math.simplify import expand_polynomial, factor_within, is_zero, tidy
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Solution
from solver.spec.errors import UserError
from solver.spec.models import Strict

ExprT = Union[str, int, float, list[Any]]
Scalar = Union[str, int, float]
LAWS = {"pd_gravity": "PD with gravity compensation",
        "pd_constant": "PD with constant gravity compensation",
        "pd": "PD without gravity compensation",
        "pid": "PID",
        "saturated_pd": "saturated PD with gravity compensation",
        "iterative": "PD with iterative gravity compensation",
        "elastic": "energy shaping for elastic joints",
        "cartesian_pd": "Cartesian PD with gravity compensation"}
NEEDS_U = {"pd_constant", "pd", "iterative", "elastic"}
MAX_ITER = 60


class ExternalForce(Strict):
    """A constant force acting on the robot at a point."""

    point: ExprT = Field(description="position p(q) of the point of application, in the base frame")
    force: ExprT = Field(description="the constant force F acting there (as many components as point)")
    compensated: Optional[ExprT] = Field(None, description="the force F̂ the law compensates with -J(q)ᵀF̂ "
                                                           "(default: force, i.e. known; 0: not compensated)")


class Limits(Strict):
    """Bounds |(M u)_i| ≤ u_max at the ``at:`` state: the largest gains that respect them."""

    u_max: Scalar = Field(description="the bound on each (mapped) input")
    map: Optional[ExprT] = Field(None, description="matrix M: the bounded quantities are M u (default identity), "
                                                   "e.g. T^T for torques on other coordinates")


class RegulationAsk(Strict):
    """Regulation to a constant set point: the law, its closed loop, all equilibria, Lyapunov/LaSalle, gains."""

    kind: Literal["regulation"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    law: Literal["pd_gravity", "pd_constant", "pd", "pid", "saturated_pd", "iterative", "elastic",
                 "cartesian_pd"] = Field(
        "pd_gravity", description="pd_gravity: u = K_P e - K_D dq + g(q); pd_constant: ... + g(q_d); pd: no "
                                  "compensation; pid: + K_I int e; saturated_pd: K_P tanh(e) - K_D tanh(dq) + g(q); "
                                  "iterative: + u_(i-1), u_i = u_(i-1) + K_P e_i; elastic: energy shaping on the "
                                  "actuated (motor) coordinates; cartesian_pd: J^T K_P (p_d - f(q)) - K_D dq + g(q)")
    qd: Optional[ExprT] = Field(None, description="desired configuration (n expressions; elastic: of the "
                                                  "non-actuated coordinates); default qd1..")
    kp: Optional[ExprT] = Field(None, description="proportional gains: one expression or a list (diagonal of K_P; "
                                                  "cartesian_pd: m entries, elastic: one per input); default kp1..")
    kd: Optional[ExprT] = Field(None, description="derivative gains, as kp (≥ 0); default kd1..")
    ki: Optional[ExprT] = Field(None, description="pid: integral gains, as kp; default ki1..")
    task: Optional[ExprT] = Field(None, description="cartesian_pd: the task function p = f(q) (m expressions)")
    pd: Optional[ExprT] = Field(None, description="cartesian_pd: the desired task value p_d; default pd1..")
    assume: dict[str, Scalar] = Field({}, description="parameter relations assumed by this ask, substituted in "
                                                      "the model first, e.g. {d2: 0, d1: -m2*l1/m1} (a "
                                                      "self-balanced robot)")
    ranges: dict[str, list[Scalar]] = Field({}, description="joint ranges {q2: [d, L]} used for α (needed for "
                                                             "prismatic coordinates that appear in ∂g/∂q)")
    alpha: Optional[bool] = Field(None, description="compute α ≥ ‖∂g/∂q‖ (default: for the laws whose conditions "
                                                    "use it: pd_constant, pd, iterative, elastic)")
    bound_for: Optional[str] = Field(None, description="a parameter: its largest value with K_P,m > α (numeric "
                                                       "gains), e.g. a payload mass")
    external: list[ExternalForce] = Field([], description="constant external forces (contact, payload push)")
    at: Optional[dict[str, Scalar]] = Field(None, description="a state {q1: .., dq1: ..} where u and B q̈ are "
                                                              "evaluated (velocities default 0)")
    limits: Optional[Limits] = Field(None, description="input bounds at the at: state: the largest gains")
    q0: Optional[ExprT] = Field(None, description="iterative: the initial configuration (at rest)")
    u0: Optional[ExprT] = Field(None, description="iterative: the initial feedforward (default g(q0))")
    epsilon: Optional[Scalar] = Field(None, description="iterative: the required accuracy on ‖e_i‖")
    beta: Optional[Scalar] = Field(None, description="iterative: β with K_P = K'_P/β, K'_P,m > α, β < 1/2 "
                                                     "(default the least, α/K_P,m)")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$",
                        description="appended to every result name (several control asks in one problem)")

    @field_validator("kp", "kd", "ki")
    @classmethod
    def _literal_gains(cls, v: Any, info: Any) -> Any:
        """Plain numbers are checked already here (robosolve check); expressions when solving."""
        strict = info.field_name != "kd"
        for x in (v if isinstance(v, list) else [v]):
            if isinstance(x, (int, float)) and not isinstance(x, bool) and (x < 0 or (strict and x == 0)):
                raise ValueError(f"gain {x} is {'negative' if x < 0 else 'zero'}: the gains must be "
                                 f"{'positive' if strict else 'non-negative'}")
        return v


# ------------------------------------------------------------------------------------------------ spec helpers
def _place(problem, ctx, *key: Any):  # type: ignore[no-untyped-def]
    return problem.located.place(ctx.path + tuple(key))


def _fresh(problem, base: str) -> str:  # type: ignore[no-untyped-def]
    """``base`` or, if the problem already uses it for something else, ``base`` + c, cc, ..."""
    mine = problem.__dict__.setdefault("_control_names", set())
    name = base
    while name in problem.names and name not in mine:
        name += "c"
    mine.add(name)
    return name


def _new_symbol(problem, name: str, tex: str, **assume: bool) -> sp.Symbol:  # type: ignore[no-untyped-def]
    name = _fresh(problem, name)
    s = sp.Symbol(name, **(assume or {"real": True}))
    s = problem.names.setdefault(name, s)
    problem.latex_names.setdefault(s, tex)
    return s


def _qname(name: str, mark: str) -> str:
    """q1 -> qd1, theta1 -> thetad1."""
    head = name.rstrip("0123456789")
    return head + mark + name[len(head):]


def _sub_tex(tex: str, sub: str) -> str:
    head, _, tail = tex.partition("_")
    tail = tail.strip("{}")
    return f"{head}_{{{sub}{',' if tail else ''}{tail}}}"


def _list(problem, ctx, key: str, n: int, what: str, example: str) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """A list of n expressions at the ask's ``key`` (a single expression is allowed when n = 1)."""
    val = ctx.expr(key)
    vals = val if isinstance(val, list) else [val]
    if len(vals) != n or any(isinstance(v, list) for v in vals):
        got = f"{len(vals)} entr{'y' if len(vals) == 1 else 'ies'}" if not any(isinstance(v, list) for v in vals) \
            else "a nested list"
        raise UserError(f"{key} must be a list of {n} expressions ({what}), got {got}", _place(problem, ctx, key),
                        f"write e.g. {key}: {example}")
    return [sp.sympify(v) for v in vals]


def _gains(problem, options: RegulationAsk, ctx, key: str, n: int, strict: bool) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """Diagonal gains: n positive symbols by default, or the ask's value (one expression or n); numbers must be
    > 0 (``strict``) or ≥ 0."""
    tex = {"kp": "k_{{P,{i}}}", "kd": "k_{{D,{i}}}", "ki": "k_{{I,{i}}}"}[key]
    if getattr(options, key) is None:
        return [_new_symbol(problem, f"{key}{i + 1}", tex.format(i=i + 1), positive=True) for i in range(n)]
    val = ctx.expr(key)
    vals = val if isinstance(val, list) else [val] * n
    if len(vals) != n or any(isinstance(v, list) for v in vals):
        raise UserError(f"{key} must be one expression or a list of {n} (the diagonal of the gain matrix)",
                        _place(problem, ctx, key), f"write e.g. {key}: 100 or {key}: [{', '.join(['100'] * n)}]")
    out = [sp.sympify(v) for v in vals]
    for i, v in enumerate(out):
        bad = (v.is_negative or (strict and v.is_zero)) if v.is_number else \
            (v.is_negative or (strict and v.is_nonpositive))
        if bad:
            where = _place(problem, ctx, key, i) if isinstance(val, list) else _place(problem, ctx, key)
            raise UserError(f"{key}: gain {v} is {'negative' if v.is_negative else 'zero'}; the gains must be "
                            f"{'positive' if strict else 'non-negative'}", where,
                            "use positive gains (a gain matrix must be positive definite)")
    return out


def _vec(problem, ctx, path: tuple, what: str) -> sp.Matrix:  # type: ignore[no-untyped-def]
    val = problem.parse_at(ctx.path + path)
    vals = val if isinstance(val, list) else [val]
    if any(isinstance(v, list) for v in vals):
        raise UserError(f"{what} must be a vector (a flat list)", problem.located.place(ctx.path + path))
    return sp.Matrix([sp.sympify(v) for v in vals])


def _substituted(x: Any, subs: dict) -> Any:
    """x (an expression or a matrix, or None) with ``subs`` substituted, entries tidied."""
    return None if x is None else (x.xreplace(subs).applyfunc(tidy) if isinstance(x, sp.MatrixBase)
                                   else tidy(sp.sympify(x).xreplace(subs)))


def _numeric(x: Any) -> bool:
    return all(sp.sympify(v).is_number for v in (x if isinstance(x, (list, sp.MatrixBase)) else [x]))


# ------------------------------------------------------------------------------------------------ pure math
def potential_of(g: sp.Matrix, q: list[sp.Symbol]) -> Optional[sp.Expr]:
    """U with ∇U = g (path integral along the axes from 0); None if g is not a gradient or not integrable."""
    U = sp.Integer(0)
    try:
        for i, qi in enumerate(q):
            t = sp.Dummy("t", real=True)
            gi = g[i].xreplace({qj: 0 for qj in q[i + 1:]}).xreplace({qi: t})
            U += sp.integrate(gi, (t, 0, qi))
    except Exception:  # pragma: no cover - sympy integration failures
        return None
    U = tidy(U)
    return U if all(_zero(sp.diff(U, qi) - gi) for qi, gi in zip(q, g)) else None


def dissipation(V: sp.Expr, q: list, dq: list, B: sp.Matrix, force: sp.Matrix) -> sp.Expr:
    """V̇ along B q̈ = force(q, q̇) (force = τ + τ_ext − c − g − F_v q̇), for V = ½ q̇ᵀBq̇ + P(q):
    V̇ = ∂V/∂q q̇ + ∂V/∂q̇ B⁻¹ force, computed without B⁻¹ as ∇P·q̇ + ½ q̇ᵀḂq̇ + q̇ᵀ force."""
    v = sp.Matrix(dq)
    T = (v.T * B * v)[0] / 2
    P = sp.expand(V - T)
    Bdot = sum((B.diff(qk) * dqk for qk, dqk in zip(q, dq)), sp.zeros(*B.shape))
    grad = sum((sp.diff(P, qk) * dqk for qk, dqk in zip(q, dq)), sp.Integer(0))
    return grad + (v.T * Bdot * v)[0] / 2 + (v.T * force)[0]


def contraction(alpha: sp.Expr, kp_min: sp.Expr, beta: Optional[sp.Expr] = None) -> tuple[sp.Expr, sp.Expr]:
    """(β, ρ) of the iterative gravity compensation: K_P = K'_P/β with K'_P,m = β K_P,m > α, and
    ‖e_i‖ ≤ ρ ‖e_{i−1}‖, ρ = β/(1 − β) (< 1 iff β < ½, i.e. K_P,m > 2α). Default β = α/K_P,m (the least)."""
    if beta is None:
        return sp.nsimplify(alpha / kp_min), sp.nsimplify(alpha / (kp_min - alpha))
    b = sp.sympify(beta)
    return b, sp.nsimplify(b / (1 - b))


def iterations_needed(e1_bound: float, rho: float, eps: float) -> int:
    """The least i ≥ 1 with ê_i = ρ^(i−1) ê_1 < ε."""
    i, e = 1, e1_bound
    while not e < eps:
        i, e = i + 1, e * rho
        if i > 100_000:
            raise ValueError("too many iterations")
    return i


def find_equilibria(phi: sp.Matrix, q: list[sp.Symbol], box: list[tuple[float, float]], periodic: list[bool],
                    extra: list[np.ndarray] = (), starts: int = 2000) -> list[np.ndarray]:
    """Every zero of the numeric φ(q) in the box: sign changes on a fine grid refined by bisection (n = 1,
    :func:`solver.math.search.bisect_root`), multi-start Newton (:func:`solver.math.numeric.newton_zeros`, every
    start at once) from a grid otherwise; periodic coordinates wrapped to [−π, π)."""
    n = len(q)
    sols: list[np.ndarray] = []

    def add(x: np.ndarray) -> None:
        x = np.array([((xi + np.pi) % (2 * np.pi) - np.pi) if per else xi for xi, per in zip(x, periodic)])
        if any(not (lo - 1e-9 <= xi <= hi + 1e-9) for xi, (lo, hi), per in zip(x, box, periodic) if not per):
            return
        if all(np.max(np.abs(_wrapdiff(x, s, periodic))) > 1e-6 for s in sols):
            sols.append(x)

    if n == 1:
        f = lambdify_np(q, list(phi))
        lo, hi = box[0]
        xs = np.linspace(lo, hi, 20001)
        ys = np.array([float(f(x)[0]) for x in xs])
        for i in range(len(xs) - 1):
            if ys[i] == 0:
                add(np.array([xs[i]]))
            elif ys[i] * ys[i + 1] < 0:
                add(np.array([bisect_root(lambda x: float(f(x)[0]), xs[i], xs[i + 1])]))
        if ys[-1] == 0:
            add(np.array([xs[-1]]))
        return sorted(sols, key=lambda s: tuple(s))
    m = max(2, int(starts ** (1.0 / n)))
    axes = [np.linspace(lo, hi, m) for lo, hi in box]
    grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(n, -1).T
    X0 = np.array(list(extra) + list(grid), dtype=float)
    ends, res = newton_zeros(list(phi), q, X0)
    for x, r in zip(ends, res):
        if np.all(np.isfinite(x)) and np.max(np.abs(r)) < 1e-9:
            add(x)
    return sorted(sols, key=lambda s: tuple(s))


def _outside(e: sp.Expr, c: sp.Symbol) -> bool:
    """Whether c appears in e outside sin/cos/tanh."""
    return c in e.replace(lambda y: isinstance(y, (sp.sin, sp.cos, sp.tanh)), lambda y: sp.Integer(1)).free_symbols


def _wrapdiff(a: np.ndarray, b: np.ndarray, periodic: list[bool]) -> np.ndarray:
    d = a - b
    return np.array([((x + np.pi) % (2 * np.pi) - np.pi) if per else x for x, per in zip(d, periodic)])


def largest_gains(expr: sp.Matrix, gains: list[sp.Symbol], bound: sp.Expr, values: dict) -> dict:
    """For |expr_i| ≤ bound with expr affine in the gains (all ≥ 0): each gain's largest value (a linear
    program, solved exactly by :func:`solver.math.search.lp_max`, the others free), in closed form when the
    binding constraint involves that gain only. Gains that do not appear are unbounded (None)."""
    A = expr.jacobian(gains)
    b = expr.xreplace({k: 0 for k in gains})
    An = np.array(A.xreplace(values).evalf(), dtype=float)
    bn = np.array(b.xreplace(values).evalf(), dtype=float).ravel()
    Un = float(sp.sympify(bound).xreplace(values))
    out: dict = {}
    for j, k in enumerate(gains):
        if not any(A[i, j] != 0 for i in range(A.rows)):
            out[k] = None
            continue
        c = [1 if jj == j else 0 for jj in range(len(gains))]
        status, x = lp_max(c, np.vstack([An, -An]).tolist(), np.concatenate([Un - bn, Un + bn]).tolist())
        if status != 0:
            out[k] = sp.nan if status == 2 else sp.oo
            continue
        kmax = float(x[j])
        exact = None
        for i in range(A.rows):
            others = [A[i, jj] for jj in range(len(gains)) if jj != j]
            if A[i, j] == 0 or any(o != 0 for o in others):
                continue
            for sgn in (1, -1):
                cand = (sgn * bound - b[i]) / A[i, j]
                if abs(float(sp.sympify(cand).xreplace(values)) - kmax) < 1e-7 * max(1.0, abs(kmax)):
                    exact = tidy(cand)
        out[k] = exact if exact is not None else sp.Float(kmax, 10)
    return out


# ------------------------------------------------------------------------------------------------ the ask
def validate_regulation(problem, options: RegulationAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The options read and checked as :func:`solve_regulation` reads them first (:meth:`_Regulation.check`: assume,
    the law's options, ranges, external forces, the at: state and limits:; law: elastic's input map, springs, q_d
    and gains; the other laws' q_d and gains, cartesian_pd's task and p_d, iterative's beta, q0, u0, epsilon),
    without deriving the model."""
    _Regulation(problem, options, ctx, check_only=True).check()


@ask_kind("regulation", RegulationAsk,
          "regulation to a set point: PD (+ gravity, constant, iterative compensation), PID, saturated PD, "
          "elastic joints, Cartesian PD; equilibria, Lyapunov/LaSalle, α, gain conditions",
          validate=validate_regulation)
def solve_regulation(problem, options: RegulationAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the suffix): u, closed_loop, equilibrium_eq, equilibria, V, P, V_dot, V_check, dg_dq, alpha,
    alpha_max, alpha_q, alpha_frobenius, alpha_bound, kp_threshold, condition, param_max..., law-specific ones
    (docs/spec.md)."""
    return _Regulation(problem, options, ctx).solve()


class _Regulation:
    """One regulation ask being solved (keeps the spec context for error places). ``check_only``: no model, for
    :meth:`check`."""

    def __init__(self, problem, options: RegulationAsk, ctx, check_only: bool = False) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.options, self.ctx = problem, options, ctx
        self.robot = require_model(problem)
        self.dm = derive(self.robot) if not check_only else None
        self.assumed = self._assume()
        self.n = self.robot.n
        self.law = options.law
        self.sfx = options.suffix
        self.sol = Solution("regulation", title=options.title or f"Regulation: {LAWS[self.law]}")
        self.values = dict(problem.values)

    def _assume(self) -> dict:
        """Substitute the ask's parameter relations in the model (a copy)."""
        import dataclasses
        o = self.options
        if not o.assume:
            return {}
        subs = {}
        for name in o.assume:
            if name not in self.problem.symbols:
                raise UserError(f"'{name}' in assume: is not a parameter of the problem",
                                self.place("assume", name), "name a symbol declared under symbols:")
            subs[self.problem.symbols[name]] = sp.sympify(self.ctx.expr("assume", name))
        dm = self.dm
        if dm is None:
            return subs

        def sub(x):  # type: ignore[no-untyped-def]
            return _substituted(x, subs)
        self.dm = dataclasses.replace(dm, B=sub(dm.B), c=sub(dm.c), g=sub(dm.g), U=sub(dm.U), lhs=sub(dm.lhs),
                                      Fv=sub(dm.Fv), G=sub(dm.G), S=sub(dm.S),
                                      C=None if dm.C is None else [sub(c) for c in dm.C])
        return subs

    def _input_map(self) -> sp.Matrix:
        """G (with the assumed relations; the identity without an input map), as the model has it."""
        G = self.robot.input_map
        if G is None:
            return sp.eye(self.n)
        return _substituted(G, self.assumed) if self.assumed else G

    # -- small helpers
    def place(self, *key: Any):  # type: ignore[no-untyped-def]
        return _place(self.problem, self.ctx, *key)

    def add(self, name: str, value: Any, kind: str | None = None, label: str = "") -> Any:
        return self.sol.add(name + self.sfx, value, kind, label)

    def tex(self, s: sp.Symbol) -> str:
        return self.problem.latex_names.get(s, s.name)

    def all_numeric(self, *exprs: Any, allow: tuple = ()) -> bool:
        keep = set(allow)
        for e in exprs:
            for x in (e if isinstance(e, (list, sp.MatrixBase)) else [e]):
                if (sp.sympify(x).xreplace(self.values).free_symbols - keep):
                    return False
        return True

    # -- the solve
    def check(self) -> None:
        """The options :meth:`solve` reads first, without the model: the law's options, the ranges, the external
        forces, law: elastic's inputs, the other laws' q_d, gains, task and iterative options, the at: state and
        limits: (pid: the names of at: only when solving, they may be the law's states ξ)."""
        r = self.robot
        self.q, self.dq, self.ddq = list(r.q), list(r.dq), list(r.ddq)
        self._check_options()
        self.ranges = self._ranges()
        self.external = self._read_forces()
        self.elastic_inputs = self._read_elastic() if self.law == "elastic" else None
        self.read = self._read_law() if self.law != "elastic" else {}
        if self.options.at is not None and self.law != "pid":
            self._read_at([])
        inputs = len(self.elastic_inputs[0]) if self.elastic_inputs is not None else self.n
        self.limits = self._read_limits(inputs) if self.options.limits is not None else None

    def solve(self) -> Solution:
        o, r, dm, n = self.options, self.robot, self.dm, self.n
        self.check()
        self.revolute = {c for c, j in zip(self.q, r.joints) if j == "R"} if r.joints else set()
        self.Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
        self._forces()
        self.G = self._input_map()
        self.sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None,
                      assumed=self.assumed,
                      forces=self.forces_view, tau_ext=self.tau_ext, tau_comp=self.tau_comp, law=self.law)
        build = {"elastic": self._elastic, "cartesian_pd": self._cartesian, "pid": self._pid}.get(self.law, self._joint)
        build()
        self._input()
        self._closed_loop()
        if self.law != "pid":
            self._lyapunov()
        self._alpha()
        self._equilibria()
        if self.law == "iterative":
            self._iterative()
        if self.law == "pid":
            self._pid_linear()
        if o.at is not None:
            self._at()
        self.sol.step("summary", law=self.law, gas=self.gas, cond=self.cond_text, local=self.law == "pid",
                      damped=self.damped)
        return self.sol

    def _check_options(self) -> None:
        o, law = self.options, self.law
        only = {"ki": {"pid"}, "task": {"cartesian_pd"}, "pd": {"cartesian_pd"}, "q0": {"iterative"},
                "u0": {"iterative"}, "epsilon": {"iterative"}, "beta": {"iterative"}}
        for key, laws in only.items():
            if getattr(o, key) is not None and law not in laws:
                raise UserError(f"{key}: is an option of law: {' or '.join(sorted(laws))}, not of law: {law}",
                                self.place(key), f"remove {key}: or change the law")
        if law == "cartesian_pd":
            if o.task is None:
                raise UserError("law: cartesian_pd needs task: (the task function p = f(q))", self.place("law"),
                                "add e.g. task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]")
            if o.qd is not None:
                raise UserError("law: cartesian_pd takes pd: (the desired task value), not qd:", self.place("qd"),
                                "write pd: [..]")
        if o.limits is not None and o.at is None:
            raise UserError("limits: are checked at a state: add at: {q1: .., ...}", self.place("limits"))
        if o.bound_for is not None and o.bound_for not in self.problem.symbols:
            raise UserError(f"bound_for: '{o.bound_for}' is not a parameter of the problem", self.place("bound_for"),
                            "name a symbol declared under symbols:")

    def _ranges(self) -> dict:
        out = {}
        by_name = {s.name: s for s in self.q}
        for name, rng in self.options.ranges.items():
            if name not in by_name:
                raise UserError(f"'{name}' in ranges: is not a coordinate", self.place("ranges", name),
                                "use " + ", ".join(by_name))
            if len(rng) != 2:
                raise UserError(f"the range of {name} must be [low, high]", self.place("ranges", name))
            lo, hi = (sp.sympify(v) for v in self.ctx.expr("ranges", name))
            dv = (hi - lo).xreplace(self.values)
            if dv.is_number and not dv > 0:
                raise UserError(f"empty range for {name}: [{lo}, {hi}]", self.place("ranges", name),
                                "write [low, high] with low < high")
            out[by_name[name]] = (lo, hi)
        return out

    def _read_forces(self) -> list[tuple[sp.Matrix, sp.Matrix, sp.Matrix]]:
        """(p, F, F̂) of each external force: F and F̂ constant, with as many components as p."""
        out = []
        for i, f in enumerate(self.options.external):
            p = _vec(self.problem, self.ctx, ("external", i, "point"), "point")
            F = _vec(self.problem, self.ctx, ("external", i, "force"), "force")
            Fh = F if f.compensated is None else _vec(self.problem, self.ctx, ("external", i, "compensated"),
                                                      "compensated")
            if Fh.shape == (1, 1) and Fh[0] == 0:
                Fh = sp.zeros(*F.shape)
            for vec, key in ((F, "force"), (Fh, "compensated")):
                if vec.shape != p.shape:
                    raise UserError(f"external force {i + 1}: {key} has {vec.rows} components, point has {p.rows}",
                                    self.place("external", i, key), "give as many components as the point")
                if any(x.free_symbols & set(self.q + self.dq) for x in vec):
                    raise UserError(f"external force {i + 1}: {key} must be constant (free of q and dq)",
                                    self.place("external", i, key))
            out.append((p, F, Fh))
        return out

    def _forces(self) -> None:
        n, q = self.n, self.q
        self.tau_ext, self.tau_comp = sp.zeros(n, 1), sp.zeros(n, 1)
        self.forces_view = []
        self.U_ext, self.U_comp = sp.Integer(0), sp.Integer(0)
        for i, (p, F, Fh) in enumerate(self.external):
            J = p.jacobian(q).applyfunc(tidy)
            self.tau_ext += J.T * F
            self.tau_comp += J.T * Fh
            self.U_ext -= (F.T * p)[0]
            self.U_comp -= (Fh.T * p)[0]
            k = i + 1
            self.add(f"pF{k}", p, label=f"p_{{F,{k}}}")
            self.add(f"JF{k}", J, "matrix", label=f"J_{{F,{k}}}(q)")
            self.forces_view.append({"p": p, "J": J, "F": F, "Fh": Fh, "k": k, "known": F == Fh})
        self.tau_ext = self.tau_ext.applyfunc(tidy)
        self.tau_comp = self.tau_comp.applyfunc(tidy)
        if self.options.external:
            self.add("tau_ext", self.tau_ext, "vector", label="\\tau_{ext} = \\sum J^T F")
            self.add("JtF", self.tau_comp, "vector", label="\\sum J^T \\hat F")
        # the plant's conservative generalized force: g(q) - tau_ext(q), potential U + U_ext
        self.gamma = (self.dm.g - self.tau_comp).applyfunc(tidy)   # what the law compensates
        self.g_plant = (self.dm.g - self.tau_ext).applyfunc(tidy)

    def _desired(self, coords: list[sp.Symbol]) -> sp.Matrix:
        o = self.options
        if o.qd is not None:
            ex = "[" + ", ".join("0" for _ in coords) + "]"
            return self._constant("qd", _list(self.problem, self.ctx, "qd", len(coords), "one per coordinate"
                                              if self.law != "elastic" else "one per non-actuated coordinate", ex))
        return sp.Matrix([_new_symbol(self.problem, _qname(s.name, "d"), _sub_tex(self.tex(s), "d")) for s in coords])

    def _constant(self, key: str, xs: list[sp.Expr]) -> sp.Matrix:
        """The column of ``xs`` (the ask's ``key``), which must be free of the coordinates and velocities."""
        state = set(self.q + self.dq + self.ddq)
        bad = sorted(set().union(*(sp.sympify(x).free_symbols for x in xs)) & state, key=str)
        if bad:
            raise UserError(f"{key} must be constant, free of the coordinates and velocities (it has "
                            f"{', '.join(map(str, bad))})", self.place(key), "write numbers or parameters")
        return sp.Matrix(xs)

    def _positive(self, key: str, upper: Optional[float] = None) -> sp.Expr:
        """The ask's scalar ``key``: > 0 and < ``upper``; a number (parameters with values allowed), or symbolic,
        of parameters only, when nothing it is known to be contradicts that (the report then states the
        condition: β < ½, ε > 0)."""
        x = sp.nsimplify(self.ctx.expr(key))
        v = self._num(x)
        state = set(self.q + self.dq + self.ddq)
        if v is None and x.free_symbols and not x.free_symbols & state and x.is_real is not False:
            x_v = sp.sympify(x).xreplace(self.values)
            if x_v.is_positive is not False and (upper is None or (x_v - upper).is_nonnegative is not True):
                return x
        if v is None or not v > 0 or (upper is not None and not v < upper):
            what = "a positive number" if upper is None else f"in (0, {sp.nsimplify(upper)})"
            raise UserError(f"{key} must be {what}, got {x}", self.place(key),
                            "the contraction factor beta/(1 - beta) is < 1 only for 0 < beta < 1/2" if key == "beta"
                            else "the required accuracy on ||e_i||, e.g. epsilon: 0.001")
        return x

    def _read_law(self) -> dict:
        """The options of the laws but elastic (:meth:`_read_elastic`), as the laws use them: q_d (constant) and
        the diagonal gains K_P, K_D (n each; pid also K_I); cartesian_pd: the task f(q) (m ≥ 1 components, of q
        only), p_d (m, constant), K_P (m), K_D (n); iterative: β ∈ (0, ½), q₀, û₀ (n each, constant) and ε > 0."""
        o, n, law = self.options, self.n, self.law
        out: dict = {}
        if law == "cartesian_pd":
            f = _vec(self.problem, self.ctx, ("task",), "task")
            if f.rows == 0:
                raise UserError("task must list the task function's components", self.place("task"),
                                "write e.g. task: [l1*cos(q1) + l2*cos(q1 + q2), l1*sin(q1) + l2*sin(q1 + q2)]")
            vel = sorted(set().union(*(x.free_symbols for x in f)) & set(self.dq + self.ddq), key=str)
            if vel:
                raise UserError(f"task must be a function of the coordinates only (it has "
                                f"{', '.join(map(str, vel))})", self.place("task"), "write p = f(q)")
            m = f.rows
            if o.pd is not None:
                pd = self._constant("pd", _list(self.problem, self.ctx, "pd", m, "one per task component",
                                                "[" + ", ".join(["0"] * m) + "]"))
            else:
                pd = sp.Matrix([_new_symbol(self.problem, f"pd{i + 1}", f"p_{{d,{i + 1}}}") for i in range(m)])
            out.update(f=f, pd=pd, kp=_gains(self.problem, o, self.ctx, "kp", m, True))
        else:
            out.update(qd=self._desired(self.q), kp=_gains(self.problem, o, self.ctx, "kp", n, True))
        out["kd"] = _gains(self.problem, o, self.ctx, "kd", n, False)
        if law == "pid":
            out["ki"] = _gains(self.problem, o, self.ctx, "ki", n, True)
        if law == "iterative":
            ex = "[" + ", ".join(["0"] * n) + "]"
            out.update(beta=self._positive("beta", 0.5) if o.beta is not None else None,
                       q0=self._constant("q0", _list(self.problem, self.ctx, "q0", n, "one per coordinate", ex))
                       if o.q0 is not None else None,
                       u0=self._constant("u0", _list(self.problem, self.ctx, "u0", n, "feedforward", ex))
                       if o.u0 is not None else None,
                       eps=self._positive("epsilon") if o.epsilon is not None else None)
        return out

    # -- the laws
    def _joint(self) -> None:
        """pd_gravity, pd_constant, pd, saturated_pd, iterative: τ(q, q̇) and P_core (−∇P_core = τ(q, 0) + ...)."""
        n, law = self.n, self.law
        q, dq = sp.Matrix(self.q), sp.Matrix(self.dq)
        self.qd, self.kp, self.kd = self.read["qd"], self.read["kp"], self.read["kd"]
        KP, KD = sp.diag(*self.kp), sp.diag(*self.kd)
        e = self.qd - q
        self.e = e
        self.states: list = []
        self.uhat = None
        if law == "saturated_pd":
            tanh_e = e.applyfunc(sp.tanh)
            tau = KP * tanh_e - KD * dq.applyfunc(sp.tanh) + self.gamma
            self.damping = KD * dq.applyfunc(sp.tanh)
            self.P_core = sum((k * sp.log(sp.cosh(x)) for k, x in zip(self.kp, e)), sp.Integer(0))
            self.add("u_bound", sp.Matrix([a + b for a, b in zip(self.kp, self.kd)]), "vector",
                     label="|u - g(q)| <")
        else:
            self.damping = KD * dq
            comp = {"pd_gravity": self.gamma, "pd_constant": self.gamma.xreplace(dict(zip(self.q, self.qd))),
                    "pd": sp.zeros(n, 1)}.get(law)
            if law == "iterative":
                self.uhat = sp.Matrix([_new_symbol(self.problem, f"uhat{i + 1}", f"\\hat u_{{{i + 1}}}")
                                       for i in range(n)])
                comp = self.uhat
            tau = KP * e - KD * dq + comp
            self.P_core = sum((k * x ** 2 for k, x in zip(self.kp, e)), sp.Integer(0)) / 2
            if law in ("pd_constant", "iterative"):
                self.P_core -= (q.T * comp)[0]
            if law == "pd_constant":
                self.add("gd", comp.applyfunc(tidy), "vector", label="g(q_d)")
        self.tau = tau
        self.compensates_g = law in ("pd_gravity", "saturated_pd")
        self.eq_known = self.qd if law in ("pd_gravity", "pd_constant", "saturated_pd") else None
        self.sol.step("law", law=law, KP=KP, KD=KD, qd=self.qd, e=e, tau=tau, comp=None if law in
                      ("pd_gravity", "saturated_pd", "pd") else comp, forces=bool(self.options.external),
                      uhat=self.uhat)

    def _pid(self) -> None:
        n = self.n
        q, dq = sp.Matrix(self.q), sp.Matrix(self.dq)
        self.qd, self.kp, self.kd, self.ki = self.read["qd"], self.read["kp"], self.read["kd"], self.read["ki"]
        KP, KD, KI = sp.diag(*self.kp), sp.diag(*self.kd), sp.diag(*self.ki)
        xi = sp.Matrix([_new_symbol(self.problem, f"xi{i + 1}", f"\\xi_{{{i + 1}}}") for i in range(n)])
        self.e = self.qd - q
        self.tau = KP * self.e - KD * dq + KI * xi
        self.damping = KD * dq
        self.states = list(xi)
        self.uhat = None
        self.compensates_g = False
        self.eq_known = self.qd
        self.xi_eq = (KI.inv() * self.g_plant.xreplace(dict(zip(self.q, self.qd)))).applyfunc(tidy)
        self.add("controller_state", xi, "vector", label="\\xi")
        self.add("controller_rate", self.e, "vector", label="\\dot\\xi")
        self.sol.step("law", law="pid", KP=KP, KD=KD, KI=KI, qd=self.qd, e=self.e, tau=self.tau, xi=xi, comp=None,
                      forces=bool(self.options.external), uhat=None)

    def _cartesian(self) -> None:
        dq = sp.Matrix(self.dq)
        f, pd, self.kp, self.kd = self.read["f"], self.read["pd"], self.read["kp"], self.read["kd"]
        m = f.rows
        KP, KD = sp.diag(*self.kp), sp.diag(*self.kd)
        J = f.jacobian(self.q).applyfunc(tidy)
        ep = pd - f
        self.tau = J.T * KP * ep - KD * dq + self.gamma
        self.damping = KD * dq
        self.P_core = (ep.T * KP * ep)[0] / 2
        self.states, self.uhat = [], None
        self.compensates_g = True
        self.eq_known = None
        self.qd, self.e = None, None
        self.pd, self.f, self.J = pd, f, J
        self.add("f", f.applyfunc(tidy), "vector", label="f(q)")
        self.add("J", J, "matrix", label="J(q)")
        self.sol.step("law", law="cartesian_pd", KP=KP, KD=KD, pd=pd, f=f, J=J, tau=self.tau, m=m, comp=None,
                      forces=bool(self.options.external), uhat=None)

    def _read_elastic(self) -> tuple[list[int], list[int], sp.Matrix, sp.Matrix, list[sp.Expr], list[sp.Expr]]:
        """law: elastic: (the actuated coordinates θ, which the columns of G select; the others; the stiffness K,
        the constant Hessian of the extra potential; q_d, one per non-actuated coordinate; K_P, K_D, one per
        input)."""
        n, x = self.n, self.q
        G = self._input_map()
        act = []
        for j in range(G.cols):
            col = list(G[:, j])
            nz = [i for i, v in enumerate(col) if v != 0]
            if len(nz) != 1 or col[nz[0]] != 1:
                raise UserError("law: elastic needs an input map that selects the actuated coordinates (columns "
                                "of the identity)", self.problem.located.place(("robot", "input_map")),
                                "write e.g. input_map: [[0, 0], [0, 0], [1, 0], [0, 1]] for motor coordinates 3, 4")
            act.append(nz[0])
        pas = [i for i in range(n) if i not in act]
        if not pas:
            raise UserError("law: elastic needs non-actuated (link) coordinates; every coordinate is actuated",
                            self.place("law"), "use law: pd_constant")
        Ue = sum(self.robot.potential_extra, sp.Integer(0))
        K = sp.hessian(Ue, x) if Ue != 0 else sp.zeros(n, n)
        if any(k.free_symbols & set(x) for k in K):
            raise UserError("law: elastic needs linear springs (a constant Hessian of the extra potential)",
                            self.problem.located.place(("robot", "extra")))
        qd = self._desired([x[i] for i in pas])
        kp = _gains(self.problem, self.options, self.ctx, "kp", len(act), True)
        kd = _gains(self.problem, self.options, self.ctx, "kd", len(act), False)
        return act, pas, K, qd, kp, kd

    def _elastic(self) -> None:
        dm = self.dm
        act, pas, K, qd, self.kp, self.kd = self.elastic_inputs
        x = self.q
        qs, th = [x[i] for i in pas], [x[i] for i in act]
        U = dm.U if dm.U is not None else potential_of(dm.g, x)
        if U is None:
            raise UserError("law: elastic needs the potential energy U(q) (g(q) given directly is not a gradient)",
                            self.problem.located.place(("robot",)))
        U = U + self.U_comp    # the law's model: the compensated forces F̂ (the plant feels F: U_ext)
        grad_q = sp.Matrix([sp.diff(U, s) for s in qs]).xreplace(dict(zip(qs, qd)))
        sol = sp.solve(list(grad_q), th, dict=True)
        if len(sol) != 1 or any(t not in sol[0] for t in th):
            raise UserError("law: elastic: the motor positions θ_d with ∇_q U(q_d, θ_d) = 0 are not unique "
                            f"({len(sol)} solutions)", self.place("qd"),
                            "check the springs: each link must be coupled to a motor")
        thd = sp.Matrix([tidy(sol[0][t]) for t in th])
        xd = {**dict(zip(qs, qd)), **dict(zip(th, thd))}
        ud = sp.Matrix([tidy(sp.diff(U, t).xreplace(xd)) for t in th])
        KP, KD = sp.diag(*self.kp), sp.diag(*self.kd)
        thv, dthv = sp.Matrix(th), sp.Matrix([self.dq[i] for i in act])
        u = KP * (thd - thv) - KD * dthv + ud
        self.u_elastic = u
        self.tau = self.G * u
        self.damping = self.G * KD * dthv
        self.P_core = ((thd - thv).T * KP * (thd - thv))[0] / 2 - (thv.T * ud)[0]
        self.states, self.uhat = [], None
        self.compensates_g = False
        self.eq_known = sp.Matrix([xd[s] for s in x])
        self.qd, self.e = qd, None
        self.act, self.pas, self.K_el = act, pas, K
        self.add("thetad", thd, "vector", label="\\theta_d")
        self.add("ud", ud, "vector", label="u_d")
        self.sol.step("law", law="elastic", KP=KP, KD=KD, qd=qd, thd=thd, ud=ud, tau=self.tau, u=u,
                      qs=sp.Matrix(qs), th=thv, K=K, comp=None, forces=bool(self.options.external), uhat=None)

    # -- u, closed loop
    def _input(self) -> None:
        n = self.n
        if self.law == "elastic":
            u = self.u_elastic
        else:
            G = self.G
            if G.rows != G.cols:
                raise UserError(f"law: {self.law} needs one input per coordinate, but the input map G is "
                                f"{G.rows}x{G.cols}", self.problem.located.place(("robot", "input_map")),
                                "use law: elastic for robots with elastic joints (motor coordinates)")
            if sp.simplify(G.det()) == 0:
                raise UserError(f"law: {self.law} needs an invertible input map G", self.problem.located.place(
                    ("robot", "input_map")))
            u = self.tau if self.dm.G is None else (G.inv() * self.tau)
        u = u.applyfunc(lambda x: tidy(sp.expand(x)) if not x.has(sp.tanh) else sp.expand(x))
        self.u = u
        self.add("u", u, "vector", label="u")
        self.sol.step("input", u=u, Ginv=None if self.dm.G is None or self.law == "elastic" else self.G.inv(), n=n)

    def _closed_loop(self) -> None:
        dm, n = self.dm, self.n
        closed = (dm.lhs - self.tau - self.tau_ext).applyfunc(expand_polynomial)
        self.closed = closed
        self.add("closed_loop", closed, "vector", label="B\\ddot q + c + g + F_v\\dot q - \\tau - \\tau_{ext}")
        at_rest = {v: 0 for v in self.dq + self.ddq}
        phi = (self.tau + self.tau_ext - dm.g).xreplace(at_rest).applyfunc(lambda x: tidy(sp.expand(x))
                                                                          if not x.has(sp.tanh) else x)
        self.phi = phi
        self.add("equilibrium_eq", phi, "vector", label="\\tau(q,0) + \\tau_{ext}(q) - g(q)")
        self.damped = [i for i in range(n) if (self.damping[i] != 0 or any(self.Fv[i, j] != 0 for j in range(n)))]
        pid_phi = None
        if self.law == "pid":   # φ without the integral term: B q̈ + c + K_D q̇ = φ(q) + K_I ξ
            pid_phi = phi - sp.diag(*self.ki) * sp.Matrix(self.states)
        self.sol.step("closed_loop", closed=closed, phi=phi, law=self.law, friction=self.dm.Fv is not None,
                      states=self.states, damping=self.damping, n=n, pid_phi=pid_phi)
        if self.law == "pid":
            return
        # the generalized force at rest must be conservative: −∇P = φ
        needs_U = self.law in NEEDS_U
        if needs_U:
            U = self.dm.U if self.dm.U is not None else potential_of(self.dm.g, self.q)
            if U is None:
                self.P = None
                return
            P = U + self.U_ext + self.P_core
        else:
            P = self.P_core - self.U_comp + self.U_ext
        if self.eq_known is not None:
            P = P - P.xreplace(dict(zip(self.q, self.eq_known)))
        if not P.has(sp.tanh, sp.cosh):
            rest = tidy(sp.expand(P - self.P_core))
            P = self.P_core + rest if sp.count_ops(rest) < sp.count_ops(tidy(sp.expand(P))) else tidy(sp.expand(P))
        self.P = P

    # -- Lyapunov
    def _lyapunov(self) -> None:
        dm, n = self.dm, self.n
        self.gas = None
        if self.P is None:
            self.sol.step("lyapunov", V=None)
            return
        v = sp.Matrix(self.dq)
        T = (v.T * dm.B * v)[0] / 2
        V = T + self.P
        grad_ok = all(_zero(sp.diff(self.P, qk) + ph) for qk, ph in zip(self.q, self.phi))
        force = self.tau + self.tau_ext - dm.c - dm.g - self.Fv * v
        vdot = dissipation(V, self.q, self.dq, dm.B, force)
        claimed = -(v.T * self.damping)[0] - (v.T * self.Fv * v)[0]
        ok = grad_ok and _zero(vdot - claimed)
        self.add("V", V, "scalar", label="V")
        self.add("P", self.P, "scalar", label="P(q)")
        self.add("V_dot", sp.expand(claimed), "scalar", label="\\dot V")
        self.add("V_check", bool(ok), "bool", label="\\dot V \\text{ verified}")
        self.V, self.vdot_ok = V, ok
        mismatch = any(not _zero(x) for x in (self.tau_ext - self.tau_comp))
        self.sol.step("lyapunov", V=V, T=T, P=self.P, vdot=sp.expand(claimed), ok=ok, law=self.law, mismatch=mismatch,
                      friction=dm.Fv is not None, damped=self.damped, n=n, skew=dm.skew,
                      tanh=self.law == "saturated_pd", forces=bool(self.options.external))

    # -- alpha and gain conditions
    def _alpha(self) -> None:
        o, law = self.options, self.law
        want = o.alpha if o.alpha is not None else (law in NEEDS_U or o.bound_for is not None)
        self.cond_text, self.alpha_info = None, None
        if not hasattr(self, "gas"):
            self.gas = None
        if law == "pid":
            return
        if not want:
            if law in ("pd_gravity", "saturated_pd", "cartesian_pd"):
                self.gas = None if law == "cartesian_pd" else self._lasalle_ok()
            return
        g_grav = self.g_plant
        if law == "elastic":
            g_grav = (self.dm.g - sp.Matrix([sp.diff(sum(self.robot.potential_extra, sp.Integer(0)), s)
                                             for s in self.q]) - self.tau_ext).applyfunc(tidy)
        for c in self.q:
            if (o.alpha or o.bound_for) and c not in self.revolute and c not in self.ranges and any(
                    c in x.free_symbols for x in g_grav.jacobian(self.q)):
                raise UserError(f"α (the bound on ‖∂g/∂q‖) needs the range of the prismatic coordinate {c}",
                                self.place("ranges") if o.ranges else self.place("law"),
                                f"add ranges: {{{c}: [min, max]}}")
        b = gradient_bound(g_grav, self.q, self.revolute, self.ranges, self.values)
        self.alpha_info = b
        A = b.A
        self.add("dg_dq", A, "matrix", label="\\partial g/\\partial q")
        AtA = (A.T * A).applyfunc(tidy)
        self.add("AtA", AtA, "matrix", label="A^T A")
        lam_max = None
        if A.shape == (2, 2):
            tr, det = tidy(AtA.trace()), tidy(factor_within(AtA.det()))
            self.add("AtA_trace", tr, "scalar", label="\\operatorname{tr}(A^T A)")
            self.add("AtA_det", det, "scalar", label="\\det(A^T A)")
            lam_max = (tr + sp.sqrt(tr ** 2 - 4 * det)) / 2
            self.add("lambda_max", lam_max, "scalar", label="\\lambda_{\\max}(A^T A)")
        extra_ata = {"AtA": AtA, "lam_max": lam_max, "tr": tr if lam_max is not None else None,
                     "det": det if lam_max is not None else None}
        self.add("alpha", b.alpha, "scalar", label="\\alpha")
        if b.alpha_max is not None:
            self.add("alpha_max", b.alpha_max, "scalar", label="\\max_q \\|\\partial g/\\partial q\\|")
            if b.q_max is not None:
                self.add("alpha_q", b.q_max, "vector", label="q_{\\alpha}")
        if b.frobenius is not None:
            self.add("alpha_frobenius", b.frobenius, "scalar", label="\\max_q \\|\\partial g/\\partial q\\|_F")
        if b.termwise is not None:
            self.add("alpha_bound", b.termwise, "scalar", label="\\alpha_{\\text{termwise}}")
        factor = 2 if law == "iterative" else 1
        kps = self.kp
        thr = None
        extra: dict = {}
        if law in ("pd_constant", "pd", "iterative"):
            thr = factor * b.alpha
            self.add("kp_threshold", thr, "scalar", label="K_{P,m} >")
            kmin = sp.Min(*kps) if len(kps) > 1 else kps[0]
            self.cond_text = ("kp", thr)
            num = self._num(kmin), self._num(thr)
            if None not in num:
                met = num[0] > num[1]
                self.add("condition", bool(met), "bool", label="K_{P,m} > " + ("2" if factor == 2 else "") + "\\alpha")
                extra["met"] = met
                if law in ("pd_constant", "pd"):
                    self.gas = bool(met) and self._lasalle_ok()
        elif law == "elastic":
            M = self.K_el + sp.diag(*[0 if i not in self.act else self.kp[self.act.index(i)] for i in range(self.n)])
            self.add("shaping_matrix", M, "matrix", label="\\nabla^2 U_{el} + \\text{diag}(0, K_P)")
            lam = None
            Mn = M.xreplace(self.values)
            if _numeric(list(Mn)):
                lam = sp.Float(min(np.linalg.eigvalsh(np.array(Mn.evalf(), dtype=float))), 10)
                self.add("lambda_min", lam, "scalar", label="\\lambda_{\\min}")
                an = self._num(b.alpha)
                if an is not None:
                    met = float(lam) > an
                    self.add("condition", bool(met), "bool", label="\\lambda_{\\min} > \\alpha")
                    extra["met"] = met
                    self.gas = bool(met) and self._lasalle_ok()
            extra["M"], extra["lam"] = M, lam
            self.cond_text = ("elastic", b.alpha)
        if law in ("pd_gravity", "saturated_pd"):
            self.gas = self._lasalle_ok()
        kmin = sp.Min(*kps) if len(kps) > 1 else kps[0]
        self.sol.step("alpha", b=b, law=law, thr=thr, factor=factor, kps=kps, kmin=kmin, **extra, **extra_ata,
                      revolute=self.revolute, ranges=self.ranges)
        if o.bound_for is not None:
            self._bound_for(b, thr if thr is not None else b.alpha)

    def _num(self, x: Any) -> Optional[float]:
        """x with the parameter values as a float; a real number written with complex radicals (an imaginary part
        that vanishes at 30 digits) counts as real."""
        v = sp.sympify(x).xreplace(self.values)
        if v.is_number and v.is_real is not False:
            try:
                return float(v)
            except TypeError:
                z = real_value(v, {})
                return None if z is None else z.real
        return None

    def _lasalle_ok(self) -> bool:
        """LaSalle: V̇ = 0 forces the damped velocities to zero. If every coordinate is damped, q̇ ≡ 0. Otherwise the
        damped coordinates are constant; with no inertial or velocity coupling to the undamped ones (B_du ≡ 0,
        c_d = 0 when q̇_d = 0) their equations reduce to φ_d(q) = 0, which must fix the undamped coordinates
        (φ_d linear in them with full column rank): then q̇ ≡ 0 and the state is an equilibrium."""
        if not getattr(self, "vdot_ok", False):
            return False
        und = [i for i in range(self.n) if i not in self.damped]
        if not und:
            return True
        if not self.damped:
            return False
        B, c = self.dm.B, self.dm.c
        if any(not _zero(B[i, j]) for i in self.damped for j in und):
            return False
        stop = {self.dq[i]: 0 for i in self.damped}
        if any(not _zero(c[i].xreplace(stop)) for i in self.damped):
            return False
        rows = sp.Matrix([self.phi[i] for i in self.damped])
        Jc = rows.jacobian([self.q[i] for i in und]).xreplace(self.values)
        if any(x.free_symbols & set(self.q) for x in Jc):
            return False
        return Jc.rank(simplify=True) == len(und)

    def _bound_for(self, b: GradientBound, thr: sp.Expr) -> None:
        """The largest value of a parameter p with K_P,m > α(p) (numeric gains)."""
        p = self.problem.symbols[self.options.bound_for]
        kmin = min(self.kp, key=lambda k: self._num(k) if self._num(k) is not None else math.inf)
        if self._num(kmin) is None:
            raise UserError("bound_for: needs numeric gains kp:", self.place("bound_for"), "give kp: [..]")
        vals = {k: v for k, v in self.values.items() if k != p}
        out = []
        for name, a in (("param_max", thr), ("param_max_frobenius",
                                             None if b.frobenius is None else thr / b.alpha * b.frobenius
                                             if b.alpha != 0 else None),
                        ("param_max_bound", None if b.termwise is None else thr / b.alpha * b.termwise
                         if b.alpha != 0 else None)):
            if a is None:
                continue
            sols = [s for s in sp.solve(sp.Eq(a.xreplace(vals), kmin), p) if s.is_positive]
            if not sols:
                continue
            val = sp.nsimplify(min(sols)) if not min(sols).atoms(sp.Float) else min(sols)
            self.add(name, val, "number", label=f"{self.tex(p)}_{{\\max}}")
            out.append((name, val, a))
        self.sol.step("bound_for", p=p, kmin=kmin, rows=out)

    # -- equilibria
    def _equilibria(self) -> None:
        law, n = self.law, self.n
        q = self.q
        self.equilibria = None
        phi = self.phi
        if law == "pid":
            eq = self.qd
            self.equilibria = [eq]
            self.add("equilibria", [eq], "set", label="q_e")
            self.add("xi_eq", self.xi_eq, "vector", label="\\bar\\xi = K_I^{-1} g(q_d)")
            self.sol.step("equilibria", law=law, phi=phi, exact=True, configs=[eq], how="pid", xi_eq=self.xi_eq,
                          stable=None)
            return
        configs, how, stable = None, None, None
        mismatch = any(not _zero(x) for x in (self.tau_ext - self.tau_comp))
        if law in ("pd_gravity", "saturated_pd") and not mismatch:
            configs, how = [self.qd], "unique_exact"
        elif not any(x.has(sp.sin, sp.cos, sp.tanh) for x in phi) and law != "cartesian_pd":
            try:
                sols = sp.solve(list(phi), q, dict=True)
            except NotImplementedError:
                sols = None
            if sols is not None and all(all(c in s for c in q) for s in sols):
                configs, how = [sp.Matrix([tidy(s[c]) for c in q]) for s in sols], "solved"
        met = None
        for st in self.sol.steps:
            if st.name == "alpha":
                met = st.data.get("met")
        if configs is None and met and self.eq_known is not None and not mismatch:
            configs, how = [self.eq_known], "convex"   # (unique by α; q_d only when τ_ext is compensated exactly)
        numeric_ok = self.all_numeric(phi, allow=tuple(q)) and (law != "cartesian_pd" or
                                                               self.f.rows == n)
        found = None
        if configs is None and numeric_ok and (law != "iterative"):
            found, box, periodic = self._search(phi)
            if found is not None:
                configs, how = found, "numeric"
                Hfun = lambdify_np(q, (-phi.xreplace(self.values)).jacobian(q).tolist())
                stable = []
                for c in configs:
                    H = np.array(Hfun(*[float(x) for x in c]), dtype=float)
                    ev = np.linalg.eigvals(H)
                    stable.append(bool(np.all(ev.real > 1e-9)))
        if configs is not None:
            self.equilibria = configs
            self.add("equilibria", configs, "set", label="q_e")
            self.add("n_equilibria", sp.Integer(len(configs)), "number", label="N_e")
        self.sol.step("equilibria", law=law, phi=phi, configs=configs, how=how, stable=stable,
                      qd=self.qd if law != "elastic" else self.eq_known, mismatch=mismatch,
                      search=getattr(self, "search_view", None))

    def _search(self, phi: sp.Matrix) -> tuple[Optional[list], Any, Any]:
        """Every equilibrium numerically (all gains and parameters numeric)."""
        q, n = self.q, self.n
        ph = phi.xreplace(self.values).applyfunc(lambda x: x.evalf())
        periodic, box = [], []
        ref = self.eq_known.xreplace(self.values) if self.eq_known is not None else sp.zeros(n, 1)
        for i, c in enumerate(q):
            outside = any(_outside(x, c) for x in ph)
            per = c in self.revolute and not outside and c not in self.ranges
            periodic.append(per)
            if c in self.ranges:
                lo, hi = (float(sp.sympify(v).xreplace(self.values)) for v in self.ranges[c])
            elif per:
                lo, hi = -math.pi, math.pi
            else:
                lo, hi = None, None
            box.append((lo, hi))
        # a coordinate that enters linearly, φ_i = a q_i + r_i(q) (K_P e): every root has |q_i| ≤ sup |r_i| / |a|
        for i, c in enumerate(q):
            if box[i][0] is not None:
                continue
            a = sp.expand(ph[i]).coeff(c)
            r_i = sp.expand(ph[i] - a * c)
            if a.free_symbols or a == 0 or _outside(r_i, c):
                continue
            wide = [b if b[0] is not None else (float(ref[j]) - 4 * math.pi, float(ref[j]) + 4 * math.pi)
                    for j, b in enumerate(box)]
            fn = matrix_function(sp.Matrix([[r_i]]), q)
            sup, _ = maximize(lambda p: np.abs(fn(p)[:, 0, 0]), wide, [False] * n)
            half = 1.05 * sup / abs(float(a)) + 1e-3
            box[i] = (-half, half)
        if any(b[0] is None for b in box):
            return None, None, None
        extra = [np.array([float(x) for x in ref])] if self.eq_known is not None else []
        sols = find_equilibria(ph, q, box, periodic, extra)
        self.search_view = {"box": box, "periodic": periodic, "n": n}
        return [sp.Matrix([sp.Float(x, 8) for x in s]) for s in sols], box, periodic

    # -- iterative scheme
    def _iterative(self) -> None:
        o = self.options
        b = self.alpha_info
        kmin = sp.Min(*self.kp) if len(self.kp) > 1 else self.kp[0]
        beta_opt = self.read["beta"]
        alpha = b.alpha
        beta, rho = contraction(alpha, kmin, beta_opt)
        self.add("beta", beta, "scalar", label="\\beta")
        self.add("rho", rho, "scalar", label="\\beta/(1-\\beta)")
        data: dict = {"beta": beta, "rho": rho, "alpha": alpha, "kmin": kmin, "given_beta": beta_opt is not None}
        an, kn, bn = self._num(alpha), self._num(kmin), self._num(beta)
        if beta_opt is not None and an is not None and kn is not None and bn is not None and not bn * kn > an:
            raise UserError(f"beta = {beta_opt} is too small: beta*K_P,m = {bn * kn:.6g} must exceed alpha = "
                            f"{an:.6g}", self.place("beta"), f"use beta > {an / kn:.6g}, or omit beta:")
        if o.q0 is not None:
            q0 = self.read["q0"]
            e0 = self.qd - q0
            e0n = sp.sqrt(sum(x ** 2 for x in e0))
            g = self.g_plant
            gq0 = g.xreplace(dict(zip(self.q, q0)))
            u0 = gq0 if o.u0 is None else self.read["u0"]
            self.add("e0", tidy(e0n), "scalar", label="\\|e_0\\|")
            data.update(q0=q0, e0=e0n, u0=u0, u0_is_g=o.u0 is None or all(_zero(a - b2) for a, b2 in zip(u0, gq0)))
            if data["u0_is_g"]:
                e1 = rho * e0n
            else:
                gd = g.xreplace(dict(zip(self.q, self.qd)))
                e1 = sp.sqrt(sum(x ** 2 for x in (gd - u0))) / (kmin - alpha)
            data["e1"] = e1
            if o.epsilon is not None:
                eps = self.read["eps"]
                en, rn, e1n = self._num(eps), self._num(rho), self._num(e1)
                data["eps"] = eps
                if rn is not None and not 0 <= rn < 1:   # β ≥ ½ (ρ ≥ 1, or ρ < 0 when β > 1: K_P,m < α)
                    data["no_contraction"] = True
                elif en is None or rn is None or e1n is None:  # ρ^(i−1) ê₁ < ε from i > 1 + ln(ε/ê₁)/ln ρ on
                    data["i_formula"] = 1 + sp.log(eps / e1) / sp.log(rho)
                else:
                    imin = iterations_needed(e1n, rn, en)
                    rho_v, e1_v = sp.sympify(rho).xreplace(self.values), sp.sympify(e1).xreplace(self.values)
                    bounds = [tidy(e0n.xreplace(self.values))] + [sp.nsimplify(e1_v * rho_v ** k) if not
                                                                   (e1_v * rho_v).atoms(sp.Float) else
                                                                   e1_v * rho_v ** k for k in range(imin)]
                    self.add("iterations", sp.Integer(imin), "number", label="i_{\\min}")
                    self.add("error_bounds", bounds, "list", label="\\hat e_i")
                    data.update(imin=imin, bounds=bounds, rho_v=rho_v)
            if self.all_numeric(g, self.qd, q0, u0, self.kp, allow=tuple(self.q)):
                self._iterate(q0, u0, data)
        self.sol.step("iterative", **data)

    def _iterate(self, q0: sp.Matrix, u0: sp.Matrix, data: dict) -> None:
        """The actual iterates: q_i solves g(q) = K_P (q_d − q) + u_{i−1}, then u_i = u_{i−1} + K_P e_i."""
        q = self.q
        g = self.g_plant.xreplace(self.values)
        gf = lambdify_np(q, list(g))
        gj = lambdify_np(q, g.jacobian(q).tolist())
        kp = np.array([float(sp.sympify(k).xreplace(self.values)) for k in self.kp])
        qd = np.array([float(sp.sympify(x).xreplace(self.values)) for x in self.qd])
        x = np.array([float(sp.sympify(v).xreplace(self.values)) for v in q0])
        u = np.array([float(sp.sympify(v).xreplace(self.values)) for v in u0])
        eps = self._num(data.get("eps", 0)) or 0.0
        rows = [(0, x.copy(), float(np.linalg.norm(qd - x)), u.copy())]
        actual = None
        for i in range(1, MAX_ITER + 1):
            uprev = u.copy()
            z = newton_root(lambda z: np.array(gf(*z), dtype=float) - kp * (qd - z) - uprev,
                            lambda z: np.array(gj(*z), dtype=float) + np.diag(kp), x)
            res = np.array(gf(*z), dtype=float) - kp * (qd - z) - uprev
            if np.max(np.abs(res)) > 1e-9 * (1 + np.max(np.abs(uprev))):
                break
            x = z
            e = qd - x
            u = uprev + kp * e
            rows.append((i, x.copy(), float(np.linalg.norm(e)), u.copy()))
            if actual is None and eps and np.linalg.norm(e) < eps:
                actual = i
            if np.linalg.norm(e) < 1e-12 or (actual is not None and i >= max(actual, data.get("imin", 0)) + 1):
                break
        self.add("iterates", [sp.Matrix([sp.Float(v, 8) for v in row[1]]) for row in rows[1:]], "list",
                 label="q_i")
        self.add("feedforward", [sp.Matrix([sp.Float(v, 8) for v in row[3]]) for row in rows[1:]], "list",
                 label="u_i")
        if actual is not None:
            self.add("iterations_actual", sp.Integer(actual), "number", label="i_{\\text{actual}}")
        data["rows"] = rows
        data["actual"] = actual
        data["ginf"] = [float(v) for v in np.array(gf(*qd), dtype=float)]

    # -- PID linearization
    def _pid_linear(self) -> None:
        n = self.n
        s = sp.Symbol("s")
        at = dict(zip(self.q, self.qd))
        Bd = self.dm.B.xreplace(at)
        A = self.g_plant.jacobian(self.q).xreplace(at).applyfunc(tidy)
        KP, KD, KI = sp.diag(*self.kp), sp.diag(*self.kd), sp.diag(*self.ki)
        Ms = Bd * s ** 3 + KD * s ** 2 + (KP + A) * s + KI
        data: dict = {"Bd": Bd, "Ad": A, "n": n}
        poly = None
        if n <= 2 or _numeric(list(Ms.xreplace(self.values).free_symbols - {s})):
            poly = sp.expand(Ms.det(method="berkowitz"))
            self.add("char_poly", poly, "scalar", label="\\det(B(q_d)s^3 + K_D s^2 + (K_P + A(q_d))s + K_I)")
        data["poly"] = poly
        if n == 1:
            b, kd, k1, ki = Bd[0, 0], self.kd[0], self.kp[0] + A[0, 0], self.ki[0]
            routh = [kd, tidy(k1), ki, tidy(kd * k1 - b * ki)]
            self.add("routh", sp.Matrix(routh), "vector", label="\\text{Routh: all} > 0")
            data["routh"] = routh
        if poly is not None and not (sp.sympify(poly).xreplace(self.values).free_symbols - {s}):
            coeffs = [float(c) for c in sp.Poly(sp.sympify(poly).xreplace(self.values), s).all_coeffs()]
            roots = np.roots(coeffs)
            stable = bool(np.all(roots.real < 0))
            self.add("locally_stable", stable, "bool", label="\\text{locally asymptotically stable}")
            data["roots"] = [complex(r) for r in sorted(roots, key=lambda z: (z.real, z.imag))]
            data["stable"] = stable
        self.sol.step("pid", **data)

    # -- a state
    def _read_at(self, states: list[sp.Symbol]) -> dict:
        """The state of at: (coordinates, velocities, the law's ``states``)."""
        names = {s.name: s for s in self.q + self.dq + states}
        state = {}
        for name in self.options.at:
            if name not in names:
                raise UserError(f"'{name}' in at: is not a coordinate or velocity", self.place("at", name),
                                "use q1, dq1, ...")
            state[names[name]] = sp.sympify(self.ctx.expr("at", name))
        return state

    def _read_limits(self, m: int) -> tuple[sp.Expr, Optional[sp.Matrix]]:
        """(u_max > 0, the map M of m columns or None) of limits:, for m inputs."""
        Ulim = sp.sympify(self.ctx.expr("limits", "u_max"))
        if self._num(Ulim) is None or self._num(Ulim) <= 0:
            raise UserError("limits.u_max must be a positive number", self.place("limits", "u_max"))
        M = None
        if self.options.limits.map is not None:
            Mv = self.ctx.expr("limits", "map")
            try:
                M = sp.Matrix(Mv)
            except (TypeError, ValueError):
                M = None
            if M is None or M.cols != m:
                raise UserError(f"limits.map must be a matrix with {m} columns", self.place("limits", "map"))
        return Ulim, M

    def _at(self) -> None:
        o = self.options
        state = self._read_at(self.states)
        for v in self.dq:
            state.setdefault(v, sp.Integer(0))
        u_at = self.u.xreplace(state).applyfunc(tidy)
        net = (self.tau + self.tau_ext - self.dm.c - self.dm.g - self.Fv * sp.Matrix(self.dq)).xreplace(state)
        net = net.applyfunc(tidy)
        self.add("u_at", u_at, "vector", label="u\\big|_{*}")
        if self.law == "cartesian_pd":
            self.add("f_at", self.f.xreplace(state).applyfunc(tidy), "vector", label="f\\big|_{*}")
            self.add("J_at", self.J.xreplace(state).applyfunc(tidy), "matrix", label="J\\big|_{*}")
        self.add("Bddq_at", net, "vector", label="B\\ddot q\\big|_{*}")
        rest = all(state[v] == 0 for v in self.dq)
        if rest:
            self.add("equilibrium_at", all(_zero(x) for x in net), "bool", label="\\text{equilibrium at } *")
        data: dict = {"state": state, "u_at": u_at, "net": net, "rest": rest, "friction": self.dm.Fv is not None,
                      "eq": rest and all(_zero(x) for x in net)}
        if o.limits is not None:
            Ulim, M = self.limits
            y = u_at
            if M is not None:
                y = (M * u_at).applyfunc(tidy)
                self.add("Mu_at", y, "vector", label="M u\\big|_{*}")
                data["M"] = M
            gains = [k for k in dict.fromkeys(list(self.kp) + list(self.kd) + list(getattr(self, "ki", [])))
                     if isinstance(k, sp.Symbol)]
            if not self.all_numeric(y, allow=tuple(gains)):
                raise UserError("limits: every parameter but the gains needs a numeric value", self.place("limits"),
                                "add them under values:")
            best = largest_gains(y, gains, Ulim, self.values)
            rows = []
            for k, v in best.items():
                if v is not None:
                    self.add(f"{k.name}_max", v, "number", label=f"{self.tex(k)}^{{\\max}}")
                rows.append((k, v))
            data.update(y=y, Ulim=Ulim, rows=rows)
        self.sol.step("at", **data)


# ------------------------------------------------------------------------------------------------ grading
def _regulation_ask(problem, suffix: str = ""):  # type: ignore[no-untyped-def]
    for a in problem.asks:
        if a.kind == "regulation" and a.options.suffix == suffix:
            return a
    return None


def _sample_values(problem, rng: np.random.Generator, skip: set) -> dict:  # type: ignore[no-untyped-def]
    """Problem values, random positive numbers (in [0.5, 2]) for the other positive parameters."""
    out = {}
    for s in problem.symbols.values():
        if s in skip:
            continue
        out[s] = problem.values.get(s, sp.Float(rng.uniform(0.5, 2.0)))
    return out


def _as_scalar(value: Any) -> Optional[sp.Expr]:
    if isinstance(value, list):
        return None
    try:
        return sp.sympify(value)
    except (sp.SympifyError, TypeError):
        return None


def _sup_norm(problem, A: sp.Matrix, ask, vals: dict) -> Optional[float]:  # type: ignore[no-untyped-def]
    robot = problem.robot
    q = list(robot.q)
    revolute = {c for c, j in zip(q, robot.joints) if j == "R"}
    ranges = {}
    if ask is not None:
        by = {c.name: c for c in q}
        for name in ask.options.ranges:
            lo, hi = ask.ctx.expr("ranges", name)
            ranges[by[name]] = (float(sp.sympify(lo).xreplace(vals)), float(sp.sympify(hi).xreplace(vals)))
    An = A.xreplace(vals)
    coords = [c for c in q if any(c in x.free_symbols for x in An)]
    if any(x.free_symbols - set(coords) for x in An):
        return None
    try:
        box = box_of(coords, revolute, ranges)
    except ValueError:
        return None
    fn = matrix_function(An, coords)
    v, _ = maximize(lambda p: spectral(fn(p)), box, [c in revolute and c not in ranges for c in coords])
    return v


@property_check("alpha", "kp_threshold")
def check_alpha(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Any α ≥ max_q ‖∂g/∂q‖ is a valid bound (kp_threshold: any threshold ≥ the reference's factor × that):
    checked at the problem's parameter values and at random ones; a smaller value is refused with the
    configuration where ‖∂g/∂q‖ exceeds it."""
    A = results.get("dg_dq")
    ref = results.get(name)
    ans = _as_scalar(value)
    if A is None or ref is None or ans is None or problem.robot is None:
        return None
    factor = 1
    if name == "kp_threshold" and results.get("alpha") is not None:
        ratio = sp.nsimplify(sp.simplify(ref.value / results["alpha"].value))
        factor = ratio if ratio.is_number else 1
    ask = _regulation_ask(problem)
    rng = np.random.default_rng(11)
    gains = {s for s in ans.free_symbols if s.name.startswith(("kp", "kd", "ki"))}
    worst = None
    for trial in range(4):
        vals = _sample_values(problem, rng, set()) if trial else {**{s: problem.values.get(s, sp.Integer(1)) for s in
                                                                      problem.symbols.values()}}
        sup = _sup_norm(problem, A.value, ask, vals)
        a = ans.xreplace(vals)
        if sup is None or not a.is_number or gains:
            return None
        av = float(a) / float(factor)
        if av < sup * (1 - 1e-6):
            return PropertyVerdict(False, 0.0, [f"not a valid bound: for the parameter values {_show_vals(vals)} "
                                                f"max_q ‖∂g/∂q‖ = {sup:.6g} > {av:.6g}"])
        worst = (av, sup) if trial == 0 else worst
    av, sup = worst
    fb = [("a valid bound" if name == "alpha" else "a valid sufficient threshold") +
          f": ‖∂g/∂q‖ ≤ {sup:.6g} for every q (at the problem's values)"]
    if av > sup * 1.001:
        fb.append(f"conservative: {av / sup:.3g} times the least bound")
    return PropertyVerdict(True, 1.0, fb)


def _show_vals(vals: dict) -> str:
    return ", ".join(f"{k} = {float(v):.4g}" for k, v in list(vals.items())[:6])


@property_check("param_max")
def check_param_max(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """A parameter bound guaranteeing K_P,m > α: any positive value up to the largest one is sufficient
    (a smaller one is conservative), a larger one is not guaranteed."""
    ref, ans = results.get(name), _as_scalar(value)
    if ref is None or ans is None or not ans.is_number:
        return None
    r, a = float(ref.value), float(ans)
    if a <= 0:
        return PropertyVerdict(False, 0.0, ["the bound must be positive"])
    if a > r * (1 + 1e-3):
        return PropertyVerdict(False, 0.0, [f"too large: above {r:.6g} the condition K_P,m > α is not guaranteed"])
    fb = ["a sufficient bound"]
    if a < r * (1 - 1e-3):
        fb.append(f"conservative: the condition holds up to {r:.6g}")
    return PropertyVerdict(True, 1.0, fb)


@property_check("V")
def check_lyapunov(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """A Lyapunov function for the closed loop: V − V(x_e) > 0 away from the equilibrium x_e = (q_e, 0) and
    V̇ ≤ 0 along the closed loop (q̈ from the closed_loop result), at random states and parameter values (where
    the reference V passes the same test); equal to the reference up to a constant: accepted at once."""
    ref, cl, eqs = results.get("V"), results.get("closed_loop"), results.get("equilibria")
    ans = _as_scalar(value)
    robot = problem.robot
    if ref is None or cl is None or ans is None or robot is None:
        return None
    if not any(a.kind == "regulation" and not getattr(a.options, "suffix", "") for a in problem.asks):
        return None  # V of another ask (an adaptive law's, with estimates and q_d(t)): compared with the reference
    q, dq, ddq = list(robot.q), list(robot.dq), list(robot.ddq)
    d = sp.expand(ans - ref.value)
    if all(is_zero(sp.diff(d, x)) for x in q + dq):
        return PropertyVerdict(True, 1.0, ["equal to the reference Lyapunov function up to a constant"])
    closed = cl.value
    Bm = closed.jacobian(ddq)
    rest = closed.xreplace({a: 0 for a in ddq})
    eq = eqs.value[0] if eqs is not None and len(eqs.value) == 1 else None
    rng = np.random.default_rng(5)
    syms = (ans.free_symbols | ref.value.free_symbols | closed.free_symbols) - set(q + dq + ddq)
    checked = 0
    for trial in range(6):
        vals = {s: problem.values.get(s, sp.Float(rng.uniform(0.5, 2.0) * (5 if s.name.startswith("kp") else 1)))
                for s in sorted(syms, key=lambda x: x.name)}  # sorted: the same draws whatever the hash seed
        try:
            fails_ref = _lyap_fail(ref.value, Bm, rest, q, dq, eq, vals, rng)
            if fails_ref is not None:
                continue
            bad = _lyap_fail(ans, Bm, rest, q, dq, eq, vals, rng)
        except (TypeError, ValueError, ZeroDivisionError, np.linalg.LinAlgError):
            return None
        checked += 1
        if bad is not None:
            return PropertyVerdict(False, 0.0, [bad])
    if not checked:
        return None
    return PropertyVerdict(True, 1.0, [f"a valid Lyapunov function: V > V(equilibrium) and V̇ ≤ 0 at random states "
                                       f"({checked} parameter sets)"])


def _lyap_fail(V: sp.Expr, Bm: sp.Matrix, rest: sp.Matrix, q: list, dq: list, eq: Optional[sp.Matrix], vals: dict,
               rng: np.random.Generator) -> Optional[str]:
    """Why V fails at some random state (None if it passes)."""
    Vn = V.xreplace(vals)
    grad_q = [sp.diff(Vn, x) for x in q]
    grad_v = [sp.diff(Vn, x) for x in dq]
    f_grad = lambdify_np(q + dq, grad_q + grad_v)
    f_B = lambdify_np(q + dq, Bm.xreplace(vals).tolist())
    f_r = lambdify_np(q + dq, list(rest.xreplace(vals)))
    f_V = lambdify_np(q + dq, Vn)
    n = len(q)
    eqn = None if eq is None else [float(sp.sympify(x).xreplace(vals)) for x in eq]
    if eqn is not None and any(not np.isfinite(x) for x in eqn):
        eqn = None
    V0 = float(f_V(*(eqn + [0.0] * n))) if eqn is not None else None
    for _ in range(40):
        x = list(rng.uniform(-2.5, 2.5, n)) + list(rng.uniform(-2, 2, n))
        if eqn is not None and rng.random() < 0.3:
            x[:n] = [a + 0.1 * b for a, b in zip(eqn, rng.standard_normal(n))]
        gr = np.array(f_grad(*x), dtype=float)
        B = np.array(f_B(*x), dtype=float)
        acc = np.linalg.solve(B, -np.array(f_r(*x), dtype=float))
        vdot = float(gr[:n] @ np.array(x[n:]) + gr[n:] @ acc)
        scale = 1.0 + float(np.abs(gr).sum())
        if vdot > 1e-7 * scale:
            return f"V̇ = {vdot:.4g} > 0 at q = {np.round(x[:n], 3).tolist()}, q̇ = {np.round(x[n:], 3).tolist()}"
        if V0 is not None:
            dist = np.linalg.norm(np.array(x[:n]) - eqn) + np.linalg.norm(x[n:])
            if dist > 1e-3 and float(f_V(*x)) - V0 <= 0:
                return (f"V is not larger than at the equilibrium at q = {np.round(x[:n], 3).tolist()}, "
                        f"q̇ = {np.round(x[n:], 3).tolist()}")
    return None


@property_check("alpha_q")
def check_alpha_q(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Any configuration where ‖∂g/∂q‖ reaches its maximum (there are often several, e.g. ±π/2)."""
    A, amax = results.get("dg_dq"), results.get("alpha_max")
    robot = problem.robot
    if A is None or amax is None or robot is None or not isinstance(value, list):
        return None
    try:
        qv = [sp.sympify(x) for x in (value[0] if len(value) == 1 and isinstance(value[0], list) else value)]
    except (sp.SympifyError, TypeError):
        return None
    if len(qv) != robot.n or any(not x.is_number for x in qv):
        return None
    vals = dict(problem.values)
    At = A.value.xreplace(dict(zip(robot.q, qv)))
    free = set().union(*[x.free_symbols for x in At]) | amax.value.free_symbols
    rng = np.random.default_rng(3)
    for _ in range(3):
        sub = {**{s: sp.Float(rng.uniform(0.5, 2.0)) for s in free}, **vals}
        Mn = np.array(At.xreplace(sub).evalf(), dtype=float)
        got, want = float(np.linalg.svd(Mn, compute_uv=False)[0]), float(amax.value.xreplace(sub))
        if abs(got - want) > 1e-6 * max(1.0, want):
            return PropertyVerdict(False, 0.0, [f"‖∂g/∂q‖ = {got:.6g} there, below its maximum {want:.6g}"])
    return PropertyVerdict(True, 1.0, ["a configuration where ‖∂g/∂q‖ is maximum"])
