"""Handouts: the exam sheet, the solutions and the answer key of an exam file or of a list of problems.

An exam file (``exams/*.yaml``, documented in docs/spec.md)::

    course: Robotics II
    title: Written exam
    date: 2004-03-25
    duration: 2 hours
    instructions: Markdown text
    problems:
      - problem: 2004-03-25-ex1      # an id of the library, or a path relative to the exam file
        points: 12                   # default: the problem's grading points, else 10
        values: {m: 2}               # optional variant: numeric values replacing the problem's

Kinds: ``exam`` (statements, points, blank space), ``solutions`` (statements + step-by-step solutions + plots),
``key`` (final answers of the graded items with their points). Formats: pdf (LaTeX compiled with latexmk or
pdflatex), tex, md, html (MathJax).
"""
from __future__ import annotations

import datetime as dt
import math
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Union

from pydantic import Field, ValidationError

from solver.grading.grader import Reference, grading_spec, prepare
from solver.publish.figures import write_figures
from solver.publish.render import latex_printer, md2html, render_template, template_env
from solver.spec.errors import Place, UserError
from solver.spec.loader import SpecLoader, load_problem, validation_error
from solver.spec.expr import number
from solver.spec.models import Strict, is_exam_data
from solver.spec.texmath import text_math_problem
from solver.spec.problem import Problem
from solver.spec.yamlpos import Located, load_file

KINDS = ("exam", "solutions", "key")
LATEX_PACKAGES = "latexmk texlive-latex-recommended texlive-latex-extra"


class ExamProblem(Strict):
    problem: str = Field(description="a problem id of the library (problems/<id>.yaml) or a path to a spec")
    points: Optional[float] = Field(None, ge=0, description="points (default: the problem's grading points, else 10)")
    values: dict[str, Union[int, float, str]] = Field({}, description="variant: numeric values replacing the problem's")


class ExamSpec(Strict):
    course: str = Field("", description="course name, e.g. Robotics II")
    title: str = Field("Written exam", description="title of the handout")
    date: Optional[Union[str, dt.date]] = Field(None, description="date of the exam")
    duration: str = Field("", description="e.g. 2 hours")
    instructions: str = Field("", description="Markdown text printed under the title of the exam sheet")
    problems: list[ExamProblem] = Field(min_length=1, description="the exercises, in order")


@dataclass
class Part:
    """One exercise of a handout."""

    problem: Problem
    points: float
    variant: dict[str, Any] = field(default_factory=dict)
    ref: Reference | None = None


@dataclass
class Handout:
    exam: ExamSpec
    parts: list[Part]
    source: str


# ------------------------------------------------------------------------------------------ loading
def _find_problem(name: str, base: Path, place: Place) -> Path:
    cands = [base / name] if name.endswith((".yaml", ".yml")) else [
        base / f"{name}.yaml", base.parent / "problems" / f"{name}.yaml", Path("problems") / f"{name}.yaml",
        Path(__file__).resolve().parents[2] / "problems" / f"{name}.yaml"]
    for c in cands:
        if c.is_file():
            return c
    raise UserError(f"problem '{name}' not found", place,
                    "give a problem id of problems/ (e.g. 2004-03-25-ex1) or a path to a .yaml spec")


def _apply_variant(problem: Problem, values: dict[str, Any], located: Located, index: int) -> dict[str, Any]:
    shown = {}
    for name, raw in values.items():
        place = located.place(("problems", index, "values", name))
        sym = problem.symbols.get(name)
        if sym is None:
            raise UserError(f"'{name}' is not a parameter of {problem.id}", place,
                            "parameters: " + ", ".join(problem.symbols))
        text = repr(raw) if isinstance(raw, float) else str(raw).strip()
        sign, digits = (-1, text[1:]) if text.startswith("-") else (1, text.lstrip("+"))
        try:
            if isinstance(raw, bool) or (isinstance(raw, float) and not math.isfinite(raw)):
                raise UserError("not a finite number")
            value = sign * number(digits, lambda msg: UserError(msg))
        except UserError as exc:
            raise UserError(f"value of '{name}' must be a number ({exc.message})", place,
                            "write e.g. 0.5 or 2.5e-3") from None
        problem.values[sym] = value
        shown[name] = text  # printed as the teacher wrote it (0.25, not 1/4): a validated numeric literal
    return shown


def load_exam(path: Path, located: Located | None = None) -> Handout:
    """Read an exam file (``located``: its already parsed YAML) and the problems it names (errors at the exam
    file's lines)."""
    loc = located or load_file(path)
    try:
        exam = ExamSpec.model_validate(loc.data if isinstance(loc.data, dict) else {})
    except ValidationError as exc:
        raise validation_error(exc, loc, what="exam", hint="see docs/spec.md, section 'Exam files'") from None
    why = text_math_problem(exam.instructions)
    if why:
        raise UserError(f"instructions: {why}", loc.place(("instructions",)),
                        "math between $...$ may use symbols, Greek letters, \\frac, \\sqrt, accents, fonts, matrices")
    parts = []
    for i, ep in enumerate(exam.problems):
        problem = load_problem(_find_problem(ep.problem, path.parent, loc.place(("problems", i, "problem"))))
        variant = _apply_variant(problem, ep.values, loc, i)
        parts.append(Part(problem, ep.points if ep.points is not None else -1.0, variant))
    return Handout(exam, parts, str(path))


def load_sources(paths: list[Path]) -> Handout:
    """An exam file, or an ad-hoc selection of problem specs (each file read once)."""
    located = [load_file(p) for p in paths]
    exams = [(p, loc) for p, loc in zip(paths, located) if is_exam_data(loc.data)]
    if exams:
        if len(paths) > 1:
            raise UserError("give one exam file, or problem specs only", Place(str(exams[0][0])),
                            "list the problems inside the exam file")
        return load_exam(*exams[0])
    parts = [Part(SpecLoader(loc).load(), -1.0) for loc in located]
    return Handout(ExamSpec(title="Exercises", problems=[ExamProblem(problem=str(p)) for p in paths]), parts,
                   ", ".join(str(p) for p in paths))


# ------------------------------------------------------------------------------------------ building
def _key_items(part: Part) -> list[dict[str, Any]]:
    assert part.ref is not None
    latex = latex_printer(part.problem)
    out = []
    for name, item in part.ref.items.items():
        r = part.ref.results[name]
        out.append({"name": name, "title": item.title or "", "label": r.label or name,
                    "latex": latex(r.value), "points": item.points})
    return out


def build(handout: Handout, kind: str, fmt: str, output: Path, template_dir: Path | None = None) -> dict[str, Any]:
    """Write the handout to ``output`` (pdf | tex | md | html). Returns {"files": [...], "solve": s, "latex": s}."""
    if kind not in KINDS:
        raise UserError(f"unknown handout kind '{kind}'", None, "use --kind exam, solutions or key")
    from solver.solve import solve_problem
    t0 = time.perf_counter()
    solved = []
    for part in handout.parts:
        sols = solve_problem(part.problem) if kind != "exam" else []
        if kind == "key":
            part.ref = prepare(part.problem)
        if part.points < 0:
            items = grading_spec(part.problem).items
            part.points = sum(i.points for i in items.values()) if items else 10.0
        solved.append(sols)
    t_solve = time.perf_counter() - t0
    output.parent.mkdir(parents=True, exist_ok=True)
    stem = output.stem
    tex_fmt = fmt in ("pdf", "tex")
    work = Path(tempfile.mkdtemp(prefix="robosolve-")) if fmt == "pdf" else output.parent
    files: list[Path] = []
    bodies = []
    for k, (part, sols) in enumerate(zip(handout.parts, solved), 1):
        if kind == "solutions":
            for fig in write_figures(sols, work / f"{stem}-p{k}.x", "tex" if tex_fmt else "md"):
                files.append(fig)
        body = ""
        if kind == "solutions":
            body = render_template(part.problem, "solution.tex.j2" if tex_fmt else "solution.md.j2",
                                   "tex" if tex_fmt else "md", template_dir, solutions=sols, level=2, fragment=True)
        bodies.append({"problem": part.problem, "points": part.points, "variant": part.variant, "solution": body,
                       "key": _key_items(part) if kind == "key" else []})
    ctx = {"exam": handout.exam, "parts": bodies, "kind": kind, "total": sum(b["points"] for b in bodies)}
    if tex_fmt:
        text = template_env("latex", template_dir).get_template("handout.tex.j2").render(**ctx)
        tex_path = (output if fmt == "tex" else work / f"{stem}.tex")
        tex_path.write_text(text, encoding="utf-8")
        if fmt == "tex":
            return {"files": [tex_path, *files], "solve": t_solve, "latex": 0.0}
        t1 = time.perf_counter()
        try:
            pdf = compile_latex(tex_path, output, places=[p.problem.located.place(("statement",))
                                                          for p in handout.parts])
        finally:
            shutil.rmtree(work, ignore_errors=True)
        return {"files": [pdf], "solve": t_solve, "latex": time.perf_counter() - t1}
    md = template_env("md", template_dir).get_template("handout.md.j2").render(**ctx)
    text = md if fmt == "md" else template_env("html", template_dir, autoescape=True).get_template(
        "handout.html.j2").render(body=md2html(md), **ctx)
    output.write_text(text, encoding="utf-8")
    return {"files": [output, *files], "solve": t_solve, "latex": 0.0}


# ------------------------------------------------------------------------------------------ LaTeX
PDFLATEX = "pdflatex -no-shell-escape -interaction=nonstopmode -halt-on-error -file-line-error"
LATEX_TIMEOUT = 120.0   # seconds for a whole build
LATEX_MEMORY = 2 << 30  # bytes of address space for the compiler


def latex_tool() -> list[str] | None:
    """The compiler command: latexmk (preferred, without rc files, driving a paranoid pdflatex) or pdflatex;
    None when neither is installed."""
    if shutil.which("latexmk"):
        return ["latexmk", "-norc", "-pdf", f"-pdflatex={PDFLATEX} %O %S"]
    if shutil.which("pdflatex"):
        return PDFLATEX.split()
    return None


def latex_env() -> dict[str, str]:
    """The compiler's environment: no shell escape, files read and written only in the build directory
    (kpathsea's paranoid mode refuses absolute paths, '..' and dot files; packages are still found)."""
    import os
    env = {k: v for k, v in os.environ.items() if not k.startswith(("TEXINPUTS", "TEXMF", "openin", "openout"))}
    env.update(openin_any="p", openout_any="p", shell_escape="f", TEXMFOUTPUT="")
    return env


def _limit_compiler() -> None:  # in the compiler's process, before exec
    import resource
    resource.setrlimit(resource.RLIMIT_AS, (LATEX_MEMORY, LATEX_MEMORY))


def compile_latex(tex: Path, output: Path, timeout: float = LATEX_TIMEOUT, places: list[Place] | None = None) -> Path:
    """Compile ``tex`` (in its directory) and copy the PDF to ``output``, the compiler paranoid and bounded in
    time and memory. Without LaTeX the .tex (and its figures) are kept beside ``output`` and a UserError says
    what to install. On a LaTeX error the .tex is kept beside ``output`` and the error names the exercise and,
    from ``places`` (one per exercise), the spec it comes from."""
    import os
    import signal
    tool = latex_tool()
    if tool is None:
        kept = output.with_suffix(".tex")
        for f in tex.parent.iterdir():
            if f.is_file() and f.suffix in (".tex", ".pdf", ".png"):
                shutil.copy2(f, output.parent / (kept.name if f == tex else f.name))
        raise UserError(f"LaTeX is not installed: wrote {kept} (compile it later) but no PDF",
                        None, f"install it with: sudo apt-get install {LATEX_PACKAGES}   (or use --format tex|md|html)")
    runs = 1 if tool[0] == "latexmk" else 2
    deadline = time.monotonic() + timeout
    for _ in range(runs):
        proc = subprocess.Popen([*tool, tex.name], cwd=tex.parent, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, text=True, errors="replace", env=latex_env(),
                                start_new_session=True, preexec_fn=_limit_compiler)
        try:
            stdout, _ = proc.communicate(timeout=max(1.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise UserError(f"LaTeX did not finish within {timeout:.0f} s (a macro that loops?)", None,
                            "build with --format tex and look at the text of the exercise") from None
        if proc.returncode != 0:
            log = tex.with_suffix(".log")
            text = log.read_text(errors="replace") if log.exists() else stdout
            kept = output.with_suffix(".failed.tex")
            shutil.copy2(tex, kept)
            k = _exercise(tex, text)
            place = places[k - 1] if places and 0 < k <= len(places) else None
            raise UserError(f"LaTeX failed{f' in exercise {k}' if k else ''}:\n" + log_excerpt(text), place,
                            f"the LaTeX is kept in {kept}; fix the text of that exercise or the template")
    pdf = tex.with_suffix(".pdf")
    shutil.copy2(pdf, output)
    return output


def _exercise(tex: Path, log: str) -> int:
    """The exercise (from the \\section*{Exercise k} headings) of the first error line of the log; 0 if none."""
    m = re.search(r"^[^:\s]+\.tex:(\d+): ", log, re.M) or re.search(r"^l\.(\d+) ", log, re.M)
    if not m:
        return 0
    line = int(m.group(1))
    k = 0
    for i, text in enumerate(tex.read_text(errors="replace").splitlines(), 1):
        if i > line:
            break
        h = re.match(r"\\section\*\{Exercise (\d+)", text)
        if h:
            k = int(h.group(1))
    return k


def log_excerpt(log: str, context: int = 4, limit: int = 30) -> str:
    """The error lines of a LaTeX log ('! ...' or 'file:line: ...') with a few lines of context."""
    lines = log.splitlines()
    picked: list[str] = []
    for i, line in enumerate(lines):
        if line.startswith("!") or re.match(r"^[^:\s]+\.tex:\d+: ", line):
            picked += lines[i:i + context + 1] + ["..."]
        if len(picked) >= limit:
            break
    return "\n".join(picked[:limit]) if picked else "\n".join(lines[-limit:])
