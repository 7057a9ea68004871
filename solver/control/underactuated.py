"""Partial feedback linearization of underactuated robots (``control_law`` with ``law: partial_fbl``).

Order the coordinates as q = (q_a, q_p): the inputs act on the actuated ones, G = [G_a; 0] with G_a square and
invertible. With n = c + g + F_v q̇ the model splits into
    M_aa q̈_a + M_ap q̈_p + n_a = G_a u,        M_pa q̈_a + M_pp q̈_p + n_p = 0.
Collocated (q̈_a = v, always possible since M_pp > 0):
    q̈_p = −M_pp⁻¹(M_pa v + n_p),   G_a u = (M_aa − M_ap M_pp⁻¹ M_pa) v + n_a − M_ap M_pp⁻¹ n_p.
Non-collocated (q̈_p = v, needs M_pa of full row rank — the strong inertial coupling condition —, here with as many
inputs as passive coordinates, det M_pa ≠ 0):
    q̈_a = −M_pa⁻¹(M_pp v + n_p),   G_a u = (M_ap − M_aa M_pa⁻¹ M_pp) v + n_a − M_aa M_pa⁻¹ n_p.
The coordinates not linearized keep the second-order "internal" dynamics q̈_free(q, q̇, v).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from solver.control.laws import (
    ControlLawAsk,
    _gain_symbols,
    _gain_values,
    _qname,
    _sub_tex,
    _symbol,
    _zero,
    listed_values,
    record_law,
)
from solver.dynamics.model import derive, require_model
from solver.math.simplify import factor_within, tidy
from solver.results import Solution
from solver.spec.errors import UserError


def split_inputs(problem, G: sp.Matrix | None, n: int, ctx, law: str  # type: ignore[no-untyped-def]
                 ) -> tuple[list[int], list[int], sp.Matrix]:
    """(actuated indices, passive indices, G_a) of the input map G of n coordinates: the rows of G that are not
    zero are the actuated coordinates."""
    place = problem.located.place(ctx.path + ("law",))
    if G is None:
        raise UserError(f"law: {law} needs robot.input_map: the inputs act on some coordinates only", place,
                        "give input_map, e.g. [[1], [0]] for a force on q1 only")
    act = [i for i in range(n) if any(not _zero(x) for x in G.row(i))]
    pas = [i for i in range(n) if i not in act]
    Ga = G.extract(act, list(range(G.cols)))
    if len(act) != G.cols or _zero(sp.simplify(Ga.det())):
        raise UserError(f"law: {law} needs the inputs to act one to one on {G.cols} coordinates (G = [G_a; 0] with "
                        f"G_a square and invertible)", place, "check robot.input_map")
    if not pas:
        raise UserError(f"law: {law} is for underactuated robots, but every coordinate is actuated", place,
                        "use law: computed_torque")
    return act, pas, Ga


def _block(M: sp.Matrix, rows: list[int], cols: list[int]) -> sp.Matrix:
    return M.extract(rows, cols)


def _inv(M: sp.Matrix) -> sp.Matrix:
    return (M.adjugate() / factor_within(M.det())).applyfunc(sp.simplify) if M.rows > 1 else \
        sp.Matrix([[1 / M[0, 0]]])


@dataclass
class PartialInputs:
    """The options of ``law: partial_fbl`` as read: the actuated and passive coordinates (indices), G_a, the
    linearized and free ones, and the gains and q_d given (None: not given)."""

    act: list[int]
    pas: list[int]
    Ga: sp.Matrix
    lin: list[int]
    free: list[int]
    kp: list[sp.Expr] | None
    kd: list[sp.Expr] | None
    yd: list[sp.Expr] | None


def read_partial(problem, options: ControlLawAsk, ctx) -> PartialInputs:  # type: ignore[no-untyped-def]
    """The options of ``law: partial_fbl`` read and checked without the model (``check`` runs it, and
    :func:`solve_partial` first): the input map (underactuated, G_a invertible), as many inputs as passive
    coordinates when not collocated, and with kp:/kd: the gains and qd: (one per linearized coordinate)."""
    robot = require_model(problem)
    act, pas, Ga = split_inputs(problem, robot.input_map, robot.n, ctx, "partial_fbl")
    col = options.collocated
    lin, free = (act, pas) if col else (pas, act)
    if not col and len(pas) != len(act):
        raise UserError(f"non-collocated partial feedback linearization is built here with as many inputs as passive "
                        f"coordinates ({len(act)} inputs, {len(pas)} passive)",
                        problem.located.place(ctx.path + ("collocated",)), "use collocated: true, or choose the inputs")
    kp = kd = yd = None
    if options.kp is not None or options.kd is not None:
        kp = _gain_values(problem, options, ctx, "kp", len(lin))
        kd = _gain_values(problem, options, ctx, "kd", len(lin))
        if options.qd is not None:
            yd = listed_values(problem, ctx, "qd", len(lin), "the linearized coordinates")
    return PartialInputs(act, pas, Ga, lin, free, kp, kd, yd)


def solve_partial(problem, options: ControlLawAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: u (in v, or in the gains with kp/kd), v, ddq_free, M_v (the matrix of v in G_a u), n_v (the rest),
    coupling (det M_pa, non-collocated), closed_loop_check; with kp/kd also zero_dynamics."""
    read = read_partial(problem, options, ctx)
    robot = problem.robot
    dm = derive(robot)
    n = robot.n
    act, pas, Ga, lin, free = read.act, read.pas, read.Ga, read.lin, read.free
    q, dq = list(robot.q), list(robot.dq)
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    nv = dm.c + dm.g + Fv * sp.Matrix(dq)
    M = dm.B
    col = options.collocated
    place = problem.located.place(ctx.path + ("collocated",))
    v = sp.Matrix([_symbol(problem, "v" + (q[i].name[1:] if q[i].name[1:].isdigit() else q[i].name),
                           f"v_{{{i + 1}}}") for i in lin])
    Mff, Mfl = _block(M, free, free), _block(M, free, lin)
    Mlf, Mll = _block(M, lin, free), _block(M, lin, lin)
    nf, nl = nv.extract(free, [0]), nv.extract(lin, [0])
    # free-coordinate equations: Mff q̈_f + Mfl v + n_f = (0 collocated | G_a u non-collocated)
    coupling = None
    if col:
        Mffi = _inv(Mff)
        ddq_free = (-Mffi * (Mfl * v + nf)).applyfunc(tidy)
        Mv = (Mll - Mlf * Mffi * Mfl).applyfunc(tidy)
        nvec = (nl - Mlf * Mffi * nf).applyfunc(tidy)
    else:
        # passive rows: M_pa q̈_a + M_pp v + n_p = 0 ; here lin = passive, free = actuated
        Mpa = _block(M, pas, act)
        coupling = factor_within(sp.simplify(Mpa.det()))
        if _zero(coupling):
            raise UserError("non-collocated partial feedback linearization needs det M_pa ≠ 0 (strong inertial "
                            "coupling), but M_pa is singular everywhere", place, "use collocated: true")
        Mpai = _inv(Mpa)
        ddq_free = (-Mpai * (_block(M, pas, pas) * v + nv.extract(pas, [0]))).applyfunc(tidy)
        Mv = (_block(M, act, pas) - _block(M, act, act) * Mpai * _block(M, pas, pas)).applyfunc(tidy)
        nvec = (nv.extract(act, [0]) - _block(M, act, act) * Mpai * nv.extract(pas, [0])).applyfunc(tidy)
    Gai = _inv(Ga)
    u_v = (Gai * (Mv * v + nvec)).applyfunc(tidy)
    # exact check: the full model with this u gives q̈_lin = v
    ddq = sp.zeros(n, 1)
    for k, i in enumerate(lin):
        ddq[i] = v[k]
    for k, i in enumerate(free):
        ddq[i] = ddq_free[k]
    G = dm.G
    res = M * ddq + nv - G * u_v
    ok = all(_zero(sp.simplify(x)) for x in res)
    sol = Solution("control_law", title=options.title or "Partial feedback linearization")
    u = u_v
    law_v = None
    zero_dyn = None
    if options.kp is not None or options.kd is not None:
        kp = read.kp if read.kp is not None else _gain_symbols(problem, "kp", len(lin))
        kd = read.kd if read.kd is not None else _gain_symbols(problem, "kd", len(lin))
        if read.yd is not None:
            yd = read.yd
        else:
            yd = [_symbol(problem, _qname(q[i].name, "d"), _sub_tex(problem.latex_names.get(q[i], q[i].name), "d"))
                  for i in lin]
        law_v = sp.Matrix([kp[k] * (yd[k] - q[i]) - kd[k] * dq[i] for k, i in enumerate(lin)])
        u = u_v.xreplace(dict(zip(v, law_v))).applyfunc(tidy)
        at = {q[i]: yd[k] for k, i in enumerate(lin)} | {dq[i]: 0 for i in lin}
        zero_dyn = ddq_free.xreplace(dict(zip(v, [0] * len(lin)))).xreplace(at).applyfunc(tidy)
        sol.add("v_law", law_v, "vector", label="v")
        record_law(problem, options.suffix, [q[i] for i in lin], [[y] for y in yd],
                   yd if options.qd is not None else None)
    if law_v is None:
        record_law(problem, options.suffix, [q[i] for i in lin], [[None] for _ in lin], None)
    sol.add("u", u, "vector", label="u")
    sol.add("M_v", Mv, "matrix", label="\\bar M(q)")
    sol.add("n_v", nvec, "vector", label="\\bar n(q,\\dot q)")
    sol.add("ddq_free", ddq_free, "vector", label="\\ddot q_{free}")
    if coupling is not None:
        sol.add("coupling", coupling, "scalar", label="\\det M_{pa}(q)")
    if zero_dyn is not None:
        sol.add("zero_dynamics", zero_dyn, "vector", label="\\ddot q_{free}\\,|_{y = y_d}")
    sol.add("closed_loop_check", bool(ok), "bool", label="\\text{closed loop verified}")
    names = [q[i] for i in lin]
    sol.step("model", B=dm.B, c=dm.c, g=dm.g, Fv=dm.Fv, G=dm.G, n=n, friction=dm.Fv is not None)
    sol.step("pfl", collocated=col, lin=sp.Matrix(names), free=sp.Matrix([q[i] for i in free]), v=v,
             ddq_free=ddq_free, Mv=Mv, nvec=nvec, Ga=Ga, u=u_v, coupling=coupling, ok=ok,
             Mff=Mff, Mfl=Mfl, law_v=law_v, u_law=u if law_v is not None else None, zero_dyn=zero_dyn,
             Mpa=_block(M, pas, act), friction=dm.Fv is not None)
    return sol
