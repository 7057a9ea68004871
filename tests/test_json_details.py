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
