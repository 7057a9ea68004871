"""A CPU-time budget for symbolic computations that may blow up (exact surds, large symbolic inverses).

    with cpu_budget(3.0):          # raises BudgetExceeded after 3 s of CPU time of this process
        M = heavy_symbolic(...)

It uses the profiling timer (SIGPROF, CPU time: the same on a loaded or an idle machine, unlike wall-clock time),
so it does not disturb wall-clock limits (SIGALRM) set by callers; nested budgets keep the tightest one. Outside
the main thread (or without SIGPROF) there is no limit.
"""
from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


class BudgetExceeded(Exception):
    """The computation did not finish within its CPU-time budget."""


_depth = 0


def _raise(signum: int, frame: Any) -> None:
    raise BudgetExceeded()


@contextmanager
def cpu_budget(seconds: float) -> Iterator[None]:
    """Raise BudgetExceeded when the body uses more than ``seconds`` of CPU time."""
    global _depth
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "SIGPROF"):
        yield
        return
    outer_left, _ = signal.getitimer(signal.ITIMER_PROF)
    old = signal.signal(signal.SIGPROF, _raise)
    limit = min(seconds, outer_left) if (outer_left > 0 and _depth > 0) else seconds
    _depth += 1
    signal.setitimer(signal.ITIMER_PROF, limit)
    try:
        yield
    finally:
        left, _ = signal.getitimer(signal.ITIMER_PROF)
        signal.setitimer(signal.ITIMER_PROF, 0)
        _depth -= 1
        signal.signal(signal.SIGPROF, old)
        if _depth > 0 and outer_left > 0:  # restore the outer budget, less what the inner one used
            used = limit - left if left > 0 else limit
            signal.setitimer(signal.ITIMER_PROF, max(outer_left - used, 1e-3))
