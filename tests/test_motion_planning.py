"""The `motion_planning` ask: A* against Dijkstra on random grids and graphs, the expansions, potential-field
equilibria as zeros of the field, the law's Lyapunov derivative, and the encoded problem."""
import math
import random

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, error_found_without_solving

from solver.planning.motion_planning import astar, dijkstra, field_zeros, grid_graph, heuristic_check
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem


def random_grid(rng: random.Random, rows: int, cols: int, p: float) -> list[str]:
    g = [["#" if rng.random() < p else "." for _ in range(cols)] for _ in range(rows)]
    g[0][0], g[rows - 1][cols - 1] = "S", "G"
    return ["".join(r) for r in g]


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("conn", [4, 8])
def test_astar_is_optimal_on_random_grids(seed, conn):
    rng = random.Random(seed)
    rows = random_grid(rng, 9, 11, 0.28)
    nb, pos, s, g = grid_graph(rows, conn)
    gx, gy = pos[g]
    h = {k: math.hypot(pos[k][0] - gx, pos[k][1] - gy) for k in nb}
    path, cost, steps = astar(nb, s, g, h)
    dist = dijkstra(nb, s)
    if g not in dist:
        assert path is None
        return
    assert cost == pytest.approx(dist[g], abs=1e-9)
    # the path is a chain of edges whose weights add up to the cost
    w = sum(dict(nb[a])[b] for a, b in zip(path, path[1:]))
    assert w == pytest.approx(cost) and path[0] == s and path[-1] == g
    # with the zero heuristic (Dijkstra order) at least as many expansions
    _, c0, steps0 = astar(nb, s, g, {k: 0.0 for k in nb})
    assert c0 == pytest.approx(cost) and len(steps0) >= len(steps)


def test_astar_on_random_graphs_with_consistent_heuristic():
    rng = random.Random(4)
    for _ in range(20):
        n = 15
        pos = {str(i): (rng.uniform(0, 10), rng.uniform(0, 10)) for i in range(n)}
        nb = {k: [] for k in pos}
        for i in range(n):
            for j in range(i + 1, n):
                if rng.random() < 0.25:
                    w = math.dist(pos[str(i)], pos[str(j)]) * rng.uniform(1, 1.5)
                    nb[str(i)].append((str(j), w))
                    nb[str(j)].append((str(i), w))
        h = {k: math.dist(pos[k], pos["14"]) for k in pos}
        path, cost, _ = astar(nb, "0", "14", h)
        d = dijkstra(nb, "0")
        assert (path is None) == ("14" not in d)
        if path:
            assert cost == pytest.approx(d["14"])


GRAPH = """
id: t
title: A*
asks:
  - kind: motion_planning
    method: astar
    graph:
      nodes: {A: [0, 0], B: [1, 0], C: [1, 1], D: [2, 1]}
      edges: [[A, B, 1], [B, D, 5], [A, C, 2], [C, D, 1], [B, C]]
    start: A
    target: D
"""


def test_astar_spec_expansions_and_report():
    p = load_problem_text(GRAPH)
    sols = solve_problem(p)
    res = all_results(sols)
    assert res["cost"].value == 3 and res["path_found"].value is True
    steps = sols[0].steps[0].data["steps"]
    assert [s["node"] for s in steps][0] == "A" and steps[-1]["node"] == "D"
    fs = [s["f"] for s in steps]
    assert all(b >= a - 1e-12 for a, b in zip(fs, fs[1:]))  # consistent heuristic: f never decreases
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "A → C → D" in md and "\\begin{tabular}" in tex


def test_astar_errors():
    with pytest.raises(UserError):
        solve_problem(load_problem_text(GRAPH.replace("target: D", "target: Z")))


GRID = """
id: t
title: A* on a grid
asks:
  - kind: motion_planning
    method: astar
    grid: ["...G", ".#..", "S.#."]
    connectivity: 8
    heuristic: euclidean
"""


def test_astar_grid_figure_draws_the_occupied_cells():
    """The search figure fills each '#' cell (a unit square at x = c, y = −r) under the path."""
    sols = solve_problem(load_problem_text(GRID))
    panel, = next(f for f in sols[0].figures if f.name == "search").panels
    cells = sorted((min(c.x), max(c.x), min(c.y), max(c.y)) for c in panel.curves if c.filled)
    assert cells == [(0.5, 1.5, -1.5, -0.5), (1.5, 2.5, -2.5, -1.5)]
    assert [c.label for c in panel.curves if c.filled] == ["obstacle", ""]
    assert panel.curves[-1].label == "path" and not panel.curves[-1].filled   # drawn over them
    steps = sols[0].steps[-1].data["steps"]   # the expanded nodes numbered with their step of the table
    numbered = {label: (x, y) for x, y, label in panel.markers if label.isdigit()}
    assert numbered and all(steps[int(k) - 1]["node"] == f"({-int(y)},{int(x)})" for k, (x, y) in numbered.items())
    assert {label for *_, label in panel.markers} >= {"start", "goal"}


def test_astar_grid_diagonal_rule_and_corner_cutting():
    """8-connected: diagonal √2, past an occupied corner unless corner_cutting: false; the report states the rule."""
    nb, _, s, g = grid_graph(["S#", ".G"], 8)
    assert dict(nb[s]) == {"(1,0)": 1.0, "(1,1)": pytest.approx(math.sqrt(2))}
    nb, _, s, g = grid_graph(["S#", ".G"], 8, corner_cutting=False)
    assert dict(nb[s]) == {"(1,0)": 1.0} and astar(nb, s, g, {k: 0.0 for k in nb})[1] == 2
    nb, _, s, g = grid_graph(["S#", "#G"], 8, corner_cutting=False)
    assert astar(nb, s, g, {k: 0.0 for k in nb})[0] is None
    p = load_problem_text(GRID)
    sols = solve_problem(p)
    assert all_results(sols)["cost"].value == 1 + 2 * sp.sqrt(2)   # S, (2,1), (1,2), G: between two '#' twice
    md = render(p, sols, "md")
    assert "8-connected, cost 1 to a side cell and √2 to a diagonal one, corner cutting allowed" in md
    p = load_problem_text(GRID.replace("connectivity: 8", "connectivity: 8\n    corner_cutting: false"))
    sols = solve_problem(p)
    assert all_results(sols)["cost"].value == 5   # up the left column, along the top row
    assert "√2 to a diagonal one, no corner cutting" in render(p, sols, "md")
    p = load_problem_text(GRID.replace("connectivity: 8", "connectivity: 4"))
    assert "4-connected, cost 1 to a side cell, no diagonal moves" in render(p, solve_problem(p), "md")


def test_heuristic_check_flags_an_overestimate_and_the_optimal_cost():
    """Manhattan on an 8-connected grid overestimates diagonals: not admissible, and here A* returns 3 + √2 while
    the optimum is 1 + 2√2; the report says both."""
    p = load_problem_text(GRID.replace("euclidean", "manhattan"))
    sols = solve_problem(p)
    res = all_results(sols)
    assert res["admissible"].value is False and res["consistent"].value is False
    assert res["cost"].value == 3 + sp.sqrt(2)
    d = sols[0].steps[0].data
    assert d["optimal_cost"] == pytest.approx(1 + 2 * math.sqrt(2)) and d["optimal"] is False
    # the worst node (h − h* = 4 − 2√2 at S too; the one nearer the goal named)
    assert d["over"] == ("(2,1)", 4.0, pytest.approx(2 * math.sqrt(2)))
    md = render(p, sols, "md")
    assert "**not admissible** ($h = 4 > h^* = 2.828$ at (2,1))" in md
    assert "the path found is **not optimal**: the optimal cost is **3.82843**" in md
    # Euclidean on the same grid: admissible and consistent, optimal
    sols = solve_problem(load_problem_text(GRID))
    res = all_results(sols)
    assert res["admissible"].value is True and res["consistent"].value is True
    assert "admissible ($h \\le h^*$ at every node) and consistent" in render(load_problem_text(GRID), sols, "md")


def test_heuristic_check_admissible_but_inconsistent():
    """h ≤ h* everywhere but h(B) = 3 > c(B, A) + h(A) = 2: A* (no reopening) closes A first with g = 3 and
    returns S-A-G (5) instead of S-B-A-G (4)."""
    nb = {"S": [("A", 3.0), ("B", 1.0)], "A": [("S", 3.0), ("B", 1.0), ("G", 2.0)], "B": [("S", 1.0), ("A", 1.0)],
          "G": [("A", 2.0)]}
    h = {"S": 0.0, "A": 1.0, "B": 3.0, "G": 0.0}
    chk = heuristic_check(nb, "G", h)
    assert chk["hstar"] == {"G": 0.0, "A": 2.0, "B": 3.0, "S": 4.0}
    assert chk["admissible"] and not chk["consistent"] and chk["edge"] == ("B", "S", 1.0, 3.0, 0.0)
    assert astar(nb, "S", "G", h)[:2] == (["S", "A", "G"], 5.0)
    p = load_problem_text("""
id: t
title: A*
asks:
  - kind: motion_planning
    method: astar
    graph:
      nodes: {S: null, A: null, B: null, G: null}
      edges: [[S, A, 3], [S, B, 1], [A, B, 1], [A, G, 2]]
    start: S
    target: G
    heuristic: {S: 0, A: 1, B: 3, G: 0}
""")
    sols = solve_problem(p)
    res = all_results(sols)
    assert res["admissible"].value is True and res["consistent"].value is False and res["cost"].value == 5
    md = render(p, sols, "md")
    assert "admissible ($h \\le h^*$ at every node) and **not consistent** ($h = 3$ at B $> c + h = 1 + 0$ at S)" in md
    assert "the optimal cost is **4**" in md


POT = """
id: t
title: potential
symbols: {a: obstacle x, b: obstacle y, r0: range, kr: repulsive gain, ka: attractive gain, kd: damping}
values: {a: 1, b: 0.6, r0: 1.5, kr: 0.5, ka: 1, kd: 2}
robot:
  joints: [P, P]
  coordinates: [x, y]
  model: {B: [[2, 0], [0, 2]]}
asks:
  - kind: motion_planning
    method: potential
    goal: [2, 1]
    gain: ka
    damping: kd
    obstacles:
      - {clearance: sqrt((x - a)^2 + (y - b)^2), range: r0, gain: kr}
    range: {x: [-1, 3], y: [-1, 3]}
"""


def test_potential_equilibria_are_zeros_of_the_field():
    p = load_problem_text(POT)
    res = all_results(solve_problem(p))
    x, y = p.robot.q
    vals = p.values
    G = res["grad_rep1"].value.xreplace(vals)
    eta = sp.sqrt((x - 1) ** 2 + (y - sp.Rational(3, 5)) ** 2)
    eqs = res["equilibria_at"].value
    assert eqs, "the goal at least"
    for e in eqs:
        sub = {x: e[0], y: e[1]}
        F = sp.Matrix([2 - x, 1 - y]) - (G if float(eta.subs(sub)) < 1.5 else sp.zeros(2, 1))
        assert max(abs(float(v)) for v in F.subs(sub)) < 1e-7
    # the goal lies in the obstacle's range: the equilibrium is displaced away from the obstacle
    assert not any(abs(float(e[0]) - 2) < 1e-6 and abs(float(e[1]) - 1) < 1e-6 for e in eqs)
    # V̇ = −K_D ‖q̇‖² exactly
    dx, dy = p.robot.dq
    assert sp.simplify(res["V_dot"].value + p.names["kd"] * (dx ** 2 + dy ** 2)) == 0


def test_field_zeros_1d():
    zs = field_zeros(lambda z: np.array([(z[0] - 0.3) * (z[0] + 1.2)]), np.array([-2.0]), np.array([2.0]))
    assert sorted(round(float(z[0]), 9) for z in zs) == [-1.2, 0.3]


def test_problem_verifies():
    rep = check_problem(load_problem(PROBLEMS / "2005-04-05-ex2.yaml"))
    assert rep.ok, [c for c in rep.checks if not c.ok]


@pytest.mark.parametrize("text, words", [
    (GRAPH.replace("target: D", "target: Z"), "start: and target: must be nodes of the graph"),
    (GRAPH.replace("[B, C]]", "[B, Q]]"), "an edge is [a, b] or [a, b, weight] between declared nodes"),
    (POT.replace("goal: [2, 1]", "goal: [2, 1, 0]"), "goal: 2 components expected"),
    (POT.replace("gain: kr}", "gain: kq}"), "unknown name 'kq'"),
])
def test_check_finds_bad_input_without_solving(text, words):
    """The graph and the potential's inputs are read by the kind's validate hook (`check`) as by solving."""
    assert words in error_found_without_solving(text)


@pytest.mark.parametrize("rows, line, words", [
    (["...G", ".#x.", "S.#."], 9, "row 1, column 2: 'x' is not a cell"),
    (["..SG", ".#..", "S.#."], 10, "one S (start); it has 2 (row, column: (0, 2), (2, 0))"),
    (["...G", ".#.", "S.#."], 9, "grid row 1 has 3 cells, row 0 has 4"),
    (["....", ".#..", "S.#."], 8, "one G (goal); it has 0"),
])
def test_astar_grid_is_checked_cell_by_cell(rows, line, words):
    """Another character than . # S G, rows of different lengths, no or two S/G: an error at the row's line
    (before, 'x' was a free cell and a second S silently replaced the first)."""
    text = GRID.replace('grid: ["...G", ".#..", "S.#."]', "grid:\n" + "".join(f'      - "{r}"\n' for r in rows))
    with pytest.raises(UserError) as exc:
        load_problem_text(text, "g.yaml")
        solve_problem(load_problem_text(text, "g.yaml"))
    assert f"g.yaml:{line}:" in str(exc.value) and words in str(exc.value)


def test_astar_unreachable_goal_still_draws_the_search(tmp_path):
    """No path: the figure shows the obstacles, start, goal and the nodes expanded before the open list ran out."""
    from solver.publish.figures import draw
    sols = solve_problem(load_problem_text(GRID.replace('"...G", ".#..", "S.#."', '"S.#.", "..#G", "###."')))
    res = all_results(sols)
    assert res["path_found"].value is False and res["expansions"].value == 4
    fig = next(f for f in sols[0].figures if f.name == "search")
    assert "no path" in fig.caption
    panel, = fig.panels
    assert not any(c.label == "path" for c in panel.curves) and sum(c.filled for c in panel.curves) == 5
    assert sorted(label for *_, label in panel.markers) == ["2", "3", "4", "goal", "start"]  # 1: the start
    draw(fig, tmp_path / "search.png")
    assert (tmp_path / "search.png").stat().st_size > 5000


def test_a_caption_with_a_star_stays_one_emphasis_in_markdown_and_html():
    """"*A*: the path ...*" made "A" the emphasis; the caption's stars outside math are escaped. In HTML, an
    emphasis around math was left as literal stars."""
    from solver.publish.render import md2html
    p = load_problem_text(GRID)
    sols = solve_problem(p)
    fig = next(f for f in sols[0].figures if f.name == "search")
    fig.path = "r-1-search.png"
    md = render(p, sols, "md")
    assert "\n*A\\*: the path found and the expanded nodes, numbered with their step, the occupied cells in grey.*\n" in md
    assert "<em>A*: the path found and the expanded nodes, numbered with their step, the occupied cells in " \
           "grey.</em>" in md2html(md)
    assert md2html("*$q^*$ and x\\*y*") == "<p><em>$q^*$ and x*y</em></p>"
    assert md2html("*Gravity torque $g_1(q)$.*") == "<p><em>Gravity torque $g_1(q)$.</em></p>"  # was "*...*"
