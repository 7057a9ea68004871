"""A CPU-time budget for symbolic computations that may blow up (exact surds, large symbolic inverses).

    with cpu_budget(3.0):          # raises BudgetExceeded after 3 s of CPU time of this process
        M = heavy_symbolic(...)

It uses the profiling timer (SIGPROF, CPU time: the same on a loaded or an idle machine, unlike wall-clock time),
so it does not disturb wall-clock limits (SIGALRM) set by callers. Outside the main thread (or without SIGPROF)
there is no limit.

Nested budgets: the timer runs for the tightest one. When it expires, the budget that is exhausted is the one that
raises BudgetExceeded: an inner budget cut short by its outer one lets an `_Exhausted` (a BaseException, which
`except BudgetExceeded` and `except Exception` handlers do not catch) pass up to the outer one, so a loop of inner
budgets cannot outlive the outer budget. An exception swallowed on its way (a gc callback, a ``__del__``) is raised
again 50 ms of CPU later; Python's report of the swallowed one ("Exception ignored in ...", sys.unraisablehook,
a warning under pytest) is dropped, as it is no error.
"""
from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any


class BudgetExceeded(Exception):
    """The computation did not finish within its CPU-time budget."""


class _Exhausted(BaseException):
    """An outer budget ran out inside an inner one: it unwinds to the outer budget, which raises BudgetExceeded."""

    def __init__(self, owner: int) -> None:
        super().__init__(owner)
        self.owner = owner


_REFIRE = 0.05
_owners: list[int] = []   # for each open budget (innermost last): the depth whose deadline the timer is running
_fired = 0


def _raise(signum: int, frame: Any) -> None:
    global _fired
    _fired += 1
    signal.setitimer(signal.ITIMER_PROF, _REFIRE)  # raised again if swallowed
    depth = len(_owners) - 1
    owner = _owners[-1] if _owners else depth
    if owner == depth:
        raise BudgetExceeded()
    raise _Exhausted(owner)


@contextmanager
def cpu_budget(seconds: float) -> Iterator[None]:
    """Raise BudgetExceeded when the body uses more than ``seconds`` of CPU time."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "SIGPROF"):
        yield
        return
    outer_left, _ = signal.getitimer(signal.ITIMER_PROF)
    nested = bool(_owners) and outer_left > 0
    old = signal.signal(signal.SIGPROF, _raise)
    depth = len(_owners)
    if nested and outer_left <= seconds:   # the outer deadline comes first: the timer runs for it
        limit, owner = outer_left, _owners[-1]
    else:
        limit, owner = seconds, depth
    _owners.append(owner)
    fired = _fired
    report = sys.unraisablehook

    def unraisable(info: Any) -> None:  # a finalizer swallowed the budget's exception: raised again (_REFIRE)
        if not isinstance(info.exc_value, (BudgetExceeded, _Exhausted)):
            report(info)
    sys.unraisablehook = unraisable
    signal.setitimer(signal.ITIMER_PROF, limit)
    try:
        yield
    except _Exhausted as e:
        if e.owner == depth:
            raise BudgetExceeded() from None
        raise
    finally:
        left, _ = signal.setitimer(signal.ITIMER_PROF, 0)  # disarmed first: a re-fire cannot hit the clean-up
        sys.unraisablehook = report
        _owners.pop()
        signal.signal(signal.SIGPROF, old)
        if nested:  # the outer budget goes on, less what this one used
            used = limit if (_fired > fired or left <= 0) else limit - left
            signal.setitimer(signal.ITIMER_PROF, max(outer_left - used, 1e-3))
