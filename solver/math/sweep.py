"""Numeric sweeps of formulas along one coordinate, for the figures of a report.

f(q_j) is sampled on a grid of q_j with the other coordinates held at a reference state and the parameters at
their numeric ``values`` (parameters without a value are set to 1, and the caption says so).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

import sympy as sp

from solver.math.numeric import evaluate_np
from solver.results import Curve, Figure, Panel

if TYPE_CHECKING:
    import numpy as np

    from solver.spec.robot import Robot


def default_range(joint: str) -> tuple[float, float]:
    """[-π, π] for a revolute coordinate, [-1, 1] for a prismatic one (or any other)."""
    return (-math.pi, math.pi) if joint == "R" else (-1.0, 1.0)


def numeric_values(exprs: Sequence[sp.Expr], values: dict[sp.Symbol, sp.Expr],
                   free: set[sp.Symbol]) -> tuple[dict[sp.Symbol, float], list[sp.Symbol]]:
    """Values of every parameter in ``exprs`` (not in ``free``): given ones, else 1; and the list set to 1."""
    params: set[sp.Symbol] = set()
    for e in exprs:
        params |= e.free_symbols
    params -= free
    out, unit = {}, []
    for s in sorted(params, key=lambda s: s.name):
        if s in values and values[s].is_number:
            out[s] = float(values[s])
        else:
            out[s], unit = 1.0, unit + [s]
    return out, unit


def sweep(expr: sp.Expr, x: sp.Symbol, grid: np.ndarray, fixed: dict[sp.Symbol, float]) -> list[float]:
    """expr(x) on ``grid`` with every other symbol replaced by ``fixed``."""
    e = expr.xreplace({s: sp.Float(v) for s, v in fixed.items() if s != x})  # (subs: the same, ~5x slower)
    if not e.free_symbols:
        return [float(e)] * len(grid)
    import numpy as np  # here, not at the top: most solves draw no figure (start-up of `check`, `solve`)
    vals = evaluate_np(e, [x], [grid])
    return [float(v) for v in np.broadcast_to(vals, grid.shape)]


def coordinate_figure(name: str, caption: str, entries: list[tuple[str, sp.Expr]], robot: Robot,
                      values: dict[sp.Symbol, sp.Expr], reference: dict[sp.Symbol, float],
                      ranges: dict[sp.Symbol, tuple[float, float]], latex: dict[sp.Symbol, str],
                      points: int = 181) -> Figure | None:
    """One panel per coordinate q_j on which some entry depends: each entry plotted against q_j, the other
    coordinates at ``reference`` (default 0). An entry that vanishes identically there (b₁₂ = f(q₃) sin q₂ against
    q₃ with q₂ = 0) is not drawn as a flat line: the caption names it. None when nothing is left to draw."""
    q = robot.q
    state = set(q) | set(robot.dq) | set(robot.ddq)
    fixed, unit = numeric_values([e for _, e in entries], values, state)
    fixed.update({s: reference.get(s, 0.0) for s in state})
    exact = {s: sp.Integer(0) if v == 0 else sp.Float(v) for s, v in fixed.items() if s in state}
    columns, flat = [], {}  # flat: {label: coordinates against which it vanishes}
    for j, qj in enumerate(q):
        deps = []
        for label, e in entries:
            if qj not in e.free_symbols:
                continue
            if e.xreplace({s: v for s, v in exact.items() if s != qj}) == 0:
                flat.setdefault(label, []).append(f"${latex.get(qj, sp.latex(qj))}$")
            else:
                deps.append((label, e))
        if deps:
            columns.append((j, qj, deps))
    if not columns:
        return None

    def sample() -> list[Panel]:
        panels = []
        for j, qj, deps in columns:
            lo, hi = ranges.get(qj, default_range(robot.joints[j]))
            import numpy as np
            grid = np.linspace(lo, hi, points)
            curves = [Curve(label, [float(v) for v in grid], sweep(e, qj, grid, fixed)) for label, e in deps]
            panels.append(Panel(f"${latex.get(qj, sp.latex(qj))}$", "", curves, robot.joints[j] == "R"))
        return panels

    others = [s for s in q if reference.get(s, 0.0) != 0.0]
    note = " Other coordinates at 0" if not others else " Other coordinates at the reference state"
    note += "." if not unit else (", parameters without a numeric value set to 1 ("
                                 + ", ".join(f"${latex.get(s, sp.latex(s))}$" for s in unit) + ").")
    if flat:
        note += " Not drawn (zero at these values of the other coordinates): " + ", ".join(
            f"{label} against {' and '.join(axes)}" for label, axes in flat.items()) + "."
    return Figure(name, caption + note, sample)
