"""The `visual_servoing` ask: interaction matrices against finite differences of the projection (Cartesian and
polar, several points and depths, averages), null-space motions that leave the features still, numeric rank with
a tolerance, the IBVS law and its simulation, and the encoded exam problems."""
import random

import numpy as np
import pytest
import sympy as sp
from conftest import PROBLEMS, error_found_without_solving

from solver.control.visual_servoing import (cleared, content_free, point_matrix, polar_matrix, simulate_ibvs)
from solver.publish.render import render
from solver.solve import all_results, solve_problem
from solver.spec import load_problem, load_problem_text
from solver.spec.errors import UserError
from solver.verify import check_problem

LAM = 0.8


def project(P: np.ndarray, lam: float = LAM) -> np.ndarray:
    return lam * P[:2] / P[2]


def moved(P: np.ndarray, tw: np.ndarray, h: float) -> np.ndarray:
    """P after the camera moved with twist tw for time h (to first order: Ṗ = −V − Ω × P, exact up to O(h²))."""
    return P + h * (-tw[:3] - np.cross(tw[3:], P))


def fd_feature_rate(P: np.ndarray, tw: np.ndarray, feat, h: float = 1e-6) -> np.ndarray:
    return (feat(moved(P, tw, h)) - feat(moved(P, tw, -h))) / (2 * h)


def num(M) -> np.ndarray:
    return np.array(sp.Matrix(M).evalf(20).tolist(), dtype=float)


U, V, Z, L, R, T = sp.symbols("u v Z lambda rho theta", real=True)


@pytest.mark.parametrize("seed", range(6))
def test_point_matrix_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    P = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.5, 4)])
    u, v = project(P)
    J = num(point_matrix(sp.Float(u), sp.Float(v), sp.Float(P[2]), sp.Float(LAM)))
    for _ in range(3):
        tw = rng.normal(size=6)
        assert np.allclose(J @ tw, fd_feature_rate(P, tw, project), atol=1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_polar_matrix_matches_finite_differences(seed):
    rng = np.random.default_rng(10 + seed)
    P = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.5, 4)])

    def polar(Q):
        u, v = project(Q)
        return np.array([np.hypot(u, v), np.arctan2(v, u)])

    rho, th = polar(P)
    J = num(polar_matrix(sp.Float(rho), sp.Float(th), sp.Float(P[2]), sp.Float(LAM)))
    tw = rng.normal(size=6)
    assert np.allclose(J @ tw, fd_feature_rate(P, tw, polar), atol=1e-6)


def test_polar_matrix_symbolic_form():
    """J_polar = J_t⁻¹ J_p: the decoupled entries (V_z only on ρ̇, Ω_z only on θ̇)."""
    J = polar_matrix(R, T, Z, L)
    assert sp.simplify(J[0, 5]) == 0 and sp.simplify(J[1, 2]) == 0 and sp.simplify(J[1, 5] + 1) == 0
    assert sp.simplify(J[0, 2] - R / Z) == 0


def spec(points: str, extra: str = "", symbols: str = "") -> str:
    return f"""
id: t
title: vs
symbols:
  lambda: focal length
{symbols}
asks:
  - kind: visual_servoing
    points: {points}
{extra}"""


SYM3 = "".join(f"  u{i}: {{meaning: u, sign: real}}\n  v{i}: {{meaning: v, sign: real}}\n  Z{i}: depth\n"
               for i in range(1, 4))


@pytest.mark.parametrize("feature", ["points", "average"])
def test_stacked_and_average_match_finite_differences(feature):
    rng = np.random.default_rng(3)
    Ps = [np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.5, 4)]) for _ in range(3)]
    pts = [[*project(P), P[2]] for P in Ps]
    text = spec(str([[float(x) for x in p] for p in pts]), f"    feature: {feature}\n") + f"values: {{lambda: {LAM}}}\n"
    res = all_results(solve_problem(load_problem_text(text)))
    J = num(res["J_s"].value.subs(sp.Symbol("lambda", positive=True), LAM))

    def feat(Qs):
        f = np.array([project(Q) for Q in Qs])
        return f.mean(0) if feature == "average" else f.reshape(-1)

    tw = rng.normal(size=6)
    h = 1e-6
    fd = (feat([moved(P, tw, h) for P in Ps]) - feat([moved(P, tw, -h) for P in Ps])) / (2 * h)
    assert np.allclose(J @ tw, fd, atol=1e-6)


def test_null_motions_leave_features_still():
    """Every null-space motion (basis and special ones) gives J x = 0 exactly, symbolic, for 1 point and for the
    average of 3 points; moving the 3D point along them keeps the projection still (finite differences)."""
    for points, feature, syms in (("[u1, v1, Z1]", "points", SYM3), ("[[u1, v1, Z1], [u2, v2, Z2], [u3, v3, Z3]]",
                                                                      "average", SYM3)):
        res = all_results(solve_problem(load_problem_text(spec(points, f"    feature: {feature}\n", syms))))
        J = res["J_s"].value
        names = ["null_translation", "null_rotation", "null_axis_motion"]
        for name in names:
            if name in res:
                assert (J * res[name].value).applyfunc(sp.simplify) == sp.zeros(2, 1), name
        for M in ("null_motions", "null_motions_cleared"):
            if M in res:
                assert (J * res[M].value).applyfunc(sp.simplify) == sp.zeros(2, res[M].value.shape[1])
        assert res["dim_null"].value == 4
    # numeric: the single point moved along each basis motion
    rng = np.random.default_rng(5)
    P = np.array([0.3, -0.4, 2.0])
    u, v = project(P)
    sub = {sp.Symbol("u1", real=True): u, sp.Symbol("v1", real=True): v, sp.Symbol("Z1", positive=True): P[2],
           sp.Symbol("lambda", positive=True): LAM}
    res = all_results(solve_problem(load_problem_text(spec("[u1, v1, Z1]", "", SYM3))))
    N = num(res["null_motions"].value.subs(sub))
    for j in range(N.shape[1]):
        assert np.allclose(fd_feature_rate(P, N[:, j], project), 0, atol=1e-6)
    bad = rng.normal(size=6)
    assert not np.allclose(fd_feature_rate(P, bad, project), 0, atol=1e-3)  # the test can fail


def test_cleared_and_content_free():
    x = sp.Matrix([U / L, V / L, 1])
    assert cleared(x) == sp.Matrix([U, V, L])
    assert cleared(-x) == sp.Matrix([U, V, L])
    assert content_free(sp.Matrix([U / Z, V / Z, L / Z])) == sp.Matrix([U, V, L])


def test_numeric_rank_with_tolerance_and_singular_configuration():
    """Three collinear points, one of them at the center: fine; two coincident points: rank 4 < 6 (singular)."""
    good = "[[0.1, 0.2, 1], [-0.2, 0.1, 2], [0.15, -0.3, 1.5]]"
    res = all_results(solve_problem(load_problem_text(spec(good, "", "") + "values: {lambda: 1}\n")))
    assert res["rank_at"].value == 6 and res["singular_at"].value is False
    same = "[[0.1, 0.2, 1], [0.1, 0.2, 1], [0.3, -0.1, 2]]"
    res = all_results(solve_problem(load_problem_text(spec(same, "", "") + "values: {lambda: 1}\n")))
    assert res["rank_at"].value == 4 and res["singular_at"].value is True and res["cond_at"].value == sp.oo
    # a nearly coincident point: rank 6 with a tight tolerance, 4 with a loose one (two small σ)
    near = "[[0.1, 0.2, 1], [0.1000001, 0.2, 1], [0.3, -0.1, 2]]"
    r_t = all_results(solve_problem(load_problem_text(spec(near, "    tol: 1e-12\n", "") + "values: {lambda: 1}\n")))
    r_l = all_results(solve_problem(load_problem_text(spec(near, "    tol: 1e-4\n", "") + "values: {lambda: 1}\n")))
    assert r_t["rank_at"].value == 6 and r_l["rank_at"].value == 4


def test_ibvs_simulation_converges():
    rng = np.random.default_rng(1)
    P0 = np.array([[0.3, 0.2, 2.0], [-0.3, 0.25, 2.2], [0.0, -0.3, 1.8], [0.25, -0.2, 2.1]])
    # desired: the image of the same points seen from a slightly displaced camera
    shift = np.array([0.1, -0.05, -0.3])
    sd = np.array([project(P - shift, 1.0) for P in P0]).reshape(-1)
    res = simulate_ibvs(P0, sd, 1.0, 1.0, 8.0, 800, False, "true")
    assert res["err"][-1] < 1e-3 * res["err"][0]
    assert np.all(np.diff(res["err"]) <= 1e-9)  # ė = −k e: the error norm decreases monotonically
    del rng


def test_law_with_robot_and_norm_task():
    text = spec("[[u1, v1, Z1], [u2, v2, Z2]]", """    desired: [u1d, v1d, u2d, v2d]
    norm: true
    robot_jacobian: [[1, 0], [0, 1], [0, 0], [0, 0], [0, 0], [1, 1]]
""", SYM3 + "".join(f"  {n}: {{meaning: desired, sign: real}}\n" for n in ("u1d", "v1d", "u2d", "v2d")))
    res = all_results(solve_problem(load_problem_text(text)))
    Jeta, Jp = res["J_eta"].value, res["J_eta_pinv"].value
    assert Jeta.shape == (1, 2) and Jp.shape == (2, 1)
    rng = random.Random(2)
    sub = {s: sp.Rational(rng.randint(1, 9), rng.randint(1, 5)) for s in (Jeta.free_symbols | Jp.free_symbols)}
    assert sp.simplify((Jeta * Jp).subs(sub)[0, 0] - 1) == 0


def test_report_and_simulation_figure(tmp_path):
    text = spec("[[0.2, 0.1, 2], [-0.2, 0.15, 2], [0.0, -0.2, 2]]", """    desired: [0.25, 0.15, -0.25, 0.2, 0.0, -0.25]
    gain: 2
    simulate: {time: 3, steps: 300}
""") + "values: {lambda: 1}\n"
    p = load_problem_text(text)
    sols = solve_problem(p)
    md, tex = render(p, sols, "md"), render(p, sols, "tex")
    assert "IBVS law" in md and "\\textbf{IBVS law.}" in tex
    res = all_results(sols)
    assert res["law_at"].value.shape == (6, 1)
    panels = sols[0].figures[0].panels
    assert len(panels) == 2 and panels[1].curves[0].y[-1] < 0.05 * panels[1].curves[0].y[0]


def test_depth_true_unquoted_is_the_current_depth():
    """`depth: true` as the docs write it (YAML reads a boolean) means the current depth, as `depth: "true"`."""
    base = spec("[[0.2, 0.1, 2], [-0.2, 0.15, 2], [0.0, -0.2, 2]]", """    desired: [0.25, 0.15, -0.25, 0.2, 0.0, -0.25]
    gain: 2
    simulate: {time: 1, steps: 100, depth: DEPTH}
""") + "values: {lambda: 1}\n"
    runs = [solve_problem(load_problem_text(base.replace("DEPTH", d)))[0].figures[0].panels for d in ("true", '"true"')]
    assert runs[0][1].curves[0].y == runs[1][1].curves[0].y
    with pytest.raises(UserError, match="depth"):
        load_problem_text(base.replace("DEPTH", "false"))


def test_user_errors():
    with pytest.raises(UserError):
        solve_problem(load_problem_text(spec("[[1, 2], [3, 4]]")))
    with pytest.raises(UserError):
        solve_problem(load_problem_text(spec("[1, 2, 3]", "    desired: [1, 2, 3]\n")))


@pytest.mark.parametrize("name", ["2012-06-11-ex1", "2020-09-11-remote-ex2", "2018-07-11-ex3", "2017-05-29-final-ex2",
                                  "2018-02-05-ex1"])
def test_problems_verify(name):
    rep = check_problem(load_problem(PROBLEMS / f"{name}.yaml"))
    assert rep.ok, [c for c in rep.checks if not c.ok]


def _eta_run(sign: float, k: float = 1.0, T: float = 0.5, steps: int = 500) -> tuple[float, float]:
    """Free-flying camera, two points, q̇ = sign · J_η^# k η with J_η = −eᵀJ/η, J_η^# = −η Jᵀe/(eᵀJJᵀe)."""
    P = np.array([[0.2, 0.1, 2.0], [-0.2, 0.15, 2.5]])
    sd = np.array([0.15, 0.05, -0.1, 0.1])

    def eta_and_twist(P):
        uv = P[:, :2] / P[:, 2:3]
        J = np.vstack([[[-1 / z, 0, u / z, u * v, -(1 + u * u), v], [0, -1 / z, v / z, 1 + v * v, -u * v, -u]]
                       for (u, v), z in zip(uv, P[:, 2])])
        e = sd - uv.reshape(-1)
        eta = np.linalg.norm(e)
        pinv = -eta * J.T @ e / (e @ J @ J.T @ e)
        return eta, sign * k * eta * pinv

    eta0, _ = eta_and_twist(P)
    h = T / steps
    for _ in range(steps):
        _, tw = eta_and_twist(P)
        P = P + h * (-tw[:3][None, :] - np.cross(tw[3:][None, :], P))
    return eta0, eta_and_twist(P)[0]


def test_norm_task_sign_by_simulation():
    """The printed law q̇ = J_η^# k η (2018-02-05, eq. 9) makes ‖e‖ grow like e^{kt}; −J_η^# k η makes it decay."""
    e0, e_printed = _eta_run(+1.0)
    _, e_ours = _eta_run(-1.0)
    assert e_printed > 1.5 * e0 and e_ours < 0.7 * e0
    assert abs(e_ours / e0 - np.exp(-0.5)) < 0.02


def test_property_check_accepts_any_null_motion():
    from solver.control.visual_servoing import _null_check
    p = load_problem(PROBLEMS / "2012-06-11-ex1.yaml")
    res = all_results(solve_problem(p))
    u, v, Z, lam = (p.names[n] for n in ("u", "v", "Z", "lambda"))
    ok = _null_check(p, res, "null_translation", sp.Matrix([2 * u, 2 * v, 2 * lam, 0, 0, 0]), lambda n: None, {})
    assert ok is not None and ok.correct
    bad = _null_check(p, res, "null_translation", sp.Matrix([u, -v, lam, 0, 0, 0]), lambda n: None, {})
    assert bad is not None and not bad.correct
    basis = res["null_motions_cleared"].value * sp.Matrix([[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    assert _null_check(p, res, "null_motions", basis, lambda n: None, {}).correct
    assert not _null_check(p, res, "null_motions", basis[:, :3], lambda n: None, {}).correct


def test_null_directions_are_the_null_space_up_to_a_factor():
    """The fast null space of the special motions (exact, over the field of fractions) spans N(M) as
    Matrix.nullspace does: the same canonical vectors after cleared(), the same number of directions when the
    rank is deficient or full; entries that are not rational functions of symbols (cos θ and sin θ, whose
    relation the field of fractions would miss; square roots) take Matrix.nullspace itself."""
    from solver.control.visual_servoing import _null_directions
    a, b, c, d, lam = sp.symbols("a b c d lambda", positive=True)
    u = sp.symbols("u1:4", real=True)
    theta = sp.Symbol("theta", real=True)
    rational = [
        point_matrix(u[0], u[1], c, lam)[:, 3:],                              # 2x3, rank 2: one direction
        point_matrix(u[0], u[1], c, lam)[:, :3] + point_matrix(u[1], u[2], d, lam)[:, :3],
        sp.Matrix([[a, b, c], [2 * a, 2 * b, 2 * c]]),                       # rank 1: two directions
        sp.Matrix([[a, 0, 0], [0, b, 0], [0, 0, c]]),                        # full rank: none
    ]
    for M in rational:
        fast, ref = _null_directions(M), M.nullspace(simplify=True)
        assert len(fast) == len(ref)
        for v in fast:
            assert (M * v).applyfunc(sp.simplify) == sp.zeros(M.rows, 1)
        if len(ref) == 1:
            assert cleared(fast[0]) == cleared(ref[0])
    others = [polar_matrix(a, theta, c, lam)[:, 3:],
              sp.Matrix([[sp.cos(theta) ** 2, 1, 0], [1 - sp.sin(theta) ** 2, 1, 0]]),  # rank 1 by cos² + sin² = 1
              sp.Matrix([[sp.sqrt(a), b, 1], [1, c, d]])]
    for M in others:
        assert _null_directions(M) == M.nullspace(simplify=True)
    assert len(_null_directions(others[1])) == 2


def test_cleared_sparse_equals_the_sympy_path():
    """cleared() takes the numerators from the sparse field of rational functions: the sympy path's (cancel, lcm,
    gcd) direction, with integer coefficients and no common factor (where sympy's gcd over Q left a content
    such as 1/4), on random vectors of rational functions."""
    from solver.control import visual_servoing as vs
    x, y, z = sp.symbols("x y z")
    rng = random.Random(3)
    atoms = [x, y, z, x * y, y * z, sp.Integer(1)]

    def poly() -> sp.Expr:
        return sum(sp.Rational(rng.randint(-6, 6), rng.randint(1, 4)) * rng.choice(atoms) for _ in range(3))

    checked = 0
    for _ in range(40):
        common = poly() or x
        vec = sp.Matrix([common * poly() / (poly() or 1) if rng.random() < 0.7 else 0 for _ in range(3)])
        if all(e == 0 for e in vec):
            continue
        fast = vs._cleared_sparse(vec)
        ref = vs._cleared_sympy(vec)
        assert fast is not None
        k = next(i for i, e in enumerate(ref) if e != 0)  # the same direction: fast = c·ref, c a number
        c = sp.cancel(fast[k] / ref[k])
        assert c.is_Rational and c != 0 and all(sp.expand(a - c * b) == 0 for a, b in zip(fast, ref)), (vec, fast)
        polys = [sp.Poly(e, x, y, z) for e in fast if e != 0]  # integer coefficients, no common integer factor
        assert all(p.domain == sp.ZZ for p in polys) and sp.gcd_list([p.content() for p in polys]) == 1
        checked += 1
    assert checked > 30
    assert vs._cleared_sparse(sp.Matrix([sp.cos(x), 1])) is None  # outside the field: the sympy path


@pytest.mark.parametrize("J", [
    sp.Matrix([[sp.cos(T), -R * sp.sin(T)], [sp.sin(T), R * sp.cos(T)]]),               # polar J_t: 2 x 2
    sp.Matrix([[L / Z, 0, -U / Z], [0, L / Z, -V / Z]]),                                  # a 2 x 3 rational one
    sp.Matrix([[sp.cos(T), sp.sin(T), 1], [-R * sp.sin(T), R * sp.cos(T), 0], [0, 1, R]]),  # 3 x 3, trig
])
def test_dls_inverse_solves_the_damped_normal_equations(J):
    """J^DLS (σ² I + J Jᵀ) = Jᵀ at random points, and σ → 0 gives the inverse of a square J."""
    from solver.control.visual_servoing import dls_inverse
    s = sp.Symbol("sigma", positive=True)
    D = dls_inverse(J, s)
    rng = random.Random(3)
    for _ in range(3):
        pt = {x: sp.Rational(rng.randint(3, 17), 7) for x in J.free_symbols | {s}}
        lhs = num((D * (s ** 2 * sp.eye(J.rows) + J * J.T)).xreplace(pt))
        assert np.allclose(lhs, num(J.T.xreplace(pt)), atol=1e-12)
        if J.rows == J.cols:
            assert np.allclose(num(D.xreplace({**pt, s: 0})), np.linalg.inv(num(J.xreplace(pt))), atol=1e-9)
    if J.rows == 2 and J.cols == 2:  # the printed form (2017-05-29, line 8794)
        assert D[0, 0] == sp.cos(T) / (1 + s ** 2) and D[1, 1] == R * sp.cos(T) / (R ** 2 + s ** 2)


def test_ibvs_text_follows_the_rank_of_a_tall_matrix():
    """Three points through a 5-joint arm: J = J_s J_m is 6×5 of rank 5, so J J^# ≠ I and ė = −k J J^# e (the text
    claimed ė = −k e "while J keeps full row rank", impossible for a tall J); with J_s alone (6×6, rank 6) the
    claim is right and stays. The gain, the symbol k, is not written "k = k"; a gain with a value is."""
    pts = "[[0.2, 0.1, 2], [-0.2, 0.15, 2], [0.0, -0.2, 2]]"
    law = "    desired: [0.25, 0.15, -0.25, 0.2, 0.0, -0.25]\n"
    Jm = "    robot_jacobian: [[1, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0], [0, 0, 0, 1, 0], [0, 0, 0, 0, 1], " \
         "[0, 0, 0, 0, 0]]\n"
    p = load_problem_text(spec(pts, law + Jm, "  k: gain\n") + "values: {lambda: 1}\n")
    sols = solve_problem(p)
    J = num(all_results(sols)["J_task"].value.subs(sp.Symbol("lambda", positive=True), 1))
    assert J.shape == (6, 5) and np.linalg.matrix_rank(J) == 5
    assert not np.allclose(J @ np.linalg.pinv(J), np.eye(6))  # independent check: ė = −k J J^# e ≠ −k e
    for fmt in ("md", "tex"):
        text = render(p, sols, fmt)
        assert "keeps full row rank" not in text and "never has full row rank" in text, fmt
        assert "J J^\\# e$, where $J = J_s J_m$ is" in text and "of rank 5" in text, fmt
        assert "gain $k$," in text and "k = k" not in text, fmt
    p = load_problem_text(spec(pts, law + "    gain: 2\n") + "values: {lambda: 1}\n")
    sols = solve_problem(p)
    for fmt in ("md", "tex"):
        text = render(p, sols, fmt)
        assert "gives $\\dot e = -k e$ while $J$ keeps full row rank." in text and "gain $k = 2$," in text, fmt


def test_null_motions_of_a_symmetric_average_are_primitive():
    """Four points symmetric about the image center at one depth: the barycenter stays still under a translation
    along the optical axis, (0, 0, 1, 0, 0, 0) (it kept the spurious factor 4 of Σ λ/Z_i = 4λ/Z), and under a
    rotation about it; each is checked with J x = 0."""
    text = spec("[[a, a, Z], [-a, a, Z], [-a, -a, Z], [a, -a, Z]]", "    feature: average\n",
                "  a: {meaning: half side, sign: positive}\n  Z: depth\n")
    res = all_results(solve_problem(load_problem_text(text)))
    J = res["J_s"].value
    for name, want in (("null_translation", [0, 0, 1, 0, 0, 0]), ("null_axis_motion", [0, 0, 0, 0, 0, 1])):
        assert res[name].value == sp.Matrix(want), name
        assert (J * res[name].value).applyfunc(sp.simplify) == sp.zeros(2, 1), name
    origin = all_results(solve_problem(load_problem_text(spec("[0, 0, Z]", "", "  Z: depth\n"))))
    assert origin["null_rotation"].value == sp.Matrix([0, 0, 0, 0, 0, 1])  # (0, 0, 0, 0, 0, λ) before


def test_primitive_divides_by_the_rational_content_only():
    from solver.control.visual_servoing import primitive
    assert primitive(sp.Matrix([0, 0, 4 * L, 0])) == sp.Matrix([0, 0, L, 0])
    assert primitive(sp.Matrix([sp.Rational(1, 2), sp.Rational(-1, 3) * U])) == sp.Matrix([3, -2 * U])
    assert primitive(sp.Matrix([U, 2 * V, L])) == sp.Matrix([U, 2 * V, L])


@pytest.mark.parametrize("points, extra, words", [
    ("[[1, 2], [3, 4]]", "", "points: must be a list of [u, v, Z] triples"),
    ("[[0.1, 0.2, 2], [0.3, 0.1, 2]]", "    desired: [1, 2, 3]\n", "desired: 4 components expected"),
    ("[[0.1, 0.2, 2], [0.3, 0.1, 2]]", "    feature: average\n    desired: [1, 2, 3]\n", "desired: 2 components"),
    ("[[0.1, 0.2, 2]]", "    robot_jacobian: [[1, 0], [0, 1]]\n", "robot_jacobian: 6 rows expected"),
    ("[[0.1, 0.2, 2]]", "    at: {zz: 1}\n", "at: 'zz' is not a declared symbol"),
])
def test_check_finds_bad_options_without_solving(points, extra, words):
    """The points, desired features, robot Jacobian and state are read by the kind's validate hook (`check`):
    solving's error, without the interaction matrices."""
    assert words in error_found_without_solving(spec(points, extra))
