"""Searches without scipy.optimize, whose import alone costs half a second to a second: a bounded scalar minimum,
a local maximum in a box, exact linear programs, a bracketed zero and Newton's method from one or many starts."""
from __future__ import annotations

import itertools
import math
from fractions import Fraction
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    import numpy as np

_INV_PHI = (math.sqrt(5) - 1) / 2  # 1/φ


def golden_min(f: Callable[[float], float], lo: float, hi: float, xtol: float,
               max_iter: int = 200) -> tuple[float, float]:
    """(x, f(x)) minimizing f on [lo, hi] by golden-section search: the bracket shrinks by 1/φ per evaluation
    until it is narrower than ``xtol``; exact for f unimodal on [lo, hi] (a grid's best cell and its
    neighbours), a local minimum otherwise. The ends are candidates too."""
    a, b = float(lo), float(hi)
    c, d = b - _INV_PHI * (b - a), a + _INV_PHI * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(max_iter):
        if b - a <= xtol:
            break
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - _INV_PHI * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + _INV_PHI * (b - a)
            fd = f(d)
    best = min(((fc, c), (fd, d), (f(lo), float(lo)), (f(hi), float(hi))), key=lambda p: p[0])
    return best[1], best[0]


def pattern_max(fn: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, step: np.ndarray,
                lower: np.ndarray, upper: np.ndarray, xtol: float = 1e-11,
                max_iter: int = 2000) -> tuple[np.ndarray, float]:
    """(x, f(x)) a local maximum of a vectorized f (rows of points -> values) near x0, in the box
    lower <= x <= upper (±inf for a free coordinate), by a pattern search: f at x + h ⊙ d for every d in
    {-1, 0, 1}^k (the 2k axes past four coordinates), one call per iteration; x moves to the best point while it
    improves f, otherwise h is halved, until every h_i < xtol (1 + |x_i|). Derivative-free: it also climbs a
    largest eigenvalue or a spectral norm where two branches cross."""
    import numpy as np
    x = np.clip(np.asarray(x0, dtype=float), lower, upper)
    h = np.asarray(step, dtype=float).copy()
    k = len(x)
    if k <= 4:
        dirs = np.array(list(itertools.product((-1.0, 0.0, 1.0), repeat=k)))
        dirs = dirs[np.any(dirs != 0, axis=1)]
    else:
        dirs = np.vstack([np.eye(k), -np.eye(k)])
    fx = float(fn(x[None, :])[0])
    for _ in range(max_iter):
        if np.all(h < xtol * (1 + np.abs(x))):
            break
        pts = np.clip(x + dirs * h, lower, upper)
        vals = fn(pts)
        j = int(np.argmax(vals))
        if vals[j] > fx:
            x, fx = pts[j], float(vals[j])
        else:
            h = h / 2
    return x, fx


def lp_max(c: list, A: list[list], b: list) -> tuple[int, list[Fraction] | None]:
    """max cᵀx subject to A x ≤ b, x ≥ 0, exactly (every number as a Fraction: floats exactly as they are) by the
    two-phase simplex method with Bland's rule (no cycling); for the small programs of gain design (a few
    variables, a few dozen constraints). Returns (status, x) with scipy's codes: 0 optimal, 2 infeasible,
    3 unbounded (x None unless optimal)."""
    n, m = len(c), len(A)
    if not all(math.isfinite(float(v)) for v in [*c, *b, *(x for row in A for x in row)]):
        raise ValueError("lp_max: a coefficient is infinite or undefined")
    cf = [Fraction(v) for v in c]
    T: list[list[Fraction]] = []  # rows [x (n) | slacks (m) | artificials | rhs], in canonical form for `basis`
    basis: list[int] = []
    flipped = [Fraction(b[i]) < 0 for i in range(m)]
    n_art = sum(flipped)
    width = n + m + n_art
    a = 0
    for i in range(m):
        s = -1 if flipped[i] else 1
        row = [s * Fraction(v) for v in A[i]] + [Fraction(s if k == i else 0) for k in range(m)]
        row += [Fraction(0)] * n_art + [s * Fraction(b[i])]
        if flipped[i]:
            row[n + m + a] = Fraction(1)
            basis.append(n + m + a)
            a += 1
        else:
            basis.append(n + i)
        T.append(row)

    def pivot(r: int, j: int) -> None:
        p = T[r][j]
        T[r] = [v / p for v in T[r]]
        for i in range(len(T)):
            if i != r and T[i][j]:
                f = T[i][j]
                T[i] = [v - f * w for v, w in zip(T[i], T[r])]
        basis[r] = j

    def run(cost: list[Fraction], allowed: int) -> bool:
        """Maximize cost·x over the columns < allowed; False when unbounded."""
        while True:
            z = [sum((cost[basis[i]] * T[i][j] for i in range(len(T))), Fraction(0)) - cost[j]
                 for j in range(allowed)]
            enter = next((j for j in range(allowed) if z[j] < 0), None)
            if enter is None:
                return True
            rows = [(T[i][-1] / T[i][enter], basis[i], i) for i in range(len(T)) if T[i][enter] > 0]
            if not rows:
                return False
            pivot(min(rows)[2], enter)

    if n_art:
        run([Fraction(0)] * (n + m) + [Fraction(-1)] * n_art, width)
        if any(basis[i] >= n + m and T[i][-1] != 0 for i in range(len(T))):
            return 2, None
        for i in range(len(T) - 1, -1, -1):  # artificials left in the basis at level 0: pivot them out
            if basis[i] >= n + m:
                j = next((j for j in range(n + m) if T[i][j] != 0), None)
                if j is None:
                    del T[i], basis[i]  # (a redundant row)
                else:
                    pivot(i, j)
    if not run(cf + [Fraction(0)] * (m + n_art), n + m):
        return 3, None
    x = [Fraction(0)] * n
    for i, j in enumerate(basis):
        if j < n:
            x[j] = T[i][-1]
    return 0, x


def bisect_root(f: Callable[[float], float], a: float, b: float) -> float:
    """A zero of f in [a, b] where f(a) f(b) < 0, by bisection down to adjacent doubles (at most about 64
    halvings from any bracket of finite doubles): the bracket keeps the sign change, so the result is within
    one ulp-wide bracket of a zero."""
    fa = f(a)
    for _ in range(200):
        m = a + (b - a) / 2
        if m <= a or m >= b:
            break
        fm = f(m)
        if fm == 0:
            return m
        if (fm < 0) == (fa < 0):
            a, fa = m, fm
        else:
            b = m
    return a if abs(fa) <= abs(f(b)) else b


def newton_root(f: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray], x0: np.ndarray,
                xtol: float = 1e-13, max_iter: int = 100, halvings: int = 10) -> np.ndarray:
    """x near x0 with f(x) = 0 by Newton's method, J(x) Δ = −f(x) (least squares where J is singular), the step
    halved (at most ``halvings`` times) until ‖f‖ decreases; stops when the step is below xtol (1 + ‖x‖) or ‖f‖
    does not decrease. The caller checks the residual (no convergence is claimed: a start far from every zero
    gives up after a few steps). :func:`newton_roots` with one start."""
    import numpy as np
    return newton_roots(lambda X: np.asarray(f(X[0]), dtype=float)[None, :],
                        lambda X: np.asarray(jac(X[0]), dtype=float)[None, :, :],
                        np.asarray(x0, dtype=float)[None, :], xtol, max_iter, halvings)[0]


def newton_roots(f: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray], X0: np.ndarray,
                 xtol: float = 1e-13, max_iter: int = 100, halvings: int = 10) -> np.ndarray:
    """:func:`newton_root` from every row of X0 at once (multi-start searches): f maps the (N, n) points to
    their (N, m) residuals and jac to the (N, m, n) Jacobians (m ≠ n: least-squares steps); each row steps, halves and stops on its own as
    newton_root's rule says, and a few numpy calls per iteration serve all the rows. Returns the (N, n) end
    points (the caller checks the residuals)."""
    import numpy as np
    X = np.array(X0, dtype=float)
    F = np.asarray(f(X), dtype=float)
    nF = np.sqrt(np.einsum("ij,ij->i", F, F))
    active = np.isfinite(nF) & (nF > 0)
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        J = np.asarray(jac(X[idx]), dtype=float)
        rhs = -F[idx]
        try:
            S = np.linalg.solve(J, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:  # a singular or non-square one: row by row, least squares where singular
            S = np.empty((len(idx), X.shape[1]))
            for r in range(len(idx)):
                try:
                    S[r] = np.linalg.solve(J[r], rhs[r])
                except np.linalg.LinAlgError:
                    try:
                        S[r] = np.linalg.lstsq(J[r], rhs[r], rcond=None)[0]
                    except np.linalg.LinAlgError:  # (not finite: this row stops)
                        S[r] = np.nan
        t = np.ones(len(idx))
        accepted = np.zeros(len(idx), dtype=bool)
        Xn, Fn, nn = X[idx].copy(), F[idx].copy(), nF[idx].copy()
        pending = np.arange(len(idx))
        for _h in range(halvings + 1):
            Xt = X[idx[pending]] + t[pending, None] * S[pending]
            Ft = np.asarray(f(Xt), dtype=float)
            with np.errstate(invalid="ignore"):
                nt = np.sqrt(np.einsum("ij,ij->i", Ft, Ft))
                ok = nt < nF[idx[pending]]
            good = pending[ok]
            Xn[good], Fn[good], nn[good], accepted[good] = Xt[ok], Ft[ok], nt[ok], True
            pending = pending[~ok]
            if not pending.size:
                break
            t[pending] /= 2
        rows = idx[accepted]
        X[rows], F[rows], nF[rows] = Xn[accepted], Fn[accepted], nn[accepted]
        step = t[accepted] * np.sqrt(np.einsum("ij,ij->i", S[accepted], S[accepted]))
        done = step <= xtol * (1 + np.sqrt(np.einsum("ij,ij->i", X[rows], X[rows])))
        active[idx[~accepted]] = False
        active[rows[done]] = False
        active &= np.isfinite(nF) & (nF > 0)
    return X
