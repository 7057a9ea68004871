"""Handouts: exam sheets without solutions, solutions with results, keys matching `solve --format json`."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest
from conftest import PROBLEMS, ROOT

from solver.publish.handout import build, load_sources, log_excerpt
from solver.publish.render import to_json
from solver.solve import solve_problem
from solver.spec import load_problem
from solver.spec.errors import UserError

EXAM = ROOT / "exams" / "2004-03-25.yaml"
HAS_LATEX = bool(shutil.which("latexmk") or shutil.which("pdflatex")) and bool(shutil.which("pdftotext"))


def pdf_text(path) -> str:  # type: ignore[no-untyped-def]
    out = subprocess.run(["pdftotext", "-layout", str(path), "-"], capture_output=True, text=True, check=True).stdout
    return re.sub(r"\s+", " ", out)


def words(markdown: str) -> str:
    """The first words of a statement outside math, as pdftotext prints them."""
    plain = re.sub(r"\$[^$]*\$", " ", markdown).split()
    return " ".join(plain[:8])


@pytest.mark.skipif(not HAS_LATEX, reason="LaTeX/poppler not installed")
def test_exam_solutions_key_pdfs(tmp_path):
    hand = load_sources([EXAM])
    statement = hand.parts[0].problem.statement
    exam = build(load_sources([EXAM]), "exam", "pdf", tmp_path / "exam.pdf")["files"][0]
    text = pdf_text(exam)
    assert words(statement) in text and "12 points" in text and "Name:" in text
    assert "Solution" not in text and "Inertia matrix" not in text and "skew" not in text  # no solution
    sol = pdf_text(build(load_sources([EXAM]), "solutions", "pdf", tmp_path / "sol.pdf")["files"][0])
    assert words(statement) in sol and "Inertia matrix" in sol and "skew-symmetric (checked)" in sol
    key = pdf_text(build(load_sources([EXAM]), "key", "pdf", tmp_path / "key.pdf")["files"][0])
    assert "answer key" in key and "4 pt" in key and words(statement) not in key


def test_key_matches_solve_json(tmp_path):
    tex = build(load_sources([EXAM]), "key", "tex", tmp_path / "key.tex")["files"][0].read_text()
    p = load_problem(PROBLEMS / "2004-03-25-ex1.yaml")
    results = to_json(p, solve_problem(p))["results"]
    for name in ("B", "christoffel", "c", "S", "g"):  # the graded items of the problem
        assert results[name]["latex"] in tex, name


def test_tex_is_deterministic_and_selections(tmp_path):
    a = build(load_sources([EXAM]), "solutions", "tex", tmp_path / "a" / "s.tex")["files"]
    b = build(load_sources([EXAM]), "solutions", "tex", tmp_path / "b" / "s.tex")["files"]
    assert a[0].read_bytes() == b[0].read_bytes()
    assert [f.name for f in a[1:]] == ["s-p1-1-gravity.pdf", "s-p1-1-inertia.pdf"]  # figures beside the .tex
    assert "\\includegraphics[width=1.0\\linewidth]{s-p1-1-gravity.pdf}" in a[0].read_text()
    two = load_sources([PROBLEMS / "2004-03-25-ex1.yaml", PROBLEMS / "2005-04-05-ex1.yaml"])
    tex = build(two, "exam", "tex", tmp_path / "two.tex")["files"][0].read_text()
    assert tex.count("\\section*{Exercise") == 2


def test_markdown_and_html(tmp_path):
    md = build(load_sources([EXAM]), "solutions", "md", tmp_path / "s.md")["files"][0].read_text()
    assert md.startswith("# Written exam: solutions") and "## Exercise 1 (12 points)" in md and "$$B(q) =" in md
    assert "![" in md and (tmp_path / "s-p1-1-gravity.png").exists()
    sol = build(load_sources([EXAM]), "solutions", "html", tmp_path / "s.html")["files"][0].read_text()
    assert '<img alt="Gravity terms g_i(q)' in sol and 'src="s-p1-1-gravity.png"' in sol
    html = build(load_sources([EXAM]), "key", "html", tmp_path / "k.html")["files"][0].read_text()
    assert "mathjax" in html.lower() and "<table>" in html and "<h2>Exercise 1 (12 points)</h2>" in html


def test_variant_values(tmp_path):
    hand = load_sources([ROOT / "exams" / "2019-09-11-variant-b.yaml"])
    tex = build(hand, "solutions", "tex", tmp_path / "v.tex")["files"][0].read_text()
    assert "Data for this exam:" in tex and "L = 0.25" in tex


def test_exam_file_errors(tmp_path):
    bad = tmp_path / "e.yaml"
    bad.write_text("title: X\nproblems:\n  - problem: no-such-problem\n")
    with pytest.raises(UserError) as e:
        load_sources([bad])
    assert "problem 'no-such-problem' not found" in str(e.value) and ":3:" in str(e.value)
    bad.write_text("title: X\nproblems: []\n")
    with pytest.raises(UserError):
        load_sources([bad])


def test_no_latex_installed(tmp_path):
    """Without LaTeX: the .tex is written, one message says what to install, exit code 2."""
    env = dict(os.environ, PATH=str(tmp_path / "empty"))
    r = subprocess.run([sys.executable, "-m", "solver", "handout", str(EXAM), "--kind", "exam", "-o",
                        str(tmp_path / "x.pdf")], capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
    assert r.returncode == 2 and "apt-get install latexmk" in r.stderr and "Traceback" not in r.stderr
    assert (tmp_path / "x.tex").read_text().startswith("\\documentclass")


@pytest.mark.skipif(not HAS_LATEX, reason="LaTeX not installed")
def test_latex_error_shows_relevant_lines(tmp_path):
    custom = tmp_path / "tpl" / "latex"
    custom.mkdir(parents=True)
    (custom / "handout.tex.j2").write_text("\\documentclass{article}\n\\begin{document}\n\\undefinedmacro\n"
                                           "\\end{document}\n")
    r = subprocess.run([sys.executable, "-m", "solver", "handout", str(EXAM), "-o", str(tmp_path / "x.pdf"),
                        "--templates", str(tmp_path / "tpl")], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 2 and "Undefined control sequence" in r.stderr and "\\undefinedmacro" in r.stderr
    assert len(r.stderr.splitlines()) < 40


def test_log_excerpt():
    log = "\n".join(["noise"] * 500 + ["./x.tex:3: Undefined control sequence.", "l.3 \\foo", ""] + ["more"] * 100)
    ex = log_excerpt(log)
    assert "x.tex:3: Undefined control sequence." in ex and len(ex.splitlines()) < 10


@pytest.mark.skipif(not HAS_LATEX, reason="LaTeX/poppler not installed")
def test_every_statement_on_a_two_exercise_exam_sheet(tmp_path):
    hand = load_sources([ROOT / "exams" / "2020-07-15-remote.yaml"])
    text = pdf_text(build(hand, "exam", "pdf", tmp_path / "e.pdf")["files"][0])
    assert all(words(p.problem.statement) in text for p in hand.parts) and "30 points" in text
    assert "Solution" not in text and "Pseudoinverse" not in text and "Inertia matrix" not in text


@pytest.mark.parametrize("exam", sorted((ROOT / "exams").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_exam_file_builds_its_exam_sheet(exam, tmp_path):
    """Each exam file names existing problems, and its sheet has every statement and the points it says."""
    hand = load_sources([exam])
    assert hand.parts and all(part.points > 0 for part in hand.parts)
    md = build(hand, "exam", "md", tmp_path / "exam.md")["files"][0].read_text()
    text = re.sub(r"\s+", " ", md)
    total = sum(part.points for part in hand.parts)
    assert f"{total:g} points" in text and "Solution" not in text
    for part in hand.parts:
        assert words(part.problem.statement) in re.sub(r"\s+", " ", re.sub(r"\$[^$]*\$", " ", text))
