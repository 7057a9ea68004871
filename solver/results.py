"""What solvers return: named results and the explanation steps, as sympy objects (never formatted text)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional

# sympy is imported where a value is classified (kind_of), not here: the figure helper imports this module
# (Figure, Panel, ...) before sympy, to warm matplotlib up while the solving worker imports sympy


class Deferred:
    """A value computed when first read, in an attribute of a :class:`Resolving` object: per-body quantities are
    printed only when a report, a check or ``--details`` reads them. ``optional``: a quantity of a part the ask
    does not show, which a helper process does not compute to send it (:func:`sending_optional`)."""

    __slots__ = ("make", "optional")

    def __init__(self, make: Callable[[], Any], optional: bool = False) -> None:
        self.make = make
        self.optional = optional


class NotSent:
    """In place of an optional :class:`Deferred` that a helper did not compute (reading it is a bug: the caller
    needed it and did not ask the helpers for the optional quantities)."""

    __slots__ = ()


_SEND_OPTIONAL = [True]


def sending_optional(send: bool) -> None:
    """Whether pickling this process's :class:`Resolving` objects computes their optional deferred values (True)
    or leaves them out (False: the receiver reads none of them, e.g. a report that does not show their part)."""
    _SEND_OPTIONAL[0] = send


class Resolving:
    """An attribute holding a :class:`Deferred` is computed on first read and kept; pickling computes them all
    (the optional ones only while :func:`sending_optional` is on)."""

    def __getattribute__(self, name: str) -> Any:
        value = object.__getattribute__(self, name)
        if type(value) is Deferred:
            value = value.make()
            object.__setattr__(self, name, value)
        elif type(value) is NotSent:
            raise RuntimeError(f"{type(self).__name__}.{name} was not sent by the helper that solved it")
        return value

    def given(self, name: str) -> bool:
        """Whether the attribute is not None, without computing it."""
        return object.__getattribute__(self, name) is not None

    def __getstate__(self) -> dict[str, Any]:
        raw = object.__getattribute__(self, "__dict__")
        return {k: NotSent() if type(v) is Deferred and v.optional and not _SEND_OPTIONAL[0] else getattr(self, k)
                for k, v in raw.items()}


@dataclass
class Result(Resolving):
    """A named result. kind: scalar | vector | matrix | list (of matrices/vectors) | set (of configurations)
    | number | bool. ``value`` may be given :class:`Deferred` (then ``kind`` must be given)."""

    name: str
    value: Any
    kind: str
    label: str = ""  # LaTeX left-hand side, e.g. B(q)
    detail: bool = False  # an intermediate quantity (per-body energies, ...): in JSON only on request


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
    dashed: bool = False  # a reference or predicted value drawn dashed
    filled: bool = False  # a closed polygon (x, y its corners) filled in grey under the lines: an obstacle


@dataclass
class Panel:
    xlabel: str  # LaTeX
    ylabel: str
    curves: list[Curve]
    x_is_angle: bool = False  # ticks at multiples of π/2
    hlines: list[tuple[float, str]] = field(default_factory=list)  # (y, label): bounds, drawn dashed
    markers: list[tuple[float, float, str]] = field(default_factory=list)  # (x, y, label): points to mark
    equal_axes: bool = False  # same scale on x and y (a path in the plane)
    categorical: bool = False  # x are indices (joints): points side by side, dashed curves as bound ticks
    sketch: Optional["Sketch"] = None  # a robot sketch (drawn to scale) instead of, or over, the curves


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

    def add(self, name: str, value: Any, kind: str | None = None, label: str = "", detail: bool = False) -> Any:
        if kind is None and isinstance(value, Deferred):
            raise ValueError(f"{name}: a deferred result needs its kind")
        self.results[name] = Result(name, value, kind or kind_of(value), label, detail)
        return value

    def step(self, name: str, **data: Any) -> None:
        self.steps.append(Step(name, data))


def kind_of(value: Any) -> str:
    """The result kind of a value."""
    import sympy as sp
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, sp.MatrixBase):
        return "vector" if value.shape[1] == 1 else "matrix"
    if isinstance(value, (list, tuple)):
        return "list"
    if isinstance(value, (int, float)) or (isinstance(value, sp.Expr) and value.is_number):
        return "number"
    return "scalar"


@dataclass
class RobotPose:
    """A planar robot drawn at one configuration, in numbers: the chain's points P_0 (base), P_1, ..., P_n (end
    effector); joint i (``joints[i-1]``, R or P) sits at P_{i-1}, link i joins P_{i-1} and P_i; ``slides[i-1]`` is
    the unit direction of a prismatic joint (None for a revolute one)."""

    label: str
    points: list[tuple[float, float]]
    joints: list[str]
    slides: list[tuple[float, float] | None]


@dataclass
class Arrow:
    """A vector drawn at a point (a task velocity or force, a direction)."""

    x: float
    y: float
    dx: float
    dy: float
    label: str = ""


@dataclass
class Sketch:
    """A robot sketch panel: poses of the robot, arrows, and paths (curves in the plane)."""

    poses: list[RobotPose]
    arrows: list[Arrow] = field(default_factory=list)
    paths: list[Curve] = field(default_factory=list)
    xlabel: str = "$x$"
    ylabel: str = "$y$"
