"""Trajectories (ask kind ``trajectory``): timing laws in joint space, or Cartesian paths (line, arc, circle;
position with axis-angle orientation) with a timing law s(t) and the joint motion through the robot's kinematics.

Timing laws and their formulas: :mod:`solver.planning.laws`; paths: :mod:`solver.planning.paths`. The values
at given instants (q, q̇, q̈ and, on a path, p, ṗ, p̈, ω) are exact when the data are; the maxima of |q̇| and |q̈|
with the instants where they occur come from the ends of the pieces and the zeros of the next derivative.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field
from sympy.matrices.common import ShapeError

from solver.math.numeric import lambdify_np
from solver.math.simplify import simplified
from solver.planning.laws import LawError, extremum, less, sample
from solver.planning.motion import Motion, MotionSpec, read_motion
from solver.planning.paths import IK_TOL, Path, arc, follow, is_rotation, line, rot_axis_angle, with_orientation
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Curve, Figure, Panel, Solution, Step
from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
ACCENT = ("", "\\dot ", "\\ddot ")


class PathSpec(Strict):
    """A Cartesian path, parametrized by its arc length s ∈ [0, L]."""

    type: Literal["line", "arc", "circle"] = Field(description="line (start to end), arc or circle")
    start: Optional[ExprT] = Field(None, description="line: initial point p_A, or a 4x4 pose ⁰T_A (then the "
                                                     "orientation is interpolated too)")
    end: Optional[ExprT] = Field(None, description="line: final point p_B, or a 4x4 pose ⁰T_B")
    center: Optional[ExprT] = Field(None, description="arc/circle: center (2 or 3 components)")
    radius: Optional[Scalar] = Field(None, description="arc/circle: radius ρ")
    phase: Scalar = Field(0, description="arc/circle: angle φ₀ of the initial point, from the first axis")
    angle: Optional[Scalar] = Field(None, description="arc: swept angle α (signed; circle: 2π)")
    axes: Optional[ExprT] = Field(None, description="arc/circle in space: [u, v], orthonormal axes of its plane "
                                                    "(default x and y)")
    orientation: Optional[dict[str, ExprT]] = Field(
        None, description="{start: ⁰R_A, end: ⁰R_B}: orientation interpolated by axis-angle, θ(s) = θ_AB s/L")


class TrajectoryAsk(MotionSpec):
    """A timing law (joint or path coordinate), its values, derivatives and maxima; optionally along a path."""

    kind: Literal["trajectory"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    path: Optional[PathSpec] = Field(None, description="a Cartesian path; the law is then s(t) from 0 to L")
    task: Optional[ExprT] = Field(None, description="with a path: the robot's task function r = f(q) (as many "
                                                    "components as the path), or `dh` for the position of the last "
                                                    "DH frame, for the joint motion (numerical IK)")
    q_start: Optional[ExprT] = Field(None, description="with task: initial guess of q for the inverse kinematics at "
                                                       "the start of the path (default all 0)")
    at: Optional[Union[Scalar, list[Scalar]]] = Field(
        None, description="instant(s) where values are given (may use T, the duration), e.g. T/2 or [0, T]")
    positive: list[Scalar] = Field([], description="expressions known to be positive (e.g. R - d), to simplify |.|")
    plots: bool = Field(True, description="figures of the law, its derivatives and the path")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")


def time_symbol(problem) -> sp.Symbol:  # type: ignore[no-untyped-def]
    """The problem's symbol t (so that expected values may use it), else a real symbol t."""
    s = problem.symbols.get("t")
    return s if s is not None else sp.Symbol("t", real=True)


def assume_positive(e: Any, positives: list[sp.Expr]) -> Any:
    """|x| → x for x positive under the problem's symbols and the listed positive expressions."""
    if not positives or e is None:
        return e
    if isinstance(e, sp.MatrixBase):
        return e.applyfunc(lambda x: assume_positive(x, positives))
    if not isinstance(e, sp.Basic):
        return e
    if isinstance(e, sp.Expr) and not e.has(sp.Float) and not any(p.has(sp.Float) for p in positives):
        return _assume_positive(e, tuple(positives))
    return _refined(e, positives)


@lru_cache(maxsize=4096)
def _assume_positive(e: sp.Expr, positives: tuple) -> Any:
    """:func:`_refined`, memoized for exact expressions (a result is refined again when it is reported)."""
    return _refined(e, list(positives))


def _refined(e: sp.Basic, positives: list[sp.Expr]) -> Any:
    facts = sp.And(*[sp.Q.positive(p) for p in positives])
    return simplified(sp.refine(e, facts))


def time_labels(problem, path: tuple) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """The instants of ``at:`` as written (T a symbol), for the report."""
    names = dict(problem.names)
    names.setdefault("T", sp.Symbol("T", positive=True))
    val = problem.parse_at(path, names)
    return val if isinstance(val, list) else [val]


def parse_times(problem, path: tuple, raw: Any, T: sp.Expr | None) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """The instants of ``at:`` (T = the duration)."""
    names = dict(problem.names)
    if T is not None:
        names["T"] = T
    val = problem.parse_at(path, names)
    vals = val if isinstance(val, list) else [val]
    for k, v in enumerate(vals):
        if isinstance(v, list):
            raise UserError("at: takes instants (a value or a flat list)", problem.located.place(path))
        if v.free_symbols & {s for s in problem.robot.q + problem.robot.dq} if problem.robot else set():
            raise UserError("an instant cannot depend on the coordinates", problem.located.place(path))
        if T is not None and (less(v, 0) is True or less(T, v) is True):
            raise UserError(f"the instant {v} is outside the motion [0, {T}]",
                            problem.located.place(path + ((k,) if isinstance(val, list) else ())),
                            "give instants between 0 and T")
    return vals


def vec_or_scalar(xs: list[Any]) -> Any:
    return xs[0] if len(xs) == 1 else sp.Matrix(xs)


def substitute(x: Any, values: dict) -> Any:
    if x is None or not values:
        return None
    y = x.subs(values) if hasattr(x, "subs") else x
    if isinstance(y, sp.MatrixBase):
        y = y.applyfunc(simplified)
        return None if y == x else y
    y = simplified(y)
    return None if y == x else y


def law_results(sol: Solution, motion: Motion, values: dict, positives: list[sp.Expr], sfx: str,
                var: str) -> dict:
    """Results of the law itself: parameters, q(t) and derivatives (one-piece laws), maxima. Returns the data
    the templates show."""
    def add(name: str, value: Any, label: str = "") -> None:
        sol.add(name + sfx, assume_positive(value, positives), label=label)

    laws = motion.laws
    params: dict[str, Any] = {}
    for key in ("A", "V", "Ts"):
        if all(key in law.params for law in laws):
            params[key] = vec_or_scalar([law.params[key] for law in laws])
            add(key, params[key], label={"A": "A", "V": "V", "Ts": "T_s"}[key])
    if motion.T is not None:
        add("T", motion.T, label="T")
    if motion.law in ("cubic", "quintic", "polynomial"):
        co = [law.params["coeffs"][0] for law in laws]
        add("coeffs", sp.Matrix(co[0]) if len(co) == 1 else sp.Matrix(co), label="a")
    exprs = {}
    for k, pre in enumerate(("", "d", "dd")):
        e = motion.exprs(k)
        if e is not None:
            exprs[k] = e
            add(f"{pre}{var}_t", e[0] if e.shape[0] == 1 else e, label=ACCENT[k] + f"{var}(t)")
    maxima = {}
    for k, pre in ((1, "d"), (2, "dd")):
        ext = [extremum(law.diff(k), values) for law in laws]
        if any(e is None for e in ext):
            continue
        maxima[k] = ext
        add(f"max_{pre}{var}", vec_or_scalar([e.abs for e in ext]), label=f"\\max|{ACCENT[k]}{var}|")
        if all(e.time is not None for e in ext):
            add(f"t_max_{pre}{var}", vec_or_scalar([e.time for e in ext]), label="t^*")
    dlaws = [(law_view(law.diff(1)), law_view(law.diff(2))) for law in laws]
    return {"params": params, "exprs": exprs, "maxima": maxima, "dlaws": dlaws}


def evaluate(sol: Solution, motion: Motion, times: list[sp.Expr], values: dict, positives: list[sp.Expr],
             sfx: str, var: str, labels: list[sp.Expr]) -> list[dict]:
    """q, q̇, q̈ at each instant (results <var>_at, d<var>_at, dd<var>_at, numbered when several, and _num with
    the parameter values)."""
    rows = []
    for j, tau in enumerate(times, 1):
        tag = "_at" + (str(j) if len(times) > 1 else "")
        row = {"t": tau, "label": labels[j - 1], "vals": [], "nums": []}
        for k, pre in enumerate(("", "d", "dd")):
            v = assume_positive(vec_or_scalar(list(motion.vector(k, tau))), positives)
            sol.add(f"{pre}{var}{tag}{sfx}", v, label=f"{pre}{var}({tau})")
            num = substitute(v, values)
            if num is not None:
                sol.add(f"{pre}{var}{tag}_num{sfx}", num)
            row["vals"].append(v)
            row["nums"].append(num)
        rows.append(row)
    return rows


def coordinate_labels(problem, motion: Motion) -> list[str]:  # type: ignore[no-untyped-def]
    """$q_1$, $\\theta$, $s$: the coordinates' LaTeX names (the problem's, for a robot's coordinates)."""
    by_name = {s.name: s for s in (problem.robot.q if problem.robot else [])}
    out = []
    for n in motion.names:
        sym = by_name.get(n)
        tex = problem.latex_names.get(sym) if sym is not None else None
        out.append(f"${tex or sp.latex(sp.Symbol(n))}$")
    return out


def law_figure(name: str, caption: str, motion: Motion, values: dict, var: str = "q",
               labels: list[str] | None = None) -> Figure:
    """Position, velocity and acceleration against time, one curve per coordinate."""
    labels = labels or [f"${sp.latex(sp.Symbol(n))}$" for n in motion.names]
    syms: set = set()
    for law in motion.laws:
        for p in law.pieces:
            syms |= p.free_symbols
        for b in law.breaks:
            syms |= sp.sympify(b).free_symbols
    unit = sorted((s.name for s in syms - {motion.t} - set(values)))

    def sample_all() -> list[Panel]:
        panels = []
        single = labels[0].strip("$") if len(labels) == 1 else var
        for k, ylab in enumerate((f"${single}$", f"$\\dot {{{single}}}$", f"$\\ddot {{{single}}}$")):
            curves = []
            for law, lab in zip(motion.derivative(k) if k else motion.laws, labels):
                xs, ys = sample(law, values)
                curves.append(Curve(lab if len(labels) > 1 else "", xs, ys))  # (one coordinate: the axis names it)
            panels.append(Panel("$t$", ylab, curves))
        return panels

    note = "" if not unit else " Parameters without a numeric value set to 1 (" + ", ".join(unit) + ")."
    return Figure(name, caption + note, sample_all)


# ------------------------------------------------------------------------------------------------ paths
def _matrix(problem, path: tuple, shape: tuple | None = None) -> sp.Matrix:  # type: ignore[no-untyped-def]
    val = problem.parse_at(path)
    shp = shape_of(val)
    if len(shp) == 1:
        return sp.Matrix(val)
    if len(shp) == 2 and shp[1] > 0:
        return sp.Matrix(val)
    raise UserError("a vector or a matrix is needed here", problem.located.place(path))


def build_path(problem, ctx, spec: PathSpec, s: sp.Symbol, check_only: bool = False) -> Path:  # type: ignore[no-untyped-def]
    """The path of ``path:``; ``check_only`` (validation): the same checks, a line's length and p(s) not
    simplified, the relative rotation of the end poses not computed."""
    base = ctx.path + ("path",)

    def fail(sub: tuple, msg: str, hint: str | None = None) -> UserError:
        return UserError(msg, problem.located.place(base + sub), hint)

    if spec.type == "line":
        if spec.start is None or spec.end is None:
            raise fail(("type",), "a line needs start: and end: (points or 4x4 poses)")
        ends = [_matrix(problem, base + (k,)) for k in ("start", "end")]
        poses = [M.shape == (4, 4) for M in ends]
        if poses[0] != poses[1]:
            raise fail(("end",), "start and end must both be points or both 4x4 poses")
        if poses[0]:
            pA, pB = ends[0][:3, 3], ends[1][:3, 3]
            RA, RB = ends[0][:3, :3], ends[1][:3, :3]
        else:
            for k, M in zip(("start", "end"), ends):
                if M.shape[1] != 1 or M.shape[0] not in (2, 3):
                    raise fail((k,), "a point has 2 or 3 components (or give a 4x4 pose)")
            pA, pB, RA, RB = ends[0], ends[1], None, None
            if pA.shape != pB.shape:
                raise fail(("end",), "start and end have different dimensions")
        try:
            p = line(s, pA, pB, simplify=not check_only)
        except ValueError as exc:
            raise fail(("end",), str(exc)) from None
    else:
        if spec.center is None or spec.radius is None:
            raise fail(("type",), f"a{'n' if spec.type == 'arc' else ''} {spec.type} needs center: and radius:")
        c = _matrix(problem, base + ("center",))
        if c.shape[1] != 1 or c.shape[0] not in (2, 3):
            raise fail(("center",), "the center has 2 or 3 components")
        rho = problem.parse_at(base + ("radius",))
        if isinstance(rho, list) or (rho.is_number and not rho.is_positive):
            raise fail(("radius",), "the radius must be a positive scalar")
        phase = problem.parse_at(base + ("phase",))
        if spec.type == "circle":
            if spec.angle is not None:
                raise fail(("angle",), "a circle sweeps 2π", "use type: arc for a part of a circle")
            ang = 2 * sp.pi
        else:
            if spec.angle is None:
                raise fail(("type",), "an arc needs angle: (the swept angle)")
            ang = problem.parse_at(base + ("angle",))
            if isinstance(ang, list) or ang == 0:
                raise fail(("angle",), "the swept angle must be a non-zero scalar")
        axes = None
        if spec.axes is not None:
            M = _matrix(problem, base + ("axes",))
            if M.shape != (2, c.shape[0]):
                raise fail(("axes",), f"axes must be two vectors of {c.shape[0]} components, [u, v]")
            u, v = M[0, :].T, M[1, :].T
            G = sp.Matrix([[u.dot(u), u.dot(v)], [v.dot(u), v.dot(v)]]).applyfunc(simplified)
            if G != sp.eye(2):
                raise fail(("axes",), "the axes must be orthonormal (unit length, perpendicular)")
            axes = (u, v)
        elif c.shape[0] == 3:
            axes = (sp.Matrix([1, 0, 0]), sp.Matrix([0, 1, 0]))
        p = arc(s, c, rho, phase, ang, axes)
        RA = RB = None
    if spec.orientation is not None:
        if RA is not None:
            raise fail(("orientation",), "the poses already give the orientation")
        missing = {"start", "end"} - set(spec.orientation)
        if missing or set(spec.orientation) - {"start", "end"}:
            raise fail(("orientation",), "orientation: needs exactly start: and end: (3x3 rotation matrices)")
        RA = _matrix(problem, base + ("orientation", "start"))
        RB = _matrix(problem, base + ("orientation", "end"))
    if RA is not None:
        for k, R in (("start", RA), ("end", RB)):
            sub = ("orientation", k) if spec.orientation is not None else (k,)
            if R.shape != (3, 3) or not is_rotation(R):
                raise fail(sub, "not a rotation matrix (RᵀR = I, det R = 1 are needed)")
        if p.p.shape[0] != 3:
            raise fail(("type",), "an orientation needs a path in space (3 components)")
        if not check_only:
            with_orientation(p, RA, RB)
    return p


def path_results(sol: Solution, path: Path, motion: Motion, times: list[sp.Expr], values: dict,
                 positives: list[sp.Expr], sfx: str, labels: list[sp.Expr]) -> list[dict]:
    def add(name: str, value: Any, label: str = "") -> None:
        sol.add(name + sfx, assume_positive(value, positives), label=label)

    add("L", path.L, label="L")
    add("p_s", path.p, label="p(s)")
    if path.rot is not None:
        add("R_AB", path.R_AB, label="{}^A R_B")
        add("theta_AB", path.rot.theta, label="\\theta_{AB}")
        if path.rot.axis is not None:
            add("axis_AB", path.rot.axis, label="{}^A r")
    law = motion.laws[0]
    rows = []
    for j, tau in enumerate(times, 1):
        tag = "_at" + (str(j) if len(times) > 1 else "")
        s_v, ds, dds = law.at(tau), law.diff(1).at(tau), law.diff(2).at(tau)
        vals = {
            "p": path.p.subs(path.s, s_v).applyfunc(simplified),
            "v": (path.dp.subs(path.s, s_v) * ds).applyfunc(simplified),
            "acc": (path.ddp.subs(path.s, s_v) * ds ** 2 + path.dp.subs(path.s, s_v) * dds).applyfunc(simplified),
        }
        if path.rot is not None:
            wA = path.omega_A(ds)
            vals["omega_A"] = wA
            vals["omega"] = (path.R_A * wA).applyfunc(simplified)
            vals["R"] = path.R(s_v)
        row = {"t": tau, "label": labels[j - 1], "vals": vals, "nums": {}}
        for k, v in vals.items():
            add(f"{k}{tag}", v)
            num = substitute(v, values)
            if num is not None:
                add(f"{k}{tag}_num", num)
                row["nums"][k] = num
        rows.append(row)
    return rows


def path_figure(path: Path, values: dict) -> Figure:
    def sample_path() -> list[Panel]:
        L = float(sp.sympify(path.L).subs(values).subs({x: 1 for x in sp.sympify(path.L).subs(values).free_symbols}))
        grid = np.linspace(0.0, L, 241)
        pe = path.p.subs(values)
        pe = pe.subs({x: 1 for x in pe.free_symbols - {path.s}})
        f = lambdify_np(path.s, pe)
        pts = np.array([np.asarray(f(x), dtype=float).ravel() for x in grid])
        if pts.shape[1] == 2 or np.allclose(pts[:, 2], pts[0, 2]):
            c = Curve("path", [float(x) for x in pts[:, 0]], [float(y) for y in pts[:, 1]])
            return [Panel("$x$", "$y$", [c], markers=[(float(pts[0, 0]), float(pts[0, 1]), "start"),
                                                      (float(pts[-1, 0]), float(pts[-1, 1]), "end")],
                          equal_axes=True)]
        panels = []
        for a, b in ((0, 1), (0, 2), (1, 2)):
            ax = "xyz"
            c = Curve("path", [float(x) for x in pts[:, a]], [float(y) for y in pts[:, b]])
            panels.append(Panel(f"${ax[a]}$", f"${ax[b]}$", [c],
                                markers=[(float(pts[0, a]), float(pts[0, b]), "start"),
                                         (float(pts[-1, a]), float(pts[-1, b]), "end")], equal_axes=True))
        return panels

    return Figure("path", "The path (projections on the coordinate planes for a path in space).", sample_path)


def _joint_task(problem, ctx, options: TrajectoryAsk, path: Path, values: dict) -> tuple[sp.Matrix, np.ndarray]:  # type: ignore[no-untyped-def]
    """The task r = f(q) followed along the path (numeric parameters) and the start of the inverse kinematics."""
    robot = problem.robot
    place = problem.located.place(ctx.path + ("task",))
    if robot is None:
        raise UserError("task: needs the robot's coordinates", place, "add robot: {joints: [...]}")
    if isinstance(options.task, str) and options.task.strip() == "dh" and "dh" not in problem.names:
        f = dh_position(problem, place)[:path.p.shape[0], :]
    else:
        raw = ctx.expr("task")
        f = sp.Matrix(raw if isinstance(raw, list) else [raw])
    if f.shape[0] != path.p.shape[0]:
        raise UserError(f"the task has {f.shape[0]} components, the path {path.p.shape[0]}", place,
                        "give r = f(q) with as many components as the path's points")
    rest = (f.free_symbols - set(robot.q)) - set(values)
    if rest:
        raise UserError("the joint motion is computed numerically: every parameter of the task needs a value",
                        place, "add values: for " + ", ".join(sorted(s.name for s in rest)))
    q0 = np.zeros(robot.n)
    if options.q_start is not None:
        v = ctx.expr("q_start")
        v = v if isinstance(v, list) else [v]
        if len(v) != robot.n or any(x.subs(values).free_symbols for x in v):
            raise UserError(f"q_start must be {robot.n} numbers", problem.located.place(ctx.path + ("q_start",)))
        q0 = np.array([float(x.subs(values)) for x in v])
    return f, q0


def joint_motion(sol: Solution, problem, ctx, options: TrajectoryAsk, path: Path, motion: Motion,  # type: ignore[no-untyped-def]
                 times: list[sp.Expr], values: dict, sfx: str, labels: list[sp.Expr]) -> dict:
    """q(t) through numerical inverse kinematics of the task function along the path."""
    robot = problem.robot
    f, q0 = _joint_task(problem, ctx, options, path, values)
    law = motion.laws[0]
    xs, s_vals = sample(law, values, 200)
    _, ds_vals = sample(law.diff(1), values, 200)
    _, dds_vals = sample(law.diff(2), values, 200)
    ts = list(xs)
    extra = []
    for tau in times:  # the instants asked are appended (exact positions in the sampled motion)
        tv = float(sp.sympify(tau).subs(values))
        fn = [law.diff(k).numeric_pieces(values) for k in range(3)]
        k = law.piece_of(tau)
        extra.append((tv, *[float(fn[d][0][k](np.array([tv]))[0]) for d in range(3)]))
    P = lambdify_np(path.s, path.p.subs(values))
    dP = lambdify_np(path.s, path.dp.subs(values))
    ddP = lambdify_np(path.s, path.ddp.subs(values))

    def cart(sv: float, dsv: float, ddsv: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p = np.asarray(P(sv), dtype=float).ravel()
        d1 = np.asarray(dP(sv), dtype=float).ravel()
        d2 = np.asarray(ddP(sv), dtype=float).ravel()
        return p, d1 * dsv, d2 * dsv ** 2 + d1 * ddsv

    all_t = ts + [e[0] for e in extra]
    triples = [cart(s_vals[i], ds_vals[i], dds_vals[i]) for i in range(len(ts))] + \
        [cart(e[1], e[2], e[3]) for e in extra]
    pos, vel, acc = (np.array([x[i] for x in triples]) for i in range(3))
    order = np.argsort(np.array(all_t), kind="stable")
    jm = follow(f, robot.q, robot.dq, values, np.array(all_t)[order], pos[order], vel[order], acc[order], q0)
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    rows = []
    for j, tau in enumerate(times, 1):
        idx = inv[len(ts) + j - 1]
        tag = "_at" + (str(j) if len(times) > 1 else "")
        vals = [sp.Matrix([sp.Float(x, 10) for x in arr[idx]]) for arr in (jm.q, jm.dq, jm.ddq)]
        for name, v in zip(("q", "dq", "ddq"), vals):
            sol.add(f"{name}{tag}{sfx}", v, "vector", label=f"{name}({tau})")
        rows.append({"t": tau, "label": labels[j - 1], "vals": vals})
    if jm.error > 1e-6:
        raise UserError(f"the inverse kinematics did not converge along the path (task error {jm.error:.2g})",
                        problem.located.place(ctx.path + ("q_start",)),
                        "give q_start: near the configuration at the start of the path, or check the path is "
                        "inside the workspace")
    keep = [i for i in range(len(order)) if order[i] < len(ts)]

    def sample_joints() -> list[Panel]:
        panels = []
        for arr, ylab in ((jm.q, "$q$"), (jm.dq, "$\\dot q$"), (jm.ddq, "$\\ddot q$")):
            curves = [Curve(f"${robot.q[i].name[0]}_{{{robot.q[i].name[1:]}}}$", [float(jm.t[k]) for k in keep],
                            [float(arr[k, i]) for k in keep]) for i in range(robot.n)]
            panels.append(Panel("$t$", ylab, curves))
        return panels

    sol.figures.append(Figure("joints", "Joint motion along the path (numerical inverse kinematics).",
                              sample_joints))
    return {"task": f, "rows": rows, "error": jm.error, "tol": IK_TOL, "q_start": q0.tolist()}


def dh_position(problem, place) -> sp.Matrix:  # type: ignore[no-untyped-def]
    """Position of the last DH frame, ⁰A_n(q)[:3, 3] (with the base transform), from the robot's DH table."""
    from solver.math.rigid import dh_chain

    data = problem.located.data.get("robot", {}) if isinstance(problem.located.data, dict) else {}
    dh = data.get("dh") if isinstance(data, dict) else None
    if not isinstance(dh, dict) or not dh.get("table"):
        raise UserError("task: dh needs the robot's DH table (robot: {dh: {table: ...}})", place,
                        "give the task function r = f(q), or a DH table")
    base = ("robot", "dh")
    rows = []
    for i in range(len(dh["table"])):
        row = []
        for key in ("a", "alpha", "d", "theta"):
            v = problem.parse_at(base + ("table", i, key))
            row.append(v)
        rows.append(tuple(row))
    A = dh_chain(rows, dh.get("convention", "standard"))[-1]
    if dh.get("base") is not None:
        A = sp.Matrix(problem.parse_at(base + ("base",))) * A
    return A[:3, 3].applyfunc(simplified)


# ------------------------------------------------------------------------------------------------ the ask
def positive_expressions(problem, options, ctx) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    """The expressions of ``positive:`` (known to be positive, to simplify |.|)."""
    positives = []
    for k in range(len(options.positive)):
        v = ctx.expr("positive", k)
        if isinstance(v, list):
            raise UserError("positive: lists scalar expressions", problem.located.place(ctx.path + ("positive", k)))
        positives.append(v)
    return positives


def _path_and_motion(problem, options: TrajectoryAsk, ctx, t: sp.Symbol, check_only: bool = False) -> tuple:  # type: ignore[no-untyped-def]
    """(path or None, the timing law, its variable "s" on a path or "q"); ``check_only`` as in :func:`build_path`."""
    path = None
    if options.path is not None:
        s = problem.symbols.get("s") or sp.Symbol("s", real=True)
        path = build_path(problem, ctx, options.path, s, check_only)
        for side in ("initial", "final"):
            b = getattr(options, side)
            if b is not None and b.q is not None:
                raise UserError("on a path, the law runs from s = 0 to s = L: do not give its positions",
                                problem.located.place(ctx.path + (side, "q")), "remove q:")
        motion = read_motion(problem, ctx.path, options, t, n=1, names=["s"],
                             defaults={"initial": sp.Integer(0), "final": path.L})
        var = "s"
    else:
        if options.task is not None:
            raise UserError("task: needs a path: (the joint motion follows a Cartesian path)",
                            problem.located.place(ctx.path + ("task",)))
        robot = problem.robot
        motion = read_motion(problem, ctx.path, options, t)
        if robot is not None and motion.n == robot.n:
            motion.names = [x.name for x in robot.q] if robot.n > 1 else [robot.q[0].name]
        var = "q"
    return path, motion, var


def validate_trajectory(problem, options: TrajectoryAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_trajectory` reads them (the path, the timing law, the
    instants, the joint task), without the derivatives, values and figures."""
    t = time_symbol(problem)
    positive_expressions(problem, options, ctx)
    path, motion, _ = _path_and_motion(problem, options, ctx, t, check_only=True)
    if options.at is not None:
        parse_times(problem, ctx.path + ("at",), options.at, motion.T)
    if path is not None and options.task is not None:
        _joint_task(problem, ctx, options, path, problem.values)


@ask_kind("trajectory", TrajectoryAsk,
          "timing laws (polynomials, splines, trapezoidal, bang-bang, cycloidal) and Cartesian paths",
          validate=validate_trajectory)
def solve_trajectory(problem, options: TrajectoryAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the suffix): A, V, Ts, T, coeffs; q_t, dq_t, ddq_t (one-piece laws); max_dq, t_max_dq,
    max_ddq, t_max_ddq; q_at, dq_at, ddq_at (+ _num); with a path the law is s: s_t, ..., and L, p_s, R_AB,
    theta_AB, axis_AB, p_at, v_at, acc_at, omega_A_at, omega_at; with task: q_at, dq_at, ddq_at (numerical)."""
    sfx = options.suffix
    t = time_symbol(problem)
    values = problem.values
    positives = positive_expressions(problem, options, ctx)
    sol = Solution("trajectory", title=options.title or ("Cartesian trajectory" if options.path else "Timing law"))
    path, motion, var = _path_and_motion(problem, options, ctx, t)
    sol.step("law", motion=motion, var=var, t=t, laws=[law_view(law) for law in motion.laws],
             T=motion.T, notes=motion.notes, path=path is not None)
    data = law_results(sol, motion, values, positives, sfx, var)
    sol.step("derivatives", motion=motion, var=var, t=t, **data)
    times = parse_times(problem, ctx.path + ("at",), options.at, motion.T) if options.at is not None else []
    labels = time_labels(problem, ctx.path + ("at",)) if times else []
    try:
        if times:
            rows = evaluate(sol, motion, times, values, positives, sfx, var, labels)
            sol.step("at", rows=rows, var=var, names=motion.names, values=_used(values, motion))
        prows = path_results(sol, path, motion, times, values, positives, sfx, labels) if path is not None else []
    except LawError as exc:
        raise UserError(str(exc), problem.located.place(ctx.path + ("at",)), exc.hint) from None
    if path is not None:
        sol.steps.insert(0, Step("path", {"path": path}))
        if prows:
            sol.step("path_at", path=path, rows=prows, values=_used(values, motion))
        if options.task is not None:
            jdata = joint_motion(sol, problem, ctx, options, path, motion, times, values, sfx, labels)
            sol.step("joints", **jdata, names=[x.name for x in problem.robot.q])
    if options.plots and motion.T is not None:
        sol.figures.insert(0, law_figure("law", "Position, velocity and acceleration against time.", motion,
                                         values, var=var, labels=coordinate_labels(problem, motion)))
        if path is not None:
            sol.figures.insert(1, path_figure(path, values))
    return sol


SIGMA = sp.Symbol("sigma", nonnegative=True)


def law_view(law) -> dict:  # type: ignore[no-untyped-def]
    """What the templates show of one law: its pieces with their intervals, its parameters and, for a
    polynomial, its normalized form Σ a_j σ^j."""
    view = {"pieces": [(p, law.breaks[k], law.breaks[k + 1]) for k, p in enumerate(law.pieces)],
            "params": law.params, "normalized": None}
    if "coeffs" in law.params and len(law.pieces) == 1:
        view["normalized"] = sp.Add(*[c * SIGMA ** j for j, c in enumerate(law.params["coeffs"][0])])
    return view


def _used(values: dict, motion: Motion) -> dict:
    syms: set = set()
    for law in motion.laws:
        for p in law.pieces:
            syms |= p.free_symbols
    return {k: v for k, v in values.items() if k in syms or (motion.T is not None and k in
                                                             sp.sympify(motion.T).free_symbols)}


@property_check("axis_AB", "theta_AB")
def check_axis_angle(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """(r, θ) is not unique, (−r, −θ) describes the same rotation: accepted when Rot(r, θ) = ᴬR_B, ‖r‖ = 1
    (with the other item of the pair answered, else the reference one)."""
    ref = results.get("R_AB")
    if ref is None:
        return None
    if name == "axis_AB":
        r, th = value, other("theta_AB")
        th = th if th is not None else results["theta_AB"].value
    else:
        r, th = other("axis_AB"), value
        if r is None:
            return None  # θ alone: compared with the reference
    try:
        r = sp.Matrix(r).reshape(3, 1)
        if isinstance(th, list):
            return None
        R = rot_axis_angle(r, sp.sympify(th))
        err = max(abs(complex(sp.N(x, 20))) for x in (R - ref.value))
        unit = abs(complex(sp.N((r.T * r)[0] - 1, 20)))
    except (ValueError, TypeError, AttributeError, ShapeError):
        return None
    if err < 1e-9 and unit < 1e-9:
        return PropertyVerdict(True, 1.0, ["Rot(r, θ) equals the relative rotation: a valid axis-angle pair"])
    return None
