"""JSON output: only the asked results, each written once; per-body quantities and step expressions on request."""
import json
import subprocess
import sys

from conftest import PROBLEMS, ROOT

from solver.publish.render import render
from solver.solve import solve_problem
from solver.spec import load_problem

RP = PROBLEMS / "2004-03-25-ex1.yaml"  # planar RP robot: dynamic_model + linear_parametrization


def _solved():
    p = load_problem(RP)
    return p, solve_problem(p)


def test_json_has_the_asked_results_each_once():
    p, sols = _solved()
    text = render(p, sols, "json")
    data = json.loads(text)
    for name in ("T", "B", "christoffel", "c", "S", "skew", "U", "g", "model", "Y", "a", "p"):
        assert name in data["results"], name
    # per-body quantities are intermediate: not in the default output, but still results (verify, grading)
    assert not {"pc1", "vc1", "w1", "T1", "U1", "pc2", "T2"} & set(data["results"])
    assert {"pc1", "T2"} <= set(sols[0].results) and sols[0].results["T1"].detail
    # each expression once: B's LaTeX appears only in its result; the steps refer to results by name
    assert text.count(json.dumps(data["results"]["B"]["latex"])) == 1
    model = next(s for s in data["steps"] if s["ask"] == "dynamic_model")
    assert "dm" not in model["data"] and "view" not in model["data"]
    regressor = next(s for s in data["steps"] if s["step"] == "regressor")
    assert regressor["data"]["Y"] == {"result": "Y"} and regressor["data"]["a"] == {"result": "a"}
    assert '"expr"' not in json.dumps(data["steps"])


def test_json_details_on_request():
    p, sols = _solved()
    data = json.loads(render(p, sols, "json", details=True))
    assert {"pc1", "vc2", "w2", "T1", "T2", "U2"} <= set(data["results"])
    model = next(s for s in data["steps"] if s["ask"] == "dynamic_model")
    assert model["data"]["dm"]["B"] == {"result": "B"}  # still by reference
    bodies = model["data"]["dm"]["bodies"]
    assert bodies[1]["T"] == {"result": "T2"} and "latex" in bodies[1]["v2"]  # ‖v_c2‖² is not a result
    assert "view" not in model["data"]  # the lazy report view is not serialized


def test_cli_details_option():
    run = lambda *a: subprocess.run([sys.executable, "-m", "solver", "solve", str(RP), "-f", "json", *a],  # noqa: E731
                                    capture_output=True, text=True, cwd=ROOT, timeout=600)
    plain, detailed = json.loads(run().stdout), json.loads(run("--details").stdout)
    assert "T1" not in plain["results"] and "T1" in detailed["results"]
    assert plain["results"]["B"] == detailed["results"]["B"]


def test_reports_still_explain_the_bodies():
    """The per-body energies stay in the md/tex reports (their `show:` decides), computed when rendered."""
    p, sols = _solved()
    assert "T_{2}" in render(p, sols, "tex") and "v_{c2}" in render(p, sols, "md")


def test_long_expressions_printed_directly_read_back():
    """Past LARGE_PRINT nodes the text and LaTeX are printed directly (terms in stored order): the text reads back
    to the same expression, and short expressions keep sympy's printing."""
    import random

    import sympy as sp
    from sympy.parsing.sympy_parser import parse_expr

    from solver.publish.render import LARGE_PRINT, Latex, _expr_str, is_large
    q1, q2, a, b, m = sp.symbols("q1 q2 a b m")
    rng = random.Random(5)
    atoms = [sp.cos(q1), sp.sin(q1 + 2 * q2), a, b**2, m, sp.Rational(-3, 4), a + b, sp.cos(q2) ** 2, sp.Integer(3)]
    big = sum(sp.Mul(*rng.choices(atoms, k=4)) * sp.Symbol(f"k{i}") for i in range(LARGE_PRINT // 8))
    assert is_large(big) and not is_large(a * sp.cos(q1))
    names = {s.name: s for s in big.free_symbols}
    assert sp.expand(parse_expr(_expr_str(big), local_dict=names) - big) == 0
    M = sp.Matrix([[big, a]])
    assert sp.expand(parse_expr(_expr_str(M), local_dict={**names, "Matrix": sp.Matrix})[0] - big) == 0
    tex = Latex({a: "\\alpha"})(big)
    assert "\\alpha" in tex and "\\cos{\\left(q_{1}\\right)}" in tex and tex.count("\\left(") == tex.count("\\right)")
    assert _expr_str(a * sp.cos(q1)) == str(a * sp.cos(q1))


def test_steps_refer_to_their_own_asks_results():
    """Equal results of two asks are one shared object (memoized simplification): each ask's steps name its own
    result (suffix), a step of an ask without that result names the first ask's."""
    import sympy as sp

    from solver.results import Solution
    p = load_problem(RP)
    x = sp.Symbol("x") ** 2 + 1
    sols = []
    for sfx in ("", "_b"):
        s = Solution("kinematics", title="t")
        s.add("v" + sfx, x, "scalar", label="v")
        s.step("use", v=x)
        sols.append(s)
    third = Solution("redundancy", title="t")
    third.step("use", v=x)
    data = json.loads(render(p, sols + [third], "json"))
    assert [s["data"]["v"] for s in data["steps"]] == [{"result": "v"}, {"result": "v_b"}, {"result": "v"}]


def test_steps_refer_to_results_by_value_not_identity():
    """A step value equal to a result (another object: which objects sympy's caches share changes from run to
    run, with the hash seed) is written as a reference, so the JSON of a problem is the same on every run."""
    import sympy as sp

    from solver.results import Solution
    p = load_problem(RP)
    q = sp.Symbol("q")
    s = Solution("kinematics", title="t")
    s.add("M", sp.Matrix([[sp.cos(q), 1], [0, sp.sin(q)]]), "matrix", label="M")
    s.add("w", sp.cos(q) + 2, "scalar", label="w")
    s.step("use", M=sp.Matrix([[sp.cos(q), 1], [0, sp.sin(q)]]), w=2 + sp.cos(q), other=sp.sin(q) + 2)
    data = json.loads(render(p, [s], "json"))["steps"][0]["data"]
    assert data["M"] == {"result": "M"} and data["w"] == {"result": "w"} and "other" not in data


def test_json_is_strict_json_with_infinite_values():
    """±∞ and NaN are no JSON numbers (json.dumps wrote Infinity, which strict readers refuse: 2021-09-10-ex1's
    λ_i,1): they are written as the strings "inf", "-inf", "nan", which float() reads."""
    import math

    import sympy as sp

    from solver.results import Solution
    p, sols = _solved()
    extra = Solution("extra", title="extra")
    extra.add("unbounded", sp.Matrix([sp.Rational(1, 2), sp.oo, -sp.oo]), "vector")
    extra.step("s", bound=float("inf"), gap=float("nan"))

    def refuse(c):  # noqa: ANN001, ANN202
        raise ValueError(c)
    data = json.loads(render(p, sols + [extra], "json"), parse_constant=refuse)
    assert data["results"]["unbounded"]["value"] == [0.5, "inf", "-inf"]
    assert [float(x) for x in data["results"]["unbounded"]["value"][1:]] == [math.inf, -math.inf]
    assert data["steps"][-1]["data"] == {"bound": "inf", "gap": "nan"}
