"""The robosolve command line (thin: parse options, call the library, print)."""
from __future__ import annotations

import json
import os
import sys
from enum import Enum
from pathlib import Path
from typing import Any, Callable, Optional

import typer

from solver.spec.errors import UserError

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Solve, explain, verify robotics (dynamics & control) exam problems written as YAML specs.")


class Fmt(str, Enum):
    md = "md"
    tex = "tex"
    json = "json"


def _fail(exc: UserError) -> None:
    typer.echo(str(exc), err=True)
    raise typer.Exit(2)


SPEC_LIMITS = (600.0, 4096)  # seconds and MB to read and solve one spec (solve, grade, handout, answer-template)


def _bounded(fn: Callable[[], Any], limits: tuple[float, int] = SPEC_LIMITS) -> Any:
    """``fn()`` in a bounded worker process (solver.sandbox): its value, or a UserError saying why it stopped."""
    from solver.sandbox import USER, Limits, run_one
    out = run_one(fn, Limits(*limits))
    if out.ok:
        return out.value
    if out.failure == USER:
        raise _Reported(out.message)
    raise UserError(out.message if out.failure != "exception" else f"internal error: {out.message}")


class _Reported(UserError):
    """A UserError already formatted in the worker (its text is printed as is)."""

    def __str__(self) -> str:
        return self.message


def _output_file(path: Path) -> Path:
    """Check an output file before any work: not a folder, its folder creatable and writable."""
    if path.is_dir():
        raise UserError(f"-o {path} is a folder; give a file name", None, f"e.g. -o {path / 'solution.md'}")
    anc = path.parent
    while not anc.exists():
        anc = anc.parent
    if not anc.is_dir():
        raise UserError(f"-o {path} is under {anc}, which is a file", None, "give a path in a folder")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"-o {path}: cannot create its folder ({exc.strerror})", None,
                        "choose a place you can write") from None
    if not os.access(path.parent, os.W_OK | os.X_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise UserError(f"-o {path}: cannot write there", None, "choose a place you can write")
    return path


def _write(path: Path, text: str) -> None:
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot write {path} ({exc.strerror})", None, "choose a place you can write") from None


@app.command()
def solve(spec: Path = typer.Argument(..., help="problem spec (YAML)"),
          format: Fmt = typer.Option(Fmt.md, "--format", "-f", help="md, tex or json"),
          output: Optional[Path] = typer.Option(None, "--output", "-o", help="write here (plots beside it)"),
          fragment: bool = typer.Option(False, help="LaTeX body only, no preamble"),
          templates: Optional[Path] = typer.Option(None, help="directory with your own md/ and tex/ templates"),
          details: bool = typer.Option(False, "--details", help="JSON: also the intermediate results (per-body "
                                       "quantities) and the expressions of the steps"),
          jobs: int = typer.Option(0, "--jobs", "-j", min=0, help="processes solving the asks (0: one per core)")
          ) -> None:
    """Solve a problem and print the step-by-step solution."""
    from functools import partial

    from solver.publish.report import solve_job
    try:
        if output:
            _output_file(output)
        text, n_figures = _bounded(partial(solve_job, spec, format.value, output, fragment, templates, details, jobs))
        if output:
            _write(output, text)
    except UserError as exc:
        _fail(exc)
        return
    if output:
        typer.echo(f"wrote {output}" + (f" and {n_figures} figure(s) beside it" if n_figures else ""), err=True)
    else:
        sys.stdout.write(text)


@app.command()
def check(specs: list[Path] = typer.Argument(..., help="spec files (or exam files) to validate"),
          time_limit: float = typer.Option(120.0, "--time-limit", min=1, help="seconds per file (reading and solving)")
          ) -> None:
    """Validate specs or exam files: 'ok', or every error found (file:line, what, how to fix; exit code 2).
    A spec with expected: values is solved, to find entries that name no result or cannot be read."""
    from solver.registry import preload
    from solver.sandbox import Limits, cores, run_many
    preload(len(specs))
    ask_jobs = max(1, cores() // len(specs))  # fewer files than cores: the asks of each shared
    outcomes = run_many(lambda path: _check_file(path, ask_jobs), specs, 0, Limits(time_limit, 4096))
    bad = 0
    for s, out in zip(specs, outcomes):
        lines = out.value if out.ok else [f"{s}: error: {out.message}"]
        if lines and lines[0].startswith(f"{s}: ok"):
            typer.echo(lines[0])
        else:
            bad += 1
            for line in lines:
                typer.echo(line, err=True)
    if bad:
        raise typer.Exit(2)


def _check_file(path: Path, ask_jobs: int = 1) -> list[str]:
    """`check` of one file (in a bounded worker): ["<file>: ok ..."] or the error messages. Imports only what the
    file needs: the modules of its ask kinds, the handout module only for an exam file. Every ask's options are
    read and checked without solving (its kind's validate hook; every failing ask reported); a file with expected
    values is then solved, so that each expected entry names a result."""
    from solver.spec.loader import SpecLoader
    from solver.spec.models import is_exam_data
    from solver.spec.yamlpos import load_file
    try:
        located = load_file(path)
        if is_exam_data(located.data):
            from solver.publish.handout import load_exam
            exam = load_exam(path, located)
            return [f"{path}: ok (exam file, {len(exam.parts)} problem(s))"]
        problem = SpecLoader(located).load()
        from solver.grading.options import grading_spec
        grading_spec(problem)
        from solver.solve import validate_problem
        invalid = validate_problem(problem)
        if invalid:
            return [str(exc) for exc in invalid]
        if not problem.expected:
            return [f"{path}: ok"]
        from solver.verify import ERROR, check_problem
        rep = check_problem(problem, compare=False, jobs=ask_jobs)
    except UserError as exc:
        return [str(exc)]
    errors = [c.verdict.detail for c in rep.checks if c.verdict.verdict == ERROR]
    return errors or [f"{path}: ok"]


@app.command()
def verify(paths: list[Path] = typer.Argument(..., help="spec files or directories"),
           quiet: bool = typer.Option(False, "--quiet", "-q", help="only failures and the summary"),
           jobs: int = typer.Option(0, "--jobs", "-j", min=0, help="worker processes (0: one per core)"),
           time_limit: float = typer.Option(900.0, "--time-limit", min=1, help="seconds per problem"),
           seed: int = typer.Option(2024, help="seed of the random points of the equivalence tests")) -> None:
    """Solve every problem and compare with its expected (printed) values; non-zero exit on any mismatch."""
    from solver.math import equivalence
    from solver.sandbox import Limits
    from solver.verify import describe, verify_paths
    equivalence.SEED = seed

    def show(rep) -> None:  # type: ignore[no-untyped-def]
        if not quiet or not rep.ok:
            typer.echo("\n".join(describe(rep)))
    try:
        reports = verify_paths(paths, jobs, Limits(time_limit, 8192), on_done=show)
    except UserError as exc:
        _fail(exc)
        return
    n_ok = sum(r.ok for r in reports)
    checks = sum(len(r.checks) for r in reports)
    errata = sum(c.erratum is not None for r in reports for c in r.checks)
    typer.echo(f"\n{n_ok}/{len(reports)} problems ok, {checks} results checked, {errata} errata recorded "
               f"(random points: seed {seed})")
    if n_ok != len(reports) or not reports:
        raise typer.Exit(1)


@app.command()
def grade(spec: Path = typer.Argument(..., help="problem spec (YAML)"),
          submissions: Path = typer.Argument(..., help="a submission file (YAML/JSON) or a directory of them"),
          out: Optional[Path] = typer.Option(None, "--out", "-o", help="write summary.csv and per-student feedback here"),
          gradescope: bool = typer.Option(False, help="also write Gradescope results.json"),
          jobs: int = typer.Option(0, "--jobs", "-j", min=0, help="worker processes (0: one per core)")) -> None:
    """Grade submitted answers: feedback on stdout for one file; a class with --out."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from solver.grading.gradebook import (ResultsFolder, feedback_markdown, grade_files, submission_entries,
                                          write_outputs)
    from solver.grading.grader import prepare
    from solver.spec import load_problem
    folder = None
    try:
        if not submissions.exists() and not submissions.is_symlink():
            raise UserError(f"no such file or directory: {submissions}", None, "give a submission file or a directory")
        entries = submission_entries(submissions)
        if not entries:
            raise UserError(f"no submissions (*.yaml, *.yml, *.json) in {submissions}", None, "check the directory")
        single = not submissions.is_dir()
        if single and entries[0].problem:
            raise UserError(f"{submissions}: {entries[0].problem}", None, "give a submission file (YAML or JSON)")
        folder = ResultsFolder(out) if out else None  # a bad --out is refused before any work
        ref = _bounded(lambda: prepare(load_problem(spec)), SPEC_LIMITS)
        if single:
            reports = grade_files(ref, entries, 1)
        else:
            with Progress(TextColumn("grading"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                          transient=True) as bar:
                task = bar.add_task("grading", total=len(entries))
                reports = grade_files(ref, entries, jobs, progress=lambda r: bar.advance(task))
        if folder:
            written = write_outputs(ref.problem, ref, reports, folder, gradescope)
            typer.echo(f"graded {len(reports)} submission(s); wrote {len(written)} files under {out}/ "
                       f"(summary.csv)", err=True)
    except UserError as exc:
        _fail(exc)
        return
    finally:
        if folder:
            folder.close()
    if not out or len(reports) == 1:
        for r in reports:
            sys.stdout.write(feedback_markdown(ref.problem, r))
    else:
        for r in reports:
            typer.echo(f"{r['student']:<30} {r['total']:g}/{r['max']:g}")


@app.command("answer-template")
def answer_template_(spec: Path = typer.Argument(..., help="problem spec (YAML)")) -> None:
    """Print the blank answer sheet (YAML) students fill in."""
    from solver.grading.gradebook import answer_template
    from solver.grading.grader import prepare
    from solver.spec import load_problem
    try:
        sys.stdout.write(_bounded(lambda: answer_template(prepare(load_problem(spec)))))
    except UserError as exc:
        _fail(exc)


class HandoutKind(str, Enum):
    exam = "exam"
    solutions = "solutions"
    key = "key"


class HandoutFmt(str, Enum):
    pdf = "pdf"
    tex = "tex"
    md = "md"
    html = "html"


@app.command()
def handout(sources: list[Path] = typer.Argument(..., help="an exam file (exams/*.yaml) or problem specs"),
            kind: HandoutKind = typer.Option(HandoutKind.exam, "--kind", "-k", help="exam, solutions or key"),
            output: Path = typer.Option(..., "--output", "-o", help="the file to write (.pdf, .tex, .md, .html)"),
            format: Optional[HandoutFmt] = typer.Option(None, "--format", "-f",
                                                        help="pdf, tex, md or html (default: from -o's suffix)"),
            templates: Optional[Path] = typer.Option(None, help="directory with your own latex/, md/, html/ templates"),
            timing: bool = typer.Option(False, help="print the time of the solve and LaTeX phases")) -> None:
    """Publish a handout: the exam sheet, the solutions or the answer key (PDF via LaTeX, or tex/md/html)."""
    from solver.publish.handout import build, load_sources
    fmt = format.value if format else {".tex": "tex", ".md": "md", ".html": "html"}.get(output.suffix, "pdf")
    try:
        _output_file(output)
        result = _bounded(lambda: build(load_sources(sources), kind.value, fmt, output, templates),
                          (SPEC_LIMITS[0] * max(1, len(sources)), SPEC_LIMITS[1]))
    except UserError as exc:
        _fail(exc)
        return
    typer.echo(f"wrote {output}" + (f" (+{len(result['files']) - 1} figure files)" if len(result["files"]) > 1 else ""),
               err=True)
    if timing:
        typer.echo(f"solve {result['solve']:.2f} s, LaTeX {result['latex']:.2f} s", err=True)


@app.command()
def schema() -> None:
    """Print the JSON Schema of the spec format (for editor completion)."""
    from solver.spec.models import json_schema
    typer.echo(json.dumps(json_schema(), indent=2, ensure_ascii=False))


@app.command("list")
def list_(paths: list[Path] = typer.Argument(..., help="spec files or directories")) -> None:
    """One line per problem: id, title, topics, asks."""
    from solver.spec import load_problem
    from solver.sandbox import Limits, run_many
    from solver.verify import spec_files
    try:
        files = spec_files(paths)
    except UserError as exc:
        _fail(exc)
        return

    def line(f: Path) -> str:
        pr = load_problem(f)
        return f"{pr.id:<32} {pr.title[:50]:<50} [{','.join(pr.topics)}] asks: {','.join(a.kind for a in pr.asks)}"
    from solver.registry import preload
    preload(len(files))
    bad = 0
    for f, out in zip(files, run_many(line, files, 0, Limits(60.0, 2048))):
        if out.ok:
            typer.echo(out.value)
        else:
            typer.echo(f"{f}: {out.message.splitlines()[0]}", err=True)
            bad += 1
    if bad:
        raise typer.Exit(2)


def main() -> None:
    """Entry point: user errors exit 2 with a message, never a traceback."""
    try:
        app()
    except UserError as exc:
        typer.echo(str(exc), err=True)
        sys.exit(2)


if __name__ == "__main__":
    main()
