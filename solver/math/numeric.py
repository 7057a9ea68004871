"""Numeric functions of sympy expressions."""
from __future__ import annotations

from typing import Any, Callable

import sympy as sp


def lambdify_np(args: Any, expr: Any) -> Callable[..., Any]:
    """``sp.lambdify(args, expr, "numpy")``: the same code (sympy's NumPy printer), run in numpy's own namespace.

    The "numpy" module string makes sympy run ``from numpy import *`` once per process, which imports numpy's
    testing, f2py, random, ma, ... submodules (about 45 ms of every `solve` that samples a curve); the names the
    printer needs beyond numpy's top level (numpy.linalg's) are imported by lambdify itself."""
    import numpy as np
    return sp.lambdify(args, expr, [np])


def newton_zeros(exprs: Any, syms: list[sp.Symbol], X0: Any) -> tuple[Any, Any]:
    """Multi-start Newton on f(x) = ``exprs`` (numbers but ``syms``), every start (a row of X0) at once with
    :func:`solver.math.search.newton_roots` (J Δ = −f, least squares where J is singular or not square): the end
    points and the residuals f there, both (N, m) arrays; the caller decides which are zeros."""
    import numpy as np

    from solver.math.search import newton_roots
    exprs = list(exprs)
    f = lambdify_np(syms, exprs)
    jac = lambdify_np(syms, sp.Matrix(exprs).jacobian(syms).tolist())

    def rows(vals: Any, N: int) -> Any:  # lambdified entries (arrays or constants) as (N, ...) floats
        return np.stack([np.broadcast_to(np.asarray(v, dtype=float), (N,)) for v in vals], axis=-1)

    def fs(X: Any) -> Any:
        return rows(f(*X.T), len(X))

    def js(X: Any) -> Any:
        return np.stack([rows(r, len(X)) for r in jac(*X.T)], axis=1)

    with np.errstate(all="ignore"):
        ends = newton_roots(fs, js, np.asarray(X0, dtype=float))
        return ends, fs(ends)


class Unsupported(Exception):
    """A node :func:`numpy_tree` cannot evaluate."""


_UFUNCS = {sp.sin: "sin", sp.cos: "cos", sp.tan: "tan", sp.exp: "exp", sp.log: "log", sp.Abs: "abs",
           sp.atan: "arctan", sp.asin: "arcsin", sp.acos: "arccos", sp.sinh: "sinh", sp.cosh: "cosh",
           sp.tanh: "tanh", sp.sign: "sign"}


def numpy_tree(e: sp.Expr, env: dict[sp.Symbol, Any], np: Any, memo: dict) -> Any:
    """e with each symbol x replaced by the array env[x], computed by numpy node by node (each shared
    subexpression once), as lambdify's code computes it, without generating code (lambdify prints the
    expression: tens of ms for a sum of a few hundred terms). :class:`Unsupported` for any other node."""
    hit = memo.get(e)
    if hit is not None:
        return hit
    if e.is_Symbol:
        if e not in env:
            raise Unsupported(e.name)
        out = env[e]
    elif e.is_Number:
        out = complex(e) if e.has(sp.I) else float(e)
    elif e.is_NumberSymbol:
        out = float(e)
    elif e.is_Add:
        out = sum((numpy_tree(a, env, np, memo) for a in e.args), 0.0)
    elif e.is_Mul:
        out = 1.0
        for a in e.args:
            out = out * numpy_tree(a, env, np, memo)
    elif e.is_Pow:
        b, k = numpy_tree(e.base, env, np, memo), e.exp
        out = np.sqrt(b) if k == sp.S.Half else 1 / np.sqrt(b) if k == -sp.S.Half else \
            np.power(b, int(k)) if k.is_Integer else np.power(b, numpy_tree(k, env, np, memo))
    elif type(e) in _UFUNCS and len(e.args) == 1:
        out = getattr(np, _UFUNCS[type(e)])(numpy_tree(e.args[0], env, np, memo))
    elif isinstance(e, sp.atan2):
        out = np.arctan2(numpy_tree(e.args[0], env, np, memo), numpy_tree(e.args[1], env, np, memo))
    else:
        raise Unsupported(type(e).__name__)
    memo[e] = out
    return out


def evaluate_np(e: sp.Expr, syms: list[sp.Symbol], arrays: list[Any]) -> Any:
    """e(syms = arrays) by numpy (floating-point errors ignored: inf and nan come out as values):
    :func:`numpy_tree`, or lambdify's code for a node it does not know."""
    import numpy as np
    with np.errstate(all="ignore"):
        try:
            return numpy_tree(e, dict(zip(syms, arrays)), np, {})
        except Unsupported:
            return lambdify_np(syms, e)(*arrays)
