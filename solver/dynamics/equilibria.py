"""Equilibria and steady motions under a constant input (ask kind ``equilibria``).

At rest (q̇ = 0) with the constant input ū (default 0) the robot stays at q exactly where g(q) = G ū.
Each angle θ (a coordinate inside sin/cos) is replaced by (c_θ, s_θ) with c_θ² + s_θ² = 1, which turns the
equations into a polynomial system; its solutions (all of them, by Gröbner bases) give θ = atan2(s_θ, c_θ) ∈ (-π, π].
A coordinate left free by a solution is arbitrary there (a continuum of equilibria); square roots in a solution
give the conditions for it to exist.

Steady motions with constant velocity (``steady: velocity``): q(t) = q̄ + v̄ t, q̈ = 0, in the model
B(q) q̈ + c(q, q̇) + g(q) + F_v q̇ = G u with u ≡ ū. They exist iff

    E(q) = c(q, v̄) + g(q) + F_v v̄ − G ū = 0   for every q = q̄ + v̄ t,

i.e. E must be constant (and zero) along the motion. For coordinates outside sin/cos, q_p → q̄_p + v̄_p t makes E
a polynomial in t whose coefficients must all vanish (for springs: E(q̄) = 0 and K v̄ = 0, the motion does not
deform them). An angle either stays (v̄_θ = 0) or rotates; for each set of rotating angles E must not depend on
them (every coefficient of E as a polynomial in cos θ, sin θ, reduced by sin²θ = 1 − cos²θ, vanishes: exact for
one rotating angle, and for several ones rotating at speeds with irrational ratios). v̄ = 0 gives the equilibria.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations
from typing import Literal, Optional, Union

import sympy as sp
from pydantic import Field

from solver.dynamics.model import derive, require_model
from solver.math.simplify import angle_symbols, tidy
from solver.registry import ask_kind
from solver.results import Solution
from solver.spec.errors import UserError
from solver.spec.models import Strict

Scalar = Union[str, int, float]


class EquilibriaAsk(Strict):
    """Find every configuration where the robot stays at rest (u = 0 or a constant input), or every steady motion
    with constant velocity under a constant input."""

    kind: Literal["equilibria"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    input: Optional[dict[str, Scalar]] = Field(
        None, description="the constant input ū by input name, e.g. {u: ubar} (inputs left out are 0)")
    steady: Literal["rest", "velocity"] = Field(
        "rest", description="rest: equilibria g(q) = G ū (q̇ = 0); velocity: steady motions q = q̄ + v̄ t with "
                            "q̈ = 0 (v̄ = 0 among them)")
    velocity: Optional[dict[str, Scalar]] = Field(
        None, description="steady: velocity: the given components of v̄ by coordinate name, e.g. {theta: Omega} "
                          "(the others are unknowns)")
    solve_for: list[str] = Field(
        default_factory=list, description="inputs whose constant value is unknown and found with the steady "
                                          "state (e.g. the torque that sustains a given speed)")
    deformations: Optional[list[str]] = Field(
        None, description="expressions in q (e.g. q1 - q2, the springs' deformations) evaluated at each steady "
                          "state: result deformations")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$",
                        description="appended to every result name (several equilibria asks in one problem)")


def _to_polynomial(g: list[sp.Expr], angles: list[sp.Symbol]) -> tuple[list[sp.Expr], dict]:
    cs = {a: (sp.Symbol(f"c_{a.name}", real=True), sp.Symbol(f"s_{a.name}", real=True)) for a in angles}
    eqs = []
    for x in g:
        e = sp.expand(sp.expand_trig(sp.expand(x, trig=True)))
        e = e.subs({sp.cos(a): cs[a][0] for a in angles}).subs({sp.sin(a): cs[a][1] for a in angles})
        e = sp.numer(sp.together(e))
        if e != 0:
            eqs.append(sp.expand(e))
    eqs += [c ** 2 + s ** 2 - 1 for c, s in cs.values()]
    return eqs, cs


def equilibria(g: sp.Matrix, q: list[sp.Symbol]) -> tuple[list[sp.Matrix], list[sp.Expr], bool]:
    """(configurations, conditions, every_configuration) for g(q) = 0."""
    g_list = [tidy(x) for x in g]
    if all(x == 0 for x in g_list):
        return [sp.Matrix(q)], [], True
    angles = [a for a in angle_symbols(sp.Add(*g_list)) if a in q]
    eqs, cs = _to_polynomial(g_list, angles)
    unknowns = [v for a in angles for v in cs[a]] + [x for x in q if x not in angles]
    sols = sp.solve(eqs, unknowns, dict=True)
    configs, conditions = [], []
    for s in sols:
        vals = []
        for x in q:
            if x in angles:
                c, sn = s.get(cs[x][0], cs[x][0]), s.get(cs[x][1], cs[x][1])
                if c.free_symbols & {cs[x][0], cs[x][1]} or sn.free_symbols & {cs[x][0], cs[x][1]}:
                    vals.append(x)  # free angle
                else:
                    vals.append(tidy(sp.atan2(sn, c)) if not (c.is_number and sn.is_number) else sp.atan2(sn, c))
            else:
                vals.append(tidy(s.get(x, x)))
        if any(v.has(sp.I) for v in vals):
            continue
        for v in vals:
            for p in v.atoms(sp.Pow):
                if p.exp == sp.Rational(1, 2) and not p.base.is_nonnegative:
                    conditions.append(sp.GreaterThan(p.base, 0))
        configs.append(sp.Matrix(vals))
    configs.sort(key=lambda m: [float(sp.N(x)) if x.is_number else 0.0 for x in m])
    return configs, list(dict.fromkeys(conditions)), False


@dataclass
class SteadyMotion:
    """q(t) = q + v t under the constant input u (an entry of q or v left as its own symbol is arbitrary)."""

    q: sp.Matrix
    v: sp.Matrix
    u: sp.Matrix


@dataclass
class SteadyAnalysis:
    """The steady motions of B q̈ + c + g + F_v q̇ = G ū with q̈ = 0, and what explains them."""

    rows: sp.Matrix                    # c(q, q̇) + g(q) + F_v q̇ (q̈ = 0, q̇ = v̄ written as q̇)
    rhs: sp.Matrix                     # G ū
    motions: list[SteadyMotion]
    conditions: list[sp.Expr]          # each > 0 for the motions with square roots to exist
    angles: list[sp.Symbol]            # coordinates inside sin/cos of the equations
    partial: bool = False              # not every set of rotating angles was searched
    K: sp.Matrix | None = None         # ∂g/∂q when constant and c ≡ 0 (linear elastic forces)
    rigid: list[sp.Matrix] = field(default_factory=list)   # K r = 0: the motions that keep every spring's length
    sums: list[tuple[sp.Matrix, sp.Expr, sp.Expr]] = field(default_factory=list)  # (w, wᵀF_v q̇, wᵀG ū), wᵀK = 0


class _Skip(Exception):
    """This set of rotating angles cannot be decided (an angle also outside sin/cos)."""


def _reduce_sc(expr: sp.Expr, c: sp.Symbol, s: sp.Symbol) -> sp.Expr:
    """A polynomial in (c, s) with s² replaced by 1 − c² (at most linear in s): a unique form on the circle."""
    out = sp.Integer(0)
    for (k,), coeff in sp.Poly(expr, s).terms():
        out += coeff * s ** (k % 2) * (1 - c ** 2) ** (k // 2)
    return sp.expand(out)


def _angle_free_parts(expr: sp.Expr, rotating: list[sp.Symbol], cs: dict) -> list[sp.Expr]:
    """The coefficients of ``expr`` as a polynomial in cos θ, sin θ of the rotating angles θ (reduced on the
    circle): ``expr`` is the same for every value of those angles iff all but the constant one vanish."""
    e = sp.expand(sp.expand_trig(sp.expand(expr, trig=True)))
    e = e.subs({sp.cos(a): cs[a][0] for a in rotating}).subs({sp.sin(a): cs[a][1] for a in rotating})
    e = sp.numer(sp.together(e))
    if e.free_symbols & set(rotating):
        raise _Skip
    for a in rotating:
        e = _reduce_sc(e, *cs[a])
    gens = [x for a in rotating for x in cs[a]]
    return list(sp.Poly(e, *gens).coeffs()) if e != 0 else []


def _along_line(expr: sp.Expr, moving: dict, t: sp.Symbol) -> list[sp.Expr]:
    """The coefficients of expr(q̄ + v̄ t) as a polynomial in t (all must vanish for expr ≡ 0 along the line)."""
    e = sp.numer(sp.together(expr.xreplace({p: p + v * t for p, v in moving.items()})))
    try:
        return list(sp.Poly(sp.expand(e), t).all_coeffs())
    except sp.PolynomialError:
        raise _Skip from None


def _elastic_sums(c: sp.Matrix, g: sp.Matrix, Fv: sp.Matrix, rhs: sp.Matrix, q: list, dq: list) -> tuple:
    """For linear elastic forces (c ≡ 0, g = K q + g₀ with K constant): K, the rigid motions r (K r = 0) and, for each
    w with wᵀK = 0, the weighted sum of the equations in which the elastic forces cancel: wᵀF_v q̇ = wᵀG ū."""
    if any(x != 0 for x in c):
        return None, [], []
    K = g.jacobian(q)
    if any(x.free_symbols & set(q) for x in K) or K.is_zero_matrix:
        return None, [], []
    left = K.T.nullspace()
    if not left:
        return K, [], []
    v = sp.Matrix(dq)
    sums = [(w, tidy((w.T * Fv * v)[0]), tidy((w.T * rhs)[0])) for w in left]
    return K, K.nullspace(), sums


def steady_motions(rows: sp.Matrix, rhs: sp.Matrix, q: list[sp.Symbol], dq: list[sp.Symbol],
                   given_v: dict[sp.Symbol, sp.Expr], unknown_u: list[sp.Symbol], u: list[sp.Expr],
                   max_rotating: int = 3) -> tuple[list[SteadyMotion], list[sp.Expr], list[sp.Symbol], bool]:
    """Every motion q(t) = q̄ + v̄ t with rows(q, v̄) = rhs (ū) at all t (rows = c + g + F_v q̇ with q̈ = 0, q̇ = v̄
    written with the symbols dq). given_v fixes components of v̄ (by the dq symbol); u is ū, where the inputs
    unknown_u (found with the motion) are their own symbols. Returns (motions, conditions, angles, partial)."""
    t = sp.Dummy("t")
    E = [tidy(sp.expand(r - h).xreplace(given_v)) for r, h in zip(rows, rhs)]
    vel = {x: given_v.get(d, d) for x, d in zip(q, dq)}
    angles = [a for a in angle_symbols(sp.Add(*E)) if a in q]
    forced = [a for a in angles if given_v.get(vel_sym(a, q, dq), 0) != 0]
    optional = [a for a in angles if a not in forced and vel_sym(a, q, dq) not in given_v]
    partial = len(optional) > max_rotating
    if partial:   # too many angles to try every set: only the rotations the spec gives
        subsets = [forced]
    else:
        subsets = [forced + list(extra) for k in range(len(optional) + 1) for extra in combinations(optional, k)]
    cs = {a: (sp.Symbol(f"c_{a.name}", real=True), sp.Symbol(f"s_{a.name}", real=True)) for a in angles}
    motions: list[SteadyMotion] = []
    conditions: list[sp.Expr] = []
    for rotating in subsets:
        stay = {vel_sym(a, q, dq): sp.Integer(0) for a in angles
                if a not in rotating and vel_sym(a, q, dq) not in given_v}
        others = [x for x in q if x not in angles]
        moving = {x: vel[x].xreplace(stay) for x in others}
        eqs: list[sp.Expr] = []
        try:
            for e in E:
                e = e.xreplace(stay)
                for part in (_angle_free_parts(e, rotating, cs) if rotating else [e]):
                    eqs += _along_line(part, moving, t)
        except _Skip:
            partial = True
            continue
        eqs = list(dict.fromkeys(sp.expand(x) for x in eqs if sp.expand(x) != 0))
        su, eqs = _eliminate_inputs(eqs, list(unknown_u))
        still = [a for a in angles if a not in rotating and any(a in x.free_symbols for x in eqs)]
        poly, cs2 = _to_polynomial(eqs, still)
        unknowns = ([x for a in still for x in cs2[a]] + others
                    + [d for x, d in zip(q, dq) if d not in given_v and d not in stay])
        present = set().union(*(x.free_symbols for x in poly)) if poly else set()
        unknowns = [x for x in unknowns if x in present]  # sympy's solve can miss solutions given absent unknowns
        if any(not (x.free_symbols & set(unknowns)) for x in poly):
            continue  # an equation of the parameters alone (generic parameters: it does not hold)
        sols = sp.solve(poly, unknowns, dict=True) if poly else [{}]
        named = _branches(sols, still, cs2)
        for k, s in enumerate(sols):
            qs, trig, raw = [], {}, []
            for x in q:
                if x in still:
                    c, sn = s.get(cs2[x][0], cs2[x][0]), s.get(cs2[x][1], cs2[x][1])
                    if (c.free_symbols | sn.free_symbols) & set(cs2[x]):
                        qs.append(x)
                    else:
                        qs.append(named.get((k, x)) or (tidy(sp.atan2(sn, c)) if not (c.is_number and sn.is_number)
                                                        else sp.atan2(sn, c)))
                        raw += [c, sn]
                        th = named.get((k, x))   # with its own cosine and sine (the branch the name says)
                        trig |= {sp.cos(x): sp.cos(th), sp.sin(x): sp.sin(th)} if th is not None else \
                            {sp.cos(x): c, sp.sin(x): sn}
                else:
                    qs.append(tidy(sp.sympify(s.get(x, x))))
            vs = [tidy(sp.sympify(s.get(d, vel[x].xreplace(stay)))) for x, d in zip(q, dq)]
            if any(vs[q.index(a)] == 0 for a in rotating):
                continue  # found with that angle at rest
            at = {x: v for x, v in zip(q, qs) if x not in trig and x != v} | {d: v for d, v in zip(dq, vs)}
            us = [tidy(sp.expand_trig(sp.expand(su.get(w, w), trig=True)).subs(trig).subs(at))
                  if w in unknown_u else sp.sympify(w) for w in u]
            allv = qs + vs + us
            if any(x.has(sp.I) for x in allv + raw):
                continue
            for x in allv + raw:
                for p in x.atoms(sp.Pow):
                    if p.exp == sp.Rational(1, 2) and not p.base.is_nonnegative:
                        conditions.append(sp.GreaterThan(p.base, 0))
            m = SteadyMotion(sp.Matrix(qs), sp.Matrix(vs), sp.Matrix(us))
            if not any(m.q == o.q and m.v == o.v and m.u == o.u for o in motions):
                motions.append(m)
    motions.sort(key=lambda m: [float(sp.N(x)) if x.is_number else 0.0 for x in list(m.v) + list(m.q)])
    return motions, list(dict.fromkeys(conditions)), angles, partial


def _has_sqrt(e: sp.Expr) -> bool:
    return any(p.exp.is_Rational and p.exp.q == 2 for p in sp.sympify(e).atoms(sp.Pow))


def _branches(sols: list[dict], angles: list[sp.Symbol], cs: dict) -> dict:
    """Angles of the solution pairs (c, s), (−c, s) with s free of square roots (θ = asin s and π − asin s) or
    (c, s), (c, −s) with c free of them (θ = ±acos c): as a set they are the same for every value of the parameters,
    while atan2(s, c) with c = ±√(…)/D swaps its branches with the sign of D. Returns {(solution, angle): θ}."""
    out: dict = {}
    for a in angles:
        c_, s_ = cs[a]
        for i, si in enumerate(sols):
            ci, sni = si.get(c_, c_), si.get(s_, s_)
            if (i, a) in out or (ci.free_symbols | sni.free_symbols) & {c_, s_}:
                continue
            for sin_known in (True, False):
                known, other = (sni, ci) if sin_known else (ci, sni)
                if _has_sqrt(known) or not _has_sqrt(other):
                    continue
                if not tidy(sp.expand(ci ** 2 + sni ** 2 - 1)) == 0:
                    continue
                rest = {k: v for k, v in si.items() if k not in (c_, s_)}
                for j, sj in enumerate(sols):
                    if j == i or (j, a) in out or {k: v for k, v in sj.items() if k not in (c_, s_)} != rest:
                        continue
                    cj, snj = sj.get(c_, c_), sj.get(s_, s_)
                    kj, oj = (snj, cj) if sin_known else (cj, snj)
                    if tidy(kj - known) != 0 or tidy(oj + other) != 0:
                        continue
                    if sin_known:
                        base = tidy(sp.asin(known))
                        out[(i, a)], out[(j, a)] = base, sp.pi - base
                    else:
                        base = tidy(sp.acos(known))
                        out[(i, a)], out[(j, a)] = base, -base
                    # the pair is the same set whichever is the + branch; the solutions' other entries are equal
                    break
                if (i, a) in out:
                    break
    return out


def _eliminate_inputs(eqs: list[sp.Expr], unknown_u: list[sp.Symbol]) -> tuple[dict, list[sp.Expr]]:
    """The equations are affine in the unknown inputs: solve independent ones for them (u = u(q, v̄)) and return
    that solution and the remaining equations with it substituted (constraints on q and v̄ alone)."""
    if not unknown_u:
        return {}, eqs
    lin = [e for e in eqs if e.free_symbols & set(unknown_u)]
    chosen: list[sp.Expr] = []
    rank = 0
    for e in lin:
        M = sp.Matrix(chosen + [e]).jacobian(unknown_u)
        r = M.rank(simplify=True)
        if r > rank:
            chosen, rank = chosen + [e], r
    sol = sp.solve(chosen, unknown_u, dict=True) if chosen else [{}]
    su = sol[0] if sol else {}
    rest = [sp.numer(sp.together(sp.expand(e.xreplace(su)))) for e in eqs]
    return su, [sp.expand(e) for e in rest if sp.expand(e) != 0]


def vel_sym(x: sp.Symbol, q: list[sp.Symbol], dq: list[sp.Symbol]) -> sp.Symbol:
    """The velocity symbol of coordinate x."""
    return dq[q.index(x)]


def _read_inputs(problem, options: EquilibriaAsk, ctx, robot) -> tuple[dict, list]:  # type: ignore[no-untyped-def]
    """ū by input symbol (0 where not given; the symbol itself for the inputs to solve for) and those inputs."""
    names = {w.name: w for w in robot.inputs}
    hint = f"the inputs are {', '.join(names)} (robot: inputs:)"
    ubar: dict = {w: sp.Integer(0) for w in robot.inputs}
    for key in options.input or {}:
        if key not in names:
            raise UserError(f"input: {key} is not an input of the robot", problem.located.place(
                ctx.path + ("input", key)), hint)
        ubar[names[key]] = sp.sympify(ctx.expr("input", key))
    unknown = []
    for k, key in enumerate(options.solve_for):
        place = problem.located.place(ctx.path + ("solve_for", k))
        if key not in names:
            raise UserError(f"solve_for: {key} is not an input of the robot", place, hint)
        if key in (options.input or {}):
            raise UserError(f"solve_for: {key} is also given in input:", place, "give an input or solve for it")
        ubar[names[key]] = names[key]
        unknown.append(names[key])
    return ubar, unknown


def _read_velocity(problem, options: EquilibriaAsk, ctx, robot) -> dict:  # type: ignore[no-untyped-def]
    """The given components of v̄, by velocity symbol."""
    if options.velocity is None:
        return {}
    if options.steady != "velocity":
        raise UserError("velocity: needs steady: velocity (at rest every velocity is 0)",
                        problem.located.place(ctx.path + ("velocity",)), "add steady: velocity")
    names = {x.name: d for x, d in zip(robot.q, robot.dq)} | {d.name: d for d in robot.dq}
    out = {}
    for key in options.velocity:
        if key not in names:
            raise UserError(f"velocity: {key} is not a coordinate", problem.located.place(
                ctx.path + ("velocity", key)), f"the coordinates are {', '.join(x.name for x in robot.q)}")
        out[names[key]] = sp.sympify(ctx.expr("velocity", key))
    return out


@ask_kind("equilibria", EquilibriaAsk,
          "equilibria g(q) = G ū (u = 0 by default) and steady motions with constant velocity under a constant input")
def solve_equilibria(problem, options: EquilibriaAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the suffix): at rest equilibria (set of configurations), n_equilibria (and equilibrium_input
    with solve_for); with steady: velocity steady_state (set of q̄), steady_velocity (set of v̄), n_steady (and
    steady_input with solve_for); deformations (set of the given expressions at each steady state)."""
    robot = require_model(problem)
    dm = derive(robot)
    n, q, dq = robot.n, list(robot.q), list(robot.dq)
    ubar, unknown = _read_inputs(problem, options, ctx, robot)
    given_v = _read_velocity(problem, options, ctx, robot)
    G = dm.G if dm.G is not None else sp.eye(n)
    rhs = (G * sp.Matrix([ubar[w] for w in robot.inputs])).applyfunc(tidy)
    given_u = [(w, ubar[w]) for w in robot.inputs if w not in unknown]   # shown unless every input is 0
    given_u = given_u if unknown or any(v != 0 for _, v in given_u) else []
    defs = [sp.sympify(x) for x in ctx.expr("deformations")] if options.deformations else []
    sfx = options.suffix
    if options.steady == "rest" and not unknown:
        configs, conditions, every = equilibria((dm.g - rhs).applyfunc(tidy), q)
        sol = Solution("equilibria", title=options.title or "Equilibrium configurations")
        sol.add("equilibria" + sfx, configs, "set", label="q_e")
        sol.add("n_equilibria" + sfx, sp.Integer(len(configs)) if not every else sp.oo, "number", label="N_e")
        dvals = [sp.Matrix([tidy(x.xreplace(dict(zip(q, c)))) for x in defs]) for c in configs] if defs else []
        if defs:
            sol.add("deformations" + sfx, _distinct(dvals), "set", label="\\delta")
        sol.step("equilibria", g=dm.g, q=q, configs=configs, conditions=conditions, every=every,
                 free=[list(dict.fromkeys(x for x in c if x in q)) for c in configs], input=given_u, rhs=rhs,
                 defs=sp.Matrix(defs) if defs else None, dvals=dvals)
        return sol
    Fv = dm.Fv if dm.Fv is not None else sp.zeros(n, n)
    rest = options.steady == "rest"
    v_fix = {d: sp.Integer(0) for d in dq} if rest else given_v
    rows = (dm.c + dm.g + Fv * sp.Matrix(dq)).applyfunc(tidy)
    if rest:
        rows = rows.xreplace(v_fix).applyfunc(tidy)
    motions, conditions, angles, partial = steady_motions(rows, rhs, q, dq, v_fix, unknown,
                                                         [ubar[w] for w in robot.inputs])
    K, rigid, sums = (None, [], []) if rest else _elastic_sums(dm.c, dm.g, Fv, rhs, q, dq)
    an = SteadyAnalysis(rows, rhs, motions, conditions, angles, partial, K, rigid, sums)
    dvals = [sp.Matrix([tidy(x.xreplace(dict(zip(q, m.q)))) for x in defs]) for m in motions] if defs else []
    if rest:
        sol = Solution("equilibria", title=options.title or "Equilibria under a constant input")
        sol.add("equilibria" + sfx, [m.q for m in motions], "set", label="q_e")
        sol.add("n_equilibria" + sfx, sp.Integer(len(motions)), "number", label="N_e")
        sol.add("equilibrium_input" + sfx, _distinct([m.u for m in motions]), "set", label="\\bar u")
    else:
        sol = Solution("equilibria", title=options.title or "Steady motions under a constant input")
        sol.add("steady_state" + sfx, _distinct([m.q for m in motions]), "set", label="\\bar q")
        sol.add("steady_velocity" + sfx, _distinct([m.v for m in motions]), "set", label="\\bar v")
        sol.add("n_steady" + sfx, sp.Integer(len(motions)), "number", label="N_s")
        if unknown:
            sol.add("steady_input" + sfx, _distinct([m.u for m in motions]), "set", label="\\bar u")
    if defs:
        sol.add("deformations" + sfx, _distinct(dvals), "set", label="\\delta")
    sol.step("steady", rest=rest, q=q, dq=dq, rows=an.rows, rhs=an.rhs, input=given_u, unknown=unknown,
             given_v=list(given_v.items()), motions=[dict(q=m.q, v=m.v, u=m.u) for m in motions],
             conditions=conditions, angles=angles, partial=partial, K=K, rigid=rigid, sums=sums,
             defs=sp.Matrix(defs) if defs else None, dvals=dvals, inputs=list(robot.inputs))
    return sol


def _distinct(ms: list[sp.Matrix]) -> list[sp.Matrix]:
    out: list[sp.Matrix] = []
    for m in ms:
        if not any(m == o for o in out):
            out.append(m)
    return out
