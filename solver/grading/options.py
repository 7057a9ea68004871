"""The ``grading:`` block of a problem spec: how each item is graded (read by `check` without the grader)."""
from __future__ import annotations

from typing import Literal, Optional

from pydantic import Field, ValidationError

from solver.spec.loader import validation_error
from solver.spec.models import Strict
from solver.spec.problem import Problem


class ItemSpec(Strict):
    """How one item is graded."""

    points: float = Field(1.0, ge=0, description="points for a fully correct answer")
    partial: bool = Field(True, description="matrices/vectors/lists/sets: credit proportional to correct entries")
    accept: Literal["property", "reference"] = Field(
        "property", description="property: any answer with the defining property (S, U, equilibria); "
                                "reference: must equal the reference solution")
    require_skew: bool = Field(True, description="S only: Ḃ - 2S must be skew-symmetric for full credit")
    rel_tol: Optional[float] = Field(None, ge=0, description="numbers: relative tolerance (default 1e-3)")
    abs_tol: float = Field(0.0, ge=0, description="numbers: absolute tolerance")
    sigfigs: Optional[int] = Field(None, ge=1, le=15, description="numbers: compare rounded to this many digits")
    title: Optional[str] = Field(None, description="what the item is, in the feedback")


class GradingSpec(Strict):
    """The ``grading:`` block of a problem spec."""

    items: Optional[dict[str, ItemSpec]] = Field(
        None, description="items by result name; default: every result named under expected:, 1 point each")
    time_limit: float = Field(10.0, gt=0, le=600, description="seconds per item before it is left undecided")


def grading_spec(problem: Problem) -> GradingSpec:
    """The validated grading block (errors point at the spec file)."""
    raw = (problem.located.data or {}).get("grading")
    try:
        return GradingSpec.model_validate(raw or {})
    except ValidationError as exc:
        raise validation_error(exc, problem.located, ("grading",), hint="see docs/grading.md") from None
