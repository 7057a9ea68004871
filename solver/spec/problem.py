"""A problem as the solvers see it: symbols, numeric values, the robot and the asks, all parsed."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import sympy as sp
from pydantic import BaseModel

from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.robot import Robot
from solver.spec.yamlpos import Located, PathT


@dataclass
class AskContext:
    """Gives a solver the parsed expressions of its ask entry (errors point at the spec's line)."""

    path: PathT
    parse_at: Callable[[PathT], Any]

    def expr(self, *sub: Any) -> Any:
        """The parsed value at ``asks[i].<sub...>``."""
        return self.parse_at(self.path + tuple(sub))


class AskReader:
    """Base of a solver's parsed inputs (``self.problem``, ``self.ctx``): errors at the ask's spec line, and
    vectors of a given size read from the ask entry."""

    problem: Problem
    ctx: AskContext

    def fail(self, sub: tuple, message: str, hint: str | None = None) -> UserError:
        return UserError(message, self.problem.located.place(self.ctx.path + sub), hint)

    def _vector(self, key: str, size: int, what: str) -> sp.Matrix:
        val = self.ctx.expr(key)
        if not isinstance(val, list):
            val = [val]
        if shape_of(val) != (size,):
            raise self.fail((key,), f"{what} must have {size} components, got shape {shape_of(val)}",
                            f"write a list of {size} expressions")
        return sp.Matrix(val)


@dataclass
class Ask:
    kind: str
    options: BaseModel
    ctx: AskContext


@dataclass
class Problem:
    id: str
    title: str
    statement: str
    source: dict[str, Any] | None
    symbols: dict[str, sp.Symbol]          # parameters
    meanings: dict[str, str]
    names: dict[str, sp.Expr]              # every name an expression may use
    latex_names: dict[sp.Symbol, str]      # how symbols print in LaTeX
    values: dict[sp.Symbol, sp.Expr]       # numeric values of parameters, where given
    known: list[sp.Symbol]
    robot: Robot | None
    asks: list[Ask]
    expected: dict[str, Any]
    located: Located
    file: str
    topics: list[str] = field(default_factory=list)
    notes: str = ""
    parse_at: Callable[[PathT], Any] | None = None
