"""The robot as solvers see it: bodies with CoM positions, angular velocities and inertias, all sympy in q."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from solver.results import Resolving


@dataclass
class Body(Resolving):
    """One rigid body. ``com`` is p_c(q) in the base frame; ``omega`` is the angular velocity (linear in q̇)
    expressed in the same frame as ``inertia`` (the barycentric inertia tensor), so T_rot = ½ ωᵀ I ω.
    ``com``, ``omega`` and ``rotation`` may be given :class:`solver.results.Deferred` (written when first read);
    ``trig``: (the :class:`solver.math.trigpoly.TrigAlgebra`, p_c, ω) of a body computed in the canonical form,
    which :func:`solver.dynamics.canonical.derive_canonical` takes as they are (not pickled: an optimization)."""

    name: str
    mass: sp.Expr
    com: sp.Matrix
    omega: sp.Matrix
    inertia: sp.Matrix
    rotation: sp.Matrix | None = None
    omega_frame: str = "base"  # base | link: the frame of omega and inertia, for the report
    trig: Any = field(default=None, repr=False, compare=False, metadata={"json": False})

    def __getstate__(self) -> dict[str, Any]:
        return {**super().__getstate__(), "trig": None}


@dataclass
class Robot(Resolving):
    """Generalized coordinates q (velocities dq, accelerations ddq), bodies and the non-body terms.

    Model: B(q) q̈ + c(q, q̇) + g(q) + F_v q̇ = G u, with B from T = Σ T_i + T_extra = ½ q̇ᵀ B q̇ and
    U = -Σ m_i g₀ᵀ p_ci + U_extra.
    """

    q: list[sp.Symbol]
    dq: list[sp.Symbol]
    ddq: list[sp.Symbol]
    joints: list[str]
    bodies: list[Body] = field(default_factory=list)
    gravity: sp.Matrix | None = None
    kinetic_extra: list[sp.Expr] = field(default_factory=list)
    potential_extra: list[sp.Expr] = field(default_factory=list)
    friction: sp.Matrix | None = None
    input_map: sp.Matrix | None = None
    inputs: list[sp.Symbol] = field(default_factory=list)
    given_B: sp.Matrix | None = None
    given_U: sp.Expr | None = None
    given_g: sp.Matrix | None = None
    given_c: sp.Matrix | None = None
    frames: list[sp.Matrix] = field(default_factory=list)  # DH robots: ⁰A_0 (base), ⁰A_1, ..., ⁰A_n (4x4); may be
    #                                                        given Deferred (written when first read)
    dh_convention: str | None = None                        # standard | modified (DH robots)

    @property
    def n(self) -> int:
        return len(self.q)
