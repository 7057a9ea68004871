"""User-facing errors: one message with a place, what is wrong and how to fix it."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Place:
    """A position in a user's file (1-based line and column; 0 means unknown)."""

    file: str = "<input>"
    line: int = 0
    col: int = 0

    def __str__(self) -> str:
        if self.line and self.col:
            return f"{self.file}:{self.line}:{self.col}"
        if self.line:
            return f"{self.file}:{self.line}"
        return self.file


class UserError(Exception):
    """An error in what the user wrote (spec, submission, option): exit code 2, no traceback."""

    def __init__(self, message: str, place: Place | None = None, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.place = place
        self.hint = hint

    def __str__(self) -> str:
        where = f"{self.place}: " if self.place else ""
        fix = f"\n  fix: {self.hint}" if self.hint else ""
        return f"{where}error: {self.message}{fix}"


class ExprError(UserError):
    """An expression that the allow-list parser refuses; `col` is 1-based within the expression text."""

    def __init__(self, message: str, text: str, col: int = 0, hint: str | None = None) -> None:
        super().__init__(message, None, hint)
        self.text = text
        self.col = col

    def __str__(self) -> str:
        base = super().__str__()
        if not self.text or len(self.text) > 200:
            return base
        caret = f"\n    {self.text}\n    {' ' * max(self.col - 1, 0)}^" if self.col else f"\n    {self.text}"
        return base + caret
