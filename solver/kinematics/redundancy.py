"""Velocity-level inverse kinematics of redundant robots (ask kind ``redundancy``).

For a task r = f(q) ∈ R^m of a robot with n joints (or a task Jacobian J(q) given directly), ṙ = J(q) q̇:

    J_W^# = W⁻¹ Jᵀ (J W⁻¹ Jᵀ)⁻¹                        (J full row rank; W = I: the pseudoinverse Jᵀ(J Jᵀ)⁻¹)
    J_W^# = R⁻¹ (J R⁻¹)^+,   W = Rᵀ R                  (rank deficient: Moore-Penrose for W = I)
    q̇_ps = J_W^# ṙ                                     minimizes ½ q̇ᵀ W q̇ among the q̇ minimizing ‖J q̇ - ṙ‖
    q̇    = q̇_ps + (I - J_W^# J) q̇₀,                  q̇₀ = step · ∇H(q) with a gradient

At a numeric configuration the computation is exact (sympy) when every entry is an exact number and the sizes are
small, in floating point otherwise; the rank is then exact or from the singular values. Without a configuration
(or with parameters left symbolic) J_W^# is given symbolically for small tasks (1×n up to n = 4, 2×2, 2×3).
"""
from __future__ import annotations

import random
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Literal, Union

import numpy as np
import sympy as sp
from pydantic import Field, model_validator

from solver.kinematics import resolution as rs
from solver.kinematics.methods import (
    Bounds,
    Method,
    Motion,
    TaskItem,
    VariableDamping,
    read_methods,
    solve_methods,
    wants_methods,
)
from solver.math.opcount import count_ops
from solver.math.simplify import factor_within, tidy
from solver.registry import ask_kind
from solver.results import Solution
from solver.spec.expr import shape_of
from solver.spec.models import Strict
from solver.spec.problem import AskReader

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]


class RedundancyAsk(Strict):
    """Joint velocity realizing a task velocity with a redundant robot: (weighted) pseudoinverse, null space."""

    kind: Literal["redundancy"]
    title: str | None = Field(None, description="heading of this part in the report")
    task: ExprT | None = Field(None, description="task function r = f(q), a vector (or scalar) expression in q")
    jacobian: ExprT | None = Field(None, description="task Jacobian J(q) (m x n) given directly, instead of task:")
    at: dict[str, Scalar] | None = Field(
        None, description="configuration {q1: ..., q2: ...} where everything is evaluated (parameter values used)")
    velocity: ExprT | None = Field(None, description="desired task velocity rdot (m components)")
    weight: ExprT | None = Field(
        None, description="weighting matrix W (n x n, or the n diagonal entries, may depend on q): q̇ minimizes "
                          "½ q̇ᵀ W q̇; `inertia` for the robot's inertia matrix B(q) (minimum kinetic energy)")
    null: ExprT | None = Field(
        None, description="preferred joint velocity q̇₀, projected in the null space of J (quote the key, \"null\": "
                          "a bare null: is YAML's empty key; or write qdot0:)")
    qdot0: ExprT | None = Field(None, description="the same as null: (preferred joint velocity q̇₀)")
    gradient: Scalar | None = Field(
        None, description="scalar H(q): q̇₀ = step · ∇H(q) projected in the null space; or a named H "
                          "(method path): manipulability (√det JJᵀ), joint_range (needs joint_ranges:)")
    step: Scalar = Field(1, description="step along ∇H (negative to decrease H)")
    symbolic: bool | None = Field(
        None, description="give J_W^# and q̇_ps also as functions of q (1×n up to n = 4, 2×2, 2×3 Jacobians): "
                          "default: without at:, or when J is short; false: never")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$",
                        description="appended to every result name (several redundancy asks in one problem)")
    # ---- the method path (any of these selects it; see solver/kinematics/methods.py)
    tasks: list[TaskItem] | None = Field(
        None, description="two or more tasks in priority order [{name, task|jacobian, velocity|acceleration}], "
                          "instead of task:/jacobian:")
    level: Literal["velocity", "acceleration"] = Field(
        "velocity", description="velocity: q̇ from ṙ; acceleration: q̈ from r̈ − J̇q̇ (needs joint_velocity:)")
    joint_velocity: ExprT | None = Field(None, description="q̇ at the state (acceleration level)")
    acceleration: ExprT | None = Field(None, description="desired task acceleration r̈ (acceleration level)")
    methods: list[Method] | None = Field(
        None, description="methods compared in one table: pseudoinverse, weighted (weight:), dls (mu:), "
                          "null_space (null:/gradient:/damping:), priority and extended (tasks:), scaled and sns "
                          "(bounds:); default: those the given options call for")
    mu: VariableDamping | Scalar | None = Field(
        None, description="damping factor μ of damped least squares, or {epsilon, max}: μ chosen from the smallest "
                          "singular value σ, μ² = max²(1 − (σ/epsilon)²) for σ < epsilon, 0 elsewhere")
    direction: ExprT | None = Field(
        None, description="task direction d for max_scaling: the task λ d with the largest λ ≥ 0 whose minimum-norm "
                          "command is within bounds:; `stop` for d = −J q̇ (decelerate along the current velocity)")
    bounds: Bounds | ExprT | None = Field(
        None, description="joint bounds on q̇ (velocity level) or q̈ (acceleration level): n values (±) or "
                          "{lower: [...], upper: [...]}")
    damping: ExprT | None = Field(
        None, description="K_d (scalar, n diagonal entries or n x n): q̈₀ = −K_d q̇ is projected in the null "
                          "space (acceleration level; added to null:/gradient: if given)")
    rank_tol: float = Field(rs.DEFAULT_TOL, gt=0, lt=1e-2,
                            description="a singular value σ ≤ rank_tol · max(1, σ_max) counts as zero")
    sketch: bool = Field(True, description="draw the planar robot at the state (method path)")
    joint_ranges: dict[str, tuple[Scalar, Scalar]] | None = Field(
        None, description="{q1: [min, max], ...} for gradient: joint_range")
    partition: list[str] | None = Field(
        None, description="reduced_gradient: the m coordinates q_a whose columns J_a are inverted (default: the best "
                          "conditioned choice)")
    motion: Motion | None = Field(
        None, description="velocity level: integrate q̇ of one method from start: for duration: seconds (constant "
                          "task velocities), stopping at the first singularity; plots q̇(t) with the bounds")

    @model_validator(mode="after")
    def _exclusive(self) -> RedundancyAsk:
        if self.tasks is not None:
            if self.task is not None or self.jacobian is not None:
                raise ValueError("give either tasks: or task:/jacobian:")
            if len(self.tasks) < 1:
                raise ValueError("tasks: needs at least one task")
            return self
        if (self.task is None) == (self.jacobian is None):
            raise ValueError("give exactly one of task: (r = f(q)) or jacobian: (J(q))")
        if wants_methods(self):
            return self
        given = [k for k in ("null", "qdot0", "gradient") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ValueError(f"give only one of null:/qdot0: (a joint velocity) or gradient: (H(q)), "
                             f"got {' and '.join(given)}")
        if given and self.velocity is None:
            raise ValueError("a null-space term needs velocity: (the desired task velocity)")
        return self


# ------------------------------------------------------------------------------------------------ numerics
SMALL_EXACT = 24  # m*n up to which numeric configurations are computed exactly
MAX_RADICALS = 2  # distinct square roots up to which exact numbers stay exact (none nested)
EXACT_SECONDS = 4.0  # CPU budget of an exact or symbolic evaluation before going numeric / giving up
SYMBOLIC_OPS_BIG = 400  # operations in J and W up to which a larger-than-small symbolic J_W^# is attempted
SYMBOLIC_OPS = 40  # with a configuration, J_pinv_sym & co. are also given when J and W have at most this many ops
_TOL = 1e-9


def _small_symbolic(m: int, n: int) -> bool:
    """Sizes for which J_W^# is worth giving symbolically (1×n up to n = 4, 2×2, 2×3)."""
    return (m == 1 and n <= 4) or (m == 2 and 2 <= n <= 3)


def _exact_ok(*mats: sp.Matrix) -> bool:
    """Every entry an exact number without unevaluated functions (sin(1/2)) or floats."""
    for M in mats:
        for x in M:
            if x.free_symbols or x.atoms(sp.Float) or x.atoms(sp.Function):
                return False
    return True


def _clean(e: sp.Expr) -> sp.Expr:
    """An exact number in a canonical, short form (rationalized denominators, a + b*sqrt(c))."""
    if e.is_Rational or not e.is_number:
        return e
    out = sp.expand(sp.radsimp(sp.together(e)))
    if count_ops(out) > 12:
        s = sp.simplify(out)
        out = s if count_ops(s) < count_ops(out) else out
    return out


def _hide_radicals(e: sp.Expr) -> tuple[sp.Expr, dict]:
    """Square roots b^(k/2) of non-constant b replaced by d_b^k, d_b a positive dummy (b tidied first), so that
    the fast trigonometric simplifications apply to the rest; returns (expression, {d_b: sqrt(b)})."""
    back: dict[sp.Dummy, sp.Expr] = {}
    by_base: dict[sp.Expr, sp.Dummy] = {}

    def is_root(x: Any) -> bool:
        return bool(x.is_Pow and x.exp.is_Rational and x.exp.q == 2 and x.base.free_symbols)

    def hide(x: sp.Expr) -> sp.Expr:
        b = tidy(x.base)
        if b not in by_base:
            d = sp.Dummy("r", positive=True)
            by_base[b], back[d] = d, sp.sqrt(b)
        return by_base[b] ** x.exp.p

    out = e.replace(is_root, hide)
    return (out, back) if back else (e, back)


def _sine_square_pair(f: sp.Expr) -> bool:
    """Whether both cos x − 1 and cos x + 1 occur in f for some x: only then can f.subs((cos x − 1)(cos x + 1),
    −sin² x) replace anything (a Mul must have both as bases); sympy's subs walks every node of f for each cos."""
    return any(f.has(c - 1) and f.has(c + 1) for c in f.atoms(sp.cos))


@lru_cache(maxsize=4096)
def _tidy_rational(e: sp.Expr) -> sp.Expr:
    """tidy, or the factored form when that is shorter (rational functions of cos q, sin q); square roots are
    kept as they are (their radicands tidied). Memoized (minimum_norm's three asks tidy the same entries)."""
    if not e.free_symbols:
        return tidy(e)
    e, back = _hide_radicals(e)
    t = tidy(e)
    if t.free_symbols and not t.is_polynomial() and count_ops(t) <= 150:
        f = factor_within(sp.expand_trig(t))
        for _ in range(2):  # (cos x - 1)(cos x + 1) -> -sin(x)^2, then cancel again
            if not _sine_square_pair(f):
                break  # (nothing to replace: subs would only re-evaluate f, which factor_within gives back)
            g = f
            for c in f.atoms(sp.cos):
                g = g.subs((c - 1) * (c + 1), -sp.sin(c.args[0]) ** 2)
            if g == f:
                break
            f = factor_within(g)
        if count_ops(f) < count_ops(t):
            t = f
    return t.xreplace(back) if back else t


def _number_field_matrix(M: sp.Matrix) -> Any:
    """M as a DomainMatrix over Q or an algebraic number field Q(√2, ...) (exact, fast arithmetic), or None
    when its entries are not algebraic numbers (π, sin 1) or the field cannot be built."""
    from sympy.polys.constructor import construct_domain
    from sympy.polys.matrices import DomainMatrix
    entries = list(M)
    if not entries or any(not x.is_number or x.atoms(sp.Float, sp.Function) or x.has(sp.pi, sp.E)
                          for x in entries):
        return None
    try:
        K, els = construct_domain(entries, extension=True)
    except (sp.polys.polyerrors.PolificationFailed, NotImplementedError, ValueError, TypeError):
        return None
    if not (K.is_QQ or K.is_ZZ or K.is_AlgebraicField):
        return None
    m, n = M.shape
    return DomainMatrix([els[i * n:(i + 1) * n] for i in range(m)], (m, n), K).to_field()


def _field_inverse(dM: Any) -> Any:
    """dM⁻¹ over its field, or None when dM is singular (one elimination)."""
    from sympy.polys.matrices.exceptions import DMNonInvertibleMatrixError
    try:
        return dM.inv()
    except DMNonInvertibleMatrixError:
        return None


def _exact_zero(e: sp.Expr) -> bool:
    return e == 0 or sp.simplify(e) == 0


def _to_np(M: sp.Matrix) -> np.ndarray:
    return np.array(M.evalf(30).tolist(), dtype=float).reshape(M.shape)


def _from_np(a: np.ndarray) -> sp.Matrix:
    a = np.atleast_2d(a)
    scale = max(1.0, float(np.max(np.abs(a)))) if a.size else 1.0
    return sp.Matrix(a.shape[0], a.shape[1],
                     lambda i, j: sp.Integer(0) if abs(a[i, j]) < 1e-12 * scale else sp.Float(float(a[i, j]), 15))


def _np_rank(a: np.ndarray) -> int:
    if a.size == 0:
        return 0
    s = np.linalg.svd(a, compute_uv=False)
    return int(np.sum(s > _TOL * max(1.0, s[0]))) if s.size else 0


class Arith:
    """Linear algebra in one mode: ``exact`` (sympy numbers), ``float`` (numpy) or ``symbolic`` (tidied)."""

    def __init__(self, mode: str) -> None:
        self.mode = mode

    def clean(self, M: sp.Matrix) -> sp.Matrix:
        """Intermediate values: exact numbers simplified; symbolic ones left as they are (see :meth:`final`)."""
        if self.mode == "exact":
            return M.applyfunc(_clean)
        if self.mode == "symbolic":
            return M
        return _from_np(_to_np(M))

    def final(self, M: Any) -> Any:
        """A value shown as a result: symbolic ones tidied once, at the end."""
        if M is None or self.mode != "symbolic":
            return M
        if isinstance(M, sp.MatrixBase):
            return M.applyfunc(_tidy_rational)
        return _tidy_rational(M)

    def mul(self, *ms: sp.Matrix) -> sp.Matrix:
        if self.mode == "float":
            out = _to_np(ms[0])
            for M in ms[1:]:
                out = out @ _to_np(M)
            return _from_np(out)
        out = ms[0]
        for M in ms[1:]:
            out = out * M
        return self.clean(out)

    def inv(self, M: sp.Matrix) -> sp.Matrix:
        if self.mode == "float":
            return _from_np(np.linalg.inv(_to_np(M)))
        if self.mode == "symbolic":
            if M.is_diagonal():
                return sp.diag(*[1 / M[i, i] for i in range(M.shape[0])])
            return (M.adjugate() / sp.cancel(M.det())).applyfunc(sp.cancel)
        dM = _number_field_matrix(M)
        inv = _field_inverse(dM) if dM is not None else None  # exactly in Q(√2, ...); singular: sympy's error below
        return self.clean(inv.to_Matrix() if inv is not None else M.inv())

    def det(self, M: sp.Matrix) -> sp.Expr:
        if self.mode == "float":
            return sp.Float(float(np.linalg.det(_to_np(M))), 15)
        if self.mode == "exact":
            dM = _number_field_matrix(M)
            return _clean(dM.domain.to_sympy(dM.det()) if dM is not None else M.det())
        return M.det()

    def rank(self, M: sp.Matrix) -> int:
        if self.mode == "exact":
            dM = _number_field_matrix(M)
            return dM.rank() if dM is not None else M.rank(iszerofunc=_exact_zero)
        if self.mode == "float":
            return _np_rank(_to_np(M))
        return generic_rank(M)

    def pinv_mp(self, M: sp.Matrix) -> sp.Matrix:
        """Moore-Penrose pseudoinverse."""
        if self.mode == "float":
            a = _to_np(M)
            return _from_np(np.linalg.pinv(a, rcond=_TOL))
        if self.mode == "exact":
            dM = _number_field_matrix(M)
            if dM is not None:  # full rank: Mᵀ(M Mᵀ)⁻¹ or (MᵀM)⁻¹Mᵀ, exactly in Q(√2, ...), ~100x faster
                m, n = M.shape
                Mt = dM.transpose()
                Gi = _field_inverse(dM * Mt if m <= n else Mt * dM)
                if Gi is not None:
                    return self.clean((Mt * Gi if m <= n else Gi * Mt).to_Matrix())
        return self.clean(M.pinv())

    def chol_factor(self, W: sp.Matrix) -> sp.Matrix:
        """R with W = Rᵀ R."""
        if self.mode == "float":
            return _from_np(np.linalg.cholesky(_to_np(W)).T)
        if W.is_diagonal():
            return sp.diag(*[sp.sqrt(W[i, i]) for i in range(W.shape[0])])
        return self.clean(W.cholesky(hermitian=False).T)


def generic_rank(M: sp.Matrix, trials: int = 3) -> int:
    """Rank of M(q, p) at generic points (random values of every symbol): the rank almost everywhere."""
    syms = sorted(M.free_symbols, key=lambda s: s.name)
    if not syms:
        return _np_rank(_to_np(M))
    rng = random.Random(7)
    best = 0
    for _ in range(trials):
        point = {s: sp.Rational(rng.randint(101, 997), rng.randint(101, 397)) *
                 (1 if (s.is_positive or s.is_nonnegative or rng.random() < 0.5) else -1) for s in syms}
        try:
            best = max(best, _np_rank(_to_np(M.xreplace(point))))  # (subs: the same numbers, 7x slower)
        except (TypeError, ValueError, ZeroDivisionError):
            continue
    return best


# ------------------------------------------------------------------------------------------------ solver
@dataclass
class Pinv:
    JWJ: sp.Matrix | None    # J W⁻¹ Jᵀ
    det: sp.Expr | None      # its determinant
    J_pinv: sp.Matrix
    method: str              # full | mp


def _quot(n: sp.Expr, d: sp.Expr) -> sp.Expr:
    """n/d with common factors cancelled when that is cheap."""
    if n == 0:
        return sp.Integer(0)
    if count_ops(n) + count_ops(d) <= 60:
        return _tidy_rational(n / d)
    return n / d


def symbolic_pinv(J: sp.Matrix, W: sp.Matrix | None) -> tuple[Pinv, sp.Matrix, sp.Expr]:
    """Full-row-rank J_W^# = W⁻¹Jᵀ adj(A) / det(A), A = J W⁻¹ Jᵀ, with numerator N and denominator D tidied
    separately (trigonometric polynomials stay in their fast canonical form). Returns (pinv, N, D)."""
    m = J.shape[0]
    if W is None:
        WJt = J.T
    elif W.is_diagonal():
        WJt = (sp.diag(*[1 / W[i, i] for i in range(W.shape[0])]) * J.T).applyfunc(tidy)
    else:
        WJt = (W.adjugate() * J.T / tidy(W.det())).applyfunc(_tidy_rational)
    A = (J * WJt).applyfunc(_tidy_rational)
    D = _tidy_rational(A.det()) if m > 1 else A[0, 0]
    adjA = A.adjugate() if m > 1 else sp.Matrix([[1]])
    N = (WJt * adjA).applyfunc(_tidy_rational)
    return Pinv(A, D, N.applyfunc(lambda x: _quot(x, D)), "full"), N, D


def weighted_pinv(J: sp.Matrix, W: sp.Matrix | None, ar: Arith, rank: int) -> Pinv:
    """J_W^#: W⁻¹Jᵀ(JW⁻¹Jᵀ)⁻¹ at full row rank, R⁻¹(JR⁻¹)^+ (W = RᵀR) otherwise."""
    m = J.shape[0]
    if ar.mode == "symbolic" and rank == m:
        return symbolic_pinv(J, W)[0]
    Wi = ar.inv(W) if W is not None else None
    JWJ = ar.mul(J, Wi, J.T) if Wi is not None else ar.mul(J, J.T)
    det = ar.det(JWJ) if rank == m or ar.mode != "float" else sp.Integer(0)
    if rank == m:
        JWt = ar.mul(Wi, J.T) if Wi is not None else J.T
        return Pinv(JWJ, det, ar.mul(JWt, ar.inv(JWJ)), "full")
    if W is None:
        return Pinv(JWJ, det, ar.pinv_mp(J), "mp")
    R = ar.chol_factor(W)
    Ri = ar.inv(R)
    return Pinv(JWJ, det, ar.mul(Ri, ar.pinv_mp(ar.mul(J, Ri))), "mp")


def _numeric_display(M: Any) -> Any:
    """A float copy for display when an exact value has irrational entries (None otherwise)."""
    if M is None:
        return None
    items = list(M) if isinstance(M, sp.MatrixBase) else [M]
    if all(x.is_Rational or x.free_symbols or x.atoms(sp.Float) for x in items):
        return None
    return M.evalf(6) if isinstance(M, sp.MatrixBase) else sp.Float(M.evalf(6), 6)


class _Spec(AskReader):
    """The parsed, validated inputs of one ask. ``check_only`` (validation): the same checks without the work
    they do not need (J not tidied; `weight: inertia` checked without deriving B, W is then the identity)."""

    def __init__(self, problem, options: RedundancyAsk, ctx, check_only: bool = False) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.options, self.ctx = problem, options, ctx
        self.check_only = check_only
        robot = problem.robot
        self.q: list[sp.Symbol] = list(robot.q) if robot is not None else []
        self.task: sp.Matrix | None = None
        if options.task is not None:
            if robot is None:
                raise self.fail(("task",), "task: needs the robot's coordinates", "add robot: {joints: [...], ...}")
            val = ctx.expr("task")
            shp = shape_of(val)
            if len(shp) > 1:
                raise self.fail(("task",), f"task must be a vector (or a scalar), got shape {shp}",
                                "write [f1(q), f2(q)]")
            self.task = sp.Matrix(val if isinstance(val, list) else [val])
            self.J = self.task.jacobian(self.q)
        else:
            val = ctx.expr("jacobian")
            shp = shape_of(val)
            if shp == ():
                J = sp.Matrix([[val]])
            elif len(shp) == 1:
                J = sp.Matrix([val])  # a flat list is one row
            elif len(shp) == 2 and shp[1] >= 0:
                J = sp.Matrix(val)
            else:
                raise self.fail(("jacobian",), "jacobian must be a matrix [[...], [...]] with rows of equal length")
            if robot is None:
                self.q = [sp.Symbol(f"q{i + 1}", real=True) for i in range(J.shape[1])]
            if J.shape[1] != len(self.q):
                raise self.fail(("jacobian",), f"jacobian must have {len(self.q)} columns (one per coordinate), "
                                               f"got {J.shape[1]}")
            self.J = J
        self.m, self.n = self.J.shape
        if not check_only:
            self.J = self.J.applyfunc(lambda x: sp.factor_terms(_tidy_rational(x)))
        self.rdot = self._vector("velocity", self.m, "velocity") if options.velocity is not None else None
        self.W = self._weight() if options.weight is not None else None
        self.H = None
        self.q0 = None
        for key in ("null", "qdot0"):
            if getattr(options, key) is not None:
                self.q0 = self._vector(key, self.n, key)
        if options.gradient is not None:
            if robot is None:
                raise self.fail(("gradient",), "gradient: needs the robot's coordinates")
            H = ctx.expr("gradient")
            if isinstance(H, list):
                raise self.fail(("gradient",), "gradient: must be a scalar function H(q)", "write e.g. sin(q2)^2")
            self.H = H
            self.step = ctx.expr("step") if "step" in options.model_fields_set else sp.Integer(1)
            if isinstance(self.step, list) or self.step.free_symbols - set(problem.symbols.values()):
                raise self.fail(("step",), "step must be a number (or an expression of parameters)")
        self.state = self._state()

    def _weight(self) -> sp.Matrix:
        raw, n = self.options.weight, self.n
        if isinstance(raw, str) and raw.strip() == "inertia" and "inertia" not in self.problem.names:
            from solver.dynamics.model import derive, has_model
            if self.problem.robot is None or not has_model(self.problem.robot):
                raise self.fail(("weight",), "weight: inertia needs a robot with bodies or a model")
            self.weight_is_inertia = True
            if self.check_only:
                return sp.eye(n)
            B = derive(self.problem.robot).B
            if B.shape != (n, n):
                raise self.fail(("weight",), f"the inertia matrix is {B.shape[0]}x{B.shape[1]}, the task has {n} joints")
            return B
        self.weight_is_inertia = False
        val = self.ctx.expr("weight")
        shp = shape_of(val)
        if shp == ():
            W = val * sp.eye(n)
        elif shp == (n,):
            W = sp.diag(*val)
        elif shp == (n, n):
            W = sp.Matrix(val)
        else:
            raise self.fail(("weight",), f"weight must be {n}x{n}, a list of {n} diagonal entries or a scalar, "
                                         f"got shape {shp}")
        if any(not _exact_zero(x) for x in (W - W.T)):
            raise self.fail(("weight",), "the weighting matrix W must be symmetric")
        return W

    def _state(self) -> dict[sp.Symbol, sp.Expr] | None:
        if self.options.at is None:
            return None
        by_name = {s.name: s for s in self.q}
        state = {}
        for name in self.options.at:
            if name not in by_name:
                raise self.fail(("at", name), f"'{name}' in at: is not a coordinate",
                                "use " + ", ".join(by_name) if by_name else "at: needs a robot")
            v = self.ctx.expr("at", name)
            if isinstance(v, list):
                raise self.fail(("at", name), f"the value of {name} must be a scalar")
            state[by_name[name]] = v
        return state


def _radicals(*mats: sp.Matrix) -> tuple[set, bool]:
    """The distinct square roots (and other radicals) of numbers in the entries, and whether any is nested."""
    rads: set = set()
    nested = False
    for M in mats:
        for x in M:
            for p in x.atoms(sp.Pow):
                if p.exp.is_Rational and not p.exp.is_Integer:
                    rads.add(p.base)
                    if not p.base.is_Rational:
                        nested = True
    return rads, nested


def _mode(*mats: sp.Matrix | None) -> str:
    ms = [M for M in mats if M is not None]
    if any(x.free_symbols for M in ms for x in M):
        return "symbolic"
    big = any(M.shape[0] * M.shape[1] > SMALL_EXACT for M in ms)
    if not _exact_ok(*ms) or big:
        return "float"
    rads, nested = _radicals(*ms)
    return "float" if nested or len(rads) > MAX_RADICALS else "exact"


def exact_reason(*mats: sp.Matrix | None) -> str | None:
    """Why exact numbers are computed in floating point (None when they are not)."""
    ms = [M for M in mats if M is not None]
    if not ms or any(x.free_symbols for M in ms for x in M) or not _exact_ok(*ms):
        return None
    if any(M.shape[0] * M.shape[1] > SMALL_EXACT for M in ms):
        return f"matrices with more than {SMALL_EXACT} entries"
    rads, nested = _radicals(*ms)
    if nested:
        return "nested radicals (e.g. sin(2π/5)) make exact simplification slow"
    if len(rads) > MAX_RADICALS:
        return f"{len(rads)} distinct radicals ({', '.join('√' + str(b) for b in sorted(rads, key=str))})"
    return None


def _subbed(spec: _Spec, subs: dict) -> list:
    """J, W, ṙ and q̇₀ (or ∇H) with ``subs`` applied: the data that decide the arithmetic."""
    out = [spec.J.subs(subs)]
    out.append(spec.W.subs(subs) if spec.W is not None else None)
    out.append(spec.rdot.subs(subs) if spec.rdot is not None else None)
    if spec.H is not None:
        out.append(sp.Matrix([sp.diff(spec.H, x) for x in spec.q]).subs(subs))
    elif spec.q0 is not None:
        out.append(spec.q0.subs(subs))
    return out


def _check_pd(W: sp.Matrix, spec: _Spec) -> None:
    if W.free_symbols:
        return
    ev = np.linalg.eigvalsh(_to_np(W))
    if ev.min() <= 0:
        raise spec.fail(("weight",), f"the weighting matrix W is not positive definite here "
                                     f"(smallest eigenvalue {ev.min():.4g})", "use a symmetric W > 0")


def _evaluate(spec: _Spec, subs: dict, mode_hint: str | None = None, brief: bool = False,
              allow_big: bool = False) -> dict[str, Any]:
    """Every configuration-level quantity, with ``subs`` applied (may be empty: symbolic); ``brief``: only J_W^#,
    its determinant and q̇_ps."""
    J = spec.J.subs(subs) if subs else spec.J
    W = spec.W.subs(subs) if (spec.W is not None and subs) else spec.W
    rdot = spec.rdot.subs(subs) if (spec.rdot is not None and subs) else spec.rdot
    grad = None
    q0 = None
    if spec.H is not None:
        grad = sp.Matrix([sp.diff(spec.H, x) for x in spec.q])
        q0 = spec.step * grad
    elif spec.q0 is not None:
        q0 = spec.q0
    if q0 is not None and subs:
        q0 = q0.subs(subs)
        grad = grad.subs(subs) if grad is not None else None
    mode = mode_hint or _mode(J, W, rdot, q0)
    ar = Arith(mode)
    if mode == "symbolic" and not _small_symbolic(spec.m, spec.n):
        ops = sp.count_ops(J) + (sp.count_ops(W) if W is not None else 0)
        if not allow_big or ops > SYMBOLIC_OPS_BIG or spec.m > 3:
            why = (f"J and W have {ops} operations (limit {SYMBOLIC_OPS_BIG})" if ops > SYMBOLIC_OPS_BIG
                   else f"a {spec.m}-row task" if spec.m > 3 else "q is left symbolic (no at:)")
            return {"mode": mode, "J": ar.clean(J), "too_big": True, "W": W, "rdot": rdot, "grad": grad,
                    "reason": why}
    if W is not None:
        _check_pd(W, spec)
    J = ar.clean(J)
    if W is not None:
        W = ar.clean(W)
    if rdot is not None:
        rdot = ar.clean(rdot)
    rank = ar.rank(J)
    if mode == "exact" and rank < spec.m and W is not None and not W.is_diagonal():
        mode, ar = "float", Arith("float")  # exact Cholesky factors of a full W get unwieldy
        J, W, rdot = ar.clean(J), ar.clean(W), (ar.clean(rdot) if rdot is not None else None)
    if mode == "symbolic" and rank < spec.m:
        return {"mode": mode, "J": J, "too_big": False, "generic_singular": True, "rank": rank, "W": W,
                "rdot": rdot, "grad": grad}
    if mode == "symbolic":
        pv, N, D = symbolic_pinv(J, W)
    else:
        pv = weighted_pinv(J, W, ar, rank)
    out: dict[str, Any] = {"mode": mode, "J": J, "W": W, "rdot": rdot, "rank": rank, "too_big": False,
                           "grad": ar.clean(grad) if grad is not None else None}
    if rdot is not None:
        if mode == "symbolic":
            qps = (N * rdot).applyfunc(lambda x: _quot(_tidy_rational(x), D))
        else:
            qps = ar.mul(pv.J_pinv, rdot)
        out["qdot_ps"] = qps
        qdot = qps
        if brief:
            q0 = None
        if q0 is not None:
            q0 = ar.clean(q0)
            P = ar.clean(sp.eye(spec.n) - ar.mul(pv.J_pinv, J))
            qn = ar.mul(P, q0)
            qdot = ar.clean(qps + qn)
            out.update(q0=q0, P=P, qdot_null=qn, J_qnull=ar.mul(J, qn))
        out["qdot"] = qdot
        if brief:
            return _finish(out, pv, ar)
        out["Jq"] = ar.mul(J, qdot)
        out["task_error"] = ar.clean(out["Jq"] - rdot)
        half = sp.Rational(1, 2) if mode != "float" else sp.Float(0.5)
        if mode != "symbolic":
            out["norm2_ps"] = _scalar(ar, half * (qps.T * qps)[0])
            if W is not None:
                out["cost_ps"] = _scalar(ar, half * (qps.T * W * qps)[0])
                qmn = ar.mul(ar.pinv_mp(J), rdot)
                out["qdot_mn"] = qmn
                out["cost_mn"] = _scalar(ar, half * (qmn.T * W * qmn)[0])
                out["norm2_mn"] = _scalar(ar, half * (qmn.T * qmn)[0])
    return _finish(out, pv, ar)


def _finish(out: dict[str, Any], pv: Pinv, ar: Arith) -> dict[str, Any]:
    """Symbolic values tidied once, at the end."""
    if ar.mode == "symbolic":
        for k in ("q0", "P", "qdot_null", "J_qnull", "qdot", "Jq", "task_error", "norm2_ps", "cost_ps",
                  "grad", "W", "rdot"):
            if out.get(k) is not None:
                out[k] = ar.final(out[k])
        exact = out.get("Jq") is not None and out.get("rdot") is not None
        if exact and all(_exact_zero(x) for x in out["task_error"]):
            out["Jq"] = out["rdot"]  # J q̇ ≡ ṙ exactly: shown as ṙ, not as the product J q̇ left uncancelled
    out["pinv"] = pv
    return out


def _scalar(ar: Arith, e: sp.Expr) -> sp.Expr:
    if ar.mode == "float":
        return sp.Float(float(sp.N(e)), 15)
    return _clean(e)


def validate_redundancy(problem, options: RedundancyAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_redundancy` reads them (the inputs of the method path
    or of the single task), without computing (B is not derived for `weight: inertia`)."""
    if wants_methods(options):
        read_methods(problem, options, ctx)
    else:
        _Spec(problem, options, ctx, check_only=True)


@ask_kind("redundancy", RedundancyAsk,
          "velocity-level inverse kinematics of redundant robots: (weighted) pseudoinverse, null-space term",
          validate=validate_redundancy)
def solve_redundancy(problem, options: RedundancyAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (each with the ask's suffix): J, J_at, grad_H, grad_H_at, J_pinv_sym, det_JJt_sym, qdot_ps_sym,
    JJt, det_JJt, J_pinv, rank, singular, qdot_ps, qdot0, qdot_null, qdot, task_error, norm2_ps, cost_ps, qdot_mn,
    cost_mn, norm2_mn."""
    if wants_methods(options):
        sol = Solution("redundancy", title=options.title or (
            "Joint acceleration for redundant tasks" if options.level == "acceleration"
            else "Joint velocity for redundant tasks"))
        return solve_methods(problem, options, ctx, sol)
    spec = _Spec(problem, options, ctx)
    sfx = options.suffix
    sol = Solution("redundancy", title=options.title or "Joint velocity for a redundant task")

    def add(name: str, value: Any, kind: str | None = None, label: str = "") -> None:
        sol.add(name + sfx, value, kind, label=label)

    m, n = spec.m, spec.n
    add("J", spec.J, "matrix", label="J(q)")
    grad_sym = None
    if spec.H is not None:
        grad_sym = sp.Matrix([tidy(sp.diff(spec.H, x)) for x in spec.q])
        add("grad_H", grad_sym, "vector", label="\\nabla_q H(q)")
    sol.step("task", task=spec.task, J=spec.J, q=sp.Matrix(spec.q), m=m, n=n, W=spec.W,
             inertia=getattr(spec, "weight_is_inertia", False), H=spec.H, grad=grad_sym,
             step=getattr(spec, "step", None), null=spec.q0, rdot=spec.rdot, redundancy=n - m)

    # symbolic pseudoinverse (small tasks): parameters symbolic, q free
    sym = None
    cheap = spec.state is None or sp.count_ops(spec.J) + (sp.count_ops(spec.W) if spec.W is not None else 0) \
        <= SYMBOLIC_OPS
    symbolic = any(M is not None and any(x.free_symbols for x in M) for M in (spec.J, spec.W, spec.rdot))
    if options.symbolic is not None:
        cheap = options.symbolic
    if _small_symbolic(m, n) and cheap and symbolic:
        sym = _evaluate(spec, {}, "symbolic", brief=spec.state is not None)
        if not sym.get("too_big") and "pinv" in sym:
            add("J_pinv_sym", sym["pinv"].J_pinv, "matrix", label="J^{\\#}(q)")
            add("det_JJt_sym", sym["pinv"].det, "scalar", label="\\det(J W^{-1} J^T)")
            if "qdot_ps" in sym:
                add("qdot_ps_sym", sym["qdot_ps"], "vector", label="\\dot q_{ps}(q)")
    if sym is not None:
        det = sym["pinv"].det if "pinv" in sym else None
        never = det is not None and not (det.free_symbols & set(spec.q)) and bool(det.is_nonzero)
        sol.step("symbolic", r=sym, at=spec.state is not None, never_singular=never)

    if spec.state is None and options.symbolic is False and spec.J.free_symbols:
        rank = generic_rank(spec.J)
        add("rank", sp.Integer(rank), "number", label="\\operatorname{rank} J")
        add("singular", bool(rank < m), "bool", label="\\text{singular}")
        sol.step("generic_rank", rank=rank, m=m)
        return sol
    if spec.state is None:
        r = sym if sym is not None else _evaluate(spec, {})
    else:
        from solver.math.budget import BudgetExceeded, cpu_budget
        subs = {**problem.values, **spec.state}
        data = _subbed(spec, subs)
        reason = None
        try:
            with cpu_budget(EXACT_SECONDS):
                r = _evaluate(spec, subs, allow_big=True)
        except BudgetExceeded:
            reason = f"the exact (or symbolic) computation did not finish within {EXACT_SECONDS:g} s of CPU time"
            if any(x.free_symbols for M in data if M is not None for x in M):
                r = {"mode": "symbolic", "J": spec.J.subs(subs), "too_big": True, "W": None, "rdot": None,
                     "grad": None, "reason": reason + " (give values to the parameters for the numeric solution)"}
            else:
                r = _evaluate(spec, subs, "float")
        why = reason or (exact_reason(*data) if r["mode"] == "float" else None)
        if why and not r.get("too_big"):
            sol.step("numeric", reason=why)
        add("J_at", r["J"], "matrix", label="J\\big|_{*}")
        if r.get("grad") is not None:
            add("grad_H_at", r["grad"], "vector", label="\\nabla_q H\\big|_{*}")
        used = set().union(*[M.free_symbols for M in (spec.J, spec.W, spec.rdot, spec.q0) if M is not None])
        if spec.H is not None:
            used |= spec.H.free_symbols
        sol.step("config", state=spec.state, values={k: v for k, v in problem.values.items() if k in used},
                 r=r, J_num=_numeric_display(r["J"]), W_num=_numeric_display(r.get("W")))
    if r.get("too_big"):
        sol.step("too_big", m=m, n=n, reason=r.get("reason"), at=spec.state is not None)
        return sol
    if "rank" in r:
        add("rank", sp.Integer(r["rank"]), "number", label="\\operatorname{rank} J")
        add("singular", bool(r["rank"] < m), "bool", label="\\text{singular}")
    if r.get("generic_singular"):
        sol.step("generic_singular", rank=r["rank"], m=m)
        return sol
    pv: Pinv = r["pinv"]
    add("JJt", pv.JWJ, "matrix", label="J W^{-1} J^T" if spec.W is not None else "J J^T")
    add("det_JJt", pv.det, "scalar" if r["mode"] == "symbolic" else "number", label="\\det(J W^{-1} J^T)")
    add("J_pinv", pv.J_pinv, "matrix", label="J^{\\#}_W" if spec.W is not None else "J^{\\#}")
    sol.step("rank", r=r, m=m, n=n, singular=r["rank"] < m, weighted=spec.W is not None,
             mode=r["mode"], at=spec.state is not None)
    sol.step("pinv", r=r, pv=pv, weighted=spec.W is not None, mode=r["mode"],
             num=_numeric_display(pv.J_pinv), JWJ_num=_numeric_display(pv.JWJ))
    if "qdot_ps" not in r:
        return sol
    add("qdot_ps", r["qdot_ps"], "vector", label="\\dot q_{ps}")
    add("task_error", r["task_error"], "vector", label="J\\dot q - \\dot r")
    if "norm2_ps" in r:
        add("norm2_ps", r["norm2_ps"], None, label="\\tfrac12 \\|\\dot q_{ps}\\|^2")
    if "cost_ps" in r:
        add("cost_ps", r["cost_ps"], None, label="\\tfrac12 \\dot q_{ps}^T W \\dot q_{ps}")
    sol.step("qdot", r=r, weighted=spec.W is not None, num=_numeric_display(r["qdot_ps"]),
             singular=r["rank"] < m, exact_task=all(_exact_zero(x) if r["mode"] != "float" else abs(float(x)) < 1e-9
                                                    for x in r["task_error"]))
    if "q0" in r:
        add("qdot0", r["q0"], "vector", label="\\dot q_0")
        add("qdot_null", r["qdot_null"], "vector", label="(I - J^{\\#}J)\\dot q_0")
        sol.step("null", r=r, gradient=spec.H is not None, step=getattr(spec, "step", None),
                 num=_numeric_display(r["qdot"]), q0_num=_numeric_display(r["q0"]))
    add("qdot", r["qdot"], "vector", label="\\dot q")
    if options.sketch and spec.state is not None and problem.robot is not None and \
            set(spec.state) == set(problem.robot.q):  # a pose needs every coordinate
        _old_path_sketch(sol, problem, spec)
    if "qdot_mn" in r:
        add("qdot_mn", r["qdot_mn"], "vector", label="\\dot q_{mn} = J^{+}\\dot r")
        add("cost_mn", r["cost_mn"], None, label="\\tfrac12 \\dot q_{mn}^T W \\dot q_{mn}")
        add("norm2_mn", r["norm2_mn"], None, label="\\tfrac12 \\|\\dot q_{mn}\\|^2")
        sol.step("compare", r=r, num={k: _numeric_display(r[k]) for k in
                                      ("qdot_mn", "cost_ps", "cost_mn", "norm2_ps", "norm2_mn")},
                 inertia=getattr(spec, "weight_is_inertia", False))
    return sol


def _old_path_sketch(sol: Solution, problem, spec: _Spec) -> None:  # type: ignore[no-untyped-def]
    """The planar robot at the configuration, with the desired task velocity when the task is a planar position."""
    from solver.kinematics.sketch import robot_sketch
    task = spec.task if (spec.task is not None and spec.task.shape[0] == 2) else None
    arrows = []
    if task is not None and spec.rdot is not None:
        try:
            v = [float(sp.N(c.subs(problem.values))) for c in spec.rdot]
            pos = task.subs(problem.values).subs(spec.state)
            reach = max(0.2, float(sp.N(sp.sqrt(pos[0] ** 2 + pos[1] ** 2))))
            nv = float(np.hypot(*v))
            if nv > 0:
                arrows.append(("$\\dot r_d$", spec.state, pos, [x * 0.3 * reach / nv for x in v]))
        except (TypeError, ValueError):
            pass
    try:
        fig = robot_sketch(problem, [("$q$", spec.state)], task=task, arrows=arrows,
                           name="sketch" + spec.options.suffix, caption="The robot at the configuration used"
                           + (", with the desired task velocity" if arrows else ""))
    except (TypeError, ValueError):
        fig = None
    if fig is not None:
        sol.figures.append(fig)
