"""Motion planning with numbers (ask kind ``motion_planning``): artificial potential fields and graph search.

Potential fields on the robot's coordinates q (or a point x):
    U_a(q) = ½ k_a ‖q − q_d‖²                                 (attractive paraboloid)
    U_r,i(q) = ½ k_i (1/η_i(q) − 1/η_0,i)²  for η_i < η_0,i, else 0   (repulsive, clearance η_i, range η_0,i)
    u = k_a (q_d − q) − K_D q̇ + g(q) − Σ ∇U_r,i       with V = ½ q̇ᵀB q̇ + U_a + Σ U_r,i,  V̇ = −q̇ᵀ K_D q̇
The equilibria (with numbers) are the zeros of the field −∇U (grid search over the given range, then refinement).

Graph search: A* on a weighted graph (nodes with positions for the Euclidean heuristic, or given heuristic values)
or on an occupancy grid (4-connected, or 8-connected with diagonal cost √2 and, unless corner_cutting: false, a
diagonal allowed past an occupied cell at its corner); every expansion is recorded (node, g, f, the open list after
it). A closed node is never reopened, so the path is optimal when h is consistent; h is checked against the exact
cost-to-go h* (Dijkstra from the goal): admissible (h ≤ h*), consistent (h(n) ≤ c(n, m) + h(m)), and the optimal
cost compared with the path's.
"""
from __future__ import annotations

import heapq
import math
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import BaseModel, Field

from solver.math.numeric import lambdify_np
from solver.math.search import bisect_root
from solver.math.simplify import factor_within, tidy
from solver.registry import ask_kind
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.models import Strict

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
MAX_NODES = 20_000


class Obstacle(BaseModel):
    """A repulsive potential with a limited range of influence."""

    model_config = {"extra": "forbid"}
    clearance: Scalar = Field(description="η(q) > 0, the distance from the obstacle (e.g. x - xL)")
    range: Scalar = Field(description="η₀: no action where η ≥ η₀")
    gain: Scalar = Field(description="k of ½ k (1/η − 1/η₀)²")


class GraphSpec(BaseModel):
    """A weighted graph: nodes (optionally with positions) and undirected edges [a, b, weight]."""

    model_config = {"extra": "forbid"}
    nodes: dict[str, Optional[list[float]]] = Field(description="name: [x, y] (position, for the heuristic) or null")
    edges: list[list[Union[str, float, int]]] = Field(description="[a, b] (Euclidean weight) or [a, b, weight]")


class MotionPlanningAsk(Strict):
    """Artificial potential fields (law, Lyapunov function, equilibria) or A* search with every expansion."""

    kind: Literal["motion_planning"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    method: Literal["potential", "astar"] = Field(description="potential fields, or A* graph search")
    goal: Optional[ExprT] = Field(None, description="potential: q_d (one per coordinate)")
    gain: Scalar = Field("kp", description="potential: attractive gain k_a of ½ k_a ‖q − q_d‖²")
    damping: Scalar = Field("kd", description="potential: damping gain K_D of the law")
    obstacles: list[Obstacle] = Field([], description="potential: repulsive terms")
    gravity: bool = Field(True, description="potential: add g(q) of the robot's model to the law (if any)")
    range: Optional[dict[str, list[float]]] = Field(None, description="potential: {q1: [lo, hi]} for the numeric "
                                                                     "equilibria and the plot (numbers needed)")
    graph: Optional[GraphSpec] = Field(None, description="astar: the graph")
    grid: Optional[list[str]] = Field(None, description="astar: occupancy grid rows, '.' free, '#' occupied, "
                                                        "S start, G goal (row 0 on top)")
    connectivity: Literal[4, 8] = Field(4, description="astar on a grid: 4 or 8 neighbours (diagonal √2)")
    corner_cutting: bool = Field(True, description="astar on an 8-connected grid: a diagonal move may pass an "
                                                   "occupied cell at its corner (false: both cells beside it free)")
    start: Optional[str] = Field(None, description="astar on a graph: start node")
    target: Optional[str] = Field(None, description="astar on a graph: goal node")
    heuristic: Union[Literal["euclidean", "manhattan", "zero"], dict[str, float]] = Field(
        "euclidean", description="h(n): euclidean/manhattan distance to the goal (positions needed), zero "
                                 "(Dijkstra), or given values {node: h}")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")


# ------------------------------------------------------------------------------------------------ potentials
def repulsive(eta: sp.Expr, eta0: sp.Expr, k: sp.Expr) -> sp.Expr:
    """½ k (1/η − 1/η₀)², the active branch (η < η₀; zero elsewhere)."""
    return k * (1 / eta - 1 / eta0) ** 2 / 2


def field_zeros(f, lo: np.ndarray, hi: np.ndarray, n: int = 2000) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    """Zeros of a field f: R^d -> R^d (d = 1: sign changes on a fine grid, refined by bisection without scipy,
    whose import costs more than the search; d = 2: grid minima of ‖f‖ refined by scipy's root)."""
    d = len(lo)
    out: list[np.ndarray] = []
    if d == 1:
        xs = np.linspace(lo[0], hi[0], n)
        vs = np.array([f(np.array([x]))[0] for x in xs])
        for i in range(n - 1):
            a, b = vs[i], vs[i + 1]
            if not (np.isfinite(a) and np.isfinite(b)):
                continue
            if a == 0:
                out.append(np.array([xs[i]]))
            elif a * b < 0:
                z = bisect_root(lambda x: f(np.array([x]))[0], xs[i], xs[i + 1])
                if abs(f(np.array([z]))[0]) < 1e-6 * (1 + abs(a) + abs(b)):
                    out.append(np.array([z]))
        return out
    from scipy.optimize import root
    m = int(round(n ** (1 / d))) + 1
    axes = [np.linspace(lo[i], hi[i], m) for i in range(d)]
    for pt in np.array(np.meshgrid(*axes)).reshape(d, -1).T:
        r = root(f, pt, tol=1e-12)
        if r.success and np.all(r.x >= lo) and np.all(r.x <= hi) and np.linalg.norm(f(r.x)) < 1e-8:
            if not any(np.linalg.norm(r.x - z) < 1e-6 for z in out):
                out.append(r.x)
    return out


def _potential_inputs(problem, options: MotionPlanningAsk, ctx) -> tuple:  # type: ignore[no-untyped-def]
    """The robot, q_d, the gains k_a, k_d and each obstacle's (clearance η, range η₀, gain k)."""
    robot = problem.robot
    if robot is None:
        raise UserError("method: potential needs a robot (its coordinates; a point mass: joints [P] and "
                        "model: {B: [[m]]})", problem.located.place(ctx.path + ("method",)))
    n = len(robot.q)
    if options.goal is None:
        raise UserError("method: potential needs goal: (q_d)", problem.located.place(ctx.path + ("method",)))
    raw = ctx.expr("goal")
    qd = sp.Matrix(raw if isinstance(raw, list) else [raw])
    if qd.shape[0] != n:
        raise UserError(f"goal: {n} components expected", problem.located.place(ctx.path + ("goal",)))

    def par(field: str) -> sp.Expr:
        if field in options.model_fields_set:
            return sp.sympify(ctx.expr(field))
        name = str(getattr(options, field))
        return problem.names.get(name, sp.Symbol(name, positive=True))

    ka, kd = par("gain"), par("damping")
    obstacles = [tuple(sp.sympify(ctx.expr("obstacles", i, key)) for key in ("clearance", "range", "gain"))
                 for i in range(len(options.obstacles))]
    return robot, qd, ka, kd, obstacles


def _solve_potential(problem, options: MotionPlanningAsk, ctx, sol: Solution, add) -> None:  # type: ignore[no-untyped-def]
    robot, qd, ka, kd, obstacles = _potential_inputs(problem, options, ctx)
    q, dq = list(robot.q), list(robot.dq)
    n = len(q)
    e = qd - sp.Matrix(q)
    Ua = ka * (e.T * e)[0, 0] / 2
    add("U_att", Ua, "scalar", label="U_a")
    reps, grads = [], []
    for i, (eta, eta0, k) in enumerate(obstacles, 1):
        U = repulsive(eta, eta0, k)
        G = sp.Matrix([tidy(factor_within(sp.diff(U, x))) for x in q])
        add(f"U_rep{i}", U, "scalar", label=f"U_{{r,{i}}}")
        add(f"grad_rep{i}", G if n > 1 else G[0], "vector" if n > 1 else "scalar",
            label=f"\\partial U_{{r,{i}}}/\\partial q")
        reps.append((eta, eta0, k, U, G))
        grads.append(G)
    grad_rep = sum(grads, sp.zeros(n, 1))
    g = sp.zeros(n, 1)
    model = None
    try:
        from solver.dynamics.model import derive
        model = derive(robot)
        g = model.g if options.gravity else sp.zeros(n, 1)
    except Exception:  # noqa: BLE001 - a robot without dynamics: a kinematic point
        model = None
    u = ka * e - kd * sp.Matrix(dq) + g - grad_rep
    add("u", u if n > 1 else u[0], "vector" if n > 1 else "scalar", label="u")
    qdot = sp.Matrix(dq)
    B = model.B if model is not None else sp.eye(n)
    V = (qdot.T * B * qdot)[0, 0] / 2 + Ua + sum((r[3] for r in reps), sp.Integer(0))
    add("V", V, "scalar", label="V")
    # V̇ = q̇ᵀ(B q̈ + ½Ḃ q̇) − k_a eᵀq̇ + ∇U_rᵀ q̇, and B q̈ + ½Ḃq̇ = u − g + (½Ḃ − S)q̇ with q̇ᵀ(½Ḃ − S)q̇ = 0
    Vdot = tidy(sp.expand((qdot.T * (u - g))[0, 0] - ka * (e.T * qdot)[0, 0] + (grad_rep.T * qdot)[0, 0]))
    add("V_dot", Vdot, "scalar", label="\\dot V")
    data: dict[str, Any] = {"q": sp.Matrix(q), "qd": qd, "Ua": Ua, "reps": reps, "u": u, "V": V, "Vdot": Vdot,
                            "g": g, "has_g": any(x != 0 for x in g), "equilibria": None}
    # numbers: equilibria and plot
    vals = dict(problem.values)
    field = ka * e - grad_rep   # −∇U at rest
    free = (field.free_symbols - set(q))
    if options.range is not None and not (free - set(vals)):
        lo = np.array([options.range.get(str(x), [-1, 1])[0] for x in q], dtype=float)
        hi = np.array([options.range.get(str(x), [-1, 1])[1] for x in q], dtype=float)
        active = [(lambdify_np(q, r[0].xreplace(vals)), float(sp.sympify(r[1]).xreplace(vals)),
                   lambdify_np(q, list(r[4].xreplace(vals)))) for r in reps]
        fa = lambdify_np(q, list((ka * e).xreplace(vals)))

        def F(x: np.ndarray) -> np.ndarray:
            out = np.array(fa(*x), dtype=float)
            for eta_f, eta0v, gf in active:
                et = float(eta_f(*x))
                if et <= 0:
                    return np.full(n, np.nan)
                if et < eta0v:
                    out = out - np.array(gf(*x), dtype=float)
            return out

        zs = field_zeros(F, lo, hi)
        eqs = [sp.Matrix([sp.Float(float(z), 10) for z in x]) for x in zs]
        add("equilibria_at", eqs, "set", label="q_e")
        data["equilibria"] = eqs
        if n == 1:
            Uf = [(lambdify_np(q, r[0].xreplace(vals)), float(sp.sympify(r[1]).xreplace(vals)),
                   lambdify_np(q, r[3].xreplace(vals))) for r in reps]
            Uaf = lambdify_np(q, Ua.xreplace(vals))

            def panels() -> list[Panel]:
                xs = np.linspace(lo[0], hi[0], 801)[1:-1]
                tot, rep = [], []
                for x in xs:
                    r = 0.0
                    for eta_f, eta0v, uf in Uf:
                        et = float(eta_f(x))
                        r += float(uf(x)) if 0 < et < eta0v else (math.inf if et <= 0 else 0.0)
                    rep.append(min(r, 1e6))
                    tot.append(min(float(Uaf(x)) + r, 1e6))
                top = 10 * max(1.0, float(Uaf(lo[0])), float(Uaf(hi[0])))
                cl = lambda ys: [min(y, top) for y in ys]  # noqa: E731
                return [Panel(f"${sp.latex(q[0])}$", "$U$", [Curve("$U_a + U_r$", list(xs), cl(tot)),
                                                             Curve("$U_r$", list(xs), cl(rep), dashed=True)],
                              markers=[(float(z[0]), 0.0, "eq.") for z in zs])]

            sol.figures.append(Figure("potential", "Total and repulsive potential (clipped), equilibria marked.",
                                      panels))
    sol.step("potential", **data)


# ------------------------------------------------------------------------------------------------ graph search
def astar(neighbours: dict[str, list[tuple[str, float]]], start: str, goal: str,
          h: dict[str, float]) -> tuple[Optional[list[str]], float, list[dict[str, Any]]]:
    """A* with f = g + h; ties broken by the smaller h, then by name. Returns (path, cost, expansions); each
    expansion is {node, g, f, open: [(node, f), ...] after the expansion}."""
    g = {start: 0.0}
    parent: dict[str, Optional[str]] = {start: None}
    heap = [(h[start], h[start], start)]
    closed: set[str] = set()
    steps: list[dict[str, Any]] = []
    while heap:
        f, _, x = heapq.heappop(heap)
        if x in closed or f > g[x] + h[x] + 1e-12:
            continue
        closed.add(x)
        if x == goal:
            steps.append({"node": x, "g": g[x], "f": f, "open": []})
            path = [x]
            while parent[path[-1]] is not None:
                path.append(parent[path[-1]])  # type: ignore[arg-type]
            return path[::-1], g[x], steps
        for y, w in neighbours.get(x, []):
            if y in closed:
                continue
            ng = g[x] + w
            if ng < g.get(y, math.inf) - 1e-12:
                g[y], parent[y] = ng, x
                heapq.heappush(heap, (ng + h[y], h[y], y))
        best: dict[str, float] = {}
        for ff, _, y in heap:
            if y not in closed and abs(ff - g[y] - h[y]) < 1e-9:
                best[y] = ff
        steps.append({"node": x, "g": g[x], "f": f, "open": sorted(best.items(), key=lambda t: (t[1], t[0]))})
        if len(steps) > MAX_NODES:
            break
    return None, math.inf, steps


def dijkstra(neighbours: dict[str, list[tuple[str, float]]], start: str) -> dict[str, float]:
    """Shortest distances from start (for checking A*)."""
    dist = {start: 0.0}
    heap = [(0.0, start)]
    while heap:
        d, x = heapq.heappop(heap)
        if d > dist.get(x, math.inf):
            continue
        for y, w in neighbours.get(x, []):
            if d + w < dist.get(y, math.inf):
                dist[y] = d + w
                heapq.heappush(heap, (d + w, y))
    return dist


def heuristic_check(neighbours: dict[str, list[tuple[str, float]]], goal: str,
                    h: dict[str, float]) -> dict[str, Any]:
    """h against the exact cost-to-go h* (Dijkstra from the goal; the graphs here are undirected): admissible when
    h(n) ≤ h*(n) wherever the goal is reachable, consistent when h(x) ≤ w + h(y) on every edge (x, y, w). Returns
    {hstar, admissible, consistent, over: (n, h, h*) of the largest h − h* > 0 or None, edge: (x, y, w, h(x),
    h(y)) of the largest h(x) − w − h(y) > 0 or None; among equal ones the first, nodes in Dijkstra's order from
    the goal, edges in the graph's}."""
    hstar = dijkstra(neighbours, goal)
    tol = 1e-9
    over, worst = None, 0.0
    for n, hs in hstar.items():
        ex = h[n] - hs
        if ex > tol * (1 + abs(hs)) and ex > worst + tol:
            over, worst = (n, h[n], hs), ex
    edge, worst = None, 0.0
    for x, ys in neighbours.items():
        for y, w in ys:
            ex = h[x] - w - h[y]
            if ex > tol * (1 + abs(h[x])) and ex > worst + tol:
                edge, worst = (x, y, w, h[x], h[y]), ex
    return {"hstar": hstar, "admissible": over is None, "consistent": edge is None, "over": over, "edge": edge}


def grid_graph(rows: list[str], connectivity: int, corner_cutting: bool = True) -> tuple[dict, dict, str, str]:
    """Neighbours, positions (x = column, y = −row), start and goal of an occupancy grid: moves of cost 1 to the 4
    side cells, with connectivity 8 also of cost √2 to the diagonal ones; without corner_cutting a diagonal move
    needs both cells beside it (sharing a side with the start and the end cell) free."""
    pos: dict[str, tuple[float, float]] = {}
    start = goal = ""
    for r, line in enumerate(rows):
        for c, ch in enumerate(line):
            if ch != "#":
                name = f"({r},{c})"
                pos[name] = (float(c), float(-r))
                start = name if ch == "S" else start
                goal = name if ch == "G" else goal
    steps = [(0, 1), (1, 0), (0, -1), (-1, 0)] + ([(1, 1), (1, -1), (-1, 1), (-1, -1)] if connectivity == 8 else [])
    nb: dict[str, list[tuple[str, float]]] = {k: [] for k in pos}
    for name in pos:
        r, c = (int(t) for t in name[1:-1].split(","))
        for dr, dc in steps:
            other = f"({r + dr},{c + dc})"
            if other not in pos:
                continue
            if dr and dc and not corner_cutting and (f"({r + dr},{c})" not in pos or f"({r},{c + dc})" not in pos):
                continue
            nb[name].append((other, math.hypot(dr, dc)))
    return nb, pos, start, goal


GRID_CELLS = ".#SG"


def _check_grid(rows: list[str], row_place, place) -> None:  # type: ignore[no-untyped-def]
    """An occupancy grid: rows of one length, cells among '.', '#', 'S', 'G', exactly one S and one G; else a
    UserError at the row."""
    if not rows:
        raise UserError("the grid has no rows", place, 'e.g. grid: ["S..", ".#.", "..G"]')
    for r, line in enumerate(rows):
        bad = next((c for c, ch in enumerate(line) if ch not in GRID_CELLS), None)
        if bad is not None:
            raise UserError(f"grid row {r}, column {bad}: {line[bad]!r} is not a cell", row_place(r),
                            "write '.' (free), '#' (occupied), 'S' (start) or 'G' (goal)")
        if len(line) != len(rows[0]):
            raise UserError(f"grid row {r} has {len(line)} cells, row 0 has {len(rows[0])}", row_place(r),
                            "give every row the same number of cells")
    for mark, what in (("S", "start"), ("G", "goal")):
        at = [(r, c) for r, line in enumerate(rows) for c, ch in enumerate(line) if ch == mark]
        if len(at) != 1:
            raise UserError(f"the grid needs one {mark} ({what}); it has {len(at)}"
                            + (f" (row, column: {', '.join(f'({r}, {c})' for r, c in at)})" if at else ""),
                            row_place(at[1][0]) if len(at) > 1 else place, f"mark one cell {mark}")


def _astar_inputs(problem, options: MotionPlanningAsk, ctx) -> tuple:  # type: ignore[no-untyped-def]
    """The graph (neighbours with weights), the node positions, start, goal and the heuristic by node."""
    place = problem.located.place(ctx.path + ("method",))
    if options.grid is not None:
        _check_grid(options.grid, lambda r: problem.located.place(ctx.path + ("grid", r)),
                    problem.located.place(ctx.path + ("grid",)))
        nb, pos, start, goal = grid_graph(options.grid, options.connectivity, options.corner_cutting)
    elif options.graph is not None:
        if not options.start or not options.target:
            raise UserError("a graph search needs start: and target: (node names)", place)
        pos = {k: tuple(v) for k, v in options.graph.nodes.items() if v is not None}  # type: ignore[misc]
        nb = {k: [] for k in options.graph.nodes}
        for i, ed in enumerate(options.graph.edges):
            where = problem.located.place(ctx.path + ("graph", "edges", i))
            if len(ed) not in (2, 3) or str(ed[0]) not in nb or str(ed[1]) not in nb:
                raise UserError("an edge is [a, b] or [a, b, weight] between declared nodes", where)
            a, b = str(ed[0]), str(ed[1])
            if len(ed) == 3:
                w = float(sp.N(ctx.expr("graph", "edges", i, 2)))
            elif a in pos and b in pos:
                w = math.dist(pos[a], pos[b])
            else:
                raise UserError("an edge without weight needs positions of both nodes", where)
            nb[a].append((b, w))
            nb[b].append((a, w))
        start, goal = options.start, options.target
        if start not in nb or goal not in nb:
            raise UserError("start: and target: must be nodes of the graph", place)
    else:
        raise UserError("method: astar needs graph: or grid:", place)
    if len(nb) > MAX_NODES:
        raise UserError(f"at most {MAX_NODES} nodes", place)
    hs = options.heuristic
    if isinstance(hs, dict):
        h = {k: float(hs.get(k, 0.0)) for k in nb}
    elif hs == "zero":
        h = {k: 0.0 for k in nb}
    else:
        if goal not in pos or any(k not in pos for k in nb):
            raise UserError(f"heuristic: {hs} needs the positions of every node", place)
        gx, gy = pos[goal]
        h = {k: (math.hypot(pos[k][0] - gx, pos[k][1] - gy) if hs == "euclidean"
                 else abs(pos[k][0] - gx) + abs(pos[k][1] - gy)) for k in nb}
    return nb, pos, start, goal, h


def _solve_astar(problem, options: MotionPlanningAsk, ctx, sol: Solution, add) -> None:  # type: ignore[no-untyped-def]
    nb, pos, start, goal, h = _astar_inputs(problem, options, ctx)
    hs = options.heuristic
    path, cost, steps = astar(nb, start, goal, h)
    chk = heuristic_check(nb, goal, h)
    best = chk["hstar"].get(start, math.inf)   # the optimal cost
    if path is None:
        add("path_found", False, "bool", label="\\text{path found}")
    else:
        add("path_found", True, "bool", label="\\text{path found}")
        add("cost", sp.nsimplify(cost, [sp.sqrt(2), sp.sqrt(5), sp.sqrt(10)], tolerance=1e-9) if abs(
            cost - round(cost)) > 1e-12 else sp.Integer(round(cost)), "number", label="L")
        add("path_length", sp.Integer(len(path)), "number", label="\\#\\text{nodes}")
    add("expansions", sp.Integer(len(steps)), "number", label="\\#\\text{expansions}")
    add("admissible", chk["admissible"], "bool", label="h \\le h^*")
    add("consistent", chk["consistent"], "bool", label="\\text{consistent}")
    moves = None if options.grid is None else {"connectivity": options.connectivity,
                                               "corner_cutting": options.corner_cutting}
    sol.step("astar", path=path, cost=cost, steps=steps, start=start, goal=goal, heuristic=str(hs)
             if not isinstance(hs, dict) else "given", moves=moves, admissible=chk["admissible"],
             consistent=chk["consistent"], over=chk["over"], edge=chk["edge"], optimal_cost=best,
             optimal=path is not None and cost <= best + 1e-9 * (1 + best))
    if pos and start in pos and goal in pos:
        blocked = [(float(c), float(-r)) for r, line in enumerate(options.grid or []) for c, ch in enumerate(line)
                   if ch == "#"]

        def panels() -> list[Panel]:
            cells = [Curve("obstacle" if i == 0 else "", [x - .5, x + .5, x + .5, x - .5],
                           [y - .5, y - .5, y + .5, y + .5], filled=True) for i, (x, y) in enumerate(blocked)]
            curves = cells + ([Curve("path", [pos[k][0] for k in path], [pos[k][1] for k in path])]
                              if path is not None else [])
            order = [(i, s["node"]) for i, s in enumerate(steps, 1) if s["node"] in pos and s["node"] not in
                     (start, goal)]   # each expanded node numbered with its step of the table
            marks = [(*pos[start], "start"), (*pos[goal], "goal")] + [(*pos[k], str(i)) for i, k in order]
            return [Panel("$x$", "$y$", curves, markers=marks, equal_axes=True)]
        sol.figures.append(Figure("search", ("A*: the path found and the expanded nodes" if path is not None else
                                             "A*: no path; the nodes expanded before the open list ran out")
                                  + ", numbered with their step" + (", the occupied cells in grey." if blocked
                                                                    else "."), panels))


def validate_motion_planning(problem, options: MotionPlanningAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_motion_planning` reads them (potential: robot, goal,
    gains, obstacles; A*: the graph or grid, start, target, heuristic), without the fields and the search."""
    if options.method == "potential":
        _potential_inputs(problem, options, ctx)
    else:
        _astar_inputs(problem, options, ctx)


@ask_kind("motion_planning", MotionPlanningAsk, "artificial potential fields (law, equilibria) and A* search",
          validate=validate_motion_planning)
def solve_motion_planning(problem, options: MotionPlanningAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: potential: U_att, U_rep<i>, grad_rep<i>, u, V, V_dot, equilibria_at (with range: and numbers);
    astar: path_found, cost, path_length, expansions, admissible, consistent."""
    sol = Solution("motion_planning", title=options.title or ("Artificial potential fields"
                                                              if options.method == "potential" else "A* search"))

    def add(name: str, value: Any, kind: Optional[str] = None, label: str = "") -> Any:
        return sol.add(name + options.suffix, value, kind, label=label)

    if options.method == "potential":
        _solve_potential(problem, options, ctx, sol, add)
    else:
        _solve_astar(problem, options, ctx, sol, add)
    return sol
