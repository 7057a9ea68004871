"""Reading problems: YAML with positions (yamlpos), the allow-list expression parser (expr), the spec models
(models) and loader (loader), the Problem and Robot objects the solvers see (problem, robot), user errors (errors).

Public entry points: ``load_problem(path)`` and ``load_problem_text(text)`` (imported lazily, so that
``solver.spec.errors`` stays light for the CLI's start-up).
"""
from __future__ import annotations

from typing import Any

__all__ = ["load_problem", "load_problem_text"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from solver.spec import loader
        return getattr(loader, name)
    raise AttributeError(f"module 'solver.spec' has no attribute {name!r}")
