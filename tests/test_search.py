"""Golden-section search (solver.math.search), which replaced scipy's bounded minimize_scalar."""
from __future__ import annotations

import math

import pytest

from solver.math.search import golden_min


@pytest.mark.parametrize("x0", [0.3, 0.0001, 0.9999, 0.5])
def test_golden_min_finds_the_minimum_of_a_unimodal_function(x0: float) -> None:
    x, fx = golden_min(lambda x: (x - x0) ** 2 + 1.0, 0.0, 1.0, 1e-12)
    assert abs(x - x0) < 1e-6 and abs(fx - 1.0) < 1e-12


def test_golden_min_at_an_end_and_on_a_grid_cell() -> None:
    x, fx = golden_min(lambda x: x, 2.0, 3.0, 1e-12)          # monotone: the left end
    assert x == 2.0 and fx == 2.0
    # |sin| on a cell around its peak (the use in planning.laws: maximize |q(t)| near the best grid sample)
    x, fx = golden_min(lambda t: -abs(math.sin(t)), 1.5, 1.65, 1e-12)
    assert abs(x - math.pi / 2) < 1e-6 and abs(fx + 1.0) < 1e-12
