"""Equilibria and steady motions under a constant input (ask kind ``equilibria``).

At rest (q̇ = 0) with the constant input ū (default 0) the robot stays at q exactly where g(q) = G ū.
Each angle θ (a coordinate inside sin/cos) is replaced by (c_θ, s_θ) with c_θ² + s_θ² = 1, which turns the
equations into a polynomial system; its solutions (all of them, by Gröbner bases) give θ = atan2(s_θ, c_θ) ∈ (-π, π].
A coordinate left free by a solution is arbitrary there (a continuum of equilibria); square roots in a solution
give the conditions for it to exist. When the angles enter only through r fewer integer combinations (g(q1 + q2)
on a 2R), the system is solved in those sums φ = T θ (T unimodular, the other angles kept and free) and written
back, θ = T⁻¹ φ: q1 = atan2(a, b) − q2 rather than atan2 of radicals in q2, and in a fraction of the time.

Steady motions with constant velocity (``steady: velocity``): q(t) = q̄ + v̄ t, q̈ = 0, in the model
B(q) q̈ + c(q, q̇) + g(q) + F_v q̇ = G u with u ≡ ū. They exist iff

    E(q) = c(q, v̄) + g(q) + F_v v̄ − G ū = 0   for every q = q̄ + v̄ t,

i.e. E must be constant (and zero) along the motion. For coordinates outside sin/cos, q_p → q̄_p + v̄_p t makes E
a polynomial in t whose coefficients must all vanish (for springs: E(q̄) = 0 and K v̄ = 0, the motion does not
deform them). An angle either stays (v̄_θ = 0) or rotates; for each set of rotating angles E must not depend on
them (every coefficient of E as a polynomial in cos θ, sin θ, reduced by sin²θ = 1 − cos²θ, vanishes: exact for
one rotating angle, and for several ones rotating at speeds with irrational ratios). v̄ = 0 gives the equilibria.

The configurations are listed as distinct sets: an angle left free by the solver (cos θ in terms of sin θ on half
a circle) is written as θ in the other values, equal sets (angles modulo 2π) are kept once and, at rest, a point
inside a listed family is dropped. At rest, a row of g(q) − G ū free of q is a condition on the parameters
(F − m g0 = 0), reported with the configurations of the other rows instead of "no solution"; the steady motions
(and solve_for) split off an equation free of their unknowns the same way (:func:`split_conditions`), as a condition
of the motions of that set of rotating angles.
"""
from __future__ import annotations

import cmath
import math
import random
from dataclasses import dataclass, field
from itertools import combinations
from typing import Literal, Optional, Union

import sympy as sp
from pydantic import Field

from solver.dynamics.model import derive, require_model
from solver.math.fourier import ring_reader, ring_trig
from solver.math.numeric import newton_zeros
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
    """The rows in c_θ = cos θ, s_θ = sin θ (sums and multiples of angles expanded as sympy's expand_trig writes
    them), each cleared of denominators and expanded, and c_θ² + s_θ² − 1 for each angle."""
    cs = {a: (sp.Symbol(f"c_{a.name}", real=True), sp.Symbol(f"s_{a.name}", real=True)) for a in angles}
    eqs = _ring_rows(g, cs)
    if eqs is not None:
        return eqs + [c ** 2 + s ** 2 - 1 for c, s in cs.values()], cs
    eqs = []
    for x in g:
        e = sp.expand(sp.expand_trig(sp.expand(x, trig=True)))
        e = e.subs({sp.cos(a): cs[a][0] for a in angles}).subs({sp.sin(a): cs[a][1] for a in angles})
        e = sp.numer(sp.together(e))
        if e != 0:
            eqs.append(sp.expand(e))
    eqs += [c ** 2 + s ** 2 - 1 for c, s in cs.values()]
    return eqs, cs


def _ring_rows(g: list[sp.Expr], cs: dict) -> list[sp.Expr] | None:
    """What :func:`_to_polynomial`'s expansions give for rows that are polynomials over Q in symbols and sin/cos of
    integer combinations of the angles, computed in a sparse ring instead: cos/sin of k·θ as sympy's expand_trig
    writes them (the addition formulas, which multiply out as Π (C_j + i S_j), and cos nθ = T_n(cos θ),
    sin nθ = ±T_n(sin θ) for odd n, ±cos θ U_{n−1}(sin θ) for even n), and numer(together(e)) of a polynomial e is
    e times the least common multiple of its coefficients' denominators. None for anything else."""
    from sympy.polys.domains import QQ
    from sympy.polys.rings import ring
    syms = sorted(set().union(*(x.free_symbols for x in g)) - set(cs), key=lambda s: s.name) if g else []
    flat = [v for pair in cs.values() for v in pair]
    if set(flat) & set(syms):
        return None
    R, *gens = ring(syms + flat, QQ)
    gen = dict(zip(syms + flat, gens))
    angle_cs = {a: (gen[c], gen[s]) for a, (c, s) in cs.items()}

    def trig(f: sp.Expr):  # type: ignore[no-untyped-def]
        c, s = ring_trig(f.args[0], angle_cs)
        return c if isinstance(f, sp.cos) else s

    def leaf(e: sp.Expr):  # type: ignore[no-untyped-def]
        if e.is_Symbol:
            return gen[e]
        if isinstance(e, (sp.sin, sp.cos)):
            return trig(e)
        raise ValueError(e)
    conv = ring_reader(R, leaf)

    out = []
    try:
        for x in g:
            p = conv(sp.sympify(x))
            if p:
                den = 1
                for c in p.itercoeffs():
                    den = sp.ilcm(den, int(c.denominator))
                out.append((p * den).as_expr())
    except (ValueError, KeyError):
        return None
    return out


def equilibria(g: sp.Matrix, q: list[sp.Symbol], clean: bool = False) -> tuple[list[sp.Matrix], list[sp.Expr], bool]:
    """(configurations, conditions, every_configuration) for g(q) = 0 (none when a row free of q is not 0);
    ``clean`` as in :func:`conditional_equilibria`."""
    configs, conditions, every, requires = conditional_equilibria(g, q, clean)
    return ([], [], False) if requires else (configs, conditions, every)


class NotSolved(Exception):
    """sympy's polynomial solver failed on the equations (a Gröbner basis dividing by a coefficient that vanishes
    for the parameters, or a system it does not handle): not an answer, and not the user's fault."""


def solve_polynomials(eqs: list[sp.Expr], unknowns: list[sp.Symbol]) -> list[dict]:
    """sympy's solve of a polynomial system (dict solutions); its internal failures raised as :class:`NotSolved`."""
    try:
        return sp.solve(eqs, unknowns, dict=True)
    except (ZeroDivisionError, NotImplementedError, sp.PolynomialError) as exc:
        raise NotSolved(f"{type(exc).__name__}: {exc}") from None


class Unclean(Exception):
    """A solution of :func:`conditional_equilibria` with ``clean=True`` has an angle that is a root of its
    parameters (atan2 of radicals): the caller wants only numbers and free coordinates."""


def conditional_equilibria(g: sp.Matrix, q: list[sp.Symbol], clean: bool = False
                           ) -> tuple[list[sp.Matrix], list[sp.Expr], bool, list[sp.Expr]]:
    """(configurations, conditions, every_configuration, requirements) for g(q) = 0, distinct as sets (angles
    modulo 2π). A row of g free of q (a constant input against a constant force, m g0 − F) is a requirement r = 0
    on the parameters: the configurations are those of the other rows, and exist iff every r = 0 (none when some r
    is non-zero for every value of the parameters, e.g. m g0 without input). ``clean``: raise :class:`Unclean` at
    the first angle whose cosine or sine is a radical of the parameters, before writing it (atan2 of radicals)."""
    split = split_conditions([tidy(x) for x in g], set(q))
    if split is None:
        return [], [], False, []
    requires, g_list = split
    if all(x == 0 for x in g_list):
        return [sp.Matrix(q)], [], True, requires
    angles = _angles(g_list, q)
    change = angle_sums(g_list, angles)
    if change is not None:
        return (*_in_sums(g_list, q, angles, change, clean), requires)
    eqs, cs = _to_polynomial(g_list, angles)
    unknowns = [v for a in angles for v in cs[a]] + [x for x in q if x not in angles]
    sols = solve_polynomials(eqs, unknowns)
    if not sols and _numeric_root(g_list, q, angles):   # roots exist: sympy missed them (a family of a repeated
        once = [e for k, e in enumerate(eqs) if not any(x in (e, -e) for x in eqs[:k])]   # equation: once each)
        sols = solve_polynomials(once, unknowns) if len(once) < len(eqs) else []
        if not sols:
            raise NotSolved("it found no solution, but g(q) = 0 has roots (found numerically at sample values of "
                            "the parameters)")
    configs, conditions = [], []
    for s in sols:
        vals, raw = [], []   # (raw: the cosines and sines, whose radicands are the conditions also where the
        #                      angle is written without them, acos(x/c))
        free = [x for x in angles if _is_free(s, *cs[x])]
        subs = [_free_angle(s, x, *cs[x]) for x in free]
        for x in q:
            if x in free:
                vals.append(x)  # free angle
            elif x in angles:
                c, sn = s.get(cs[x][0], cs[x][0]), s.get(cs[x][1], cs[x][1])
                c, sn = _in_free_angles(c, subs), _in_free_angles(sn, subs)
                if clean and any(_parametric_root(v, q) for v in (c, sn)):
                    raise Unclean(x)
                raw += [c, sn]
                vals.append(_atan2_angle(tidy(_atan2_reduced(sn, c))) if not (c.is_number and sn.is_number)
                            else sp.atan2(sn, c))
            else:
                vals.append(tidy(_in_free_angles(sp.sympify(s.get(x, x)), subs)))
        if any(v.has(sp.I) for v in vals):
            continue
        conditions += _radicand_conditions(vals + raw)
        configs.append(sp.Matrix(vals))
    configs.sort(key=lambda m: [float(sp.N(x)) if x.is_number else 0.0 for x in m])
    return distinct_configurations(configs, q, set(angles)), list(dict.fromkeys(conditions)), False, requires


def _radicand_conditions(values: list[sp.Expr]) -> list[sp.Expr]:
    """b ≥ 0 for each square root √b in the values whose radicand b is not known to be ≥ 0."""
    return [sp.GreaterThan(p.base, 0) for v in values for p in v.atoms(sp.Pow)
            if p.exp == sp.Rational(1, 2) and not p.base.is_nonnegative]


@dataclass
class AngleSums:
    """New angles φ = T θ (T unimodular: a bijection of the torus) when the rows depend on the angles θ only through
    r ≤ len(θ) independent integer combinations: φ_1..φ_r are those combinations, the others are angles of θ kept
    as they are (free in every solution). With r = len(θ) (the absolute angles q1, q1 + q2, ... of a planar arm)
    every argument is one new angle and the equations decouple."""
    T: sp.Matrix
    sums: list[sp.Symbol]     # φ_1..φ_r (dummies)
    forms: list[sp.Expr]      # their combinations of the angles
    kept: list[sp.Symbol]     # the angles kept as coordinates


def _angle_form(arg: sp.Expr, angles: list[sp.Symbol]) -> Optional[tuple[int, ...]]:
    """The integer k of arg = k·θ + b (b free of the angles), or None."""
    try:
        poly = sp.Poly(arg, *angles)
    except sp.PolynomialError:
        return None
    if poly.total_degree() > 1:
        return None
    k = [poly.coeff_monomial(x) for x in angles]
    if not all(c.is_Integer for c in k) or (poly.coeff_monomial(1).free_symbols & set(angles)):
        return None
    return tuple(int(c) for c in k)


def angle_sums(rows: list[sp.Expr], angles: list[sp.Symbol]) -> Optional[AngleSums]:
    """The change to angle sums (:class:`AngleSums`) when the sin/cos arguments of the rows span fewer than
    len(angles) directions (g = g(q1 + q2) on a 2R: a family along q1 − q2 ... of equilibria), or exactly
    len(angles) directions, one per argument, not all single angles (g of q1 and q1 + q2 on a 2R in a vertical
    plane: cos φ2 = ū2/(m2 d2 g0) alone, then φ1); None otherwise or when the arguments are not integer
    combinations of the angles. The kept angles are the last ones that complete the combinations to a unimodular
    T."""
    if len(angles) < 2:
        return None
    forms: list[tuple[int, ...]] = []
    for r in rows:
        for f in sp.sympify(r).atoms(sp.sin, sp.cos):
            k = _angle_form(f.args[0], angles)
            if k is None:
                return None
            if not any(k):
                continue
            d = math.gcd(*k) * (1 if next(c for c in k if c) > 0 else -1)   # primitive: 2q1 + 2q2 -> q1 + q2
            k = tuple(c // d for c in k)
            if k not in forms:
                forms.append(k)
    forms.sort(key=lambda k: (sum(1 for c in k if c), [-abs(c) for c in k]))   # q1, q1 + q2, q1 + q2 + q3, ...
    basis: list[list[int]] = []
    for k in forms:
        if sp.Matrix(basis + [list(k)]).rank() > len(basis):
            basis.append(list(k))
    n = len(angles)
    if not basis or (len(basis) == n and (len(forms) > n or all(sum(map(abs, k)) == 1 for k in forms))):
        return None   # (as many directions as angles: a change only when each argument becomes one new angle)
    unit = sp.eye(n).tolist()
    rows, kept = list(basis), []
    for j in reversed(range(n)):   # the last angles that complete the rank
        if len(rows) < n and sp.Matrix(rows + [unit[j]]).rank() > len(rows):
            rows.append(unit[j])
            kept.append(j)
    kept.sort()
    T = sp.Matrix(basis + [unit[m] for m in kept])
    if abs(T.det()) != 1:
        return None
    sums = [sp.Dummy(f"phi{i + 1}", real=True) for i in range(len(basis))]
    forms_e = [sum(c * x for c, x in zip(row, angles)) for row in basis]
    return AngleSums(T, sums, forms_e, [angles[m] for m in kept])


def _in_sums(rows: list[sp.Expr], q: list[sp.Symbol], angles: list[sp.Symbol], ch: AngleSums, clean: bool
             ) -> tuple[list[sp.Matrix], list[sp.Expr], bool]:
    """The equilibria of rows(θ) = 0 solved in the angle sums φ = T θ (fewer angles, lower degrees, families as
    φ = const with the kept angles free), then written back as θ = T⁻¹ φ."""
    new = ch.sums + ch.kept
    Tinv = ch.T.inv()
    back = dict(zip(angles, list(Tinv * sp.Matrix(new))))
    g2 = list(dict.fromkeys(tidy(sp.expand(x.xreplace(back))) for x in rows))
    g2 = [x for k, x in enumerate(g2) if -x not in g2[:k]]
    others = [x for x in q if x not in angles]
    configs, conditions, every, _ = conditional_equilibria(sp.Matrix(g2), new + others, clean)
    fwd = dict(zip(ch.sums, ch.forms))
    out = []
    for c in configs:
        vals = dict(zip(new + others, c))
        theta = (Tinv * sp.Matrix([vals[x] for x in new])).xreplace(fwd)
        at = dict(zip(angles, (_principal(tidy(x)) for x in theta)))
        out.append(sp.Matrix([at[x] if x in at else tidy(vals[x].xreplace(fwd)) for x in q]))
    out.sort(key=lambda m: [float(sp.N(x)) if x.is_number else 0.0 for x in m])
    return out, [c.xreplace(fwd) for c in conditions], every


def _principal(a: sp.Expr) -> sp.Expr:
    """A numeric angle in (−π, π] (θ = T⁻¹φ of angles in (−π, π] may leave it: 3π/2, −π); others as they are."""
    if not a.is_number or not a.is_real:
        return a
    turns = sp.ceiling((a - sp.pi) / (2 * sp.pi))
    return a - 2 * sp.pi * turns if turns.is_Integer and turns != 0 else a


def _atan2_reduced(y: sp.Expr, x: sp.Expr) -> sp.Expr:
    """atan2(y, x) with the factors common to y and x that are ≥ 0 wherever they are real (positive numbers, even
    roots) divided out: atan2(k a, k b) = atan2(a, b) for k > 0."""
    fy, fx = list(sp.Mul.make_args(sp.factor_terms(y))), list(sp.Mul.make_args(sp.factor_terms(x)))
    for f in list(fy):
        nonneg = f.is_positive or (f.is_Pow and f.exp.is_Rational and f.exp.q % 2 == 0)
        if nonneg and f in fx:
            fy.remove(f)
            fx.remove(f)
    cy, cx = sp.Mul(*[f for f in fy if f.is_Rational]), sp.Mul(*[f for f in fx if f.is_Rational])
    k = sp.gcd(cy, cx) if cy.is_Rational and cx.is_Rational and cy and cx else 1
    return sp.atan2(sp.Mul(*fy) / abs(k), sp.Mul(*fx) / abs(k))


def _numeric_root(rows: list[sp.Expr], q: list[sp.Symbol], angles: list[sp.Symbol], starts: int = 24) -> bool:
    """Whether the rows vanish together somewhere, found by multi-start Newton (:func:`newton_zeros`; angles from
    (−π, π], other coordinates from (−3, 3)) at a random point of the parameters (:func:`random_point`, positive
    ones positive): the check before saying "no solution" when sympy's solve returned none (it may miss a
    family)."""
    import numpy as np

    from solver.math.equivalence import random_point
    pt = random_point(set().union(*(x.free_symbols for x in rows)) - set(q), random.Random(3))
    gen = np.random.default_rng(3)
    X0 = np.array([[gen.uniform(-np.pi, np.pi) if x in angles else gen.uniform(-3, 3) for x in q]
                   for _ in range(starts)])
    ends, res = newton_zeros([x.xreplace(pt) for x in rows], q, X0)
    return bool(np.any(np.all(np.isfinite(ends), axis=1) & (np.max(np.abs(res), axis=1) < 1e-10)))


def _parametric_root(e: sp.Expr, q: list[sp.Symbol]) -> bool:
    """Whether e has a fractional power of an expression in symbols other than the coordinates (√(l1² − r²))."""
    return any(p.exp.is_Rational and not p.exp.is_Integer and (p.base.free_symbols - set(q))
               for p in e.atoms(sp.Pow))


def split_conditions(rows: list[sp.Expr], unknowns: set[sp.Symbol]
                     ) -> Optional[tuple[list[sp.Expr], list[sp.Expr]]]:
    """(conditions, the other rows): a non-zero row free of the unknowns (a constant input against a constant force,
    m g0 − F) is a condition r = 0 on the parameters, listed once; the rows that are 0 are dropped. None when a
    condition is non-zero for every value of the parameters (m g0 without input): then nothing satisfies the rows."""
    free = [tidy(x) for x in rows if not (x.free_symbols & unknowns)]
    conditions = list(dict.fromkeys(x for x in free if x != 0))
    if any(x.is_zero is False for x in conditions):
        return None
    return conditions, [x for x in rows if x.free_symbols & unknowns]


def _angles(rows: list[sp.Expr], q: list[sp.Symbol]) -> list[sp.Symbol]:
    """The coordinates inside sin/cos of any row (of each row: rows may cancel in a sum), sorted by name."""
    found = set().union(*(angle_symbols(x) for x in rows)) if rows else set()
    return sorted((a for a in found if a in q), key=lambda a: a.name)


def _is_free(s: dict, c: sp.Symbol, sn: sp.Symbol) -> bool:
    """Whether the solution leaves the angle of (cos, sin) = (c, sn) free (one of them in terms of the other)."""
    cv, sv = s.get(c, c), s.get(sn, sn)
    return bool((cv.free_symbols | sv.free_symbols) & {c, sn})


def _free_angle(s: dict, x: sp.Symbol, c: sp.Symbol, sn: sp.Symbol) -> Optional[tuple]:
    """How to write a solution's values in the free angle x instead of its (cos, sin) symbols: the solver keeps
    one of them, say s, and gives c = σ√(1 − s²) (σ = ±1: half a circle): there s = sin x and √(1 − s²) = σ cos x
    (and the same with the roles swapped). Returns (radicand, σ f(x), replacements of the symbols) or None when the
    solution is not of that form."""
    cv, sv = s.get(c, c), s.get(sn, sn)
    if cv == c and sv == sn:
        return (None, None, {c: sp.cos(x), sn: sp.sin(x)})
    for own, other, f_own, f_other in ((sn, c, sp.sin, sp.cos), (c, sn, sp.cos, sp.sin)):
        own_v, other_v = s.get(own, own), s.get(other, other)
        if own_v != own or other_v == other or other_v.free_symbols & {other}:
            continue
        roots = [p for p in other_v.atoms(sp.Pow) if p.exp == sp.Rational(1, 2)]
        if len(roots) != 1 or sp.expand(roots[0].base - (1 - own ** 2)) != 0:
            return None
        sigma = sp.cancel(other_v / roots[0])
        if sigma not in (1, -1):
            return None
        return (roots[0].base, sigma * f_other(x), {own: f_own(x), other: f_other(x)})
    return None


def _in_free_angles(e: sp.Expr, subs: list[Optional[tuple]]) -> sp.Expr:
    """e with the (cos, sin) symbols of the free angles written as cos x, sin x (see :func:`_free_angle`)."""
    for sub in subs:
        if sub is None:
            continue
        base, value, names = sub
        if base is not None:
            e = e.replace(lambda p: p.is_Pow and p.exp.is_Rational and p.exp.q == 2
                          and sp.expand(p.base - base) == 0, lambda p: value ** (2 * p.exp))
        e = e.xreplace(names)
    return e


def _atan2_angle(e: sp.Expr) -> sp.Expr:
    """atan2(±sin a, ±cos a) written as a, π − a, −a, a + π (equal modulo 2π); atan2(±√(c² − x²), x) with c > 0
    as ±acos(x/c) (c² − x² a perfect square difference: an angle whose cosine alone is fixed)."""
    def angle(y: sp.Expr, x: sp.Expr) -> Optional[sp.Expr]:
        sy, ay = (-1, -y) if y.could_extract_minus_sign() else (1, y)
        sx, ax = (-1, -x) if x.could_extract_minus_sign() else (1, x)
        if not (isinstance(ay, sp.sin) and isinstance(ax, sp.cos) and ay.args[0] == ax.args[0]):
            return _acos(sy, ay, x)
        a = ay.args[0]
        return {(1, 1): a, (1, -1): sp.pi - a, (-1, 1): -a, (-1, -1): a + sp.pi}[(sy, sx)]

    return e.replace(lambda f: isinstance(f, sp.atan2) and angle(*f.args) is not None, lambda f: angle(*f.args))


def _acos(sign: int, root: sp.Expr, x: sp.Expr) -> Optional[sp.Expr]:
    """sign·acos(x/c) for atan2(sign·√R, x) when R + x² = c² with c > 0 (by the symbols' assumptions); None
    otherwise (or when R is too large to factor quickly)."""
    if not (root.is_Pow and root.exp == sp.Rational(1, 2)) or sp.count_ops(root.base) > 60 or x.is_number:
        return None
    c = sp.sqrt(sp.factor(sp.expand(root.base + x ** 2)))
    if any(p.exp.is_Rational and p.exp.q == 2 for p in c.atoms(sp.Pow)) or not c.is_positive:
        return None   # (not a perfect square, or of unknown sign)
    arg = tidy(x / c)
    if arg.could_extract_minus_sign():   # acos(−z) = π − acos z (printed without a sign inside the function)
        return sign * (sp.pi - sp.acos(-arg))
    return sign * sp.acos(arg)


def _same_value(a: sp.Expr, b: sp.Expr, periodic: bool) -> bool:
    """a ≡ b (exactly; modulo 2π with equal cosine and sine when ``periodic``); undecided counts as different."""
    from solver.math.equivalence import identically_zero
    a, b = sp.sympify(a), sp.sympify(b)
    if a == b:
        return True
    if a.is_number and b.is_number:   # a quick numeric rejection before the exact test
        d = complex(sp.N(a - b, 30))
        if abs(d.imag) > 1e-20:
            return False
        k = d.real / (2 * float(sp.pi)) if periodic else d.real
        if abs((k - round(k)) if periodic else k) > 1e-12:
            return False
    elif _differ_at_a_point(a, b, periodic):   # the exact test of two parametric roots takes seconds
        return False
    try:
        if not periodic:
            return identically_zero(a - b)
        return identically_zero(sp.cos(a) - sp.cos(b)) and identically_zero(sp.sin(a) - sp.sin(b))
    except (TypeError, ValueError, sp.PolynomialError):
        return False


def _differ_at_a_point(a: sp.Expr, b: sp.Expr, periodic: bool) -> bool:
    """a ≢ b proved by their real values (30 digits) at one of four random points of their symbols
    (:func:`random_point`, :func:`real_value`: a positive symbol positive); False when no point gives two finite real
    values (roots out of their domain, where branch cuts may part two equal real roots), or when they agree."""
    from solver.math.equivalence import random_point, real_value
    rng = random.Random(5)
    for _ in range(4):
        pt = random_point(a.free_symbols | b.free_symbols, rng)
        da, db = real_value(a, pt), real_value(b, pt)
        if da is None or db is None:
            continue
        if periodic:
            d = abs(cmath.cos(da) - cmath.cos(db)) + abs(cmath.sin(da) - cmath.sin(db))
        else:
            d = abs(da - db)
        if d > 1e-12 * (1 + abs(da) + abs(db)):
            return True
    return False


def _contained(a: sp.Matrix, b: sp.Matrix, q: list[sp.Symbol], periodic: set[sp.Symbol]) -> bool:
    """Every configuration of the family a is one of the family b (a coordinate written as itself is free): b's
    free coordinates take a's values there, and then every entry must agree (angles modulo 2π)."""
    free_b = {x: a[i] for i, x in enumerate(q) if b[i] == x}
    if any((v.free_symbols & set(q)) - set(free_b) for v in b):
        return all(_same_value(x, y, q[i] in periodic) for i, (x, y) in enumerate(zip(a, b)))
    return all(_same_value(x, y.xreplace(free_b), q[i] in periodic) for i, (x, y) in enumerate(zip(a, b)))


def same_configurations(a: sp.Matrix, b: sp.Matrix, q: list[sp.Symbol], periodic: set[sp.Symbol]) -> bool:
    """Whether two configurations or families of configurations are the same set (the angles in ``periodic``
    modulo 2π): [q1, q1 + π] and [q2 − π, q2] are."""
    if a.shape != b.shape:
        return False
    if a == b:
        return True
    return _contained(a, b, q, periodic) and _contained(b, a, q, periodic)


def distinct_configurations(configs: list[sp.Matrix], q: list[sp.Symbol], periodic: set[sp.Symbol]
                            ) -> list[sp.Matrix]:
    """The configurations (or families) without repetitions as sets, the first of equal ones kept, and without the
    ones inside a family also listed (the points [π/2, π/2] of the family [q2, q2])."""
    out: list[sp.Matrix] = []
    for c in configs:
        if not any(same_configurations(c, o, q, periodic) for o in out):
            out.append(c)
    families = [o for o in out if any(o[i] == x for i, x in enumerate(q))]
    return [c for c in out if not any(o is not c and _contained(c, o, q, periodic) for o in families)]


@dataclass
class SteadyMotion:
    """q(t) = q + v t under the constant input u (an entry of q or v left as its own symbol is arbitrary)."""

    q: sp.Matrix
    v: sp.Matrix
    u: sp.Matrix
    requires: list[sp.Expr] = field(default_factory=list)   # conditions r = 0 on the parameters for it to exist


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
    angles = _angles(E, q)
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
    names = list(q) + list(dq) + [w if w in unknown_u else sp.Dummy() for w in u]   # a slot equal to its name is free

    def keep(rotating: list, su: dict, requires: list, qs: list, vs: list, trig: dict, raw: list,
             radicals: bool) -> None:
        """The motion (q̄, v̄) with its inputs listed, unless an angle counted as rotating is at rest in it or a
        value is complex; with ``radicals``, the radicands of its values (and of the cosines and sines ``raw``)
        as conditions."""
        if any(vs[q.index(a)] == 0 for a in rotating):
            return  # found with that angle at rest
        at = {x: v for x, v in zip(q, qs) if x not in trig and x != v} | {d: v for d, v in zip(dq, vs)}
        us = [tidy(sp.expand_trig(sp.expand(su.get(w, w), trig=True)).subs(trig).subs(at))
              if w in unknown_u else sp.sympify(w) for w in u]
        if any(x.has(sp.I) for x in qs + vs + us + raw):
            return
        if radicals:
            conditions.extend(_radicand_conditions(qs + vs + us + raw))
        _add_motion(motions, SteadyMotion(sp.Matrix(qs), sp.Matrix(vs), sp.Matrix(us), requires), names, angles)

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
        split = split_conditions(eqs, set(q) | set(unknown_u) | {d for d in dq if d not in given_v and d not in stay})
        if split is None:
            continue  # an equation of the parameters alone that cannot hold (m g0 l = 0 for a rotating angle)
        requires, eqs = split
        still = [a for a in angles if a not in rotating and any(a in x.free_symbols for x in eqs)]
        free_v = [d for x, d in zip(q, dq) if d not in given_v and d not in stay]
        summed = _in_angle_sums(eqs, still, others + free_v) if len(still) > 1 else None
        if summed is not None:   # (the angles enter only through integer combinations: solved in them, with
            values, conds = summed   # their conditions)
            conditions += conds
            for val in values:
                vs = [tidy(sp.sympify(val.get(d, vel[x].xreplace(stay)))) for x, d in zip(q, dq)]
                keep(rotating, su, requires, [val.get(x, x) for x in q], vs, {}, [], radicals=False)
            continue
        poly, cs2 = _to_polynomial(eqs, still)
        unknowns = ([x for a in still for x in cs2[a]] + others
                    + [d for x, d in zip(q, dq) if d not in given_v and d not in stay])
        present = set().union(*(x.free_symbols for x in poly)) if poly else set()
        unknowns = [x for x in unknowns if x in present]  # sympy's solve can miss solutions given absent unknowns
        if any(not (x.free_symbols & set(unknowns)) for x in poly):
            continue  # an equation of the parameters alone (generic parameters: it does not hold)
        sols = solve_polynomials(poly, unknowns) if poly else [{}]
        named = _branches(sols, still, cs2)
        for k, s in enumerate(sols):
            qs, trig, raw = [], {}, []
            free = [x for x in still if _is_free(s, *cs2[x])]
            subs = [_free_angle(s, x, *cs2[x]) for x in free]
            for x in q:
                if x in still:
                    c, sn = s.get(cs2[x][0], cs2[x][0]), s.get(cs2[x][1], cs2[x][1])
                    if x in free:
                        qs.append(x)
                    else:
                        c, sn = _in_free_angles(c, subs), _in_free_angles(sn, subs)
                        qs.append(named.get((k, x)) or (_atan2_angle(tidy(sp.atan2(sn, c)))
                                                        if not (c.is_number and sn.is_number) else sp.atan2(sn, c)))
                        raw += [c, sn]
                        th = named.get((k, x))   # with its own cosine and sine (the branch the name says)
                        trig |= {sp.cos(x): sp.cos(th), sp.sin(x): sp.sin(th)} if th is not None else \
                            {sp.cos(x): c, sp.sin(x): sn}
                else:
                    qs.append(tidy(_in_free_angles(sp.sympify(s.get(x, x)), subs)))
            vs = [tidy(_in_free_angles(sp.sympify(s.get(d, vel[x].xreplace(stay))), subs)) for x, d in zip(q, dq)]
            keep(rotating, su, requires, qs, vs, trig, raw, radicals=True)
    motions.sort(key=lambda m: [float(sp.N(x)) if x.is_number else 0.0 for x in list(m.v) + list(m.q)])
    return motions, list(dict.fromkeys(conditions)), angles, partial


def _add_motion(motions: list[SteadyMotion], m: SteadyMotion, names: list, angles: list[sp.Symbol]) -> None:
    """m appended unless the same motion is listed (angles modulo 2π); a twin found also without conditions
    loses its conditions."""
    twin = next((o for o in motions if same_configurations(_stacked(m), _stacked(o), names, set(angles))), None)
    if twin is None:
        motions.append(m)
    elif not m.requires:
        twin.requires = []   # also found without conditions


def _in_angle_sums(eqs: list[sp.Expr], still: list[sp.Symbol], unknowns: list[sp.Symbol]
                   ) -> Optional[tuple[list[dict], list[sp.Expr]]]:
    """The solutions of eqs = 0 for the angles ``still`` and the other ``unknowns`` when the angles enter only
    through integer combinations that :func:`angle_sums` changes to (fewer than the angles: the others free; as
    many, one per argument: decoupled), solved by :func:`conditional_equilibria` in those combinations.
    ([{unknown: value}], an unknown mapped to itself being arbitrary, conditions), or None to solve as before (no
    such change, every value a solution, a condition on the parameters, or sympy failing)."""
    if angle_sums(eqs, still) is None:
        return None
    present = set().union(*(e.free_symbols for e in eqs))
    xs = still + [x for x in unknowns if x in present]
    try:
        configs, conditions, every, requires = conditional_equilibria(sp.Matrix(eqs), xs)
    except NotSolved:
        return None
    if every or requires:
        return None
    return [dict(zip(xs, c)) for c in configs], conditions


def _stacked(m: SteadyMotion) -> sp.Matrix:
    return sp.Matrix.vstack(m.q, m.v, m.u)


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
    sol = solve_polynomials(chosen, unknown_u) if chosen else [{}]
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


def _deformations(options: EquilibriaAsk, ctx) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    return [sp.sympify(x) for x in ctx.expr("deformations")] if options.deformations else []


def validate_equilibria(problem, options: EquilibriaAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_equilibria` reads them (inputs, velocity,
    deformations), without deriving the model."""
    robot = require_model(problem)
    _read_inputs(problem, options, ctx, robot)
    _read_velocity(problem, options, ctx, robot)
    _deformations(options, ctx)


@ask_kind("equilibria", EquilibriaAsk,
          "equilibria g(q) = G ū (u = 0 by default) and steady motions with constant velocity under a constant input",
          validate=validate_equilibria)
def solve_equilibria(problem, options: EquilibriaAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the suffix): at rest equilibria (set of configurations), n_equilibria (and equilibrium_input
    with solve_for); with steady: velocity steady_state (set of q̄), steady_velocity (set of v̄), n_steady (and
    steady_input with solve_for); deformations (set of the given expressions at each steady state)."""
    try:
        return _solve_equilibria(problem, options, ctx)
    except NotSolved as exc:
        raise UserError("the equilibrium equations are not solved in closed form: sympy's polynomial solver fails on "
                        f"them ({str(exc)[:80]})", problem.located.place(ctx.path),
                        "give the parameters numeric values in the model, or fewer symbolic parameters") from None


def _solve_equilibria(problem, options: EquilibriaAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    robot = require_model(problem)
    dm = derive(robot)
    n, q, dq = robot.n, list(robot.q), list(robot.dq)
    ubar, unknown = _read_inputs(problem, options, ctx, robot)
    given_v = _read_velocity(problem, options, ctx, robot)
    G = dm.G if dm.G is not None else sp.eye(n)
    rhs = (G * sp.Matrix([ubar[w] for w in robot.inputs])).applyfunc(tidy)
    given_u = [(w, ubar[w]) for w in robot.inputs if w not in unknown]   # shown unless every input is 0
    given_u = given_u if unknown or any(v != 0 for _, v in given_u) else []
    defs = _deformations(options, ctx)
    sfx = options.suffix
    if options.steady == "rest" and not unknown:
        configs, conditions, every, requires = conditional_equilibria((dm.g - rhs).applyfunc(tidy), q)
        sol = Solution("equilibria", title=options.title or "Equilibrium configurations")
        sol.add("equilibria" + sfx, configs, "set", label="q_e")
        sol.add("n_equilibria" + sfx, sp.Integer(len(configs)) if not every else sp.oo, "number", label="N_e")
        if requires:
            sol.add("equilibrium_conditions" + sfx, sp.Matrix(requires), "vector",
                    label="\\text{conditions } (=0)")
        dvals = [sp.Matrix([tidy(x.xreplace(dict(zip(q, c)))) for x in defs]) for c in configs] if defs else []
        if defs:
            sol.add("deformations" + sfx, _distinct(dvals), "set", label="\\delta")
        moving = [x for x in (dm.g - rhs).applyfunc(tidy) if x.free_symbols & set(q)]
        ch = angle_sums(moving, _angles(moving, q)) if configs and not every else None
        sums = {"sums": ch.forms, "kept": ch.kept} if ch else {}
        sol.step("equilibria", g=dm.g, q=q, configs=configs, conditions=conditions, every=every, **sums,
                 free=[list(dict.fromkeys(x for x in c if x in q)) for c in configs], input=given_u, rhs=rhs,
                 defs=sp.Matrix(defs) if defs else None, dvals=dvals, **({"requires": requires} if requires else {}))
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
    requires = list(dict.fromkeys(r for m in motions for r in m.requires))
    if requires:
        sol.add("equilibrium_conditions" + sfx, sp.Matrix(requires), "vector", label="\\text{conditions } (=0)")
    if defs:
        sol.add("deformations" + sfx, _distinct(dvals), "set", label="\\delta")
    shared = all(m.requires == requires for m in motions)
    sol.step("steady", rest=rest, q=q, dq=dq, rows=an.rows, rhs=an.rhs, input=given_u, unknown=unknown,
             given_v=list(given_v.items()),
             motions=[dict(q=m.q, v=m.v, u=m.u, **({"requires": m.requires} if m.requires and not shared else {}))
                      for m in motions],
             conditions=conditions, angles=angles, partial=partial, K=K, rigid=rigid, sums=sums,
             defs=sp.Matrix(defs) if defs else None, dvals=dvals, inputs=list(robot.inputs),
             **({"requires": requires} if requires and shared else {}))
    return sol


def _distinct(ms: list[sp.Matrix]) -> list[sp.Matrix]:
    out: list[sp.Matrix] = []
    for m in ms:
        if not any(m == o for o in out):
            out.append(m)
    return out
