"""What solvers return: named results and the explanation steps, as sympy objects (never formatted text)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import sympy as sp


@dataclass
class Result:
    """A named result. kind: scalar | vector | matrix | list (of matrices/vectors) | set (of configurations)
    | number | bool."""

    name: str
    value: Any
    kind: str
    label: str = ""  # LaTeX left-hand side, e.g. B(q)


@dataclass
class Step:
    """One explanation step: ``name`` selects the template block, ``data`` holds its sympy objects."""

    name: str
    data: dict[str, Any] = field(default_factory=dict)


@dataclass
class Curve:
    label: str  # LaTeX
    x: list[float]
    y: list[float]


@dataclass
class Panel:
    xlabel: str  # LaTeX
    ylabel: str
    curves: list[Curve]
    x_is_angle: bool = False  # ticks at multiples of π/2
    hlines: list[tuple[float, str]] = field(default_factory=list)  # (y, label): bounds, drawn dashed
    markers: list[tuple[float, float, str]] = field(default_factory=list)  # (x, y, label): points to mark
    equal_axes: bool = False  # same scale on x and y (a path in the plane)


@dataclass
class Figure:
    """Numbers to plot (the renderer draws them): one or more side-by-side panels, sampled by ``sample`` the
    first time they are asked for (reports without files, verify and grading never pay for them)."""

    name: str
    caption: str
    sample: Callable[[], list[Panel]] = field(repr=False)
    path: str = ""  # set when the renderer writes the image file
    _panels: Optional[list[Panel]] = field(default=None, repr=False)

    @property
    def panels(self) -> list[Panel]:
        if self._panels is None:
            self._panels = self.sample()
        return self._panels


@dataclass
class Solution:
    """The answer to one ask: its results (by name) and the steps that explain them."""

    kind: str
    results: dict[str, Result] = field(default_factory=dict)
    steps: list[Step] = field(default_factory=list)
    title: str = ""
    figures: list[Figure] = field(default_factory=list)

    def add(self, name: str, value: Any, kind: str | None = None, label: str = "") -> Any:
        self.results[name] = Result(name, value, kind or kind_of(value), label)
        return value

    def step(self, name: str, **data: Any) -> None:
        self.steps.append(Step(name, data))


def kind_of(value: Any) -> str:
    """The result kind of a value."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, sp.MatrixBase):
        return "vector" if value.shape[1] == 1 else "matrix"
    if isinstance(value, (list, tuple)):
        return "list"
    if isinstance(value, (int, float)) or (isinstance(value, sp.Expr) and value.is_number):
        return "number"
    return "scalar"
