"""Closed-form solution of small systems of trigonometric equations by elimination: inverse kinematics of planar
(and similar) arms, and the configurations where a Jacobian loses rank.

The equations e_k(x) = 0 are polynomial in sin/cos of the revolute unknowns and in the prismatic ones, with
coefficients in known symbols. The unknowns are found one at a time, the way a teacher does:

- ``linear``: an equation a·x + b = 0 in one unknown x (a prismatic variable, or an angle entering linearly):
  x = -b/a;
- ``pair``: two equations linear in (cos x, sin x) of one angle x: the 2×2 linear system gives (cos x, sin x) up
  to a positive factor, x = atan2(sin x, cos x) (one solution);
- ``trig``: one equation A cos x + B sin x + D = 0: x = atan2(B, A) ± atan2(√(A² + B² - D²), -D) (cos x = c alone:
  x = atan2(±√(1 - c²), c)); a general polynomial P(cos x) + sin x·Q(cos x) = 0 through the roots of
  P² - (1 - cos²x) Q² in cos x;
- ``quadratic``: a x² + b x + c = 0 in one prismatic unknown;
- ``substitute``: an equation linear in x with a numeric coefficient (φ = q1 + q2 + q3) eliminates x from the
  others (x = φ - q1 - q2, back-substituted at the end);
- ``squares``: when no equation has a single unknown, the sum of squares of two or three equations u_i(x) = k_i
  (the parts with and without unknowns) often loses an unknown: ‖p‖² of a planar 2R is l1² + l2² + 2 l1 l2 cos q2;
- ``factor``: an equation that factors is split into one branch per factor.

An unknown solved with a short value (a number, π/2, φ - q1) is substituted in the remaining equations; a long one
(an atan2) is kept as a symbol there, so that each step is written with the earlier unknowns (q1 = atan2(l py -
q2 px, l px + q2 py)) and the final values are back-substituted. Every family of solutions is then checked
numerically (the equations must vanish at sample points where its values are real): spurious branches are dropped,
and the work is bounded (number of branches, equation size).
"""
from __future__ import annotations

import cmath
import itertools
import random
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Callable, Iterable, Sequence

import sympy as sp

from solver.math.fourier import factor_list_fast, ring_reader, ring_trig
from solver.math.simplify import factor_within, tidy

MAX_FAMILIES = 32
MAX_OPS = 400  # equations larger than this are not eliminated symbolically
MAX_NODES = 120  # elimination steps explored per system


@dataclass
class Stage:
    """One elimination step: ``unknown`` from ``equations`` (each = 0) by ``method``; ``values`` are in terms of the
    known symbols and of the unknowns found before (``substitute``: of the unknowns still to be found)."""

    unknown: sp.Symbol | None
    method: str
    equations: list[sp.Expr]
    values: list[sp.Expr] = field(default_factory=list)
    data: dict[str, Any] = field(default_factory=dict)


@dataclass
class Family:
    """One family of solutions: ``values`` of every unknown in terms of the known symbols (a free unknown maps to
    itself), the elimination ``stages`` that gave them, and equations left ``pending`` (not solved in closed form)."""

    values: dict[sp.Symbol, sp.Expr]
    stages: list[Stage]
    free: list[sp.Symbol] = field(default_factory=list)
    pending: list[sp.Expr] = field(default_factory=list)
    verified: bool | None = None


@dataclass
class _Node:
    eqs: list[sp.Expr]
    left: list[sp.Symbol]
    sol: dict[sp.Symbol, sp.Expr]
    stages: list[Stage]
    derived: set[sp.Expr] = field(default_factory=set)


class Solver:
    """Elimination over ``unknowns`` (``prismatic`` ones enter polynomially, the others through sin/cos)."""

    def __init__(self, unknowns: Sequence[sp.Symbol], prismatic: Iterable[sp.Symbol] = (),
                 max_families: int = MAX_FAMILIES) -> None:
        self.unknowns = list(unknowns)
        self.prismatic = set(prismatic)
        self.max_families = max_families
        self.order = {x: i for i, x in enumerate(self.unknowns)}

    # ------------------------------------------------------------------ helpers
    def unk(self, e: sp.Expr, left: Sequence[sp.Symbol]) -> list[sp.Symbol]:
        fs = e.free_symbols
        return [x for x in left if x in fs]

    @staticmethod
    def clean(e: sp.Expr) -> sp.Expr:
        """An equation in canonical form, numeric factors and common known factors dropped when cheap."""
        e = sp.sympify(e)
        if e.atoms(sp.atan2, sp.Abs) or any(p.exp.is_Rational and not p.exp.is_Integer for p in e.atoms(sp.Pow)) \
                or sp.count_ops(e) > MAX_OPS or not _canonical_trig(e):
            e = sp.expand(e)
        else:
            e = tidy(e)
        if e.is_Mul:
            coeff, rest = e.as_coeff_Mul()
            if coeff != 0 and rest.free_symbols:
                e = rest
        return e

    # ------------------------------------------------------------------ the search
    def solve(self, equations: Sequence[sp.Expr]) -> list[Family]:
        eqs = [self.clean(e) for e in equations]
        eqs = [e for e in eqs if e != 0]
        out: list[Family] = []
        self.nodes = 0
        self._search(_Node(eqs, list(self.unknowns), {}, []), out)
        return out

    def _search(self, node: _Node, out: list[Family]) -> None:
        self.nodes += 1
        if len(out) >= self.max_families or self.nodes > MAX_NODES:
            out.append(self._family(node, list(node.eqs)))  # out of budget: left implicit
            return
        eqs = []
        for e in node.eqs:
            if e == 0:
                continue
            if not self.unk(e, node.left):
                if e.is_number and e != 0:
                    return  # inconsistent branch (a non-zero constant must vanish)
                continue  # a condition on the known symbols only: left to the numeric check
            eqs.append(e)
        node.eqs = eqs
        if not eqs or not node.left:
            out.append(self._family(node, []))
            return
        for step in (self._linear, self._pair, self._single, self._substitute, self._factor, self._squares,
                     self._underdetermined):
            children = step(node)
            if children is not None:
                for child in children:
                    self._search(child, out)
                return
        out.append(self._family(node, eqs))  # stuck: the rest stays implicit

    def _assign(self, node: _Node, x: sp.Symbol, value: sp.Expr, stage: Stage, used: list[sp.Expr]) -> _Node:
        """A child node with x = value: substituted in the other equations when short, else x stays a symbol."""
        sol = dict(node.sol)
        sol[x] = value
        left = [y for y in node.left if y != x]
        rest = [e for e in node.eqs if not any(e is u for u in used)]
        if _short(value):
            rest = [self.clean(e.subs(x, value)) for e in rest]
        else:
            rest = [e for e in rest]  # x stays: later equations in x are consistency conditions (checked)
            rest = [e for e in rest if not (set(self.unk(e, left)) == set() and x in e.free_symbols)]
        return _Node(rest, left, sol, node.stages + [stage], set(node.derived))

    # ------------------------------------------------------------------ steps
    def _linear(self, node: _Node) -> list[_Node] | None:
        for e in node.eqs:
            u = self.unk(e, node.left)
            if len(u) != 1:
                continue
            x = u[0]
            p = _poly_in(e, x)
            if p is None or p.degree() != 1:
                continue
            a, b = p.all_coeffs()
            if a.is_number and a == 0:
                continue
            v = _simple(-b / a)
            return [self._assign(node, x, v, Stage(x, "linear", [e], [v]), [e])]
        return None

    def _pair(self, node: _Node) -> list[_Node] | None:
        by_x: dict[sp.Symbol, list[tuple[sp.Expr, tuple]]] = {}
        for e in node.eqs:
            u = self.unk(e, node.left)
            if len(u) != 1 or u[0] in self.prismatic:
                continue
            lin = _cs_linear(e, u[0])
            if lin is not None:
                by_x.setdefault(u[0], []).append((e, lin))
        for x in sorted(by_x, key=lambda s: self.order[s]):
            for (e1, (a1, b1, d1)), (e2, (a2, b2, d2)) in itertools.combinations(by_x[x], 2):
                det = tidy(sp.expand(a1 * b2 - a2 * b1))
                if det == 0:
                    continue
                cn = tidy(sp.expand(-d1 * b2 + d2 * b1))
                sn = tidy(sp.expand(-a1 * d2 + a2 * d1))
                sign = _sign(det)
                if sign > 0:
                    v = sp.atan2(sn, cn)
                elif sign < 0:
                    v = sp.atan2(-sn, -cn)
                else:
                    v = sp.atan2(sn / det, cn / det)
                v = _simple(v)
                st = Stage(x, "pair", [e1, e2], [v], {"matrix": sp.Matrix([[a1, b1], [a2, b2]]),
                                                      "rhs": sp.Matrix([-d1, -d2]), "det": det, "cos": cn,
                                                      "sin": sn, "sign": sign})
                return [self._assign(node, x, v, st, [e1, e2])]
        return None

    def _single(self, node: _Node) -> list[_Node] | None:
        best = None
        for e in node.eqs:
            u = self.unk(e, node.left)
            if len(u) != 1:
                continue
            x = u[0]
            res = self.solve_single(e, x)
            if res is None:
                continue
            values, data = res
            key = (len(values), self.order[x])
            if best is None or key < best[0]:
                best = (key, e, x, values, data)
        if best is None:
            return None
        _, e, x, values, data = best
        st = Stage(x, data.pop("method"), [e], values, data)
        if not values:
            return []  # no solution: the branch ends
        return [self._assign(node, x, v, st, [e]) for v in values]

    def solve_single(self, e: sp.Expr, x: sp.Symbol) -> tuple[list[sp.Expr], dict] | None:
        """All solutions of e(x) = 0 in closed form, or None."""
        if x in self.prismatic or not _in_trig(e, x):
            p = _poly_in(e, x)
            if p is None:
                return None
            roots = _poly_roots(p)
            if roots is None:
                return None
            return roots, {"method": "quadratic" if p.degree() == 2 else "polynomial"}
        C, S = sp.Dummy("c"), sp.Dummy("s")
        poly = _cs_poly(e, x, C, S)
        if poly is None:
            return None
        try:
            linear = sp.Poly(poly, C, S).total_degree() <= 1
        except sp.PolynomialError:
            return None
        factors = [f for f, _ in sp.factor_list(poly)[1]] if poly.free_symbols and not linear else [poly]
        factors = [f for f in factors if f.has(C) or f.has(S)] or [poly]
        values: list[sp.Expr] = []
        data: dict[str, Any] = {"method": "trig"}
        for f in factors:
            res = _solve_cs(sp.expand(f), C, S)
            if res is None:
                return None
            vals, info = res
            if len(factors) == 1:
                data.update(info)
            values += vals
        return _dedupe(values), data

    def _substitute(self, node: _Node) -> list[_Node] | None:
        for e in node.eqs:
            u = self.unk(e, node.left)
            if len(u) < 2:
                continue
            for x in sorted(u, key=lambda s: -self.order[s]):
                if _in_trig(e, x):
                    continue
                p = _poly_in(e, x)
                if p is None or p.degree() != 1:
                    continue
                a, b = p.all_coeffs()
                if not a.is_number or a == 0:
                    continue
                v = sp.expand(-b / a)
                sol = dict(node.sol)
                sol[x] = v
                left = [y for y in node.left if y != x]
                rest = [self.clean(f.subs(x, v)) for f in node.eqs if f is not e]
                st = Stage(x, "substitute", [e], [v])
                return [_Node(rest, left, sol, node.stages + [st], set(node.derived))]
        return None

    def _factor(self, node: _Node) -> list[_Node] | None:
        for e in node.eqs:
            if e in node.derived or sp.count_ops(e) > MAX_OPS:
                continue
            fac = trig_factors(e)
            parts = [f for f, _ in fac[1] if self.unk(f, node.left)]
            if len(parts) < 2:
                continue
            children = []
            for f in parts:
                rest = [f if g is e else g for g in node.eqs]
                st = Stage(None, "factor", [e], [], {"factor": f})
                children.append(_Node(rest, list(node.left), dict(node.sol), node.stages + [st], set(node.derived)))
            return children
        return None

    def _squares(self, node: _Node) -> list[_Node] | None:
        base = [e for e in node.eqs if e not in node.derived and sp.count_ops(e) <= MAX_OPS]
        best = None
        for size in (2, 3):
            for group in itertools.combinations(base, size):
                us = set().union(*[set(self.unk(e, node.left)) for e in group])
                if len(us) < 2:
                    continue
                parts = [_split(e, node.left) for e in group]
                new = self.clean(sp.expand(tidy(sp.expand(sum(u**2 for u, _ in parts))) - sum(k**2 for _, k in parts)))
                nu = set(self.unk(new, node.left))
                if not nu or not nu < us or new == 0 or new in node.eqs or -new in node.eqs:
                    continue  # (an equation derived before: squaring the same group again loops)
                key = (len(nu), size)
                if best is None or key < best[0]:
                    best = (key, group, new)
            if best is not None:
                break
        if best is None:
            return None
        _, group, new = best
        st = Stage(None, "squares", list(group), [], {"derived": new})
        derived = set(node.derived) | {new}
        return [_Node(node.eqs + [new], list(node.left), dict(node.sol), node.stages + [st], derived)]

    def _underdetermined(self, node: _Node) -> list[_Node] | None:
        """An equation in several unknowns solved for one of them, the others left free (a singular surface
        a2 c2 + a3 c23 + d4 s23 = 0 gives q2 as a function of q3)."""
        for e in node.eqs:
            u = self.unk(e, node.left)
            if len(u) < 2 or len(node.eqs) >= len(node.left):
                continue
            for x in u:
                res = self.solve_single(e, x)
                if res is None or not res[0]:
                    continue
                values, data = res
                st = Stage(x, data.pop("method"), [e], values, data)
                return [self._assign(node, x, v, st, [e]) for v in values]
        return None

    # ------------------------------------------------------------------ results
    def _family(self, node: _Node, pending: list[sp.Expr]) -> Family:
        free = [x for x in self.unknowns if x not in node.sol]
        final: dict[sp.Symbol, sp.Expr] = {}

        def resolve(x: sp.Symbol, depth: int = 0) -> sp.Expr:
            if x in final:
                return final[x]
            if x not in node.sol or depth > len(self.unknowns) + 2:
                return x
            v = node.sol[x]
            deps = [y for y in v.free_symbols if y in node.sol or y in self.order]
            v = v.subs({y: resolve(y, depth + 1) for y in deps if y != x}) if deps else v
            final[x] = _simple(v)
            return final[x]

        values = {x: resolve(x) for x in self.unknowns}
        return Family(values, node.stages, free, pending)


# ------------------------------------------------------------------------------------------------ algebra
def _canonical_trig(e: sp.Expr) -> bool:
    """Every sin/cos argument is an integer combination of symbols plus a multiple of π/2 (tidy's fast form)."""
    for f in e.atoms(sp.sin, sp.cos):
        for t, c in f.args[0].as_coefficients_dict().items():
            if t is sp.pi:
                if not (2 * c).is_Integer:
                    return False
            elif not (t.is_Symbol and c.is_Integer):
                return False
    return True


def freeze_constants(eqs: Sequence[sp.Expr]) -> tuple[list[sp.Expr], dict[sp.Symbol, sp.Expr]]:
    """sin/cos of numbers that are not multiples of π/2 (cos(1/2)) replaced by symbols, so that the elimination
    stays in exact, fast algebra; returns the equations and {symbol: value}."""
    back: dict[sp.Symbol, sp.Expr] = {}
    rep: dict[sp.Expr, sp.Symbol] = {}
    for e in eqs:
        for f in e.atoms(sp.sin, sp.cos):
            if not f.free_symbols and not _canonical_trig(f) and f not in rep:
                d = sp.Dummy(f"k{len(rep)}", real=True)
                rep[f], back[d] = d, f
    return [e.xreplace(rep) for e in eqs], back


def _short(v: sp.Expr) -> bool:
    """Values substituted into the remaining equations (else kept as a symbol there)."""
    if v.is_number and not v.atoms(sp.Float):
        return not v.atoms(sp.atan2) or sp.count_ops(v) <= 6
    return sp.count_ops(v) <= 6 and not v.atoms(sp.atan2, sp.Pow) or v.is_Symbol


def _simple(v: sp.Expr) -> sp.Expr:
    """Exact numbers simplified (atan2(1, 1) -> π/4), floats rounded; symbolic values left as they are."""
    if v.is_number:
        if v.atoms(sp.Float):
            z = complex(sp.N(v))
            return sp.Float(z.real, 15) if abs(z.imag) < 1e-12 else v
        return _simple_exact(v)
    return v


@lru_cache(maxsize=4096)
def _simple_exact(v: sp.Expr) -> sp.Expr:
    """:func:`_simple` of an exact number, memoized (the same angles recur in every family and ask)."""
    try:
        v2 = sp.nsimplify(sp.simplify(v), [sp.pi]) if sp.count_ops(v) <= 40 else v
        return v2 if sp.count_ops(v2) <= sp.count_ops(v) and abs(complex(sp.N(v2 - v))) < 1e-12 else v
    except Exception:  # pragma: no cover - sympy internals
        return v


def _poly_in(e: sp.Expr, x: sp.Symbol) -> sp.Poly | None:
    try:
        p = sp.Poly(sp.expand(e), x)
    except sp.PolynomialError:
        return None
    if any(c.has(x) for c in p.all_coeffs()):
        return None
    return p


def _in_trig(e: sp.Expr, x: sp.Symbol) -> bool:
    return any(x in f.args[0].free_symbols for f in e.atoms(sp.sin, sp.cos, sp.tan))


def _sign(d: sp.Expr) -> int:
    """+1 / -1 when d keeps a sign at random points (it vanishes at most on a singular set), else 0."""
    if d.is_positive:
        return 1
    if d.is_negative:
        return -1
    rng = random.Random(11)
    signs = set()
    syms = sorted(d.free_symbols, key=lambda s: s.name)
    for _ in range(24):
        pt = {s: (rng.uniform(0.2, 3.0) if (s.is_positive or s.is_nonnegative) else rng.uniform(-3.0, 3.0))
              for s in syms}
        try:
            v = complex(sp.N(d.subs(pt)))
        except (TypeError, ValueError):
            return 0
        if abs(v.imag) > 1e-9:
            return 0
        if abs(v.real) > 1e-12:
            signs.add(v.real > 0)
    if signs == {True}:
        return 1
    if signs == {False}:
        return -1
    return 0


def _cs_poly(e: sp.Expr, x: sp.Symbol, C: sp.Symbol, S: sp.Symbol) -> sp.Expr | None:
    """e as a polynomial in C = cos x, S = sin x (other symbols as coefficients), or None."""
    bad = False

    def rep(f: sp.Expr) -> sp.Expr:
        nonlocal bad
        arg = f.args[0]
        if x not in arg.free_symbols:
            return f
        k = sp.expand(arg).coeff(x)
        rest = sp.expand(arg - k * x)
        if not k.is_Integer or rest.has(x) or abs(int(k)) > 6:
            bad = True
            return f
        y = sp.Dummy("y")
        ck = sp.expand(sp.expand_trig(sp.cos(int(k) * y))).subs({sp.cos(y): C, sp.sin(y): S})
        sk = sp.expand(sp.expand_trig(sp.sin(int(k) * y))).subs({sp.cos(y): C, sp.sin(y): S})
        if isinstance(f, sp.cos):
            return ck * sp.cos(rest) - sk * sp.sin(rest)
        if isinstance(f, sp.sin):
            return sk * sp.cos(rest) + ck * sp.sin(rest)
        bad = True
        return f

    out = e.replace(lambda f: isinstance(f, (sp.sin, sp.cos, sp.tan)) and x in f.free_symbols, rep)
    if bad:
        return None
    out = sp.expand(out)
    if out.has(x):
        return None
    return out


def _cs_linear(e: sp.Expr, x: sp.Symbol) -> tuple[sp.Expr, sp.Expr, sp.Expr] | None:
    """(A, B, D) with e = A cos x + B sin x + D, or None."""
    C, S = sp.Dummy("c"), sp.Dummy("s")
    p = _cs_poly(e, x, C, S)
    if p is None:
        return None
    try:
        P = sp.Poly(p, C, S)
    except sp.PolynomialError:
        return None
    if P.total_degree() > 1:
        return None
    A, B, D = P.coeff_monomial(C), P.coeff_monomial(S), P.coeff_monomial(1)
    if A == 0 and B == 0:
        return None
    return tidy(A), tidy(B), tidy(D)


def _root(e: sp.Expr) -> sp.Expr:
    """√e with the radicand tidied (and perfect squares recognized)."""
    e = tidy(sp.expand(e))
    return sp.sqrt(factor_within(e)) if e.free_symbols else sp.sqrt(e)


def _solve_cs(p: sp.Expr, C: sp.Symbol, S: sp.Symbol) -> tuple[list[sp.Expr], dict] | None:
    """Angles x with p(cos x, sin x) = 0."""
    try:
        P = sp.Poly(p, C, S)
    except sp.PolynomialError:
        return None
    if P.total_degree() == 1:
        A, B, D = (tidy(P.coeff_monomial(m)) for m in (C, S, 1))
        info = {"A": A, "B": B, "D": D}
        if B == 0:
            c = _simple(tidy(-D / A))
            info["cos"] = c
            return _from_cos(c), info
        if A == 0:
            s = _simple(tidy(-D / B))
            info["sin"] = s
            return _from_sin(s), info
        if D == 0:
            return _dedupe([_simple(sp.atan2(-A, B)), _simple(sp.atan2(A, -B))]), info
        R2 = tidy(sp.expand(A**2 + B**2 - D**2))
        if R2.is_number and R2 < 0:
            return [], info
        base = sp.atan2(B, A)
        w = sp.atan2(_root(R2), -D)
        if R2 == 0:
            return [_simple(base)], info
        return [_simple(base + w), _simple(base - w)], info
    # reduce sin² = 1 - cos²: p = P0(C) + S·Q(C)
    red = sp.expand(p)
    for _ in range(8):
        red2 = sp.expand(red.subs(S**2, 1 - C**2)) if red.has(S**2) else red
        red2 = sp.expand(sp.rem(sp.Poly(red2, S), sp.Poly(S**2 + C**2 - 1, S)).as_expr()) if sp.degree(red2, S) > 1 \
            else red2
        if red2 == red:
            break
        red = red2
    Q = red.coeff(S, 1)
    P0 = sp.expand(red - Q * S)
    if Q == 0:
        poly = _poly_in(P0, C)
        if poly is None:
            return None
        roots = _poly_roots(poly)
        if roots is None:
            return None
        out = []
        for c in roots:
            out += _from_cos(_simple(c))
        return _dedupe(out), {"poly_cos": P0}
    poly = _poly_in(sp.expand(P0**2 - (1 - C**2) * Q**2), C)
    if poly is None:
        return None
    roots = _poly_roots(poly)
    if roots is None:
        return None
    out = []
    for c in roots:
        q = Q.subs(C, c)
        if q == 0:
            out += _from_cos(_simple(c))
        else:
            out.append(_simple(sp.atan2(-P0.subs(C, c) / q, c)))
    return _dedupe(out), {"poly_cos": sp.expand(P0**2 - (1 - C**2) * Q**2)}


def _from_cos(c: sp.Expr) -> list[sp.Expr]:
    """x with cos x = c: atan2(±√(1 - c²), c)."""
    if c.is_number:
        cv = complex(sp.N(c))
        if abs(cv.imag) > 1e-12 or abs(cv.real) > 1 + 1e-12:
            return []
        if abs(abs(cv.real) - 1) < 1e-14 and not c.atoms(sp.Float):
            return [sp.Integer(0) if cv.real > 0 else sp.pi]
        r2 = _simple(1 - c**2)
    else:
        r2 = 1 - c**2  # kept as written: cos(atan2(√(1 - c²), c)) = c, sin(...) = √(1 - c²)
    s = sp.sqrt(r2)
    return _dedupe([_simple(sp.atan2(s, c)), _simple(sp.atan2(-s, c))])


def _from_sin(s: sp.Expr) -> list[sp.Expr]:
    """x with sin x = s: atan2(s, ±√(1 - s²))."""
    if s.is_number:
        sv = complex(sp.N(s))
        if abs(sv.imag) > 1e-12 or abs(sv.real) > 1 + 1e-12:
            return []
        if abs(abs(sv.real) - 1) < 1e-14 and not s.atoms(sp.Float):
            return [sp.pi / 2 if sv.real > 0 else -sp.pi / 2]
        r2 = _simple(1 - s**2)
    else:
        r2 = 1 - s**2
    c = sp.sqrt(r2)
    return _dedupe([_simple(sp.atan2(s, c)), _simple(sp.atan2(s, -c))])


def _poly_roots(p: sp.Poly) -> list[sp.Expr] | None:
    """Real roots (numeric coefficients) or the closed-form roots up to degree 2 (symbolic), else None."""
    deg = p.degree()
    if deg <= 0:
        return None
    coeffs = [tidy(c) for c in p.all_coeffs()]
    if all(c.is_number for c in coeffs):
        if deg <= 2 and not any(c.atoms(sp.Float) for c in coeffs):
            rs = sp.roots(sp.Poly(coeffs, sp.Dummy()), multiple=True)
            out = [r for r in rs if abs(complex(sp.N(r)).imag) < 1e-12]
            return _dedupe([_simple(r) for r in out])
        vals = sp.Poly([float(sp.N(c)) for c in coeffs], sp.Dummy()).nroots()
        return _dedupe([sp.Float(sp.re(v), 15) for v in vals if abs(complex(v).imag) < 1e-9])
    if deg == 1:
        return [tidy(-coeffs[1] / coeffs[0])]
    if deg == 2:
        a, b, c = coeffs
        disc = tidy(sp.expand(b**2 - 4 * a * c))
        if disc == 0:
            return [tidy(-b / (2 * a))]
        r = _root(disc)
        return [sp.factor_terms((-b + r) / (2 * a)), sp.factor_terms((-b - r) / (2 * a))]
    return None


def _dedupe(values: list[sp.Expr]) -> list[sp.Expr]:
    """Values without repetitions (numbers compared numerically, expressions structurally)."""
    out: list[sp.Expr] = []
    for v in values:
        if any((abs(complex(sp.N(v - w))) < 1e-12) if (v.is_number and w.is_number) else
               (v == w or sp.expand(v - w) == 0) for w in out):
            continue
        out.append(v)
    return out


def _split(e: sp.Expr, left: Sequence[sp.Symbol]) -> tuple[sp.Expr, sp.Expr]:
    """(u, k): the terms of e with and without unknowns."""
    u, k = [], []
    for t in sp.Add.make_args(sp.expand(e)):
        (u if t.free_symbols & set(left) else k).append(t)
    return sp.Add(*u), sp.Add(*k)


def trig_factors(e: sp.Expr) -> tuple[sp.Expr, list[tuple[sp.Expr, int]]]:
    """e = constant · Π f_i^{k_i}, each factor a trigonometric polynomial in compact form.

    Trigonometric polynomials are not a unique factorization domain in cos/sin (sin² + cos² = 1), so the
    factorization is done after the substitution t = tan(x/2) (cos x = (1 - t²)/(1 + t²), sin x = 2t/(1 + t²)),
    in a genuine polynomial ring: a factor F of degree d in t (d even, or d odd taking one of the roots at x = π
    that the numerator lost, 2m - deg N of them for a denominator (1 + t²)^m) is the trigonometric polynomial
    F/(1 + t²)^{⌈d/2⌉}. The result is checked exactly; the plain factorization in cos/sin is the fallback.
    Memoized (a problem's asks factor the same determinants and minors again)."""
    const, facs = _trig_factors(sp.sympify(e))
    return const, list(facs)


@lru_cache(maxsize=1024)
def _trig_factors(e: sp.Expr) -> tuple[sp.Expr, tuple[tuple[sp.Expr, int], ...]]:
    const, facs = _trig_factors_uncached(e)
    return const, tuple(facs)


def _trig_factors_uncached(e: sp.Expr) -> tuple[sp.Expr, list[tuple[sp.Expr, int]]]:
    if e == 0 or not e.free_symbols:
        return e, []
    angles = sorted({s for f in e.atoms(sp.sin, sp.cos) for s in f.args[0].free_symbols}, key=lambda s: s.name)
    if angles:
        try:
            out = _factor_half_tangent(e, angles)
            if out is not None:
                return out
        except (ValueError, sp.PolynomialError, NotImplementedError, ZeroDivisionError):
            pass
    return _factor_cs(e, angles)


def _factor_cs(e: sp.Expr, angles: list[sp.Symbol]) -> tuple[sp.Expr, list[tuple[sp.Expr, int]]]:
    """Factorization of e as a polynomial in the cos/sin of the single angles."""
    cs = {x: (sp.Dummy(f"c_{x.name}"), sp.Dummy(f"s_{x.name}")) for x in angles}
    try:
        poly_form = sp.expand(sp.expand_trig(e))
        poly_form = poly_form.subs({sp.cos(x): c for x, (c, _) in cs.items()}).subs(
            {sp.sin(x): s for x, (_, s) in cs.items()})
        if any(poly_form.has(x) for x in angles):
            raise ValueError
        const, facs = sp.factor_list(poly_form)
    except (ValueError, sp.PolynomialError):
        try:
            const, facs = sp.factor_list(e)
        except sp.PolynomialError:  # not a polynomial in anything (a root of a function of q): one factor
            return sp.Integer(1), [(e, 1)]
        return const, [(tidy(f), k) for f, k in facs]
    back = {c: sp.cos(x) for x, (c, _) in cs.items()}
    back.update({s: sp.sin(x) for x, (_, s) in cs.items()})
    return _collect(const, [(tidy(f.subs(back)), k) for f, k in facs], angles)


def _collect(const: sp.Expr, facs: list[tuple[sp.Expr, int]], angles: list[sp.Symbol]
             ) -> tuple[sp.Expr, list[tuple[sp.Expr, int]]]:
    """Numbers into the constant, numeric content pulled out, equal (or opposite) factors merged."""
    out: list[tuple[sp.Expr, int]] = []
    for g, k in facs:
        if g.is_number or not g.free_symbols:
            const *= g**k
            continue
        c, rest = sp.factor_terms(g).as_coeff_Mul()
        const *= c**k
        for i, (h, m) in enumerate(out):
            if sp.expand(h - rest) == 0:
                out[i] = (h, m + k)
                break
            if sp.expand(h + rest) == 0:
                out[i] = (h, m + k)
                const *= (-1) ** k
                break
        else:
            out.append((rest, k))
    return const, out


def _factor_half_tangent(e: sp.Expr, angles: list[sp.Symbol]) -> tuple[sp.Expr, list[tuple[sp.Expr, int]]] | None:
    ts = [sp.Dummy(f"t_{x.name}") for x in angles]
    terms = _expanded_terms(e, angles)
    fast = _half_tangent_numerator(None, angles, ts, terms) if terms is not None else None
    P = None
    if fast is None:
        P = sp.expand(sp.expand_trig(e))
        fast = _half_tangent_numerator(P, angles, ts) if terms is None else None
    if fast is not None:
        const, facs, m, deg_total = fast
    else:
        sub = {}
        for x, t in zip(angles, ts):
            sub[sp.cos(x)] = (1 - t**2) / (1 + t**2)
            sub[sp.sin(x)] = 2 * t / (1 + t**2)
        R = P.xreplace(sub)
        if any(R.has(x) for x in angles):
            return None
        num, den = sp.fraction(sp.together(R))
        num = sp.expand(num)
        # den = c · Π (1 + t_i²)^{m_i}
        m = [0] * len(ts)
        dc, dfac = sp.factor_list(den)
        for f, k in dfac:
            hit = [i for i, t in enumerate(ts) if sp.expand(f - (1 + t**2)) == 0]
            if not hit:
                return None
            m[hit[0]] += k
        const, facs0 = sp.factor_list(num)
        const = const / dc
        deg_total = [sp.degree(num, t) if num.has(t) else 0 for t in ts]
        facs = [(f, k, [sp.degree(f, t) if f.has(t) else 0 for t in ts]) for f, k in facs0]
    slack = [2 * mi - di for mi, di in zip(m, deg_total)]
    pieces: list[tuple[sp.Expr, list[int], int]] = []  # (F, k per variable, multiplicity)
    odd: list[tuple[sp.Expr, list[int]]] = []
    for f, k, d in facs:
        if not any(d):
            if f.free_symbols:
                pieces.append((f, [0] * len(ts), k))
            else:
                const *= f**k
            continue
        if any(di % 2 for di in d):
            odd += [(f, d)] * k
        else:
            pieces.append((f, [di // 2 for di in d], k))
    # an odd factor takes a root at π (monomials t first: t/(1 + t²) = sin x / 2), or pairs with its mirror
    # f(-t) (1 - t and 1 + t: cos x), or with another factor of the same odd variables
    odd.sort(key=lambda fd: (len(sp.Add.make_args(fd[0])) > 1, sum(fd[1])))
    rest: list[tuple[sp.Expr, list[int]]] = []
    for f, d in odd:
        vs = [i for i, di in enumerate(d) if di % 2]
        if all(slack[i] >= 1 for i in vs):
            for i in vs:
                slack[i] -= 1
            pieces.append((f, [(di + 1) // 2 for di in d], 1))
        else:
            rest.append((f, d))
    while rest:
        f, d = rest.pop(0)
        sig = [di % 2 for di in d]
        mirror = sp.expand(f.xreplace({t: -t for t, o in zip(ts, sig) if o}))
        pick = None
        for j, (g, dg) in enumerate(rest):
            if [x % 2 for x in dg] == sig and (sp.expand(g - mirror) == 0 or sp.expand(g + mirror) == 0):
                pick = j
                break
        if pick is None:
            pick = next((j for j, (g, dg) in enumerate(rest) if [x % 2 for x in dg] == sig), None)
        if pick is None:
            if not rest:
                return None
            pick = 0
        g, dg = rest.pop(pick)
        F, dF = sp.expand(f * g), [a + b for a, b in zip(d, dg)]
        if any(x % 2 for x in dF):
            rest.insert(0, (F, dF))
        else:
            pieces.append((F, [x // 2 for x in dF], 1))
    used = [sum(kk[i] * mult for _, kk, mult in pieces) for i in range(len(ts))]
    facs_trig: list[tuple[sp.Expr, int]] = []
    for i, x in enumerate(angles):
        extra = m[i] - used[i]
        if extra < 0:
            return None
        if extra:  # 1/(1 + t²) = (1 + cos x)/2
            facs_trig.append(((1 + sp.cos(x)) / 2, extra))
    for F, kk, mult in pieces:
        facs_trig.append((_from_half_tangent(F, ts, angles, kk), mult))
    const2, out = _collect(const, facs_trig, angles)
    check = tidy(sp.expand(e - const2 * sp.Mul(*[f**k for f, k in out])))
    if check != 0:
        return None
    return tidy(const2), out


def _expanded_terms(e: sp.Expr, angles: list[sp.Symbol]
                    ) -> list[tuple[sp.Rational, list[int], list[int], dict[sp.Symbol, int]]] | None:
    """The terms of sp.expand(sp.expand_trig(e)) as :func:`_half_tangent_numerator` reads them (coefficient,
    exponents of cos x_i, of sin x_i, of the other symbols), computed in a polynomial ring of (cos x_i, sin x_i,
    symbols) over Q: each sin/cos of Σ n_j x_j (integers n_j, no constant) is expand_trig's polynomial (the
    multiple-angle and addition formulas: :func:`solver.math.fourier.ring_trig`), and the ring multiplies out what
    sympy's expand would. None for anything else (a constant in an argument, a radical, a symbol in a
    denominator, an angle outside sin/cos): the caller then expands with sympy."""
    k = len(angles)
    params = sorted(e.free_symbols - set(angles), key=lambda s: s.name)
    R = sp.polys.rings.PolyRing([sp.Dummy() for _ in range(2 * k)] + params, sp.QQ, sp.polys.orderings.lex)
    C, S, P = R.gens[:k], R.gens[k:2 * k], dict(zip(params, R.gens[2 * k:]))
    cs = {x: (C[i], S[i]) for i, x in enumerate(angles)}

    def leaf(f: sp.Expr) -> Any:
        if isinstance(f, sp.cos):
            return ring_trig(f.args[0], cs)[0]
        if isinstance(f, sp.sin):
            return ring_trig(f.args[0], cs)[1]
        if f in P:
            return P[f]
        raise ValueError
    conv = ring_reader(R, leaf)

    try:
        poly = conv(e)
    except ValueError:
        return None
    out = []
    for mono, c in poly.terms():
        other = {g: d for g, d in zip(params, mono[2 * k:]) if d}
        out.append((sp.Rational(int(c.numerator), int(c.denominator)), list(mono[:k]), list(mono[k:2 * k]), other))
    return out


def _half_tangent_numerator(P: sp.Expr | None, angles: list[sp.Symbol], ts: list[sp.Symbol],
                            terms: list | None = None
                            ) -> tuple[sp.Expr, list[tuple[sp.Expr, int, list[int]]], list[int], list[int]] | None:
    """P (expanded, a polynomial in the cos/sin of the angles with polynomial coefficients) as N(t)/Π(1 + t_i²)^{m_i}
    with t_i = tan(x_i/2), m_i the largest degree of a term in (cos x_i, sin x_i): each term c^a s^b becomes
    (1 - t²)^a (2t)^b (1 + t²)^{m-a-b}, computed in a sparse polynomial ring (no rational-function arithmetic on
    expressions). Returns (constant, [(factor, multiplicity, degree in each t_i)], m, degree of N in each t_i), the
    factors those of ``sp.factor_list(N)`` in its order; None when P is not of that shape (the caller then takes
    the general path). ``terms``: P's terms already read (:func:`_expanded_terms`), P then unused."""
    index = {x: i for i, x in enumerate(angles)}
    k = len(angles)
    parsed: list[tuple[sp.Rational, list[int], list[int], dict[sp.Symbol, int]]] = list(terms or [])
    params: set[sp.Symbol] = {s_ for *_, other in parsed for s_ in other}
    for term in (sp.Add.make_args(P) if terms is None else ()):
        coeff, a, b, other = sp.Integer(1), [0] * k, [0] * k, {}
        for f in sp.Mul.make_args(term):
            if f.is_Rational:
                coeff *= f
                continue
            base, ex = f.as_base_exp()
            if not (ex.is_Integer and ex > 0):
                return None
            if isinstance(base, (sp.cos, sp.sin)) and base.args[0] in index:
                (a if isinstance(base, sp.cos) else b)[index[base.args[0]]] += int(ex)
            elif base.is_Symbol and base not in index:
                other[base] = other.get(base, 0) + int(ex)
                params.add(base)
            else:
                return None
        parsed.append((coeff, a, b, other))
    if len(parsed) < 2:
        return None  # (a monomial: factor_list takes its factors one by one)
    m = [max(pa[i] + pb[i] for _, pa, pb, _ in parsed) for i in range(k)]
    from sympy.polys.polyutils import _sort_gens
    gens = list(_sort_gens(list(ts) + sorted(params, key=str)))
    R = sp.polys.rings.PolyRing(gens, sp.QQ, sp.polys.orderings.lex)
    gi = {g: R.gens[j] for j, g in enumerate(gens)}
    powers: dict[tuple[int, int, int], Any] = {}

    def block(i: int, a: int, b: int) -> Any:  # (1 - t²)^a (2t)^b (1 + t²)^{m-a-b}
        key = (i, a, b)
        if key not in powers:
            t = gi[ts[i]]
            powers[key] = (1 - t**2) ** a * (2 * t) ** b * (1 + t**2) ** (m[i] - a - b)
        return powers[key]

    num = R.zero
    for coeff, a, b, other in parsed:
        term = R(sp.QQ(int(coeff.p), int(coeff.q)))
        for s_, e_ in other.items():
            term *= gi[s_] ** e_
        for i in range(k):
            if m[i]:
                term *= block(i, a[i], b[i])
        num += term
    if len(num) < 2:
        return None  # (zero, or a monomial: as above)
    lead = 1  # (the coefficients' common denominator: N·lead over ZZ, as sympy's numerator of together)
    for c in num.values():
        lead = sp.ilcm(lead, int(c.denominator))
    terms = {mono: int(c * lead) for mono, c in num.items()}
    # as sp.factor_list(N) does it: together() pulls the monomial content Π g^{e_g} out first (each g a factor of
    # its own), and the rest is factored over the generators it has
    low = [min(mo[j] for mo in terms) for j in range(len(gens))]
    terms = {tuple(x - y for x, y in zip(mo, low)): c for mo, c in terms.items()}
    used = [j for j in range(len(gens)) if any(mo[j] for mo in terms)]
    rest_gens = [gens[j] for j in used]
    Rz = sp.polys.rings.PolyRing(rest_gens, sp.ZZ, sp.polys.orderings.lex)
    const, ring_facs = factor_list_fast(Rz.from_dict({tuple(mo[j] for j in used): c for mo, c in terms.items()}))
    # (sympy's factors of the same polynomial, by gcds where it is linear in a generator: as Polys in its generators)
    rest_facs = [(sp.Poly.from_dict(dict(f.terms()), *rest_gens, domain=sp.ZZ), e_) for f, e_ in ring_facs]
    monomial = sp.Mul(*[gens[j] ** low[j] for j in range(len(gens)) if low[j]])
    facs: list[tuple[sp.Poly, int]] = []
    for f in sp.Mul.make_args(monomial):
        if f != 1:
            g, e_ = f.as_base_exp()
            facs.append((sp.Poly(g, g), int(e_)))
    facs += rest_facs

    def key(fe: tuple[sp.Poly, int]) -> tuple:
        rep = fe[0].rep.to_list()
        return (len(rep), len(fe[0].gens), fe[1], str(fe[0].domain), rep)

    out = []
    for f, e_ in sorted(facs, key=key):
        degs = dict(zip(f.gens, f.degree_list()))
        out.append((f.as_expr(), e_, [degs.get(t, 0) for t in ts]))
    deg_total = [max(mo[gens.index(t)] for mo in num.keys()) if t in gens else 0 for t in ts]
    return sp.Rational(const) / lead, out, m, deg_total


def _from_half_tangent(F: sp.Expr, ts: list[sp.Symbol], angles: list[sp.Symbol], k: list[int]) -> sp.Expr:
    """F(t) / Π (1 + t_i²)^{k_i} as a trigonometric polynomial: t^{2a+b} / (1 + t²)^k = ((1 - cos x)/2)^a
    (sin x / 2)^b ((1 + cos x)/2)^{k-a-b}, summed in a sparse ring of (cos x_i, sin x_i, parameters)."""
    params = sorted(F.free_symbols - set(ts), key=str)
    try:
        P = sp.Poly(F, *ts, *params)
    except sp.PolynomialError:  # (a radical of a parameter, say: the general path below)
        P = None
    if P is not None and P.domain in (sp.ZZ, sp.QQ):
        n = len(angles)
        cs = [f(x) for x in angles for f in (sp.cos, sp.sin)]
        R = sp.polys.rings.PolyRing(cs + params, sp.QQ, sp.polys.orderings.lex)
        half = sp.QQ(1, 2)
        blocks: dict[tuple[int, int, int], Any] = {}
        total = R.zero
        for mono, coeff in P.terms():
            term = R(sp.QQ.from_sympy(coeff))
            for i in range(n):
                a, b = divmod(int(mono[i]), 2)
                key = (i, a, b)
                if key not in blocks:
                    c, s_ = R.gens[2 * i], R.gens[2 * i + 1]
                    blocks[key] = ((half - half * c) ** a * (half * s_) ** b
                                   * (half + half * c) ** int(k[i] - a - b))
                term *= blocks[key]
            for j, e_ in enumerate(mono[n:]):
                if e_:
                    term *= R.gens[2 * n + j] ** e_
            total += term
        return tidy(total.as_expr())
    P = sp.Poly(F, *ts)
    total = sp.Integer(0)
    for mono, coeff in P.terms():
        term = coeff
        for j, x, ki in zip(mono, angles, k):
            a, b = divmod(j, 2)
            c = ki - a - b
            term *= ((1 - sp.cos(x)) / 2) ** a * (sp.sin(x) / 2) ** b * ((1 + sp.cos(x)) / 2) ** c
        total += term
    return tidy(sp.expand(total))


# ------------------------------------------------------------------------------------------------ numeric check
Sampler = Callable[[random.Random], dict[sp.Symbol, float]]


def _atan2c(y: complex, x: complex) -> complex:
    y, x = complex(y), complex(x)
    if abs(y.imag) > 1e-9 * max(1.0, abs(y)) or abs(x.imag) > 1e-9 * max(1.0, abs(x)):
        return complex("nan")
    return complex(cmath.phase(complex(x.real, y.real)))


_MODULES = [{"atan2": _atan2c, "sqrt": cmath.sqrt, "Abs": abs, "atan": cmath.atan, "acos": cmath.acos,
             "asin": cmath.asin}, "cmath"]


def numeric_function(exprs: Sequence[sp.Expr], symbols: Sequence[sp.Symbol]) -> Callable[..., list[complex]]:
    """exprs as a fast complex-valued function of ``symbols`` (cmath; atan2 of non-real arguments is nan)."""
    f = sp.lambdify(list(symbols), list(exprs), modules=_MODULES)

    def call(*args: float) -> list[complex]:
        try:
            return [complex(v) for v in f(*args)]
        except (ValueError, ZeroDivisionError, TypeError, OverflowError):
            return [complex("nan")] * len(exprs)
    return call


def check_families(families: list[Family], equations: Sequence[sp.Expr], unknowns: Sequence[sp.Symbol],
                   sampler: Sampler | None, trials: int = 6, tol: float = 1e-7) -> list[Family]:
    """Keep the families whose values satisfy every equation at some sample point where they are real (all of
    them when the data are numbers: then at the one point), each marked ``verified``; duplicates dropped."""
    rng = random.Random(2024)
    points = [sampler(rng) for _ in range(trials)] if sampler else [{}]
    syms = sorted(set().union(*[e.free_symbols for e in equations], *[set(p) for p in points]) - set(unknowns),
                  key=lambda s: s.name)
    eq_f = numeric_function(equations, list(unknowns) + syms)
    kept: list[tuple[Family, list]] = []
    for fam in families:
        free_syms = [x for x in fam.free]
        val_f = numeric_function([fam.values[x] for x in unknowns], syms + free_syms)
        ok, sig = False, []
        for pt in points:
            pt = dict(pt)
            for x in free_syms:
                pt.setdefault(x, rng.uniform(-2.5, 2.5))
            zs = val_f(*[pt.get(s, 0.0) for s in syms], *[pt[x] for x in free_syms])
            if any(not cmath.isfinite(z) or abs(z.imag) > 1e-9 * max(1.0, abs(z.real)) for z in zs):
                sig.append(None)
                continue
            vals = [z.real for z in zs]
            res = eq_f(*vals, *[pt.get(s, 0.0) for s in syms])
            scale = max([1.0] + [abs(v) for v in vals] + [abs(pt.get(s, 0.0)) for s in syms]) ** 3
            good = all(cmath.isfinite(r) and abs(r) < tol * scale for r in res)
            ok = ok or good
            sig.append(tuple(vals) if good else None)
        if not ok:
            continue
        fam.verified = True
        if any(_same(sig, s2, unknowns) for _, s2 in kept):
            continue
        kept.append((fam, sig))
    return [f for f, _ in kept]


def _same(a: list, b: list, unknowns: Sequence[sp.Symbol]) -> bool:
    """Two families agree (modulo 2π) at every sample point where both are real and valid."""
    import math
    both = [(x, y) for x, y in zip(a, b) if x is not None and y is not None]
    if not both:
        return False
    for x, y in both:
        for u, v in zip(x, y):
            d = (u - v) / (2 * math.pi)
            if abs(u - v) > 1e-7 and abs(d - round(d)) > 1e-9:
                return False
    return True
