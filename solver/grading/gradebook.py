"""Grading a class: many submissions in parallel, results written atomically.

    out/summary.csv             one row per submission: student, file, one column per item, total, max
    out/<student>.md            feedback (Markdown)
    out/<student>.json          the graded items
    out/results.json            with gradescope=True, one submission (Gradescope's autograder schema);
    out/gradescope/<student>/results.json   the same for each submission of a directory

Every file is written to a temporary name and renamed, so an interrupted run leaves no half-written file; a
re-run regrades everything and overwrites (nothing skipped, nothing duplicated).
"""
from __future__ import annotations

import csv
import io
import json
import multiprocessing as mp
import os
import tempfile
from pathlib import Path
from typing import Any, Callable, Iterable

import jinja2

from solver.grading.grader import Reference, Report, grade
from solver.grading.submission import load_submission, safe_stem
from solver.publish.render import template_env
from solver.spec.problem import Problem

SUBMISSION_SUFFIXES = {".yaml", ".yml", ".json"}


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same directory and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def submission_files(path: Path) -> list[Path]:
    """The submission files of a directory (sorted), or the file itself."""
    if path.is_dir():
        return sorted(p for p in path.iterdir() if p.suffix.lower() in SUBMISSION_SUFFIXES and p.is_file())
    return [path]


# ------------------------------------------------------------------------------------ parallel grading
_REF: Reference | None = None


def _grade_file(path: str) -> dict[str, Any]:
    assert _REF is not None
    try:
        report = grade(_REF, load_submission(Path(path)))
    except Exception as exc:  # noqa: BLE001 - one broken submission never stops a batch
        from solver.grading.grader import INVALID, ItemResult
        report = Report(safe_stem(Path(path).stem), path, _REF.problem.id,
                        [ItemResult(n, INVALID, 0.0, it.points, ["internal error while grading: manual review"])
                         for n, it in _REF.items.items()], [f"internal error: {exc.__class__.__name__}"])
    return report.to_dict()


def grade_files(ref: Reference, files: list[Path], jobs: int = 0,
                progress: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """Grade ``files`` with ``jobs`` worker processes (0: one per core); reports in the order of ``files``.
    The reference is computed once, before the workers fork."""
    global _REF
    _REF = ref
    jobs = jobs or os.cpu_count() or 1
    results: dict[str, dict[str, Any]] = {}
    names = [str(f) for f in files]
    if jobs == 1 or len(files) < 4 or "fork" not in mp.get_all_start_methods():
        it: Iterable[dict[str, Any]] = map(_grade_file, names)
        pool = None
    else:
        pool = mp.get_context("fork").Pool(jobs)
        it = pool.imap_unordered(_grade_file, names, chunksize=1)
    try:
        for rep in it:
            results[rep["file"]] = rep
            if progress:
                progress(rep)
    finally:
        if pool is not None:
            pool.terminate()
            pool.join()
    return [results[n] for n in names if n in results]


# ------------------------------------------------------------------------------------------ outputs
def _env(subdir: str = "md") -> jinja2.Environment:
    env = template_env(subdir)
    env.filters["cell"] = lambda s: str(s).replace("|", "\\|").replace("\n", " ")
    return env


def feedback_markdown(problem: Problem, report: dict[str, Any]) -> str:
    """The feedback page of one submission."""
    return _env().get_template("feedback.md.j2").render(problem=problem, report=report)


def answer_template(ref: Reference) -> str:
    """The blank answer sheet (YAML) of a problem: one commented entry per graded item."""
    env = _env("yaml")
    problem = ref.problem
    names = [k for k, v in problem.names.items() if not k.startswith("_")]
    coords = ", ".join(s.name for s in problem.robot.q) if problem.robot else ""
    items = [(n, it, ref.results[n]) for n, it in ref.items.items()]
    return env.get_template("answers.yaml.j2").render(problem=problem, items=items, names=", ".join(names),
                                                      coords=coords)


def gradescope_json(report: dict[str, Any]) -> dict[str, Any]:
    """Gradescope autograder results: score, output, tests[] with name, score, max_score, status, output."""
    tests = [{"name": it["name"], "score": it["score"], "max_score": it["max_score"],
              "status": "passed" if it["verdict"] == "correct" else "failed",
              "output": f"{it['verdict']}" + (": " + "; ".join(it["feedback"]) if it["feedback"] else "")}
             for it in report["items"]]
    return {"score": report["total"], "output": "\n".join(report["notes"]) or "graded by robosolve",
            "tests": tests}


def summary_csv(reports: list[dict[str, Any]], items: list[str]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["student", "file", *items, "total", "max"])
    for r in reports:
        by = {it["name"]: it for it in r["items"]}
        w.writerow([r["student"], r["file"], *[f"{by[i]['score']:g}" if i in by else "" for i in items],
                    f"{r['total']:g}", f"{r['max']:g}"])
    return buf.getvalue()


def unique_stems(reports: list[dict[str, Any]]) -> list[str]:
    """File stems of the outputs: the submission file's name (unique within a directory)."""
    return [safe_stem(Path(r["file"]).stem) for r in reports]


def write_outputs(problem: Problem, ref: Reference, reports: list[dict[str, Any]], out: Path,
                  gradescope: bool = False) -> list[Path]:
    """summary.csv, <stem>.md, <stem>.json (and Gradescope results) under ``out``."""
    written = []
    for r, stem in zip(reports, unique_stems(reports)):
        for path, text in ((out / f"{stem}.md", feedback_markdown(problem, r)),
                           (out / f"{stem}.json", json.dumps(r, indent=2, ensure_ascii=False) + "\n")):
            write_atomic(path, text)
            written.append(path)
        if gradescope:
            path = out / "results.json" if len(reports) == 1 else out / "gradescope" / stem / "results.json"
            write_atomic(path, json.dumps(gradescope_json(r), indent=2) + "\n")
            written.append(path)
    path = out / "summary.csv"
    write_atomic(path, summary_csv(reports, list(ref.items)))
    written.append(path)
    return written
