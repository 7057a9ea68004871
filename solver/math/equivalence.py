"""Mathematical equivalence of answers: exact where possible, never a silent false verdict.

Scalars, in order:

1. exact randomized zero-testing of d = a - b: every parameter gets a random rational value and every angle x a
   random rational t = tan(x/2), so that cos x = (1 - t²)/(1 + t²) and sin x = 2t/(1 + t²) are rational and trig
   identities hold exactly; d is evaluated in exact rational arithmetic (sin/cos of k·x through (cos + i sin)^k).
   A non-zero value proves a ≢ b; zero at several independent points means a ≡ b (Schwartz-Zippel: a non-zero
   rational function vanishes at a random point of a large grid with negligible probability). An angle that also
   appears outside sin/cos (α(q₃ − q₃,fin) beside cos q₃) gets there an independent random value: x is
   transcendental over the trigonometric functions of x (a periodic function's algebraic conjugates of x would
   include every x + 2πk), so an identity in (x, cos x, sin x) holds for independent values and the test stays exact;
2. where (1) does not apply (radicals, exp, other constants): the
   canonical Fourier form of :mod:`solver.math.simplify`, then 30-digit evaluation at random points;
3. otherwise ``undecided``, never a guess.

Matrices entry by entry, lists item by item, sets of configurations up to order and to 2π in the angles,
conditions (lists of expressions, each meaning ``expr > 0``) as sets after removing positive factors.
"""
from __future__ import annotations

import itertools
import random
from dataclasses import dataclass, field
from fractions import Fraction
from functools import lru_cache
from typing import Any, Callable, Iterable, Iterator

import sympy as sp

from solver.math.fourier import NotTrigPolynomial, factor_list_expr, factor_small, split_angle
from solver.math.simplify import angle_symbols, is_zero, zero_or_simplified

CORRECT, INCORRECT, UNDECIDED = "correct", "incorrect", "undecided"
SEED = 2024  # every random point derives from it (symbols taken in name order): a run is reproducible


@dataclass
class Verdict:
    verdict: str
    detail: str = ""
    wrong: list[Any] = field(default_factory=list)  # indices of wrong entries

    @property
    def ok(self) -> bool:
        return self.verdict == CORRECT


def _by_name(symbols: set[sp.Symbol]) -> list[sp.Symbol]:
    """Symbols in a fixed order (set order follows string hashing, which changes from run to run)."""
    return sorted(symbols, key=lambda s: (s.name, str(s.assumptions0)))


def random_point(symbols: set[sp.Symbol], rng: random.Random) -> dict[sp.Symbol, sp.Expr]:
    point = {}
    for s in _by_name(symbols):
        lo = 0 if (s.is_positive or s.is_nonnegative) else -3
        point[s] = sp.Rational(rng.randint(lo * 1000 + 1 if lo else 137, 3000), 997)
    return point


def real_value(expr: sp.Expr, point: dict[sp.Symbol, sp.Expr]) -> complex | None:
    """expr at ``point`` to 30 digits; None where it is undefined or not real (the point is outside the domain
    where the expression exists, e.g. acos of a number > 1)."""
    try:
        val = sp.N(expr.xreplace(point), 30)  # xreplace: symbols -> numbers, far cheaper than subs on large sums
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    if val.has(sp.nan, sp.zoo, sp.oo) or not val.is_number:
        return None
    z = complex(val)
    return z if abs(z.imag) <= 1e-20 * max(1.0, abs(z.real)) else None


def numeric_zero(expr: sp.Expr, trials: int = 6, seed: int | None = None,
                 parts: tuple[sp.Expr, ...] = ()) -> bool | None:
    """Is ``expr`` zero at random rational points (30 digits)? Points where ``expr`` or one of ``parts`` (the
    compared results) is undefined or not real are skipped: results are compared where they exist. None when no
    point of up to 5·trials draws is usable."""
    rng = random.Random(SEED if seed is None else seed)
    syms = expr.free_symbols.union(*(p.free_symbols for p in parts))
    seen = 0
    for _ in range(trials * 5):
        point = random_point(syms, rng)
        if any(real_value(p, point) is None for p in parts):
            continue
        val = real_value(expr, point)
        if val is None:
            continue
        seen += 1
        if abs(val) > 1e-20:
            return False
        if seen == trials:
            break
    return True if seen else None


def identically_zero(x: sp.Expr) -> bool:
    """x ≡ 0, for the checks of a derivation (closed loops, Lyapunov derivatives, residuals): the randomized exact
    test where x has no floats (a proof when it finds a non-zero value; Schwartz-Zippel otherwise), else the
    canonical trigonometric form, else sympy's simplify (hyperbolic functions rewritten as exponentials)."""
    x = sp.sympify(x)
    if x == 0:
        return True
    if not x.atoms(sp.Float):
        z = exact_zero(x)
        if z is not None:
            return z
    x = sp.expand(x)
    if x.has(sp.tanh, sp.sinh, sp.cosh, sp.log):   # outside the trigonometric canonical form
        return sp.simplify(x.rewrite(sp.exp)) == 0
    return zero_or_simplified(x)


class NotRational(Exception):
    """The expression cannot be evaluated exactly in rational arithmetic."""


Complex = tuple[Fraction, Fraction]
MAX_BITS = 200_000  # larger exact values are not computed (a tower of powers would take minutes)


def _cmul(a: Complex, b: Complex) -> Complex:
    return (a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0])


def _cpow(z: Complex, k: int) -> Complex:
    if k < 0:
        n = z[0] * z[0] + z[1] * z[1]
        z, k = (z[0] / n, -z[1] / n), -k
    out: Complex = (Fraction(1), Fraction(0))
    while k:
        if k & 1:
            out = _cmul(out, z)
        z, k = _cmul(z, z), k >> 1
    return out


class RationalPoint:
    """Exact evaluation at one point: parameters -> rationals, angles -> e^{ix} from t = tan(x/2)."""

    def __init__(self, params: dict[sp.Symbol, Fraction], angles: dict[sp.Symbol, Fraction]) -> None:
        self.params = params
        self.unit_c = {x: ((1 - t * t) / (1 + t * t), 2 * t / (1 + t * t)) for x, t in angles.items()}  # (cos, sin)
        self.angles = list(angles)
        self.index = {x: j for j, x in enumerate(self.angles)}
        self.memo: dict[sp.Expr, Fraction] = {}

    def phase(self, arg: sp.Expr) -> Complex:
        """e^{i·arg} for arg = Σ k_j x_j + r·π with integer k_j and 2r integer."""
        try:
            k, quarter = split_angle(arg, self.index)
        except NotTrigPolynomial:
            raise NotRational(arg) from None
        z: Complex = _cpow((Fraction(0), Fraction(1)), quarter % 4)  # i^quarter = e^{i·quarter·π/2}
        for x, kx in zip(self.angles, k):
            if kx:
                z = _cmul(z, _cpow(self.unit_c[x], kx))
        return z

    def value(self, e: sp.Expr) -> Fraction:
        hit = self.memo.get(e)
        if hit is not None:
            return hit
        if e.is_Rational:
            out = Fraction(int(e.p), int(e.q))
        elif e.is_Symbol:
            if e not in self.params:
                raise NotRational(e)
            out = self.params[e]
        elif e.is_Add:
            out = sum((self.value(a) for a in e.args), Fraction(0))
        elif e.is_Mul:
            out = Fraction(1)
            for a in e.args:
                out *= self.value(a)
                if out.numerator.bit_length() + out.denominator.bit_length() > MAX_BITS:
                    raise NotRational(e)
        elif e.is_Pow and e.exp.is_Integer:
            base = self.value(e.base)
            if abs(int(e.exp)) * max(base.numerator.bit_length(), base.denominator.bit_length()) > MAX_BITS:
                raise NotRational(e)  # a tower of powers: too large to evaluate exactly
            out = base ** int(e.exp)
        elif isinstance(e, (sp.sin, sp.cos, sp.tan, sp.cot)):
            c, s = self.phase(e.args[0])
            out = {sp.sin: s, sp.cos: c}.get(type(e)) if isinstance(e, (sp.sin, sp.cos)) else \
                (s / c if isinstance(e, sp.tan) else c / s)
        else:
            raise NotRational(e)
        self.memo[e] = out
        return out


def _random_rational(rng: random.Random, positive: bool) -> Fraction:
    v = Fraction(rng.randint(1, 10**6), rng.randint(1, 10**4) * 97 + 1)
    return v if positive or rng.random() < 0.5 else -v


def _bare_symbols(expr: sp.Expr) -> set[sp.Symbol]:
    """Symbols of ``expr`` that occur outside the arguments of sin, cos, tan, cot."""
    if expr.is_Symbol:
        return {expr}
    if isinstance(expr, (sp.sin, sp.cos, sp.tan, sp.cot)):
        return set()
    out: set[sp.Symbol] = set()
    for a in expr.args:
        out |= _bare_symbols(a)
    return out


def random_points(exprs: list[sp.Expr], seed: int | None = None) -> Iterator[RationalPoint]:
    """Random points (an endless supply) where every expression of ``exprs`` can be evaluated exactly: each
    parameter a random rational (positive where it is declared so), each angle a random rational tangent of its
    half, an angle also outside sin/cos an independent rational there (see the module doc)."""
    angles = _by_name(set().union(*(angle_symbols(e) for e in exprs)))
    params = _by_name(set().union(*(e.free_symbols for e in exprs)) - set(angles))
    bare = _by_name(set().union(*(_bare_symbols(e) for e in exprs)) & set(angles))
    rng = random.Random(SEED if seed is None else seed)
    while True:
        values = {s: _random_rational(rng, bool(s.is_positive or s.is_nonnegative)) for s in params}
        trig = {x: _random_rational(rng, False) for x in angles}
        values.update({x: _random_rational(rng, False) for x in bare})
        yield RationalPoint(values, trig)


def exact_test(residuals: Callable[[RationalPoint], Iterable[Any]], exprs: list[sp.Expr], trials: int = 3,
               seed: int | None = None) -> bool | None:
    """The randomized exact test of any identity: ``residuals(point)`` (exact values at one point of
    :func:`random_points` of ``exprs``) all zero at ``trials`` points -> True, one non-zero -> False (a proof),
    None when a value is not rational (NotRational); a point where an evaluation divides by zero (a pole, a
    singular matrix) is skipped, up to 3·trials draws."""
    done = 0
    for point in itertools.islice(random_points(exprs, seed), trials * 3):
        try:
            values = list(residuals(point))
        except ZeroDivisionError:
            continue  # a pole: try another point
        except NotRational:
            return None
        if any(v != 0 for v in values):
            return False
        done += 1
        if done == trials:
            return True
    return None


def exact_zero(expr: sp.Expr, trials: int = 3, seed: int | None = None) -> bool | None:
    """Randomized exact zero test (see module doc): True (zero at every point), False (a point where it is
    provably non-zero), None (not evaluable in rational arithmetic)."""
    return exact_test(lambda point: [point.value(expr)], [expr], trials, seed)


def scalar_equiv(a: sp.Expr, b: sp.Expr, rel_tol: float | None = None, abs_tol: float = 0.0) -> Verdict:
    """Is a ≡ b? Numbers compare within tolerances when given; expressions exactly or by 30-digit sampling."""
    a, b = sp.sympify(a), sp.sympify(b)
    if a.is_number and b.is_number and (rel_tol is not None or abs_tol):
        da, db = complex(sp.N(a)), complex(sp.N(b))
        ok = abs(da - db) <= max(abs_tol, (rel_tol or 0.0) * abs(db))
        return Verdict(CORRECT if ok else INCORRECT, "" if ok else f"{da.real:.6g} vs {db.real:.6g}")
    diff = a - b
    if not diff.atoms(sp.Float):
        z0 = exact_zero(diff)
        if z0 is not None:
            return Verdict(CORRECT if z0 else INCORRECT)
    z = is_zero(diff)
    if z is True:
        return Verdict(CORRECT)
    if z is False and not diff.atoms(sp.Float):
        return Verdict(INCORRECT)
    nz = numeric_zero(diff, parts=(a, b))
    if nz is True:
        return Verdict(CORRECT, "numerically")
    if nz is False:
        return Verdict(INCORRECT)
    return Verdict(UNDECIDED, "could not decide")


def matrix_equiv(a: sp.Matrix, b: sp.Matrix, **tol: Any) -> Verdict:
    """Entry-by-entry equivalence after a shape check; ``wrong`` lists the (i, j) that differ (1-based)."""
    if a.shape != b.shape:
        return Verdict(INCORRECT, f"shape {a.shape[0]}x{a.shape[1]}, expected {b.shape[0]}x{b.shape[1]}")
    wrong, undecided = [], []
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            v = scalar_equiv(a[i, j], b[i, j], **tol)
            if v.verdict == INCORRECT:
                wrong.append((i + 1, j + 1))
            elif v.verdict == UNDECIDED:
                undecided.append((i + 1, j + 1))
    if wrong:
        return Verdict(INCORRECT, "entries " + ", ".join(f"({i},{j})" for i, j in wrong) + " differ", wrong)
    if undecided:
        return Verdict(UNDECIDED, "entries " + ", ".join(f"({i},{j})" for i, j in undecided) + " undecided")
    return Verdict(CORRECT)


def _angle_equal(a: sp.Expr, b: sp.Expr) -> bool:
    """a ≡ b modulo 2π: equal, or with equal cosine and sine (compared where both angles exist)."""
    if scalar_equiv(a, b).ok:
        return True
    if a.is_number and b.is_number:
        k = float(sp.N(a - b)) / (2 * float(sp.pi))
        return abs(k - round(k)) < 1e-9
    try:
        return scalar_equiv(sp.cos(a), sp.cos(b)).ok and scalar_equiv(sp.sin(a), sp.sin(b)).ok
    except sp.PolynomialError:  # not an angle (e.g. a speed u/(3 d) in a set of steady velocities): unequal
        return False


def set_equiv(got: list[sp.Matrix], want: list[sp.Matrix], angles: list[int] | None = None) -> Verdict:
    """Sets of configurations: same size, and each expected one equals a computed one (2π-periodic angles)."""
    used: set[int] = set()
    missing = []
    for w in want:
        for k, g in enumerate(got):
            if k in used or g.shape != w.shape:
                continue
            if all((_angle_equal(g[i], w[i]) if angles is None or i in angles else scalar_equiv(g[i], w[i]).ok)
                   for i in range(len(w))):
                used.add(k)
                break
        else:
            missing.append(w)
    extra = [g for k, g in enumerate(got) if k not in used]
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"{len(missing)} expected element(s) not found: {[list(m) for m in missing]}")
        if extra:
            parts.append(f"{len(extra)} unexpected element(s): {[list(m) for m in extra]}")
        return Verdict(INCORRECT, "; ".join(parts))
    return Verdict(CORRECT)


def numer_denom(expr: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """expr = n/d with n, d expanded polynomials: read from the tree and cancelled in the ring of its generators
    (:func:`ring_numer_denom`), else through sympy's field of rational functions (sfield, which expands first),
    else sympy's together/expand where neither takes it."""
    from sympy.polys.fields import sfield
    fast = ring_numer_denom(expr)
    if fast is not None:
        return fast[0].as_expr(), fast[1].as_expr()
    try:
        _, f = sfield(expr)
        return f.numer.as_expr(), f.denom.as_expr()
    except (sp.PolynomialError, ValueError, TypeError, NotImplementedError, sp.polys.polyerrors.GeneratorsNeeded):
        num, den = sp.fraction(sp.together(expr))
        return sp.expand(num), sp.expand(den)


def ring_numer_denom(expr: sp.Expr) -> tuple[Any, Any] | None:
    """numer_denom of a rational function over QQ without expanding it, as polynomials of the ring of its
    generators: n / Π bᵏ read from the tree (simplify.ring_fraction), then cancelled as sfield cancels (the same
    canonical n, d); None for anything else."""
    from solver.math.simplify import ring_fraction
    nb = ring_fraction(expr)
    if nb is None:
        return None
    n, bases = nb
    d = n.ring.one
    for b, k in bases.items():
        d *= b**k
    return n.cancel(d)


def normalize_condition(expr: sp.Expr) -> sp.Expr:
    """The condition ``expr > 0`` in a canonical form: the numerator and denominator factored, every factor known
    to be positive (from the symbols' assumptions: masses, stiffnesses, ...) and every positive number removed,
    the remaining factors multiplied (n/d > 0 iff n·d > 0). Returns 1 for a condition that always holds, -1 for
    one that never does. Memoized (the same Routh entries recur across the asks of a problem)."""
    return _normalize_condition(sp.sympify(expr))


@lru_cache(maxsize=512)
def _normalize_condition(expr: sp.Expr) -> sp.Expr:
    ring_nd = ring_numer_denom(expr)
    if ring_nd is not None:  # factored in the ring, without printing n and d and reading them back
        if not ring_nd[0]:
            return sp.Integer(-1)  # 0 > 0 never holds
        parts = [(sp.QQ.to_sympy(c), [(f.as_expr(), k) for f, k in fl])
                 for c, fl in (factor_small(x) for x in ring_nd)]
    else:
        num, den = numer_denom(expr)
        if num == 0:
            return sp.Integer(-1)
        parts = [factor_list_expr(num), factor_list_expr(den)]
    sign, kept = 1, []
    for coeff, factors in parts:
        if coeff < 0:
            sign = -sign
        for f, k in factors:
            known = _sign(f)
            if known is None:
                kept.append(f ** k)  # a factor of the denominator has the sign of the same factor in the numerator
            elif known < 0 and k % 2:
                sign = -sign
    if not kept:
        return sp.Integer(sign)
    return sign * sp.Mul(*kept)


def _sign(f: sp.Expr) -> int | None:
    """+1 / -1 when f is known to be positive / negative from its symbols' assumptions, None otherwise. A long
    sum is decided by its terms' signs alone (all of one sign in positive symbols), where sympy's assumption
    system would take long to find no more."""
    if f.is_Add and len(f.args) > 8:
        if not all(x.is_positive for x in f.free_symbols):
            return None
        signs = set()
        for t in f.args:  # monomials c·Π xᵢ^kᵢ in positive symbols have the sign of c
            c, m = t.as_coeff_Mul()
            if not all(_power_of_symbol(x) for x in sp.Mul.make_args(m)):
                return None
            signs.add(c > 0)
        return (1 if True in signs else -1) if len(signs) == 1 else None
    return 1 if f.is_positive else -1 if f.is_negative else None


def _power_of_symbol(x: sp.Expr) -> bool:
    return x.is_Symbol or (x.is_Pow and x.base.is_Symbol and x.exp.is_Integer)


def _same_polynomial(a: sp.Expr, b: sp.Expr, at: RationalPoint | None = None) -> bool:
    """a ≡ b, by expanding a - b; first, cheaply, different exact values at one rational point prove a ≢ b
    (used only where both values are rational numbers: polynomials and rational functions of the symbols).
    ``at``: the point (with its memo of values), shared by the comparisons of one set; by default one from the
    symbols of a and b (any point gives the same answer: it only proves a difference)."""
    if a == b:
        return True
    if at is None:
        at = _common_point([a, b])
    try:  # (in Fractions, read from the trees: substituting and re-evaluating the expressions costs more)
        if at.value(a) != at.value(b):
            return False
    except (NotRational, ZeroDivisionError):
        pass
    return sp.expand(a - b) == 0


def _common_point(exprs: list[sp.Expr]) -> RationalPoint:
    """The rational point x_k = (97 + 31k)/(89 + 7k) for the symbols of ``exprs`` sorted by name."""
    syms = sorted(set().union(*[e.free_symbols for e in exprs]), key=lambda x: x.name)
    return RationalPoint({x: Fraction(97 + 31 * k, 89 + 7 * k) for k, x in enumerate(syms)}, {})


def reduce_conditions(conditions: list[sp.Expr]) -> list[sp.Expr]:
    """A set of conditions c_i > 0, each normalized (:func:`normalize_condition`), without the ones that always
    hold, and without the factors of a condition that are themselves conditions of the set (positive then):
    [k_d, k_d (k_f + 1) - m k_i] -> [k_d, k_d (k_f + 1) - m k_i], [k_d, k_d·(...)] -> [k_d, (...)]. The
    comparisons share one rational point: every condition and factor is evaluated once."""
    out = [normalize_condition(c) for c in conditions]
    out = [c for c in out if c != 1]
    at = _common_point(out)
    changed = True
    while changed:
        changed = False
        for i, c in enumerate(out):
            factors = sp.Mul.make_args(c)
            if len(factors) < 2:
                continue
            keep = [f for f in factors if not any(j != i and _same_polynomial(f.as_base_exp()[0], o, at)
                                                  for j, o in enumerate(out))]
            if len(keep) < len(factors):
                out[i] = normalize_condition(sp.Mul(*keep)) if keep else sp.Integer(1)
                changed = True
        uniq: list[sp.Expr] = []
        for c in out:
            if c != 1 and not any(_same_polynomial(c, u, at) for u in uniq):
                uniq.append(c)
        out = uniq
    return out


def conditions_equiv(got: list[sp.Expr], want: list[sp.Expr]) -> Verdict:
    """Two lists of conditions c_i > 0 are the same set once reduced (:func:`reduce_conditions`): normalized,
    conditions that always hold (``k_d > 0`` for a positive symbol k_d) left out, factors that are other
    conditions of the set removed."""
    g, w = reduce_conditions(list(got)), reduce_conditions(list(want))
    used: set[int] = set()
    missing = []
    for c in w:
        k = next((k for k, x in enumerate(g) if k not in used and scalar_equiv(x, c).ok), None)
        if k is None:
            missing.append(c)
        else:
            used.add(k)
    extra = [x for k, x in enumerate(g) if k not in used]
    if missing or extra:
        parts = ([f"expected condition(s) {', '.join(f'{c} > 0' for c in missing)} not found"] if missing else []) \
            + ([f"unexpected condition(s) {', '.join(f'{c} > 0' for c in extra)}"] if extra else [])
        return Verdict(INCORRECT, "; ".join(parts))
    return Verdict(CORRECT)


def equivalent(got: Any, want: Any, kind: str, **tol: Any) -> Verdict:
    """Compare a computed value with an expected one, by result kind."""
    if kind == "conditions":
        w = list(want) if isinstance(want, (list, tuple, sp.MatrixBase)) else [want]
        return conditions_equiv(list(got), w)
    if kind == "bool":
        return Verdict(CORRECT if bool(got) == bool(want) else INCORRECT)
    if kind == "set":
        return set_equiv([sp.Matrix(g) for g in got], [sp.Matrix(w) for w in want])
    if kind == "list":
        if not isinstance(want, list) or len(want) != len(got):
            return Verdict(INCORRECT, f"{len(want) if isinstance(want, list) else 1} items, expected {len(got)}")
        for k, (g, w) in enumerate(zip(got, want), 1):
            v = equivalent(g, w, "matrix" if isinstance(g, sp.MatrixBase) else "scalar", **tol)
            if not v.ok:
                return Verdict(v.verdict, f"item {k}: {v.detail or v.verdict}")
        return Verdict(CORRECT)
    if isinstance(got, sp.MatrixBase):
        w = want if isinstance(want, sp.MatrixBase) else sp.Matrix(want)
        if got.shape[1] == 1 and w.shape == (1, got.shape[0]):
            w = w.T
        return matrix_equiv(got, w, **tol)
    if isinstance(want, (list, sp.MatrixBase)):
        return Verdict(INCORRECT, "a list/matrix where a scalar is expected")
    return scalar_equiv(got, want, **tol)
