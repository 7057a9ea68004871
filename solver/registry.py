"""Ask kinds: each solver module registers its kind, its options model and its solve function.

A new ask kind = one module in a chapter package (``solver/<chapter>/``) that calls :func:`ask_kind` + one
template per format in ``templates/``; nothing else changes (docs/architecture.md). A command imports only the
modules of the kinds it uses (:func:`get_kind`, :func:`ask_kinds`, found by :func:`kind_modules`); grading, the
schema and the parallel workers import them all (:func:`load_all`).
"""
from __future__ import annotations

import gc
import importlib
import pkgutil
import re
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable, Iterator

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
    validate: Callable[["Problem", BaseModel, "AskContext"], None] | None = None


ASKS: dict[str, AskKind] = {}


def ask_kind(name: str, options: type[BaseModel], summary: str,
             validate: Callable[["Problem", BaseModel, "AskContext"], None] | None = None) -> Callable:
    """Decorator registering ``solve(problem, options, ctx) -> Solution`` for ``kind: name``. ``validate(problem,
    options, ctx)``, optional: the ask's options read and checked as ``solve`` reads them, without solving (no
    dynamic model derived where it can be avoided), raising the UserError ``solve`` would raise; ``robosolve
    check`` runs it for every ask (:func:`solver.solve.validate_problem`)."""

    def wrap(fn: Callable) -> Callable:
        ASKS[name] = AskKind(name, options, fn, summary, validate)
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
_DECLARED = re.compile(r"""@ask_kind\(\s*["']([A-Za-z_][A-Za-z0-9_]*)["']""")


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


@lru_cache(maxsize=1)
def kind_modules() -> dict[str, str]:
    """Every ask kind's name -> the module that registers it (chapters in order, modules by name, kinds in the
    order of their module), found without importing anything when the modules are not imported yet (see
    :func:`_declared_modules`), else read from the registrations."""
    return _registered_modules() if _LOADED else _declared_modules()


def _registered_modules() -> dict[str, str]:
    """:func:`kind_modules` from the registered kinds (every chapter imported: :func:`load_all`)."""
    by_module: dict[str, list[str]] = {}
    for name, kind in ASKS.items():
        by_module.setdefault(kind.solve.__module__, []).append(name)
    out: dict[str, str] = {}
    root = Path(__file__).resolve().parent
    for chapter in CHAPTERS:
        for info in pkgutil.iter_modules([str(root / chapter)]):
            module = f"solver.{chapter}.{info.name}"
            for name in by_module.get(module, []):
                out.setdefault(name, module)
    return out


def _declared_modules() -> dict[str, str]:
    """:func:`kind_modules` by searching the chapter modules' source for ``@ask_kind("name", ...)``
    (tests/test_startup.py checks that this finds exactly what importing them registers). Empty when the source
    cannot be read (then the callers import every chapter, as :func:`load_all`)."""
    out: dict[str, str] = {}
    root = Path(__file__).resolve().parent
    for chapter in CHAPTERS:
        folder = root / chapter
        for info in pkgutil.iter_modules([str(folder)]):
            source = folder / info.name / "__init__.py" if info.ispkg else folder / f"{info.name}.py"
            try:
                text = source.read_text(encoding="utf-8")
            except OSError:
                return {}
            for name in _DECLARED.findall(text):
                out.setdefault(name, f"solver.{chapter}.{info.name}")
    return out


def ask_kinds(names: Iterable[str]) -> dict[str, AskKind] | None:
    """The registered ask kinds of ``names``, importing only their modules (``robosolve check`` and ``solve`` of a
    file load the kinds it uses, not every chapter). None when a name is not a known kind."""
    index = kind_modules()
    out = {}
    for name in names:
        if name not in ASKS:
            module = index.get(name)
            if module is None:
                return None
            importlib.import_module(module)
            if name not in ASKS:
                return None
        out[name] = ASKS[name]
    return out


def get_kind(name: str) -> AskKind:
    """The registered ask kind ``name`` (its module imported on demand; KeyError if none registers it)."""
    found = ask_kinds([name])
    if found is None:
        return load_all()[name]
    return found[name]


@contextmanager
def frozen_imports() -> Iterator[None]:
    """Heavy imports (sympy, the chapters) without the cyclic garbage collector, their objects then frozen
    (``gc.freeze``): importing creates 1.2–1.6·10⁵ long-lived container objects and no garbage, and every later full
    collection would traverse them all (40–60 ms each, one to three per solve) and, in a forked worker, touch
    and copy their memory pages. For the commands' processes, not for a program that imports the library."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
        gc.freeze()


def preload(count: int = 2) -> None:
    """Before forking one worker per file: import the spec reader and every chapter once in the parent, so that
    the ``count`` workers inherit them instead of each importing sympy, numpy and the chapters again."""
    if count > 1:
        with frozen_imports():
            importlib.import_module("solver.spec.loader")
            load_all()
