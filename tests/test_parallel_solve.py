"""Asks solved by forked helpers (`solve -j`, issue 11): the same solutions, names and reports as in one process,
errors raised as in order, a helper that cannot send replaced by the parent."""
import subprocess
import sys

import pytest
import sympy as sp

import solver.solve as solve_mod
from conftest import PROBLEMS, R2_ROBOT, ROOT
from solver.publish.render import render
from solver.results import Solution
from solver.spec import load_problem
from solver.spec.errors import UserError

# ask 3 uses rd1, a name the law of ask 2 registers; two laws register the same gains
SHARED_NAMES = PROBLEMS / "2021-02-04-ex3.yaml"
# eight asks of several kinds, with figures
MANY_ASKS = PROBLEMS / "2018-01-11-ex3.yaml"


def solved(path, jobs: int, figures: bool = True) -> tuple:
    problem = load_problem(path)
    sols = solve_mod.solve_problem(problem, jobs=jobs, figures=figures)
    panels = [repr(fig.panels) for s in sols for fig in s.figures]
    return (render(problem, sols, "md"), render(problem, sols, "json"), panels, dict(problem.names),
            dict(problem.latex_names))


@pytest.mark.parametrize("path", [SHARED_NAMES, MANY_ASKS], ids=["shared-names", "many-asks"])
def test_helpers_give_the_solutions_of_one_process(path):
    one, two = solved(path, 1), solved(path, 2)
    assert one[0] == two[0] and one[1] == two[1]          # the report and the JSON, byte for byte
    assert one[2] == two[2] and one[2]                     # the figures' samples
    assert one[3] == two[3] and one[4] == two[4]           # the names the asks registered, merged in order


def test_a_name_registered_by_an_earlier_ask_can_be_used():
    """Each ask is solved from the problem as loaded; one that fails so (rd1 is unknown there) is solved again
    from the names the earlier asks left: rd1 is the first law's symbol."""
    problem = load_problem(SHARED_NAMES)
    sols = solve_mod.solve_problem(problem, jobs=2)
    rd1 = problem.names["rd1"]
    assert rd1 in sols[2].results["u_jsd"].value.free_symbols | sols[2].results["a_r_jsd"].value.free_symbols


SINGULAR = ("id: sing\ntitle: t\nsymbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, g0: g0}\n"
            + R2_ROBOT + """asks:
  - kind: dynamic_model
    plots: false
  - kind: control_law
    law: cartesian_computed_torque
    task: [q1 + q2, 2*q1 + 2*q2]
  - kind: dynamic_model
    plots: false
    show: [B]
""")


@pytest.mark.parametrize("jobs", [1, 2])
def test_an_error_is_raised_as_in_order(write, jobs):
    with pytest.raises(UserError, match="singular everywhere"):
        solve_mod.solve_problem(load_problem(write(SINGULAR)), jobs=jobs)


def test_an_ask_a_helper_cannot_send_is_solved_by_the_parent(monkeypatch):
    def unpicklable(obj):  # (the helpers are forked after this: they inherit it)
        raise TypeError("cannot pickle")
    monkeypatch.setattr(solve_mod, "_dumps", unpicklable)
    assert solved(MANY_ASKS, 2)[:2] == solved(MANY_ASKS, 1)[:2]


def fake_asks(problem, k: int) -> Solution:
    """Ask k registers a symbol x: printed A by ask 0, B by ask 1 (a clash: x is taken, so ask 1 takes xc when
    it sees x), and ask 2 reuses ask 0's x, printed A (no clash)."""
    tex = "B" if k == 1 else "A"
    name = "x"
    if "x" in problem.names and problem.latex_names.get(problem.names["x"]) != tex:
        name = "xc"
    s = problem.names.setdefault(name, sp.Symbol(name))
    problem.latex_names.setdefault(s, tex)
    sol = Solution("fake")
    sol.add("s", s, "scalar")
    return sol


@pytest.mark.parametrize("jobs", [1, 2, 3])
def test_clashing_names_are_solved_again_in_order(monkeypatch, write, jobs):
    monkeypatch.setattr(solve_mod, "_solve_ask", fake_asks)
    problem = load_problem(write(SINGULAR))
    sols = solve_mod.solve_problem(problem, jobs=jobs)
    x, xc = sp.Symbol("x"), sp.Symbol("xc")
    assert [s.results["s"].value for s in sols] == [x, xc, x]
    assert problem.latex_names[x] == "A" and problem.latex_names[xc] == "B"
    assert problem.names["x"] == x and problem.names["xc"] == xc


def test_asks_solved_ahead_of_a_slow_one_are_given_early(monkeypatch):
    """With helpers, an ask this process solves while a helper is still on an earlier one goes to ``early`` at
    once (the CLI draws its figures then), with the solution object the merge keeps; ``solved`` still comes in
    order. The helper's first ask is the slow one: this process solves all the others meanwhile."""
    import os
    import time
    parent, slept = os.getpid(), []

    def asks(problem, k: int) -> Solution:
        slow = os.getpid() != parent and not slept
        if slow:
            slept.append(k)
            time.sleep(1.5)
        elif k:   # (this process leaves the helper time to take an ask)
            time.sleep(0.1)
        sol = Solution("fake")
        sol.add("k", sp.Integer(k), "number")
        sol.add("slow", sp.Integer(int(slow)), "number")
        return sol
    monkeypatch.setattr(solve_mod, "_solve_ask", asks)
    problem = load_problem(MANY_ASKS)
    events: list[tuple[str, int, Solution]] = []
    sols = solve_mod.solve_problem(problem, lambda k, s: events.append(("solved", k, s)), jobs=2,
                                   early=lambda k, s: events.append(("early", k, s)))
    n = len(problem.asks)
    assert [s.results["k"].value for s in sols] == list(range(n))
    assert [k for what, k, _ in events if what == "solved"] == list(range(1, n + 1))
    (j,) = [k for k, s in enumerate(sols, 1) if s.results["slow"].value == 1]   # the helper's (1-based)
    early = {k: s for what, k, s in events if what == "early"}
    assert j < n - 1 and set(early) == set(range(j + 1, n + 1))     # every ask after it, none twice
    at_j = next(i for i, (what, k, _) in enumerate(events) if what == "solved" and k == j)
    assert all(i < at_j for i, (what, _, _) in enumerate(events) if what == "early")
    assert all(sols[k - 1] is s for k, s in early.items())


def test_cli_jobs_write_the_same_report_and_figures(tmp_path):
    outs = []
    for j in ("1", "2"):
        out = tmp_path / j / "sol.md"
        r = subprocess.run([sys.executable, "-m", "solver", "solve", str(MANY_ASKS), "-o", str(out), "-j", j],
                           cwd=ROOT, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        outs.append((out.read_text(), sorted(p.name for p in out.parent.iterdir())))
    assert outs[0] == outs[1] and len(outs[0][1]) > 1


def test_verify_of_one_file_shares_its_asks_and_passes():
    from solver.verify import check_problem, verify_paths
    (two,) = verify_paths([SHARED_NAMES], jobs=2)       # one file, two processes: its asks shared by both
    one = check_problem(load_problem(SHARED_NAMES))
    assert two.ok and one.ok
    assert [(c.name, c.verdict.ok) for c in two.checks] == [(c.name, c.verdict.ok) for c in one.checks]
    assert len(two.checks) > 10


def test_check_of_one_file_shares_its_asks():
    r = subprocess.run([sys.executable, "-m", "solver", "check", str(SHARED_NAMES)], cwd=ROOT, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0 and r.stdout.strip() == f"{SHARED_NAMES}: ok", r.stdout + r.stderr


LAZY = ("id: lazy\ntitle: t\nsymbols: {m1: m1, m2: m2, d1: d1, d2: d2, l1: l1, I1: I1, I2: I2, g0: g0, r: r}\n"
        + R2_ROBOT + "asks:\n  - kind: dynamic_model\n    plots: false\n"
        + "".join(f"""  - kind: constrained_dynamics
    h: (l1*cos(q1) + l1*cos(q1 + q2))^2 + (l1*sin(q1) + l1*sin(q1 + q2))^2 - {c}*r^2
    multiplier: false
    show: [reduced, u_dv]
    suffix: _{c}
""" for c in (1, 2, 3)))


def test_helpers_leave_out_the_optional_results_only_when_told(write):
    """The terms of an unshown reduced model are computed by a helper to send them (verify, grading, --details
    read them), unless ``optional=False`` (a report): then they come as NotSent, which raise when read; the
    asks this process solved keep them deferred."""
    from solver.results import Deferred, NotSent
    path = write(LAZY)
    names = [f"reduced_model_{c}" for c in (1, 2, 3)]
    one = solve_mod.all_results(solve_mod.solve_problem(load_problem(path)))
    sent = solve_mod.all_results(solve_mod.solve_problem(load_problem(path), jobs=2))
    assert [sent[x].value for x in names] == [one[x].value for x in names]
    left = solve_mod.all_results(solve_mod.solve_problem(load_problem(path), jobs=2, optional=False))
    kinds = [type(object.__getattribute__(left[x], "value")) for x in names]
    assert NotSent in kinds and set(kinds) <= {NotSent, Deferred}
    for x, kind in zip(names, kinds):
        if kind is NotSent:
            with pytest.raises(RuntimeError, match="not sent"):
                left[x].value
        else:
            assert left[x].value == one[x].value


def test_cli_json_details_with_helpers_has_the_optional_results(write):
    import json
    path = write(LAZY)
    problem = load_problem(path)
    expected = render(problem, solve_mod.solve_problem(problem), "json", details=True)
    r = subprocess.run([sys.executable, "-m", "solver", "solve", str(path), "-f", "json", "--details", "-j", "2"],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == expected.strip()
    assert "reduced_model_3" in json.loads(r.stdout)["results"]
