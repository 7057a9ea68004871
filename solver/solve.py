"""Solving a problem: run each ask's registered solver in order."""
from __future__ import annotations

from typing import Callable

from solver.math.nounits import without_units
from solver.registry import get_kind
from solver.results import Solution
from solver.spec.problem import Problem


def solve_problem(problem: Problem, solved: Callable[[int, Solution], None] | None = None) -> list[Solution]:
    """One :class:`Solution` per ask of ``problem`` (only the modules of its ask kinds are imported);
    ``solved(k, solution)`` is called as soon as ask k (from 1) is solved (the CLI's painter draws its figures
    while the next asks are solved)."""
    out = []
    with without_units():
        for k, a in enumerate(problem.asks, 1):
            out.append(get_kind(a.kind).solve(problem, a.options, a.ctx))
            if solved is not None:
                solved(k, out[-1])
    return out


def all_results(solutions: list[Solution]) -> dict:
    """Results of every ask, by name (a later ask's result of the same name wins)."""
    out = {}
    for s in solutions:
        out.update(s.results)
    return out
