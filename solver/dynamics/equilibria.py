"""Unforced equilibria (ask kind ``equilibria``): all q with g(q) = 0 (u = 0, q̇ = 0).

Each angle θ (a coordinate inside sin/cos) is replaced by (c_θ, s_θ) with c_θ² + s_θ² = 1, which turns g(q) = 0
into a polynomial system; its solutions (all of them, by Gröbner bases) give θ = atan2(s_θ, c_θ) ∈ (-π, π].
A coordinate left free by a solution is arbitrary there (a continuum of equilibria); square roots in a solution
give the conditions for it to exist.
"""
from __future__ import annotations

from typing import Literal, Optional

import sympy as sp
from pydantic import Field

from solver.dynamics.model import derive, require_model
from solver.math.simplify import angle_symbols, tidy
from solver.registry import ask_kind
from solver.results import Solution
from solver.spec.models import Strict


class EquilibriaAsk(Strict):
    """Find every configuration where the robot stays at rest with u = 0."""

    kind: Literal["equilibria"]
    title: Optional[str] = Field(None, description="heading of this part in the report")


def _to_polynomial(g: list[sp.Expr], angles: list[sp.Symbol]) -> tuple[list[sp.Expr], dict]:
    cs = {a: (sp.Symbol(f"c_{a.name}", real=True), sp.Symbol(f"s_{a.name}", real=True)) for a in angles}
    eqs = []
    for x in g:
        e = sp.expand(sp.expand_trig(sp.expand(x, trig=True)))
        e = e.subs({sp.cos(a): cs[a][0] for a in angles}).subs({sp.sin(a): cs[a][1] for a in angles})
        e = sp.numer(sp.together(e))
        if e != 0:
            eqs.append(sp.expand(e))
    eqs += [c ** 2 + s ** 2 - 1 for c, s in cs.values()]
    return eqs, cs


def equilibria(g: sp.Matrix, q: list[sp.Symbol]) -> tuple[list[sp.Matrix], list[sp.Expr], bool]:
    """(configurations, conditions, every_configuration) for g(q) = 0."""
    g_list = [tidy(x) for x in g]
    if all(x == 0 for x in g_list):
        return [sp.Matrix(q)], [], True
    angles = [a for a in angle_symbols(sp.Add(*g_list)) if a in q]
    eqs, cs = _to_polynomial(g_list, angles)
    unknowns = [v for a in angles for v in cs[a]] + [x for x in q if x not in angles]
    sols = sp.solve(eqs, unknowns, dict=True)
    configs, conditions = [], []
    for s in sols:
        vals = []
        for x in q:
            if x in angles:
                c, sn = s.get(cs[x][0], cs[x][0]), s.get(cs[x][1], cs[x][1])
                if c.free_symbols & {cs[x][0], cs[x][1]} or sn.free_symbols & {cs[x][0], cs[x][1]}:
                    vals.append(x)  # free angle
                else:
                    vals.append(tidy(sp.atan2(sn, c)) if not (c.is_number and sn.is_number) else sp.atan2(sn, c))
            else:
                vals.append(tidy(s.get(x, x)))
        if any(v.has(sp.I) for v in vals):
            continue
        for v in vals:
            for p in v.atoms(sp.Pow):
                if p.exp == sp.Rational(1, 2) and not p.base.is_nonnegative:
                    conditions.append(sp.GreaterThan(p.base, 0))
        configs.append(sp.Matrix(vals))
    configs.sort(key=lambda m: [float(sp.N(x)) if x.is_number else 0.0 for x in m])
    return configs, list(dict.fromkeys(conditions)), False


@ask_kind("equilibria", EquilibriaAsk, "unforced equilibrium configurations: g(q) = 0")
def solve_equilibria(problem, options: EquilibriaAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: equilibria (set of configurations), n_equilibria."""
    robot = require_model(problem)
    dm = derive(robot)
    configs, conditions, every = equilibria(dm.g, robot.q)
    sol = Solution("equilibria", title=options.title or "Equilibrium configurations")
    sol.add("equilibria", configs, "set", label="q_e")
    sol.add("n_equilibria", sp.Integer(len(configs)) if not every else sp.oo, "number", label="N_e")
    sol.step("equilibria", g=dm.g, q=robot.q, configs=configs, conditions=conditions, every=every,
             free=[[x for x in c if x in robot.q] for c in configs])
    return sol
