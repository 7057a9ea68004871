"""Rendering: Jinja2 templates (Markdown, LaTeX) and JSON. Solvers never format text; templates do."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import jinja2
import sympy as sp

from .problem import Problem
from .results import Result, Solution

FORMATS = ("md", "tex", "json")


def templates_dir() -> Path:
    """The shipped templates: inside the installed package, else the repository's top-level templates/."""
    here = Path(__file__).resolve().parent
    for cand in (here / "templates", here.parent / "templates"):
        if cand.is_dir():
            return cand
    raise FileNotFoundError("robosolve templates not found")


class Latex:
    """sympy -> LaTeX with the problem's symbol names (q̇ as \\dot q, m2 as m_{2}, ...)."""

    def __init__(self, names: dict[sp.Symbol, str]) -> None:
        self.names = names

    def __call__(self, value: Any) -> str:
        if isinstance(value, bool):
            return "\\text{true}" if value else "\\text{false}"
        if isinstance(value, (list, tuple)):
            return ",\\quad ".join(self(v) for v in value)
        if isinstance(value, sp.MatrixBase):
            body = " \\\\ ".join(" & ".join(self(value[i, j]) for j in range(value.shape[1]))
                                 for i in range(value.shape[0]))
            return f"\\begin{{bmatrix}} {body} \\end{{bmatrix}}"
        if isinstance(value, (int, float)):
            value = sp.sympify(value)
        if isinstance(value, sp.Basic):
            if value.is_Float:
                return number(value)
            if value.atoms(sp.Float):
                value = value.xreplace({f: sp.Float(f, 4) for f in value.atoms(sp.Float)})
            return sp.latex(value, symbol_names=self.names, fold_short_frac=False, mul_symbol=None)
        return str(value)


def number(value: Any, digits: int = 4) -> str:
    """A number with ``digits`` significant figures."""
    try:
        x = float(sp.N(value))
    except (TypeError, ValueError):
        return str(value)
    return f"{x:.{digits}g}"


def _env(fmt: str, custom: Path | None, names: dict[sp.Symbol, str]) -> jinja2.Environment:
    dirs = [str(p / fmt) for p in ([custom] if custom else []) + [templates_dir()]]
    opts: dict[str, Any] = dict(loader=jinja2.FileSystemLoader(dirs), undefined=jinja2.StrictUndefined,
                                trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True)
    if fmt == "tex":
        opts.update(block_start_string="<%", block_end_string="%>", variable_start_string="<<",
                    variable_end_string=">>", comment_start_string="<#", comment_end_string="#>")
    env = jinja2.Environment(**opts)
    env.filters["tex"] = Latex(names)
    env.filters["num"] = number
    env.globals["sp"] = sp
    return env


def render(problem: Problem, solutions: list[Solution], fmt: str, fragment: bool = False,
           template_dir: Path | None = None, assets: dict[str, str] | None = None) -> str:
    """The report of ``problem`` in ``fmt`` (md | tex | json)."""
    if fmt == "json":
        return json.dumps(to_json(problem, solutions), indent=2, ensure_ascii=False) + "\n"
    env = _env(fmt, template_dir, problem.latex_names)
    page = env.get_template(f"page.{fmt}.j2")
    return page.render(problem=problem, solutions=solutions, fragment=fragment, assets=assets or {},
                       symbols=[(problem.symbols[k], v) for k, v in problem.meanings.items()])


# ------------------------------------------------------------------------------------------------- JSON
def _expr_str(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_expr_str(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_expr_str(k)}: {_expr_str(v)}" for k, v in value.items()) + "}"
    return str(value)


def _numeric(value: Any) -> Any:
    """Numbers (nested lists for matrices) where the value is fully numeric, else None."""
    try:
        if isinstance(value, bool):
            return value
        if isinstance(value, sp.MatrixBase):
            rows = [[_numeric(value[i, j]) for j in range(value.shape[1])] for i in range(value.shape[0])]
            if any(x is None for r in rows for x in r):
                return None
            return [r[0] for r in rows] if value.shape[1] == 1 else rows
        if isinstance(value, (list, tuple)):
            out = [_numeric(v) for v in value]
            return None if any(x is None for x in out) else out
        if isinstance(value, (int, float)):
            return value
        if isinstance(value, sp.Basic) and value.is_number:
            c = complex(sp.N(value))
            return c.real if abs(c.imag) < 1e-12 else [c.real, c.imag]
    except (TypeError, ValueError):
        return None
    return None


def result_json(r: Result, latex: Latex) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": r.kind, "expr": _expr_str(r.value), "latex": latex(r.value)}
    num = _numeric(r.value)
    if num is not None:
        out["value"] = num
    return out


def _plain(obj: Any, latex: Latex) -> Any:
    if isinstance(obj, sp.Basic) or isinstance(obj, sp.MatrixBase):
        return {"expr": str(obj), "latex": latex(obj)}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _plain(getattr(obj, f.name), latex) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): _plain(v, latex) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v, latex) for v in obj]
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return str(obj)


def to_json(problem: Problem, solutions: list[Solution]) -> dict[str, Any]:
    """{"id", "title", "results": {NAME: {kind, expr, latex, value?}}, "steps": [...]}."""
    latex = Latex(problem.latex_names)
    results: dict[str, Any] = {}
    steps: list[Any] = []
    for sol in solutions:
        for name, r in sol.results.items():
            results[name] = result_json(r, latex)
        for st in sol.steps:
            data = {k: v for k, v in st.data.items() if k not in ("robot",)}
            steps.append({"ask": sol.kind, "step": st.name, "data": _plain(data, latex)})
    return {"id": problem.id, "title": problem.title, "results": results, "steps": steps}
