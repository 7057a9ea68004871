"""Linear approximation at an equilibrium and its controllability (``control_law`` with ``law: linearization``).

State x = (q, q̇), model B(q) q̈ + c(q, q̇) + g(q) + F_v q̇ = G(q) u. At rest in q_e the constant input u_e solves
G(q_e) u_e = g(q_e) (an equilibrium iff it has a solution). c is quadratic in q̇, so its first-order term
vanishes at q̇ = 0 and, with δx = x − x_e, δu = u − u_e,
    δẋ = A δx + B_l δu,   A = [[0, I], [−B⁻¹ K_e, −B⁻¹ F_v]],   B_l = [[0], [B⁻¹ G]],
    K_e = ∂(g(q) − G(q) u_e)/∂q at q_e (the stiffness of the equilibrium), every matrix at q_e.
Controllable iff rank [B_l, A B_l, ..., A^{2n−1} B_l] = 2n (Kalman).
"""
from __future__ import annotations

import itertools
from typing import Any

import sympy as sp

from solver.control.laws import ControlLawAsk, _zero
from solver.dynamics.model import derive, require_model
from solver.math.simplify import exact_det, factor_within, matmul, rational_matrix, tidy
from solver.results import Solution
from solver.spec.errors import UserError


def linearize(B: sp.Matrix, g: sp.Matrix, G: sp.Matrix, Fv: sp.Matrix, q: list, at: dict, ue: sp.Matrix
              ) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix]:
    """(A, B_l, K_e) of the linear approximation at rest in ``at`` with the input ``ue``."""
    n = len(q)
    Ke = (g - G * ue).jacobian(q).xreplace(at).applyfunc(tidy)
    Be = B.xreplace(at).applyfunc(tidy)
    Bi = (Be.adjugate() / factor_within(Be.det())).applyfunc(sp.simplify)
    A = sp.zeros(2 * n, 2 * n)
    A[:n, n:] = sp.eye(n)
    A[n:, :n] = matmul(-Bi, Ke).applyfunc(tidy)
    A[n:, n:] = matmul(-Bi, Fv.xreplace(at)).applyfunc(tidy)
    Bl = sp.zeros(2 * n, G.cols)
    Bl[n:, :] = matmul(Bi, G.xreplace(at)).applyfunc(tidy)
    return A, Bl, Ke


def _passive(G: sp.Matrix) -> list[int]:
    """The coordinates where no input acts (G row zero)."""
    return [i for i in range(G.rows) if all(_zero(x) for x in G.row(i))]


def _passive_rows(g: sp.Matrix, G: sp.Matrix) -> sp.Matrix:
    """The rows of g where no input acts: at rest they must vanish by themselves."""
    return sp.Matrix([g[i] for i in _passive(G)])


def read_equilibrium(problem, options: ControlLawAsk, ctx) -> tuple[dict, list[sp.Symbol]]:  # type: ignore[no-untyped-def]
    """The configuration of ``equilibrium:`` read and checked without the model (``check`` runs it, and
    :func:`solve_linearization` first): (the coordinates given, with their values; the ones not given, which the
    unactuated equations at rest must determine: as many as those equations)."""
    robot = require_model(problem)
    q = list(robot.q)
    place = problem.located.place(ctx.path + ("equilibrium",))
    if options.equilibrium is None:
        raise UserError("law: linearization needs equilibrium: {q1: .., q2: ..} (a configuration at rest)", place,
                        "e.g. equilibrium: {q1: 0, q2: 0}")
    names = {s.name: s for s in q}
    at: dict = {}
    for key in options.equilibrium:
        if key not in names:
            raise UserError(f"equilibrium: {key} is not a coordinate ({', '.join(names)})",
                            problem.located.place(ctx.path + ("equilibrium", key)))
        at[names[key]] = sp.sympify(ctx.expr("equilibrium", key))
    missing = [x for x in q if x not in at]
    rows = _passive(robot.input_map if robot.input_map is not None else sp.eye(robot.n))
    if missing and len(rows) != len(missing):
        raise UserError(f"equilibrium: {len(missing)} coordinates are not given, but the unactuated equations at rest "
                        f"are {len(rows)}: give the other coordinates", place)
    return at, missing


def solve_missing(problem, g: sp.Matrix, G: sp.Matrix, q: list, at: dict, missing: list, place) -> dict:  # type: ignore[no-untyped-def]
    """The coordinates of an equilibrium not given (as many as the unactuated rows of g(q) = G u at rest:
    :func:`read_equilibrium`): from those rows, with the parameter values; the unique real solution (polynomial
    equations: all real roots are found; otherwise a numeric root from 0)."""
    eqs = [x.xreplace(at) for x in _passive_rows(g, G)]
    num = [x.xreplace(problem.values) for x in eqs]
    free = set().union(*(x.free_symbols for x in num)) - set(missing) if num else set()
    if free:
        raise UserError("equilibrium: the coordinates not given are found numerically and need values for "
                        + ", ".join(sorted(map(str, free))), place, "add them to values:")
    if len(missing) == 1:
        try:
            poly = sp.Poly(sp.nsimplify(sp.expand(num[0]), rational=True), missing[0])
        except sp.PolynomialError:
            poly = None
        if poly is not None and poly.degree() > 0:
            roots = [r for r in sp.Poly(poly).real_roots()]
            roots = sorted({sp.Float(sp.N(r, 20), 15) for r in roots})
            if len(roots) != 1:
                raise UserError(f"equilibrium: {len(roots)} real solutions for {missing[0]} "
                                f"({', '.join(str(sp.N(r, 6)) for r in roots)}): give it", place)
            return {missing[0]: roots[0]}
    try:
        root = sp.nsolve(num, missing, [0.1] * len(missing))
    except (ValueError, ZeroDivisionError, TypeError) as exc:
        raise UserError(f"equilibrium: no solution found for {', '.join(map(str, missing))} ({exc})", place) from None
    return {x: sp.Float(root[i], 15) for i, x in enumerate(missing)}


def controllability(A: sp.Matrix, Bl: sp.Matrix) -> sp.Matrix:
    """[B_l, A B_l, ..., A^{N−1} B_l], N = dim x."""
    blocks, P = [], Bl
    for _ in range(A.rows):
        blocks.append(P)
        P = matmul(A, P).applyfunc(tidy)
    return sp.Matrix.hstack(*blocks)


def exact_controllability(A: sp.Matrix, Bl: sp.Matrix) -> Any:
    """:func:`controllability` as a DomainMatrix over the field of rational functions of the entries of A and B_l
    (:func:`solver.math.simplify.rational_matrix`), whose rank and det are exact; None when an entry is not such a
    function (a float, √2 or cos θ: the caller uses sympy's rank and det)."""
    fA, fB = rational_matrix(A), rational_matrix(Bl)
    if fA is None or fB is None:
        return None
    fA, fB = fA.unify(fB)
    blocks = [fB]
    for _ in range(A.rows - 1):
        blocks.append(fA * blocks[-1])
    return blocks[0].hstack(*blocks[1:])


def kalman_rank(A: sp.Matrix, Bl: sp.Matrix, trials: int = 3) -> int:
    """rank [B_l, A B_l, ..., A^{N−1} B_l] for generic parameter values, without the symbolic matrix (whose entries
    are rational functions that grow with every power of A): the exact rank at random rational points of the
    parameters (a rank is never larger at one point than generically, so a full rank at one point proves it; the
    largest of ``trials`` points is the generic rank with probability ≈ 1)."""
    from solver.math.equivalence import NotRational, random_points
    best = 0
    entries = [x for x in list(A) + list(Bl) if not x.is_number]
    for point in itertools.islice(random_points(entries), 3 * trials):
        try:
            a, b = (M.applyfunc(lambda x: sp.Rational(point.value(x))) for M in (A, Bl))
        except (ZeroDivisionError, NotRational):
            continue
        best = max(best, sp.Matrix.hstack(*(a ** k * b for k in range(A.rows))).rank())
        trials -= 1
        if best == A.rows or trials == 0:
            break
    return best


def _factored_det(M: sp.Matrix, exact: Any = None) -> sp.Expr:
    """det M factored: over the field of rational functions of its entries when they are such (``exact``: M there,
    when already converted; the determinant is then reduced, and factoring it is canonical), else M.det()
    simplified and factored."""
    exact = exact if exact is not None else rational_matrix(M)
    if exact is None:
        return factor_within(sp.simplify(M.det()))
    return factor_within(exact.domain.to_sympy(exact.det()))


def solve_linearization(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: u_eq, K_e, A_lin, B_lin, ctrb, rank_ctrb, controllable, det_ctrb (single input), char_poly."""
    at, missing = read_equilibrium(problem, options, ctx)
    robot = problem.robot
    dm = derive(robot)
    n = robot.n
    q, dq = list(robot.q), list(robot.dq)
    place = problem.located.place(ctx.path + ("equilibrium",))
    G = dm.G if dm.G is not None else sp.eye(n)
    m = G.cols
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    solved_for: list = []
    if missing:
        at |= solve_missing(problem, dm.g, G, q, at, missing, place)
        solved_for = missing
    at |= {v: 0 for v in dq}
    num = dict(problem.values) if solved_for else {}   # a numeric equilibrium: a numeric linearization
    Bm, gm, G, Fv = (x.xreplace(num) for x in (dm.B, dm.g, G, Fv))
    ge, Ge = gm.xreplace(at).applyfunc(tidy), G.xreplace(at).applyfunc(tidy)
    if solved_for:   # the numeric root leaves round-off in the equations it solves
        ge = ge.applyfunc(lambda x: sp.Integer(0) if x.is_number and abs(sp.N(x)) < 1e-9 else sp.N(x, 15))
    us = sp.symbols(f"ue0:{m}")
    sols = sp.linsolve((Ge, ge), *us)
    if not sols:
        raise UserError(f"the configuration is not an equilibrium for any constant input: G(q_e) u = g(q_e) has no "
                        f"solution (g(q_e) = {list(ge)})", place, "choose a configuration where the passive "
                        "coordinates feel no gravity torque")
    ue = sp.Matrix(list(next(iter(sols)))).applyfunc(tidy)
    ue = ue.xreplace({s: 0 for s in us})   # free inputs (more inputs than needed) set to 0
    A, Bl, Ke = linearize(Bm, gm, G, Fv, q, at, ue)
    lam = sp.Symbol("s")
    Be = Bm.xreplace(at).applyfunc(tidy)
    if n <= 2 or not (A.free_symbols | Bl.free_symbols):
        C = controllability(A, Bl)
        exact = exact_controllability(A, Bl)
        rank = exact.rank() if exact is not None else C.rank(simplify=True)
        if A.has(sp.Float):   # division-free (Berkowitz) and expanded: float coefficients neither cancel nor factor
            cp = sp.Add(*(lam ** k * tidy(c) for (k,), c in A.charpoly(lam).terms()))   # (1.0000000000000002 -> 1)
        else:
            cp = _factored_det(lam * sp.eye(2 * n) - A)
    else:  # the powers of A are rational functions that grow without bound: rank at random points, and
        C = None  # det(sI − A) = det(B_e s² + F_v s + K_e) / det B_e, an n×n polynomial determinant
        rank = kalman_rank(A, Bl)
        Fe = Fv.xreplace(at)
        num = sp.Poly(exact_det(Be * lam ** 2 + Fe * lam + Ke), lam)
        den = factor_within(exact_det(Be))
        cp = sp.Add(*(factor_within(sp.cancel(c / den)) * lam ** k for (k,), c in num.terms()))
    sol = Solution("control_law", title=options.title or "Linear approximation at an equilibrium")
    sol.add("q_eq", sp.Matrix([at[x] for x in q]), "vector", label="q_e")
    sol.add("u_eq", ue, "vector", label="u_e")
    sol.add("K_e", Ke, "matrix", label="K_e = \\partial(g - G u_e)/\\partial q")
    sol.add("A_lin", A, "matrix", label="A")
    sol.add("B_lin", Bl, "matrix", label="B")
    if C is not None:
        sol.add("ctrb", C, "matrix", label="\\mathcal{C}")
    sol.add("rank_ctrb", sp.Integer(rank), "number", label="\\operatorname{rank}\\mathcal{C}")
    sol.add("controllable", bool(rank == 2 * n), "bool", label="\\text{controllable}")
    detc = None
    if m == 1 and C is not None:
        detc = _factored_det(C, exact)
        sol.add("det_ctrb", detc, "scalar", label="\\det\\mathcal{C}")
    sol.add("char_poly", cp, "scalar", label="\\det(sI - A)")
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("linearization", qe=sp.Matrix([at[s] for s in q]), ue=ue, Ke=Ke, A=A, Bl=Bl, C=C, rank=rank, N=2 * n,
             detc=detc, cp=cp, Be=Be, friction=dm.Fv is not None,
             zero_g=all(_zero(x) for x in ge), solved_for=sp.Matrix(solved_for) if solved_for else None,
             passive_eq=_passive_rows(dm.g, G) if solved_for else None)
    return sol
