"""Torques along a motion, uniform time scaling and minimum time (ask kind ``time_scaling``).

Along q(t), inverse dynamics splits the torque by how it scales when the motion is slowed to q(t/k):

    τ(t) = a(t) + f(t) + g(q(t)),   a = B(q) q̈ + c(q, q̇),   f = F_v q̇,      τ_k(k t) = a(t)/k² + f(t)/k + g(q(t))

With y = 1/k, every bound |τ_i| <= U_i is a quadratic a y² + f y + g ∈ [−U, U] holding on an interval [0, y_i(t)]
(if |g| <= U): the smallest uniform factor is k* = 1 / min_{t,i} y_i(t) (without friction
y_i(t) = sqrt((±U_i − g_i)/a_i)), and the scaled motion touches a bound where the minimum is attained.
A rest-to-rest law q_i + Δ σ(t/T) has the same shape for every T, so its minimum time under torque bounds is
k* T; under |q̇| <= V, |q̈| <= A the family is re-planned with T free and T_min is the smallest T meeting the
bounds.

Time-optimal rest-to-rest motion of one coordinate q_j (the others held): along it τ_i = b_i a + c_i v² + g_i
(v = q̇_j, a = q̈_j). Rows with constant b_i (c_i = 0) bound the acceleration, rows with constant c_i (b_i = 0) the
velocity; the optimum is bang-coast-bang, T = |Δ|/V + V/(2A₊) + V/(2A₋) when |Δ| > V²(1/A₊ + 1/A₋)/2, else
bang-bang, T = V_p/A₊ + V_p/A₋ with V_p = sqrt(2|Δ| A₊A₋/(A₊ + A₋)). The other rows are checked along the result.
Minima over time are searched on a grid refined by a bounded scalar search; one found at a break of the law
(tolerance 1e-7 T) is evaluated there exactly.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field

from solver.dynamics.model import DynamicModel, derive, require_model
from solver.math.equivalence import exact_zero
from solver.math.numeric import lambdify_np
from solver.math.opcount import count_ops
from solver.math.search import golden_min
from solver.planning.laws import Law, LawError, extremum, sample
from solver.planning.motion import Motion, MotionSpec, coordinated_trapezoids, read_motion
from solver.planning.trajectory import (law_view, assume_positive, coordinate_labels, law_figure, parse_times,
                                        positive_expressions, substitute, time_labels,
                                        time_symbol, vec_or_scalar)
from solver.registry import ask_kind
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.models import Strict
from solver.math.simplify import factor_within, simplified

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
GRID = 801
EDGE = 1e-7
UNKNOWN_T = sp.Symbol("T", positive=True)   # a duration found when solving: at: read before it is known


class Peak(Strict):
    """A torque known at one instant of a motion (the motion itself not given)."""

    joint: int = Field(ge=1, description="the joint (1..n)")
    tau: Scalar = Field(description="its torque τ_j at that instant")
    q: Optional[ExprT] = Field(None, description="the configuration at that instant (for the gravity torque)")


class TimeScalingAsk(Strict):
    """Torque along a motion; uniform time scaling under torque bounds; minimum time; time-optimal motion."""

    kind: Literal["time_scaling"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    find: Literal["torque", "scaling", "minimum_time", "time_optimal"] = Field(
        description="torque: τ(t) by inverse dynamics; scaling: the smallest uniform factor k (t -> k t) meeting "
                    "|τ_i| <= torque_max_i; minimum_time: the shortest T of the law under vmax/amax or torque_max; "
                    "time_optimal: rest-to-rest motion of one coordinate in minimum time under torque_max")
    motion: Optional[MotionSpec] = Field(None, description="the joint motion (a timing law of the robot's n "
                                                           "coordinates, as in trajectory)")
    peaks: Optional[list[Peak]] = Field(None, description="scaling without a motion: the torques at the peak "
                                                          "instants, {joint, tau, q}")
    T: Optional[Scalar] = Field(None, description="with peaks: the duration of the motion (for T' = k T)")
    torque_max: Optional[ExprT] = Field(None, description="bounds |τ_i| <= U_i: one expression or a list of n")
    vmax: Optional[ExprT] = Field(None, description="minimum_time: velocity bounds (one or a list of n)")
    amax: Optional[ExprT] = Field(None, description="minimum_time: acceleration bounds (one or a list of n)")
    moving: Optional[str] = Field(None, description="time_optimal: the coordinate that moves, e.g. q1")
    initial: Optional[Scalar] = Field(None, description="time_optimal: its initial value")
    final: Optional[Scalar] = Field(None, description="time_optimal: its final value")
    hold: dict[str, Scalar] = Field({}, description="time_optimal: values of the coordinates held still")
    at: Optional[Union[Scalar, list[Scalar]]] = Field(
        None, description="instant(s) where the torque is given (may use T, the duration of the motion)")
    positive: list[Scalar] = Field([], description="expressions known to be positive (e.g. R - d), to simplify |.|")
    plots: bool = Field(True, description="figures of the motion and of the torques with their bounds")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")


# ------------------------------------------------------------------------------------------------ torques
@dataclass
class Piece:
    """One interval of the motion with the torque parts as expressions of t."""

    a: sp.Expr
    b: sp.Expr
    inertial: sp.Matrix   # B q̈ + c
    friction: sp.Matrix   # F_v q̇
    gravity: sp.Matrix    # g(q)

    @property
    def tau(self) -> sp.Matrix:
        return self.inertial + self.friction + self.gravity


def _simplify(M: sp.Matrix) -> sp.Matrix:
    """Light tidying only (full simplification of trigonometric functions of polynomials in t is slow): values
    are simplified where they are evaluated."""
    return M.applyfunc(_light)


def _light(x: sp.Expr) -> sp.Expr:
    """Common factors pulled out of x expanded; not expanded where a sum stands in a denominator or under a root
    (expanding would spread it over every term: 53 operations became 4685 on a time-optimal torque)."""
    if count_ops(x) >= 300:
        return x
    if any(p.base.is_Add and not (p.exp.is_Integer and p.exp > 0) for p in x.atoms(sp.Pow)):
        return sp.factor_terms(x)
    return sp.factor_terms(sp.expand(x))


def torque_pieces(motion: Motion, dm: DynamicModel, robot, values: dict, Ginv: Optional[sp.Matrix]) -> list[Piece]:  # type: ignore[no-untyped-def]
    """τ(t) = a(t) + f(t) + g(t) on each interval of the motion (the union of the coordinates' breaks)."""
    t = motion.t
    laws = motion.laws
    same = all(len(law.breaks) == len(laws[0].breaks) and all(simplified(x - y) == 0 for x, y in
                                                                 zip(law.breaks, laws[0].breaks)) for law in laws)
    if same:
        spans = [(laws[0].breaks[k], laws[0].breaks[k + 1], [k] * len(laws)) for k in range(len(laws[0].pieces))]
    else:
        allb: list[sp.Expr] = []
        for law in laws:
            for b in law.breaks:
                if not any(simplified(b - c) == 0 for c in allb):
                    allb.append(b)
        try:
            allb.sort(key=lambda b: float(sp.sympify(b).subs(values)))
        except TypeError:
            raise LawError("the coordinates' laws switch at times that cannot be ordered without parameter values",
                           "law", "give values: for the parameters") from None
        spans = []
        for k in range(len(allb) - 1):
            mid = (allb[k] + allb[k + 1]) / 2
            spans.append((allb[k], allb[k + 1], [law.piece_of(mid.subs(values)) if mid.subs(values).is_number
                                                 else law.piece_of(mid) for law in laws]))
    q, dq, ddq = robot.q, robot.dq, robot.ddq
    out = []
    for a, b, idx in spans:
        pos = [laws[i].pieces[idx[i]] for i in range(len(laws))]
        sub = {}
        for i, p in enumerate(pos):
            sub[q[i]] = p
            sub[dq[i]] = sp.diff(p, t)
            sub[ddq[i]] = sp.diff(p, t, 2)
        inertial = (dm.B * sp.Matrix(ddq) + dm.c).xreplace(sub)
        fric = (dm.Fv * sp.Matrix(dq)).xreplace(sub) if dm.Fv is not None else sp.zeros(robot.n, 1)
        grav = dm.g.xreplace(sub)
        if Ginv is not None:
            Gi = Ginv.xreplace(sub)
            inertial, fric, grav = Gi * inertial, Gi * fric, Gi * grav
        out.append(Piece(a, b, _simplify(inertial), _simplify(fric), _simplify(grav)))
    return out


def tau_law(pieces: list[Piece], i: int, t: sp.Symbol, part: str = "tau") -> Law:
    return Law(t, [pieces[0].a] + [p.b for p in pieces], [getattr(p, part)[i] for p in pieces])


# ------------------------------------------------------------------------------------------------ scaling
def y_limit(a: float, f: float, g: float, U: float) -> float:
    """The largest y >= 0 with a y'² + f y' + g ∈ [−U, U] for every y' in [0, y] (0 if |g| > U; inf if none)."""
    if abs(g) > U * (1 + 1e-12):
        return 0.0
    best = np.inf
    for rhs in (U, -U):
        if a == 0:
            roots = [(rhs - g) / f] if f != 0 else []
        else:
            disc = f * f - 4 * a * (g - rhs)
            if disc < 0:
                continue
            sq = np.sqrt(disc)
            roots = [(-f + sq) / (2 * a), (-f - sq) / (2 * a)]
        for r in roots:
            if r > 1e-15:
                best = min(best, r)
    return best


def y_exact(a: sp.Expr, f: sp.Expr, g: sp.Expr, U: sp.Expr, values: dict) -> Optional[sp.Expr]:
    """The same limit in closed form (the parameters symbolic), on the branch the parameter values select
    (None if no bound). The roots are chosen by value, and only the chosen one is simplified (as sp.solve would
    simplify every root)."""
    y = sp.Symbol("y", positive=True)
    best, val = None, np.inf
    for rhs in (U, -U):
        if simplified(a) == 0 and simplified(f) == 0:
            continue
        for c in sp.solve(a * y ** 2 + f * y + g - rhs, y, simplify=False):
            cv = sp.N(c.subs(values), 30)
            if cv.free_symbols:
                continue
            cn = complex(cv)
            if abs(cn.imag) < 1e-12 and cn.real > 1e-15 and cn.real < val:
                best, val = c, cn.real
    return simplified(best) if best is not None else None


def inverse(y: sp.Expr) -> sp.Expr:
    """1/y for y > 0, written sqrt(1/y²) when that is shorter (k = sqrt((τ − g)/(U − g)) rather than
    1/sqrt((U − g)/(τ − g)))."""
    a = simplified(1 / y)
    b = sp.sqrt(factor_within(sp.cancel(simplified(1 / y ** 2))))
    return b if count_ops(b) < count_ops(a) else a


@dataclass
class Binding:
    """Where the smallest y is attained: joint, piece, time, and whether at a piece end (exact)."""

    joint: int
    piece: int
    t: float
    y: float
    end: Optional[sp.Expr] = None


def scaling_search(pieces: list[Piece], U: list[sp.Expr], values: dict, t: sp.Symbol) -> list[Binding]:
    """min over t of y_i(t) for each joint i: on a grid of each piece, refined by a bounded scalar search; a
    minimum within EDGE of a piece end is attributed to that end (evaluated exactly later)."""
    n = len(U)
    Un = [float(u.subs(values)) for u in U]
    res: list[Binding] = [Binding(i, 0, 0.0, np.inf) for i in range(n)]
    for k, pc in enumerate(pieces):
        a0, b0 = float(sp.sympify(pc.a).subs(values)), float(sp.sympify(pc.b).subs(values))
        if b0 <= a0:
            continue
        fa = [lambdify_np(t, pc.inertial[i].subs(values)) for i in range(n)]
        ff = [lambdify_np(t, pc.friction[i].subs(values)) for i in range(n)]
        fg = [lambdify_np(t, pc.gravity[i].subs(values)) for i in range(n)]
        grid = np.linspace(a0, b0, GRID)
        for i in range(n):
            def yv(x: float, i: int = i) -> float:
                return y_limit(float(fa[i](x)), float(ff[i](x)), float(fg[i](x)), Un[i])
            ys = np.array([yv(x) for x in grid])
            j = int(np.argmin(ys))
            if not np.isfinite(ys[j]):
                continue
            tb, yb = float(grid[j]), float(ys[j])
            lo, hi = grid[max(j - 1, 0)], grid[min(j + 1, GRID - 1)]
            if 0 < j < GRID - 1:
                x, fx = golden_min(yv, lo, hi, 1e-12 * (b0 - a0))
                if fx < yb:
                    tb, yb = x, fx
            end = None
            for e, ev in ((pc.a, a0), (pc.b, b0)):
                if abs(tb - ev) <= EDGE * max(1.0, b0):
                    end = e
            if yb < res[i].y - 1e-14 * max(1.0, yb):
                res[i] = Binding(i, k, tb, yb, end)
    return res


# ------------------------------------------------------------------------------------------------ helpers
def _bounds(problem, ctx, key: str, n: int) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    place = problem.located.place(ctx.path + (key,))
    v = ctx.expr(key)
    vals = v if isinstance(v, list) else [v]
    if len(vals) == 1:
        vals = vals * n
    if len(vals) != n or any(isinstance(x, list) for x in vals):
        raise UserError(f"{key} needs one bound or a list of {n}", place)
    for x in vals:
        if (x.is_number and not x.is_positive) or x.is_nonpositive:
            raise UserError(f"the bounds of {key} must be positive, got {x}", place, "give bounds > 0")
    return vals


def _input_inverse(robot, problem, ctx) -> Optional[sp.Matrix]:  # type: ignore[no-untyped-def]
    G = robot.input_map
    if G is None:
        return None
    if G.shape[0] != G.shape[1]:
        raise UserError("torque bounds need a square input map G (the inputs u = G⁻¹τ)",
                        problem.located.place(("robot", "input_map")))
    return G.inv().applyfunc(simplified)


def _numeric_ready(exprs: list[sp.Expr], values: dict, t: sp.Symbol) -> list[str]:
    """Names of the parameters without a value (a numeric search needs them all)."""
    syms: set = set()
    for e in exprs:
        syms |= sp.sympify(e).subs(values).free_symbols
    return sorted(s.name for s in syms - {t})


def _depends_on(e: sp.Expr, x: sp.Symbol) -> bool:
    """Whether e depends on x: by the exact zero test of de/dx where it decides (π taken as a symbol: it is
    transcendental), else x left after simplifying."""
    if x not in e.free_symbols:
        return False
    z = exact_zero(sp.diff(e, x).xreplace({sp.pi: sp.Dummy("pi", positive=True)}))
    if z is not None:
        return not z
    return x in simplified(e).free_symbols


def _shape_invariant(motion_T: Motion, Tsym: sp.Symbol) -> bool:
    """q(σT; T) does not depend on T (the same shape for every duration)."""
    sig = sp.Symbol("sigma_", positive=True)
    for law in motion_T.laws:
        for p in law.pieces:
            if _depends_on(p.subs(law.t, sig * Tsym), Tsym):
                return False
        for b in law.breaks:
            if _depends_on(sp.sympify(b) / Tsym, Tsym):
                return False
    return True


def _add(sol: Solution, sfx: str, positives: list[sp.Expr], name: str, value: Any, values: dict,
         label: str = "") -> Any:
    """Add a result (|.| simplified with the positive expressions) and its _num companion (parameter values)."""
    v = assume_positive(value, positives)
    sol.add(name + sfx, v, label=label)
    num = substitute(v, values)
    if num is not None:
        sol.add(name + "_num" + sfx, num)
    return v


def _float(x: Any) -> float:
    return float(sp.N(x))


def motion_view(motion: Motion, pieces: Optional[list[Piece]] = None) -> dict:
    """What the templates show of a motion: each coordinate's law and, when short, each joint's torque."""
    view: dict = {"motion": motion, "var": "q", "laws": [law_view(law) for law in motion.laws], "taus": None,
                  "symbols": [sp.Symbol(n, real=True) for n in motion.names]}
    if pieces:
        taus = [law_view(tau_law(pieces, i, motion.t)) for i in range(len(pieces[0].tau))]
        # each row "τ(t) = piece, t ∈ [a, b]" must fit the page width: the piece and its interval's ends together
        if all(count_ops(p) < 60 and count_ops(p) + count_ops(a) + count_ops(b) < 80
               for v in taus for p, a, b in v["pieces"]):
            view["taus"] = taus
    return view


# ------------------------------------------------------------------------------------------------ figures
def torque_figure(pieces: list[Piece], U: Optional[list[sp.Expr]], values: dict, t: sp.Symbol, k: Optional[float],
                  names: list[str], caption: str, marks_at: Optional[list[tuple]] = None) -> Figure:
    """Each joint's torque against time (nominal, and scaled to k T), with the bounds ±U_i."""
    def sample_all() -> list[Panel]:
        panels = []
        for i, name in enumerate(names):
            law = tau_law(pieces, i, t).subs(values)
            law = law.subs({s: 1 for p in law.pieces for s in p.free_symbols - {t}})
            xs, ys = sample(law, {})
            curves = [Curve("nominal" if k else f"$\\tau_{{{i + 1}}}$", xs, ys)]
            if k is not None and abs(k - 1) > 1e-9:
                gl = tau_law(pieces, i, t, "gravity").subs(values)
                fl = tau_law(pieces, i, t, "friction").subs(values)
                _, gs = sample(gl, {})
                _, fs = sample(fl, {})
                scaled = [(y - g - f) / k ** 2 + f / k + g for y, g, f in zip(ys, gs, fs)]
                curves.append(Curve(f"scaled, $k = {k:.4g}$", [x * k for x in xs], scaled))
            hl = []
            if U is not None:
                u = float(U[i].subs(values))
                hl = [(u, "bound"), (-u, "")]
            marks = [(float(x), float(y), lab) for j, x, y, lab in (marks_at or []) if j == i]
            panels.append(Panel("$t$", f"$\\tau_{{{i + 1}}}$", curves, hlines=hl, markers=marks))
        return panels

    return Figure("torque", caption, sample_all)


# ------------------------------------------------------------------------------------------------ the ask
def validate_time_scaling(problem, options: TimeScalingAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The options of the ask's `find`, read and checked by the reader :func:`solve_time_scaling` runs first
    (``_Job.read_<find>``: the motion, the instants, the bounds, the peaks, the moving and held coordinates, a
    square input map), without the model; what needs the torques (a bound below gravity, an instant after the
    minimum time) is checked when solving."""
    job = _Job(problem, options, ctx, Solution("time_scaling"), positive_expressions(problem, options, ctx))
    if options.find == "scaling":
        if job.read_scaling() is None:
            job.read_peaks()
        return
    getattr(job, "read_" + options.find)()


@ask_kind("time_scaling", TimeScalingAsk,
          "torque along a motion, uniform time scaling and minimum time under velocity/acceleration/torque bounds",
          validate=validate_time_scaling)
def solve_time_scaling(problem, options: TimeScalingAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the suffix; `_num` companions with the parameter values):
    torque: tau_path (n-vector of expressions of the motion), tau_at, tau_peak, t_peak, g_max, feasible;
    scaling: k, k_joint, T_scaled, tau_peak, t_peak, g_peak (peaks), tau_scaled_peak, feasible;
    minimum_time: T_min, k (T_min / T), A, V, Ts (the law at T_min), t_peak;
    time_optimal: tau_path, A (or A_acc, A_dec), V, T_min, T_min_coast, T_min_bang, coast_margin, tau_peak,
    feasible, tau_at."""
    positives = positive_expressions(problem, options, ctx)
    sol = Solution("time_scaling", title=options.title or {
        "torque": "Torque along the motion", "scaling": "Uniform time scaling",
        "minimum_time": "Minimum motion time", "time_optimal": "Time-optimal motion"}[options.find])
    job = _Job(problem, options, ctx, sol, positives)
    getattr(job, options.find)()
    return sol


class _Job:
    def __init__(self, problem, options: TimeScalingAsk, ctx, sol: Solution, positives: list[sp.Expr]) -> None:  # type: ignore[no-untyped-def]
        self.problem, self.options, self.ctx, self.sol = problem, options, ctx, sol
        self.positives = positives
        self.values = problem.values
        self.sfx = options.suffix
        self.t = time_symbol(problem)

    # -- small helpers ------------------------------------------------------------------------------------
    def fail(self, sub: tuple, msg: str, hint: str | None = None) -> UserError:
        return UserError(msg, self.problem.located.place(self.ctx.path + sub), hint)

    def add(self, name: str, value: Any, label: str = "") -> Any:
        return _add(self.sol, self.sfx, self.positives, name, value, self.values, label)

    def need(self, key: str, why: str) -> None:
        if getattr(self.options, key) is None:
            raise self.fail(("find",), f"find: {self.options.find} needs {key}: ({why})", f"add {key}:")

    def read_model(self) -> tuple[Any, Optional[sp.Matrix]]:
        """The robot with dynamics and G⁻¹ (None without an input map), without the model."""
        robot = require_model(self.problem)
        return robot, _input_inverse(robot, self.problem, self.ctx)

    def motion(self, T_override: sp.Expr | None = None) -> Motion:
        self.need("motion", "the joint motion")
        robot = self.problem.robot
        m = read_motion(self.problem, self.ctx.path + ("motion",), self.options.motion, self.t, n=robot.n,
                        names=[x.name for x in robot.q], T_override=T_override)
        if m.T is None:
            raise self.fail(("motion",), "the motion needs a finite duration T")
        return m

    def times(self, T: sp.Expr | None) -> list[sp.Expr]:
        if self.options.at is None:
            return []
        return parse_times(self.problem, self.ctx.path + ("at",), self.options.at, T)

    def check_numeric(self, exprs: list[sp.Expr], what: str) -> None:
        missing = _numeric_ready(exprs, self.values, self.t)
        if missing:
            raise self.fail(("find",), f"{what} is searched numerically: every parameter needs a value",
                            "add values: for " + ", ".join(missing))

    def torques(self, motion: Motion, dm: DynamicModel, robot, values: dict,  # type: ignore[no-untyped-def]
                Ginv: Optional[sp.Matrix]) -> list[Piece]:
        try:
            return torque_pieces(motion, dm, robot, values, Ginv)
        except LawError as exc:
            raise self.fail(("motion",), str(exc), exc.hint) from None

    def probe(self, exprs: list[sp.Expr]) -> dict:
        """The parameter values, and 1 for every parameter without one: they only choose between the branches
        of a formula (which root, which joint), the results stay symbolic."""
        syms: set = set()
        for e in exprs:
            syms |= sp.sympify(e).free_symbols
        return {**self.values, **{s: sp.Integer(1) for s in syms if s not in self.values}}

    def largest(self, xs: list[sp.Expr]) -> sp.Expr:
        """The largest of ``xs``: decided with the parameter values, else a Max."""
        if len(xs) == 1:
            return xs[0]
        if all(not sp.sympify(x).subs(self.values).free_symbols for x in xs):
            return max(xs, key=lambda x: _float(sp.sympify(x).subs(self.values)))
        return sp.Max(*xs)

    def law_params(self, motion: Motion) -> None:
        for key in ("A", "V", "Ts"):
            if all(key in law.params for law in motion.laws):
                moving = [law.params[key] for law in motion.laws if law.params.get("Delta", 1) != 0]
                self.add(key, vec_or_scalar(moving or [motion.laws[0].params[key]]), label=key)

    def peaks_of(self, pieces: list[Piece], n: int, part: str = "tau") -> list[Any]:
        return [extremum(tau_law(pieces, i, self.t, part), self.values) for i in range(n)]

    def figures(self, motion: Motion, pieces: list[Piece], U: Optional[list[sp.Expr]], k: Optional[float],
                caption: str, marks: Optional[list[tuple]] = None) -> None:
        if not self.options.plots:
            return
        self.sol.figures.append(law_figure("motion", "The joint motion: position, velocity, acceleration.", motion,
                                           self.values, labels=coordinate_labels(self.problem, motion)))
        self.sol.figures.append(torque_figure(pieces, U, self.values, self.t, k, motion.names, caption, marks))

    # -- torque ---------------------------------------------------------------------------------------------
    def read_torque(self) -> tuple[Any, Optional[sp.Matrix], Motion, list[sp.Expr], Optional[list[sp.Expr]]]:
        """find: torque: (robot, G⁻¹, the motion, the instants, the bounds if given)."""
        robot, Ginv = self.read_model()
        motion = self.motion()
        times = self.times(motion.T)
        U = _bounds(self.problem, self.ctx, "torque_max", robot.n) if self.options.torque_max is not None else None
        return robot, Ginv, motion, times, U

    def torque(self) -> None:
        robot, Ginv, motion, times, U = self.read_torque()
        dm = derive(robot)
        pieces = self.torques(motion, dm, robot, self.values, Ginv)
        self.sol.step("motion", view=motion_view(motion, pieces), dm=dm, G=Ginv is not None)
        self.law_params(motion)
        rows = self.at_rows(pieces, times)
        peaks = self.peak_results(pieces, robot.n, U)
        self.sol.step("torques", rows=rows, peaks=peaks, U=U, names=motion.names)
        self.figures(motion, pieces, U, None, "Torques along the motion" + (" and their bounds." if U else "."))

    def at_rows(self, pieces: list[Piece], times: list[sp.Expr]) -> list[dict]:
        rows = []
        law = Law(self.t, [pieces[0].a] + [p.b for p in pieces], [sp.Integer(0)] * len(pieces))
        labels = time_labels(self.problem, self.ctx.path + ("at",)) if times else []
        for j, tau in enumerate(times, 1):
            tag = "_at" + (str(j) if len(times) > 1 else "")
            try:
                k = law.piece_of(tau)
            except LawError as exc:
                raise self.fail(("at",), str(exc)) from None
            v = pieces[k].tau.subs(self.t, tau).applyfunc(simplified)
            v = self.add("tau" + tag, v, label=f"\\tau({sp.latex(tau)})")
            rows.append({"t": tau, "label": labels[j - 1], "tau": v, "num": substitute(v, self.values)})
        return rows

    def peak_results(self, pieces: list[Piece], n: int, U: Optional[list[sp.Expr]]) -> dict:
        ext = self.peaks_of(pieces, n)
        gext = self.peaks_of(pieces, n, "gravity")
        out: dict = {"tau": ext, "g": gext, "feasible": None}
        if all(e is not None for e in ext):
            self.add("tau_peak", sp.Matrix([e.abs for e in ext]), label="\\max_t|\\tau_i|")
            if all(e.time is not None for e in ext):
                self.add("t_peak", sp.Matrix([e.time for e in ext]), label="t_i^*")
        if all(e is not None for e in gext) and any(e.abs != 0 for e in gext):
            self.add("g_max", sp.Matrix([e.abs for e in gext]), label="\\max_t|g_i|")
        if U is not None and all(e is not None for e in ext):
            try:
                ok = all(_float(e.abs.subs(self.values)) <= _float(u.subs(self.values)) * (1 + 1e-12)
                         for e, u in zip(ext, U))
                out["feasible"] = ok
                self.sol.add("feasible" + self.sfx, bool(ok), "bool", label="\\text{feasible}")
            except TypeError:
                pass
        return out

    # -- uniform scaling ------------------------------------------------------------------------------------
    def read_scaling(self) -> Optional[tuple[Any, Optional[sp.Matrix], Motion, list[sp.Expr], list[sp.Expr]]]:
        """find: scaling along a motion: (robot, G⁻¹, the motion, the bounds, the instants); None with peaks:
        (read by :meth:`read_peaks`)."""
        self.need("torque_max", "the torque bounds")
        if self.options.peaks is not None:
            if self.options.motion is not None:
                raise self.fail(("peaks",), "give either motion: or peaks:, not both")
            return None
        robot, Ginv = self.read_model()
        motion = self.motion()
        U = _bounds(self.problem, self.ctx, "torque_max", robot.n)
        return robot, Ginv, motion, U, self.times(motion.T)

    def scaling(self) -> None:
        read = self.read_scaling()
        if read is None:
            return self.scaling_peaks()
        robot, Ginv, motion, U, times = read
        dm = derive(robot)
        pieces = self.torques(motion, dm, robot, self.values, Ginv)
        self.sol.step("motion", view=motion_view(motion, pieces), dm=dm, G=Ginv is not None)
        self.law_params(motion)
        peaks = self.peak_results(pieces, robot.n, U)
        data = self.uniform(pieces, U, motion.T, robot.n)
        self.add("k_joint", sp.Matrix(data["k_joint"]), label="k_i")
        self.add("k", data["k"], label="k")
        self.add("T_scaled", simplified(data["k"] * motion.T), label="T' = k T")
        self.add("tau_scaled_peak", sp.Matrix(data["scaled"]), label="\\tau_i(k t_i^*)")
        rows = self.at_rows(pieces, times)
        friction = any(x != 0 for pc in pieces for x in pc.friction)
        self.sol.step("scaling", **data, peaks=peaks, U=U, rows=rows, names=motion.names, T=motion.T,
                      friction=friction)
        kf = data["k_float"] if np.isfinite(data["k_float"]) else None
        marks = None
        if kf is not None:
            j, b = data["joint"], data["binds"][data["joint"]]
            marks = [(j, kf * b.t, _float(sp.sympify(data["scaled"][j]).subs(self.values)), "at the bound")]
        self.figures(motion, pieces, U, kf, "Torques of the nominal and of the scaled motion, with the bounds.",
                     marks)

    def uniform(self, pieces: list[Piece], U: list[sp.Expr], T: sp.Expr, n: int) -> dict:
        """k_i = 1/min_t y_i(t), k = max_i k_i, exact where the minimum is at a break."""
        self.check_numeric([e for p in pieces for e in list(p.tau)] + [p.b for p in pieces] + U,
                           "the largest scaling need")
        binds = scaling_search(pieces, U, self.values, self.t)
        for i, b in enumerate(binds):
            if b.y == 0:
                raise self.fail(("torque_max",), f"the gravity torque of joint {i + 1} exceeds its bound along the "
                                "motion: no time scaling makes it feasible", "raise the bound or change the path")
        k_joint, k_num, exact = [], [], []
        for i, b in enumerate(binds):
            if not np.isfinite(b.y):
                k_joint.append(sp.Integer(0))
                k_num.append(0.0)
                exact.append(True)
                continue
            val = None
            if b.end is not None:
                pc = pieces[b.piece]
                parts = [getattr(pc, part)[i].subs(self.t, b.end) for part in ("inertial", "friction", "gravity")]
                y = y_exact(*[simplified(x) for x in parts], U[i], self.values)
                if y is not None:
                    val = inverse(y)
            if val is None:
                val = sp.Float(1 / b.y, 12)
            k_joint.append(val)
            k_num.append(1 / b.y)
            exact.append(b.end is not None)
        j = int(np.argmax(k_num))
        k = k_joint[j]
        # the scaled torques at the binding instants: (τ − g − f)/k² + f/k + g
        scaled = []
        for i, b in enumerate(binds):
            if not np.isfinite(b.y):
                scaled.append(sp.Integer(0))
                continue
            pc = pieces[b.piece]
            tb = b.end if b.end is not None else sp.Float(b.t, 15)
            a, f, g = (getattr(pc, part)[i].subs(self.t, tb) for part in ("inertial", "friction", "gravity"))
            scaled.append(simplified(a / k ** 2 + f / k + g))
        knum = _float(sp.sympify(k).subs(self.values))
        return {"binds": binds, "k_joint": k_joint, "k": k, "joint": j, "exact": exact, "k_float": knum,
                "scaled": scaled}

    def read_peaks(self) -> tuple[list[sp.Expr], list[tuple[Any, sp.Expr, Optional[list]]], Optional[sp.Expr]]:
        """find: scaling with peaks: (the bounds, per peak (its entry, τ, q when there is gravity), T if given):
        joints of the robot (or of the bounds without one), a configuration of n values with gravity."""
        peaks = self.options.peaks or []
        robot = self.problem.robot
        n = robot.n if robot is not None else max(p.joint for p in peaks)
        U = _bounds(self.problem, self.ctx, "torque_max", n)
        gravity = robot is not None and robot.gravity is not None
        rows = []
        for j, p in enumerate(peaks):
            base = ("peaks", j)
            if p.joint > n:
                raise self.fail(base + ("joint",), f"joint {p.joint} does not exist (n = {n})")
            tau = self.ctx.expr(*base, "tau")
            qv = None
            if gravity:
                if p.q is None:
                    raise self.fail(base, "with gravity, a peak needs its configuration q: (for g(q))")
                qv = self.ctx.expr(*base, "q")
                qv = qv if isinstance(qv, list) else [qv]
                if len(qv) != robot.n:
                    raise self.fail(base + ("q",), f"q needs {robot.n} values")
            rows.append((p, tau, qv))
        return U, rows, self.ctx.expr("T") if self.options.T is not None else None

    def scaling_peaks(self) -> None:
        U, peaks, T = self.read_peaks()
        robot = self.problem.robot
        g_vec = None
        if robot is not None and robot.gravity is not None:
            g_vec = derive(robot).g
        rows, k_list, g_list, scaled = [], [], [], []
        probe = self.probe([tau for _, tau, _ in peaks] + U)
        for j, (p, tau, qv) in enumerate(peaks):
            base = ("peaks", j)
            g = sp.Integer(0)
            if g_vec is not None:
                g = simplified(g_vec[p.joint - 1].subs(dict(zip(robot.q, qv))))
            u = U[p.joint - 1]
            a = simplified(tau - g)
            nums = [_float(x.subs(probe)) for x in (a, g, u)]
            if abs(nums[1]) > nums[2]:
                raise self.fail(base, "the gravity torque alone exceeds the bound: no time scaling helps")
            y = y_exact(a, sp.Integer(0), g, u, probe)
            kk = inverse(y) if y is not None else sp.Integer(0)
            k_list.append(kk)
            g_list.append(g)
            rows.append({"joint": p.joint, "tau": tau, "g": g, "U": u, "k": kk})
        kn = [_float(x.subs(probe)) for x in k_list]
        jmax = int(np.argmax(kn))
        k = k_list[jmax]
        for r in rows:
            r["scaled"] = simplified((r["tau"] - r["g"]) / k ** 2 + r["g"])
            scaled.append(r["scaled"])
        if robot is not None and robot.gravity is not None:
            self.add("g_peak", sp.Matrix(g_list), label="g_j(q(t_j))")
        self.add("k_joint", sp.Matrix(k_list), label="k_j")
        self.add("k", k, label="k")
        if T is not None:
            self.add("T_scaled", simplified(k * T), label="T' = k T")
        self.add("tau_scaled_peak", sp.Matrix(scaled), label="\\tau_j(k t_j)")
        self.sol.step("peaks", rows=rows, k=k, joint=jmax, T=T, gravity=g_vec is not None,
                      unit=sorted(s.name for s in probe if s not in self.values))

    # -- minimum time -----------------------------------------------------------------------------------------
    def read_minimum_time(self) -> tuple[Any, Optional[sp.Expr], dict]:
        """find: minimum_time: (robot, the motion's T if given, what :meth:`read_minimum_time_kinematic` or
        :meth:`read_minimum_time_torque` read): a motion and either kinematic or torque bounds."""
        robot = self.problem.robot
        if robot is None:
            raise self.fail(("find",), "minimum_time needs the robot (its coordinates)", "add robot:")
        spec = self.options.motion
        self.need("motion", "the timing law")
        kin = self.options.vmax is not None or self.options.amax is not None
        if kin and self.options.torque_max is not None:
            raise self.fail(("torque_max",), "give kinematic bounds (vmax/amax) or torque bounds, not both")
        if not kin and self.options.torque_max is None:
            raise self.fail(("find",), "minimum_time needs bounds: vmax/amax or torque_max")
        T_given = self.ctx.expr("motion", "T") if spec.T is not None else None
        read = self.read_minimum_time_kinematic(robot, spec) if kin else self.read_minimum_time_torque()
        return robot, T_given, read

    def minimum_time(self) -> None:
        robot, T_given, read = self.read_minimum_time()
        if "V" in read:
            self.minimum_time_kinematic(robot, self.options.motion, T_given, **read)
        else:
            self.minimum_time_torque(robot, T_given, **read)

    def read_minimum_time_kinematic(self, robot, spec: MotionSpec) -> dict:  # type: ignore[no-untyped-def]
        """The velocity and acceleration bounds V, A and the motion of free duration T_f (of the trapezoidal law
        the bounds define: only its end positions, read as a cubic)."""
        n = robot.n
        V = _bounds(self.problem, self.ctx, "vmax", n) if self.options.vmax is not None else None
        A = _bounds(self.problem, self.ctx, "amax", n) if self.options.amax is not None else None
        Tf = sp.Symbol("T_f", positive=True)
        if spec.law in ("trapezoidal", "bang_coast_bang") and V is not None and A is not None:
            if spec.Ts is not None or spec.V is not None or spec.A is not None:
                raise self.fail(("motion", "law"), "the bounds define the trapezoidal law: remove Ts/V/A from it")
            spec = spec.model_copy(update={"law": "cubic"})  # only to read the end positions
        base = read_motion(self.problem, self.ctx.path + ("motion",), spec, self.t, n=n,
                           names=[x.name for x in robot.q], T_override=Tf)
        return {"V": V, "A": A, "Tf": Tf, "base": base}

    def minimum_time_kinematic(self, robot, spec: MotionSpec, T_given: Optional[sp.Expr], V: Optional[list],  # type: ignore[no-untyped-def]
                               A: Optional[list], Tf: sp.Symbol, base: Motion) -> None:
        law = spec.law
        if law in ("trapezoidal", "bang_coast_bang") and V is not None and A is not None:
            qi = [law_.pieces[0].subs(self.t, 0) for law_ in base.laws]
            qf = [law_.pieces[-1].subs(self.t, Tf) for law_ in base.laws]
            notes: list[str] = []
            laws = coordinated_trapezoids(self.t, [simplified(x) for x in qi], [simplified(x) for x in qf], V, A,
                                          notes)
            motion = Motion(self.t, "trapezoidal", laws, laws[0].end, base.names, notes)
            T_min = motion.T
            per = [{"T": lw.params["T_own"], "coast": lw.params["coast"], "margin": lw.params["margin"],
                    "T_coast": lw.params["T_coast"], "T_bang": lw.params["T_bang"]} for lw in laws]
            how = "trapezoid"
        else:
            per, Ts = [], []
            for i, lw in enumerate(base.laws):
                cands = []
                for k, bound in ((1, V), (2, A)):
                    if bound is None:
                        continue
                    ext = extremum(lw.diff(k), self.values)
                    if ext is None or ext.how == "symbolic" or ext.how == "numeric":
                        raise self.fail(("motion",), f"the largest {'speed' if k == 1 else 'acceleration'} of "
                                        f"{base.names[i]} is not found in closed form: the minimum time is not "
                                        "computed", "use a polynomial, cycloidal or trapezoidal law")
                    if ext.abs == 0:
                        continue
                    sols = [s for s in sp.solve(sp.Eq(ext.abs, bound[i]), Tf) if s.is_positive is not False]
                    if not sols:
                        raise self.fail(("motion",), f"no duration meets the bound on {base.names[i]}")
                    cands.append((k, simplified(self.largest(sols)), ext))
                Ti = self.largest([c[1] for c in cands]) if cands else sp.Integer(0)
                per.append({"T": Ti, "cands": cands})
                Ts.append(Ti)
            T_min = self.largest(Ts)
            motion = base.subs({Tf: T_min})
            how = "replan"
        self.add("T_min", T_min, label="T_{\\min}")
        if T_given is not None:
            self.add("k", simplified(T_min / T_given), label="k = T_{\\min}/T")
        self.law_params(motion)
        shown = motion.subs(self.values)
        self.sol.step("minimum_time", how=how, per=per, T_min=T_min, T=T_given, V=V, A=A, view=motion_view(shown),
                      names=motion.names, Tf=Tf)
        if self.options.plots and not sp.sympify(T_min).subs(self.values).free_symbols:
            self.sol.figures.append(law_figure("motion", "The minimum-time motion: position, velocity, acceleration.",
                                               motion, self.values, labels=coordinate_labels(self.problem, motion)))

    def read_minimum_time_torque(self) -> dict:
        """G⁻¹, the law of unit duration (a rest-to-rest law: the same shape for every T) and the torque bounds;
        the instants, read with T unknown (whether they lie in [0, T_min] is checked when solving)."""
        robot, Ginv = self.read_model()
        Tsym = sp.Symbol("T_s", positive=True)
        if not _shape_invariant(self.motion(Tsym), Tsym):
            raise self.fail(("motion", "law"), "under torque bounds the minimum time is found by scaling a law whose "
                            "shape does not change with T (a rest-to-rest law)", "use a rest-to-rest law, or "
                            "find: scaling for a given T")
        unit = self.motion(sp.Integer(1))
        U = _bounds(self.problem, self.ctx, "torque_max", robot.n)
        self.times(UNKNOWN_T)
        return {"Ginv": Ginv, "unit": unit, "U": U}

    def minimum_time_torque(self, robot, T_given: Optional[sp.Expr], Ginv: Optional[sp.Matrix], unit: Motion,  # type: ignore[no-untyped-def]
                            U: list[sp.Expr]) -> None:
        dm = derive(robot)
        pieces = self.torques(unit, dm, robot, self.values, Ginv)
        data = self.uniform_min_time(pieces, U, robot.n)
        T_min = data["k"]
        motion = self.motion(T_min)
        self.law_params(motion)
        if T_given is not None:
            self.add("k", simplified(T_min / T_given), label="k = T_{\\min}/T")
        b = data["binds"][data["joint"]]
        tpk = (b.end if b.end is not None else sp.Float(b.t, 12)) * T_min
        self.add("t_peak", simplified(tpk), label="t^*")
        full = self.torques(motion.subs(self.values), dm, robot, self.values, Ginv)
        times = self.times(T_min)
        rows = self.at_rows(full, times)
        shown = motion.subs(self.values)
        self.sol.step("minimum_time_torque", **data, U=U, unit=motion_view(unit, pieces),
                      view=motion_view(shown, full) if not _numeric_ready([shown.T], {}, self.t) else None,
                      dm=dm, names=motion.names, t_peak=tpk, rows=rows)
        if self.options.plots:
            Tn = _float(sp.sympify(T_min).subs(self.values))
            tv = _float(sp.sympify(tpk).subs(self.values))
            marks = [(data["joint"], tv, _float(sp.sympify(data["scaled"][data["joint"]]).subs(self.values)),
                      "at the bound")]
            self.figures(motion.subs({**self.values}), full, U, None, marks=marks, caption=
                         f"Torques of the minimum-time motion ($T = {Tn:.4g}$), with the bounds.")

    def uniform_min_time(self, pieces: list[Piece], U: list[sp.Expr], n: int) -> dict:
        """As :meth:`uniform` for the law of unit duration: T_min = k*."""
        data = self.uniform(pieces, U, sp.Integer(1), n)
        self.add("T_min", data["k"], label="T_{\\min}")
        return data

    # -- time-optimal -----------------------------------------------------------------------------------------
    def display_law(self, law: Law, qi: sp.Expr, qf: sp.Expr, sign: sp.Expr, coast: Optional[bool],
                    sym: bool) -> Law:
        """The optimal law written with the symbols A (A_+, A_-), V (or V_p) and T* (shorter than the values)."""
        t = self.t
        if sym:
            A1 = A2 = sp.Symbol("A", positive=True)
        else:
            A1, A2 = sp.Symbol("A_+", positive=True), sp.Symbol("A_-", positive=True)
        V = sp.Symbol("V" if (coast or coast is None) else "V_p", positive=True)
        T = sp.Symbol("T^*", positive=True)
        p1 = qi + sign * A1 * t ** 2 / 2
        p3 = qf - sign * A2 * (T - t) ** 2 / 2
        if len(law.pieces) == 3:
            p2 = qi + sign * (V ** 2 / (2 * A1) + V * (t - V / A1))
            return Law(t, [sp.Integer(0), V / A1, T - V / A2, T], [p1, p2, p3])
        return Law(t, [sp.Integer(0), V / A1, T], [p1, p3])

    def read_time_optimal(self) -> tuple[Any, Optional[sp.Matrix], int, dict, sp.Expr, sp.Expr, sp.Expr,
                                         list[sp.Expr]]:
        """find: time_optimal: (robot, G⁻¹, the moving coordinate's index j, the held values, q_i, q_f, Δ, the
        bounds); the instants read with T unknown (whether they lie in [0, T*] is checked when solving)."""
        robot, Ginv = self.read_model()
        for key in ("moving", "initial", "final", "torque_max"):
            self.need(key, {"moving": "the coordinate that moves", "initial": "its initial value",
                            "final": "its final value", "torque_max": "the torque bounds"}[key])
        by_name = {x.name: i for i, x in enumerate(robot.q)}
        if self.options.moving not in by_name:
            raise self.fail(("moving",), f"'{self.options.moving}' is not a coordinate", "use " + ", ".join(by_name))
        j = by_name[self.options.moving]
        hold = {}
        for name in self.options.hold:
            if name not in by_name or by_name[name] == j:
                raise self.fail(("hold", name), f"'{name}' is not a coordinate held still")
            hold[robot.q[by_name[name]]] = self.ctx.expr("hold", name)
        missing = [x.name for i, x in enumerate(robot.q) if i != j and x not in hold]
        if missing:
            raise self.fail(("hold",), "give the values of the coordinates held still: " + ", ".join(missing))
        qi, qf = self.ctx.expr("initial"), self.ctx.expr("final")
        D = simplified(qf - qi)
        if D == 0:
            raise self.fail(("final",), "the final value equals the initial one: nothing to move")
        U = _bounds(self.problem, self.ctx, "torque_max", robot.n)
        self.times(UNKNOWN_T)
        return robot, Ginv, j, hold, qi, qf, D, U

    def time_optimal(self) -> None:
        robot, Ginv, j, hold, qi, qf, D, U = self.read_time_optimal()
        dm = derive(robot)
        x, v, a = robot.q[j], robot.dq[j], robot.ddq[j]
        sub = dict(hold)
        for i in range(robot.n):
            if i != j:
                sub[robot.dq[i]] = 0
                sub[robot.ddq[i]] = 0
        tau = dm.lhs.xreplace(sub)
        if Ginv is not None:
            tau = Ginv.xreplace(sub) * tau
        tau = tau.applyfunc(lambda e: sp.factor_terms(simplified(e)))
        self.add("tau_path", tau, label="\\tau \\text{ along the motion}")
        sign = sp.sign(D) if D.is_number else sp.Integer(1)
        acc_up, acc_dn, vel, rows = [], [], [], []
        zero = {v: 0, a: 0}
        for i in range(robot.n):
            e = tau[i]
            bi = simplified(sp.diff(e, a))
            ci = simplified(sp.diff(e, v, 2).subs(zero) / 2)
            fi = simplified(sp.diff(e, v).subs(zero))
            gi = simplified(e.subs(zero))
            if simplified(e - (bi * a + ci * v ** 2 + fi * v + gi)) != 0:
                bi = ci = fi = sp.nan  # not of this form: checked along the motion
            deps = (sp.sympify(bi).free_symbols | sp.sympify(ci).free_symbols | gi.free_symbols) & {x, v, a}
            kind = "none"
            if bi is sp.nan or deps or fi != 0 or (bi != 0 and ci != 0):
                kind = "check"
            elif bi != 0:
                kind = "acc"
                if i == j:  # b_jj > 0: B is positive definite
                    self.positives = self.positives + [bi]
                bs = bi if (i == j or bi.is_positive or bi.is_negative) else None
                if bs is None and gi != 0:
                    kind = "check"
                else:
                    sb = 1 if (bs is None or i == j or bi.is_positive) else -1
                    mag = bi if i == j else sp.Abs(bi)
                    hi, lo = (U[i] - gi) / (sb * mag), (-U[i] - gi) / (sb * mag)
                    if sb < 0:
                        hi, lo = lo, hi
                    up, dn = (hi, -lo) if sign > 0 else (-lo, hi)
                    acc_up.append(simplified(up))
                    acc_dn.append(simplified(dn))
            elif ci != 0:
                kind = "vel"
                cs = assume_positive(sp.Abs(ci), self.positives)
                if ci.is_positive or (cs == ci):
                    vel.append(simplified(sp.sqrt((U[i] - gi) / cs)))
                elif ci.is_negative or cs == -ci:
                    vel.append(simplified(sp.sqrt((U[i] + gi) / cs)))
                elif gi == 0:
                    vel.append(simplified(sp.sqrt(U[i] / cs)))
                else:
                    kind = "check"
            if kind == "none" and gi != 0:
                kind = "check"  # a constant (gravity) torque: within its bound or not, at any speed
            rows.append({"i": i, "b": bi, "c": ci, "g": gi, "f": fi, "kind": kind})
        if not acc_up:
            raise self.fail(("moving",), "no row of the model bounds the acceleration of the moving coordinate with "
                            "constant coefficients: not an analytic case", "the time-optimal motion then needs a "
                            "numerical method (not provided)")

        def least(xs: list[sp.Expr]) -> sp.Expr:
            if len(xs) == 1:
                return xs[0]
            if all(not e.subs(self.values).free_symbols for e in xs):
                return min(xs, key=lambda e: _float(e.subs(self.values)))
            return sp.Min(*xs)

        A1, A2 = assume_positive(least(acc_up), self.positives), assume_positive(least(acc_dn), self.positives)
        Vb = assume_positive(least(vel), self.positives) if vel else None
        aD = sp.Abs(D) if not (D.is_positive or D.is_negative) else sign * D
        aD = assume_positive(aD, self.positives)
        sym = simplified(A1 - A2) == 0
        Vp = simplified(sp.sqrt(2 * aD * A1 * A2 / (A1 + A2)))
        T_bang = simplified(Vp / A1 + Vp / A2)
        coast = False
        T_coast = margin = None
        if Vb is not None:
            T_coast = simplified(aD / Vb + Vb / (2 * A1) + Vb / (2 * A2))
            margin = simplified(aD - Vb ** 2 * (1 / A1 + 1 / A2) / 2)
            mnum = margin.subs(self.values)
            coast = bool(mnum > 0) if mnum.is_number else None
        T_bang = assume_positive(T_bang, self.positives)
        if T_coast is not None:
            T_coast, margin = assume_positive(T_coast, self.positives), assume_positive(margin, self.positives)
        if coast is None:
            T_min = T_coast
            note = "coast"
        else:
            T_min = T_coast if coast else T_bang
            note = ""
        if sym:
            self.add("A", A1, label="A")
        else:
            self.add("A_acc", A1, label="A_+")
            self.add("A_dec", A2, label="A_-")
        if Vb is not None:
            self.add("V", Vb, label="V")
            self.add("T_min_coast", T_coast, label="T_{\\text{coast}}")
            self.add("coast_margin", margin, label="|\\Delta| - V^2/A")
        self.add("T_min_bang", T_bang, label="T_{\\text{bang}}")
        self.add("T_min", T_min, label="T^*")
        # the optimal law of q_j and the torques along it
        t = self.t
        Vuse = Vb if (coast or coast is None) else Vp
        t1 = simplified(Vuse / A1)
        t2 = simplified(T_min - Vuse / A2)
        p1 = qi + sign * A1 * t ** 2 / 2
        p3 = qf - sign * A2 * (T_min - t) ** 2 / 2
        if coast or coast is None:
            p2 = qi + sign * (A1 * t1 ** 2 / 2 + Vuse * (t - t1))
            law = Law(t, [sp.Integer(0), t1, t2, T_min], [p1, p2, p3])
        else:
            law = Law(t, [sp.Integer(0), t1, T_min], [p1, p3])
        laws = []
        for i, q_i in enumerate(robot.q):
            laws.append(law if i == j else Law(t, list(law.breaks), [hold[q_i]] * len(law.pieces)))
        motion = Motion(t, "time_optimal", laws, T_min, [x.name for x in robot.q])
        pieces = self.torques(motion, dm, robot, self.values, Ginv)
        peaks = self.peak_results(pieces, robot.n, U)
        times = self.times(T_min)
        at_rows = self.at_rows(pieces, times)
        self.sol.step("time_optimal", rows=rows, A1=A1, A2=A2, V=Vb, sym=sym, D=D, aD=aD, T_min=T_min,
                      T_coast=T_coast, T_bang=T_bang, margin=margin, coast=coast, note=note, x=x, v=v, a=a, tau=tau,
                      U=U, peaks=peaks, at_rows=at_rows, names=motion.names, qi=qi, qf=qf, hold=hold,
                      lawv=law_view(self.display_law(law, qi, qf, sign, coast, sym)), Vp=Vp,
                      view=motion_view(motion, pieces), j=j)
        state = set(robot.q) | set(robot.dq) | set(robot.ddq)
        if self.options.plots and not _numeric_ready([T_min] + [e.subs({z: 0 for z in state}) for e in tau] + U,
                                                     self.values, t):
            self.figures(motion, pieces, U, None, "Time-optimal torques, with the bounds.")
