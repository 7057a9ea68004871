"""sympy without its units package, for the duration of a block.

sympy's ``simplify`` (and ``checksol``, behind ``solve``) import ``sympy.physics.units`` only to ask whether an
expression holds a physical ``Quantity`` (``Unit``): about 0.1 s, a tenth of a short problem's whole process,
in 55 of the library's problems. Our expressions never hold one. :func:`without_units` answers that import with
a stub whose classes nothing is an instance of, when the real package is not loaded yet; on leaving the block
the stub is removed and the real package imports as usual. If ``sympy.physics`` itself was imported inside the
block (it binds ``units`` at import), it is unloaded too, so that a later import starts clean.
"""
from __future__ import annotations

import sys
import types
from contextlib import contextmanager
from typing import Iterator

import sympy as sp

_NAME = "sympy.physics.units"


class _Never(sp.Basic):
    """A class of which no expression is an instance (``expr.has(_Never)`` is False)."""


def _stub() -> types.ModuleType:
    mod = types.ModuleType(_NAME, "stand-in for sympy.physics.units inside solver.math.nounits.without_units")
    mod.Quantity = mod.Unit = _Never  # type: ignore[attr-defined]
    return mod


@contextmanager
def without_units() -> Iterator[None]:
    """Inside the block, ``from sympy.physics.units import Quantity`` costs nothing (see the module)."""
    if _NAME in sys.modules or "sympy.physics" in sys.modules:  # loaded (or being loaded): leave it alone
        yield
        return
    stub = _stub()
    sys.modules[_NAME] = stub
    try:
        yield
    finally:
        if sys.modules.get(_NAME) is stub:
            del sys.modules[_NAME]
        if "sympy.physics" in sys.modules:  # imported inside the block, with the stub as its units: unload it
            for name in [m for m in sys.modules if m == "sympy.physics" or m.startswith("sympy.physics.")]:
                del sys.modules[name]
            if getattr(sp, "physics", None) is not None:
                del sp.physics
