"""Students' submissions: YAML or JSON files of answers, read as untrusted input.

    student: Alice Rossi            # optional (default: the file name)
    where: {h: m2*l1*d2}            # optional abbreviations, each may use the ones before it
    B: "[[a1 + 2*h*cos(q2), a2 + h*cos(q2)], [a2 + h*cos(q2), a2]]"
    g: "$\\begin{pmatrix} ... \\end{pmatrix}$"   # LaTeX in $...$ is accepted too

Values are plain math (the syntax of :mod:`solver.spec.expr`) or LaTeX (:mod:`solver.grading.latex_in`), numbers, or YAML
lists of them. Nothing is evaluated: every value goes through the allow-list parsers.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import sympy as sp

from solver.grading.latex_in import looks_like_latex, parse_latex
from solver.spec.errors import ExprError, UserError
from solver.spec.expr import MAX_LENGTH, MAX_LIST, expand_abbreviations, parse
from solver.spec.problem import Problem
from solver.spec.yamlpos import load_text, read_text_bounded

MAX_FILE_BYTES = 256_000  # an answer sheet is a few kB; parsing YAML costs about 50 s per MB
RESERVED = {"student", "where", "id", "name"}


@dataclass
class Submission:
    student: str
    file: str                                            # the name shown (relative to the class folder)
    answers: dict[str, Any]                              # raw values by result name
    where: dict[str, Any] = field(default_factory=dict)  # raw abbreviations
    error: str | None = None                             # the whole file could not be read


def clean_name(text: str, limit: int = 120) -> str:
    """A student's name as one line of plain text: control characters and line breaks become spaces."""
    s = "".join(ch if ch.isprintable() else " " for ch in str(text))
    return " ".join(s.split())[:limit]


def load_submission(path: Path, label: str | None = None) -> Submission:
    """Read a submission file (bounded: a regular file of at most MAX_FILE_BYTES); a broken file gives a
    Submission with ``error`` set, never an exception. ``label`` is the name shown in feedback (default: the path);
    messages never carry the grader's own paths."""
    label = label or str(path)
    stem = clean_name(Path(label).stem) or "student"
    try:
        text = read_text_bounded(path, MAX_FILE_BYTES, label)
        data = load_text(text, label).data
    except UserError as exc:
        return Submission(stem, label, {}, error=str(exc))
    except RecursionError:
        return Submission(stem, label, {}, error="file nested too deeply")
    if data is None:
        data = {}
    if not isinstance(data, dict):
        return Submission(stem, label, {}, error="a submission is a mapping of answers (name: value)")
    student = data.get("student") or data.get("name") or data.get("id")
    where = data.get("where") or {}
    if not isinstance(where, dict):
        return Submission(stem, label, {}, error="where: must be a mapping of abbreviations (name: value)")
    answers = {str(k): v for k, v in data.items() if k not in RESERVED}
    name = clean_name(student) if isinstance(student, (str, int, float)) and not isinstance(student, bool) else ""
    return Submission(name or stem, label, answers, where)


def _check_size(value: Any, depth: int = 0) -> None:
    if depth > 4:
        raise ExprError("nested too deeply for a matrix", "", 0, "matrices are lists of rows")
    if isinstance(value, list):
        if len(value) > MAX_LIST:
            raise ExprError(f"list too long (limit {MAX_LIST})", "", 0)
        for v in value:
            _check_size(v, depth + 1)
    elif isinstance(value, str) and len(value) > MAX_LENGTH:
        raise ExprError(f"answer too long ({len(value)} characters, limit {MAX_LENGTH})", "", 0,
                        "use abbreviations (where:)")


def parse_answer(value: Any, names: Mapping[str, sp.Expr], latex_names: Mapping[str, str]) -> Any:
    """One answer: a sympy expression or nested lists of them. Raises ExprError (invalid answer)."""
    _check_size(value)
    if isinstance(value, list):
        return [parse_answer(v, names, latex_names) for v in value]
    if isinstance(value, bool) or value is None:
        raise ExprError("empty answer" if value is None else "a boolean is not an expression", str(value), 0,
                        "write the value, e.g. m2*l1*cos(q2)")
    if isinstance(value, (int, float)):
        return parse(value, names)
    if isinstance(value, dict):
        raise ExprError("a mapping is not an answer", "", 0, "write a value, a list [a, b] or a matrix [[a, b], [c, d]]")
    text = str(value).strip()
    if not text:
        raise ExprError("empty answer", "", 0, "write the value, e.g. m2*l1*cos(q2)")
    if looks_like_latex(text):
        return parse_latex(text, names, latex_names)
    return parse(text, names)


def answer_names(problem: Problem, submission: Submission) -> tuple[dict[str, sp.Expr], dict[sp.Symbol, sp.Expr],
                                                                     list[str]]:
    """Names usable in answers (problem's + the submission's abbreviations), the substitution that expands the
    abbreviations, and messages about abbreviations that could not be read."""
    names = dict(problem.names)
    subs: dict[sp.Symbol, sp.Expr] = {}
    problems = []
    latex = latex_spellings(problem)
    for key, raw in submission.where.items():
        key = str(key)
        if key in names:
            problems.append(f"abbreviation '{key}' ignored: it is already a symbol of the problem")
            continue
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", key):
            problems.append(f"abbreviation '{key}' ignored: use a plain name (letters, digits, _)")
            continue
        try:
            val = parse_answer(raw, names, latex)
        except ExprError as exc:
            problems.append(f"abbreviation '{key}' could not be read: {exc.message}")
            continue
        if isinstance(val, list):
            problems.append(f"abbreviation '{key}' ignored: an abbreviation is a scalar")
            continue
        sym = sp.Symbol(f"_abbr_{key}")
        try:  # kept unexpanded (expanded per answer, where used); too large once expanded: refused now
            expand_abbreviations(sp.Symbol("_probe") + sym, {**subs, sym: val}, check_only=True)
        except ExprError as exc:
            problems.append(f"abbreviation '{key}' ignored: {exc.message}")
            continue
        names[key] = sym
        subs[sym] = val
    return names, subs, problems


def latex_spellings(problem: Problem) -> dict[str, str]:
    """LaTeX spelling -> plain name, from the problem's symbol table."""
    by_symbol = {v: k for k, v in problem.names.items() if isinstance(v, sp.Symbol)}
    return {tex: by_symbol[s] for s, tex in problem.latex_names.items() if s in by_symbol}
