"""Sketches of planar robots, for any ask kind: the robot drawn from its spec at the configurations an exercise uses.

    from solver.kinematics.sketch import robot_sketch
    fig = robot_sketch(problem, [("$q_0$", {q1: 0, q2: pi/2})], task=r, arrows=[...])   # a Figure, or None
    if fig: sol.figures.append(fig)

The chain's points P_0..P_n come from the DH frames of a planar robot (their origins), else from a planar position
task written as a sum of link contributions (:func:`solver.kinematics.geometry.task_skeleton`), else from explicit
``points``. Numbers are computed only when the figure is drawn.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Sequence

import sympy as sp

from solver.kinematics.geometry import dh_skeleton, task_skeleton
from solver.results import Arrow, Curve, Figure, Panel, RobotPose, Sketch

if TYPE_CHECKING:
    from solver.spec.problem import Problem
    from solver.spec.robot import Robot

Config = dict[sp.Symbol, sp.Expr]


def skeleton(robot: "Robot", task: sp.Matrix | None = None) -> list[sp.Matrix] | None:
    """P_0..P_n (planar, in q) of ``robot``: DH origins, else read off a position task; None if neither applies."""
    pts = dh_skeleton(robot) if robot.frames else None
    if pts is None and task is not None:
        pts = task_skeleton(task, robot.q)
    return pts


def parameter_values(exprs: Sequence[sp.Expr], values: dict, free: set) -> tuple[dict[sp.Symbol, float], list]:
    """Numbers for every parameter: its value, else 1 (listed, for the caption)."""
    params: set[sp.Symbol] = set()
    for e in exprs:
        params |= e.free_symbols
    out, unit = {}, []
    for s in sorted(params - free, key=lambda s: s.name):
        v = values.get(s)
        if v is not None and v.is_number:
            out[s] = float(v)
        else:
            out[s], unit = 1.0, unit + [s]
    return out, unit


def illustrative(robot: "Robot", points: list[sp.Matrix], fixed: dict) -> Config:
    """A configuration that shows the structure: revolute joints at π/6, prismatic ones at half the reach."""
    zero = {q: (sp.Integer(0) if j == "R" else sp.Integer(1)) for q, j in zip(robot.q, robot.joints)}
    reach = 0.0
    for p in points:
        v = [float(sp.N(c.subs(zero).subs(fixed))) for c in p]
        reach = max(reach, math.hypot(*v))
    half = sp.Float(round(0.5 * (reach or 1.0), 3))
    return {q: (sp.pi / 6 if j == "R" else half) for q, j in zip(robot.q, robot.joints)}


def pose(points: list[sp.Matrix], robot: "Robot", state: Config, fixed: dict, label: str) -> RobotPose | None:
    """The numbers of one pose (None if the configuration leaves something symbolic or complex)."""
    sub = {**fixed, **{k: v for k, v in state.items()}}
    try:
        xy = [(float(sp.N(p[0].subs(sub))), float(sp.N(p[1].subs(sub)))) for p in points]
    except (TypeError, ValueError):
        return None
    slides: list[tuple[float, float] | None] = []
    for i, (qi, kind) in enumerate(zip(robot.q, robot.joints)):
        if kind != "P":
            slides.append(None)
            continue
        d = points[i + 1].diff(qi).subs(sub)
        try:
            dx, dy = float(sp.N(d[0])), float(sp.N(d[1]))
        except (TypeError, ValueError):
            dx, dy = 0.0, 0.0
        norm = math.hypot(dx, dy)
        if norm < 1e-12:
            (x0, y0), (x1, y1) = xy[i], xy[i + 1]
            dx, dy, norm = x1 - x0, y1 - y0, math.hypot(x1 - x0, y1 - y0) or 1.0
        slides.append((dx / norm, dy / norm))
    return RobotPose(label, xy, list(robot.joints), slides)


def robot_sketch(problem: "Problem", configurations: list[tuple[str, Config]], task: sp.Matrix | None = None,
                 points: list[sp.Matrix] | None = None, arrows: list[tuple[str, Config, Any, Any]] | None = None,
                 paths: list[tuple[str, list[tuple[float, float]]]] | None = None, name: str = "sketch",
                 caption: str = "The robot") -> Figure | None:
    """A figure of the planar robot of ``problem`` at each labelled configuration (an illustrative one when the list
    is empty). ``arrows``: (label, configuration, point (2-vector expression in q or None for the end effector),
    vector (2 numbers or expressions)); ``paths``: (label, [(x, y), ...]). None when the robot is not planar or has
    no geometry to draw."""
    robot = problem.robot
    if robot is None:
        return None
    pts = points if points is not None else skeleton(robot, task)
    if pts is None or len(pts) != robot.n + 1:
        return None
    free = set(robot.q) | set(robot.dq) | set(robot.ddq)
    fixed, unit = parameter_values([c for p in pts for c in p], problem.values, free)
    confs = list(configurations) or [("illustrative configuration", illustrative(robot, pts, fixed))]
    latex = problem.latex_names

    def sample() -> list[Panel]:
        poses = [p for p in (pose(pts, robot, st, fixed, lab) for lab, st in confs) if p is not None]
        arr = []
        for lab, st, at, vec in arrows or []:
            base = (at if at is not None else pts[-1]).subs({**fixed, **st})
            try:
                x, y = float(sp.N(base[0])), float(sp.N(base[1]))
                dx, dy = (float(sp.N(sp.sympify(v).subs({**fixed, **st}))) for v in vec)
            except (TypeError, ValueError):
                continue
            arr.append(Arrow(x, y, dx, dy, lab))
        curves = [Curve(lab, [float(x) for x, _ in xy], [float(y) for _, y in xy]) for lab, xy in paths or []]
        return [Panel("$x$", "$y$", [], sketch=Sketch(poses, arr, curves))]

    if not configurations:
        caption += " at an illustrative configuration (revolute joints at $\\pi/6$)"
    if unit:
        caption += ", drawn with " + ", ".join(f"${latex.get(s, sp.latex(s))} = 1$" for s in unit)
    return Figure(name, caption + ".", sample)
