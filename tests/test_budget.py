"""The CPU-time budget: it stops a runaway computation, also when the first BudgetExceeded is swallowed, and
nested budgets keep the tightest limit and give the outer one back what is left."""
from __future__ import annotations

import signal
import time

import pytest

from solver.math.budget import BudgetExceeded, cpu_budget


def _spin(seconds: float) -> None:
    t = time.process_time()
    while time.process_time() - t < seconds:
        pass


def test_stops_a_busy_loop():
    t = time.process_time()
    with pytest.raises(BudgetExceeded):
        with cpu_budget(0.2):
            _spin(5)
    assert time.process_time() - t < 2
    assert signal.getitimer(signal.ITIMER_PROF)[0] == 0


def test_a_swallowed_exception_fires_again():
    # library code with a broad `except Exception` (or a gc callback) can swallow the first BudgetExceeded
    swallowed = 0
    t = time.process_time()
    with pytest.raises(BudgetExceeded):
        with cpu_budget(0.2):
            try:
                _spin(5)
            except Exception:
                swallowed += 1
            _spin(5)
    assert swallowed == 1 and time.process_time() - t < 2


def test_an_exception_swallowed_by_a_finalizer_is_not_reported(monkeypatch):
    """The budget runs out inside a __del__ (as in a gc or weakref callback): Python swallows the exception and
    reports it to sys.unraisablehook (pytest turns that into a warning); the budget drops that report, raises again
    after _REFIRE, and passes other unraisable exceptions on."""
    import sys
    seen: list = []
    monkeypatch.setattr(sys, "unraisablehook", lambda info: seen.append(info.exc_value))

    class Slow:
        def __del__(self) -> None:
            _spin(0.5)

    class Broken:
        def __del__(self) -> None:
            raise ValueError("not the budget's")
    with pytest.raises(BudgetExceeded):
        with cpu_budget(0.1):
            Broken()
            Slow()
            _spin(5)
    assert [type(e) for e in seen] == [ValueError]
    assert sys.unraisablehook is not None and sys.unraisablehook.__name__ == "<lambda>"


def test_finishing_in_time_leaves_no_timer():
    with cpu_budget(5):
        _spin(0.05)
    assert signal.getitimer(signal.ITIMER_PROF)[0] == 0


def test_nested_budget_caught_inside_outer_still_bounds():
    t = time.process_time()
    inner = 0
    with pytest.raises(BudgetExceeded):
        with cpu_budget(0.6):
            for _ in range(20):
                try:
                    with cpu_budget(0.1):
                        _spin(5)
                except BudgetExceeded:
                    inner += 1
    # the outer 0.6 s ends the loop after about six inner budgets, not twenty
    assert 3 <= inner <= 8 and time.process_time() - t < 2


def test_inner_budget_cut_short_by_outer_raises_in_outer():
    # the inner handler only catches its own budget: the outer deadline passes through it
    caught_inside = False
    with pytest.raises(BudgetExceeded):
        with cpu_budget(0.2):
            try:
                with cpu_budget(10):
                    _spin(5)
            except BudgetExceeded:
                caught_inside = True
    assert not caught_inside
