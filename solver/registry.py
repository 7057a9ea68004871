"""Ask kinds: each solver module registers its kind, its options model and its solve function.

A new ask kind = one module in a chapter package (``solver/<chapter>/``) that calls :func:`ask_kind` + one
template per format in ``templates/``; nothing else changes (docs/architecture.md).
"""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from pydantic import BaseModel

if TYPE_CHECKING:
    from solver.results import Solution
    from solver.spec.problem import AskContext, Problem


@dataclass
class AskKind:
    name: str
    options: type[BaseModel]
    solve: Callable[["Problem", BaseModel, "AskContext"], "Solution"]
    summary: str


ASKS: dict[str, AskKind] = {}


def ask_kind(name: str, options: type[BaseModel], summary: str) -> Callable:
    """Decorator registering ``solve(problem, options, ctx) -> Solution`` for ``kind: name``."""

    def wrap(fn: Callable) -> Callable:
        ASKS[name] = AskKind(name, options, fn, summary)
        return fn

    return wrap


@dataclass
class PropertyVerdict:
    """What a property check says of an answer: ``fraction`` of the points, and why."""

    correct: bool
    fraction: float
    feedback: list[str]
    final: bool = True  # False: also compare with the reference (to name wrong entries, give partial credit)


PropertyCheck = Callable[..., "PropertyVerdict | None"]
PROPERTY_CHECKS: dict[str, PropertyCheck] = {}


def property_check(*names: str) -> Callable:
    """Decorator registering ``check(problem, results, name, value, other, options) -> PropertyVerdict | None`` for
    results that are right but not unique (S, U, (Y, a), ...). ``value`` is the parsed answer, ``other(n)`` the
    parsed answer of another item (or None), ``options`` the item's grading options. None: not applicable, the
    grader compares with the reference instead."""

    def wrap(fn: Callable) -> Callable:
        for n in names:
            PROPERTY_CHECKS[n] = fn
        return fn

    return wrap


CHAPTERS = ("dynamics", "kinematics", "control", "interaction", "planning")
_LOADED = False


def load_all() -> dict[str, AskKind]:
    """Import every module of the chapter packages once, so that all ask kinds are registered."""
    global _LOADED
    if not _LOADED:
        for chapter in CHAPTERS:
            package = importlib.import_module(f"solver.{chapter}")
            for info in pkgutil.iter_modules(package.__path__):
                importlib.import_module(f"solver.{chapter}.{info.name}")
        _LOADED = True
    return ASKS


def preload(count: int = 2) -> None:
    """Before forking one worker per file: import the spec reader and every chapter once in the parent, so that
    the ``count`` workers inherit them instead of each importing sympy, numpy and the chapters again."""
    if count > 1:
        importlib.import_module("solver.spec.loader")
        load_all()
