"""The timing law of a spec (shared by the asks ``trajectory`` and ``time_scaling``): options and their reading.

One law per coordinate, all on [0, T] (a spline on [t_0, t_N]): the data may be scalars (one coordinate) or lists
of n (one entry per coordinate; a scalar next to lists is the same for every coordinate).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Optional, Union

import sympy as sp
from pydantic import Field

from solver.math.simplify import simplified
from solver.planning.laws import (Cond, Law, LawError, check_trapezoid, cycloidal, harmonic, less,
                                  min_time_trapezoid, piecewise_polynomial, rest_defaults, trapezoid_Ts,
                                  trapezoidal)
from solver.spec.errors import Place, UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
LAWS = ("cubic", "quintic", "polynomial", "spline", "trapezoidal", "bang_coast_bang", "bang_bang", "cycloidal",
        "harmonic", "expression")
ORDERS = ("q", "dq", "ddq", "dddq")


class Boundary(Strict):
    """Values of the law and of its derivatives at one instant (scalars or lists of n)."""

    q: Optional[ExprT] = Field(None, description="position")
    dq: Optional[ExprT] = Field(None, description="velocity")
    ddq: Optional[ExprT] = Field(None, description="acceleration")
    dddq: Optional[ExprT] = Field(None, description="jerk")


class Via(Boundary):
    """A via point (spline knot) or an inner condition of a polynomial, at time t."""

    t: Scalar = Field(description="the time of the via point")


class MotionSpec(Strict):
    """A timing law: which one, its duration and its data."""

    law: Literal[LAWS] = Field(  # type: ignore[valid-type]
        description="cubic/quintic (rest defaults: zero velocity (and acceleration) where not given), polynomial "
                    "(degree = number of conditions - 1, or `degree`), spline (through via points), trapezoidal = "
                    "bang_coast_bang (Ts, V or A; or V and A without T: minimum time), bang_bang, cycloidal "
                    "(sinusoidal acceleration), harmonic (cosine acceleration), expression (q(t) given)")
    T: Optional[Scalar] = Field(None, description="duration (the law runs on [0, T]); other fields may use T")
    initial: Optional[Boundary] = Field(None, description="values at t = 0: {q: ..., dq: ..., ddq: ...}")
    final: Optional[Boundary] = Field(None, description="values at t = T")
    via: Optional[list[Via]] = Field(None, max_length=40,
                                     description="via points {t: ..., q: ..., dq: ...} (spline knots between 0 and "
                                                 "T; inner conditions of a polynomial); at most 40")
    degree: Optional[int] = Field(None, ge=1, le=9, description="polynomial/spline degree (spline default 3)")
    continuity: Optional[int] = Field(None, ge=0, le=8,
                                      description="spline: continuous derivatives at the knots (default degree - 1)")
    Ts: Optional[ExprT] = Field(None, description="trapezoidal: acceleration (= deceleration) time, e.g. T/4")
    V: Optional[ExprT] = Field(None, description="trapezoidal: cruise speed (magnitude)")
    A: Optional[ExprT] = Field(None, description="trapezoidal: acceleration (magnitude)")
    q: Optional[ExprT] = Field(None, description="expression: q(t) (use t for time)")


@dataclass
class Motion:
    """One law per coordinate on a common interval."""

    t: sp.Symbol
    law: str
    laws: list[Law]
    T: Optional[sp.Expr]                    # duration (None: unbounded expression)
    names: list[str]                        # one per coordinate (q1, q2, ... or s)
    notes: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.laws)

    def derivative(self, k: int) -> list[Law]:
        return [law.diff(k) for law in self.laws]

    def vector(self, k: int, tau: sp.Expr) -> sp.Matrix:
        """q^(k)(τ), one entry per coordinate."""
        return sp.Matrix([law.diff(k).at(tau) if k else law.at(tau) for law in self.laws])

    def exprs(self, k: int) -> Optional[sp.Matrix]:
        """q^(k)(t) as one expression per coordinate (None when some law has several pieces)."""
        if any(len(law.pieces) > 1 for law in self.laws):
            return None
        return sp.Matrix([sp.diff(law.pieces[0], self.t, k) for law in self.laws])

    def subs(self, m: dict) -> "Motion":
        return Motion(self.t, self.law, [law.subs(m) for law in self.laws],
                      self.T.subs(m) if self.T is not None else None, self.names, self.notes)


class Reader:
    """Parses the fields of a MotionSpec found at ``path`` in the problem (errors at their line)."""

    def __init__(self, problem: Any, path: tuple, spec: MotionSpec) -> None:
        self.problem, self.path, self.spec = problem, path, spec
        self.names = dict(problem.names)

    def place(self, *sub: Any) -> Place:
        return self.problem.located.place(self.path + tuple(sub))

    def fail(self, sub: tuple, message: str, hint: str | None = None) -> UserError:
        return UserError(message, self.place(*sub), hint)

    def expr(self, *sub: Any) -> Any:
        return self.problem.parse_at(self.path + tuple(sub), self.names)

    def scalar(self, *sub: Any) -> sp.Expr:
        v = self.expr(*sub)
        if isinstance(v, list):
            raise self.fail(sub, "a single expression is needed here, got a list")
        return v

    def entries(self, *sub: Any) -> list[sp.Expr]:
        """A scalar (one entry) or a flat list."""
        v = self.expr(*sub)
        if not isinstance(v, list):
            return [v]
        if len(shape_of(v)) != 1:
            raise self.fail(sub, f"a scalar or a flat list is needed here, got shape {shape_of(v)}")
        return list(v)


def _spread(vals: list[sp.Expr], n: int, r: Reader, sub: tuple) -> list[sp.Expr]:
    if len(vals) == n:
        return vals
    if len(vals) == 1:
        return vals * n
    raise r.fail(sub, f"{len(vals)} entries here, but the motion has {n} coordinates",
                 f"give one value or a list of {n}")


def _dimension(r: Reader, extra: dict[tuple, list[sp.Expr]]) -> int:
    sizes = [len(v) for v in extra.values() if len(v) > 1]
    if len(set(sizes)) > 1:
        sub = next(k for k, v in extra.items() if len(v) > 1 and len(v) != sizes[0])
        raise r.fail(sub, f"lists of different lengths in the law ({sorted(set(sizes))})",
                     "give every list one entry per coordinate")
    return sizes[0] if sizes else 1


def read_motion(problem: Any, path: tuple, spec: MotionSpec, t: sp.Symbol, *, n: int | None = None,
                names: list[str] | None = None, T_override: sp.Expr | None = None,
                defaults: dict[str, sp.Expr] | None = None) -> Motion:
    """The Motion of ``spec`` (at ``path`` in the problem). ``n``: the number of coordinates required (a robot's);
    ``T_override``: a duration replacing the spec's (minimum-time searches); ``defaults``: initial/final
    positions when not given (paths: 0 and L)."""
    r = Reader(problem, path, spec)
    r.names.setdefault("t", t)
    T: sp.Expr | None = T_override
    if T is None and spec.T is not None:
        T = r.scalar("T")
        if T.is_number and not T.is_positive:
            raise r.fail(("T",), f"the duration must be positive, got {T}")
    if T is not None:
        r.names["T"] = T
    raw: dict[tuple, list[sp.Expr]] = {}
    for side in ("initial", "final"):
        b = getattr(spec, side)
        for o in ORDERS:
            if b is not None and getattr(b, o) is not None:
                raw[(side, o)] = r.entries(side, o)
    for key in ("Ts", "V", "A", "q"):
        if getattr(spec, key) is not None:
            raw[(key,)] = r.entries(key)
    for i, v in enumerate(spec.via or []):
        for o in ORDERS:
            if getattr(v, o) is not None:
                raw[("via", i, o)] = r.entries("via", i, o)
    dim = _dimension(r, raw)
    if n is not None and dim not in (1, n):
        sub = next(k for k, v in raw.items() if len(v) == dim)
        raise r.fail(sub, f"{dim} entries, but the robot has {n} coordinates", f"give one value or a list of {n}")
    dim = n or dim
    vals = {k: _spread(v, dim, r, k) for k, v in raw.items()}
    for key, d in (defaults or {}).items():
        side, o = ("initial", "q") if key == "initial" else ("final", "q")
        vals.setdefault((side, o), [d] * dim)
    coord = names or ([f"q{i + 1}" for i in range(dim)] if dim > 1 else ["q"])
    law = spec.law
    if law in ("bang_coast_bang",):
        law = "trapezoidal"
    if T is None and law not in ("trapezoidal", "expression"):
        raise r.fail(("law",), f"the {law} law needs its duration T", "add T: <duration>")
    motion = Motion(t, law, [], T, coord)
    try:
        if law in ("cubic", "quintic", "polynomial"):
            motion.laws = _polynomials(r, vals, dim, law, T, t)
        elif law == "spline":
            motion.laws = _splines(r, vals, dim, T, t)
        elif law in ("trapezoidal", "bang_bang"):
            _trapezoids(r, vals, dim, law, T, t, motion)
        elif law in ("cycloidal", "harmonic"):
            qi, qf = _ends(r, vals, dim)
            make = cycloidal if law == "cycloidal" else harmonic
            motion.laws = [make(t, qi[i], qf[i], T) for i in range(dim)]
        else:
            if ("q",) not in vals:
                raise r.fail(("law",), "the expression law needs q: (the law q(t))", "add q: <expression in t>")
            end = T if T is not None else sp.oo
            motion.laws = [Law(t, [sp.Integer(0), end], [vals[("q",)][i]]) for i in range(dim)]
    except LawError as exc:
        sub = (exc.field,) if exc.field in MotionSpec.model_fields else ("law",)
        raise r.fail(sub, str(exc), exc.hint) from None
    if motion.T is None and law != "expression":
        motion.T = T
    return motion


def _ends(r: Reader, vals: dict, dim: int) -> tuple[list[sp.Expr], list[sp.Expr]]:
    for side in ("initial", "final"):
        if (side, "q") not in vals:
            raise r.fail(("law",), f"this law needs the {side} position ({side}: {{q: ...}})")
    return vals[("initial", "q")], vals[("final", "q")]


def _conds(r: Reader, vals: dict, i: int, T: sp.Expr, skip_via_q: bool = False) -> list[Cond]:
    out = []
    for side, tt in (("initial", sp.Integer(0)), ("final", T)):
        for k, o in enumerate(ORDERS):
            if (side, o) in vals:
                out.append(Cond(tt, k, vals[(side, o)][i], side))
    for j, v in enumerate(r.spec.via or []):
        tv = r.scalar("via", j, "t")
        for k, o in enumerate(ORDERS):
            if ("via", j, o) in vals and not (skip_via_q and k == 0):
                out.append(Cond(tv, k, vals[("via", j, o)][i], "via"))
    return out


def _polynomials(r: Reader, vals: dict, dim: int, law: str, T: sp.Expr, t: sp.Symbol) -> list[Law]:
    spec = r.spec
    out = []
    for i in range(dim):
        conds = _conds(r, vals, i, T)
        if law == "polynomial":
            degree = spec.degree if spec.degree is not None else len(conds) - 1
        else:
            degree = 3 if law == "cubic" else 5
            if spec.degree is not None and spec.degree != degree:
                raise r.fail(("degree",), f"a {law} has degree {degree}", "use law: polynomial with degree:")
        if len(conds) > degree + 1:
            raise r.fail(("law",), f"{len(conds)} conditions for a polynomial of degree {degree} "
                                   f"({degree + 1} coefficients)", "remove some conditions or raise the degree")
        if degree < 1:
            raise r.fail(("law",), "a polynomial law needs at least two conditions")
        conds = rest_defaults(conds, sp.Integer(0), T, degree + 1)
        if len(conds) < degree + 1:
            raise r.fail(("law",), f"only {len(conds)} conditions for degree {degree}")
        _check_times(r, [c.time for c in conds if c.source == "via"], T)
        law_i = piecewise_polynomial(t, [sp.Integer(0), T], degree, 0, conds)
        law_i.params["conds"] = conds
        out.append(law_i)
    return out


def _check_times(r: Reader, times: list[sp.Expr], T: sp.Expr, first: sp.Expr = sp.Integer(0)) -> None:
    """first < t_1 < t_2 < ... < T (when decidable)."""
    prev, prev_name = first, "the start"
    for j, tv in enumerate(times):
        if less(prev, tv) is False:
            raise r.fail(("via", j, "t"), f"via-point time {tv} is not after {prev_name} ({prev})",
                         "list the via points in increasing time, strictly between 0 and T")
        prev, prev_name = tv, "the previous via point"
    if times and less(times[-1], T) is False:
        raise r.fail(("via", len(times) - 1, "t"), f"via-point time {times[-1]} is not before the end T = {T}",
                     "list the via points in increasing time, strictly between 0 and T")


def _splines(r: Reader, vals: dict, dim: int, T: sp.Expr, t: sp.Symbol) -> list[Law]:
    spec = r.spec
    degree = spec.degree or 3
    cont = spec.continuity if spec.continuity is not None else degree - 1
    if cont >= degree:
        raise r.fail(("continuity",), f"continuity {cont} is not possible with degree {degree}",
                     f"at most {degree - 1}")
    if not spec.via:
        raise r.fail(("law",), "a spline needs via points (via: [{t: ..., q: ...}, ...])")
    times = [r.scalar("via", j, "t") for j in range(len(spec.via))]
    _check_times(r, times, T)
    for j in range(len(spec.via)):
        if ("via", j, "q") not in vals:
            raise r.fail(("via", j), "every via point of a spline needs its position q")
    qi, qf = _ends(r, vals, dim)
    knots = [sp.Integer(0), *times, T]
    out = []
    for i in range(dim):
        pos = [qi[i]] + [vals[("via", j, "q")][i] for j in range(len(times))] + [qf[i]]
        conds = [c for c in _conds(r, vals, i, T, skip_via_q=True) if c.order > 0]
        nseg = len(knots) - 1
        free = nseg * (degree + 1) - 2 * nseg - (nseg - 1) * cont - len(conds)
        if free > 0:  # rest defaults at the ends first (clamped spline)
            conds = rest_defaults(conds, sp.Integer(0), T, len(conds) + free)
        law_i = _spline(t, knots, pos, degree, cont, conds)
        out.append(law_i)
    return out


def _spline(t: sp.Symbol, knots: list[sp.Expr], pos: list[sp.Expr], degree: int, cont: int,
            conds: list[Cond]) -> Law:
    """Positions at both ends of every piece, C^cont (derivatives 1..cont) at the inner knots, and ``conds``."""
    return piecewise_polynomial(t, knots, degree, cont, conds, end_positions=pos)


def _trapezoids(r: Reader, vals: dict, dim: int, law: str, T: sp.Expr | None, t: sp.Symbol,
                motion: Motion) -> None:
    qi, qf = _ends(r, vals, dim)
    D = [simplified(qf[i] - qi[i]) for i in range(dim)]
    given = [k for k in ("Ts", "V", "A") if (k,) in vals]
    if law == "bang_bang":
        if given:
            raise r.fail((given[0],), "a bang-bang law is fixed by T (Ts = T/2)", "remove it, or use trapezoidal")
        if T is None:
            raise r.fail(("law",), "the bang_bang law needs its duration T", "add T: <duration>")
        motion.laws = [trapezoidal(t, qi[i], qf[i], T, T / 2) for i in range(dim)]
        return
    if T is not None:
        if len(given) != 1:
            raise r.fail(("law",), "with T, a trapezoidal law needs exactly one of Ts, V, A"
                         + (f" (got {', '.join(given)})" if given else ""), "e.g. Ts: T/4")
        key = given[0]
        laws = []
        for i in range(dim):
            x = vals[(key,)][i]
            if x.is_number and not x.is_positive:
                raise r.fail((key,), f"{key} must be positive, got {x}")
            Ts = x if key == "Ts" else trapezoid_Ts(D[i], T, **{key: x})
            check_trapezoid(Ts, T, key)
            laws.append(trapezoidal(t, qi[i], qf[i], T, Ts))
        motion.laws = laws
        return
    if set(given) != {"V", "A"}:
        raise r.fail(("law",), "without T, a trapezoidal law needs both V and A (its minimum time is found)",
                     "add T:, or V: and A:")
    for key in ("V", "A"):
        for x in vals[(key,)]:
            if x.is_number and not x.is_positive:
                raise r.fail((key,), f"{key} must be positive, got {x}")
    motion.laws = coordinated_trapezoids(t, qi, qf, vals[("V",)], vals[("A",)], motion.notes)
    motion.T = motion.laws[0].end


def coordinated_trapezoids(t: sp.Symbol, qi: list[sp.Expr], qf: list[sp.Expr], V: list[sp.Expr],
                           A: list[sp.Expr], notes: list[str]) -> list[Law]:
    """Minimum-time trapezoidal laws under |q̇_i| <= V_i, |q̈_i| <= A_i ending together: T = max_i T_i; the
    other coordinates keep their A_i and cruise slower (Ts_i = T/2 − sqrt(T²/4 − |Δ_i|/A_i))."""
    dim = len(qi)
    Ti, info = [], []
    for i in range(dim):
        D = simplified(qf[i] - qi[i])
        Tc, Tb, coast, margin = min_time_trapezoid(D, V[i], A[i])
        if coast is None:
            notes.append(f"coordinate {i + 1}: a coast phase is assumed (|Δ| > V²/A, i.e. {margin} > 0)")
            coast = True
        Ti.append(Tc if coast else Tb)
        info.append((D, coast, Tc, Tb, margin))
    if dim == 1:
        T = Ti[0]
        j = 0
    else:
        nums = [x for x in Ti if x.is_number]
        if len(nums) == dim:
            j = max(range(dim), key=lambda k: float(Ti[k]))
            T = Ti[j]
        else:
            T, j = sp.Max(*Ti), -1
            notes.append("the slowest coordinate cannot be decided symbolically: T = max of the T_i")
    laws = []
    for i in range(dim):
        D, coast, Tc, Tb, margin = info[i]
        if i == j or dim == 1:
            Ts = V[i] / A[i] if coast else Ti[i] / 2
        else:
            sgn = sp.sign(D) if D.is_number and D != 0 else 1
            Ts = simplified(T / 2 - sp.sqrt(T ** 2 / 4 - D / (sgn * A[i])))
        law = trapezoidal(t, qi[i], qf[i], T, Ts) if simplified(D) != 0 else \
            Law(t, [sp.Integer(0), T], [qi[i]], {"A": sp.Integer(0), "V": sp.Integer(0), "Ts": sp.Integer(0),
                                                  "Delta": sp.Integer(0)})
        law.params.update(T_own=Ti[i], T_coast=Tc, T_bang=Tb, coast=coast, margin=margin)
        laws.append(law)
    return laws
