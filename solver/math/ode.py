"""Initial value problems y' = f(t, y) without scipy.integrate, whose import alone (a quarter to half a second:
it pulls in scipy.special and scipy.optimize) costs more than the library's simulations.

Dormand–Prince 5(4): seven stages (the last one, f at the new point, is the first of the next step), the step
accepted when the RMS norm of the embedded error estimate h Σ eᵢkᵢ / (atol + rtol·max(|y|, |y_new|)) is at most
1, the next step h·min(10, max(0.2, 0.9·err^(-1/5))); values at the requested times from the continuous
extension of order 4, y(t + θh) = y + h Σᵢ kᵢ Σⱼ Pᵢⱼ θʲ. A stiff problem (h|λ| beyond the method's stability
region, λ estimated as ‖k₇ − k₆‖/‖y₇ − y₆‖: h|λ| > 2.5 on 15 accepted steps, or the steps held at h|λ| > 1 once
300 evaluations are spent) is handed to scipy's LSODA."""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

C = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1, 1])
A = [np.array(r) for r in ([1 / 5],
                           [3 / 40, 9 / 40],
                           [44 / 45, -56 / 15, 32 / 9],
                           [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
                           [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
                           [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])]
B = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0])          # order 5
E = B - np.array([5179 / 57600, 0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40])  # 5 − 4
P = np.array([  # continuous extension (Shampine): row i, the coefficients of θ, θ², θ³, θ⁴ for kᵢ
    [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0, 0, 0, 0],
    [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])
STIFF_STEPS = 15       # accepted steps with h|λ| > STIFF_H_LAMBDA: Hairer & Wanner's test (3.25 there; this step
STIFF_H_LAMBDA = 2.5   # control settles at h|λ| ≈ 2.8 on a stiff problem, just inside the stability region)
STIFF_WORK = 300       # past these evaluations, steps held at h|λ| > 1 (the median of the last 50) are stiff too:
STIFF_WINDOW = 50      # at tight tolerances the error estimate holds a stiff problem's steps at h|λ| ≈ 1.4


@dataclass
class OdeResult:
    """As scipy's solve_ivp returns it: times t, states y (one column per time), success, message, nfev;
    ``method`` says which integrator produced it ("DOPRI5", or "LSODA" for a stiff problem)."""

    t: np.ndarray
    y: np.ndarray
    success: bool
    message: str
    nfev: int
    method: str = "DOPRI5"


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


def _first_step(f: Callable, t0: float, y0: np.ndarray, f0: np.ndarray, direction: float, rtol: float,
                atol: float) -> tuple[float, int]:
    """Hairer, Nørsett & Wanner's starting step: h₀ = 0.01‖y₀‖/‖f₀‖ (scaled norms), then
    h₁ = (0.01/max(‖f₀‖, ‖f'‖))^(1/5) from one explicit Euler step; min(100 h₀, h₁). (h, evaluations)."""
    scale = atol + np.abs(y0) * rtol
    d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    f1 = np.asarray(f(t0 + direction * h0, y0 + direction * h0 * f0), dtype=float)
    d2 = _rms((f1 - f0) / scale) / h0
    h1 = max(1e-6, h0 * 1e-3) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** (1 / 5)
    return min(100 * h0, h1), 1


def solve(f: Callable[[float, np.ndarray], Sequence[float]], t_span: tuple[float, float], y0: Sequence[float],
          t_eval: Sequence[float] | None = None, rtol: float = 1e-6, atol: float = 1e-8,
          max_step: float = np.inf) -> OdeResult:
    """y' = f(t, y) on t_span from y0: the states at ``t_eval`` (inside t_span, in its direction), else at every
    accepted step. On failure (a step below the spacing of the floats, a state that is not finite), the times
    reached so far, success False. Stiff problems go to scipy's LSODA with the same arguments. Exceptions raised
    by f propagate (a caller's budget)."""
    t0, t1 = float(t_span[0]), float(t_span[1])
    y = np.array(y0, dtype=float)
    direction = 1.0 if t1 >= t0 else -1.0
    out_t: list[float] = [] if t_eval is not None else [t0]
    out_y: list[np.ndarray] = [] if t_eval is not None else [y.copy()]
    te = np.asarray(t_eval, dtype=float) if t_eval is not None else None
    j = 0
    if te is not None:  # a requested time at t0 itself
        while j < len(te) and (te[j] - t0) * direction <= 0:
            out_t.append(float(te[j]))
            out_y.append(y.copy())
            j += 1
    if t1 == t0:
        return _result(out_t, out_y, y, True, "the interval is empty", 0)
    t = t0
    k = np.empty((7, len(y)))
    k[0] = np.asarray(f(t, y), dtype=float)
    nfev = 1
    h, extra = _first_step(f, t, y, k[0], direction, rtol, atol)
    nfev += extra
    max_step = min(max_step, abs(t1 - t0))
    stiff, calm = 0, 0
    recent: deque[float] = deque(maxlen=STIFF_WINDOW)
    rejected = False
    while (t1 - t) * direction > 0:
        h = min(h, max_step)
        if h < 10 * np.spacing(abs(t)) or not np.isfinite(h):
            return _result(out_t, out_y, y, False, "the step became smaller than the spacing of the floats", nfev)
        last = (t + direction * h - t1) * direction >= 0
        step = (t1 - t) if last else direction * h
        for i in range(1, 7):
            k[i] = np.asarray(f(t + C[i] * step, y + step * (A[i - 1] @ k[:i])), dtype=float)
        nfev += 6
        y_new = y + step * (B[:6] @ k[:6])
        scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
        err = _rms(step * (E @ k) / scale)
        if not np.isfinite(err):  # (a state where f is not finite: shorter steps, until they are too short)
            h, rejected = abs(step) * 0.2, True
            continue
        if err > 1:
            h, rejected = abs(step) * max(0.2, 0.9 * err ** -0.2), True
            continue
        # accepted: the stiffness test (k₇, k₆ are f at t + h, at y_new and at the sixth stage's point)
        y6 = y + step * (A[4] @ k[:5])
        dy = _rms(y_new - y6)
        h_lambda = abs(step) * _rms(k[6] - k[5]) / dy if dy > 0 else 0.0
        recent.append(h_lambda)
        if nfev > STIFF_WORK and len(recent) == STIFF_WINDOW and np.median(recent) > 1:
            return _lsoda(f, (t0, t1), y0, t_eval, rtol, atol, max_step, nfev)
        if h_lambda > STIFF_H_LAMBDA:
            stiff, calm = stiff + 1, 0
            if stiff >= STIFF_STEPS:
                return _lsoda(f, (t0, t1), y0, t_eval, rtol, atol, max_step, nfev)
        else:
            calm += 1
            if calm >= 6:
                stiff = 0
        t_new = t1 if last else t + step
        if te is not None:
            while j < len(te) and (te[j] - t_new) * direction <= 0:
                theta = (te[j] - t) / step
                out_t.append(float(te[j]))
                out_y.append(y + step * ((k.T @ P) @ (theta ** np.arange(1, 5))))
                j += 1
        else:
            out_t.append(t_new)
            out_y.append(y_new.copy())
        factor = 10.0 if err == 0 else min(10.0, max(0.2, 0.9 * err ** -0.2))
        if rejected:
            factor = min(factor, 1.0)
        t, y, h, rejected = t_new, y_new, abs(step) * factor, False
        k[0] = k[6]
    return _result(out_t, out_y, y, True, "the end of the interval was reached", nfev)


def _result(ts: list[float], ys: list[np.ndarray], y: np.ndarray, ok: bool, message: str, nfev: int) -> OdeResult:
    return OdeResult(np.array(ts), np.array(ys).T.reshape(len(y), len(ts)), ok, message, nfev)


def _lsoda(f: Callable, t_span: tuple[float, float], y0: Sequence[float], t_eval: Sequence[float] | None,
           rtol: float, atol: float, max_step: float, spent: int) -> OdeResult:
    """A stiff problem, integrated again from the start by scipy's LSODA (the evaluations spent are counted)."""
    from scipy.integrate import solve_ivp
    r = solve_ivp(f, t_span, np.array(y0, dtype=float), method="LSODA", t_eval=t_eval, rtol=rtol, atol=atol,
                  max_step=max_step)
    return OdeResult(r.t, r.y, bool(r.success), str(r.message), int(r.nfev) + spent, "LSODA")
