"""Linear parametrization of the dynamic model in the dynamic coefficients (ask kind ``linear_parametrization``).

    B(q) q̈ + c(q, q̇) + g(q) (+ F_v q̇) = Y(q, q̇, q̈) a,      a ∈ R^p

The dynamic parameters are the problem's symbols that are not ``known:`` (masses, CoM distances, inertias,
friction coefficients); known symbols (lengths, g0) may appear in Y. The model is a polynomial in the dynamic
parameters, so, expanding it over a canonical basis of functions of the state ("atoms": monomials in q̈, q̇,
prismatic coordinates and sin/cos of single angles, with cos² x rewritten as 1 − sin² x, which makes the
representation unique),

    model = F(q, q̇, q̈) · C · π,

with F the row of atoms (one per equation and function), π the products (monomials) of dynamic parameters and C a
matrix of constants (numbers and known symbols). A parametrization is a factorization C = L R with a = R π and
Y = F L; it is minimal when p = rank C (the columns of Y are then linearly independent over the constants).

* Given coefficients a = R π (``coefficients:``): R must have full row rank (else the a_i are dependent and Y is
  not unique); then L = C_J R_J⁻¹ (J: p independent columns of R) and C − L R must vanish (else the coefficients
  cannot express the model). If the a_i are dependent only because some known symbols are taken as known (a_2 =
  l1 m2 d2 and a_7 = g0 m2 d2), Y is computed treating those symbols as parameters and the parametrization is
  reported as not minimal.
* Computed (no ``coefficients:``): p pivot atoms P are chosen greedily in the order a teacher reads the model
  (equation by equation; accelerations, then velocity products, then gravity, then friction); a_i is the
  coefficient of the i-th pivot atom (R = C_P, with numeric and known factors taken out), so that a_1 = I1 + m1 d1²
  + I2 + m2 l1² is "the coefficient of q̈1 in the first equation", and L = C_J C_PJ⁻¹.

Ranks are generic ranks over the field of constants (known symbols at random rational values, exact); L, R and
the residual are computed exactly; the final check Y a ≡ model is exact.
"""
from __future__ import annotations

import random
from dataclasses import dataclass, field
from fractions import Fraction
from functools import lru_cache
from typing import Any, Literal, Optional, Union

import mpmath
import sympy as sp
from pydantic import Field

from solver.dynamics.model import derive, require_model
from solver.math.equivalence import equivalent, exact_zero
from solver.math.fourier import ring_reader, ring_trig
from solver.math.opcount import count_ops
from solver.math.simplify import group_expanded, is_zero, tidy
from solver.registry import PropertyVerdict, ask_kind, property_check
from solver.results import Solution
from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

ExprT = Union[str, int, float, list[Any]]
PARTS = {"model": "B(q)\\ddot q + c(q,\\dot q) + g(q)", "inertia": "B(q)\\ddot q", "gravity": "g(q)"}


class LinearParametrizationAsk(Strict):
    """Linear parametrization Y(q, q̇, q̈) a of the dynamic model in a minimal set of dynamic coefficients."""

    kind: Literal["linear_parametrization"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    coefficients: Optional[ExprT] = Field(
        None, description="the dynamic coefficients a_i as expressions of the parameters (a grouping chosen by the "
                          "printed solution, e.g. [I1 + m1*d1^2 + I2 + m2*l1^2, m2, m1*d1 + m2*l1]); robosolve "
                          "computes Y for them and checks them. Default: a minimal set computed by robosolve")
    symbol: Optional[str] = Field(
        None, pattern=r"^[A-Za-z]+$",
        description="name of the coefficients in the report: a gives a_1..a_p, pi gives π_1..π_p (default a, or "
                    "pi when the problem has a symbol such as a2)")
    part: Literal["model", "inertia", "gravity"] = Field(
        "model", description="what is parametrized: the whole model B q̈ + c + g (+ F_v q̇), only the inertial "
                             "term B(q) q̈ (Y(q, q̈)), or only the gravity vector g(q) (Y(q))")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$",
                        description="appended to every result name (several parametrizations in one problem)")


# ------------------------------------------------------------------------------------------------ algebra
class _NotPolynomial(Exception):
    def __init__(self, factor: sp.Expr, reason: str) -> None:
        super().__init__(reason)
        self.factor, self.reason = factor, reason


def canonical(expr: sp.Expr, state: set, square: str = "cos") -> sp.Expr:
    """``expr`` expanded over products of sin/cos of single angles, with cos² x -> 1 - sin² x (``square`` =
    "cos"; "sin": sin² x -> 1 - cos² x): a unique representation of trigonometric polynomials."""
    expr = sp.sympify(expr)
    fast = _ring_canonical(expr, state, square)
    if fast is not None:
        return fast
    e = sp.expand(sp.expand_trig(expr))
    fn, other = (sp.cos, sp.sin) if square == "cos" else (sp.sin, sp.cos)

    def is_square(x: Any) -> bool:
        return bool(x.is_Pow and isinstance(x.base, fn) and x.exp.is_Integer and x.exp >= 2
                    and x.base.free_symbols & state)

    def reduce(x: sp.Expr) -> sp.Expr:
        arg, k = x.base.args[0], int(x.exp)
        return fn(arg) ** (k % 2) * (1 - other(arg) ** 2) ** (k // 2)

    for _ in range(4):
        if not e.has(fn) or not any(is_square(x) for x in e.atoms(sp.Pow)):
            break
        e = sp.expand(e.replace(is_square, reduce))
    return e


def _ring_canonical(expr: sp.Expr, state: set, square: str) -> sp.Expr | None:
    """:func:`canonical` computed in a sparse ring, for a polynomial over Q in symbols and sin/cos of integer
    combinations of the state's angles: cos and sin of each angle are generators c, s, cos/sin of a combination
    their polynomial (:func:`solver.math.fourier.ring_trig`), and c² (``square`` "cos"; s² for "sin") is replaced
    by 1 − s² (1 − c²) in every monomial; the representation being unique, its expanded sum is the one the expansions give.
    None for anything else (floats, other functions, an angle outside the state, a fraction in an argument)."""
    from math import comb as binomial

    from sympy.polys.domains import QQ
    from sympy.polys.rings import ring
    angles = sorted({x for f in expr.atoms(sp.sin, sp.cos) for x in f.args[0].free_symbols}, key=lambda x: x.name)
    if not angles or not set(angles) <= state:
        return None
    syms = sorted(expr.free_symbols, key=lambda x: x.name)
    cs = {a: (sp.Dummy(f"c_{a.name}"), sp.Dummy(f"s_{a.name}")) for a in angles}
    R, *gens = ring(syms + [v for a in angles for v in cs[a]], QQ)
    gen = dict(zip(syms + [v for a in angles for v in cs[a]], gens))

    angle_cs = {a: (gen[c], gen[s]) for a, (c, s) in cs.items()}

    def trig(f: sp.Expr):  # type: ignore[no-untyped-def]
        c, s = ring_trig(f.args[0], angle_cs)   # (any form: the reduction below makes it unique)
        return c if isinstance(f, sp.cos) else s

    def leaf(e: sp.Expr):  # type: ignore[no-untyped-def]
        if e.is_Symbol:
            return gen[e]
        if isinstance(e, (sp.sin, sp.cos)):
            return trig(e)
        raise ValueError(e)
    conv = ring_reader(R, leaf)

    try:
        p = conv(expr)
    except (ValueError, KeyError):
        return None
    first = 0 if square == "cos" else 1   # the generator whose square is replaced
    pairs = [(R.symbols.index(cs[a][first]), R.symbols.index(cs[a][1 - first])) for a in angles]
    acc: dict = {}
    for mono, coeff in p.iterterms():
        terms = [(list(mono), coeff)]
        for i, j in pairs:   # c^(2k + r) = c^r (1 − s²)^k, binomially
            k = mono[i] // 2
            if k:
                spread = []
                for m, c in terms:
                    for t in range(k + 1):
                        m2 = list(m)
                        m2[i] -= 2 * k
                        m2[j] += 2 * t
                        spread.append((m2, c * binomial(k, t) * (-1) ** t))
                terms = spread
        for m, c in terms:
            key = tuple(m)
            acc[key] = acc.get(key, QQ.zero) + c
    back = list(syms) + [fn(a) for a in angles for fn in (sp.cos, sp.sin)]
    return R.from_dict({m: c for m, c in acc.items() if c}).as_expr(*back)


def split_term(term: sp.Expr, state: set, dyn: set) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """term = function(state) * monomial(dynamic parameters) * constant; _NotPolynomial otherwise."""
    f, m, c = [], [], []
    for fac in sp.Mul.make_args(term):
        fs = fac.free_symbols
        if fs & dyn and fs & state:
            raise _NotPolynomial(fac, "inside a function of the state")
        if fs & state:
            f.append(fac)
        elif fs & dyn:
            base, ex = fac.as_base_exp()
            if base in dyn and ex.is_Integer and ex > 0:
                m.append(fac)
            else:
                raise _NotPolynomial(fac, "not as a product of powers")
        else:
            c.append(fac)
    return sp.Mul(*f), sp.Mul(*m), sp.Mul(*c)


@dataclass
class Expansion:
    """model = Σ_atoms atom · Σ_monos C[atom][mono] · mono."""

    atoms: list[tuple[int, sp.Expr]] = field(default_factory=list)   # (equation, function of the state)
    monos: list[sp.Expr] = field(default_factory=list)
    C: dict[tuple[int, sp.Expr], dict[sp.Expr, sp.Expr]] = field(default_factory=dict)

    def add(self, atom: tuple[int, sp.Expr], mono: sp.Expr, const: sp.Expr) -> None:
        if atom not in self.C:
            self.C[atom] = {}
            self.atoms.append(atom)
        if mono not in self.monos:
            self.monos.append(mono)
        row = self.C[atom]
        row[mono] = row.get(mono, sp.Integer(0)) + const

    def clean(self) -> None:
        for atom in list(self.atoms):
            row = self.C[atom]
            for mono in list(row):
                if sp.cancel(row[mono]) == 0:
                    del row[mono]
            if not row:
                del self.C[atom]
                self.atoms.remove(atom)
        used = {m for row in self.C.values() for m in row}
        self.monos = [m for m in self.monos if m in used]

    def matrix(self, atoms: list, monos: list) -> sp.Matrix:
        return sp.Matrix(len(atoms), len(monos), lambda i, j: self.C.get(atoms[i], {}).get(monos[j], sp.Integer(0)))

    def phi(self, mono: sp.Expr, n: int) -> sp.Matrix:
        """The n-vector of functions multiplying ``mono`` in the model."""
        out = [sp.Integer(0)] * n
        for (k, f) in self.atoms:
            c = self.C[(k, f)].get(mono)
            if c is not None:
                out[k] += c * f
        return sp.Matrix(out)


def expand_model(vec: sp.Matrix, state: set, dyn: set) -> Expansion:
    ex = Expansion()
    for k, e in enumerate(vec):
        for term in sp.Add.make_args(canonical(e, state)):
            if term == 0:
                continue
            f, m, c = split_term(term, state, dyn)
            ex.add((k, f), m, c)
    ex.clean()
    return ex


def expand_coefficient(a: sp.Expr, dyn: set) -> dict[sp.Expr, sp.Expr]:
    out: dict[sp.Expr, sp.Expr] = {}
    for term in sp.Add.make_args(sp.expand(a)):
        if term == 0:
            continue
        _, m, c = split_term(term, set(), dyn)
        out[m] = out.get(m, sp.Integer(0)) + c
    return {m: c for m, c in out.items() if sp.cancel(c) != 0}


# ------------------------------------------------------------------------------------------------ ranks
class Generic:
    """Generic ranks over the constants: every free symbol (known data) at a fixed random rational value; exact
    rational elimination (40-digit floating point when an entry is irrational, e.g. sqrt(2) or cos(alpha))."""

    def __init__(self, seed: int = 20250) -> None:
        self.rng = random.Random(seed)
        self.point: dict[sp.Symbol, sp.Expr] = {}

    def value(self, x: sp.Expr) -> Any:
        for s in x.free_symbols:
            if s not in self.point:
                v = sp.Rational(self.rng.randint(1200, 3100), self.rng.randint(389, 997))
                self.point[s] = v if (s.is_positive or s.is_nonnegative or self.rng.random() < 0.5) else -v
        v = sp.sympify(x).xreplace(self.point) if x.free_symbols else sp.sympify(x)
        if v.is_Rational:
            return Fraction(int(v.p), int(v.q))
        return mpmath.mpf(str(sp.N(v, 50)))


class Echelon:
    """Incremental row reduction: ``add(row)`` says whether the row increases the rank."""

    def __init__(self, gen: Generic) -> None:
        self.gen = gen
        self.rows: list[tuple[int, list[Any]]] = []
        self.exact = True

    @staticmethod
    def _zero(x: Any) -> bool:
        return x == 0 if isinstance(x, (int, Fraction)) else abs(x) < mpmath.mpf("1e-28")

    def reduce(self, row: list[Any]) -> list[Any]:
        r = list(row)
        for piv, base in self.rows:
            if not self._zero(r[piv]):
                f = r[piv] / base[piv]
                r = [x - f * y for x, y in zip(r, base)]
        return r

    def add(self, exprs: list[sp.Expr]) -> bool:
        with mpmath.workdps(50):
            return self._add(exprs)

    def _add(self, exprs: list[sp.Expr]) -> bool:
        vals = [self.gen.value(x) for x in exprs]
        if not self.exact or any(isinstance(v, mpmath.mpf) for v in vals):
            if self.exact:
                self.exact = False
                self.rows = [(piv, [mpmath.mpf(x.numerator) / x.denominator if isinstance(x, Fraction) else x
                                    for x in r]) for piv, r in self.rows]
            vals = [mpmath.mpf(v.numerator) / v.denominator if isinstance(v, Fraction) else v for v in vals]
        r = self.reduce(vals)
        nz = [j for j, x in enumerate(r) if not self._zero(x)]
        if not nz:
            return False
        piv = max(nz, key=lambda j: abs(r[j]))
        self.rows.append((piv, r))
        return True


def generic_rank(M: sp.Matrix, gen: Generic) -> int:
    e = Echelon(gen)
    return sum(e.add(list(M.row(i))) for i in range(M.rows))


def independent_rows(M: sp.Matrix, gen: Generic, order: list[int] | None = None) -> list[int]:
    e = Echelon(gen)
    return [i for i in (order if order is not None else range(M.rows)) if e.add(list(M.row(i)))]


def _zero_exact(x: sp.Expr) -> bool:
    """x ≡ 0, exactly: a non-zero value at a rational point (randomized exact test) proves x ≢ 0 at once, the
    common case of a pivot; zero is confirmed by cancellation (and simplify)."""
    if x == 0:
        return True
    if not x.atoms(sp.Float) and exact_zero(x) is False:
        return False
    c = sp.cancel(sp.together(x))
    if c == 0:
        return True
    return bool(sp.simplify(c) == 0)


def exact_inverse(M: sp.Matrix) -> sp.Matrix:
    """Gauss-Jordan with exact zero tests (entries: numbers and known symbols)."""
    n = M.rows
    A = M.row_join(sp.eye(n)).as_mutable()
    for col in range(n):
        piv = next((r for r in range(col, n) if not _zero_exact(A[r, col])), None)
        if piv is None:
            raise ZeroDivisionError("singular")
        if piv != col:
            A.row_swap(piv, col)
        p = A[col, col]
        A[col, :] = (A[col, :] / p).applyfunc(sp.cancel)
        for r in range(n):
            if r != col and not _zero_exact(A[r, col]):
                f = A[r, col]
                A[r, :] = (A[r, :] - f * A[col, :]).applyfunc(sp.cancel)
    return A[:, n:]


def relations(M: sp.Matrix, names: list[sp.Symbol]) -> list[sp.Expr]:
    """Σ v_i names_i for each vector v of the null space of M (denominators cleared, content removed)."""
    out = []
    for v in M.nullspace(simplify=True):
        v = v.applyfunc(sp.cancel)
        den = sp.lcm([sp.fraction(sp.together(x))[1] for x in v])
        v = (v * den).applyfunc(sp.cancel)
        expr = sp.factor_terms(sum((x * s for x, s in zip(v, names)), sp.Integer(0)))
        _, expr = expr.as_independent(*names, as_Add=False)
        if expr.could_extract_minus_sign():
            expr = -expr
        out.append(sp.expand(expr))
    return out


# ------------------------------------------------------------------------------------------------ readability
def _group_by_state(e: sp.Expr, rate: list[sp.Symbol]) -> sp.Expr:
    """Terms collected on the monomials of the velocities/accelerations, coefficients factored."""
    return sp.Add(*[_factor_terms(sp.Add(*c)) * m for m, c in group_expanded(e, rate).items()])


def split_rates(e: sp.Expr, ddq: list[sp.Symbol], dq: list[sp.Symbol]) -> tuple[list[sp.Expr], sp.Expr, sp.Expr] | None:
    """An expanded sum e = Σ_j b_j q̈_j + c + g, linear in the accelerations, as ([∂e/∂q̈_j], c, g): c the terms
    with velocities, g those without (the jacobian, e − J q̈ expanded and its value at q̇ = 0, read off the terms
    of the sum, each written as those give it). None when an acceleration or a velocity is not a factor of a term
    to the first power (an acceleration) or a natural power (a velocity)."""
    acc, vel = set(ddq), set(dq)
    b: list[list[sp.Expr]] = [[] for _ in ddq]
    c: list[sp.Expr] = []
    g: list[sp.Expr] = []
    for term in sp.Add.make_args(e):
        factors = sp.Mul.make_args(term)
        rates = [f for f in factors if f.free_symbols & (acc | vel)]
        powers = [f.as_base_exp() for f in rates if f not in acc]
        if any(not (x in vel and k.is_Integer and k > 0) for x, k in powers):
            return None
        hit = [f for f in rates if f in acc]
        if len(hit) > 1:
            return None
        if hit:
            b[ddq.index(hit[0])].append(sp.Mul(*[f for f in factors if f is not hit[0]]))
        else:
            (c if rates else g).append(term)
    return [sp.Add(*x) for x in b], sp.Add(*c), sp.Add(*g)


@lru_cache(maxsize=4096)
def _factor_terms(e: sp.Expr) -> sp.Expr:
    """sp.factor_terms(e), memoized: the same sums of parameters multiply the monomials of many entries (Y, its
    rows, B_a, c_a, g_a; 75 distinct of 308 in 2021-02-04-ex1)."""
    return sp.factor_terms(e)


def readable(e: sp.Expr, state: set, rate: list[sp.Symbol]) -> sp.Expr:
    """The shortest of: the canonical Fourier form (tidy: c_12, sin 2q), the product forms with sin² or cos².
    Memoized: Y's entries recur in the explanation's rows, groups and in the other asks of a problem."""
    return _readable(sp.sympify(e), frozenset(state), tuple(rate))


@lru_cache(maxsize=2048)
def _readable(e: sp.Expr, state: frozenset, rate: tuple) -> sp.Expr:
    t = tidy(e)
    if not t.free_symbols & state or not t.atoms(sp.sin, sp.cos):
        return t
    best, ops = t, count_ops(t)
    for square in ("cos", "sin"):
        c = _group_by_state(canonical(e, set(state), square), list(rate))
        n = count_ops(c)
        if n < ops:
            best, ops = c, n
    return best


def _complexity(f: sp.Expr, q: list[sp.Symbol]) -> int:
    n = 0
    for fac in sp.Mul.make_args(f):
        base, ex = fac.as_base_exp()
        k = int(ex) if ex.is_Integer else 1
        if isinstance(base, (sp.sin, sp.cos)) or base in q:
            n += abs(k)
        elif fac.free_symbols & set(q):
            n += 3
    return n


def atom_order(atoms: list[tuple[int, sp.Expr]], robot) -> list[int]:  # type: ignore[no-untyped-def]
    """Teacher's reading order: equation by equation; accelerations (by joint), velocity products, gravity
    (position only), friction (linear in velocities); simpler functions first."""
    dd, d, q = list(robot.ddq), list(robot.dq), list(robot.q)

    def key(i: int) -> tuple:
        k, f = atoms[i]
        degs = {s: sp.degree(f, s) if f.is_polynomial(s) else 1 for s in dd + d if f.has(s)}
        acc = [j for j, s in enumerate(dd) if s in degs]
        vel = sum(v for s, v in degs.items() if s in d)
        kind = 0 if acc else (1 if vel >= 2 else (2 if vel == 0 else 3))
        return (k, kind, _complexity(f, q), acc[0] if acc else 0, count_ops(f), str(f))

    return sorted(range(len(atoms)), key=key)


def normalize(a: sp.Expr, dyn: list[sp.Symbol]) -> tuple[sp.Expr, sp.Expr]:
    """a = k * a' with k free of dynamic parameters (numbers, known symbols) and a' expanded, not all of its terms
    negative (I2x - I2y - m2*d2^2 stays as it is, -2*m2*d2 becomes m2*d2 with k = -2)."""
    f = sp.factor_terms(a)
    k, rest = f.as_independent(*dyn, as_Add=False)
    rest = sp.expand(rest)
    if all(t.could_extract_minus_sign() for t in sp.Add.make_args(rest)):
        k, rest = -k, -rest
    return k, compact(rest, dyn)


def compact(e: sp.Expr, dyn: list[sp.Symbol]) -> sp.Expr:
    """The expanded coefficient, or its terms collected on the most frequent parameters (coefficients factored)
    when that is clearly shorter: m2*(l2 + rc2x) rather than l2*m2 + m2*rc2x."""
    if not e.is_Add:
        return e
    terms = sp.Add.make_args(e)
    syms = sorted((s for s in dyn if e.has(s)), key=lambda s: (-sum(1 for t in terms if t.has(s)), str(s)))
    best, ops = e, count_ops(e)
    for cand in (sp.factor_terms(e), sp.collect(e, syms, func=sp.factor)):
        n = count_ops(cand)
        if n < ops:
            best, ops = cand, n
    return best


# ------------------------------------------------------------------------------------------------ solver
@dataclass
class Parametrization:
    Y: sp.Matrix
    a: sp.Matrix
    p: int
    p_min: int
    exp: Expansion
    dyn: list[sp.Symbol]
    pivots: list[tuple[int, sp.Expr] | None] = field(default_factory=list)  # auto: pivot term of each a_i
    treated: list[sp.Symbol] = field(default_factory=list)    # known symbols treated as parameters (given a)
    coeff_relations: list[sp.Expr] = field(default_factory=list)  # Σ w_i a_i = 0 over the constants
    column_relations: list[sp.Expr] = field(default_factory=list)  # Σ v_i y_i = 0


class ParamError(Exception):
    def __init__(self, message: str, index: int | None = None, hint: str | None = None) -> None:
        super().__init__(message)
        self.message, self.index, self.hint = message, index, hint


def _state(robot) -> tuple[set, list[sp.Symbol]]:  # type: ignore[no-untyped-def]
    return set(robot.q) | set(robot.dq) | set(robot.ddq), list(robot.ddq) + list(robot.dq)


def _expand_or_fail(vec: sp.Matrix, state: set, dyn: set) -> Expansion:
    try:
        return expand_model(vec, state, dyn)
    except _NotPolynomial as exc:
        bad = sorted(exc.factor.free_symbols & dyn, key=str)
        names = ", ".join(str(s) for s in bad)
        raise ParamError(f"the model is not polynomial in the dynamic parameters: {names} appears {exc.reason} "
                         f"({exc.factor})", None,
                         f"add {names} to known: if it is kinematic data (then it may appear inside Y)") from None


def _Y_from(exp: Expansion, L: sp.Matrix, atoms: list, n: int) -> sp.Matrix:
    Y = sp.zeros(n, L.cols)
    for r, (k, f) in enumerate(atoms):
        for i in range(L.cols):
            if L[r, i] != 0:
                Y[k, i] += f * L[r, i]
    return Y


def compute_auto(vec: sp.Matrix, robot, dyn_all: list[sp.Symbol]) -> Parametrization:  # type: ignore[no-untyped-def]
    state, _ = _state(robot)
    dyn = set(dyn_all)
    exp = _expand_or_fail(vec, state, dyn)
    if sp.Integer(1) in exp.monos:
        terms = [f * exp.C[(k, f)][sp.Integer(1)] for (k, f) in exp.atoms if sp.Integer(1) in exp.C[(k, f)]]
        raise ParamError(f"the model has terms without dynamic parameters ({terms[0]}), which no Y a can give",
                         None, "take the symbols of that term out of known:, or give coefficients: with a "
                               "coefficient 1")
    atoms, monos = exp.atoms, exp.monos
    C = exp.matrix(atoms, monos)
    gen = Generic()
    P = independent_rows(C, gen, atom_order(atoms, robot))
    p = len(P)
    R = C.extract(P, list(range(len(monos))))
    J = independent_rows(R.T, gen)
    Rinv = exact_inverse(R.extract(list(range(p)), J))
    L = (C.extract(list(range(len(atoms))), J) * Rinv).applyfunc(sp.cancel)
    a_list, pivots = [], []
    for i, r in enumerate(P):
        raw = sum((R[i, j] * monos[j] for j in range(len(monos))), sp.Integer(0))
        k, a = normalize(raw, dyn_all)
        a_list.append(a)
        L[:, i] = (L[:, i] * k).applyfunc(sp.cancel)
        pivots.append((atoms[r][0], atoms[r][1] * raw))
    Y = _Y_from(exp, L, atoms, len(vec))
    return Parametrization(Y, sp.Matrix(a_list), p, p, exp, list(dyn_all), pivots)


def _insufficient(exp: Expansion, monos: list, bad: list[int], rows0: list[dict], n: int) -> ParamError:
    m = monos[bad[0]]
    phi = exp.phi(m, n)
    k = next((k for k in range(n) if phi[k] != 0), None)
    where = f"; in the model it multiplies {tidy(phi[k])} in equation {k + 1}" if k is not None else \
        " (it does not appear in the model)"
    involved = [i for i, r in enumerate(rows0) if m in r]
    return ParamError(
        "the coefficients cannot express the model: no Y(q, dq, ddq) gives Y a = model for the terms in "
        f"{', '.join(str(monos[j]) for j in bad[:4])}{where}",
        involved[0] if involved else None,
        "a product of parameters that multiplies a different function needs its own coefficient (or belongs "
        "to another group)")


def _constant_coefficients(coeffs: list[sp.Expr], state: set) -> None:
    for i, a in enumerate(coeffs):
        if a.free_symbols & state:
            bad = ", ".join(sorted(str(s) for s in a.free_symbols & state))
            raise ParamError(f"coefficient {i + 1} depends on the state ({bad}): a_i must be constants",
                             i, "move the functions of q, dq, ddq into Y (robosolve computes it)")


def _coefficient_rows(coeffs: list[sp.Expr], dyn: set) -> list[dict]:
    """Each coefficient as {monomial of the dynamic parameters: its constant factor}."""
    rows = []
    for i, a in enumerate(coeffs):
        try:
            rows.append(expand_coefficient(a, dyn))
        except _NotPolynomial as exc:
            raise ParamError(f"coefficient {i + 1} is not a polynomial in the dynamic parameters "
                             f"({exc.factor} {exc.reason})", i) from None
    return rows


def _nonzero_coefficients(rows: list[dict]) -> None:
    for i, r in enumerate(rows):
        if not r:
            raise ParamError(f"coefficient {i + 1} is zero", i)


def _dependent(A: sp.Matrix, indep: list[int], names: list[sp.Symbol]) -> ParamError:
    """The error for coefficients (the rows of A) that are not linearly independent: the first dependent one and
    its relation with the previous ones."""
    first = next(i for i in range(A.rows) if i not in indep)
    rel = relations(A.extract(list(range(first + 1)), list(range(A.cols))).T, names[:first + 1])
    shown = f" ({rel[0].xreplace({nm: sp.Symbol(f'a{i + 1}') for i, nm in enumerate(names)})} = 0)" \
        if rel else ""
    return ParamError(f"the coefficients are not linearly independent: coefficient {first + 1} is a "
                      f"combination of the previous ones{shown}, so Y is not determined", first,
                      "remove it, or merge it with the others")


def _coefficient_matrix(rows: list[dict], monos: list) -> sp.Matrix:
    return sp.Matrix(len(rows), len(monos), lambda i, j: rows[i].get(monos[j], sp.Integer(0)))


def check_given(robot, dyn_all: list[sp.Symbol], coeffs: list[sp.Expr], known: list[sp.Symbol]) -> None:  # type: ignore[no-untyped-def]
    """The checks of :func:`compute_given` that need no model (validation): constant, polynomial, non-zero and
    linearly independent coefficients (ParamError as there). Coefficients dependent over the constants but
    independent once their known symbols are taken as parameters are accepted (the model decides)."""
    state, _ = _state(robot)
    _constant_coefficients(coeffs, state)
    rows = _coefficient_rows(coeffs, set(dyn_all))
    _nonzero_coefficients(rows)
    gen = Generic()
    A = _coefficient_matrix(rows, list(dict.fromkeys(m for r in rows for m in r)))
    indep = independent_rows(A, gen)
    if len(indep) == len(coeffs):
        return
    extra = sorted({s for a in coeffs for s in a.free_symbols if s in set(known)}, key=str)
    if extra:
        try:
            rows1 = _coefficient_rows(coeffs, set(dyn_all) | set(extra))
            if len(independent_rows(_coefficient_matrix(rows1, list(dict.fromkeys(m for r in rows1 for m in r))),
                                    gen)) == len(coeffs):
                return
        except ParamError:
            pass
    raise _dependent(A, indep, [sp.Symbol(f"_a{i + 1}") for i in range(len(coeffs))])


def compute_given(vec: sp.Matrix, robot, dyn_all: list[sp.Symbol], coeffs: list[sp.Expr],  # type: ignore[no-untyped-def]
                  known: list[sp.Symbol]) -> Parametrization:
    """Y for the given coefficients (see the module doc)."""
    state, _ = _state(robot)
    n, p = len(vec), len(coeffs)
    _constant_coefficients(coeffs, state)
    gen = Generic()

    def setup(dyn: set) -> tuple[Expansion, list[dict], list, sp.Matrix, sp.Matrix]:
        exp = _expand_or_fail(vec, state, dyn)
        rows = _coefficient_rows(coeffs, dyn)
        monos = list(dict.fromkeys(list(exp.monos) + [m for r in rows for m in r]))
        return exp, rows, monos, _coefficient_matrix(rows, monos), exp.matrix(exp.atoms, monos)

    exp, rows0, monos, A, C = setup(set(dyn_all))
    atoms = exp.atoms
    p_min = generic_rank(exp.matrix(atoms, exp.monos), gen) if atoms else 0
    _nonzero_coefficients(rows0)
    names = [sp.Symbol(f"_a{i + 1}") for i in range(p)]
    indep = independent_rows(A, gen)
    treated: list[sp.Symbol] = []
    coeff_rel: list[sp.Expr] = []
    structural = None
    if len(indep) < p:
        # dependent over the constants: are they independent when the known symbols they contain are parameters?
        extra = sorted({s for a in coeffs for s in a.free_symbols if s in set(known)}, key=str)
        ok = False
        if extra:
            try:
                exp1, _, monos1, A1, _ = setup(set(dyn_all) | set(extra))
                ok = len(independent_rows(A1, gen)) == p
            except ParamError:
                ok = False
        if not ok:
            raise _dependent(A, indep, names)
        treated, coeff_rel = extra, relations(A.T, names)
        J1 = independent_rows(A1.T, gen)
        structural = (exp1, monos1, A1, J1, exact_inverse(A1.extract(list(range(p)), J1)))
    # the rows solved over the constants: the first independent coefficients (all of them when independent)
    S = indep
    J = independent_rows(A.extract(S, list(range(A.cols))).T, gen)
    Ainv = exact_inverse(A.extract(S, J))
    L = sp.zeros(len(atoms), p)
    bad: set[int] = set()
    for r, atom in enumerate(atoms):
        if structural is not None:
            exp1, monos1, A1, J1, A1inv = structural
            row1 = sp.Matrix([[exp1.C.get(atom, {}).get(m, sp.Integer(0)) for m in monos1]])
            sol = (row1.extract([0], J1) * A1inv).applyfunc(sp.cancel)
            if all(_zero_exact(x) for x in row1 - sol * A1):
                L[r, :] = sol
                continue
        sol = (C.extract([r], J) * Ainv).applyfunc(sp.cancel)
        for t, i in enumerate(S):
            L[r, i] = sol[t]
        res = C.row(r) - L.row(r) * A
        bad |= {j for j in range(len(monos)) if not _zero_exact(res[j])}
    if bad:
        raise _insufficient(exp, monos, sorted(bad), rows0, n)
    Y = _Y_from(exp, L, atoms, n)
    col_rel: list[sp.Expr] = []
    if generic_rank(L, gen) < p:
        col_rel = relations(L, [sp.Symbol(f"_y{i + 1}") for i in range(p)])
    return Parametrization(Y, sp.Matrix(coeffs), p, p_min, exp, list(dyn_all), [None] * p, treated,
                           coeff_rel, col_rel)


def model_vector(dm, robot, part: str) -> sp.Matrix:  # type: ignore[no-untyped-def]
    if part == "inertia":
        return (dm.B * sp.Matrix(robot.ddq)).applyfunc(sp.expand)
    if part == "gravity":
        return dm.g
    return dm.lhs


def check(Y: sp.Matrix, a: sp.Matrix, vec: sp.Matrix) -> bool:
    """Y a ≡ model, exactly (canonical trigonometric form; randomized exact evaluation as a fallback)."""
    d = (Y * a - vec).applyfunc(sp.expand)
    for x in d:
        z = is_zero(x)
        if z is None:
            z = equivalent(x, sp.Integer(0), "scalar").ok
        if not z:
            return False
    return True


def split_products(pairs: list[tuple[sp.Expr, sp.Expr]], most: int = 3) -> list[sp.Expr]:
    """Terms c*f of a sum, with c*(f1 + f2 + ...) written as c*f1 + c*f2 + ... when f has more than ``most``
    terms (so that a LaTeX display can break the line inside it)."""
    out = []
    for c, f in pairs:
        parts = sp.Add.make_args(f)
        out += [c * t for t in parts] if len(parts) > most else [c * f]
    return out


# ------------------------------------------------------------------------------------------------ ask
def _symbol_name(problem, options: LinearParametrizationAsk) -> str:  # type: ignore[no-untyped-def]
    if options.symbol:
        return options.symbol
    import re
    clash = any(re.fullmatch(r"a_?\d+", name) for name in problem.names)
    return "pi" if clash else "a"


def _coefficient_place(problem, ctx, index: int | None) -> Any:  # type: ignore[no-untyped-def]
    return problem.located.place(ctx.path + ("coefficients",) + ((index,) if index is not None else ()))


def _given_coefficients(problem, options: LinearParametrizationAsk, ctx) -> list[sp.Expr] | None:  # type: ignore[no-untyped-def]
    """The ask's coefficients: (a list of expressions), or None."""
    if options.coefficients is None:
        return None
    val = ctx.expr("coefficients")
    if not isinstance(val, list):
        val = [val]
    if len(shape_of(val)) != 1:
        raise UserError("coefficients must be a list of expressions [a1, a2, ...]", _coefficient_place(problem, ctx, None),
                        "write e.g. [I1 + m1*d1^2, m2, m1*d1 + m2*l1]")
    return [sp.sympify(v) for v in val]


def validate_linear_parametrization(problem, options: LinearParametrizationAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_linear_parametrization` reads them, without the model:
    a robot with dynamics, and given coefficients that are constant, polynomial in the dynamic parameters,
    non-zero and linearly independent (whether they express the model needs the model: left to solving)."""
    robot = require_model(problem)
    coeffs = _given_coefficients(problem, options, ctx)
    if coeffs is None:
        return
    known = list(problem.known)
    dyn = [s for s in problem.symbols.values() if s not in set(known)]
    try:
        check_given(robot, dyn, coeffs, known)
    except ParamError as exc:
        raise UserError(exc.message, _coefficient_place(problem, ctx, exc.index), exc.hint) from None


@ask_kind("linear_parametrization", LinearParametrizationAsk,
          "linear parametrization Y(q, dq, ddq) a of the dynamic model in a minimal set of dynamic coefficients",
          validate=validate_linear_parametrization)
def solve_linear_parametrization(problem, options: LinearParametrizationAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results (with the ask's suffix): Y, a, p, Ya_check, p_min, minimal."""
    robot = require_model(problem)
    dm = derive(robot)
    vec = model_vector(dm, robot, options.part)
    state, rate = _state(robot)
    known = list(problem.known)
    dyn = [s for s in problem.symbols.values() if s not in set(known)]
    sfx = options.suffix
    sym = _symbol_name(problem, options)

    def place(index: int | None) -> Any:
        return _coefficient_place(problem, ctx, index)

    if all(x == 0 for x in vec):
        raise UserError(f"the {options.part} term is identically zero: nothing to parametrize",
                        problem.located.place(ctx.path))
    coeffs = _given_coefficients(problem, options, ctx)
    try:
        if coeffs is None:
            par = compute_auto(vec, robot, dyn)
        else:
            par = compute_given(vec, robot, dyn, coeffs, known)
    except ParamError as exc:
        hint = exc.hint
        if coeffs is not None and "cannot express" in exc.message:
            try:
                auto = compute_auto(vec, robot, dyn)
                hint = (hint or "") + "; a minimal set is [" + ", ".join(str(x) for x in auto.a) + "]"
            except ParamError:
                pass
        raise UserError(exc.message, place(exc.index) if coeffs is not None else problem.located.place(ctx.path),
                        hint) from None

    Y = par.Y.applyfunc(lambda e: readable(e, state, rate))
    a = par.a
    ok = check(Y, a, vec)
    asyms = [sp.Symbol(f"{sym}_{i + 1}") for i in range(par.p)]
    label_args = {"model": "q,\\dot q,\\ddot q", "inertia": "q,\\ddot q", "gravity": "q"}[options.part]
    sol = Solution("linear_parametrization", title=options.title or "Linear parametrization of the dynamic model")
    sol.add("Y" + sfx, Y, "matrix", label=f"Y({label_args})")
    sol.add("a" + sfx, a, "vector", label="a")
    sol.add("p" + sfx, sp.Integer(par.p), "number", label="p")
    sol.add("Ya_check" + sfx, bool(ok), "bool", label=f"Y a \\equiv {PARTS[options.part]}")
    sol.add("p_min" + sfx, sp.Integer(par.p_min), "number", label="p_{\\min}")
    sol.add("minimal" + sfx, bool(par.p == par.p_min), "bool", label="\\text{minimal}")

    # explanation data
    n = len(vec)
    monos = par.exp.monos
    phis = {m: par.exp.phi(m, n) for m in monos}
    rows = [[(m, readable(phis[m][k], state, rate)) for m in monos if phis[m][k] != 0] for k in range(n)]
    used = set().union(*[x.free_symbols for x in vec]) | set().union(*[x.free_symbols for x in a])
    sol.step("model", part=options.part, lhs=PARTS[options.part], rows=[[m * f for m, f in r] for r in rows],
             rows_split=[split_products(r) for r in rows], dyn=[s for s in par.dyn
             if any(m.has(s) for m in monos)], known=[s for s in known if s in used], monos=monos, n=n,
             unused=[s for s in par.dyn if not any(m.has(s) for m in monos)])
    groups = []
    for i in range(par.p):
        piv = par.pivots[i] if i < len(par.pivots) else None
        groups.append({"sym": asyms[i], "value": a[i], "equation": piv[0] + 1 if piv else None,
                       "term": readable(piv[1], state, rate) if piv else None})
    sol.step("grouping", given=coeffs is not None, groups=groups, p=par.p, treated=par.treated)
    asv = sp.Matrix(asyms)
    Ya = Y * asv
    pairs_a = [[(asyms[i], Y[k, i]) for i in range(par.p) if Y[k, i] != 0] for k in range(n)]
    rows_a = [[c * f for c, f in r] for r in pairs_a]
    B_a = c_a = g_a = None
    if options.part == "model":
        full = (par.Y * asv).applyfunc(sp.expand)
        parts = [split_rates(e, list(robot.ddq), list(robot.dq)) for e in full]
        if all(x is not None for x in parts):
            B_a = sp.Matrix([[readable(e, state, rate) for e in x[0]] for x in parts])
            g_a = sp.Matrix([readable(x[2], state, rate) for x in parts])
            c_a = sp.Matrix([readable(x[1], state, rate) for x in parts])
        else:
            B_a = full.jacobian(robot.ddq).applyfunc(lambda e: readable(e, state, rate))
            rest = (full - full.jacobian(robot.ddq) * sp.Matrix(robot.ddq)).applyfunc(sp.expand)
            g0 = rest.subs({v: 0 for v in robot.dq})
            g_a = g0.applyfunc(lambda e: readable(e, state, rate))
            c_a = (rest - g0).applyfunc(lambda e: readable(e, state, rate))
    sol.step("regressor", Y=Y, a=a, asyms=asv, sym=sym, rows_a=rows_a, rows_a_split=[split_products(r) for r in pairs_a],
             part=options.part, label=label_args,
             B_a=B_a, c_a=c_a if c_a is not None and any(x != 0 for x in c_a) else None,
             g_a=g_a if g_a is not None and any(x != 0 for x in g_a) else None, Ya=Ya,
             friction=dm.Fv is not None, sym_tex=sp.latex(sp.Symbol(sym)))
    minimal_set = None
    if par.p != par.p_min:
        try:
            minimal_set = compute_auto(vec, robot, dyn).a
        except ParamError:
            minimal_set = None
    ysyms = [sp.Symbol(f"y_{i + 1}") for i in range(par.p)]
    sub_a = {sp.Symbol(f"_a{i + 1}"): asyms[i] for i in range(par.p)}
    sub_y = {sp.Symbol(f"_y{i + 1}"): ysyms[i] for i in range(par.p)}
    sol.step("check", ok=ok, p=par.p, p_min=par.p_min, minimal=par.p == par.p_min, given=coeffs is not None,
             treated=par.treated, coeff_relations=[r.xreplace(sub_a) for r in par.coeff_relations],
             column_relations=[r.xreplace(sub_y) for r in par.column_relations], lhs=PARTS[options.part],
             minimal_set=minimal_set, sym_tex=sp.latex(sp.Symbol(sym)))
    return sol


# ------------------------------------------------------------------------------------------------ grading
@property_check("Y", "a")
def check_parametrization(problem, results, name, value, other, options) -> PropertyVerdict | None:  # type: ignore[no-untyped-def]
    """(Y, a) answered together: Y a ≡ the reference Y a, a free of q, q̇, q̈, Y free of the dynamic parameters
    (symbols not in known:), and no more coefficients than the minimum; any grouping is accepted."""
    from solver.math.equivalence import scalar_equiv
    if not {"Y", "a"} <= set(results):
        return None
    partner = other("a" if name == "Y" else "Y")
    if partner is None:
        return None
    Y_raw, a_raw = (value, partner) if name == "Y" else (partner, value)
    try:
        Y = sp.Matrix(Y_raw) if isinstance(Y_raw, list) else sp.Matrix([[Y_raw]])
        a = sp.Matrix(a_raw) if isinstance(a_raw, list) else sp.Matrix([a_raw])
    except (ValueError, TypeError, sp.ShapeError):
        return None
    if a.cols != 1 and a.rows == 1:
        a = a.T
    Y_ref, a_ref = results["Y"].value, results["a"].value
    if Y_ref.rows == 1 and Y.shape == (Y_ref.cols, 1):
        Y = Y.T
    if Y.rows != Y_ref.rows or Y.cols != a.rows:
        return PropertyVerdict(False, 0.0, [f"Y is {Y.rows}x{Y.cols} and a has {a.rows} entries: Y a is not defined "
                                            f"or has the wrong size (the model has {Y_ref.rows} equations)"])
    robot = problem.robot
    state = set(robot.q) | set(robot.dq) | set(robot.ddq) if robot else set()
    dynamic = set(problem.symbols.values()) - set(problem.known)
    if any(x.free_symbols & state for x in a):
        return PropertyVerdict(False, 0.0, ["the coefficients a must not depend on q, q̇, q̈"])
    if any(x.free_symbols & dynamic for x in Y):
        return PropertyVerdict(False, 0.0, ["Y must not contain dynamic parameters (masses, inertias, CoM "
                                            "positions): move them to a"])
    wrong = [str(i + 1) for i, (x, y) in enumerate(zip(Y * a, Y_ref * a_ref)) if not scalar_equiv(x, y).ok]
    if wrong:
        return PropertyVerdict(False, 0.0, ["Y a differs from the dynamic model in equation(s) " + ", ".join(wrong)])
    p_min = results.get("p_min")
    p = int(p_min.value) if p_min is not None and getattr(p_min.value, "is_Integer", False) else a_ref.rows
    if a.rows > p:
        return PropertyVerdict(False, 0.5, [f"Y a = model holds, but with {a.rows} coefficients: {p} are enough "
                                            "(not minimal)"])
    return PropertyVerdict(True, 1.0, [f"valid minimal parametrization: Y a = model with {a.rows} coefficients"])
