"""Bounded scalar minimization without scipy.optimize (whose import alone costs about half a second)."""
from __future__ import annotations

import math
from typing import Callable

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
