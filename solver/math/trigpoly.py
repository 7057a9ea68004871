"""Whole computations in the canonical trigonometric-polynomial form (no sympy expressions in between).

A :class:`TrigAlgebra` holds one ring of coefficients (every symbol of a problem, sorted by name) and the
angles; its elements are :data:`solver.math.fourier.TrigPoly` dicts {(k, cos|sin): coefficient}, so sums,
products and derivatives stay canonical and exact:

    ∂/∂x_j [a_k cos(k·x)] = -k_j a_k sin(k·x) + (∂a_k/∂x_j) cos(k·x),   ∂/∂x_j [b_k sin(k·x)] = k_j b_k cos(k·x) + ...

and each result is written once at the end by :meth:`TrigAlgebra.expr`, which gives exactly what
:func:`solver.math.simplify.tidy` gives for the same function (the form is canonical), with the size limits of
:func:`solver.math.simplify.fourier_expr`.
"""
from __future__ import annotations

from typing import Iterable

import sympy as sp
from sympy.polys.rings import PolyElement

from solver.math.fourier import NotTrigPolynomial, TrigPoly, _Algebra, times
from solver.math.simplify import fourier_expr, parts_by

__all__ = ["TrigAlgebra", "NotTrigPolynomial"]


def _pdiff(p, i: int):  # type: ignore[no-untyped-def]
    """∂p/∂x_i of a ring element (sympy's ``p.diff(x)`` finds i by comparing x with every generator by value)."""
    return p.new([(m[:i] + (m[i] - 1,) + m[i + 1:], c * m[i]) for m, c in p.items() if m[i]])


class TrigAlgebra:
    """Trigonometric polynomials in ``angles`` with polynomial coefficients in every symbol of ``exprs``."""

    def __init__(self, angles: Iterable[sp.Symbol], symbols: Iterable[sp.Symbol]) -> None:
        self.angles = sorted(set(angles), key=lambda s: s.name)
        gens = sorted(set(symbols) | set(self.angles), key=lambda s: s.name)
        self.alg = _Algebra(self.angles, gens)
        self.R = self.alg.R
        self.gens = gens
        self.gen_index = {x: i for i, x in enumerate(gens)}
        self._maps: dict[int, tuple] = {}  # id(other algebra) -> (it, where its angles and generators are here)
        self.zero: TrigPoly = {}

    @classmethod
    def of(cls, exprs: Iterable[sp.Basic], extra: Iterable[sp.Symbol] = (),
           elements: Iterable[tuple["TrigAlgebra", Iterable[TrigPoly]]] = (),
           within: "TrigAlgebra | None" = None) -> "TrigAlgebra":
        """The algebra of the sympy expressions/matrices ``exprs``: angles are the symbols inside sin/cos; and of
        the ``elements`` of other algebras, (algebra, its elements), with the angles and symbols they use (those
        of their written form), for :meth:`take`. ``within``: an algebra returned instead when it has those angles
        and symbols (the written forms are the same: an angle or a generator that no element uses is read nowhere,
        see :func:`solver.math.simplify._tree_form`)."""
        angles, symbols = cls._needs(exprs, extra, elements)
        if within is not None and angles <= set(within.angles) and symbols <= set(within.gens):
            return within
        return cls(angles, symbols)

    @staticmethod
    def _needs(exprs: Iterable[sp.Basic], extra: Iterable[sp.Symbol],
               elements: Iterable[tuple["TrigAlgebra", Iterable[TrigPoly]]]) -> tuple[set, set]:
        """(angles, symbols) of :meth:`of`."""
        angles: set[sp.Symbol] = set()
        symbols: set[sp.Symbol] = set(extra)
        for e in exprs:
            e = sp.sympify(e)
            symbols |= e.free_symbols
            for f in e.atoms(sp.sin, sp.cos):
                angles |= f.args[0].free_symbols
        for src, items in elements:
            for a in items:
                for (k, _), c in a.items():
                    angles.update(x for x, v in zip(src.angles, k) if v)
                    for m in c.itermonoms():
                        symbols.update(x for x, e in zip(src.gens, m) if e)
        return angles, symbols

    def take(self, src: "TrigAlgebra", a: TrigPoly) -> TrigPoly:
        """``a``, an element of the algebra ``src``, in this one (which has the angles and symbols ``a`` uses:
        :meth:`of`). Both order their angles by name, so a canonical key (first non-zero k_j > 0) stays one."""
        if src is self:
            return a
        maps = self._maps.get(id(src))
        if maps is None or maps[0] is not src:
            maps = self._maps[id(src)] = (src, [self.alg.index.get(x) for x in src.angles],
                                          [self.gen_index.get(x) for x in src.gens])
        _, angle_at, gen_at = maps
        m, g = len(self.angles), len(self.gens)
        new = self.R.dtype
        out: TrigPoly = {}
        for (k, kind), c in a.items():
            key = [0] * m
            for j, v in enumerate(k):
                if v:
                    key[angle_at[j]] = v  # type: ignore[index]
            terms = []
            for mono, coeff in c.items():
                e = [0] * g
                for i, d in enumerate(mono):
                    if d:
                        e[gen_at[i]] = d  # type: ignore[index]
                terms.append((tuple(e), coeff))
            out[(tuple(key), kind)] = new(terms)
        return out

    # ------------------------------------------------------------------------------------------ conversion
    def conv(self, e: sp.Expr) -> TrigPoly:
        """A sympy expression (NotTrigPolynomial when it is not a trigonometric polynomial)."""
        e = sp.sympify(e)
        if e.atoms(sp.Float):
            raise NotTrigPolynomial(e)
        return self.alg.conv(e)

    def matrix(self, m: sp.MatrixBase) -> list[list[TrigPoly]]:
        return [[self.conv(m[i, j]) for j in range(m.cols)] for i in range(m.rows)]

    def expr(self, a: TrigPoly) -> sp.Expr:
        """The printed (tidy) form of ``a``."""
        zero = self.R.zero
        coeffs: dict = {}
        for (k, kind), c in a.items():
            x, y = coeffs.get(k, (zero, zero))
            coeffs[k] = (c, y) if kind == 0 else (x, c)
        return fourier_expr(coeffs, self.angles)

    def to_matrix(self, m: list[list[TrigPoly]]) -> sp.Matrix:
        return sp.Matrix([[self.expr(x) for x in row] for row in m])

    # ------------------------------------------------------------------------------------------ arithmetic
    def add(self, *terms: TrigPoly) -> TrigPoly:
        out: TrigPoly = {}
        for t in terms:
            for key, c in t.items():
                self.alg.add_into(out, key, c)
        return out

    def sub(self, a: TrigPoly, b: TrigPoly) -> TrigPoly:
        return self.add(a, self.scale(b, -1))

    def scale(self, a: TrigPoly, c) -> TrigPoly:  # type: ignore[no-untyped-def]
        """``a`` times a number or a ring element."""
        if not c:
            return {}
        if isinstance(c, PolyElement) and c.is_ground:
            c = c.LC
        if not isinstance(c, PolyElement):  # a number: every coefficient times it, none vanishes
            x = self.R.domain.convert(c)
            return {k: times(v, x) for k, v in a.items()}
        out = {k: v * c for k, v in a.items()}
        return {k: v for k, v in out.items() if v}

    def mul(self, a: TrigPoly, b: TrigPoly) -> TrigPoly:
        if not a or not b:
            return {}
        return self.alg.mul(a, b)

    def cos_sin(self, x: sp.Expr) -> tuple[TrigPoly, TrigPoly]:
        """(cos x, sin x) without sympy's cos(x) and sin(x) (their evaluation costs more than the rest)."""
        try:
            return self.alg.trig_of(x, 0), self.alg.trig_of(x, 1)
        except NotTrigPolynomial:  # (π/3, ...: sympy evaluates them)
            return self.conv(sp.cos(x)), self.conv(sp.sin(x))

    def symbol(self, s: sp.Symbol) -> TrigPoly:
        return self.alg.const(self.alg.gen[s])

    def diff(self, a: TrigPoly, x: sp.Symbol) -> TrigPoly:
        """∂a/∂x (x an angle, a coefficient symbol, or both)."""
        out: TrigPoly = {}
        j = self.alg.index.get(x)
        g = self.gen_index.get(x)
        to = self.R.domain.convert
        for (k, kind), c in a.items():
            if g is not None:
                dc = _pdiff(c, g)
                if dc:
                    self.alg.add_into(out, (k, kind), dc)
            if j is not None and k[j]:
                if kind == 0:  # cos(k·x)' = -k_j sin(k·x)
                    self.alg.add_into(out, (k, 1), times(c, to(-k[j])))
                else:  # sin(k·x)' = k_j cos(k·x)
                    self.alg.add_into(out, (k, 0), times(c, to(k[j])))
        return out

    def dot(self, a: list[TrigPoly], b: list[TrigPoly]) -> TrigPoly:
        return self.add(*[self.mul(x, y) for x, y in zip(a, b)])

    def matmul(self, A: list[list[TrigPoly]], B: list[list[TrigPoly]]) -> list[list[TrigPoly]]:
        cols = list(zip(*B))
        return [[self.dot(row, col) for col in cols] for row in A]

    @staticmethod
    def T(A: list[list[TrigPoly]]) -> list[list[TrigPoly]]:
        return [list(r) for r in zip(*A)]

    def one(self) -> TrigPoly:
        return self.alg.const(self.R.one)

    def det_adj(self, A: list[list[TrigPoly]]) -> tuple[TrigPoly, list[list[TrigPoly]]]:
        """(det A, adj A) of a square matrix by cofactors: adj A_ij = (−1)^(i+j) det A without row j and column i,
        det A = Σ_j A_0j adj A_j0 (m! products: for the small matrices of a task, m ≤ 4 or so)."""
        m = len(A)
        if m == 1:
            return A[0][0], [[self.one()]]

        def det(M: list[list[TrigPoly]]) -> TrigPoly:
            if len(M) == 1:
                return M[0][0]
            return self.add(*[self.scale(self.mul(M[0][j], det([r[:j] + r[j + 1:] for r in M[1:]])), (-1) ** j)
                              for j in range(len(M)) if M[0][j]])

        adj = [[self.scale(det([r[:i] + r[i + 1:] for k, r in enumerate(A) if k != j]), (-1) ** (i + j))
                for j in range(m)] for i in range(m)]
        return self.add(*[self.mul(A[0][j], adj[j][0]) for j in range(m)]), adj

    def by_monomial(self, a: TrigPoly, v: list[sp.Symbol]) -> dict[tuple[int, ...], TrigPoly]:
        """``a`` = Σ_e a_e(·) v^e split by the monomials of the generators ``v`` (exponents e in the order of v):
        {e: a_e}, each a_e free of v."""
        idx = [self.gen_index[x] for x in v]
        out: dict[tuple[int, ...], TrigPoly] = {}
        for key, c in a.items():
            for e, part in parts_by(c, idx).items():
                out.setdefault(e, {})[key] = part
        return out

    def size(self, a: TrigPoly) -> int:
        """Number of monomials of ``a`` over all its Fourier coefficients."""
        return sum(len(c) for c in a.values())
