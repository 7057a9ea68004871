"""Solving a problem: run each ask's registered solver in order."""
from __future__ import annotations

from solver.math.nounits import without_units
from solver.registry import get_kind
from solver.results import Solution
from solver.spec.problem import Problem


def solve_problem(problem: Problem) -> list[Solution]:
    """One :class:`Solution` per ask of ``problem`` (only the modules of its ask kinds are imported)."""
    with without_units():
        return [get_kind(a.kind).solve(problem, a.options, a.ctx) for a in problem.asks]


def all_results(solutions: list[Solution]) -> dict:
    """Results of every ask, by name (a later ask's result of the same name wins)."""
    out = {}
    for s in solutions:
        out.update(s.results)
    return out
