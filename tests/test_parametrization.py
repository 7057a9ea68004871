"""The `linear_parametrization` ask: Y a ≡ model exactly (planar 2R against a hand-written model, RP, a spatial
3R), minimality (numeric rank of Y stacked at random states), given coefficients (valid, insufficient, dependent,
non-minimal), options, the report, and the printed values of the encoded exam problems."""
import random
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, R2_ROBOT, RP_ROBOT, check_and_solve

from solver.dynamics.model import derive
from solver.dynamics.parametrization import canonical, check
from solver.math.simplify import is_zero
from solver.publish.render import render
from solver.solve import all_results, solve_problem, validate_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem

HEAD_2R = """
id: t2r
title: planar 2R in a vertical plane
symbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, g0: g0, fv1: fv1, fv2: fv2}
""" + R2_ROBOT + "{friction}known: [l1, g0]\nasks:\n"

RP = RP_ROBOT + "known: [l1, g0]\nasks:\n"

SPATIAL_3R = """
id: t3r
title: spatial anthropomorphic 3R
symbols: {m1: m1, m2: m2, m3: m3, d2: d2, d3: d3, l2: l2, g0: g0, I1y: I1y, I2x: I2x, I2y: I2y, I2z: I2z,
          I3x: I3x, I3y: I3y, I3z: I3z}
robot:
  joints: [R, R, R]
  gravity: [0, 0, -g0]
  dh:
    table:
      - {a: 0, alpha: pi/2, d: 0, theta: q1}
      - {a: l2, alpha: 0, d: 0, theta: q2}
      - {a: 0, alpha: 0, d: 0, theta: q3}
    links:
      - {mass: m1, com: [0, 0, 0], inertia: [0, I1y, 0]}
      - {mass: m2, com: [d2 - l2, 0, 0], inertia: [I2x, I2y, I2z]}
      - {mass: m3, com: [d3, 0, 0], inertia: [I3x, I3y, I3z]}
known: [l2, g0]
asks:
  - kind: linear_parametrization
"""


def spec_2r(asks: str, friction: bool = False) -> str:
    return HEAD_2R.replace("{friction}", "  friction: {viscous: [fv1, fv2]}\n" if friction else "") + asks


def solve_text(text: str) -> tuple:
    problem = load_problem_text(text)
    return problem, all_results(solve_problem(problem))


def value(results: dict, name: str):
    return results[name].value


def stacked_rank(Y: sp.Matrix, robot, known: list, states: int = 6, seed: int = 3) -> int:
    """Numeric rank of Y evaluated at several random states (known symbols at random values), stacked."""
    rng = random.Random(seed)
    kv = {s: rng.uniform(0.5, 2.0) for s in known}
    syms = list(robot.q) + list(robot.dq) + list(robot.ddq)
    f = sp.lambdify(syms + list(kv), Y, "numpy")
    blocks = [np.array(f(*[rng.uniform(-2, 2) for _ in syms], *kv.values()), dtype=float) for _ in range(states)]
    M = np.vstack(blocks)
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > 1e-9 * s[0]))


def assert_exact(Y: sp.Matrix, a: sp.Matrix, model: sp.Matrix) -> None:
    for x in (Y * a - model):
        assert is_zero(sp.expand(x)) is True


# ------------------------------------------------------------------------------------------------ 2R
def hand_2r(s: dict, friction: bool = False) -> sp.Matrix:
    """The textbook planar 2R model, written by hand (relative angles, gravity along -y)."""
    q1, q2, dq1, dq2, ddq1, ddq2 = (s[k] for k in ("q1", "q2", "dq1", "dq2", "ddq1", "ddq2"))
    m1, m2, d1, d2, l1, I1, I2, g0 = (s[k] for k in ("m1", "m2", "d1", "d2", "l1", "I1", "I2", "g0"))
    a1 = I1 + m1 * d1**2 + I2 + m2 * (l1**2 + d2**2)
    a2 = I2 + m2 * d2**2
    a3 = m2 * l1 * d2
    B = sp.Matrix([[a1 + 2 * a3 * sp.cos(q2), a2 + a3 * sp.cos(q2)], [a2 + a3 * sp.cos(q2), a2]])
    c = sp.Matrix([-a3 * sp.sin(q2) * (dq2**2 + 2 * dq1 * dq2), a3 * sp.sin(q2) * dq1**2])
    g = sp.Matrix([g0 * (m1 * d1 + m2 * l1) * sp.cos(q1) + g0 * m2 * d2 * sp.cos(q1 + q2),
                   g0 * m2 * d2 * sp.cos(q1 + q2)])
    out = B * sp.Matrix([ddq1, ddq2]) + c + g
    if friction:
        out += sp.Matrix([s["fv1"] * dq1, s["fv2"] * dq2])
    return out


@pytest.mark.parametrize("friction", [False, True])
def test_planar_2r_computed_is_exact_and_minimal(friction):
    problem, r = solve_text(spec_2r("  - kind: linear_parametrization\n", friction))
    Y, a = value(r, "Y"), value(r, "a")
    assert Y.shape == (2, int(value(r, "p")))
    # against a hand-written model, not only against robosolve's own derivation
    assert_exact(Y, a, hand_2r(problem.names, friction))
    assert value(r, "Ya_check") is True
    # l1, g0 known: I1 + m1 d1^2 + I2 + m2 (d2^2 + l1^2), I2 + m2 d2^2, m2 d2, m1 d1 + m2 l1 (+ fv1, fv2)
    p = 6 if friction else 4
    assert value(r, "p") == p and value(r, "p_min") == p and value(r, "minimal") is True
    assert stacked_rank(Y, problem.robot, problem.known) == p
    n = problem.names
    assert sp.expand(a[0] - (n["I1"] + n["I2"] + n["m1"] * n["d1"]**2 + n["m2"] * (n["d2"]**2 + n["l1"]**2))) == 0
    assert n["m2"] * n["d2"] in list(a)
    assert any(sp.expand(x - n["m1"] * n["d1"] - n["m2"] * n["l1"]) == 0 for x in a)
    # Y is free of dynamic parameters
    dyn = {n[k] for k in ("m1", "m2", "d1", "d2", "I1", "I2", "fv1", "fv2")}
    assert not any(x.free_symbols & dyn for x in Y)


def test_planar_2r_given_coefficients():
    coeffs = "[I1 + m1*d1^2 + I2 + m2*(l1^2 + d2^2), I2 + m2*d2^2, m2*l1*d2, m1*d1 + m2*l1, m2*d2]"
    problem, r = solve_text(spec_2r(f"  - kind: linear_parametrization\n    coefficients: {coeffs}\n"))
    Y, a = value(r, "Y"), value(r, "a")
    q1, q2 = problem.names["q1"], problem.names["q2"]
    dq1, dq2, ddq1, ddq2 = (problem.names[k] for k in ("dq1", "dq2", "ddq1", "ddq2"))
    g0 = problem.names["g0"]
    # m2 l1 d2 and m2 d2 are proportional (l1 known): the a_i are dependent over the constants, the
    # parametrization is valid but not minimal (5 > 4), and each term goes to the coefficient of its known factors
    assert value(r, "p") == 5 and value(r, "p_min") == 4 and value(r, "minimal") is False
    assert value(r, "Ya_check") is True
    assert_exact(Y, a, hand_2r(problem.names))
    expected = sp.Matrix([
        [ddq1, ddq2, sp.cos(q2) * (2 * ddq1 + ddq2) - sp.sin(q2) * (dq2**2 + 2 * dq1 * dq2), g0 * sp.cos(q1),
         g0 * sp.cos(q1 + q2)],
        [0, ddq1 + ddq2, sp.cos(q2) * ddq1 + sp.sin(q2) * dq1**2, 0, g0 * sp.cos(q1 + q2)]])
    assert all(is_zero(sp.expand(x)) for x in (Y - expected))


# ------------------------------------------------------------------------------------------------ RP, spatial
def test_rp_computed_matches_the_printed_grouping():
    problem, r = solve_text(RP + "  - kind: linear_parametrization\n")
    n = problem.names
    Y, a = value(r, "Y"), value(r, "a")
    assert value(r, "p") == 3
    want_a = [n["I1"] + n["m1"] * n["d1"]**2 + n["I2"] + n["m2"] * n["l1"]**2, n["m2"],
              n["m1"] * n["d1"] + n["m2"] * n["l1"]]
    assert all(sp.expand(x - w) == 0 for x, w in zip(a, want_a))
    q1, q2, dq1, dq2, ddq1, ddq2, l1, g0 = (n[k] for k in ("q1", "q2", "dq1", "dq2", "ddq1", "ddq2", "l1", "g0"))
    want_Y = sp.Matrix([[ddq1, q2**2 * ddq1 + l1 * ddq2 + 2 * q2 * dq1 * dq2 + g0 * q2 * sp.cos(q1), g0 * sp.sin(q1)],
                        [0, l1 * ddq1 + ddq2 - q2 * dq1**2 + g0 * sp.sin(q1), 0]])
    assert all(is_zero(sp.expand(x)) for x in (Y - want_Y))
    assert_exact(Y, a, derive(problem.robot).lhs)
    assert stacked_rank(Y, problem.robot, problem.known) == 3


def test_spatial_3r_exact_and_minimal():
    problem, r = solve_text(SPATIAL_3R)
    Y, a, p = value(r, "Y"), value(r, "a"), int(value(r, "p"))
    assert Y.shape == (3, p) and a.shape == (p, 1)
    assert_exact(Y, a, derive(problem.robot).lhs)
    assert value(r, "Ya_check") is True and value(r, "minimal") is True
    assert stacked_rank(Y, problem.robot, problem.known) == p
    assert p == 7
    n = problem.names
    assert n["d3"] * n["m3"] in list(a)
    assert any(sp.expand(x - n["d2"] * n["m2"] - n["l2"] * n["m3"]) == 0 for x in a)


def test_parts_inertia_and_gravity():
    problem, r = solve_text(spec_2r("  - kind: linear_parametrization\n    part: inertia\n"
                                    "  - kind: linear_parametrization\n    part: gravity\n    suffix: _g\n"))
    dm = derive(problem.robot)
    Yb, ab = value(r, "Y"), value(r, "a")
    assert_exact(Yb, ab, dm.B * sp.Matrix(problem.robot.ddq))
    assert value(r, "p") == 3
    Yg, ag = value(r, "Y_g"), value(r, "a_g")
    assert_exact(Yg, ag, dm.g)
    assert value(r, "p_g") == 2 and not any(x.has(*problem.robot.ddq, *problem.robot.dq) for x in Yg)


def test_canonical_form_is_unique():
    q1, q2 = sp.symbols("q1 q2", real=True)
    state = {q1, q2}
    e1 = sp.cos(q1 + q2) ** 2 + sp.sin(2 * q2)
    e2 = 1 - sp.sin(q1 + q2) ** 2 + 2 * sp.sin(q2) * sp.cos(q2)
    assert canonical(e1, state) == canonical(e2, state)
    assert sp.expand(canonical(sp.sin(q2) ** 2 + sp.cos(q2) ** 2, state)) == 1


# ------------------------------------------------------------------------------------------------ given errors
RP_COEFFS = "    coefficients: {}\n"


def rp_with(coeffs: str) -> str:
    return RP + "  - kind: linear_parametrization\n" + RP_COEFFS.format(coeffs)


def test_insufficient_coefficients_error_at_the_line():
    with pytest.raises(UserError) as e:
        solve_text(rp_with("[I1 + m1*d1^2 + I2 + m2*l1^2, m2]"))
    err = e.value
    assert "cannot express the model" in err.message and "d1*m1" in err.message
    assert err.place is not None and err.place.line == RP.count("\n") + 2
    assert "minimal set" in err.hint


def test_wrongly_grouped_coefficients_are_insufficient():
    # I1 multiplies ddq1 in the first equation only, m2 also other functions: m2 cannot join the first group
    with pytest.raises(UserError, match="cannot express the model"):
        solve_text(rp_with("[I1 + m1*d1^2 + I2 + m2, m1*d1 + m2*l1]"))


def test_dependent_coefficients_error():
    with pytest.raises(UserError) as e:
        solve_text(rp_with("[I1 + m1*d1^2 + I2 + m2*l1^2, m2, 2*m2, m1*d1 + m2*l1]"))
    assert "not linearly independent" in e.value.message and "coefficient 3" in e.value.message
    # the error points at the third coefficient of the flow list
    line = RP.count("\n") + 2
    assert e.value.place.line == line and e.value.place.col > 40


@pytest.mark.parametrize("coeffs, words", [
    ("[I1 + m1*d1^2 + I2 + m2*l1^2, m2, 2*m2, m1*d1 + m2*l1]", "coefficient 3 is a combination of the previous"),
    ("[I1 + m1*d1^2 + I2 + m2*l1^2, m2*q2, m1*d1 + m2*l1]", "coefficient 2 depends on the state"),
    ("[I1 + m1*d1^2 + I2 + m2*l1^2, m2, m1*d1 + m2*l1, m2 - m2]", "coefficient 4 is zero"),
    ("[I1 + m1*d1^2 + I2 + m2*l1^2, sin(m2), m1*d1 + m2*l1]", "coefficient 2 is not a polynomial"),
    ("[[I1, m2], [m1, m2]]", "coefficients must be a list"),
])
def test_validation_raises_what_solve_raises(coeffs, words):
    """The checks of given coefficients that need no model are the kind's validate hook (what `check` runs):
    the error of solving, at the same place."""
    with pytest.raises(UserError) as e:
        solve_text(rp_with(coeffs))
    errors = validate_problem(load_problem_text(rp_with(coeffs)))
    assert [str(x) for x in errors] == [str(e.value)] and words in str(e.value)


def test_validation_accepts_coefficients_that_only_the_model_can_judge():
    """Dependent over the constants but not once the known l1 is a parameter (2R, solved as valid but not
    minimal), non-minimal, or insufficient (the model decides): no error without the model."""
    coeffs = "[I1 + m1*d1^2 + I2 + m2*(l1^2 + d2^2), I2 + m2*d2^2, m2*l1*d2, m1*d1 + m2*l1, m2*d2]"
    ask = f"  - kind: linear_parametrization\n    coefficients: {coeffs}\n"
    assert validate_problem(load_problem_text(spec_2r(ask))) == []
    for coeffs in ("[I1 + m1*d1^2, I2 + m2*l1^2, m2, m1*d1 + m2*l1]", "[I1 + m1*d1^2 + I2 + m2*l1^2, m2]"):
        assert validate_problem(load_problem_text(rp_with(coeffs))) == []


def test_check_reports_dependent_coefficients(write):
    """`check` of a spec without expected: values said ok; now exit 2 with solve's message."""
    check, solve = check_and_solve(write(rp_with("[I1 + m1*d1^2 + I2 + m2*l1^2, m2, m1*d1 + m2*l1, 2*m2]")))
    assert check.returncode == solve.returncode == 2 and check.stderr == solve.stderr, check.stderr
    assert "coefficient 4 is a combination of the previous ones (2*a2 - a4 = 0)" in check.stderr


def test_non_minimal_coefficients_note():
    problem, r = solve_text(rp_with("[I1 + m1*d1^2, I2 + m2*l1^2, m2, m1*d1 + m2*l1]"))
    assert value(r, "p") == 4 and value(r, "p_min") == 3 and value(r, "minimal") is False
    assert value(r, "Ya_check") is True
    md = render(problem, solve_problem(problem), "md")
    assert "not minimal" in md and "y_{1} - y_{2} = 0" in md and "A minimal set" in md


def test_coefficient_depending_on_the_state_is_refused():
    with pytest.raises(UserError, match="depends on the state"):
        solve_text(rp_with("[I1 + m1*d1^2 + I2 + m2*l1^2, m2*q2, m1*d1 + m2*l1]"))


def test_parameter_inside_a_function_asks_to_declare_it_known():
    text = RP.replace("known: [l1, g0]", "known: [g0]").replace(
        "com: [d1*cos(q1), d1*sin(q1)]", "com: [d1*cos(q1 + l1), d1*sin(q1 + l1)]")
    with pytest.raises(UserError) as e:
        solve_text(text + "  - kind: linear_parametrization\n")
    assert "not polynomial" in e.value.message and "l1" in e.value.hint


def test_same_coefficients_as_computed_give_the_same_Y():
    _, auto = solve_text(RP + "  - kind: linear_parametrization\n")
    coeffs = "[" + ", ".join(str(x).replace("**", "^") for x in value(auto, "a")) + "]"
    _, given = solve_text(rp_with(coeffs))
    assert all(is_zero(sp.expand(x)) for x in (value(auto, "Y") - value(given, "Y")))


def test_known_factor_inside_a_coefficient_goes_out_of_Y():
    problem, r = solve_text(rp_with("[I1 + m1*d1^2 + I2 + m2*l1^2, m2, g0*(m1*d1 + m2*l1)]"))
    Y = value(r, "Y")
    assert is_zero(sp.expand(Y[0, 2] - sp.sin(problem.names["q1"])))
    assert value(r, "minimal") is True


def test_symbol_option_and_default_on_clash():
    problem, _ = solve_text(rp_with("[I1 + m1*d1^2 + I2 + m2*l1^2, m2, m1*d1 + m2*l1]") + "    symbol: pi\n")
    md = render(problem, solve_problem(problem), "md")
    assert "\\pi_{1}" in md
    clash = RP.replace("m1: m1,", "m1: m1, a2: a constant,") + "  - kind: linear_parametrization\n"
    problem = load_problem_text(clash)
    assert "\\pi_{3}" in render(problem, solve_problem(problem), "md")


def test_check_detects_a_wrong_Y():
    problem, r = solve_text(RP + "  - kind: linear_parametrization\n")
    Y = value(r, "Y").copy()
    Y[1, 1] += problem.names["q2"]
    assert check(Y, value(r, "a"), derive(problem.robot).lhs) is False


# ------------------------------------------------------------------------------------------------ report
def test_markdown_report_reads_like_a_solution():
    problem = load_problem(PROBLEMS / "2005-04-05-ex1.yaml")
    md = render(problem, solve_problem(problem), "md")
    part = md[md.index("Linear parametrization"):]
    for text in ("Written term by term", "Dynamic coefficients", "Regressor", "Row by row", "In terms of the",
                 "Check.", "verified exactly", "minimum number of dynamic coefficients"):
        assert text in part


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex not installed")
def test_latex_report_compiles(tmp_path):
    for name in ("2021-04-14-remote-midterm-ex1", "2010-09-15-ex1"):
        out = tmp_path / f"{name}.tex"
        subprocess.run(["robosolve", "solve", str(PROBLEMS / f"{name}.yaml"), "--format", "tex", "-o", str(out)],
                       check=True, capture_output=True)
        run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", out.name], cwd=tmp_path,
                             capture_output=True, text=True)
        assert run.returncode == 0, run.stdout[-2000:]
        assert (tmp_path / f"{name}.pdf").exists()


# ------------------------------------------------------------------------------------------------ exam problems
ENCODED = ["2004-03-25-ex1", "2005-04-05-ex1", "2010-09-15-ex1", "2016-06-06-ex1", "2016-07-11-ex1",
           "2016-09-12-ex1", "2017-07-11-ex1", "2021-01-12-ex3", "2021-04-14-remote-midterm-ex1"]


@pytest.mark.parametrize("name", ENCODED)
def test_printed_parametrizations_verify(name):
    rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
    assert rep.ok, [(c.name, c.verdict) for c in rep.checks if not c.verdict.ok]
    names = {c.name for c in rep.checks}
    assert "a" in names


def test_at_least_four_problems_check_a_printed_Y():
    with_Y = [n for n in ENCODED if "Y" in load_problem(PROBLEMS / f"{n}.yaml").expected]
    assert len(with_Y) >= 4


def test_2021_04_14_eight_printed_coefficients_are_not_minimal():
    problem = load_problem(PROBLEMS / "2021-04-14-remote-midterm-ex1.yaml")
    r = all_results(solve_problem(problem))
    assert value(r, "p") == 8 and value(r, "p_min") == 6 and value(r, "minimal") is False
    assert value(r, "Ya_check") is True
    md = render(problem, solve_problem(problem), "md")
    assert "not minimal" in md and "a_{7} l_{1}" in md


def test_2010_09_15_printed_a4_cannot_express_the_model():
    text = (PROBLEMS / "2010-09-15-ex1.yaml").read_text().replace("      - m3*dc2*dc3\n", "      - m2*dc2*dc3\n")
    with pytest.raises(UserError, match="cannot express the model"):
        solve_problem(load_problem_text(text))


def test_readable_is_memoized_on_its_arguments():
    """readable is computed once per (entry, state, rates): a repeated entry (Y's entries recur in the rows and
    groups of the explanation) is the cached result, equal to a fresh computation; the set and list given in
    another order or as other containers hit the same entry."""
    from solver.dynamics.parametrization import _readable, readable
    q1, q2, dq1, ddq1, a = sp.symbols("q1 q2 dq1 ddq1 a")
    e = a * ddq1 * sp.cos(q2) ** 2 + a * dq1**2 * sp.sin(q2) * sp.cos(q2)
    _readable.cache_clear()
    first = readable(e, {q1, q2, dq1, ddq1}, [ddq1, dq1])
    again = readable(e, {ddq1, dq1, q2, q1}, (ddq1, dq1))
    assert again is first and _readable.cache_info().hits == 1
    _readable.cache_clear()
    assert readable(e, {q1, q2, dq1, ddq1}, [ddq1, dq1]) == first


def test_ring_canonical_is_the_expanded_canonical_form(monkeypatch):
    """canonical() computed in a sparse ring (cos/sin of combinations as Π (c + i s)^k, c² → 1 − s² or s² → 1 − c²)
    is node for node what expand(expand_trig(.)) and the replacements give, on terms of a robot no library problem
    has (multiples, differences, an angle outside sin/cos, a prismatic coordinate); anything else takes the
    expansions (a float, an angle outside the state, a parameter angle)."""
    import solver.dynamics.parametrization as P
    q1, q2, d3, dq1, dq2, ddq1, al = sp.symbols("q1 q2 d3 dq1 dq2 ddq1 alpha", real=True)
    m, a, b = sp.symbols("m a b", positive=True)
    state = {q1, q2, d3, dq1, dq2, ddq1}
    exprs = [m * (a * sp.cos(2 * q1 - q2) + d3 * sp.sin(q2)) ** 2 * ddq1 / 3 - b * sp.sin(3 * q2) * dq1 * dq2,
             q1 * sp.sin(q1) * sp.cos(q1 + q2) ** 3 + a * sp.cos(q2) ** 4 / 2 - m * sp.sin(q1) ** 2 * dq1 ** 2]
    fast = {(i, sq): P._ring_canonical(e, state, sq) for i, e in enumerate(exprs) for sq in ("cos", "sin")}
    assert P._ring_canonical(sp.cos(q1) ** 2, state, "cos") == 1 - sp.sin(q1) ** 2
    assert P._ring_canonical(sp.sin(2 * q1) ** 2, state, "sin") == sp.expand(4 * sp.cos(q1) ** 2 * (1 - sp.cos(q1) ** 2))
    monkeypatch.setattr(P, "_ring_canonical", lambda *args: None)
    for (i, sq), f in fast.items():
        assert f is not None and sp.srepr(f) == sp.srepr(P.canonical(exprs[i], state, sq))
    monkeypatch.undo()
    for other in (sp.Float(0.5) * sp.sin(q1), sp.cos(q1 + al), sp.sin(q1) * sp.cos(b)):
        assert P._ring_canonical(other, state, "cos") is None


def test_readable_factors_each_sum_of_parameters_once():
    """_group_by_state factors a sum of parameters once (memoized) however many entries it multiplies, with
    sympy's factor_terms result."""
    import solver.dynamics.parametrization as P
    dq1, ddq1 = sp.symbols("dq1 ddq1", real=True)
    m, a, b = sp.symbols("m a b", positive=True)
    s = 2 * m * a ** 2 + 4 * m * a * b
    P._factor_terms.cache_clear()
    first = P._group_by_state(sp.expand(s * ddq1 + s * dq1 ** 2), [ddq1, dq1])
    second = P._group_by_state(sp.expand(s * ddq1), [ddq1, dq1])
    assert first == 2 * a * m * (a + 2 * b) * ddq1 + 2 * a * m * (a + 2 * b) * dq1 ** 2
    assert second == sp.factor_terms(s) * ddq1
    assert P._factor_terms.cache_info().hits >= 2 and P._factor_terms.cache_info().misses == 1


def test_split_rates_is_the_jacobian_and_the_value_at_rest():
    """split_rates reads ∂e/∂q̈_j, the velocity terms and the rest off an expanded sum: node for node what the
    jacobian, e − J q̈ expanded and its value at q̇ = 0 give, on random sums linear in q̈; None for a q̈² term."""
    from solver.dynamics.parametrization import split_rates
    q1, q2, dq1, dq2, ddq1, ddq2, a1, a2 = sp.symbols("q1 q2 dq1 dq2 ddq1 ddq2 a_1 a_2")
    ddq, dq = [ddq1, ddq2], [dq1, dq2]
    rng = random.Random(3)
    pool = [sp.cos(q2), sp.sin(q1 + q2), q1, a1, a2, sp.Rational(-3, 2), 2]
    for _ in range(40):
        terms = []
        for _ in range(rng.randint(1, 6)):
            f = sp.Mul(*rng.sample(pool, rng.randint(1, 3)))
            kind = rng.random()
            f *= rng.choice(ddq) if kind < 0.4 else (rng.choice(dq) ** rng.randint(1, 2) * rng.choice([1] + dq)
                                                     if kind < 0.8 else 1)
            terms.append(f)
        e = sp.expand(sp.Add(*terms))
        got = split_rates(e, ddq, dq)
        M = sp.Matrix([e])
        J = M.jacobian(ddq)
        rest = (M - J * sp.Matrix(ddq)).applyfunc(sp.expand)
        g0 = rest.subs({v: 0 for v in dq})
        want = (list(J), (rest - g0)[0], g0[0])
        assert got is not None
        assert [sp.srepr(x) for x in got[0]] == [sp.srepr(x) for x in want[0]]
        assert sp.srepr(got[1]) == sp.srepr(want[1]) and sp.srepr(got[2]) == sp.srepr(want[2])
    assert split_rates(sp.expand(a1 * ddq1 ** 2 + a2 * dq1), ddq, dq) is None
    assert split_rates(a1 * sp.sin(dq1), ddq, dq) is None
