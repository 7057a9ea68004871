"""Grading: verdicts, partial credit, property checks, common mistakes, robustness against hostile answers."""
from __future__ import annotations

import csv
import json

import pytest
import sympy as sp
from conftest import PROBLEMS, ROOT
from hypothesis import given, settings
from hypothesis import strategies as st

from solver.grading.gradebook import answer_template, grade_files, gradescope_json, write_outputs
from solver.grading.grader import INVALID, MISSING, ItemSpec, grade, prepare
from solver.grading.submission import Submission, load_submission
from solver.math.equivalence import CORRECT, INCORRECT, scalar_equiv
from solver.spec import load_problem

SUBS = ROOT / "examples" / "submissions" / "2004-03-25-ex1"


@pytest.fixture(scope="module")
def ref():
    return prepare(load_problem(PROBLEMS / "2004-03-25-ex1.yaml"))


def items(report):
    return {i.name: i for i in report.items}


def sub(answers, where=None):
    return Submission("t", "t.yaml", answers, where or {})


def test_all_correct_with_abbreviations(ref):
    rep = grade(ref, load_submission(SUBS / "alice.yaml"))
    assert rep.student == "Alice" and rep.total == rep.max_total == 12
    assert all(i.verdict == CORRECT for i in rep.items)


def test_latex_answers_and_factorization_by_property(ref):
    rep = grade(ref, load_submission(SUBS / "bob.yaml"))
    it = items(rep)
    assert it["B"].verdict == CORRECT and it["c"].verdict == CORRECT  # LaTeX pmatrix / bmatrix
    assert it["christoffel"].verdict == MISSING and it["christoffel"].score == 0
    # S q̇ = c holds but Ḃ - 2S is not skew-symmetric: half the points, and said so
    assert it["S"].verdict == INCORRECT and it["S"].score == 1 and "not skew-symmetric" in " ".join(it["S"].feedback)
    assert it["g"].score == 1 and "wrong components: 2" in it["g"].feedback and "2: sign flipped" in it["g"].feedback
    assert rep.total == 4 + 2 + 1 + 1


def test_per_entry_credit_and_invalid_answers(ref):
    rep = grade(ref, load_submission(SUBS / "carol.json"))
    it = items(rep)
    assert it["B"].verdict == CORRECT  # JSON list of lists of strings
    assert it["christoffel"].score == pytest.approx(2 * 7 / 8)  # one entry of 8 wrong
    assert "item 2: wrong entries (1,1)" in it["christoffel"].feedback[0]
    assert it["c"].score == 1 and "2: sign flipped" in it["c"].feedback
    assert it["g"].verdict == INVALID and "m2l1" in it["g"].feedback[0] and "'*'" in it["g"].feedback[0]


def test_broken_file_gets_a_row(ref):
    rep = grade(ref, load_submission(SUBS / "dave.yaml"))
    assert rep.total == 0 and all(i.verdict == INVALID for i in rep.items) and "YAML syntax" in rep.notes[0]


def test_alternative_correct_forms(ref):
    alt = {
        # trig identities, expanded/factored forms, row vector for a column, transposed-symmetric B
        "B": "[[I1 + I2 + m1*d1^2 + m2*(l1^2 + q2^2*(sin(q1)^2 + cos(q1)^2)), m2*l1], [l1*m2, m2]]",
        "c": "[[m2*q2*dq1*dq2*2, -m2*q2*dq1*dq1]]",
        "g": "[g0*m2*q2*cos(q1) + 2*g0*(m1*d1 + m2*l1)*sin(q1/2)*cos(q1/2), g0*m2*cos(q1 - pi/2)]",
        "S": "$\\begin{bmatrix} m_2 q_2 \\dot q_2 & m_2 q_2 \\dot q_1 \\\\ -m_2 \\dot q_1 q_2 & 0 \\end{bmatrix}$",
    }
    it = items(grade(ref, sub(alt)))
    assert [it[k].verdict for k in alt] == [CORRECT] * 4, [it[k].feedback for k in alt]
    # S q̇ = c also holds for this S, but Ḃ - 2S is not skew-symmetric: half the points
    it = items(grade(ref, sub({"S": "[[0, 2*m2*q2*dq1], [-m2*q2*dq1, 0]]"})))
    assert it["S"].verdict == INCORRECT and it["S"].score == 1


def test_common_mistakes_are_named(ref):
    it = items(grade(ref, sub({
        "B": "[[I1 + I2 + m1*d1^2 + m2*l1^2 + m2*q2^2, m2*l1], [m2*l1, 2*m2]]",
        "g": "[g0*m2*q2*cos(q1), g0*m2*sin(q1)/2]",
    })))
    assert "(2,2): twice the correct value (a factor 2 too many)" in it["B"].feedback
    assert it["B"].score == pytest.approx(4 * 3 / 4)
    fb = " ".join(it["g"].feedback)
    assert "a term is missing" in fb and "half the correct value" in fb


def test_transposed_matrix_and_shape(ref):
    it = items(grade(ref, sub({"S": "[[m2*q2*dq2, -m2*q2*dq1], [m2*q2*dq1, 0]]", "B": "[1, 2]"})))
    assert "the matrix is transposed" in it["S"].feedback
    assert it["B"].verdict == INCORRECT and it["B"].feedback[0].startswith("wrong shape: 2")


def test_potential_energy_up_to_a_constant():
    problem = load_problem(PROBLEMS / "2004-03-25-ex1.yaml")
    r = prepare(problem)
    r.items = {"U": ItemSpec(points=2)}
    U = r.results["U"].value
    it = items(grade(r, sub({"U": str(U + 7 * sp.Symbol("g0") * sp.Symbol("m2", positive=True))})))
    assert it["U"].verdict == CORRECT and "additive constant" in it["U"].feedback[0]
    r.items = {"U": ItemSpec(points=2, accept="reference")}
    assert items(grade(r, sub({"U": str(U) + " + 1"})))["U"].verdict == INCORRECT


def test_equilibria_sets_and_numbers():
    r = prepare(load_problem(PROBLEMS / "2005-04-05-ex1.yaml"))
    r.items = {"equilibria": ItemSpec(points=2), "n_equilibria": ItemSpec(points=1)}
    good = {"equilibria": "[[-pi/2, m1*d1/m2], [3*pi/2 - 2*pi + pi, m1*d1/m2]]", "n_equilibria": "2"}
    it = items(grade(r, sub(good)))
    assert it["equilibria"].verdict == CORRECT and it["n_equilibria"].verdict == CORRECT
    half = items(grade(r, sub({"equilibria": "[[pi/2, m1*d1/m2]]", "n_equilibria": 2.0004})))
    assert half["equilibria"].score == 1 and half["n_equilibria"].verdict == CORRECT  # 1e-3 relative default


def test_printed_erratum_is_recognized():
    r = prepare(load_problem(PROBLEMS / "2016-06-06-ex1.yaml"))  # printed T2 misses a factor 1/2
    printed, why = r.errata["T2"]
    r.items = {"T2": ItemSpec()}
    it = items(grade(r, sub({"T2": str(printed)})))
    assert it["T2"].verdict == INCORRECT and "printed in the official solution" in it["T2"].feedback[0]
    assert items(grade(r, sub({"T2": str(r.results["T2"].value)})))["T2"].verdict == CORRECT


@pytest.mark.parametrize("answer", ["9^9^9^9", "(" * 10000 + "q1" + ")" * 10000, "x" * 1_000_000,
                                    "__import__('os').system('ls')", "q1.__class__", "lambda: 0",
                                    "$\\input{/etc/passwd}$", "[[1, 2], [3]]", "{{{{", "1/0"])
def test_hostile_answers_are_invalid_quickly(ref, answer):
    it = items(grade(ref, sub({"B": answer, "g": answer})))
    assert it["B"].verdict in (INVALID, INCORRECT) and it["B"].score == 0


@settings(max_examples=80, deadline=None)
@given(st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=60))
def test_fuzz_random_text_never_crashes(text):
    r = _REF
    it = items(grade(r, sub({"B": text, "c": text, "g": text})))
    assert all(i.verdict in (CORRECT, INCORRECT, INVALID, MISSING, "undecided") for i in it.values())


q1, q2 = sp.symbols("q1 q2", real=True)
a, b = sp.symbols("a b", positive=True)
atoms = st.sampled_from([a, b, q2, sp.Integer(3), sp.cos(q1), sp.sin(q2), sp.cos(q1 + q2), sp.sin(q1 - q2)])
exprs = st.recursive(atoms, lambda e: st.one_of(st.builds(sp.Add, e, e), st.builds(sp.Mul, e, e)), max_leaves=8)


@settings(max_examples=80, deadline=None)
@given(exprs)
def test_fuzz_equivalence_no_false_verdicts(e):
    assert scalar_equiv(sp.expand_trig(e), e).verdict == CORRECT  # trig identities: never a false 'incorrect'
    assert scalar_equiv(e + a * sp.sin(q1) ** 2, e).verdict == INCORRECT  # a real difference: never 'correct'


_REF = prepare(load_problem(PROBLEMS / "2004-03-25-ex1.yaml"))


def test_batch_outputs_gradescope_and_rerun(ref, tmp_path):
    files = sorted(SUBS.iterdir())
    reports = grade_files(ref, files, jobs=2)
    assert [r["student"] for r in reports] == ["Alice", "Bob", "Carol", "dave"]
    out = tmp_path / "results"
    for _ in range(2):  # a re-run overwrites: nothing duplicated
        write_outputs(ref.problem, ref, reports, out, gradescope=True)
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert [r["student"] for r in rows] == ["Alice", "Bob", "Carol", "dave"]
    assert rows[0]["total"] == "12" and rows[0]["B"] == "4" and rows[3]["total"] == "0"
    gs = json.loads((out / "gradescope" / "bob.yaml" / "results.json").read_text())
    assert set(gs) >= {"score", "output", "tests"} and gs["score"] == 8
    assert all(set(t) >= {"name", "score", "max_score", "status", "output"} for t in gs["tests"])
    assert {t["status"] for t in gs["tests"]} <= {"passed", "failed"}
    md = (out / "carol.json.md").read_text()
    assert "| `g` | invalid |" in md and "Score:" in md
    assert not list(out.glob(".*.tmp"))
    assert gradescope_json(reports[0])["score"] == 12


def test_answer_template_round_trip(ref, tmp_path):
    text = answer_template(ref)
    for name in ("B:", "christoffel:", "c:", "S:", "g:", "student:", "where:"):
        assert f"\n{name}" in text
    (tmp_path / "blank.yaml").write_text(text)
    rep = grade(ref, load_submission(tmp_path / "blank.yaml"))  # a blank sheet: every item missing, no crash
    assert all(i.verdict == MISSING for i in rep.items)


def test_redundancy_items_numbers_within_tolerance():
    """grade works for the redundancy ask: numeric vectors with tolerance, booleans, symbolic Jacobians."""
    r = prepare(load_problem(PROBLEMS / "2019-04-29-midterm-ex5.yaml"))
    r.items = {"qdot_ps": ItemSpec(points=2), "singular": ItemSpec(), "J": ItemSpec(), "rank": ItemSpec()}
    good = {"qdot_ps": "[0.1179, -0.7071]", "singular": "0", "rank": 1,
            "J": "$\\begin{bmatrix} 0 & -\\frac{l_1 l_2 \\sin q_2}{\\sqrt{l_1^2 + l_2^2 + 2 l_1 l_2 \\cos q_2}} "
                 "\\end{bmatrix}$"}
    it = items(grade(r, sub(good)))
    assert all(i.verdict == CORRECT for i in it.values()), {k: i.feedback for k, i in it.items()}
    it = items(grade(r, sub({"qdot_ps": "[0.1179, 0.7071]", "singular": "1", "rank": 2})))
    assert it["qdot_ps"].score == 1 and "2: sign flipped" in it["qdot_ps"].feedback
    assert it["singular"].verdict == INCORRECT and it["rank"].verdict == INCORRECT
    assert items(grade(r, sub({"singular": False})))["singular"].verdict == CORRECT  # YAML false
    assert items(grade(r, sub({"singular": "yes"})))["singular"].verdict == INCORRECT
    r.items = {"qdot_ps": ItemSpec(sigfigs=2)}
    assert items(grade(r, sub({"qdot_ps": "[0.12, -0.71]"})))["qdot_ps"].verdict == CORRECT


_syms = {n: _REF.problem.names[n] for n in ("q1", "q2", "m2", "l1", "d1", "g0")}
_atoms = st.sampled_from([_syms["m2"], _syms["l1"], _syms["q2"], sp.Integer(2), sp.cos(_syms["q1"]),
                          sp.sin(_syms["q2"]), sp.cos(_syms["q1"] + _syms["q2"]), sp.sin(_syms["q1"]) ** 2])
_valid = st.recursive(_atoms, lambda e: st.one_of(st.builds(sp.Add, e, e), st.builds(sp.Mul, e, e),
                                                   st.builds(lambda x, y: x - y, e, e)), max_leaves=7)


@settings(max_examples=60, deadline=None)
@given(_valid)
def test_fuzz_grader_with_random_valid_answers(e):
    """g answered as the reference plus a random expression e (written out by sympy, re-read by the parser):
    'correct' exactly when e vanishes identically (decided independently by float sampling)."""
    import random as _r
    g = _REF.results["g"].value
    answer = f"[{g[0] + e}, {g[1]}]"
    it = items(grade(_REF, sub({"g": answer})))
    rng = _r.Random(0)
    f = sp.lambdify(list(_syms.values()), e)
    vanishes = all(abs(f(*[rng.uniform(0.3, 2.0) for _ in _syms])) < 1e-9 for _ in range(5))
    assert it["g"].verdict == (CORRECT if vanishes else INCORRECT), (e, it["g"].feedback)


def test_degrees_for_radians_and_time_limit():
    from solver.grading.grader import diagnose
    assert diagnose(sp.Integer(90), sp.pi / 2) == ["degrees and radians mixed up"]
    r = prepare(load_problem(PROBLEMS / "2004-03-25-ex1.yaml"))
    r.spec.time_limit = 1e-6  # every item runs out of time: left for manual review, never guessed
    it = items(grade(r, sub({"B": "[[1, 2], [3, 4]]"})))
    assert it["B"].verdict == "undecided" and "manual review" in it["B"].feedback[0]


def test_linear_parametrization_by_property():
    """(Y, a): any grouping with Y a = model, a free of the state, Y free of dynamic parameters, dim a minimal."""
    from solver.results import Result
    r = prepare(load_problem(PROBLEMS / "2004-03-25-ex1.yaml"))
    n = r.problem.names
    q1, q2, dq1, dq2, ddq1, ddq2 = (n[k] for k in ("q1", "q2", "dq1", "dq2", "ddq1", "ddq2"))
    l1, g0 = n["l1"], n["g0"]
    a = sp.Matrix([n["I1"] + n["I2"] + n["m1"] * n["d1"] ** 2, n["m2"], n["m1"] * n["d1"]])
    Y = sp.Matrix([[ddq1, (l1**2 + q2**2) * ddq1 + l1 * ddq2 + 2 * q2 * dq1 * dq2 + g0 * q2 * sp.cos(q1)
                    + g0 * l1 * sp.sin(q1), g0 * sp.sin(q1)],
                   [0, l1 * ddq1 + ddq2 - q2 * dq1**2 + g0 * sp.sin(q1), 0]])
    r.results["Y"], r.results["a"] = Result("Y", Y, "matrix"), Result("a", a, "vector")
    r.items = {"Y": ItemSpec(points=2), "a": ItemSpec(points=1)}
    printed = {  # the printed grouping: a1 also holds m2 l1^2, a3 = m1 d1 + m2 l1
        "a": "[I1 + I2 + m1*d1^2 + m2*l1^2, m2, m1*d1 + m2*l1]",
        "Y": "[[ddq1, q2^2*ddq1 + l1*ddq2 + 2*q2*dq1*dq2 + g0*q2*cos(q1), g0*sin(q1)],"
             " [0, l1*ddq1 + ddq2 - q2*dq1^2 + g0*sin(q1), 0]]"}
    it = items(grade(r, sub(printed)))
    assert it["Y"].verdict == CORRECT and it["a"].verdict == CORRECT, (it["Y"].feedback, it["a"].feedback)
    split = {"a": "[I1 + I2 + m1*d1^2 + m2*l1^2, m2, m1*d1, m2*l1]",  # valid but one coefficient too many
             "Y": "[[ddq1, q2^2*ddq1 + l1*ddq2 + 2*q2*dq1*dq2 + g0*q2*cos(q1), g0*sin(q1), g0*sin(q1)],"
                  " [0, l1*ddq1 + ddq2 - q2*dq1^2 + g0*sin(q1), 0, 0]]"}
    it = items(grade(r, sub(split)))
    assert it["Y"].score == 1 and "not minimal" in it["Y"].feedback[0]
    cheat = {"a": "[1]", "Y": str([[str(x)] for x in (Y * a)]).replace("'", "")}
    assert "must not contain dynamic parameters" in items(grade(r, sub(cheat)))["Y"].feedback[0]
    wrong = dict(printed, a="[I1 + I2 + m1*d1^2 + m2*l1^2, m2, m1*d1 - m2*l1]")
    assert "differs from the dynamic model in equation(s) 1" in items(grade(r, sub(wrong)))["a"].feedback[0]


def test_same_polynomial_is_exact_both_ways() -> None:
    """The rational-point shortcut of reduce_conditions only proves inequality; equality still by expansion."""
    import sympy as sp

    from solver.math.equivalence import _same_polynomial
    x, y, k = sp.symbols("x y k")
    assert _same_polynomial((x + y) ** 2, x**2 + 2 * x * y + y**2)
    assert not _same_polynomial((x + y) ** 2, x**2 + y**2)
    assert not _same_polynomial(k / (x - y), k / (x + y))


def test_same_polynomial_with_a_shared_point() -> None:
    """reduce_conditions compares at one point of all the symbols of the set: the answers are those of the
    pairwise points (the point only proves differences), also where it lacks a symbol or hits a pole."""
    import sympy as sp

    from solver.math.equivalence import _common_point, _same_polynomial
    x, y, k, m = sp.symbols("x y k m", positive=True)
    pairs = [((x + y) ** 2, x**2 + 2 * x * y + y**2), ((x + y) ** 2, x**2 + y**2), (k / (x - y), k / (x + y)),
             (k * (m + 1), k * m + k), (m * x, x * m + y), (1 / (x - 1), 1 / (x - 1) + y - y)]
    x0 = _common_point([x]).params[x]  # the value of x at a point whose first symbol is x: a pole of 1/(x - x0)
    pairs += [(1 / (x - x0), 1 / (x - x0) + 0 * y), (k / (x - x0), k * x),
              (y / (x - x0), (x * y - x0 * y) / (x - x0)**2)]
    shared = _common_point([e for a, b in pairs for e in (a, b)])
    for a, b in pairs:
        want = _same_polynomial(a, b)
        assert _same_polynomial(a, b, shared) == want
        assert _same_polynomial(a, b, _common_point([x])) == want     # at the pole
        assert _same_polynomial(a, b, _common_point([m])) == want     # symbols missing: decided by expansion
