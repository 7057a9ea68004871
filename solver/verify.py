"""`robosolve verify`: solve each problem and compare its results with the printed (expected) values.

expected:
  where: {I0: "I1 + m1*d1^2"}          # abbreviations of the printed solution, substituted before comparing
  B: {value: "[[I0 + m2*q2^2, ...]]", line: 37}
  T2: {value: "<printed>", line: 211, erratum: "<why>", corrected: "<right value>"}
  tau: {value: "[1.5, -0.2]", line: 90, tol: 1e-3}   # relative tolerance for numbers (abs_tol too)
  g:                                   # a result printed twice, in two forms: a list of entries
    - {value: "[...]", line: 40}
    - {value: "[...]", line: 52}

Values are parsed after solving, with the names the solvers create (gains kp1, desired trajectories dqd1, ...).
Every entry is checked and every failure reported; an entry that names no result or cannot be read fails alone.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import sympy as sp

from solver.math.equivalence import CORRECT, INCORRECT, Verdict, equivalent
from solver.registry import preload
from solver.sandbox import Limits, Outcome, cores, run_many
from solver.solve import all_results, solve_problem
from solver.spec import load_problem
from solver.spec.errors import UserError
from solver.spec.expr import expand_abbreviations
from solver.spec.problem import Problem

ENTRY_FIELDS = {"value", "line", "erratum", "corrected", "tol", "abs_tol", "note", "where"}


ERROR = "error"  # an expected entry that could not be checked (no such result, unreadable value)


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
    if not isinstance(raw, dict):
        raise UserError(f"{'.'.join(map(str, path))} must be a mapping of abbreviations (name: value)",
                        problem.located.place(path), "write where: {I0: I1 + m1*d1^2}")
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


@dataclass
class Entry:
    """One printed result as written under ``expected:`` (a result printed twice is a list of two entries)."""

    key: str
    path: tuple
    raw: dict[str, Any]

    @property
    def line(self) -> int | None:
        line = self.raw.get("line")
        return line if isinstance(line, int) and not isinstance(line, bool) else None


def expected_entries(problem: Problem) -> tuple[list[Entry], list[UserError]]:
    """The entries of ``expected:`` with a valid structure, and an error for each entry without one."""
    entries, errors = [], []
    for key, value in problem.expected.items():
        if key == "where":
            continue
        items = list(enumerate(value)) if isinstance(value, list) and value and all(
            isinstance(v, dict) for v in value) else [(None, value)]
        for k, entry in items:
            path = ("expected", key) if k is None else ("expected", key, k)
            if not isinstance(entry, dict):
                entries.append(Entry(key, path, {"value": entry}))
                continue
            unknown = sorted(set(entry) - ENTRY_FIELDS)
            if unknown:
                errors.append(UserError(f"unknown field '{unknown[0]}' in expected.{key}",
                                        problem.located.place(path + (unknown[0],)),
                                        f"allowed: {', '.join(sorted(ENTRY_FIELDS))}"))
            elif "value" not in entry:
                errors.append(UserError(f"expected.{key} has no value:", problem.located.place(path),
                                        "add value: <printed>"))
            elif "erratum" in entry and "corrected" not in entry:
                errors.append(UserError(f"expected.{key} has an erratum but no corrected: value",
                                        problem.located.place(path), "add corrected: <the right value>"))
            else:
                entries.append(Entry(key, path, entry))
    return entries, errors


def _tolerance(problem: Problem, entry: Entry) -> dict[str, float]:
    tol = {}
    for field_, key in (("tol", "rel_tol"), ("abs_tol", "abs_tol")):
        if field_ in entry.raw:
            v = entry.raw[field_]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < float("inf"):
                raise UserError(f"expected.{entry.key}.{field_} must be a number >= 0, got {v!r}",
                                problem.located.place(entry.path + (field_,)), f"write e.g. {field_}: 1e-3")
            tol[key] = float(v)
    return tol


def parse_entry(problem: Problem, entry: Entry, names: dict[str, sp.Expr], subs: dict) -> Expected:
    """Parse one entry with ``names`` (the problem's, the solvers' and the abbreviations'); UserError if it cannot."""
    lnames, lsubs = names, subs
    if "where" in entry.raw:
        lnames, extra = _abbreviations(problem, entry.path + ("where",), names)
        lsubs = {**subs, **extra}
    node: Any = problem.located.data
    for k in entry.path:
        node = node[k]
    vpath = entry.path + ("value",) if isinstance(node, dict) else entry.path
    item = Expected(entry.key, entry.line, expand_abbreviations(problem.parse_at(vpath, lnames), lsubs),
                    tol=_tolerance(problem, entry))
    if "erratum" in entry.raw:
        item.erratum = str(entry.raw["erratum"])
        item.corrected = expand_abbreviations(problem.parse_at(entry.path + ("corrected",), lnames), lsubs)
    return item


def _global_names(problem: Problem) -> tuple[dict, dict]:
    exp = problem.expected
    if "where" in exp:
        return _abbreviations(problem, ("expected", "where"), dict(problem.names))
    return dict(problem.names), {}


def parse_expected(problem: Problem) -> list[Expected]:
    """Every entry of ``expected:`` parsed; raises the first UserError. Call it after solving, so that the names
    the solvers create (gains, desired trajectories, estimates) are known."""
    entries, errors = expected_entries(problem)
    if errors:
        raise errors[0]
    names, subs = _global_names(problem)
    return [parse_entry(problem, e, names, subs) for e in entries]


def _error(entry_name: str, line: int | None, exc: UserError) -> Check:
    return Check(entry_name, line, Verdict(ERROR, str(exc)))


def _shadowed(solutions: list) -> dict[str, list[int]]:
    """Result names produced by two or more asks with different values (ask numbers from 1): the later one wins
    in ``all_results``, so an expected entry of that name would silently check only the last."""
    seen: dict[str, tuple[int, object]] = {}
    out: dict[str, list[int]] = {}
    for i, sol in enumerate(solutions, 1):
        for name, res in sol.results.items():
            if name in seen:
                first, value = seen[name]
                try:
                    same = bool(value == res.value)
                except Exception:  # noqa: BLE001 - values that cannot be compared count as different
                    same = False
                if not same:
                    out.setdefault(name, [first]).append(i)
            else:
                seen[name] = (i, res.value)
    return out


def check_problem(problem: Problem, compare: bool = True, jobs: int = 1) -> Report:
    """Solve ``problem`` (its asks shared by ``jobs`` processes) and compare every expected value; every entry is
    checked and every failure reported (a missing result or an unreadable value fails that entry only).
    ``compare=False``: only find the entries that cannot be checked (what ``robosolve check`` reports)."""
    rep = Report(problem.id, problem.file)
    entries, errors = expected_entries(problem)
    solutions = solve_problem(problem, jobs=jobs)
    results = all_results(solutions)
    shadowed = _shadowed(solutions)
    rep.checks += [_error(str(e.place), e.place.line if e.place else None, e) for e in errors]
    names, subs = _global_names(problem)
    for entry in entries:
        if entry.key not in results:
            rep.checks.append(_error(entry.key, entry.line, UserError(
                f"expected.{entry.key}: no result of that name", problem.located.place(entry.path),
                f"results of this problem: {', '.join(results)}")))
            continue
        if entry.key in shadowed:
            rep.checks.append(_error(entry.key, entry.line, UserError(
                f"expected.{entry.key}: asks {' and '.join(map(str, shadowed[entry.key]))} both produce a result "
                f"'{entry.key}' with different values; only the last one would be compared",
                problem.located.place(entry.path), "give one of these asks `suffix:` (or split the problem)")))
            continue
        try:
            e = parse_entry(problem, entry, names, subs)
        except UserError as exc:
            rep.checks.append(_error(entry.key, entry.line, exc))
            continue
        if not compare:
            continue
        r = results[e.key]
        try:
            printed = _to_value(e.printed, r.kind)
            if e.erratum is not None:
                v = equivalent(r.value, _to_value(e.corrected, r.kind), r.kind, **e.tol)
                pv = equivalent(r.value, printed, r.kind, **e.tol)
                rep.checks.append(Check(e.key, e.line, v, e.erratum, pv.verdict == INCORRECT))
            else:
                rep.checks.append(Check(e.key, e.line, equivalent(r.value, printed, r.kind, **e.tol)))
        except Exception as exc:  # noqa: BLE001 - a value of another shape or kind: this entry fails, not the file
            rep.checks.append(Check(e.key, e.line, Verdict(ERROR, f"cannot compare with the {r.kind} result "
                                                                  f"{e.key}: {exc.__class__.__name__}: {exc}"[:300])))
    return rep


def spec_files(paths: list[Path]) -> list[Path]:
    """The spec files under ``paths`` (files, or directories searched for *.yaml / *.yml), sorted."""
    files: list[Path] = []
    for p in paths:
        if p.is_dir():
            files += sorted(p.rglob("*.yaml")) + sorted(p.rglob("*.yml"))
        elif p.exists():
            files.append(p)
        else:
            raise UserError(f"no such file or directory: {p}")
    return files


def _verify_file(path: Path, ask_jobs: int = 1) -> Report:
    try:
        return check_problem(load_problem(path), jobs=ask_jobs)
    except UserError as exc:
        return Report(path.stem, str(path), error=str(exc))


def verify_paths(paths: list[Path], jobs: int = 0, limits: Limits | None = None,
                 on_done: Callable[[Report], None] | None = None) -> list[Report]:
    """Reports for every spec under ``paths``, each file solved in a bounded worker process (``jobs`` at a time,
    0: one per core; fewer files than that: the asks of each shared by the processes left); a file that exceeds
    its limits gets a report with the reason."""
    files = spec_files(paths)
    limits = limits or Limits()
    jobs = jobs or cores()
    ask_jobs = max(1, jobs // max(1, len(files)))

    def report(i: int, out: Outcome) -> Report:
        return out.value if out.ok else Report(files[i].stem, str(files[i]), error=out.message)

    preload(len(files))
    outcomes = run_many(lambda f: _verify_file(f, ask_jobs), files, jobs, limits,
                        (lambda i, out: on_done(report(i, out))) if on_done else None)
    return [report(i, out) for i, out in enumerate(outcomes)]


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


__all__ = ["check_problem", "parse_expected", "Expected", "verify_paths", "describe", "Report", "Check", "CORRECT",
           "spec_files", "expected_entries", "parse_entry"]
