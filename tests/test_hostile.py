"""Hostile and broken files (issue 8): nothing outside the class folder is read, nothing runs, hangs, leaks or
overwrites. One test (at least) per item of the issue; each failed on the main of 2026-11-23."""
from __future__ import annotations

import csv
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import PROBLEMS, ROOT

from solver.grading.gradebook import (ResultsFolder, grade_files, output_name, submission_entries, summary_csv,
                                      write_outputs)
from solver.grading.grader import INVALID, prepare
from solver.grading.submission import load_submission
from solver.publish.render import md2html, md2tex
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.spec.expr import parse
from solver.spec.texmath import math_problem, safe_math
from solver.spec.yamlpos import load_text

RP = PROBLEMS / "2004-03-25-ex1.yaml"
SUBS = ROOT / "examples" / "submissions" / "2004-03-25-ex1"
SECRET = "robosolve-secret-4f1c"  # written outside the class folder; must never appear in any output

BOMB = "a: &a [x,x,x,x,x,x,x,x,x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8))
WHERE_CHAIN = "where:\n  a1: 9^100\n" + "".join(f"  a{k}: a{k - 1}^100\n" for k in range(2, 12)) + \
    'B: "[[1, 0], [0, 1]]"\n'


def run(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "solver", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=timeout)


@pytest.fixture(scope="module")
def ref():
    return prepare(load_problem(RP))


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    d = tmp_path / "outside"
    d.mkdir()
    (d / "secret.txt").write_text(SECRET + "\n")
    (d / "other.yaml").write_text(f"student: {SECRET}\nB: \"[[1, 0], [0, 1]]\"\n")
    return d


def _outputs_text(out: Path) -> str:
    return "\n".join(p.read_text(errors="replace") for p in out.rglob("*") if p.is_file())


# 1 ------------------------------------------------------------------------------------------ links
def test_links_out_of_the_class_folder_are_not_followed(ref, tmp_path, outside):
    cls = tmp_path / "class"
    cls.mkdir()
    shutil.copy(SUBS / "alice.yaml", cls / "alice.yaml")
    (cls / "x.yaml").symlink_to(outside / "secret.txt")
    (cls / "y.yaml").symlink_to(outside / "other.yaml")
    (cls / "z.yaml").symlink_to(cls / "alice.yaml")  # a link inside the folder is fine
    entries = submission_entries(cls)
    why = {e.label: e.problem for e in entries}
    assert why["x.yaml"] and "outside the class folder" in why["x.yaml"] and why["y.yaml"] == why["x.yaml"]
    assert why["alice.yaml"] is None and why["z.yaml"] is None
    reports = grade_files(ref, entries, jobs=2)
    assert [r["file"] for r in reports] == ["alice.yaml", "x.yaml", "y.yaml", "z.yaml"]
    assert reports[0]["total"] == reports[3]["total"] == 12
    assert all(it["verdict"] == INVALID for r in reports[1:3] for it in r["items"])
    out = tmp_path / "res"
    write_outputs(ref.problem, ref, reports, out, gradescope=True)
    assert SECRET not in _outputs_text(out)


# 2 ------------------------------------------------------------------------------------------ LaTeX
@pytest.mark.parametrize("tex", [r"\input{/etc/passwd}", r"\mbox{\catcode`\_=12 \input{/etc/passwd}}",
                                 r'\input{|"kpsewhich -var-value=HOME"}', r"\def\x{\x}\x", r"^^5cinput{/etc/passwd}",
                                 r"\csname input\endcsname{/etc/passwd}", r"\write18{ls}", "a % comment", r"x^{2",
                                 r"\begin{filecontents}{x}\end{filecontents}", r"\href{javascript:x}{y}"])
def test_latex_math_allow_list_refuses(tex):
    assert math_problem(tex) is not None
    assert "\\input" not in safe_math(tex) and "\\def" not in safe_math(tex) and "^^" not in safe_math(tex)


@pytest.mark.parametrize("tex", [r"\ddot q_1 + \frac{m_2 l_1}{2}\cos(q_2)", r"\begin{pmatrix} a & b \\ c & d \end{pmatrix}",
                                 r"\tau = B(q)\ddot{q} + \mathbf{c}", r"\theta_{1} \in [0, 2\pi)", r"\dot{\rho}_d",
                                 r"\left\| J^{\#} \right\|", r"K_P > 0,\ K_D > 0"])
def test_latex_math_allow_list_accepts_exam_math(tex):
    assert math_problem(tex) is None and safe_math(tex) == tex


SPEC = RP.read_text()


@pytest.mark.parametrize("edit", [
    ("Derive the dynamic model", r"Derive $\input{/etc/passwd}$ the dynamic model"),
    ("m1: mass of link 1", r"m1: {meaning: mass of link 1, latex: '\input{/etc/passwd}'}"),
])
def test_check_refuses_latex_that_reads_files(write, edit):
    assert edit[0] in SPEC
    path = write(SPEC.replace(edit[0], edit[1], 1))
    with pytest.raises(UserError) as err:
        load_problem(path)
    assert "not allowed in math" in str(err.value) and str(path) in str(err.value)
    r = run("check", str(path))
    assert r.returncode == 2 and "Traceback" not in r.stderr


def test_a_statement_that_slipped_through_never_reaches_latex():
    """md2tex (every statement's way into LaTeX) puts math through the allow-list even when loading was bypassed."""
    out = md2tex(r"Read $\input{/etc/passwd}$ and $$\def\x{\x}\x$$ but keep $\ddot q_1$.")
    assert "\\input" not in out and "\\def" not in out and r"$\ddot q_1$" in out


@pytest.mark.skipif(not shutil.which("pdflatex"), reason="needs pdflatex")
def test_the_compiler_is_paranoid(tmp_path, outside):
    """Even a .tex that asks for it cannot read outside its build folder (kpathsea paranoid mode, no shell)."""
    from solver.publish.handout import compile_latex
    work = tmp_path / "work"
    work.mkdir()
    tex = work / "x.tex"
    tex.write_text("\\documentclass{article}\\begin{document}A \\input{" + str(outside / "secret.txt") +
                   "} \\input{|\"echo pwned\"} B\\end{document}\n")
    with pytest.raises(UserError) as err:
        compile_latex(tex, tmp_path / "x.pdf", timeout=60)
    assert SECRET not in str(err.value) and not (tmp_path / "x.pdf").exists()


@pytest.mark.skipif(not shutil.which("pdflatex"), reason="needs pdflatex")
def test_a_looping_macro_is_stopped(tmp_path):
    from solver.publish.handout import compile_latex
    tex = tmp_path / "loop.tex"
    tex.write_text("\\documentclass{article}\\begin{document}\\def\\x{\\x}\\x\\end{document}\n")
    with pytest.raises(UserError, match="did not finish"):
        compile_latex(tex, tmp_path / "loop.pdf", timeout=3)


# 3 ------------------------------------------------------------------------------------------ HTML
def test_html_images_cannot_carry_attributes_or_scripts():
    for md in ['![x" onerror="alert(1)](y)', 'see ![x" onerror="alert(1)](y) here', '![a](javascript:alert(1))']:
        html = md2html(md)
        assert 'onerror="' not in html and "javascript:" not in html and "<img " in html


# 4 ------------------------------------------------------------------------------------------ hanging
@pytest.mark.parametrize("text", ['x: !!python/object/apply:os.system ["echo PWNED"]', "x: !foo bar",
                                  "x: !!binary AAAA", "x: !!set {a, b}"])
def test_yaml_tags_are_refused(text):
    with pytest.raises(UserError, match="tags"):
        load_text(text, "t.yaml")


def test_alias_bomb_is_refused_at_once():
    with pytest.raises(UserError, match="aliases"):
        load_text(BOMB, "bomb.yaml")


def test_a_huge_matrix_is_not_read(tmp_path):
    big = tmp_path / "big.yaml"
    row = "[" + ", ".join(["m1*q1 + 1"] * 400) + "]"
    big.write_text("B: [" + ",\n".join([row] * 400) + "]\n")
    sub = load_submission(big, "big.yaml")
    assert sub.error and "too large" in sub.error


# 5
def test_where_chain_does_not_hang(ref, tmp_path):
    f = tmp_path / "chain.yaml"
    f.write_text(WHERE_CHAIN)
    [rep] = grade_files(ref, [f], jobs=1)
    assert any("abbreviation 'a2' ignored" in n for n in rep["notes"])
    assert {it["name"]: it["verdict"] for it in rep["items"]}["B"] == "incorrect"


# 6
@pytest.mark.parametrize("value", ["1e999999999", "'1e999999999'", ".inf", "1" * 5000])
def test_huge_numbers_in_a_spec_are_refused(write, value):
    spec = SPEC.replace("id: 2004-03-25-ex1", f"id: 2004-03-25-ex1\nvalues: {{g0: {value}}}")
    with pytest.raises(UserError):
        load_problem(write(spec))


def test_huge_numbers_in_exam_values_are_refused(tmp_path):
    exam = tmp_path / "e.yaml"
    exam.write_text(f"title: X\nproblems:\n  - problem: {RP}\n    values: {{g0: '1e999999999'}}\n")
    r = run("check", str(exam), timeout=60)
    assert r.returncode == 2 and "number out of range" in r.stderr


# 7
def test_a_tower_of_powers_is_invalid_at_once(ref):
    from solver.grading.grader import grade
    from solver.grading.submission import Submission
    rep = grade(ref, Submission("t", "t.yaml", {"B": "(((q1+m1)^100)^100)^100"}))
    assert {i.name: i.verdict for i in rep.items}["B"] == INVALID
    with pytest.raises(Exception, match="too high degree"):
        parse("(((q1+m1)^100)^100)^100", {"q1": __import__("sympy").Symbol("q1"), "m1": __import__("sympy").Symbol("m1")})


def test_a_hard_limit_stops_what_signals_cannot():
    """The per-file worker is killed when C code ignores the alarm (a huge integer power)."""
    from solver.sandbox import TIME, Limits, run_many
    out = run_many(lambda n: 10 ** (10 ** n), [9], 1, Limits(2.0, 2048))
    assert out[0].failure == TIME


# 8 ------------------------------------------------------------------------------------------ losing data
def test_output_names_never_collide(ref, tmp_path):
    cls = tmp_path / "class"
    cls.mkdir()
    names = ["a b.yaml", "a_b.yaml", "张伟.yaml", "王芳.yaml", "dup.yaml", "dup.json", "x" * 200 + "1.yaml",
             "x" * 200 + "2.yaml", ".hidden.yaml", "%41.yaml", "A.yaml"]
    for n in names:
        shutil.copy(SUBS / "alice.yaml", cls / n)
    entries = submission_entries(cls)
    assert len(entries) == len(names)
    outs = {output_name(e.label) for e in entries}
    assert len(outs) == len(names) and all(len(o.encode()) <= 200 and not o.startswith(".") for o in outs)
    reports = grade_files(ref, entries, jobs=2)
    out = tmp_path / "res"
    written = write_outputs(ref.problem, ref, reports, out)
    assert len(set(written)) == len(written) == 2 * len(names) + 1
    rows = list(csv.DictReader((out / "summary.csv").open(encoding="utf-8")))
    assert sorted(r["file"] for r in rows) == sorted(names)
    assert all((out / f"{r['output']}.md").exists() for r in rows)


# 9
@pytest.mark.parametrize("bad", ["file", "under_file", "proc"])
def test_a_bad_out_is_refused_before_grading(tmp_path, bad):
    target = {"file": tmp_path / "f.txt", "under_file": tmp_path / "f.txt" / "res", "proc": Path("/proc/x/res")}[bad]
    (tmp_path / "f.txt").write_text("keep me")
    r = run("grade", str(RP), str(SUBS), "--out", str(target), timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "--out" in r.stderr
    assert "graded" not in r.stderr and r.stdout == ""  # refused before any grading
    assert (tmp_path / "f.txt").read_text() == "keep me"


def test_an_interrupted_write_leaves_the_previous_results(ref, tmp_path):
    out = tmp_path / "res"
    reports = grade_files(ref, sorted(SUBS.iterdir()), jobs=1)
    write_outputs(ref.problem, ref, reports, out)
    before = {p.name: p.read_text() for p in out.iterdir()}
    folder = ResultsFolder(out)  # a second run, killed in its write phase: never committed
    folder.write("summary.csv", "half")
    folder.fd and os.close(folder.fd)  # the process dies: the lock goes, the hidden folder stays
    folder.fd = None
    assert {p.name: p.read_text() for p in out.iterdir()} == before
    assert list(tmp_path.glob(".res.tmp-*"))
    write_outputs(ref.problem, ref, reports[:2], out)  # the next run cleans up and replaces the whole set
    assert not list(tmp_path.glob(".res.tmp-*"))
    assert sorted(p.name for p in out.iterdir()) == sorted([".robosolve-results", "summary.csv", "alice.yaml.md",
                                                            "alice.yaml.json", "bob.yaml.md", "bob.yaml.json"])


def test_a_folder_robosolve_did_not_write_is_not_replaced(ref, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    with pytest.raises(UserError, match="did not write"):
        ResultsFolder(out)
    assert (out / "thesis.tex").read_text() == "precious"


def test_two_runs_on_one_out_do_not_mix(tmp_path):
    first = ResultsFolder(tmp_path / "res")
    try:
        with pytest.raises(UserError, match="another robosolve run"):
            ResultsFolder(tmp_path / "res")
    finally:
        first.close()


# 10
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX")
def test_odd_directory_entries_get_rows(ref, tmp_path):
    cls = tmp_path / "class"
    cls.mkdir()
    shutil.copy(SUBS / "alice.yaml", cls / "alice.yaml")
    (cls / "dangling.yaml").symlink_to(cls / "gone.yaml")
    (cls / "folder.yaml").mkdir()
    os.mkfifo(cls / "fifo.yaml")
    (cls / "zero.yaml").symlink_to("/dev/zero")
    (cls / "big.yaml").write_bytes(b"B: x\n" + b"#" * 300_000)
    (cls / "binary.json").write_bytes(bytes(range(256)) * 8)
    reports = grade_files(ref, submission_entries(cls), jobs=2)
    by = {r["file"]: r for r in reports}
    assert sorted(by) == sorted(p.name for p in cls.iterdir())
    assert by["alice.yaml"]["total"] == 12
    notes = {k: " ".join(r["notes"]) for k, r in by.items()}
    assert "dangling" in notes["dangling.yaml"] and "folder" in notes["folder.yaml"]
    assert "not a regular file" in notes["fifo.yaml"] and "outside the class folder" in notes["zero.yaml"]
    assert "larger than" in notes["big.yaml"] and "UTF-8" in notes["binary.json"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX")
def test_single_file_mode_never_blocks(tmp_path):
    os.mkfifo(tmp_path / "fifo.yaml")
    for f in (tmp_path / "fifo.yaml", Path("/dev/zero")):
        r = run("grade", str(RP), str(f), timeout=60)
        assert r.returncode == 2 and "not a regular file" in r.stderr


def test_earlier_feedback_files_are_removed(ref, tmp_path):
    out = tmp_path / "res"
    reports = grade_files(ref, sorted(SUBS.iterdir()), jobs=1)
    write_outputs(ref.problem, ref, reports, out)
    assert (out / "dave.yaml.md").exists()
    write_outputs(ref.problem, ref, reports[:1], out)
    assert not (out / "dave.yaml.md").exists()


# 11 ---------------------------------------------------------------------------------------- injection
def test_names_cannot_inject_formulas_or_break_the_feedback(ref, tmp_path):
    f = tmp_path / "evil.yaml"
    f.write_text('student: "=HYPERLINK(\\"http://x\\",\\"y\\")\\n# Score: 100/100"\nB: "[[1, 0], [0, 1]]"\n')
    [rep] = grade_files(ref, [f], jobs=1)
    text = summary_csv([rep], list(ref.items))
    row = list(csv.reader(text.splitlines()))[1]
    assert row[0].startswith("'=") and "\n" not in row[0]
    from solver.grading.gradebook import feedback_markdown
    md = feedback_markdown(ref.problem, rep)
    assert md.splitlines()[0].startswith("# ") and "\n# Score" not in md


# 12 ---------------------------------------------------------------------------------------- tracebacks
@pytest.mark.parametrize("text", ["a: " + "[" * 20000 + "]" * 20000, "".join(" " * i + f"k{i}:\n" for i in range(3000)),
                                  "x: " + "9" * 5000])
def test_deep_or_huge_yaml_is_a_user_error(text):
    with pytest.raises(UserError):
        load_text(text, "x.yaml")


def test_cli_options_are_checked_before_work(tmp_path):
    assert run("solve", str(RP), "-o", str(tmp_path)).returncode == 2  # a folder
    r = run("handout", str(RP), "-o", "/proc/x/out.pdf")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    r = run("grade", str(RP), str(SUBS), "-j", "-3", "--out", str(tmp_path / "r"))
    assert r.returncode == 2 and "Traceback" not in r.stderr


def test_escaped_emoji_in_a_spec_is_text(write, tmp_path):
    spec = SPEC.replace("title: Planar RP robot in a vertical plane", 'title: "RP robot \\ud83d\\udca5"')
    assert spec != SPEC
    problem = load_problem(write(spec))
    assert problem.title == "RP robot \U0001F4A5"
    r = run("handout", str(write(spec, "e.yaml")), "--format", "md", "-o", str(tmp_path / "h.md"))
    assert r.returncode == 0, r.stderr
    lone = SPEC.replace("title: Planar RP robot in a vertical plane", 'title: "RP \\ud83d"')
    with pytest.raises(UserError, match="surrogate"):
        load_problem(write(lone, "lone.yaml"))


def test_check_validates_the_grading_block(write):
    path = write(SPEC.replace("grading:\n", "grading:\n  time_limit: -1\n", 1))
    r = run("check", str(path))
    assert r.returncode == 2 and "time_limit" in r.stderr


def test_feedback_has_no_grader_paths_and_files_are_readable(ref, tmp_path):
    cls = tmp_path / "class"
    cls.mkdir()
    (cls / "broken.yaml").write_text('B: "[[a, b]\n')
    reports = grade_files(ref, submission_entries(cls), jobs=1)
    out = tmp_path / "res"
    write_outputs(ref.problem, ref, reports, out)
    assert str(tmp_path) not in _outputs_text(out)
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE((out / "summary.csv").stat().st_mode) == 0o666 & ~umask  # as any file the user writes
    assert stat.S_IMODE(out.stat().st_mode) == 0o777 & ~umask


# fuzzing (short in CI; HYPOTHESIS_PROFILE=long for more) ------------------------------------------
def _bounded_ok(fn) -> None:
    """``fn`` runs in a worker with 10 s and 512 MB: it must finish (an error is fine, a hang or crash is not)."""
    from solver.sandbox import Limits, run_many
    [out] = run_many(lambda _: (fn(), None)[1], [0], 1, Limits(10.0, 512))
    assert out.failure in (None, "user"), out  # another exception, a time-out, a memory blow-up: a bug


from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

settings.register_profile("ci", max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
settings.register_profile("long", max_examples=1000, deadline=None, suppress_health_check=list(HealthCheck))
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

HOSTILE = st.sampled_from([BOMB, WHERE_CHAIN, "x: 1e999999999", "- " * 200, "{" * 500, "&a [*a]", "!!python/object:os.system ls",
                           "a: !!binary AAAA", "? [a, b]\n: c", "x: \\ud83d", "B: $\\input{/etc/passwd}$", "<<: *x"])
YAMLISH = st.one_of(HOSTILE, st.text(max_size=300), st.lists(HOSTILE, max_size=4).map("\n".join),
                    st.builds(lambda a, b: a + b, HOSTILE, st.text(max_size=80)))


@given(YAMLISH)
def test_fuzz_spec_loader(text):
    _bounded_ok(lambda: _try(lambda: load_problem_text(text, "fuzz.yaml")))


@given(YAMLISH)
def test_fuzz_submission_reader(text):
    def go() -> None:
        import tempfile
        with tempfile.TemporaryDirectory() as d:
            f = Path(d) / "s.yaml"
            f.write_text(text, encoding="utf-8", errors="surrogatepass")
            load_submission(f, "s.yaml")
    _bounded_ok(go)


LATEXISH = st.lists(st.sampled_from(["\\frac{", "}", "{", "\\input", "^^5c", "\\begin{pmatrix}", "\\end{pmatrix}",
                                     "q_1", "\\dot", "$", "&", "\\\\", "\\sin", "(", ")", "^", "2", "\\csname",
                                     "\\def\\x{\\x}\\x", "%"]), max_size=30).map("".join)


@given(st.one_of(LATEXISH, st.text(max_size=200)))
def test_fuzz_expression_parsers(text):
    import sympy as sp

    from solver.grading.latex_in import parse_latex
    names = {"q1": sp.Symbol("q1"), "m1": sp.Symbol("m1")}
    _bounded_ok(lambda: _try(lambda: parse(text, names)))
    _bounded_ok(lambda: _try(lambda: parse_latex("$" + text + "$", names, {"q_1": "q1", "m_1": "m1"})))
    _bounded_ok(lambda: (math_problem(text), safe_math(text)))


def _try(fn) -> None:
    try:
        fn()
    except UserError:
        pass


# the class of the acceptance point --------------------------------------------------------------------
def make_hostile_class(folder: Path, outside: Path, n: int = 300) -> list[str]:
    """A class of ``n`` ordinary submissions (copies of the examples) plus an alias bomb, a where-chain, a 50 MB
    file, a binary file, links out of the folder, colliding names and a folder named like a submission. Returns
    the names a teacher expects a row for."""
    folder.mkdir(parents=True, exist_ok=True)
    examples = sorted(SUBS.iterdir())
    for k in range(n):
        shutil.copy(examples[k % len(examples)], folder / f"s{k:03d}{examples[k % len(examples)].suffix}")
    (folder / "bomb.yaml").write_text(BOMB)
    (folder / "chain.yaml").write_text(WHERE_CHAIN)
    with open(folder / "huge.yaml", "wb") as f:
        f.truncate(50 * 1024 * 1024)
    (folder / "binary.json").write_bytes(os.urandom(4096))
    (folder / "link.yaml").symlink_to(outside / "secret.txt")
    (folder / "link2.yaml").symlink_to(outside / "other.yaml")
    for name in ("a b.yaml", "a_b.yaml", "dup.yaml", "dup.json", "张伟.yaml", "张 伟.yaml"):
        shutil.copy(examples[0], folder / name)
    (folder / "folder.yaml").mkdir()
    return sorted(p.name for p in folder.iterdir())


def test_a_hostile_class_of_300(tmp_path, outside):
    """Every entry gets a row of its own, nothing outside the folder is read, the workers stay under 1 GB
    (the time is measured in benchmarks/hostile_class.py, against the clean class)."""
    import resource
    names = make_hostile_class(tmp_path / "class", outside)
    out = tmp_path / "res"
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    r = run("grade", str(RP), str(tmp_path / "class"), "--out", str(out), "-j", "2", timeout=1800)
    assert r.returncode == 0, r.stderr[-2000:]
    peak_kb = max(before, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    assert peak_kb < 1024 * 1024
    rows = list(csv.DictReader((out / "summary.csv").open(encoding="utf-8")))
    assert sorted(r["file"] for r in rows) == names
    assert len({r["output"] for r in rows}) == len(rows)
    assert all((out / f"{row['output']}.md").exists() for row in rows)
    by = {row["file"]: row for row in rows}
    assert by["s000.yaml"]["total"] == "12" and by["bomb.yaml"]["total"] == "0"
    assert SECRET not in _outputs_text(out)


@pytest.mark.skipif(not shutil.which("pdflatex"), reason="needs pdflatex")
def test_a_latex_error_names_the_exercise_and_its_spec(tmp_path):
    """Not a deleted temporary file: the exercise, the spec file and line of its statement, and the kept .tex."""
    from solver.publish.handout import compile_latex
    from solver.spec.errors import Place
    work = tmp_path / "work"
    work.mkdir()
    tex = work / "h.tex"
    tex.write_text("\\documentclass{article}\\begin{document}\n\\section*{Exercise 1}\nfine\n"
                   "\\section*{Exercise 2}\n\\undefinedcommand\n\\end{document}\n")
    places = [Place("problems/a.yaml", 5, 1), Place("problems/b.yaml", 7, 1)]
    with pytest.raises(UserError) as err:
        compile_latex(tex, tmp_path / "h.pdf", timeout=60, places=places)
    text = str(err.value)
    assert "in exercise 2" in text and text.startswith("problems/b.yaml:7:1") and "Undefined control sequence" in text
    assert (tmp_path / "h.failed.tex").exists() and "h.failed.tex" in text
