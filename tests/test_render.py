import json
import shutil
import subprocess
import sys

import pytest
import sympy as sp
from sympy.parsing.sympy_parser import parse_expr

from solver.render import render
from solver.solve import solve_problem
from solver.spec import load_problem

from conftest import PROBLEMS

RP = PROBLEMS / "2004-03-25-ex1.yaml"


@pytest.fixture(scope="module")
def solved():
    p = load_problem(RP)
    return p, solve_problem(p)


def test_markdown_reads_like_a_solution(solved):
    md = render(*solved, "md")
    for part in ["# Planar RP robot", "**Kinetic energy.**", "**Inertia matrix.**", "C_{1}(q) =",
                 "**Coriolis and centrifugal terms.**", "skew-symmetric (checked)", "**Gravity.**",
                 "**Dynamic model.**"]:
        assert part in md
    assert "$$B(q) = \\begin{bmatrix}" in md
    assert "2 m_{2} q_{2} \\dot{q}_{1} \\dot{q}_{2}" in md  # c_1, teacher's factor order


def test_json_exprs_read_back_with_parse_expr(solved):
    data = json.loads(render(*solved, "json"))
    assert data["id"] == "2004-03-25-ex1"
    B = parse_expr(data["results"]["B"]["expr"])
    m2, l1 = sp.symbols("m2 l1")
    assert data["results"]["B"]["kind"] == "matrix" and sp.simplify(B[0, 1] - m2 * l1) == 0
    assert data["results"]["skew"]["value"] is True
    assert data["results"]["christoffel"]["kind"] == "list"
    assert any(s["step"] == "model" for s in data["steps"])


def test_latex_is_complete_document_and_fragment(solved):
    tex = render(*solved, "tex")
    assert tex.startswith("\\documentclass") and tex.rstrip().endswith("\\end{document}")
    frag = render(*solved, "tex", fragment=True)
    assert "\\documentclass" not in frag and "\\section{Dynamic model}" in frag


@pytest.mark.skipif(not shutil.which("pdflatex"), reason="pdflatex not installed")
@pytest.mark.parametrize("name", ["2004-03-25-ex1", "2016-06-06-ex1", "2016-09-12-ex1"])
def test_latex_compiles(tmp_path, name):
    p = load_problem(PROBLEMS / f"{name}.yaml")
    (tmp_path / "r.tex").write_text(render(p, solve_problem(p), "tex"))
    r = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "r.tex"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stdout[-2000:]
    assert (tmp_path / "r.pdf").stat().st_size > 1000


def test_custom_templates_dir(solved, tmp_path):
    (tmp_path / "md").mkdir()
    (tmp_path / "md" / "page.md.j2").write_text("CUSTOM {{ problem.id }}\n")
    assert render(*solved, "md", template_dir=tmp_path) == "CUSTOM 2004-03-25-ex1\n"


def test_equilibria_section():
    p = load_problem(PROBLEMS / "2016-09-12-ex1.yaml")
    md = render(p, solve_problem(p), "md")
    assert "**4** equilibria" in md
