"""Mathematical equivalence of answers: exact where possible, never a silent false verdict.

Scalars: the canonical Fourier form of a - b (exact for trigonometric polynomials, see :mod:`solver.simplify`);
otherwise a - b evaluated with 30 digits at random rational points (angles and parameters), where a verdict is
given only if every point agrees. Matrices entry by entry, lists item by item, sets of configurations up to order
and to 2π in the angles.
"""
from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from .simplify import is_zero

CORRECT, INCORRECT, UNDECIDED = "correct", "incorrect", "undecided"


@dataclass
class Verdict:
    verdict: str
    detail: str = ""
    wrong: list[Any] = field(default_factory=list)  # indices of wrong entries

    @property
    def ok(self) -> bool:
        return self.verdict == CORRECT


def _random_point(symbols: set[sp.Symbol], rng: random.Random) -> dict[sp.Symbol, sp.Expr]:
    point = {}
    for s in symbols:
        lo = 0 if (s.is_positive or s.is_nonnegative) else -3
        point[s] = sp.Rational(rng.randint(lo * 1000 + 1 if lo else 137, 3000), 997)
    return point


def numeric_zero(expr: sp.Expr, trials: int = 6, seed: int = 12345) -> bool | None:
    """Is ``expr`` zero at random rational points (30 digits)? None when evaluation fails everywhere."""
    rng = random.Random(seed)
    syms = expr.free_symbols
    seen = 0
    for _ in range(trials):
        try:
            val = sp.N(expr.subs(_random_point(syms, rng)), 30)
        except (TypeError, ValueError, ZeroDivisionError):
            continue
        if val.has(sp.nan, sp.zoo, sp.oo) or not val.is_number:
            continue
        seen += 1
        if abs(complex(val)) > 1e-20:
            return False
    return True if seen else None


def scalar_equiv(a: sp.Expr, b: sp.Expr, rel_tol: float | None = None, abs_tol: float = 0.0) -> Verdict:
    """Is a ≡ b? Numbers compare within tolerances when given; expressions exactly or by 30-digit sampling."""
    a, b = sp.sympify(a), sp.sympify(b)
    if a.is_number and b.is_number and (rel_tol is not None or abs_tol):
        da, db = complex(sp.N(a)), complex(sp.N(b))
        ok = abs(da - db) <= max(abs_tol, (rel_tol or 0.0) * abs(db))
        return Verdict(CORRECT if ok else INCORRECT, "" if ok else f"{da.real:.6g} vs {db.real:.6g}")
    diff = a - b
    z = is_zero(diff)
    if z is True:
        return Verdict(CORRECT)
    if z is False and not diff.atoms(sp.Float):
        return Verdict(INCORRECT)
    nz = numeric_zero(diff)
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
    """a ≡ b, or equal up to a multiple of 2π (numeric a - b)."""
    if scalar_equiv(a, b).ok:
        return True
    d = sp.N(a - b)
    if d.is_number:
        k = float(d) / (2 * float(sp.pi))
        return abs(k - round(k)) < 1e-9
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


def equivalent(got: Any, want: Any, kind: str, **tol: Any) -> Verdict:
    """Compare a computed value with an expected one, by result kind."""
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
