"""Iterative learning control of a tracking task (ask kind ``learning_control``), in lifted form.

A discrete-time plant x(t+1) = A x(t) + B u(t), y(t) = C x(t), x(0) = x₀ at every trial, over t = 0..N−1
(output y(1..N)) is y = G u + d in lifted form, G lower block-triangular with the Markov parameters C Aʲ B.
The update u_{k+1} = u_k + L e_k, e_k = y_d − y_k (L = γ I: P-type with the one-step shift; or a given L) gives

    e_{k+1} = (I − G L) e_k:   e_k → 0 for every e_0  ⇔  ρ(I − G L) < 1  ⇔  all |1 − γ C Aʲ⁰B| < 1 (P-type, diagonal)
    ‖e_k‖ ≤ ‖I − G L‖ᵏ ‖e_0‖ (monotone in the 2-norm when ‖I − G L‖ < 1), so
    k ≥ ln(ε/‖e_0‖) / ln‖I − G L‖ iterations guarantee ‖e_k‖ ≤ ε.
(For the iterative gravity compensation of a robot at rest see ``regulation`` with ``law: iterative``.)
"""
from __future__ import annotations

import math
from typing import Any, Literal, Optional, Union

import numpy as np
import sympy as sp
from pydantic import Field

from solver.registry import ask_kind
from solver.results import Curve, Figure, Panel, Solution
from solver.spec.errors import UserError
from solver.spec.expr import shape_of
from solver.spec.models import Strict

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]
MAX_N = 400
MAX_ITER = 500


class LearningControlAsk(Strict):
    """ILC of a discrete-time linear plant over a finite horizon: update law, convergence, iterations."""

    kind: Literal["learning_control"]
    title: Optional[str] = Field(None, description="heading of this part in the report")
    A: ExprT = Field(description="state matrix (n×n, numbers)")
    B: ExprT = Field(description="input matrix (n×1)")
    C: ExprT = Field(description="output matrix (1×n)")
    x0: Optional[ExprT] = Field(None, description="initial state of every trial (default 0)")
    horizon: int = Field(description="number of samples N of a trial", ge=1, le=MAX_N)
    reference: ExprT = Field(description="desired output y_d(t), t = 1..N: an expression in t, or a list of N")
    gain: Scalar = Field(description="γ of the P-type update u_{k+1}(t) = u_k(t) + γ e_k(t+1)")
    epsilon: Optional[Scalar] = Field(None, description="required ‖e_k‖ (2-norm over the trial)")
    iterations: int = Field(30, ge=1, le=MAX_ITER, description="trials simulated")
    suffix: str = Field("", pattern=r"^[A-Za-z0-9_]*$", description="appended to every result name")


def lifted(A: np.ndarray, B: np.ndarray, C: np.ndarray, N: int) -> np.ndarray:
    """G (N×N): y(t+1) = Σ_{j≤t} C A^{t−j} B u(j)."""
    h = []
    M = np.eye(A.shape[0])
    for _ in range(N):
        h.append(float((C @ M @ B).item()))
        M = A @ M
    G = np.zeros((N, N))
    for i in range(N):
        for j in range(i + 1):
            G[i, j] = h[i - j]
    return G


def free_response(A: np.ndarray, C: np.ndarray, x0: np.ndarray, N: int) -> np.ndarray:
    out, x = [], x0.copy()
    for _ in range(N):
        x = A @ x
        out.append(float((C @ x).item()))
    return np.array(out)


def run_ilc(G: np.ndarray, d: np.ndarray, yd: np.ndarray, L: np.ndarray, iters: int) -> list[float]:
    """‖e_k‖ for k = 0..iters, u_0 = 0."""
    u = np.zeros(G.shape[1])
    errs = []
    for _ in range(iters + 1):
        e = yd - (G @ u + d)
        errs.append(float(np.linalg.norm(e)))
        if not np.isfinite(errs[-1]) or errs[-1] > 1e150:
            break
        u = u + L @ e
    return errs


def _mat(problem, ctx, field: str) -> np.ndarray:  # type: ignore[no-untyped-def]
    raw = ctx.expr(field)
    place = problem.located.place(ctx.path + (field,))
    shp = shape_of(raw)
    M = sp.Matrix([[raw]]) if shp == () else sp.Matrix(raw)
    M = M.xreplace(problem.values)
    if M.free_symbols:
        raise UserError(f"{field}: numbers needed (give values: for {', '.join(map(str, M.free_symbols))})", place)
    return np.array(M.evalf(20).tolist(), dtype=float)


def _read(problem, options: LearningControlAsk, ctx) -> tuple:  # type: ignore[no-untyped-def]
    """A, B, C (C as a row), x0, the reference y_d(1..N) and the gain γ, as numbers."""
    A, B, C = _mat(problem, ctx, "A"), _mat(problem, ctx, "B"), _mat(problem, ctx, "C")
    n = A.shape[0]
    if A.shape != (n, n) or B.shape != (n, 1) or C.reshape(1, -1).shape[1] != n:
        raise UserError("A must be n×n, B n×1 and C 1×n", problem.located.place(ctx.path + ("A",)))
    C = C.reshape(1, n)
    x0 = _mat(problem, ctx, "x0").reshape(n) if options.x0 is not None else np.zeros(n)
    N = options.horizon
    raw = ctx.expr("reference")
    if isinstance(raw, list):
        yd = np.array([_number(problem, ctx, "reference", v) for v in raw])
        if yd.size != N:
            raise UserError(f"reference: {N} values expected", problem.located.place(ctx.path + ("reference",)))
    else:
        t = problem.names.get("t", sp.Symbol("t", real=True))
        f = sp.sympify(raw).xreplace(problem.values)
        yd = np.array([_number(problem, ctx, "reference", f.subs(t, k)) for k in range(1, N + 1)])
    gamma = _number(problem, ctx, "gain", ctx.expr("gain"))
    return A, B, C, x0, yd, gamma


def _number(problem, ctx, field: str, value: Any) -> float:  # type: ignore[no-untyped-def]
    """A numeric option (parameter values substituted) as a float; a spec error if symbols are left."""
    v = sp.sympify(value).xreplace(problem.values) if not isinstance(value, list) else None
    if v is None or v.free_symbols or not v.is_number or v.is_real is False:
        left = ", ".join(sorted(map(str, v.free_symbols))) if v is not None else ""
        raise UserError(f"{field}: a number is needed" + (f" (give values: for {left})" if left else ""),
                        problem.located.place(ctx.path + (field,)))
    return float(v)


def validate_learning_control(problem, options: LearningControlAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_learning_control` reads them, without the iterations."""
    _read(problem, options, ctx)
    if options.epsilon is not None:
        _number(problem, ctx, "epsilon", ctx.expr("epsilon"))


@ask_kind("learning_control", LearningControlAsk, "iterative learning control (lifted form): convergence, iterations",
          validate=validate_learning_control)
def solve_learning_control(problem, options: LearningControlAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: markov (first Markov parameter CB), rho (spectral radius of I − GL), norm (‖I − GL‖₂),
    converges, monotone, e0, iterations_bound (k with ‖I−GL‖ᵏ‖e_0‖ ≤ ε), iterations_actual, errors."""
    sol = Solution("learning_control", title=options.title or "Iterative learning control")
    sfx = options.suffix
    A, B, C, x0, yd, gamma = _read(problem, options, ctx)
    N = options.horizon
    G = lifted(A, B, C, N)
    d = free_response(A, C, x0, N)
    L = gamma * np.eye(N)
    E = np.eye(N) - G @ L
    rho = float(max(abs(np.linalg.eigvals(E))))
    nrm = float(np.linalg.norm(E, 2))
    cb = float((C @ B).item())
    e0 = float(np.linalg.norm(yd - d))
    add = lambda name, v, kind=None, label="": sol.add(name + sfx, v, kind, label=label)  # noqa: E731
    add("markov", sp.Float(cb, 10), "number", label="CB")
    add("rho", sp.Float(rho, 10), "number", label="\\rho(I - GL)")
    add("norm", sp.Float(nrm, 10), "number", label="\\|I - GL\\|_2")
    add("converges", bool(rho < 1), "bool", label="\\rho < 1")
    add("monotone", bool(nrm < 1), "bool", label="\\|I - GL\\| < 1")
    add("e0", sp.Float(e0, 10), "number", label="\\|e_0\\|")
    data: dict[str, Any] = {"cb": cb, "gamma": gamma, "rho": rho, "norm": nrm, "N": N, "e0": e0, "kmin": None,
                            "actual": None, "eps": None}
    errs = run_ilc(G, d, yd, L, options.iterations)
    if options.epsilon is not None:
        eps = _number(problem, ctx, "epsilon", ctx.expr("epsilon"))
        data["eps"] = eps
        if nrm < 1 and e0 > eps:
            kmin = math.ceil(math.log(eps / e0) / math.log(nrm) - 1e-12)
            add("iterations_bound", sp.Integer(kmin), "number", label="k_{\\min}")
            data["kmin"] = kmin
        actual = next((k for k, v in enumerate(errs) if v <= eps), None)
        if actual is not None:
            add("iterations_actual", sp.Integer(actual), "number", label="k_{\\text{actual}}")
            data["actual"] = actual
    add("errors", [sp.Float(v, 6) for v in errs[:12]], "list", label="\\|e_k\\|")
    data["errs"] = errs
    sol.step("ilc", **data)

    def panels() -> list[Panel]:
        ks = list(range(len(errs)))
        lg = lambda v: math.log10(max(v, 1e-300))  # noqa: E731
        curves = [Curve("$\\log_{10}\\|e_k\\|$", ks, [lg(v) for v in errs])]
        if nrm < 1:
            curves.append(Curve("bound $\\|I-GL\\|^k\\|e_0\\|$", ks, [lg(e0 * nrm ** k) for k in ks], dashed=True))
        hl = [(lg(data["eps"]), "$\\varepsilon$")] if data["eps"] else []
        return [Panel("iteration $k$", "$\\log_{10}\\|e_k\\|$", curves, hlines=hl)]

    sol.figures.append(Figure("ilc", "Tracking error norm at each trial, log scale (and its geometric bound when monotone).", panels))
    return sol
