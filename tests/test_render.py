import json
import math
import re
import shutil
import subprocess

import pytest
import sympy as sp
from conftest import PROBLEMS
from sympy.parsing.sympy_parser import parse_expr

from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem

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
@pytest.mark.parametrize("name", sorted(p.stem for p in PROBLEMS.glob("*.yaml")))
def test_latex_compiles(tmp_path, name):
    """Every problem of the library gives a LaTeX report (with its figures) that compiles."""
    from solver.publish.figures import write_figures
    p = load_problem(PROBLEMS / f"{name}.yaml")
    sols = solve_problem(p)
    figures = write_figures(sols, tmp_path / "r.tex", "tex")  # compiled with its figures
    res = all_results(sols)
    varying = any(set(p.robot.q) & res[k].value.free_symbols for k in ("B", "g") if k in res)  # else nothing to plot
    assert figures or not (varying and any(a.kind == "dynamic_model" and a.options.plots for a in p.asks))
    (tmp_path / "r.tex").write_text(render(p, sols, "tex"))
    r = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "r.tex"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stdout[-2000:]
    assert (tmp_path / "r.pdf").stat().st_size > 1000


def test_figures_hold_the_sampled_formulas(solved):
    """The gravity figure plots g_i(q_j) with the other coordinates at 0 and missing parameters at 1."""
    problem, sols = solved
    fig = next(f for f in sols[0].figures if f.name == "gravity")
    panel_q1, panel_q2 = fig.panels  # g depends on q1 and on q2
    g1 = next(c for c in panel_q1.curves if c.label == "$g_{1}$")
    # g1 = g0 m2 q2 cos q1 + g0 (d1 m1 + l1 m2) sin q1 with q2 = 0 and every parameter 1: 2 sin q1
    assert panel_q1.x_is_angle and all(abs(y - 2 * math.sin(x)) < 1e-12 for x, y in zip(g1.x, g1.y))
    g1_q2 = next(c for c in panel_q2.curves if c.label == "$g_{1}$")
    assert all(abs(y - x) < 1e-12 for x, y in zip(g1_q2.x, g1_q2.y))  # q1 = 0: g0 m2 q2
    assert "set to 1" in fig.caption


def test_figures_drawn_beside_output(solved, tmp_path):
    from solver.publish.figures import write_figures
    problem, sols = solved
    files = write_figures(sols, tmp_path / "x.tex", "tex")
    assert [f.name for f in files] == ["x-1-gravity.pdf", "x-1-inertia.pdf"]
    tex = render(problem, sols, "tex")
    assert "\\includegraphics[width=1.0\\linewidth]{x-1-gravity.pdf}" in tex
    for f in sols[0].figures:
        f.path = ""  # the module-scoped fixture is shared


def test_custom_templates_dir(solved, tmp_path):
    (tmp_path / "md").mkdir()
    (tmp_path / "md" / "page.md.j2").write_text("CUSTOM {{ problem.id }}\n")
    assert render(*solved, "md", template_dir=tmp_path) == "CUSTOM 2004-03-25-ex1\n"


def test_equilibria_section():
    p = load_problem(PROBLEMS / "2016-09-12-ex1.yaml")
    md = render(p, solve_problem(p), "md")
    assert "**4** equilibria" in md


def test_long_equations_break_into_lines():
    from solver.publish.render import display, visible_length
    assert visible_length(r"\dot{q}_{1}^{2} \sin{q_{2}}") == len("xq12xxxq2")  # q̇₁² sin q₂
    short = display(["a", "- b"], "u_{1}")
    assert short == r"\[a - b = u_{1}\]"
    long = display([f"m_{{{k}}} \\dot{{q}}_{{1}} \\cos{{q_{{2}}}}" for k in range(12)], "u_{1}", width=40)
    assert long.startswith("\\begin{multline*}") and long.count("\\\\\n") >= 2 and long.endswith("\\end{multline*}")
    assert "\n+ m_{" in long and long.rstrip("\\end{multline*}").rstrip().endswith("= u_{1}")


def test_display_math_over_several_lines_stays_one_formula():
    from solver.publish.render import md2html, md2tex
    text = "Consider\n$$\\tau = B(q)\\ddot q\n + c(q, \\dot q)$$\nand $x$."
    assert "$$\\tau = B(q)\\ddot q  + c(q, \\dot q)$$" in md2tex(text)
    assert "$$\\tau = B(q)\\ddot q  + c(q, \\dot q)$$" in md2html(text)


def test_memoized_printers_print_as_sympy_does() -> None:
    """The printers that print each subexpression once give sympy's text and the report's LaTeX unchanged,
    also where equal subexpressions recur, orders change inside a product, and floats of other precisions occur."""
    import sympy as sp

    from solver.publish import render as R
    q1, q2, m2, l1, d2 = sp.symbols("q1 q2 m2 l1 d2")
    k = m2 * l1 * d2 * sp.cos(q2) + m2 * d2**2
    exprs = [k, sp.Matrix([[k, k / 2], [k / 2, -k]]), k * sp.sin(q1 - q2) + (k + 1) ** 2,
             sp.Float(2.0, 15) * k + sp.Float(2.0, 30) * k**2, sp.Matrix([k, sp.Float(0.5) * q1])]
    plain = R.Latex({}, {})
    for e in exprs:
        assert R._expr_str(e) == str(e)
        memo = R.Latex({}, {})
        memo(k)  # fills the memo first
        assert memo(e) == plain.printer.doprint(e) or memo(e) == plain(e)


def test_list_items_over_several_lines_stay_one_item():
    """A statement's item wrapped over indented lines is one item in LaTeX and HTML (the exams' statements are
    written so); a line that is not indented after the list ends it."""
    from solver.publish.render import md2html, md2tex
    text = ("Answer:\n\n- a) the Jacobian and\n  its singularities;\n- b) the *algorithmic*\n  singularities"
            " $\\det J = 0$.\nThen the rest.")
    tex = md2tex(text)
    assert tex.count("\\begin{itemize}") == 1 and tex.count("\\item ") == 2
    assert "\\item a) the Jacobian and its singularities;" in tex
    assert "\\item b) the \\emph{algorithmic} singularities $\\det J = 0$." in tex
    assert tex.index("\\end{itemize}") < tex.index("Then the rest.")
    html = md2html("- a) the Jacobian and\n  its singularities;\n- b) the rest")
    assert html == "<ul><li>a) the Jacobian and its singularities;</li><li>b) the rest</li></ul>"


def test_an_entry_zero_at_the_reference_is_not_drawn_flat():
    """b12 = f(q3) sin q2 vanishes for every q3 with q2 = 0: the q3 panel leaves it out (a flat line on the axis
    read as a result) and the caption says so; it is still drawn against q2."""
    p = load_problem(PROBLEMS / "2017-05-29-final-ex3b.yaml")
    sols = solve_problem(p)
    fig = next(f for f in sols[0].figures if f.name == "inertia")
    by_axis = {panel.xlabel: [c.label for c in panel.curves] for panel in fig.panels}
    assert by_axis == {"$q_{2}$": ["$b_{12}$", "$b_{13}$"], "$q_{3}$": ["$b_{22}$"]}
    assert "Not drawn (zero at these values of the other coordinates): $b_{12}$ against $q_{3}$." in fig.caption
    for panel in fig.panels:
        assert all(max(abs(y) for y in c.y) > 0.1 for c in panel.curves)


def test_terms_of_a_sum_ordered_once_for_text_and_latex(monkeypatch):
    """Both printers take a sum's terms in sympy's printing order (termorder.ordered_terms), computed once per sum;
    the printed text and LaTeX are sympy's own. Sums with floats are not shared (equal floats may print with
    other precisions)."""
    from sympy.printing.latex import LatexPrinter

    import solver.publish.render as R
    a, b, q = sp.symbols("a b q")
    e = 3 * a * sp.cos(q) - sp.Rational(1, 2) * b * sp.sin(2 * q) + a ** 2 - 7
    text = str(e)
    tex = LatexPrinter({"fold_short_frac": False, "fold_func_brackets": True}).doprint(e)
    import solver.publish.termorder as T
    calls = []
    real = T.ordered_terms
    counting = lambda expr, *x, **k: calls.append(expr) or real(expr, *x, **k)  # noqa: E731
    monkeypatch.setattr(R, "ordered_terms", counting)  # (sums with floats)
    monkeypatch.setattr(T, "ordered_terms", counting)  # (the memoized printing order)
    T._PRINTING_ORDER.clear()
    assert R._Str().doprint(e) == text
    assert R._Printer({}, {}).doprint(e) == tex
    assert calls.count(e) == 1
    f = sp.Float("0.1", 30) * a + b
    R._Str().doprint(f), R._Str().doprint(f)
    assert calls.count(f) == 2


def test_details_json_writes_sets_in_a_fixed_order():
    """A set in a step (the revolute joints of a singularity analysis) is written sorted, not in the set's own
    order, which changes from run to run."""
    from solver.publish.render import _Steps, latex_printer
    q1, q2, q10 = sp.symbols("q1 q2 q10")
    p = load_problem(PROBLEMS / "2011-09-12-ex1.yaml")
    steps = _Steps(latex_printer(p), {}, True)
    assert [x["expr"] for x in steps({q2, q10, q1})] == ["q1", "q10", "q2"]


def test_a_term_wider_than_the_page_is_broken_inside_its_parentheses():
    """term_parts: a long term ± r·A/d (A a sum) is written as ± \\frac{r}{d}\\Big(a_1 + ... a_m\\Big) over parts
    a multline can break; a short term, or one without a sum, stays one part; a sum r keeps its parentheses."""

    from solver.publish.render import Latex, join_terms, term_parts
    tex = Latex({}, {})
    q1, q2, D, d, m3, Iy, dq1, a, b = sp.symbols("q1 q2 D d m3 Iy dq1 a b")
    X = D**2 - 4 * D * d + 4 * d**2 + q1**2 - 2 * q1 * q2 + q2**2
    A = sp.expand((D**2 + q1**2 + q2**2) ** 2 * m3 + Iy * (D - 2 * d) ** 2)
    parts = term_parts(dq1**2 * A / (4 * X**2), tex)
    assert len(parts) == len(A.args)
    assert parts[0].startswith("\\frac{") and "}\\Big(" in parts[0] and parts[-1].endswith("\\Big)")
    inner = join_terms(parts).split("\\Big(", 1)[1][:-len("\\Big)")]
    assert inner == tex(A)  # the sum itself, in its printed order
    neg = term_parts(-dq1**2 * A / (4 * X**2), tex)
    assert neg[0].startswith("- \\frac{") and neg[1:] == parts[1:]
    long_sum = sp.expand(A * (q1 + q2 + D))
    with_sum = term_parts((a - b) * long_sum * q1, tex)
    assert len(with_sum) == len(long_sum.args)
    assert with_sum[0].startswith("\\left(q_{1} \\left(a - b\\right)\\right)\\Big(") or with_sum[0].startswith(
        "q_{1} \\left(a - b\\right)\\Big("), with_sum[0][:60]
    assert term_parts((a - b) * long_sum, tex)[0].startswith("\\left(a - b\\right)\\Big(")  # not a - b\\Big(
    assert term_parts(a * b, tex) == [tex(a * b)]
    assert term_parts(sp.sin(q1) ** 40 * sp.cos(q2) ** 40 * a**7 * b**9 * D**3 * Iy**5 * m3**2, tex) == [
        tex(sp.sin(q1) ** 40 * sp.cos(q2) ** 40 * a**7 * b**9 * D**3 * Iy**5 * m3**2)]  # no sum: one part
    # a fraction already wider than the page before a short sum: no break inside the sum (2018-03-27-ex1's
    # "\Big(I_p \\ + d_p^2 m_p\Big)"), one part
    wide = dq1**2 * (Iy + d**2 * m3) / (4 * A * X**2)
    assert term_parts(wide, tex) == [tex(wide)]


@pytest.mark.skipif(not shutil.which("pdflatex"), reason="pdflatex not installed")
@pytest.mark.parametrize("name", ["2012-07-05-ex1", "2020-09-11-remote-ex4", "2020-04-15-remote-midterm-ex5",
                                  "2016-09-12-ex1", "2017-06-06-ex1", "2018-07-11-ex3", "2020-09-11-remote-ex3"])
def test_long_entries_stay_inside_the_page(tmp_path, name):
    """The rational model's kinetic energies and the constrained model's long entries are broken inside their
    fractions' parentheses; a 3x3 inertia matrix shown beside c and g too wide for one line is written entry by
    entry, and a matrix with long entries has them on several lines; J# and q̇_ps(q) are two displays, a long
    null-space motion is displayed, a task's 2x2 Jacobian too (no longer in the sentence): no line of these
    reports runs past the right margin (before: up to 1896 pt, 1601 pt for the 3x3 inertia matrix, 243 pt for
    J# beside q̇_ps, 203 pt for the inline null-space motions, 101 pt for the inline Jacobian)."""
    p = load_problem(PROBLEMS / f"{name}.yaml")
    (tmp_path / "r.tex").write_text(render(p, solve_problem(p), "tex"))
    r = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "r.tex"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stdout[-2000:]
    widths = [float(w) for w in re.findall(r"Overfull \\hbox \(([0-9.]+)pt too wide\)", r.stdout)]
    assert not widths, widths


def test_wide_matrices_break_their_long_entries_and_narrow_ones_are_unchanged():
    """The report's tex filter (Latex with a width): a matrix row wider than the page gets its long entries on
    lines within the cell (a sum at its signs, a quotient as numerator over denominator, each on lines), every
    line within the budget; a matrix that fits prints exactly as without a width; fractions are measured by the
    wider of numerator and denominator."""
    from solver.publish.render import MATRIX_WIDTH, Latex, printed_width, visible_length
    a, b, c, q1, q2 = sp.symbols("a b c q1 q2")
    plain, report = Latex({}, {}), Latex({}, {}, width=MATRIX_WIDTH)
    narrow = sp.Matrix([[a + b, a * sp.cos(q1)], [0, c]])
    assert report(narrow) == plain(narrow)
    long_sum = sp.expand((a + b + c + 1) ** 3 * sp.cos(q1) + (a - c) ** 2 * sp.sin(q2))
    wide = sp.Matrix([[long_sum, a], [long_sum / (a**2 + b**2 + c**2 + 2 * a * b * sp.cos(q2) + 7), c]])
    out = report(wide)
    assert out != plain(wide) and out.count("\\begin{aligned}") == 2  # the sum, and the quotient's numerator
    lines = [ln for cell in re.findall(r"\\begin\{aligned\}(?:\[t\])?(.*?)\\end\{aligned\}", out)
             for ln in cell.split("\\\\")]
    assert len(lines) > 6 and max(visible_length(ln) for ln in lines) <= MATRIX_WIDTH
    assert printed_width("\\frac{a + b + c}{d}") == 5 and printed_width("x + \\frac{1}{2}") == 3


def test_equations_share_a_line_when_they_fit_and_go_entry_by_entry_otherwise():
    from solver.publish.render import Latex, equations
    a, b, q = sp.symbols("a b q")
    tex = Latex({}, {})
    small = [("B", sp.Matrix([[a, 0], [0, b]]), "b"), ("g", sp.Matrix([a * sp.cos(q), 0]), "g")]
    assert equations(small, tex, punct=".") == \
        f"\\[B = {tex(small[0][1])}, \\qquad g = {tex(small[1][1])}.\\]"
    big = sp.expand((a + b + 1) ** 6)
    out = equations([("x", None, ""), ("B", sp.Matrix([[big, a], [a, b]]), "b")], tex, punct=".")
    assert out.startswith("\\[x,\\]") and "b_{11}" in out and "b_{22} = b" in out and out.rstrip().endswith(".\\]")


def test_a_long_term_inside_a_long_quotient_is_broken_too():
    """u = n/d written (1/d)(n) over lines: a term of n that is itself wider than the page (r·A, A a long sum) is
    broken inside its own parentheses, so that every line of the multline stays within the page (2021-02-04-ex3:
    457 pt past the margin before)."""
    from solver.publish.render import Latex, equation, visible_length
    tex = Latex({}, {})
    a, b, c, q = sp.symbols("a b c q")
    long_sum = sp.expand((a + b + c + 2) ** 4)
    n = a * b * long_sum * sp.sin(q) + sp.expand((a - c) ** 3) + b**2 * c
    out = equation(n / (a * sp.sin(q) + b * sp.cos(q)), "u", "u", tex)
    lines = out.split("\n")[1:-1]
    assert out.startswith("\\begin{multline*}") and len(lines) > 4
    assert max(visible_length(ln) for ln in lines) <= 80, max(lines, key=visible_length)


def test_a_long_product_is_broken_inside_its_parentheses():
    """x = -L (a₁ + … + a_m) wider than the page: written -L\\Big(a₁ … a_m\\Big) over the lines of a multline
    (2021-07-12-ex1's task accelerations ran 226 pt past the margin on one line)."""
    from solver.publish.render import Latex, equation, visible_length
    tex = Latex({}, {})
    L, q1, q2, q3 = sp.symbols("L q1 q2 q3")
    A = sum(sp.Symbol(f"a{k}") * sp.sin(q1 + k * q2) + sp.Symbol(f"b{k}") * sp.cos(q3 - k * q1) for k in range(1, 6))
    out = equation(-L * A, "x", "x", tex)
    lines = out.split("\n")[1:-1]
    assert out.startswith("\\begin{multline*}") and lines[0].startswith("x = - L\\Big(") and len(lines) >= 3
    assert lines[-1].endswith("\\Big)") and max(visible_length(ln) for ln in lines) <= 80


def test_tree_size_counts_as_preorder_traversal():
    """is_large's memoized node count equals sympy's preorder traversal, repeated subtrees counted each time."""
    import random
    from solver.publish.render import LARGE_TEXT, is_large, tree_size
    x, y = sp.symbols("x y")
    rng = random.Random(3)
    for _ in range(200):
        e = x
        for _ in range(rng.randint(1, 30)):
            a = rng.choice([x, y, sp.Rational(rng.randint(-3, 3), rng.randint(1, 4)), e])
            e = rng.choice([lambda: e + a, lambda: e * a, lambda: sp.sin(e), lambda: sp.cos(a - e),
                            lambda: (e + y) ** rng.randint(2, 3)])()
        assert tree_size(e) == sum(1 for _ in sp.preorder_traversal(e))
    shared = sp.Add(*[sp.sin(x + k) for k in range(10)])
    big = sp.Mul(*[shared + k for k in range(120)], evaluate=False)
    assert tree_size(big) == sum(1 for _ in sp.preorder_traversal(big)) > LARGE_TEXT
    assert is_large(big, LARGE_TEXT) and not is_large(shared, LARGE_TEXT) and not is_large("text")


def test_long_expressions_print_each_shared_subexpression_once(monkeypatch):
    """The direct printers of long expressions (JSON text and LaTeX) print a subexpression shared by several
    results once (u = B a shares the numerators of a), to the same text; not with floats (equal values may print
    with other precisions)."""
    import solver.publish.render as R
    q1, q2, m1, m2, c = sp.symbols("q1 q2 m1 m2 c")
    num = sp.Add(*[(k + 1) * sp.cos(k * q1 - q2) * q2 ** k / 3 - sp.sin(q1 + k * q2) for k in range(25)])
    den = 1 + sp.cos(q2) ** 2
    a = num / den
    u1, u2 = m1 * a + c, m2 * a - c
    latex = R.Latex({})
    memo_text: dict = {}
    texts = [R._fast_str(e, memo_text) for e in (a, u1, u2)]
    assert texts == [R._fast_str(e) for e in (a, u1, u2)]
    assert parse_expr(texts[1], local_dict={s.name: s for s in (q1, q2, m1, m2, c)}) == u1
    tex = [latex.fast(e, latex._fast_memo) for e in (a, u1, u2)]
    assert tex == [latex.fast(e) for e in (a, u1, u2)]
    printed: list = []
    text_of, tex_of = R._fast_text, R.Latex._fast
    monkeypatch.setattr(R, "_fast_text", lambda e, memo: printed.append(e) or text_of(e, memo))
    monkeypatch.setattr(R.Latex, "_fast", lambda self, e, memo: printed.append(e) or tex_of(self, e, memo))
    u3 = m1 * m2 * a
    R._fast_str(u3, memo_text), latex.fast(u3, latex._fast_memo)
    assert num not in printed and den ** -1 not in printed and u3 in printed
    printed.clear()
    R._fast_str(u3)   # (without a memo: everything again)
    assert num in printed


def test_an_even_power_of_a_sum_prints_without_a_leading_minus():
    """(−D + 2d)² is printed (D − 2d)² (2012-07-05-ex1's B), (π/3 − q1)² as (q1 − π/3)²; a base that prints
    without a leading minus and an odd power are left as they are."""
    from solver.publish.render import Latex
    tex = Latex({}, {})
    D, d, q1, x, xd = sp.symbols("D d q1 x x_d")
    assert tex((2 * d - D) ** 2) == "\\left(D - 2 d\\right)^{2}"
    assert tex(250 * (sp.pi / 3 - q1) ** 2) == "250 \\left(q_{1} - \\frac{\\pi}{3}\\right)^{2}"
    assert tex((xd - x) ** 2) == "\\left(x - x_{d}\\right)^{2}"
    assert tex(sp.sin(D - d) * (D - d) ** 2).count("\\left(D - d\\right)^{2}") == 1   # printed so already
    assert tex((2 * d - D) ** 3).startswith("\\left(- D + 2 d\\right)^{3}")  # odd: the sign matters


def test_a_formula_too_wide_for_a_sentence_is_displayed_in_latex_only():
    """``inline``: $lhs = value$ in the sentence when it fits (about half a line); in LaTeX a wider one is
    displayed, a long sum broken into lines and a wide matrix entry by entry (named after lhs without its
    arguments); Markdown keeps every formula inline."""
    from solver.publish.render import Latex, inline
    a, b, q1, q2 = sp.symbols("a b q1 q2")
    tex = Latex({}, {})
    short = a * sp.cos(q1)
    assert inline(short, "U", tex, "tex", ",") == f"$U = {tex(short)}$,"
    long_sum = sp.expand((a + b + 1) ** 4 * sp.cos(q1 + q2))
    out = inline(long_sum, "U", tex, "tex", ".")
    assert out.startswith(("\\[U = ", "\\begin{multline*}\nU = ")) and "$" not in out and out.count("\\\\") >= 2
    wide = sp.Matrix([[long_sum, a], [a, b]])
    out = inline(wide, "J(q)", tex, "tex", ".")
    assert "{J}_{11} = " in out and "{J}_{22} = b" in out
    row = sp.Matrix([[a * sp.sin(q1), a * sp.cos(q1) + b, 0, a * b, b * sp.cos(q2), a]])
    assert inline(row, "r", tex, "tex").startswith("\\[r = \\begin{bmatrix}")
    square = sp.Matrix([[a * sp.sin(q1) + b * sp.cos(q2) + a * b * sp.cos(q1), a * b], [b, a + b]])  # tall
    assert inline(square, "J", tex, "tex") == f"\\[J = {tex(square)}\\]"
    assert inline(square[0, :], "J", tex, "tex") == f"$J = {tex(square[0, :])}$"
    assert inline(long_sum, "U", tex, "md", ".") == f"$U = {tex(long_sum)}$."


def test_whole_decimals_print_as_integers():
    """sympy's Float(2.0) == 2 is False: the values at a state (approx) and kinematics' 4-digit numbers (_nfy)
    test wholeness on the float, so that 2 q̇₁ does not print 2.0 q̇₁ (2017-07-11-ex3's c at the state)."""
    from solver.kinematics.analysis import _nfy
    from solver.publish.render import Latex, approx
    x, y = sp.symbols("x y")
    c = sp.Rational(3, 10) * y * (2 * x + y) + 3 * x * y
    out = Latex({}, {})(approx(sp.Matrix([c])))
    assert "0.3" in out and "2.0" not in out and "3.0" not in out and "2 x" in out
    assert _nfy(sp.Float(3.0)) == 3 and _nfy(sp.Float(3.0)).is_Integer and _nfy(sp.Float(2.5)) == sp.Float(2.5, 4)


def test_a_quotient_that_fits_stacked_is_one_fraction_and_a_long_head_takes_a_line():
    """_broken measures a quotient stacked (printed_width): numerator and denominator that each fit are one
    fraction, not (1/d)(n) over lines (2021-04-14-remote-midterm-ex1's j21); when (1/d)\\Big( is a third of the
    line and the first term would overfill it, the first line holds the head alone (2013-02-06-ex1's λ: 155 pt
    past the margin before)."""
    from solver.publish.render import Latex, _broken, visible_length
    tex = Latex({}, {})
    l1, r, q1, q2, m, I, d = sp.symbols("l1 r q1 q2 m I d")
    j = (-l1 * sp.cos(q1) + r * sp.sin(q1 + q2) - (r + l1) * sp.cos(q1 + q2)) / (l1 * (r * sp.cos(q2) + l1 * sp.sin(q2)))
    assert _broken("j", tex(j), "", 70, j, tex) == f"\\[j = {tex(j)}\\]"
    den = I * sp.cos(q1) ** 2 + d**2 * m * sp.cos(q1) ** 2 + m * q2**2
    num = m * (l1 * q2 + 2 * I * q1 * q2 + 2 * d**2 * m * q1 * q2 - 2 * d * m * q2 * q1 + I * q2**2 * l1) * sp.sin(q1) \
        - (r - d * m * q1**2) * (I + m * q2**2 + d**2 * m - 2 * d * m * q2) * sp.cos(q1)
    out = _broken("\\lambda", tex(num / den), ".", 70, num / den, tex)
    lines = out.split("\\\\")
    assert out.startswith("\\begin{multline*}") and lines[0].rstrip().endswith("\\Big(")
    assert all(visible_length(ln) <= 80 for ln in lines[1:])


def test_formula_width_measures_a_matrix_by_its_columns():
    """formula_width: a bmatrix is as wide as its widest cells per column (a column vector as its widest entry),
    fractions by their wider line: what decides whether r and J share a display (kinematics' configuration)."""
    from solver.publish.render import formula_width, visible_length
    column = "r = \\begin{bmatrix} a + b \\\\ c \\end{bmatrix}"
    assert formula_width(column) == visible_length("r = ") + 3 + 2 < visible_length(column)
    square = "J = \\begin{bmatrix} \\frac{a + b}{2} & c \\\\ d & e f \\end{bmatrix}"
    assert formula_width(square) == visible_length("J = ") + 3 + 2 + 4 + 2


def test_a_displayed_matrix_counts_its_left_side_and_its_fractions_as_printed():
    """equation() keeps a matrix whole when its cells, measured as printed (a fraction as wide as its wider line),
    and its left-hand side fit the line: a 2×2 J⁻¹ of fractions stays one matrix (it went entry by entry when its
    numerators and denominators were counted side by side), while a vector whose entries fill the line is written
    entry by entry behind a long left-hand side (2022-02-03-ex1's g(q) = (∂U/∂q)ᵀ ran 50 pt past the margin)."""
    from solver.publish.render import Latex, equation
    tex = Latex({}, {})
    l1, l2, q1, q2, g0, m1, m2, m3, d1, d2, d3 = sp.symbols("l1 l2 q1 q2 g0 m1 m2 m3 d1 d2 d3")
    det = l1 * l2 * sp.sin(q2)
    Jinv = sp.Matrix([[l2 * sp.cos(q1 + q2) / det, l2 * sp.sin(q1 + q2) / det],
                      [(-l1 * sp.cos(q1) - l2 * sp.cos(q1 + q2)) / det, (-l1 * sp.sin(q1) - l2 * sp.sin(q1 + q2)) / det]])
    assert equation(Jinv, "J^{-1}(q)", "{J^{-1}}", tex, ".") == f"\\[J^{{-1}}(q) = {tex(Jinv)}.\\]"
    entry = (d3 * g0 * m3 * sp.cos(q1 + q2) + g0 * (d1 * m1 + l1 * m2 + l1 * m3) * sp.cos(q1)
             + g0 * (d2 * m2 - m2 * q2 - m3 * q2) * sp.sin(q1))
    g = sp.Matrix([entry, g0 * (m2 + m3) * sp.cos(q1)])
    assert equation(g, "g", "g", tex, ".") == f"\\[g = {tex(g)}.\\]"
    long_lhs = equation(g, "g(q) = \\left(\\frac{\\partial U}{\\partial q}\\right)^T", "g", tex, ".")
    assert "\\begin{bmatrix} g_{i} \\end{bmatrix}" in long_lhs and "g_{2} = " in long_lhs


def test_a_matrix_over_a_long_common_denominator_writes_it_once():
    """A matrix too wide for the line whose entries share one long denominator Δ (an inverse, a pseudoinverse) is
    written (1/Δ) N, Δ on its own line once, N whole when it fits and entry by entry otherwise (2021-02-04-ex3's J#
    repeated a three-line denominator in each of its six entries); entries over different denominators, a short
    denominator, or a symbol printed Δ keep the entry-by-entry form."""
    from solver.publish.render import Latex, common_denominator, equation
    tex = Latex({}, {})
    a, b, c, q1, q2 = sp.symbols("a b c q1 q2")
    d = (a + b + c) ** 3 + a * b * c * sp.cos(q2) + a**2 * sp.sin(q1) + b**2 * c * sp.cos(q1 + q2)
    N = sp.Matrix([[a * sp.cos(q1), -b * sp.sin(q1 + q2)], [c, 0]])
    out = equation(N / d, "J^{-1}(q)", "j", tex, ".")
    lines = out.split("\n")
    assert lines[0] == f"\\[J^{{-1}}(q) = \\frac{{1}}{{\\Delta}}\\,{tex(N)}, \\quad\\text{{with}}\\]"
    assert lines[1:] == [f"\\[\\Delta = {tex(d)}.\\]"]
    wide = N.applyfunc(lambda e: e * sp.expand((a + 2 * b + q1) ** 3) if e != 0 else e)
    out = equation(wide / d, "J^{-1}(q)", "j", tex, ".")
    assert "\\frac{1}{\\Delta}\\begin{bmatrix} n_{ij} \\end{bmatrix}" in out and out.count("\\Delta =") == 1
    assert "n_{11} = " in out and "n_{22}" in out and "and $n_{22} = 0$." in out and "\\frac" not in out.split(
        "n_{11}")[1]
    assert common_denominator(-N / d, tex, 70)[1] == -N  # (the sign of the quotients stays in N)
    mixed = sp.Matrix([[a / d, b / (d + 1)], [c / d, 0]])
    assert common_denominator(mixed, tex, 70) is None and "j_{12} = " in equation(mixed, "J", "j", tex)
    assert common_denominator(N / (a + b), tex, 70) is None  # short: each entry reads well
    Delta = sp.Symbol("Delta")
    assert common_denominator(N.subs(c, Delta) / d, tex, 70) is None
