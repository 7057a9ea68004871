"""Grading students' answers against a problem's reference solution.

Each item (a result name: B, c, g, S, christoffel, equilibria, ...) gets a verdict

    correct | incorrect | undecided (left for manual review, never guessed) | invalid (unreadable) | missing

and a score. Matrices and vectors are compared entry by entry (partial credit = share of correct entries, the
wrong entries named); answers that are right but not unique are checked by property:

    S             S q̇ ≡ c, and Ḃ - 2S skew-symmetric when the item requires it
    U             equal up to an additive constant: ∂(U - U_ref)/∂q ≡ 0
    equilibria    the same set of configurations (any order, angles mod 2π)

Wrong answers are diagnosed: sign flipped, factor 2 or ½, transposed matrix, one term of the correct answer
missing, degrees for radians, the printed solution's known erratum.
"""
from __future__ import annotations

import math
import signal
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from typing import Any, Iterator

import sympy as sp

from solver.grading.options import GradingSpec, ItemSpec, grading_spec
from solver.grading.submission import Submission, answer_names, latex_spellings, parse_answer
from solver.math.equivalence import CORRECT, INCORRECT, UNDECIDED, Verdict, scalar_equiv, set_equiv
from solver.math.simplify import tidy
from solver.registry import PROPERTY_CHECKS, load_all
from solver.results import Result
from solver.solve import all_results, solve_problem
from solver.spec.errors import ExprError, UserError
from solver.spec.expr import expand_abbreviations, shape_of
from solver.spec.problem import Problem

INVALID, MISSING = "invalid", "missing"
_BOOLS = {"true": True, "yes": True, "false": False, "no": False}


@dataclass
class ItemResult:
    name: str
    verdict: str
    score: float
    max_score: float
    feedback: list[str] = field(default_factory=list)
    read_as: str = ""


@dataclass
class Report:
    student: str
    file: str
    problem: str
    items: list[ItemResult]
    notes: list[str] = field(default_factory=list)

    @property
    def total(self) -> float:
        return round(sum(i.score for i in self.items), 4)

    @property
    def max_total(self) -> float:
        return round(sum(i.max_score for i in self.items), 4)

    def to_dict(self) -> dict[str, Any]:
        return {"student": self.student, "file": self.file, "problem": self.problem, "total": self.total,
                "max": self.max_total, "items": [asdict(i) for i in self.items], "notes": self.notes}


@dataclass
class Reference:
    """A problem solved once, with its grading options: what every submission is compared with."""

    problem: Problem
    results: dict[str, Result]
    spec: GradingSpec
    items: dict[str, ItemSpec]
    errata: dict[str, tuple[Any, str]]  # item -> (printed wrong value, why)


def prepare(problem: Problem) -> Reference:
    """Solve ``problem`` once and fix the items to grade."""
    from solver.verify import parse_expected
    spec = grading_spec(problem)
    load_all()  # every solver module registers its ask kinds and property checks
    results = all_results(solve_problem(problem))
    expected = parse_expected(problem)
    if spec.items is not None:
        items = dict(spec.items)
    else:
        items = {e.key: ItemSpec() for e in expected if e.key in results}
        if not items:  # nothing printed: every main result
            items = {k: ItemSpec() for k in ("B", "c", "g", "S", "equilibria") if k in results}
    for name in items:
        if name not in results:
            raise UserError(f"grading item '{name}' is not a result of this problem",
                            problem.located.place(("grading", "items", name)),
                            "results: " + ", ".join(sorted(results)))
    errata = {e.key: (e.printed, e.erratum) for e in expected if e.erratum}
    return Reference(problem, results, spec, items, errata)


# ------------------------------------------------------------------------------------------ time limit
class ItemTimeout(Exception):
    pass


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise ItemTimeout after ``seconds`` (POSIX main thread; elsewhere no limit)."""
    try:
        old = signal.signal(signal.SIGALRM, _alarm)
    except (ValueError, AttributeError):  # not the main thread / no SIGALRM
        yield
        return
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _alarm(signum: int, frame: Any) -> None:
    raise ItemTimeout()


# ------------------------------------------------------------------------------------------ grading
def grade(ref: Reference, sub: Submission) -> Report:
    """Grade one submission (never raises for anything in the submission)."""
    report = Report(sub.student, sub.file, ref.problem.id, [])
    if sub.error:
        report.notes.append(f"submission not read: {sub.error}")
        report.items = [ItemResult(n, INVALID, 0.0, it.points, ["the submission file could not be read (see notes)"])
                        for n, it in ref.items.items()]
        return report
    names, subs, problems = answer_names(ref.problem, sub)
    report.notes += problems
    extra = sorted(set(sub.answers) - set(ref.items))
    if extra:
        report.notes.append("not graded (not items of this problem): " + ", ".join(extra))
    latex = latex_spellings(ref.problem)
    for name, item in ref.items.items():
        try:
            with time_limit(ref.spec.time_limit):
                res = grade_item(ref, name, item, sub.answers.get(name), names, subs, latex, sub.answers)
        except ItemTimeout:
            res = ItemResult(name, UNDECIDED, 0.0, item.points,
                             [f"not decided within {ref.spec.time_limit:g} s: left for manual review"])
        except RecursionError:
            res = ItemResult(name, INVALID, 0.0, item.points, ["answer nested too deeply"])
        except Exception as exc:  # noqa: BLE001 - a sympy failure on an odd answer: a human decides
            res = ItemResult(name, UNDECIDED, 0.0, item.points,
                             [f"could not be checked automatically ({exc.__class__.__name__}): manual review"])
        report.items.append(res)
    return report


def grade_item(ref: Reference, name: str, item: ItemSpec, raw: Any, names: dict, subs: dict,
               latex: dict, answers: dict[str, Any] | None = None) -> ItemResult:
    out = ItemResult(name, MISSING, 0.0, item.points)

    def partner(other: str) -> Any:
        """Another item's answer, parsed (property checks of pairs such as (Y, a)); None if absent/unreadable."""
        raw_other = (answers or {}).get(other)
        if raw_other in (None, ""):
            return None
        try:
            return expand_abbreviations(parse_answer(raw_other, names, latex), subs)
        except ExprError:
            return None

    if raw is None or (isinstance(raw, str) and not raw.strip()):
        out.feedback.append("no answer given")
        return out
    r = ref.results[name]
    if r.kind == "bool" and (isinstance(raw, bool) or str(raw).strip().lower() in _BOOLS):
        raw = int(raw if isinstance(raw, bool) else _BOOLS[str(raw).strip().lower()])
    try:
        value = parse_answer(raw, names, latex)
    except ExprError as exc:
        out.verdict = INVALID
        msg = exc.message
        if exc.col and exc.text and len(exc.text) <= 2000:
            before = exc.text[max(0, exc.col - 25):exc.col - 1]
            msg += f" (column {exc.col}: ...{before}⟨here⟩{exc.text[exc.col - 1:exc.col + 9]})"
        out.feedback.append(f"could not read the answer: {msg}" + (f"; {exc.hint}" if exc.hint else ""))
        return out
    value = expand_abbreviations(value, subs)
    out.read_as = _show(value)
    check = PROPERTY_CHECKS.get(name) if item.accept == "property" else None
    pv = check(ref.problem, ref.results, name, value, partner, item) if check else None
    if pv is not None:
        out.verdict = CORRECT if pv.correct else INCORRECT
        out.score = round(item.points * (pv.fraction if (pv.correct or item.partial) else 0.0), 4)
        out.feedback += pv.feedback
        if pv.final:
            return out
        out.feedback.append("compared with the reference solution:")  # wrong by property: name the entries
    judge = {"matrix": _judge_matrix, "vector": _judge_matrix, "list": _judge_list, "set": _judge_set,
             "number": _judge_number, "bool": _judge_bool}.get(r.kind, _judge_scalar)
    judge(ref, name, item, r, value, out)
    out.score = round(out.score, 4)
    return out


def _show(value: Any) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return str(value)


def _credit(out: ItemResult, item: ItemSpec, good: int, total: int) -> None:
    if total and good == total:
        out.verdict, out.score = CORRECT, item.points
    else:
        out.verdict = INCORRECT
        out.score = item.points * good / total if (item.partial and total) else 0.0


# -- scalars -----------------------------------------------------------------------------------------------
def _judge_scalar(ref: Reference, name: str, item: ItemSpec, r: Result, value: Any, out: ItemResult) -> None:
    if isinstance(value, list):
        out.verdict = INCORRECT
        out.feedback.append(f"a scalar is expected, got a list of shape {shape_of(value)}")
        return
    v = scalar_equiv(value, r.value)
    _finish_scalar(ref, name, item, r.value, value, v, out)


def _finish_scalar(ref: Reference, name: str, item: ItemSpec, want: Any, got: Any, v: Verdict,
                   out: ItemResult) -> None:
    if v.verdict == CORRECT:
        out.verdict, out.score = CORRECT, item.points
    elif v.verdict == UNDECIDED:
        out.verdict = UNDECIDED
        out.feedback.append("equivalence could not be decided automatically: left for manual review")
    else:
        out.verdict = INCORRECT
        out.feedback += diagnose(got, want, ref.errata.get(name))


def diagnose(got: Any, want: Any, erratum: tuple[Any, str] | None = None) -> list[str]:
    """Names the common mistake behind a wrong answer, if any."""
    notes = []
    if erratum is not None and _same(got, erratum[0]):
        return [f"this is the value printed in the official solution, which is wrong ({erratum[1]})"]
    if isinstance(got, sp.MatrixBase) or isinstance(want, sp.MatrixBase):
        g, w = sp.Matrix(got), sp.Matrix(want)
        if g.shape == w.T.shape and g.shape != w.shape:
            return notes
        if g.shape == w.shape and w.shape[0] == w.shape[1] and _same(g, w.T):
            return ["the matrix is transposed"]
        return notes
    for factor, words in ((-1, "sign flipped"), (2, "twice the correct value (a factor 2 too many)"),
                          (sp.Rational(1, 2), "half the correct value (a factor 1/2 missing or extra)")):
        if _same(got, factor * want):
            return [words]
    if isinstance(want, sp.Expr) and want.is_number and isinstance(got, sp.Expr) and got.is_number and want != 0:
        ratio = float(got / want)
        if abs(ratio - 180 / math.pi) < 1e-3 * 180 / math.pi or abs(ratio - math.pi / 180) < 1e-3 * math.pi / 180:
            return ["degrees and radians mixed up"]
    terms = sp.Add.make_args(tidy(want)) if isinstance(want, sp.Expr) and want.is_Add else ()
    if 1 < len(terms) <= 12:
        for t in terms:
            if _same(got, want - t):
                return [f"a term is missing: {t}"]
            if _same(got, want + t):
                return [f"a term is counted twice: {t}"]
    return notes


def entry_equiv(got: sp.Expr, want: sp.Expr, item: ItemSpec) -> Verdict:
    """One entry: numbers within the item's tolerance (or significant figures), expressions exactly."""
    if getattr(want, "is_number", False) and getattr(got, "is_number", False) and not want.is_Integer:
        try:
            g, w = float(sp.N(got)), float(sp.N(want))
        except (TypeError, ValueError):
            return scalar_equiv(got, want)
        if item.sigfigs:
            return Verdict(CORRECT if _round_sig(g, item.sigfigs) == _round_sig(w, item.sigfigs) else INCORRECT)
        tol = item.rel_tol if item.rel_tol is not None else 1e-3
        return scalar_equiv(got, want, rel_tol=tol, abs_tol=item.abs_tol)
    return scalar_equiv(got, want)


def _same(a: Any, b: Any) -> bool:
    try:
        if isinstance(a, sp.MatrixBase) or isinstance(b, sp.MatrixBase):
            a, b = sp.Matrix(a), sp.Matrix(b)
            return a.shape == b.shape and all(scalar_equiv(x, y).ok for x, y in zip(a, b))
        if isinstance(a, list) or isinstance(b, list):
            return False
        if getattr(a, "is_number", False) and getattr(b, "is_number", False):  # numbers: 1e-3 relative
            return scalar_equiv(a, b, rel_tol=1e-3, abs_tol=1e-15).ok
        return scalar_equiv(a, b).ok
    except (TypeError, ValueError, sp.ShapeError):
        return False


# -- matrices and vectors -----------------------------------------------------------------------------------
def _as_matrix(value: Any, want: sp.Matrix) -> sp.Matrix | None:
    shape = shape_of(value)
    if shape == ():
        return sp.Matrix([[value]]) if want.shape == (1, 1) else None
    if len(shape) == 1:
        m = sp.Matrix(value)
    elif len(shape) == 2 and shape[1] > 0:
        m = sp.Matrix(value)
    else:
        return None
    if want.shape[1] == 1 and m.shape == (1, want.shape[0]):
        m = m.T  # a row written for a column vector
    return m


def _judge_matrix(ref: Reference, name: str, item: ItemSpec, r: Result, value: Any, out: ItemResult) -> None:
    want: sp.Matrix = r.value
    got = _as_matrix(value, want)
    if got is None or got.shape != want.shape:
        shape = "x".join(str(s) for s in (got.shape if got is not None else shape_of(value))) or "scalar"
        out.verdict = INCORRECT
        out.feedback.append(f"wrong shape: {shape}, expected {want.shape[0]}x{want.shape[1]}")
        return
    wrong, undecided, good = [], [], 0
    for i in range(want.shape[0]):
        for j in range(want.shape[1]):
            v = entry_equiv(got[i, j], want[i, j], item)
            if v.verdict == CORRECT:
                good += 1
            elif v.verdict == UNDECIDED:
                undecided.append((i, j))
            else:
                wrong.append((i, j))
    label = (lambda i, j: f"{i + 1}") if want.shape[1] == 1 else (lambda i, j: f"({i + 1},{j + 1})")
    if undecided and not wrong:
        out.verdict = UNDECIDED
        out.score = item.points * good / want.rows / want.cols if item.partial else 0.0
        out.feedback.append("entries " + ", ".join(label(*e) for e in undecided) + " undecided: manual review")
        return
    _credit(out, item, good, want.rows * want.cols)
    if wrong:
        whole = diagnose(got, want, ref.errata.get(name))
        if whole:
            out.feedback += whole
        out.feedback.append(("wrong entries: " if want.shape[1] > 1 else "wrong components: ")
                            + ", ".join(label(*e) for e in wrong))
        if not whole:
            for i, j in wrong[:6]:
                why = diagnose(got[i, j], want[i, j])
                if why:
                    out.feedback.append(f"{label(i, j)}: {why[0]}")
    if undecided:
        out.feedback.append("entries " + ", ".join(label(*e) for e in undecided) + " undecided: manual review")


# -- lists, sets, numbers ----------------------------------------------------------------------------------
def _judge_list(ref: Reference, name: str, item: ItemSpec, r: Result, value: Any, out: ItemResult) -> None:
    want = r.value
    if not isinstance(value, list) or len(value) != len(want):
        out.verdict = INCORRECT
        out.feedback.append(f"expected a list of {len(want)} items")
        return
    good = total = 0
    for k, (g, w) in enumerate(zip(value, want), 1):
        if isinstance(w, sp.MatrixBase):
            m = _as_matrix(g, w)
            entries = w.rows * w.cols
            total += entries
            if m is None or m.shape != w.shape:
                out.feedback.append(f"item {k}: wrong shape, expected {w.shape[0]}x{w.shape[1]}")
                continue
            bad = [(i, j) for i in range(w.rows) for j in range(w.cols) if not entry_equiv(m[i, j], w[i, j], item).ok]
            good += entries - len(bad)
            if bad:
                note = diagnose(m, w)
                out.feedback.append(f"item {k}: wrong entries " + ", ".join(f"({i + 1},{j + 1})" for i, j in bad)
                                    + (f" ({note[0]})" if note else ""))
        else:
            total += 1
            if not isinstance(g, list) and entry_equiv(g, w, item).ok:
                good += 1
            else:
                out.feedback.append(f"item {k} is wrong")
    _credit(out, item, good, total)


def _judge_set(ref: Reference, name: str, item: ItemSpec, r: Result, value: Any, out: ItemResult) -> None:
    want = [sp.Matrix(w) for w in r.value]
    if not isinstance(value, list):
        value = [value]
    if value and not isinstance(value[0], list):
        value = [value] if len(want) and len(value) == len(want[0]) else [[v] for v in value]
    got = [sp.Matrix(v) for v in value if isinstance(v, list)]
    v = set_equiv(got, want)
    if v.ok:
        out.verdict, out.score = CORRECT, item.points
        return
    matched = sum(1 for w in want if any(set_equiv([g], [w]).ok for g in got))
    extra = sum(1 for g in got if not any(set_equiv([g], [w]).ok for w in want))
    _credit(out, item, max(0, matched - extra), max(len(want), 1))  # each extra cancels a found one
    out.feedback.append(v.detail)


def _judge_number(ref: Reference, name: str, item: ItemSpec, r: Result, value: Any, out: ItemResult) -> None:
    if isinstance(value, list) or not getattr(value, "is_number", False):
        out.verdict = INCORRECT
        out.feedback.append("a number is expected")
        return
    if r.value is sp.oo or value is sp.oo:
        ok = value == r.value
    else:
        ok = entry_equiv(value, r.value if not r.value.is_Integer else sp.Float(r.value), item).ok
    _finish_scalar(ref, name, item, r.value, value, Verdict(CORRECT if ok else INCORRECT), out)
    if not ok:
        out.feedback.append(f"{float(sp.N(value)):.6g} is not within tolerance of the expected value")


def _round_sig(x: float, digits: int) -> float:
    return 0.0 if x == 0 else round(x, digits - 1 - int(math.floor(math.log10(abs(x)))))


def _judge_bool(ref: Reference, name: str, item: ItemSpec, r: Result, value: Any, out: ItemResult) -> None:
    ok = not isinstance(value, list) and value.is_number and bool(value != 0) == bool(r.value)
    out.verdict, out.score = (CORRECT, item.points) if ok else (INCORRECT, 0.0)
