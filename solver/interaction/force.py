"""Force control: a robot in contact with an environment (ask kind ``force_control``).

The robot is the problem's (its dynamic model B q̈ + c + g + F_v q̇ = G u, any n); the contact is at p(q) ∈ Rᵐ,
J_c = ∂p/∂q, either with an elastic environment or with an exogenous force:

    elastic:     F_c = K_e (p − p_e)  (the force the robot exerts, measured),   B q̈ + n = G u − J_cᵀ (F_c + D_e ṗ)
    exogenous:   B q̈ + n = G u + J_cᵀ F   (F applied on the robot; ``on: environment``: − J_cᵀ F_c)

Laws (gains: scalars, diagonal lists or matrices), e_F = F_d − F_c, ξ̇ = e_F:

    force        u = c_ff F_d + K_f e_F + K_I ξ − K_D v                     (one input, v = Gᵀ q̇), or
                 G u = J_cᵀ (c_ff F_d + K_f e_F + K_I ξ) − K_D q̇ + g(q)     (square G)
                 with ``inertia`` M_d (inverse dynamics):  M_d p̈ + K_D ṗ = K_f e_F + K_I ξ (+ Λ⁻¹ M_d e_F)
    compliance   G u = Jᵀ K_P (p_d − p) − K_D q̇ + g(q) (+ J_cᵀ K̂_e (p − p̂_e): estimated contact compensation)
    impedance    M_d (p̈ − p̈_d) + D_d (ṗ − ṗ_d) + K_d (p − p_d) = F  (F on the robot, measured);
                 without force sensing M_d = Λ(q) = J⁻ᵀ B J⁻¹
    admittance   M_d p̈_c + D_d ṗ_c + K_d (p_c − p_d) = F gives the reference p_c of an ideal inner position loop
    hybrid       see :mod:`solver.interaction.hybrid`

For a linear closed loop the report gives the transfer functions, the characteristic polynomial, the Routh
conditions, the equilibrium (steady-state force and position), free motion, gain design for given poles, and a
simulation (exact steps of the matrix exponential, `linear.simulate`) against the predicted steady state.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field, model_validator

from solver.dynamics.model import derive, has_model
from solver.interaction import linear as lti
from solver.math.equivalence import conditions_equiv, scalar_equiv
from solver.math.numeric import lambdify_np
from solver.math.opcount import count_ops
from solver.math.simplify import factor_within, tidy
from solver.registry import PROPERTY_CHECKS, PropertyVerdict, ask_kind, property_check
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
LAWS = {"force": "force control", "compliance": "compliance (stiffness) control",
        "impedance": "impedance control", "admittance": "admittance control",
        "hybrid": "hybrid force/velocity control", "none": "contact model"}


class ContactSpec(Strict):
    """Where and how the robot touches the environment."""

    position: ExprT = Field(description="contact coordinates p(q) (m components, or one expression); J_c = ∂p/∂q")
    rest: Optional[ExprT] = Field(None, description="rest position p_e of the environment (default 0)")
    stiffness: Optional[ExprT] = Field(
        None, description="elastic environment (or sensor) stiffness K_e > 0: one expression, m diagonal entries or "
                          "an m x m matrix; F_c = K_e (p - p_e) is the force the robot exerts (measured)")
    damping: Optional[ExprT] = Field(None, description="environment damping D_e >= 0 (not part of the measured force)")
    force: Optional[ExprT] = Field(None, description="instead of stiffness: an exogenous contact force (symbols)")
    on: Literal["robot", "environment"] = Field(
        "robot", description="the exogenous force acts on the robot (impedance: F) or is the force the robot "
                             "exerts on the environment (measured F_c)")
    measured: Optional[Union[str, list[str]]] = Field(
        None, description="elastic contact: the name(s) of the measured force in the laws (default F_c)")

    @model_validator(mode="after")
    def _one(self) -> "ContactSpec":
        if (self.stiffness is None) == (self.force is None):
            raise ValueError("give exactly one of stiffness: (an elastic environment) or force: (an exogenous force)")
        if self.force is not None and self.damping is not None:
            raise ValueError("damping: belongs to an elastic environment (with stiffness:)")
        return self


class DesignSpec(Strict):
    """Closed-loop poles to place; the listed gains are solved for."""

    poles: Optional[ExprT] = Field(None, description="the closed-loop poles (per direction for impedance)")
    omega_n: Optional[Scalar] = Field(None, description="natural frequency of a second-order loop")
    zeta: Optional[Scalar] = Field(None, description="damping ratio of a second-order loop")
    gains: Optional[list[str]] = Field(
        None, description="the symbols to solve for (default: impedance D_d and K_d; force laws their gains)")

    @model_validator(mode="after")
    def _what(self) -> "DesignSpec":
        if (self.poles is None) == (self.omega_n is None and self.zeta is None):
            raise ValueError("give either poles: or omega_n: and zeta:")
        if self.poles is None and (self.omega_n is None or self.zeta is None):
            raise ValueError("give both omega_n: and zeta:")
        return self


class SimulateSpec(Strict):
    time: Optional[float] = Field(None, description="simulated time [s] (default from the slowest pole)")
    initial: dict[str, Scalar] = Field({}, description="initial coordinates (default: at rest at the contact)")


class EstimateSpec(Strict):
    stiffness: Optional[ExprT] = Field(None, description="the estimate of K_e used by the law (default the true one)")
    rest: Optional[ExprT] = Field(None, description="the estimate of p_e used by the law")


class ForceControlAsk(Strict):
    """Interaction control: contact model, force/compliance/impedance/admittance/hybrid laws and their analysis."""

    kind: Literal["force_control"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    law: Literal["force", "compliance", "impedance", "admittance", "hybrid", "none"] = Field(
        "force", description="force: explicit force regulation (P/PI, feed-forward, damping, inverse dynamics); "
                             "compliance: PD on position; impedance; admittance; hybrid force/velocity; none: the "
                             "open-loop contact model only")
    contact: Optional[ContactSpec] = Field(None, description="the contact (elastic environment or exogenous force)")
    desired: Optional[ExprT] = Field(None, description="desired contact force F_d (default the symbol F_d)")
    kf: Optional[ExprT] = Field(None, description="force error gain K_f (default k_f); 0 for none")
    ki: Optional[ExprT] = Field(None, description="integral gain K_I on the force error (default: no integral)")
    kd: Optional[ExprT] = Field(None, description="velocity damping K_D (force law: default none; compliance: k_d)")
    kp: Optional[ExprT] = Field(None, description="compliance: position gain K_P (default k_p)")
    feedforward: Optional[Scalar] = Field(None, description="force law: coefficient c_ff of F_d (1: F_d fed forward)")
    compensate: Optional[Literal["measured", "desired"]] = Field(
        None, description="force law with inertia: cancel the measured contact force (default) or feed F_d instead")
    cancel_contact: bool = Field(False, description="compliance: add the (estimated) contact force K̂_e (p - p̂_e)")
    estimate: Optional[EstimateSpec] = Field(None, description="compliance: estimates used by the law")
    reference: Optional[ExprT] = Field(None, description="compliance/impedance/admittance: a constant p_d")
    reference_force: Optional[ExprT] = Field(
        None, description="compliance: p_d such that K̂_e (p_d - p̂_e) = F_d (the rest position giving F_d)")
    regulation: bool = Field(False, description="impedance/admittance: constant p_d (dp_d = ddp_d = 0)")
    inertia: Optional[ExprT] = Field(None, description="impedance/admittance M_d, or force law with inverse dynamics")
    damping: Optional[ExprT] = Field(None, description="impedance/admittance D_d (default d_d..)")
    stiffness: Optional[ExprT] = Field(None, description="impedance/admittance K_d (default k_d..)")
    sensing: bool = Field(True, description="impedance: with force sensing (false: M_d = Λ(q), no force needed)")
    design: Optional[DesignSpec] = Field(None, description="place the closed-loop poles by choosing gains")
    free_motion: bool = Field(False, description="also analyze the loop without contact (F_c = 0)")
    simulate: Optional[Union[bool, SimulateSpec]] = Field(
        None, description="plot the contact force and position (needs numbers: `values:`, missing ones set to 1)")
    task: Optional[ExprT] = Field(None, description="task coordinates p(q) (default: the contact position or q)")
    jacobian: Optional[ExprT] = Field(None, description="hybrid: the task Jacobian J(q), instead of task:")
    frame: Optional[ExprT] = Field(None, description="hybrid: task-frame axes in the base frame (columns of R)")
    axes: Optional[list[str]] = Field(None, description="hybrid: names of the task directions (default x, y, z, "
                                                          "rx, ry, rz for m = 6)")
    force: Optional[list[str]] = Field(None, description="hybrid: force-controlled directions (natural: v = 0)")
    motion: Optional[list[str]] = Field(None, description="hybrid: motion-controlled directions (natural: F = 0)")
    augment: Optional[ExprT] = Field(None, description="hybrid: extra motion rows (redundant robot), e.g. [q3]")
    nominal: Optional[dict[str, dict[str, Scalar]]] = Field(
        None, description="hybrid: {acceleration: {dir: value}, force: {dir: value}}: the feed-forward command")
    velocity: Optional[dict[str, Scalar]] = Field(None, description="hybrid: task velocities {dir: value} -> q̇")
    at: Optional[dict[str, Scalar]] = Field(None, description="hybrid: a state {dq3: 0, ...} for u_nominal_at")
    kv: Optional[ExprT] = Field(None, description="hybrid: velocity gains (default k_v..)")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")


# ------------------------------------------------------------------------------------------------ helpers
def fresh(problem, name: str, tex: str | None = None, **assume: bool) -> sp.Symbol:  # type: ignore[no-untyped-def]
    """The problem's symbol ``name`` if declared, else a new one registered in the problem's names."""
    s = problem.names.get(name)
    if isinstance(s, sp.Symbol):
        return s
    s = sp.Symbol(name, **(assume or {"real": True}))
    problem.names[name] = s
    problem.latex_names.setdefault(s, tex or _tex_name(name))
    return s


def _tex_name(name: str) -> str:
    """x_d -> x_{d}, dx_d -> \\dot x_{d}, ddx_d -> \\ddot x_{d}, F_d -> F_{d}."""
    greek = {"xi": "\\xi", "lambda": "\\lambda", "mu": "\\mu", "omega": "\\omega", "tau": "\\tau"}
    for pre, acc in (("dd", "\\ddot "), ("d", "\\dot ")):
        if name.startswith(pre) and "_" in name and len(name.split("_")[0]) > len(pre):
            return acc + "{" + _tex_name(name[len(pre):]) + "}"
    head, _, tail = name.partition("_")
    m = len(head.rstrip("0123456789"))
    base, idx = head[:m], head[m:]
    base = greek.get(base, base)
    sub = ",".join(x for x in (idx, tail.replace("_", ",")) if x)
    return f"{base}_{{{sub}}}" if sub else base


_TF_KEYS = {"P", "den", "num", "W", "We", "L", "poly"}  # always given as N(s)/D(s) term lists, even constant


def _step(sol: Solution, name: str, **data: Any) -> None:
    """A report step; 1x1 matrices become scalars, the contact a dict of its parts, and rational functions of s
    come with their numerator and denominator terms in descending powers (``<key>_frac``)."""
    out: dict[str, Any] = {}
    s = data.get("s")
    for k, v in data.items():
        if isinstance(v, Contact):
            v = {"p": scalar_if_1(v.p), "J": scalar_if_1(v.J), "rest": scalar_if_1(v.rest), "K": scalar_if_1(v.K),
                 "D": scalar_if_1(v.D), "force": scalar_if_1(v.force), "on": v.on, "elastic": v.elastic, "m": v.m}
        out[k] = scalar_if_1(v)
        if s is not None and isinstance(out[k], sp.Expr) and (out[k].has(s) or k in _TF_KEYS):
            out[k + "_frac"] = frac_terms(out[k], s)
    sol.step(name, **out)


S_SHOW = sp.Symbol("zzs")  # the Laplace variable in printed polynomials: its name sorts it after the coefficients


def frac_terms(e: sp.Expr, s: sp.Symbol) -> tuple[list[sp.Expr], list[sp.Expr]]:
    """Numerator and denominator of a rational function of s as lists of terms c_k s^k, highest power first.
    Memoized (the plant's P, A(s), N(s) recur in each ask of a problem)."""
    num, den = _frac_terms(sp.sympify(e), s)
    return list(num), list(den)


@lru_cache(maxsize=512)
def _frac_terms(e: sp.Expr, s: sp.Symbol) -> tuple[tuple[sp.Expr, ...], tuple[sp.Expr, ...]]:
    num, den = sp.fraction(sp.together(e))

    def terms(p: sp.Expr) -> list[sp.Expr]:
        if not p.has(s):
            return [p]
        poly = sp.Poly(sp.expand(p), s)
        out = []
        for (k,), c in zip(poly.monoms(), poly.coeffs()):
            f = factor_within(c)
            c = f if count_ops(f) <= count_ops(c) else c
            out.append(c * S_SHOW**k)
        return out

    return tuple(terms(num)), tuple(terms(den))


def nice(e: sp.Expr, state: list[sp.Symbol] | None = None) -> sp.Expr:
    """A readable, equivalent form: with ``state``, collected in the state variables (coefficients and the
    constant part factored); otherwise the shortest of factor(e) and s + factor(e - s) for a symbol s of e
    (d + k_p F_d/(k_e (k_e + k_p)) rather than one fraction)."""
    if count_ops(e) > 300:  # bounded work: large expressions are left as they are
        return e
    e = sp.expand(e)
    if state:
        terms = sp.collect(e, state, evaluate=False)
        out = sp.Integer(0)
        for k, c in terms.items():
            f = factor_within(c) if count_ops(c) < 80 else c
            out += (f if count_ops(f) <= count_ops(c) else c) * k
        return out
    best = factor_within(e)
    if count_ops(best) > 200:
        return e
    for x in sorted(e.free_symbols, key=lambda v: v.name):
        cand = x + factor_within(e - x)
        if count_ops(cand) < count_ops(best):
            best = cand
    return best


def nice_matrix(M: sp.Matrix, state: list[sp.Symbol] | None = None) -> sp.Matrix:
    return M.applyfunc(lambda x: nice(x, state))


def scalar_if_1(M: Any) -> Any:
    """A 1x1 matrix as its entry (results of 1-dof problems print and compare as scalars)."""
    if isinstance(M, sp.MatrixBase) and M.shape == (1, 1):
        return M[0, 0]
    return M


@dataclass
class Contact:
    p: sp.Matrix                      # contact coordinates p(q)
    J: sp.Matrix                      # ∂p/∂q
    rest: sp.Matrix
    K: sp.Matrix | None               # environment stiffness (elastic)
    D: sp.Matrix | None               # environment damping
    force: sp.Matrix | None           # exogenous force symbols
    on: str = "robot"

    @property
    def m(self) -> int:
        return self.p.rows

    @property
    def elastic(self) -> bool:
        return self.K is not None

    def Fc(self) -> sp.Matrix:
        """The force the robot exerts on the environment (measured): K_e (p - p_e), or the exogenous one."""
        if self.K is not None:
            return self.K * (self.p - self.rest)
        assert self.force is not None
        return -self.force if self.on == "robot" else self.force

    def generalized(self, dq: sp.Matrix) -> sp.Matrix:
        """The generalized force of the contact on the robot: −J_cᵀ(F_c + D_e ṗ), or J_cᵀ F."""
        F = self.Fc()
        if self.D is not None:
            F = F + self.D * self.J * dq
        return -(self.J.T * F)


class Ctx:
    """Parsing helpers for one ask entry (errors at the entry's lines)."""

    def __init__(self, problem, options: ForceControlAsk, ctx) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.options, self.ctx = problem, options, ctx

    def fail(self, sub: tuple, message: str, hint: str | None = None) -> UserError:
        return UserError(message, self.problem.located.place(self.ctx.path + sub), hint)

    def vector(self, sub: tuple, size: int | None, what: str) -> sp.Matrix:
        val = self.ctx.expr(*sub)
        if not isinstance(val, list):
            val = [val]
        shp = shape_of(val)
        if len(shp) != 1 or (size is not None and shp[0] != size):
            want = f"{size} component{'s' if size != 1 else ''}" if size else "a vector"
            raise self.fail(sub, f"{what} must have {want}, got shape {shp}", "write [a, b, ...] (one per direction)")
        return sp.Matrix(val)

    def square(self, sub: tuple, m: int, what: str, positive: bool | None = None) -> sp.Matrix:
        """An m x m matrix from one expression (times I), m diagonal entries, or a full matrix; ``positive``:
        True requires > 0 (definite), False requires >= 0; provably wrong entries are errors."""
        val = self.ctx.expr(*sub)
        shp = shape_of(val)
        if shp == ():
            M = val * sp.eye(m)
        elif shp == (m,):
            M = sp.diag(*val)
        elif shp == (m, m):
            M = sp.Matrix(val)
        else:
            raise self.fail(sub, f"{what} must be one expression, {m} diagonal entries or a {m}x{m} matrix, got "
                                 f"shape {shp}", f"the contact has {m} direction{'s' if m > 1 else ''}")
        if any(sp.simplify(x) != 0 for x in (M - M.T)):
            raise self.fail(sub, f"{what} must be symmetric")
        if positive is not None:
            self._check_sign(sub, M, what, positive)
        return M

    def _check_sign(self, sub: tuple, M: sp.Matrix, what: str, strict: bool) -> None:
        word = "positive" if strict else "non-negative"
        if not M.free_symbols:
            ev = np.linalg.eigvalsh(np.array(M.evalf().tolist(), dtype=float))
            if (ev.min() <= 0) if strict else (ev.min() < 0):
                raise self.fail(sub, f"{what} must be {word} (definite), got eigenvalue {ev.min():.4g}",
                                f"a physical {what} is {word}")
            return
        for i in range(M.rows):
            d = M[i, i]
            bad = (d.is_nonpositive if strict else d.is_negative)
            if bad:
                raise self.fail(sub, f"{what} must be {word}, but its entry {i + 1} is {d}",
                                "declare the symbol positive (the default) or give a positive number")


def parse_contact(c: Ctx, q: list[sp.Symbol]) -> Contact:
    spec = c.options.contact
    assert spec is not None
    p = c.vector(("contact", "position"), None, "contact position")
    m = p.rows
    J = p.jacobian(q).applyfunc(tidy)
    if all(x == 0 for x in J):
        raise c.fail(("contact", "position"), "the contact position does not depend on the coordinates",
                     "write p(q), e.g. x - d or [q1, q2]")
    rest = c.vector(("contact", "rest"), m, "rest position") if spec.rest is not None else sp.zeros(m, 1)
    K = D = F = None
    if spec.stiffness is not None:
        K = c.square(("contact", "stiffness"), m, "stiffness", positive=True)
        if spec.damping is not None:
            D = c.square(("contact", "damping"), m, "damping", positive=False)
    else:
        F = c.vector(("contact", "force"), m, "contact force")
    return Contact(p, J, rest, K, D, F, spec.on)


def gain(c: Ctx, key: str, m: int, default: str | None, tex: str | None = None) -> sp.Matrix | None:
    """A gain matrix from the ask (one expression, a diagonal list, a matrix) or default symbols (k_f or
    k_f1..k_fm); None when absent without a default."""
    if getattr(c.options, key) is not None:
        return c.square((key,), m, key)
    if default is None:
        return None
    if m == 1:
        return sp.Matrix([[fresh(c.problem, default, tex, positive=True)]])
    return sp.diag(*[fresh(c.problem, f"{default}{i + 1}", None, positive=True) for i in range(m)])


@dataclass
class Analysis:
    """What a linear closed loop gives (every field optional)."""

    loop: lti.LinearLoop | None = None
    reason: str = ""
    poly: sp.Expr | None = None
    column: list[sp.Expr] = field(default_factory=list)
    conditions: list[sp.Expr] = field(default_factory=list)
    stable: bool | None = None
    witness: dict[sp.Symbol, sp.Expr] | None = None
    factors: list[tuple[sp.Expr, int]] = field(default_factory=list)
    columns: list[list[sp.Expr]] = field(default_factory=list)
    deltas: list[sp.Expr] = field(default_factory=list)
    poles: list[sp.Expr] | None = None
    marginal: bool | None = None     # not asymptotically stable: marginally stable for all parameters (or not)
    eq: sp.Matrix | None = None
    extras: dict[str, Any] = field(default_factory=dict)


def analyze(residual: sp.Matrix, x: list, dx: list, ddx: list, s: sp.Symbol, steady: dict) -> Analysis:
    """Characteristic polynomial, Routh column and conditions, poles, equilibrium (with ``steady`` substituted:
    constant references) of a closed-loop residual."""
    out = Analysis()
    try:
        loop = lti.linear_loop(residual, x, dx, ddx)
    except lti.NotLinear as exc:
        out.reason = str(exc)
        return out
    out.loop = loop
    poly = lti.char_poly(loop, s)
    out.poly = poly
    out.factors = lti.s_factors(poly, s)
    if all(sp.Poly(f, s).degree() <= lti.MAX_SYMBOLIC_DEGREE for f, _ in out.factors):
        out.columns = [lti.routh_column(lti.coefficients(f, s)) for f, _ in out.factors]
        if len(out.factors) == 1:
            co = lti.coefficients(out.factors[0][0], s)
            out.deltas = [co[0]] + lti.short_hurwitz_determinants(co)[:-1]  # Δ_n = b_n Δ_{n-1}
        out.column = out.columns[0] if len(out.factors) == 1 and out.factors[0][1] == 1 else []
        out.conditions = lti.hurwitz_conditions([c for col in out.columns for c in col])
        out.stable, out.witness = lti.stable_for_all(out.conditions) if out.conditions else (True, None)
        if any(x == -1 for x in out.conditions):  # a Routh entry ≤ 0 for all parameters: a root at s = 0?
            out.marginal = lti.marginal_for_all(loop, out.factors, s)
    roots = [lti.short_poles(f, s) for f, k in out.factors for _ in range(k)]
    out.poles = None if any(r is None for r in roots) else [x for r in roots for x in r]
    st = lti.LinearLoop(loop.x, loop.dx, loop.ddx, loop.A2, loop.A1, loop.A0, loop.r0.xreplace(steady))
    out.eq = lti.equilibrium(st)
    return out


# ------------------------------------------------------------------------------------------------ setup
@dataclass
class Setup:
    """The robot's model and the contact, with placeholders Fm for the measured force in the laws."""

    q: sp.Matrix
    dq: sp.Matrix
    ddq: sp.Matrix
    B: sp.Matrix
    nvec: sp.Matrix                  # c + g + F_v q̇
    g: sp.Matrix
    G: sp.Matrix
    u: sp.Matrix                     # input symbols
    contact: Contact | None
    Fm: sp.Matrix | None             # placeholder of the measured force in the law (substituted afterwards)
    s: sp.Symbol
    dm: Any

    @property
    def n(self) -> int:
        return self.q.rows

    def model(self, free: bool = False) -> sp.Matrix:
        """B q̈ + n − (contact force) − G u: the open-loop model as a residual."""
        tau_c = sp.zeros(self.n, 1) if (self.contact is None or free) else self.contact.generalized(self.dq)
        return (self.B * self.ddq + self.nvec - tau_c - self.G * self.u).applyfunc(sp.expand)

    def measured(self, free: bool = False) -> dict[sp.Symbol, sp.Expr]:
        """The measured force's symbols -> the force the robot exerts on the environment; in free motion -> 0
        (an exogenous force's own symbols -> 0)."""
        ct = self.contact
        if ct is None:
            return {}
        if not ct.elastic:
            return {f: 0 for f in ct.force} if free else {}
        Fc = sp.zeros(ct.m, 1) if free else ct.Fc()
        return dict(zip(self.Fm, Fc))


def _robot(c: Ctx):  # type: ignore[no-untyped-def]
    """The problem's robot, which needs dynamics."""
    problem = c.problem
    robot = problem.robot
    if robot is None or not has_model(robot):
        raise UserError("force_control needs the robot's dynamics, but the robot has no bodies and no model",
                        problem.located.place(("robot",)),
                        "give robot: {joints: [P], coordinates: [x], links: [{mass: m, com: [x, 0]}]} for a mass")
    return robot


def _contact(c: Ctx, robot) -> tuple[Contact | None, sp.Matrix | None]:  # type: ignore[no-untyped-def]
    """The contact of ``contact:`` and the measured force in the laws: its symbols (elastic contact: registered
    in the problem) or the exogenous force."""
    problem = c.problem
    contact = parse_contact(c, list(robot.q)) if c.options.contact is not None else None
    Fm = None
    if contact is not None and contact.elastic:
        names = c.options.contact.measured or ("F_c" if contact.m == 1 else [f"F_c{i + 1}" for i in range(contact.m)])
        names = [names] if isinstance(names, str) else list(names)
        if len(names) != contact.m or any(not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", x) for x in names):
            raise c.fail(("contact", "measured"), f"measured: must be {contact.m} name(s) of the measured force",
                         "e.g. measured: F_m")
        for x in names:
            if x in problem.names and x in {v.name for v in robot.q + robot.dq + robot.ddq}:
                raise c.fail(("contact", "measured"), f"'{x}' is a coordinate")
        Fm = sp.Matrix([fresh(problem, x, None, real=True) for x in names])
    elif contact is not None:
        Fm = contact.Fc()
    return contact, Fm


def setup(c: Ctx) -> Setup:
    problem = c.problem
    robot = _robot(c)
    dm = derive(robot)
    n = robot.n
    q, dq, ddq = sp.Matrix(robot.q), sp.Matrix(robot.dq), sp.Matrix(robot.ddq)
    nvec = dm.c + dm.g + (dm.Fv * dq if dm.Fv is not None else sp.zeros(n, 1))
    G = dm.G if dm.G is not None else sp.eye(n)
    contact, Fm = _contact(c, robot)
    problem.latex_names.setdefault(S_SHOW, "s")
    s = problem.names.get("s")
    if not isinstance(s, sp.Symbol):  # the Laplace variable, complex (answers may use it)
        s = lti.S
        problem.names.setdefault("s", s)
        problem.latex_names.setdefault(s, "s")
    return Setup(q, dq, ddq, dm.B, nvec.applyfunc(tidy), dm.g, G, sp.Matrix(dm.u), contact, Fm, s, dm)


def _component_names(problem, p: sp.Matrix) -> list[str]:  # type: ignore[no-untyped-def]
    """x for a task coordinate that is the coordinate x itself, else p (m = 1) or p1..pm."""
    out = []
    for i, e in enumerate(p):
        if isinstance(e, sp.Symbol) and e in set(problem.robot.q):
            out.append(e.name)
        else:
            out.append("p" if p.rows == 1 else f"p{i + 1}")
    return out


def references(c: Ctx, p: sp.Matrix, constant: bool) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """p_d, ṗ_d, p̈_d: the ask's constant reference, or symbols x_d, dx_d, ddx_d per task component (the
    problem's own when declared)."""
    m = p.rows
    if c.options.reference is not None:
        pd = c.vector(("reference",), m, "reference")
        return pd, sp.zeros(m, 1), sp.zeros(m, 1)
    names = _component_names(c.problem, p)
    pd = sp.Matrix([fresh(c.problem, f"{k}_d") for k in names])
    if constant:
        return pd, sp.zeros(m, 1), sp.zeros(m, 1)
    dpd = sp.Matrix([fresh(c.problem, f"d{k}_d") for k in names])
    ddpd = sp.Matrix([fresh(c.problem, f"dd{k}_d") for k in names])
    return pd, dpd, ddpd


def desired_force(c: Ctx, m: int) -> sp.Matrix:
    if c.options.desired is not None:
        return c.vector(("desired",), m, "desired force")
    if m == 1:
        return sp.Matrix([fresh(c.problem, "F_d", "F_{d}", positive=True)])
    return sp.Matrix([fresh(c.problem, f"F_d{i + 1}", f"F_{{d,{i + 1}}}", real=True) for i in range(m)])


def _inverse(c: Ctx, M: sp.Matrix, what: str, sub: tuple) -> sp.Matrix:
    """M⁻¹ = adj(M)/det(M), entries tidied (no general simplification: bounded work); a singular M is an error."""
    if M.rows != M.cols:
        raise c.fail(sub, f"{what} is {M.rows}x{M.cols}, not square", "the law needs as many inputs/task "
                                                                          "directions as coordinates")
    if M.is_diagonal():
        if any(_is_zero(M[i, i]) for i in range(M.rows)):
            raise c.fail(sub, f"{what} is singular (det = 0)")
        return sp.diag(*[1 / M[i, i] for i in range(M.rows)])
    det = tidy(M.det(method="berkowitz"))
    if _is_zero(det):
        raise c.fail(sub, f"{what} is singular (det = 0)")
    if not M.free_symbols:
        return M.inv()
    return (M.adjugate() / det).applyfunc(lambda x: tidy(sp.cancel(x)) if count_ops(x) < 300 else x)


def _is_zero(e: sp.Expr) -> bool:
    """Exactly zero (randomized exact test for trigonometric polynomials, see solver.math.equivalence)."""
    return e == 0 or scalar_equiv(e, 0).ok


def _dot(M: sp.Matrix, q: sp.Matrix, dq: sp.Matrix) -> sp.Matrix:
    """dM/dt = Σ ∂M/∂q_i q̇_i."""
    out = sp.zeros(*M.shape)
    for qi, dqi in zip(q, dq):
        out += M.diff(qi) * dqi
    return out.applyfunc(tidy)


@dataclass
class Law:
    """A law: its inputs u (with the placeholder Fm), the closed loop shown, and the residual to analyze."""

    u: sp.Matrix
    residual: sp.Matrix               # model-level closed loop (Fm substituted) + integral rows
    closed: sp.Matrix                 # the closed loop as shown (task form for inverse-dynamics laws)
    x: list[sp.Symbol]
    dx: list[sp.Symbol]
    ddx: list[sp.Symbol]
    steady: dict[sp.Symbol, sp.Expr]  # substitutions for constant references
    data: dict[str, Any]
    check: bool | None = None
    xi: list[sp.Symbol] = field(default_factory=list)
    plain_force: bool = False         # u = c_ff F_d + C(s) e_F - k_d v: the loop transfer L(s) exists
    free: sp.Matrix | None = None     # residual without contact


def _actuate(c: Ctx, S: Setup, f_task: sp.Matrix, J: sp.Matrix, kd: sp.Matrix | None,
             extra: sp.Matrix | None = None) -> tuple[sp.Matrix, sp.Matrix | None]:
    """Inputs that apply the task force f: single input (scalar task): u = f − k_d Gᵀq̇ (+ extra);
    square G: G u = Jᵀ f − K_D q̇ + g(q) (+ extra)."""
    G = S.G
    if G.rows == G.cols:
        tau = J.T * f_task + S.g
        if kd is not None:
            tau -= kd * S.dq
        if extra is not None:
            tau += extra
        Gi = _inverse(c, G, "the input map G", ("law",))
        return (Gi * tau if G != sp.eye(G.rows) else tau), tau
    if G.cols == 1 and f_task.rows == 1:
        u = f_task[0] - (kd[0, 0] * (G.T * S.dq)[0] if kd is not None else 0)
        if extra is not None:
            u += extra[0]
        return sp.Matrix([u]), None
    raise c.fail(("law",), f"this law needs a square input map or a single input with a scalar contact; G is "
                           f"{G.rows}x{G.cols}", "check robot.input_map")


def _closed(S: Setup, u: sp.Matrix, free: bool = False) -> sp.Matrix:
    """The model with the law's u and the measured force substituted (tidied when small: bounded work)."""
    r = S.model(free).xreplace(dict(zip(S.u, u)))
    return r.xreplace(S.measured(free)).applyfunc(lambda e: tidy(sp.expand(e)) if count_ops(e) < 200 else e)


def law_force(c: Ctx, S: Setup) -> Law:
    """Explicit force regulation (plain or with inverse dynamics)."""
    o = c.options
    if S.contact is None:
        raise c.fail(("law",), "law: force needs a contact: (where the force is measured)",
                     "add contact: {position: x, stiffness: k_e} or {position: x, force: F_c, on: environment}")
    ct = S.contact
    m = ct.m
    Fd = desired_force(c, m)
    Kf = gain(c, "kf", m, "k_f", "k_{f}")
    Ki = gain(c, "ki", m, None)
    e = Fd - S.Fm
    xi = [fresh(c.problem, "xi" if m == 1 else f"xi{i + 1}", "\\xi" if m == 1 else f"\\xi_{{{i + 1}}}")
          for i in range(m)] if Ki is not None else []
    dxi = [fresh(c.problem, "d" + x.name, "\\dot\\xi" + ("" if m == 1 else f"_{{{i + 1}}}"))
           for i, x in enumerate(xi)]
    ddxi = [sp.Dummy("ddxi") for _ in xi]
    f = Kf * e
    if Ki is not None:
        f += Ki * sp.Matrix(xi)
    data: dict[str, Any] = {"Fd": Fd, "Kf": Kf, "Ki": Ki, "xi": sp.Matrix(xi) if xi else None, "m": m,
                            "Fd_plain": o.desired is None}
    if o.inertia is not None:
        if o.feedforward is not None:
            raise c.fail(("feedforward",), "with inertia: (inverse dynamics) give compensate: desired instead of a "
                                           "feed-forward")
        Md = c.square(("inertia",), m, "inertia", positive=True)
        kd = gain(c, "kd", m, "k_d", "k_{d}")
        Ji = _inverse(c, ct.J, "the contact Jacobian J_c", ("contact", "position"))
        Mdi = _inverse(c, Md, "the inertia M_d", ("inertia",))
        a = Mdi * (f - kd * ct.J * S.dq)
        comp = ct.J.T * (S.Fm if (o.compensate or "measured") == "measured" else Fd)
        tau = S.B * Ji * (a - _dot(ct.J, S.q, S.dq) * S.dq) + S.nvec + comp
        Gi = _inverse(c, S.G, "the input map G", ("law",))
        u = (Gi * tau).applyfunc(lambda x: tidy(sp.expand(x)))
        data.update(kind="inverse", Md=Md, KD=kd, a=a.applyfunc(sp.expand), compensate=o.compensate or "measured")
        residual = _closed(S, u)
        Jb = Md * ct.J * _inverse(c, S.B, "B", ("robot",))
        closed = (Jb * residual).applyfunc(lambda x: tidy(sp.factor_terms(sp.expand(x))))
        residual = closed  # the task-space form: same poles and equilibria, without the factors B M_d⁻¹
        free = (Jb * _closed(S, u, free=True)).applyfunc(lambda x: tidy(sp.factor_terms(sp.expand(x))))
        plain = False
    else:
        cff = c.ctx.expr("feedforward") if o.feedforward is not None else sp.Integer(0)
        if isinstance(cff, list):
            raise c.fail(("feedforward",), "feedforward must be one expression (the coefficient of F_d)")
        f += cff * Fd
        single = S.G.cols == 1
        kd = gain(c, "kd", 1 if single else S.n, None)
        u, tau = _actuate(c, S, f, ct.J, kd)
        data.update(kind="plain", cff=cff, ff=cff * Fd, KD=kd, single=single, v=(S.G.T * S.dq) if single else S.dq)
        residual = _closed(S, u)
        closed = residual
        free = _closed(S, u, free=True)
        plain = True
    rows = [sp.expand(d - x) for d, x in zip(dxi, e.xreplace(S.measured()))]
    free_rows = [sp.expand(d - x) for d, x in zip(dxi, e.xreplace(S.measured(True)))]
    residual = residual.col_join(sp.Matrix(rows)) if rows else residual
    free = free.col_join(sp.Matrix(free_rows)) if free_rows else free
    gains = [x for M in (Kf, Ki, data.get("KD")) if M is not None for x in M.free_symbols]
    u = u.applyfunc(lambda x: sp.collect(sp.expand(x), sorted(gains, key=str)))
    return Law(u, residual, closed, list(S.q) + xi, list(S.dq) + dxi, list(S.ddq) + ddxi, {}, data,
               xi=xi, plain_force=plain, free=free)


def law_compliance(c: Ctx, S: Setup) -> Law:
    """PD on the task position (+ gravity, + estimated contact force)."""
    o = c.options
    ct = S.contact
    p = c.vector(("task",), None, "task") if o.task is not None else (ct.p if ct is not None else S.q)
    m = p.rows
    J = p.jacobian(list(S.q)).applyfunc(tidy)
    Kp = gain(c, "kp", m, "k_p", "k_{p}")
    single = S.G.cols == 1
    kd = gain(c, "kd", 1 if single else S.n, "k_d", "k_{d}")
    Khat, rest_hat = None, None
    data: dict[str, Any] = {"p": p, "J": J, "Kp": Kp, "KD": kd, "single": single}
    if (o.reference_force is not None or o.cancel_contact or o.estimate is not None) and \
            (ct is None or not ct.elastic):
        raise c.fail(("law",), "reference_force:, cancel_contact: and estimate: need an elastic contact "
                               "(contact: {position: ..., stiffness: ...})")
    if ct is not None and ct.elastic:
        Khat = c.square(("estimate", "stiffness"), ct.m, "estimated stiffness", positive=True) \
            if (o.estimate and o.estimate.stiffness is not None) else ct.K
        rest_hat = c.vector(("estimate", "rest"), ct.m, "estimated rest position") \
            if (o.estimate and o.estimate.rest is not None) else ct.rest
    if o.reference_force is not None:
        if ct is None or any(sp.simplify(a - b) != 0 for a, b in zip(p, ct.p)):
            raise c.fail(("reference_force",), "reference_force: needs the task to be the contact position")
        Fd = c.vector(("reference_force",), m, "reference force")
        pd = (rest_hat + _inverse(c, Khat, "the stiffness", ("contact", "stiffness")) * Fd).applyfunc(sp.expand)
        data.update(Fd=Fd, from_force=True)
    else:
        pd, _, _ = references(c, p, True)
        data.update(from_force=False)
    extra = None
    if o.cancel_contact:
        comp = ct.J.T * (Khat * (ct.p - rest_hat))
        extra = comp if S.G.rows == S.G.cols else comp
        data.update(Khat=Khat, rest_hat=rest_hat)
    u, tau = _actuate(c, S, Kp * (pd - p), J, kd, extra)
    data.update(pd=pd, cancel=o.cancel_contact, estimated=o.estimate is not None, Khat=Khat, rest_hat=rest_hat)
    residual = _closed(S, u)
    return Law(u, residual, residual, list(S.q), list(S.dq), list(S.ddq), {}, data,
               free=_closed(S, u, free=True))


def law_impedance(c: Ctx, S: Setup, admittance: bool = False) -> Law:
    """Impedance (or admittance): M_d (p̈ − p̈_d) + D_d (ṗ − ṗ_d) + K_d (p − p_d) = F."""
    o = c.options
    ct = S.contact
    if ct is not None and o.task is not None:
        raise c.fail(("task",), "the impedance is defined at the contact: remove task: (or the contact)")
    p = ct.p if ct is not None else (c.vector(("task",), None, "task") if o.task is not None else S.q)
    m = p.rows
    J = p.jacobian(list(S.q)).applyfunc(tidy)
    if J.rows != J.cols:
        raise c.fail(("contact", "position") if ct is not None else ("task",),
                     f"impedance control here needs as many task directions as coordinates ({m} vs {S.n})",
                     "give a task with one component per coordinate")
    Ji = _inverse(c, J, "the task Jacobian", ("contact", "position") if ct is not None else ("task",))
    Jdot = _dot(J, S.q, S.dq)
    pd, dpd, ddpd = references(c, p, o.regulation or o.reference is not None)
    sensing = o.sensing or admittance
    if not sensing and o.inertia is not None:
        raise c.fail(("inertia",), "without force sensing the apparent inertia is the robot's Λ(q) = J⁻ᵀ B J⁻¹",
                     "remove inertia: (or set sensing: true)")
    constant = not (J.free_symbols | S.B.free_symbols) & set(S.q)
    Lam = (Ji.T * S.B * Ji).applyfunc(tidy) if (constant or not o.sensing) else None  # Λ(q) only when used
    if sensing:
        Md = c.square(("inertia",), m, "inertia", positive=True) if o.inertia is not None else \
            (sp.Matrix([[fresh(c.problem, "M_d", "M_{d}", positive=True)]]) if m == 1 else
             sp.diag(*[fresh(c.problem, f"M_d{i + 1}", f"M_{{d,{i + 1}}}", positive=True) for i in range(m)]))
    else:
        Md = Lam
    Dd = c.square(("damping",), m, "damping", positive=True) if o.damping is not None else \
        (sp.Matrix([[fresh(c.problem, "D_d", "D_{d}", positive=True)]]) if m == 1 else
         sp.diag(*[fresh(c.problem, f"D_d{i + 1}", f"D_{{d,{i + 1}}}", positive=True) for i in range(m)]))
    Kd = c.square(("stiffness",), m, "stiffness", positive=True) if o.stiffness is not None else \
        (sp.Matrix([[fresh(c.problem, "K_d", "K_{d}", positive=True)]]) if m == 1 else
         sp.diag(*[fresh(c.problem, f"K_d{i + 1}", f"K_{{d,{i + 1}}}", positive=True) for i in range(m)]))
    design = None
    if o.design is not None:
        design = _design_impedance(c, S, Md, Dd, Kd)
        Dd, Kd = design["Dd"], design["Kd"]
    # the force on the robot, as measured (elastic: the total interaction force, damping included)
    if ct is None:
        Fr = sp.zeros(m, 1)
        Ftrue = Fr
    elif ct.elastic:
        Fr = -S.Fm - (ct.D * ct.J * S.dq if ct.D is not None else sp.zeros(m, 1))
        Ftrue = -(ct.Fc() + (ct.D * ct.J * S.dq if ct.D is not None else sp.zeros(m, 1)))
    else:
        Fr = -S.Fm
        Ftrue = -ct.Fc()
    err_dd, err_d, err = J * S.ddq + Jdot * S.dq - ddpd, J * S.dq - dpd, p - pd
    closed = (Md * err_dd + Dd * err_d + Kd * err - Ftrue).applyfunc(lambda x: tidy(sp.expand(x)))
    data: dict[str, Any] = {"p": p, "J": J, "Jdot": Jdot, "Md": Md, "Dd": Dd, "Kd": Kd, "Lam": Lam, "pd": pd,
                            "dpd": dpd, "ddpd": ddpd, "sensing": sensing, "design": design, "m": m,
                            "regulation": o.regulation or o.reference is not None, "admittance": admittance}
    if admittance:
        names = _component_names(c.problem, p)
        pc = sp.Matrix([fresh(c.problem, f"{k}_c") for k in names])
        dpc = sp.Matrix([fresh(c.problem, f"d{k}_c") for k in names])
        ddpc = sp.Matrix([fresh(c.problem, f"dd{k}_c") for k in names])
        Fmeas = Fr.xreplace(S.measured())
        filt = (Md * ddpc + Dd * dpc + Kd * (pc - pd) - Fmeas).applyfunc(lambda x: tidy(sp.expand(x)))
        data.update(pc=pc, dpc=dpc, ddpc=ddpc, filt=filt)
        # ideal inner position loop (p = p_c): the robot moves as the admittance
        u = sp.Matrix(S.u)
        law = Law(u, closed, closed, list(S.q), list(S.dq), list(S.ddq), {}, data, check=True)
    else:
        Mdi = _inverse(c, Md, "the inertia M_d", ("inertia",)) if sensing else None
        if sensing:
            a = ddpd - Jdot * S.dq + Mdi * (Dd * (dpd - J * S.dq) + Kd * (pd - p) + Fr)
            tau = S.B * Ji * a + S.nvec - J.T * Fr
        else:
            tau = S.B * Ji * (ddpd - Jdot * S.dq) + J.T * (Dd * (dpd - J * S.dq) + Kd * (pd - p)) + S.nvec
        Gi = _inverse(c, S.G, "the input map G", ("law",))
        u = (Gi * tau).applyfunc(lambda x: tidy(sp.expand(x)) if count_ops(x) < 150 else x)
        residual = _closed(S, u)
        # check: M_d J B⁻¹ (model residual) ≡ closed loop (exactly)
        Bi = _inverse(c, S.B, "B", ("robot",))
        chk = Md * J * Bi * residual - closed
        data.update(tau=tau)
        law = Law(u, closed, closed, list(S.q), list(S.dq), list(S.ddq), {}, data,
                  check=all(_is_zero(x) for x in chk))
    law.steady = {x: 0 for x in list(dpd) + list(ddpd) if isinstance(x, sp.Symbol)}
    if ct is not None:
        law.free = (Md * err_dd + Dd * err_d + Kd * err).applyfunc(lambda x: tidy(sp.expand(x)))
    return law


def _design_impedance(c: Ctx, S: Setup, Md: sp.Matrix, Dd: sp.Matrix, Kd: sp.Matrix) -> dict[str, Any]:
    """D_d = a₁ M_d, K_d = a₀ M_d for the target s² + a₁ s + a₀ (poles, or ω_n and ζ): every direction of
    M_d ë + D_d ė + K_d e = 0 then has the target's roots (det = det M_d · target^m)."""
    target = _target(c, S.s, 2)
    a = sp.Poly(target, S.s).all_coeffs()
    if Md.free_symbols & set(S.q):
        raise c.fail(("design",), "the apparent inertia M_d = Λ(q) depends on q: constant gains cannot place "
                                  "the poles", "use force sensing with a constant inertia:")
    Dn, Kn = (a[1] * Md).applyfunc(sp.factor), (a[2] * Md).applyfunc(sp.factor)
    return {"target": target, "Dd": Dn, "Kd": Kn, "Dd_given": Dd, "Kd_given": Kd}


def _target(c: Ctx, s: sp.Symbol, degree: int | None) -> sp.Expr:
    d = c.options.design
    assert d is not None
    if d.poles is not None:
        val = c.ctx.expr("design", "poles")
        ps = val if isinstance(val, list) else [val]
        if degree is not None and len(ps) != degree:
            raise c.fail(("design", "poles"), f"{len(ps)} poles given, the closed loop has {degree}")
        return lti.desired_polynomial(s, ps)
    wn, z = c.ctx.expr("design", "omega_n"), c.ctx.expr("design", "zeta")
    if degree not in (None, 2):
        raise c.fail(("design",), f"omega_n/zeta describe a second-order loop; this one has order {degree}",
                     "give poles: instead")
    return lti.desired_polynomial(s, omega_n=wn, zeta=z)


# ------------------------------------------------------------------------------------------------ the ask
def validate_force_control(problem, options: ForceControlAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The options read and checked as :func:`solve_force_control` reads them first (the law's options, the robot,
    the contact and the measured force; the hybrid law's task, frame, augmented rows and directions), without the
    model; each law's gains and the design are read when solving."""
    c = Ctx(problem, options, ctx)
    _validate_fields(c)
    if options.law == "hybrid":
        from solver.interaction.hybrid import read_hybrid
        read_hybrid(c)
    else:
        _contact(c, _robot(c))


@ask_kind("force_control", ForceControlAsk,
          "interaction control: contact model, force/compliance/impedance/admittance/hybrid laws, transfer "
          "functions, Routh conditions, steady-state force and position, gain design, simulation",
          validate=validate_force_control)
def solve_force_control(problem, options: ForceControlAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (each with the ask's suffix): model, F_c, u, closed_loop, closed_loop_check, equilibrium, F_c_eq,
    force_error, u_eq, reference, P, P_num, P_den, tf_q, L, W, W_e, char_poly, routh, stability, stable, poles,
    M_d, D_d, K_d, omega_n, zeta, gains, free_closed_loop, free_velocity, free_input, admittance; hybrid: see
    :mod:`solver.interaction.hybrid`."""
    c = Ctx(problem, options, ctx)
    _validate_fields(c)
    if options.law == "hybrid":
        from solver.interaction.hybrid import solve_hybrid
        return solve_hybrid(c)
    S = setup(c)
    sfx = options.suffix
    sol = Solution("force_control", title=options.title or f"{LAWS[options.law].capitalize()}")

    def add(name: str, value: Any, kind: str | None = None, label: str = "") -> None:
        sol.add(name + sfx, scalar_if_1(value), kind, label=label)

    ct = S.contact
    model = nice_matrix(S.model(), list(S.ddq) + list(S.dq) + list(S.q) + list(S.u))
    add("model", model, label="B\\ddot q + n - \\tau_c - G u")
    Fc = ct.Fc() if ct is not None else None
    if ct is not None and ct.elastic:
        add("F_c", Fc, label="F_c")
    _step(sol, "model", B=S.B, nvec=S.nvec, G=S.G, u=S.u, n=S.n, model=model, contact=ct,
             Fc=Fc, q=S.q, single=S.G.cols == 1, linear=_is_linear(S))
    plant = None
    if ct is not None and ct.elastic and ct.m == 1 and S.G.cols == 1:
        plant = _plant(S, model, Fc[0])
        add("P", plant["P"], "scalar", label="P(s) = F_c(s)/U(s)")
        add("P_den", plant["den"], "scalar", label="A(s)")
        add("P_num", plant["num"], "scalar", label="N(s)")
        add("tf_q", plant["tf_q"], "vector", label="Q(s)/U(s)")
        _step(sol, "plant", **plant, s=S.s)
    if options.law == "none":
        return sol
    builder = {"force": law_force, "compliance": law_compliance, "impedance": law_impedance,
               "admittance": lambda c_, S_: law_impedance(c_, S_, admittance=True)}[options.law]
    law = builder(c, S)
    if options.law == "force" and options.design is not None:
        law = _design_force(c, S, law, sol, add)
    if options.law != "admittance":
        signals = [x for x in law.data.get("ddpd", []) if isinstance(x, sp.Symbol)] + \
            [x for x in law.data.get("dpd", []) if isinstance(x, sp.Symbol)] + \
            [x for x in law.data.get("pd", []) if isinstance(x, sp.Symbol)] + list(S.dq) + list(S.q)
        if ct is not None:
            signals += sorted((ct.force.free_symbols if ct.force is not None else set(S.Fm)), key=str)
        if options.law == "impedance" or law.data.get("kind") == "inverse":
            law.u = nice_matrix(law.u, signals)
        add("u", law.u, label="u")
    if options.law in ("compliance",) and law.data.get("from_force"):
        add("reference", nice_matrix(law.data["pd"]), label="p_d")
    if options.law in ("impedance", "admittance"):
        d = law.data
        add("M_d", d["Md"], label="M_d")
        add("D_d", d["Dd"], label="D_d")
        add("K_d", d["Kd"], label="K_d")
        if d["design"] is not None and problem.values:
            for key, name in (("Dd", "D_d"), ("Kd", "K_d")):
                num = d[key].xreplace(problem.values).applyfunc(sp.nsimplify)
                if num != d[key]:
                    add(name + "_num", num.evalf(8) if num.free_symbols == set() and
                        any(not x.is_Rational for x in num) else num, label=name)
        wz = _omega_zeta(d["Md"], d["Dd"], d["Kd"])
        if wz is not None:
            add("omega_n", wz[0], label="\\omega_n")
            add("zeta", wz[1], label="\\zeta")
        if options.law == "admittance":
            add("admittance", d["filt"], label="M_d\\ddot p_c + D_d\\dot p_c + K_d(p_c - p_d) - F")
        _step(sol, "impedance", **d, wz=wz, u=law.u, law=options.law, u_short=count_ops(law.u) < 800)
    else:
        _step(sol, "law", law=options.law, u=law.u, **law.data)
    law.closed = nice_matrix(law.closed, law.ddx + law.dx + law.x)
    add("closed_loop", law.closed, label="\\text{closed loop}")
    if law.check is not None:
        add("closed_loop_check", bool(law.check), "bool", label="\\text{closed loop verified}")
    _step(sol, "closed_loop", law=options.law, closed=law.closed, check=law.check, xi=law.xi,
             inverse=law.data.get("kind") == "inverse", n=S.n)
    an = analyze(law.residual, law.x, law.dx, law.ddx, S.s, law.steady)
    _report_analysis(c, S, law, an, sol, add, plant)
    if options.free_motion:
        _free_motion(c, S, law, sol, add)
    if options.simulate and an.loop is not None and (ct is not None):
        fig = _figure(c, S, law, an)
        if fig is not None:
            sol.figures.append(fig)
    _register_checks(sfx)
    return sol


def _validate_fields(c: Ctx) -> None:
    """Options that belong to other laws are errors (at their line)."""
    o = c.options
    hybrid_only = ("jacobian", "frame", "axes", "force", "motion", "augment", "nominal", "velocity", "at", "kv")
    by_law = {
        "force": {"desired", "kf", "ki", "kd", "feedforward", "inertia", "compensate", "design", "free_motion",
                  "simulate"},
        "compliance": {"kp", "kd", "reference", "reference_force", "cancel_contact", "estimate", "task",
                       "free_motion", "simulate"},
        "impedance": {"inertia", "damping", "stiffness", "sensing", "reference", "regulation", "design", "task",
                      "free_motion", "simulate"},
        "admittance": {"inertia", "damping", "stiffness", "reference", "regulation", "design", "task",
                       "free_motion", "simulate"},
        "hybrid": set(hybrid_only) | {"task", "contact"},
        "none": set(),
    }
    allowed = by_law[o.law] | {"kind", "title", "law", "contact", "suffix"}
    for key in o.model_fields_set:
        if key not in allowed:
            yaml_key = "lambda" if key == "lam" else key
            raise c.fail((yaml_key,), f"{yaml_key}: is not an option of law: {o.law}",
                         "options by law are listed in docs/spec.md (force_control)")
    if o.law == "force" and o.compensate is not None and o.inertia is None:
        raise c.fail(("compensate",), "compensate: goes with inertia: (inverse-dynamics force control)")


def _is_linear(S: Setup) -> bool:
    try:
        lti.linear_loop(S.model(), list(S.q), list(S.dq), list(S.ddq))
        return True
    except lti.NotLinear:
        return False


def _plant(S: Setup, model: sp.Matrix, Fc: sp.Expr) -> dict[str, Any]:
    """Open loop: P(s) = F_c(s)/U(s) = N(s)/A(s), A(s) = det(B s² + D s + K), and Q(s)/U(s). Memoized on the
    model and the contact force (the asks of a problem with one plant: P, force, force + integral)."""
    out = _plant_of(sp.ImmutableMatrix(model), sp.sympify(Fc), tuple(S.q), tuple(S.dq), tuple(S.ddq), S.u[0], S.s)
    return {k: (v.as_mutable() if isinstance(v, sp.MatrixBase) else v) for k, v in out.items()}


@lru_cache(maxsize=32)
def _plant_of(model: sp.ImmutableMatrix, Fc: sp.Expr, q: tuple, dq: tuple, ddq: tuple, u: sp.Symbol,
              s: sp.Symbol) -> dict[str, Any]:
    loop = lti.linear_loop(sp.Matrix(model), list(q), list(dq), list(ddq))
    den = lti.char_poly(loop, s)
    tf_q = lti.transfer(loop, sp.Matrix(q), {u: 0}, s)
    P = lti.transfer(loop, sp.Matrix([Fc]), {u: 0}, s)[0]
    num = lti.collect_s(sp.cancel(P * den), s)
    tf_num = tf_q.applyfunc(lambda e: lti.collect_s(sp.cancel(e * den), s))
    return {"P": P, "den": den, "num": num, "tf_q": sp.ImmutableMatrix(tf_q), "A": sp.ImmutableMatrix(loop.A(s)),
            "tf_num": sp.ImmutableMatrix(tf_num)}


def _omega_zeta(Md: sp.Matrix, Dd: sp.Matrix, Kd: sp.Matrix) -> tuple[Any, Any] | None:
    """Natural frequency and damping ratio per direction (diagonal impedances)."""
    if not (Md.is_diagonal() and Dd.is_diagonal() and Kd.is_diagonal()):
        return None
    pairs = [lti.second_order(Md[i, i], Dd[i, i], Kd[i, i]) for i in range(Md.rows)]
    w = sp.Matrix([sp.simplify(p[0]) for p in pairs])
    z = sp.Matrix([sp.simplify(p[1]) for p in pairs])
    return scalar_if_1(w), scalar_if_1(z)


def _report_analysis(c: Ctx, S: Setup, law: Law, an: Analysis, sol: Solution, add: Any, plant: Any) -> None:
    o, ct = c.options, S.contact
    if an.loop is None:
        _step(sol, "nonlinear", reason=an.reason)
        return
    s = S.s
    xi = law.xi
    eq = an.eq
    if eq is not None:
        q_eq = nice_matrix(eq[:S.n, :])
        add("equilibrium", q_eq, "vector", label="\\bar q")
        data: dict[str, Any] = {"q_eq": q_eq, "xi_eq": eq[S.n:, :] if xi else None, "steady": law.steady}
        at = dict(zip(law.x, eq)) | {v: 0 for v in law.dx} | law.steady
        if ct is not None and ct.elastic:
            F_eq = nice_matrix(ct.Fc().xreplace(at))
            add("F_c_eq", F_eq, label="\\bar F_c")
            data["F_eq"] = F_eq
            if o.law == "force" or (o.law == "compliance" and law.data.get("from_force")):
                Fd = law.data["Fd"]
                err = nice_matrix(Fd - F_eq)
                add("force_error", err, label="F_d - \\bar F_c")
                data.update(err=err, Fd=Fd)
        if o.law != "admittance":
            u_eq = nice_matrix(law.u.xreplace(S.measured()).xreplace(at))
            add("u_eq", u_eq, label="\\bar u")
            data["u_eq"] = u_eq
        _step(sol, "equilibrium", law=o.law, **data)
    else:
        _step(sol, "no_equilibrium")
    if plant is not None and o.law == "force" and ct is not None:
        Fd = law.data["Fd"][0]
        Fc = ct.Fc()[0]
        W = lti.transfer(an.loop, sp.Matrix([Fc]), {Fd: 0}, s)[0]
        We = lti.rational(1 - W, s)
        add("W", W, "scalar", label="W(s) = F_c(s)/F_d(s)")
        add("W_e", We, "scalar", label="W_e(s) = 1 - W(s)")
        tf: dict[str, Any] = {"W": W, "We": We, "W0": factor_within(W.subs(s, 0)) if not xi else sp.Integer(1)}
        if law.plain_force:
            L = _loop_gain(S, law, s)
            if L is not None:
                add("L", L, "scalar", label="L(s)")
                tf["L"] = L
        _step(sol, "transfer", **tf, cff=law.data.get("cff"), integral=bool(xi), s=s)
    if an.poly is not None:
        add("char_poly", an.poly, "scalar", label="\\det A(s)")
        if an.columns:
            if an.column:
                add("routh", sp.Matrix(an.column), "vector", label="\\text{Routh column}")
            else:
                add("routh", [sp.Matrix(col) for col in an.columns], "list", label="\\text{Routh columns}")
            add("stability", list(an.conditions) if an.conditions else [], "conditions",
                label="\\text{conditions} > 0")
            never = any(x == -1 for x in an.conditions)
            if an.stable is not None:
                add("stable", bool(an.stable), "bool", label="\\text{stable for all parameters}")
            if never and an.marginal is not None:
                add("marginally_stable", bool(an.marginal), "bool",
                    label="\\text{marginally stable for all parameters}")
        if an.poles is not None:
            add("poles", sp.Matrix(an.poles), "vector", label="\\text{poles}")
        num = None
        if problem_values(c) and an.poly.free_symbols - {s}:
            fs = [(f.xreplace(c.problem.values), k) for f, k in an.factors]
            if all(f.free_symbols <= {s} for f, _ in fs):
                num = [x for f, k in fs for _ in range(k) for x in lti.poles(f, s)]
                add("poles_num", sp.Matrix(num), "vector", label="\\text{poles}")
        kind_num = lti.classify(an.loop, c.problem.values, s) if num is not None or not (an.poly.free_symbols - {s}) \
            else None
        if kind_num in ("marginal", "unstable"):
            add("marginally_stable_num", kind_num == "marginal", "bool", label="\\text{marginally stable}")
        witness = None
        if an.witness:
            point = dict(an.witness)
            point.update({x: sp.Integer(1) for x in an.poly.free_symbols - {s} - set(point)})
            witness = {"point": point, "poles": lti.poles(an.poly.xreplace(point), s)}
        factors = [(f, k) for f, k in an.factors] if len(an.factors) > 1 or an.factors[0][1] > 1 else None
        _step(sol, "stability", poly=an.poly, column=an.column, stable=an.stable,
              conditions=[x for x in an.conditions if x != -1], never=bool(an.columns) and never,
              witness=witness, poles=an.poles, poles_num=num, s=s, degree=sp.Poly(an.poly, s).degree(),
              **({"marginal": an.marginal} if an.marginal is not None else {}),
              **({"kind_num": kind_num} if kind_num in ("marginal", "unstable") else {}),
              factors=factors, factor_terms=[frac_terms(f, s)[0] for f, _ in an.factors] if factors else None,
              columns=an.columns if factors else None, deltas=an.deltas,
              long_column=any(count_ops(x) > 40 for x in an.column))


def problem_values(c: Ctx) -> bool:
    return bool(c.problem.values)


def _loop_gain(S: Setup, law: Law, s: sp.Symbol) -> sp.Expr | None:
    """L(s) = C(s) P_d(s): the force controller C(s) = K_f + K_I/s times the plant with the velocity damping,
    so that W = (c_ff P_d + L)/(1 + L)."""
    d = law.data
    ct = S.contact
    v_in = sp.Dummy("v")
    kd = d["KD"]
    u = v_in - (kd[0, 0] * (S.G.T * S.dq)[0] if kd is not None else 0)
    model = S.model().xreplace({S.u[0]: u})
    try:
        loop = lti.linear_loop(model, list(S.q), list(S.dq), list(S.ddq))
    except lti.NotLinear:
        return None
    Pd = lti.transfer(loop, ct.Fc(), {v_in: 0}, s)[0]
    C = d["Kf"][0, 0] + (d["Ki"][0, 0] / s if d["Ki"] is not None else 0)
    return lti.rational(C * Pd, s)


def _free_motion(c: Ctx, S: Setup, law: Law, sol: Solution, add: Any) -> None:
    """Without contact (F_c = 0): the closed loop, its steady velocity or rest position."""
    if law.free is None:
        return
    free = nice_matrix(law.free, law.ddx + law.dx + law.x)
    add("free_closed_loop", free[:S.n, :], label="\\text{closed loop, free motion}")
    data: dict[str, Any] = {"free": free[:S.n, :], "integral": bool(law.xi)}
    if c.options.law == "force":
        fu = law.u.xreplace(S.measured(free=True)).applyfunc(lambda x: tidy(sp.expand(x)))
        add("free_input", fu, label="u\\,|_{F_c = 0}")
        data["u"] = fu
    try:
        loop = lti.linear_loop(free, law.x, law.dx, law.ddx)
    except lti.NotLinear:
        loop = None
    if loop is not None and not law.xi:
        st = lti.LinearLoop(loop.x, loop.dx, loop.ddx, loop.A2, loop.A1, loop.A0, loop.r0.xreplace(law.steady))
        v = lti.steady_velocity(st)
        if v is not None:
            add("free_velocity", v, label="\\dot{\\bar q}")
            data["v"] = v
        else:
            eq = lti.equilibrium(st)
            if eq is not None:
                add("free_equilibrium", eq, label="\\bar q")
                data["eq"] = eq
    _step(sol, "free", **data)


def _design_force(c: Ctx, S: Setup, law: Law, sol: Solution, add: Any) -> Law:
    """Force-law gains from the desired closed-loop polynomial: det A(s) ≡ a_n Π(s − p_i)."""
    an = analyze(law.residual, law.x, law.dx, law.ddx, S.s, {})
    if an.poly is None:
        raise c.fail(("design",), "the closed loop is not linear: gains cannot be placed")
    deg = sp.Poly(an.poly, S.s).degree()
    target = _target(c, S.s, deg)
    d = c.options.design
    if d.gains is not None:
        unknowns = []
        for i, g in enumerate(d.gains):
            sym = c.problem.names.get(g)
            if not isinstance(sym, sp.Symbol) or sym not in an.poly.free_symbols:
                raise c.fail(("design", "gains", i), f"'{g}' is not a gain of this closed loop",
                             "list symbols that appear in the characteristic polynomial")
            unknowns.append(sym)
    else:
        unknowns = list(dict.fromkeys(  # (a scalar gain repeated on a diagonal is one unknown)
            x for M in (law.data.get("Kf"), law.data.get("Ki"), law.data.get("KD")) if M is not None
            for x in M if isinstance(x, sp.Symbol)))
    sol_ = lti.match_polynomial(an.poly, target, S.s, unknowns)
    if sol_ is None:
        raise c.fail(("design",), f"no values of {', '.join(map(str, unknowns))} give these poles",
                     "the closed loop has " + str(deg) + " poles; list the gains to solve for in gains:")
    add("gains", sp.Matrix([sol_.get(k, k) for k in unknowns]), "vector", label="\\text{gains}")
    _step(sol, "design", target=target, unknowns=sp.Matrix(unknowns), gains=sp.Matrix([sol_.get(k, k) for k in unknowns]),
             s=S.s)
    sub = {k: v for k, v in sol_.items()}
    law.u = law.u.xreplace(sub)
    law.residual = law.residual.xreplace(sub)
    law.closed = law.closed.xreplace(sub)
    law.free = law.free.xreplace(sub) if law.free is not None else None
    for k in ("Kf", "Ki", "KD"):
        if law.data.get(k) is not None:
            law.data[k] = law.data[k].xreplace(sub)
    return law


# ------------------------------------------------------------------------------------------------ figure
def _numbers(c: Ctx, exprs: list) -> tuple[dict[sp.Symbol, float], list[sp.Symbol]]:
    """Numeric values of every parameter (given ones, else 1) and the list of those set to 1."""
    robot = c.problem.robot
    state = set(robot.q) | set(robot.dq) | set(robot.ddq)
    syms: set[sp.Symbol] = set()
    for e in exprs:
        syms |= e.free_symbols
    out, unit = {}, []
    for s in sorted(syms - state, key=lambda x: x.name):
        v = c.problem.values.get(s)
        if v is not None and v.is_number:
            out[s] = float(v)
        else:
            out[s], unit = 1.0, unit + [s]
    return out, unit


def _figure(c: Ctx, S: Setup, law: Law, an: Analysis) -> Figure | None:
    """The contact force and the coordinates under the closed loop (linear model, its exact response), with the
    predicted steady state."""
    loop = an.loop
    ct = S.contact
    assert loop is not None and ct is not None
    steady = law.steady
    st = lti.LinearLoop(loop.x, loop.dx, loop.ddx, loop.A2, loop.A1, loop.A0, loop.r0.xreplace(steady))
    Fc = ct.Fc()
    exprs = list(st.A2) + list(st.A1) + list(st.A0) + list(st.r0) + list(Fc) + list(ct.rest)
    nums, unit = _numbers(c, exprs)
    spec = c.options.simulate if isinstance(c.options.simulate, SimulateSpec) else SimulateSpec()
    x0 = _initial(c, S, ct, nums, spec, len(loop.x))
    if x0 is None:
        return None
    pn = lti.poles(an.poly.xreplace(nums), S.s) if an.poly is not None else None
    kind = lti.classify(st, nums, S.s)
    if kind is None:  # (symbols left in A(s) that det A(s) does not have: the poles decide, as before)
        kind = "unstable" if pn and max(complex(p).real for p in pn) >= 0 else "asymptotic"
    unstable = kind == "unstable"
    decaying = [abs(complex(p).real) for p in pn or [] if complex(p).real < -1e-9 * max(1.0, abs(complex(p)))]
    if spec.time is not None:
        t_end = float(spec.time)
    elif pn and unstable:
        t_end = float(min(max(5.0 / max(max(complex(p).real for p in pn), 1e-3), 0.5), 200.0))
    elif decaying:  # (marginal: the poles on the imaginary axis do not decay, the others set the time)
        t_end = float(min(max(10.0 / max(min(decaying), 1e-3), 0.5), 200.0))
    else:
        t_end = 10.0
    eq = an.eq.xreplace(nums) if an.eq is not None else None
    names = c.problem.latex_names
    tex = lambda x: names.get(x, sp.latex(x))  # noqa: E731

    word = "predicted" if kind == "asymptotic" else "equilibrium"

    def sample() -> list[Panel]:
        t, X, _ = lti.simulate(st, nums, x0, [0.0] * len(loop.x), t_end)
        tl = [float(v) for v in t]
        fc_f = lambdify_np(list(S.q), Fc.xreplace(nums))
        Fvals = np.array([np.ravel(fc_f(*X[:S.n, k])) for k in range(X.shape[1])]).T
        panels = []
        curves = []
        for i in (range(ct.m) if ct.elastic else ()):
            lab = f"$F_{{c{',' + str(i + 1) if ct.m > 1 else ''}}}(t)$"
            curves.append(Curve(lab, tl, [float(v) for v in Fvals[i]]))
            if ct.elastic and eq is not None:
                at = dict(zip(loop.x, eq))
                fe = float(Fc[i].xreplace(nums).xreplace(at))
                curves.append(Curve(f"{word} $\\bar F_c = {fe:.4g}$", tl, [fe] * len(tl), dashed=True))
            if "Fd" in law.data:
                fd = float(law.data["Fd"][i].xreplace(nums))
                curves.append(Curve(f"$F_d = {fd:.4g}$", tl, [fd] * len(tl), dashed=True))
        if curves:
            panels.append(Panel("$t$ [s]", "contact force", curves))
        qc = []
        for j in range(S.n):
            qc.append(Curve(f"${tex(S.q[j])}(t)$", tl, [float(v) for v in X[j]]))
            if eq is not None:
                qe = float(eq[j])
                qc.append(Curve(f"{word} $\\bar{{{tex(S.q[j])}}} = {qe:.4g}$", tl, [qe] * len(tl), dashed=True))
        panels.append(Panel("$t$ [s]", "position", qc))
        return panels

    note = ""
    if unit:
        note = " Parameters without a value set to 1: " + ", ".join(f"${tex(s)}$" for s in unit) + "."
    ref = " Constant references." if steady else ""
    if ct.elastic:
        what = "Closed-loop response from rest at the contact (linear model, contact maintained): contact force " \
               "and position"
    else:
        what = "Closed-loop response from rest under the constant contact force " + ", ".join(
            f"${tex(f)} = {float(f.xreplace(nums)):.4g}$" for f in ct.force) + ": position"
    if kind == "marginal":
        tail = (". The closed loop is marginally stable (no pole in the right half-plane; those on the imaginary "
                "axis, such as s = 0, semisimple): the response stays bounded but does not converge"
                + (" to the equilibrium (dashed)." if eq is not None else
                   " (no isolated equilibrium: an offset along an undriven direction stays)."))
    else:
        tail = (". The closed loop is unstable: the response diverges from the equilibrium (dashed)." if unstable
                else ", with the predicted steady state (dashed).")
    return Figure("response", f"{what}{tail}{ref}{note}", sample)


def _initial(c: Ctx, S: Setup, ct: Contact, nums: dict, spec: SimulateSpec, size: int) -> list[float] | None:
    """The initial state: spec values, else at rest with the contact undeformed (p(q0) = p_e, least norm)."""
    q0 = [0.0] * S.n
    if ct.elastic:
        J = np.array(ct.J.xreplace(nums).evalf().tolist(), dtype=float)
        p0 = np.array(ct.p.xreplace({x: 0 for x in S.q}).xreplace(nums).evalf().tolist(), dtype=float).ravel()
        rest = np.array(ct.rest.xreplace(nums).evalf().tolist(), dtype=float).ravel()
        try:
            q0 = list(np.linalg.pinv(J) @ (rest - p0))
        except (np.linalg.LinAlgError, ValueError):
            q0 = [0.0] * S.n
    byname = {x.name: i for i, x in enumerate(S.q)}
    for k, v in spec.initial.items():
        if k not in byname:
            raise c.fail(("simulate", "initial", k), f"'{k}' is not a coordinate", "use " + ", ".join(byname))
        q0[byname[k]] = float(sp.sympify(c.ctx.expr("simulate", "initial", k)).xreplace(nums))
    return [float(x) for x in q0] + [0.0] * (size - S.n)


# ------------------------------------------------------------------------------------------------ grading
def _register_checks(sfx: str) -> None:
    """The property checks of this ask's non-unique results, under their (suffixed) names."""
    for base, fn in (("stability", check_conditions), ("u", check_law), ("D_d", check_impedance_gains),
                     ("K_d", check_impedance_gains), ("gains", check_gains)):
        name = base + sfx
        if PROPERTY_CHECKS.get(name) is not fn and getattr(PROPERTY_CHECKS.get(name), "_force_fallback", None) is None:
            previous = PROPERTY_CHECKS.get(name)
            wrapped = _with_fallback(fn, previous)
            property_check(name)(wrapped)


def _with_fallback(fn, previous):  # type: ignore[no-untyped-def]
    """fn for force_control problems, else the check registered before (e.g. control_law's u)."""
    def check(problem, results, name, value, other, options):  # type: ignore[no-untyped-def]
        if not any(a.kind == "force_control" for a in problem.asks):
            return previous(problem, results, name, value, other, options) if previous else None
        return fn(problem, results, name, value, other, options)
    check._force_fallback = previous  # type: ignore[attr-defined]
    return check


def check_conditions(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Stability conditions c_i > 0: the same set up to positive factors and always-true conditions."""
    ref = results.get(name)
    if ref is None:
        return None
    got = value if isinstance(value, list) else [value]
    if any(isinstance(x, list) for x in got):
        return PropertyVerdict(False, 0.0, ["write the conditions as a list [c1, c2, ...], each meaning c > 0"])
    v = conditions_equiv(got, list(ref.value))
    if v.ok:
        return PropertyVerdict(True, 1.0, ["the same stability conditions (up to positive factors)"])
    return PropertyVerdict(False, 0.0, [v.detail])


def check_law(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Impedance / inverse-dynamics laws: right when the closed loop they give is ours (substituted in the
    model: B⁻¹G(u − u_ref) ≡ 0 with the measured force as in the reference)."""
    ref = results.get(name)
    if ref is None:
        return None
    ask = next((a for a in problem.asks if a.kind == "force_control" and "u" + a.options.suffix == name), None)
    if ask is not None and ask.options.law == "hybrid":
        from solver.interaction.hybrid import check_hybrid_law
        return check_hybrid_law(problem, ask, value)
    U = sp.Matrix(value) if isinstance(value, list) else sp.Matrix([value])
    R = sp.Matrix(ref.value) if isinstance(ref.value, sp.MatrixBase) else sp.Matrix([ref.value])
    if U.shape == (1, R.rows) and R.cols == 1:
        U = U.T
    if U.shape != R.shape:
        return PropertyVerdict(False, 0.0, [f"u must have {R.rows} component(s)"])
    d = U - R
    if all(scalar_equiv(x, 0).ok for x in d):
        return PropertyVerdict(True, 1.0, ["substituted in the model, this law gives the required closed loop"])
    return PropertyVerdict(False, 0.0, ["substituted in the model, this law does not give the required closed "
                                        "loop (the accelerations differ)"], final=False)


def check_impedance_gains(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """D_d and K_d are right when M_d s² + D_d s + K_d has the required roots in every direction, with the
    student's M_d if given (any M_d > 0 is a valid design with force sensing), else ours."""
    sfx = name[3:]
    Md_ans = other("M_d" + sfx)
    Md = _as_matrix(Md_ans) if Md_ans is not None else _as_matrix(results["M_d" + sfx].value)
    D = _as_matrix(value if name.startswith("D_d") else (other("D_d" + sfx) or results["D_d" + sfx].value))
    K = _as_matrix(value if name.startswith("K_d") else (other("K_d" + sfx) or results["K_d" + sfx].value))
    Dr, Kr, Mr = (_as_matrix(results[k + sfx].value) for k in ("D_d", "K_d", "M_d"))
    if D.shape != Dr.shape or K.shape != Kr.shape or Md.shape != Mr.shape:
        return PropertyVerdict(False, 0.0, [f"{name} must be {Dr.rows}x{Dr.cols}"])
    # required: D = a1 M, K = a0 M with a1 = Dr Mr⁻¹, a0 = Kr Mr⁻¹ (scalars times I); only the graded item is judged
    a1, a0 = (Dr * Mr.inv())[0, 0], (Kr * Mr.inv())[0, 0]
    mine = D - a1 * Md if name.startswith("D_d") else K - a0 * Md
    if all(scalar_equiv(x, 0).ok for x in mine):
        return PropertyVerdict(True, 1.0, [f"with M_d = {Md if Md.shape != (1, 1) else Md[0, 0]}, "
                                           "M_d s² + D_d s + K_d has the required roots in every direction"])
    return None


def check_gains(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """Designed force-law gains: compared with ours (they are unique when the design is well posed)."""
    return None


def _as_matrix(v: Any) -> sp.Matrix:
    if isinstance(v, sp.MatrixBase):
        return sp.Matrix(v)
    if isinstance(v, list):
        M = sp.Matrix(v)
        return M if M.cols > 1 or M.rows == 1 else sp.diag(*M)
    return sp.Matrix([[v]])
