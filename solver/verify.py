"""`robosolve verify`: solve each problem and compare its results with the printed (expected) values.

expected:
  where: {I0: "I1 + m1*d1^2"}          # abbreviations of the printed solution, substituted before comparing
  B: {value: "[[I0 + m2*q2^2, ...]]", line: 37}
  T2: {value: "<printed>", line: 211, erratum: "<why>", corrected: "<right value>"}
  tau: {value: "[1.5, -0.2]", line: 90, tol: 1e-3}   # relative tolerance for numbers (abs_tol too)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import sympy as sp

from solver.math.equivalence import CORRECT, INCORRECT, Verdict, equivalent
from solver.solve import all_results, solve_problem
from solver.spec import load_problem
from solver.spec.errors import UserError
from solver.spec.expr import expand_abbreviations
from solver.spec.problem import Problem

ENTRY_FIELDS = {"value", "line", "erratum", "corrected", "tol", "abs_tol", "note", "where"}


@dataclass
class Check:
    name: str
    line: int | None
    verdict: Verdict
    erratum: str | None = None
    printed_differs: bool | None = None


@dataclass
class Report:
    problem_id: str
    file: str
    checks: list[Check] = field(default_factory=list)
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None and all(c.verdict.ok and c.printed_differs is not False for c in self.checks)


def _abbreviations(problem: Problem, path: tuple, names: dict[str, sp.Expr]) -> tuple[dict, dict]:
    """Parse a where: block; each abbreviation may use the ones before it."""
    raw = problem.located.data
    for k in path:
        raw = raw[k]
    names = dict(names)
    subs: dict[sp.Symbol, sp.Expr] = {}
    for key in raw:
        if key in problem.names:
            raise UserError(f"abbreviation '{key}' clashes with a symbol of the problem",
                            problem.located.place(path + (key,)), "choose another name")
        val = problem.parse_at(path + (key,), names)
        sym = sp.Symbol(f"_abbr_{key}")
        names[key] = sym
        subs[sym] = val
    return names, subs


def _to_value(parsed: Any, kind: str) -> Any:
    if kind in ("matrix", "vector") and isinstance(parsed, list):
        return sp.Matrix(parsed)
    if kind == "list" and isinstance(parsed, list):
        return [sp.Matrix(x) if isinstance(x, list) else x for x in parsed]
    return parsed


@dataclass
class Expected:
    """One expected entry, parsed (abbreviations expanded): the printed value and, for an erratum, the fix."""

    key: str
    line: int | None
    printed: Any
    corrected: Any = None
    erratum: str | None = None
    tol: dict[str, float] = field(default_factory=dict)


def parse_expected(problem: Problem) -> list[Expected]:
    """Every entry of ``expected:`` validated and parsed (no solving): what `check` and `verify` share."""
    exp = problem.expected
    names, subs = dict(problem.names), {}
    if "where" in exp:
        names, subs = _abbreviations(problem, ("expected", "where"), names)
    out = []
    for key, entry in exp.items():
        if key == "where":
            continue
        path = ("expected", key)
        if not isinstance(entry, dict):
            entry, vpath = {"value": entry}, path
        else:
            unknown = set(entry) - ENTRY_FIELDS
            if unknown:
                raise UserError(f"unknown field '{sorted(unknown)[0]}' in expected.{key}",
                                problem.located.place(path), f"allowed: {', '.join(sorted(ENTRY_FIELDS))}")
            if "value" not in entry:
                raise UserError(f"expected.{key} has no value:", problem.located.place(path), "add value: <printed>")
            vpath = path + ("value",)
        lnames, lsubs = names, subs
        if "where" in entry:
            lnames, extra = _abbreviations(problem, path + ("where",), names)
            lsubs = {**subs, **extra}
        tol = {}
        if "tol" in entry:
            tol["rel_tol"] = float(entry["tol"])
        if "abs_tol" in entry:
            tol["abs_tol"] = float(entry["abs_tol"])
        item = Expected(key, entry.get("line"), expand_abbreviations(problem.parse_at(vpath, lnames), lsubs), tol=tol)
        if "erratum" in entry:
            if "corrected" not in entry:
                raise UserError(f"expected.{key} has an erratum but no corrected: value",
                                problem.located.place(path), "add corrected: <the right value>")
            item.erratum = str(entry["erratum"])
            item.corrected = expand_abbreviations(problem.parse_at(path + ("corrected",), lnames), lsubs)
        out.append(item)
    return out


def check_problem(problem: Problem) -> Report:
    """Solve ``problem`` and compare every expected value."""
    rep = Report(problem.id, problem.file)
    expected = parse_expected(problem)
    results = all_results(solve_problem(problem))
    for e in expected:
        if e.key not in results:
            raise UserError(f"expected.{e.key}: no result of that name",
                            problem.located.place(("expected", e.key)),
                            f"results of this problem: {', '.join(results)}")
        r = results[e.key]
        printed = _to_value(e.printed, r.kind)
        if e.erratum is not None:
            v = equivalent(r.value, _to_value(e.corrected, r.kind), r.kind, **e.tol)
            pv = equivalent(r.value, printed, r.kind, **e.tol)
            rep.checks.append(Check(e.key, e.line, v, e.erratum, pv.verdict == INCORRECT))
        else:
            rep.checks.append(Check(e.key, e.line, equivalent(r.value, printed, r.kind, **e.tol)))
    return rep


def verify_paths(paths: list[Path]) -> list[Report]:
    """Reports for every spec under ``paths`` (files or directories)."""
    files: list[Path] = []
    for p in paths:
        if p.is_dir():
            files += sorted(p.rglob("*.yaml")) + sorted(p.rglob("*.yml"))
        elif p.exists():
            files.append(p)
        else:
            raise UserError(f"no such file or directory: {p}")
    reports = []
    for f in files:
        try:
            reports.append(check_problem(load_problem(f)))
        except UserError as exc:
            reports.append(Report(f.stem, str(f), error=str(exc)))
    return reports


def describe(rep: Report) -> list[str]:
    """Lines for one problem: a status line, then one line per failing check or erratum."""
    if rep.error:
        return [f"ERROR {rep.problem_id}  {rep.error.splitlines()[0]}"]
    n_ok = sum(c.verdict.ok for c in rep.checks)
    n_err = sum(c.erratum is not None for c in rep.checks)
    status = "ok   " if rep.ok else "FAIL "
    errata = f", {n_err} erratum" + ("s" if n_err != 1 else "") if n_err else ""
    lines = [f"{status} {rep.problem_id}  {n_ok}/{len(rep.checks)} results{errata}"]
    for c in rep.checks:
        where = f" (line {c.line})" if c.line else ""
        if not c.verdict.ok:
            lines.append(f"        {c.name}{where}: {c.verdict.verdict}{': ' + c.verdict.detail if c.verdict.detail else ''}")
        if c.erratum:
            note = "printed value confirmed wrong" if c.printed_differs else "ERRATUM NOT CONFIRMED: printed value matches"
            lines.append(f"        erratum {c.name}{where}: {c.erratum} [{note}]")
    return lines


__all__ = ["check_problem", "parse_expected", "Expected", "verify_paths", "describe", "Report", "Check", "CORRECT"]
