"""Recursive Newton–Euler algorithm (ask kind ``newton_euler``), in the link frames of a DH robot.

Forward recursion, i = 1..n (R = ⁱ⁻¹Rᵢ, ẑ = the axis of joint i in frame i: Rᵀ e₃ standard DH, e₃ modified DH;
ω₀ = ω̇₀ = 0 and a₀ = −g₀ (gravity as an upward acceleration of the base), σ = 1 revolute, 0 prismatic):

    ωᵢ  = Rᵀ ωᵢ₋₁ + σ q̇ᵢ ẑ
    ω̇ᵢ  = Rᵀ ω̇ᵢ₋₁ + σ (q̈ᵢ ẑ + q̇ᵢ (Rᵀ ωᵢ₋₁) × ẑ)
    aᵢ  = Rᵀ aᵢ₋₁ + ω̇ᵢ × r + ωᵢ × (ωᵢ × r)                              (standard: r = ⁱr_{i−1,i}, fixed in link i)
        = Rᵀ (aᵢ₋₁ + ω̇ᵢ₋₁ × P + ωᵢ₋₁ × (ωᵢ₋₁ × P))                      (modified: P = ⁱ⁻¹P_i, fixed in link i−1)
          (+ (1 − σ)(q̈ᵢ ẑ + 2 q̇ᵢ ωᵢ × ẑ) for a prismatic joint)
    a_cᵢ = aᵢ + ω̇ᵢ × r_cᵢ + ωᵢ × (ωᵢ × r_cᵢ)

Backward recursion, i = n..1 (f_{n+1} = τ_{n+1} = 0; ⁱR_{i+1} = the next joint's R; moments about the point of
joint i's axis: O_{i−1} standard, O_i modified; ℓᵢ = from that point to the next joint's point, sᵢ = to the CoM):

    fᵢ = ⁱR_{i+1} f_{i+1} + mᵢ a_cᵢ
    τᵢ = ⁱR_{i+1} τ_{i+1} + ℓᵢ × ⁱR_{i+1} f_{i+1} + sᵢ × mᵢ a_cᵢ + Iᵢ ω̇ᵢ + ωᵢ × Iᵢ ωᵢ
    uᵢ = τᵢᵀ ẑ (revolute), fᵢᵀ ẑ (prismatic)     (+ F_v q̇ and the model terms outside the links)

(the standard-DH form is the textbook τᵢ = ⁱR_{i+1}τ_{i+1} + (ⁱR_{i+1}f_{i+1}) × r_{i,ci} − fᵢ × (r_{i−1,i} + r_{i,ci})
+ Iᵢω̇ᵢ + ωᵢ × Iᵢωᵢ, rearranged). As a routine, NE_γ(q, q̇, q̈) with gravity switch γ gives g(q) = NE(q, 0, 0),
c(q, q̇) + F_v q̇ = NE₀(q, q̇, 0) (the friction of the model is in u), b_j(q) = NE₀(q, 0, e_j), B q̈ + g = NE(q, 0, q̈),
T = q̇ᵀ NE₀(q, 0, q̇/2); NE₀ leaves out all of g(q) (gravity, and springs or a given U/g added from the model).

Every quantity is computed as a trigonometric polynomial of :mod:`solver.math.trigpoly` (exact; nothing simplified
in between) and each reported one is written once at the end, in the form ``tidy`` gives; data outside that
algebra (floats, parameters in denominators) take the step-by-step path with ``tidy``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import sympy as sp
from pydantic import Field

from solver.dynamics.model import LARGE_MODEL, abbreviate, derive, node_count, require_model
from solver.math.simplify import is_zero, tidy, tidy_matrix
from solver.math.trigpoly import NotTrigPolynomial, TrigAlgebra
from solver.registry import ask_kind
from solver.results import Solution
from solver.spec.errors import UserError
from solver.spec.models import ExprT, Strict
from solver.spec.robot import Robot

E3 = sp.Matrix([0, 0, 1])


@dataclass
class Joint:
    """Constant data of joint i, in frame i (all functions of q)."""

    R: sp.Matrix        # ⁱ⁻¹Rᵢ
    z: sp.Matrix        # joint axis in frame i
    r: sp.Matrix        # standard: ⁱr_{i−1,i} = Rᵢᵀ (Oᵢ − Oᵢ₋₁);  modified: ⁱ⁻¹Pᵢ = Rᵢ₋₁ᵀ (Oᵢ − Oᵢ₋₁)
    rc: sp.Matrix       # CoM from Oᵢ, in frame i
    prismatic: bool
    mass: sp.Expr
    inertia: sp.Matrix


@dataclass
class LinkState:
    """What the recursions give for link i (frame i)."""

    w: sp.Matrix
    dw: sp.Matrix
    a: sp.Matrix
    ac: sp.Matrix
    f: sp.Matrix = field(default_factory=lambda: sp.zeros(3, 1))
    tau: sp.Matrix = field(default_factory=lambda: sp.zeros(3, 1))
    u: sp.Expr = field(default_factory=lambda: sp.Integer(0))


@dataclass
class NEResult:
    links: list[LinkState]
    u: sp.Matrix               # generalized forces from the links (+ friction and extra terms when asked)
    a0: sp.Matrix              # base acceleration used (−g₀ in frame 0, or 0)


def _cross(a: sp.Matrix, b: sp.Matrix) -> sp.Matrix:
    return a.cross(b)


def joints_of(robot: Robot) -> list[Joint]:
    """Per-joint data from the frames ⁰A₀ (base), ⁰A₁, ..., ⁰Aₙ of a DH robot."""
    if not robot.frames or len(robot.frames) != robot.n + 1:
        raise ValueError("Newton-Euler needs the link frames (a robot given by dh:)")
    modified = robot.dh_convention == "modified"
    out = []
    for i in range(1, robot.n + 1):
        A0, A1 = robot.frames[i - 1], robot.frames[i]
        R0, R1 = A0[:3, :3], A1[:3, :3]
        dp = A1[:3, 3] - A0[:3, 3]
        R = (R0.T * R1).applyfunc(tidy)
        z = E3 if modified else R.T * E3
        r = (R0.T * dp) if modified else (R1.T * dp)
        b = robot.bodies[i - 1]
        rc = (R1.T * (b.com - A1[:3, 3])).applyfunc(tidy)
        out.append(Joint(R, z.applyfunc(tidy), r.applyfunc(tidy), rc, robot.joints[i - 1] == "P", b.mass, b.inertia))
    return out


def _t(m: sp.Matrix, simplify: bool) -> sp.Matrix:
    return m.applyfunc(tidy) if simplify else m.applyfunc(sp.expand)


def newton_euler(robot: Robot, dq: list[sp.Expr], ddq: list[sp.Expr], gravity: bool = True,
                 q: list[sp.Expr] | None = None, simplify: bool = True, extras: bool = True,
                 links: bool = True) -> NEResult:
    """NE_γ(q, q̇, q̈): the generalized forces u for the given velocities and accelerations (γ: gravity on/off),
    with every link's ω, ω̇, a, a_c (forward) and f, τ (backward) in its own frame (written out only with
    ``links``; without, the LinkStates are empty and only u is given).

    In the canonical trigonometric-polynomial form throughout when the data allow (:func:`_canonical`), each
    reported quantity written once at the end in the form :func:`tidy` gives; else step by step with ``tidy``
    (or only expanded, ``simplify=False``)."""
    if simplify:
        res = _canonical(robot, dq, ddq, gravity, q, links, extras)
        if res is not None:
            return res
    joints = joints_of(robot)
    subs = dict(zip(robot.q, q)) if q is not None else {}
    if subs:
        joints = [Joint(j.R.subs(subs), j.z.subs(subs), j.r.subs(subs), j.rc.subs(subs), j.prismatic, j.mass,
                        j.inertia.subs(subs)) for j in joints]
    modified = robot.dh_convention == "modified"
    g0 = robot.gravity if (gravity and robot.gravity is not None) else sp.zeros(3, 1)
    if g0.shape[0] == 2:
        g0 = g0.col_join(sp.zeros(1, 1))
    a0 = _t(robot.frames[0][:3, :3].T * (-g0), simplify)
    w, dw, a = sp.zeros(3, 1), sp.zeros(3, 1), a0
    states: list[LinkState] = []
    for i, j in enumerate(joints):
        Rt = j.R.T
        w_prev = Rt * w
        if j.prismatic:
            wi, dwi = w_prev, Rt * dw
        else:
            wi = w_prev + dq[i] * j.z
            dwi = Rt * dw + ddq[i] * j.z + dq[i] * _cross(w_prev, j.z)
        wi, dwi = _t(wi, simplify), _t(dwi, simplify)
        if modified:
            ai = Rt * (a + _cross(dw, j.r) + _cross(w, _cross(w, j.r)))
        else:
            ai = Rt * a + _cross(dwi, j.r) + _cross(wi, _cross(wi, j.r))
        if j.prismatic:
            ai += ddq[i] * j.z + 2 * dq[i] * _cross(wi, j.z)
        ai = _t(ai, simplify)
        aci = _t(ai + _cross(dwi, j.rc) + _cross(wi, _cross(wi, j.rc)), simplify)
        states.append(LinkState(wi, dwi, ai, aci))
        w, dw, a = wi, dwi, ai
    f_next, t_next, R_next = sp.zeros(3, 1), sp.zeros(3, 1), sp.eye(3)
    u = sp.zeros(robot.n, 1)
    for i in reversed(range(robot.n)):
        j, s = joints[i], states[i]
        if modified:
            ell = joints[i + 1].r if i + 1 < robot.n else sp.zeros(3, 1)
            si = j.rc
        else:
            ell = j.r
            si = j.r + j.rc
        Rf = R_next * f_next
        ma = j.mass * s.ac
        s.f = _t(Rf + ma, simplify)
        s.tau = _t(R_next * t_next + _cross(ell, Rf) + _cross(si, ma) + j.inertia * s.dw
                   + _cross(s.w, j.inertia * s.w), simplify)
        s.u = tidy((s.f.T * j.z)[0] if j.prismatic else (s.tau.T * j.z)[0]) if simplify else \
            sp.expand((s.f.T * j.z)[0] if j.prismatic else (s.tau.T * j.z)[0])
        u[i] = s.u
        f_next, t_next, R_next = s.f, s.tau, j.R
    if extras:
        u += extra_terms(robot, dq, ddq, q, potential=gravity)
    return NEResult(states, tidy_matrix(u) if simplify else u, a0)


# ------------------------------------------------------------------------------------------ canonical form
def _canonical(robot: Robot, dq: list[sp.Expr], ddq: list[sp.Expr], gravity: bool, q: list[sp.Expr] | None,
               links: bool, extras: bool) -> NEResult | None:
    """The recursions of :func:`newton_euler` on :class:`TrigAlgebra` elements (exact, nothing simplified in
    between); None when the data leave the algebra (floats, parameters in denominators, other offsets)."""
    n = robot.n
    subs = dict(zip(robot.q, q)) if q is not None else {}
    frames = [F[:3, :] for F in robot.frames]
    coms = [b.com for b in robot.bodies]
    inertias = [b.inertia for b in robot.bodies]
    if subs:
        frames = [F.subs(subs) for F in frames]
        coms = [c.subs(subs) for c in coms]
        inertias = [m.subs(subs) for m in inertias]
    g0 = robot.gravity if (gravity and robot.gravity is not None) else sp.zeros(3, 1)
    if g0.shape[0] == 2:
        g0 = g0.col_join(sp.zeros(1, 1))
    extra = extra_terms(robot, dq, ddq, q, potential=gravity) if extras and has_extras(robot) else None
    masses = [b.mass for b in robot.bodies]
    try:
        A = TrigAlgebra.of(frames + coms + inertias + masses + [g0] + list(dq) + list(ddq),
                           extra=list(robot.q) + list(robot.dq) + list(robot.ddq))
        conv = A.conv
        add, mul = A.add, A.mul

        def mv(M: list, v: list) -> list:  # M v
            return [A.dot(row, v) for row in M]

        def mtv(M: list, v: list) -> list:  # Mᵀ v
            return [A.dot([M[0][j], M[1][j], M[2][j]], v) for j in range(3)]

        def cross(a: list, b: list) -> list:
            return [A.sub(mul(a[1], b[2]), mul(a[2], b[1])), A.sub(mul(a[2], b[0]), mul(a[0], b[2])),
                    A.sub(mul(a[0], b[1]), mul(a[1], b[0]))]

        def vadd(*vs: list) -> list:
            return [add(*xs) for xs in zip(*vs)]

        def vscale(v: list, c: dict) -> list:
            return [mul(x, c) for x in v]

        Rs = [[[conv(F[r, c]) for c in range(3)] for r in range(3)] for F in frames]
        ps = [[conv(F[r, 3]) for r in range(3)] for F in frames]
        modified = robot.dh_convention == "modified"
        J = []  # per joint: R = ⁱ⁻¹Rᵢ, ẑ, r, r_c, mass, inertia
        for i in range(1, n + 1):
            R0, R1 = Rs[i - 1], Rs[i]
            R = A.matmul(A.T(R0), R1)
            z = [{}, {}, conv(sp.Integer(1))] if modified else list(R[2])
            dp = [A.sub(x, y) for x, y in zip(ps[i], ps[i - 1])]
            r = mtv(R0, dp) if modified else mtv(R1, dp)
            rc = mtv(R1, [A.sub(conv(x), y) for x, y in zip(coms[i - 1], ps[i])])
            J.append((R, z, r, rc, conv(masses[i - 1]), A.matrix(inertias[i - 1])))
        V, Acc = [conv(x) for x in dq], [conv(x) for x in ddq]
        a0 = mtv(Rs[0], [A.scale(conv(x), -1) for x in g0])
        zero = [{}, {}, {}]
        w, dw, a = zero, zero, a0
        fwd = []
        for i, (R, z, r, rc, _, _) in enumerate(J):
            prismatic = robot.joints[i] == "P"
            w_prev = mtv(R, w)
            if prismatic:
                wi, dwi = w_prev, mtv(R, dw)
            else:
                wi = vadd(w_prev, vscale(z, V[i]))
                dwi = vadd(mtv(R, dw), vscale(z, Acc[i]), vscale(cross(w_prev, z), V[i]))
            if modified:
                ai = mtv(R, vadd(a, cross(dw, r), cross(w, cross(w, r))))
            else:
                ai = vadd(mtv(R, a), cross(dwi, r), cross(wi, cross(wi, r)))
            if prismatic:
                ai = vadd(ai, vscale(z, Acc[i]), vscale(cross(wi, z), A.scale(V[i], 2)))
            aci = vadd(ai, cross(dwi, rc), cross(wi, cross(wi, rc)))
            fwd.append([wi, dwi, ai, aci])
            w, dw, a = wi, dwi, ai
        f_next, t_next, R_next = zero, zero, None
        U: list = [None] * n
        for i in reversed(range(n)):
            R, z, r, rc, m, I = J[i]
            wi, dwi, _, aci = fwd[i]
            if modified:
                ell, si = (J[i + 1][2] if i + 1 < n else zero), rc
            else:
                ell, si = r, vadd(r, rc)
            Rf = mv(R_next, f_next) if R_next is not None else zero
            Rt = mv(R_next, t_next) if R_next is not None else zero
            ma = vscale(aci, m)
            fi = vadd(Rf, ma)
            ti = vadd(Rt, cross(ell, Rf), cross(si, ma), mv(I, dwi), cross(wi, mv(I, wi)))
            U[i] = A.dot(fi if robot.joints[i] == "P" else ti, z)
            fwd[i] += [fi, ti]
            f_next, t_next, R_next = fi, ti, R
        U_links = list(U)
        if extra is not None:
            try:
                U = [add(x, conv(e)) for x, e in zip(U, extra)]
                extra = None
            except NotTrigPolynomial:  # e.g. a friction matrix with floats: added in sympy below
                pass
    except NotTrigPolynomial:
        return None
    vec = lambda v: sp.Matrix([A.expr(x) for x in v])  # noqa: E731
    u = sp.Matrix([A.expr(x) for x in U])
    if extra is not None:
        u = tidy_matrix(u + extra)
    states = []
    for i, (wi, dwi, ai, aci, fi, ti) in enumerate(fwd):
        if links:
            states.append(LinkState(vec(wi), vec(dwi), vec(ai), vec(aci), vec(fi), vec(ti),
                                    A.expr(U_links[i])))
        else:
            states.append(LinkState(sp.zeros(3, 1), sp.zeros(3, 1), sp.zeros(3, 1), sp.zeros(3, 1)))
    return NEResult(states, u, vec(a0))


def abbreviated(res: NEResult, robot: Robot) -> dict | None:
    """Past LARGE_MODEL nodes in u, the recursion as the Lagrangian model's report writes a large model (SYMORO's
    customized symbolic model): each sum of parameters a K_j defined once, every ω, ω̇, a, a_c, f, τ, u written
    with them; {"defs": [(K_j, sum)], "links": [LinkState], "u": u}. None below the size."""
    if node_count(res.u, LARGE_MODEL) <= LARGE_MODEL:
        return None
    keys = ("w", "dw", "a", "ac", "f", "tau")
    out = abbreviate({**{k: [getattr(s, k) for s in res.links] for k in keys},
                      "uk": [sp.Matrix([s.u]) for s in res.links], "u": res.u}, set(robot.q + robot.dq + robot.ddq))
    links = [LinkState(*[out[k][i] for k in keys], out["uk"][i][0]) for i in range(len(res.links))]
    return {"defs": out["defs"], "links": links, "u": out["u"]}


def same_function(x: sp.Matrix, y: sp.Matrix) -> bool:
    """x ≡ y entry by entry: compared in one trigonometric-polynomial algebra (exact, no expansion), else by
    :func:`is_zero` of the expanded differences."""
    try:
        A = TrigAlgebra.of(list(x) + list(y))
        return x.shape == y.shape and all(A.conv(a) == A.conv(b) for a, b in zip(x, y))
    except NotTrigPolynomial:
        return all(is_zero(sp.expand(d)) for d in (x - y))


def has_friction(robot: Robot) -> bool:
    """Whether the model has a viscous friction term F_v q̇ (not identically 0)."""
    return robot.friction is not None and any(x != 0 for x in robot.friction)


def has_potential(robot: Robot) -> bool:
    """Whether g(q) has terms besides gravity (springs, a given U or g): NE₀ leaves them out too."""
    return bool(robot.potential_extra or robot.given_g is not None or robot.given_U is not None)


def has_extras(robot: Robot) -> bool:
    return bool(robot.kinetic_extra or robot.potential_extra or robot.given_B is not None
                or robot.given_g is not None or robot.given_U is not None or robot.friction is not None)


def extra_terms(robot: Robot, dq: list[sp.Expr], ddq: list[sp.Expr], q: list[sp.Expr] | None = None,
                potential: bool = True) -> sp.Matrix:
    """Model terms the link bodies do not carry (motor kinetic energy, springs, given B/U/g, friction F_v q̇),
    from their Lagrangian: B_x q̈ + c_x + g_x + F_v q̇; without g_x (``potential`` False) in NE₀, which leaves out
    all of g(q) so that NE₀(q, 0, e_j) = b_j and q̇ᵀNE₀(q, 0, q̇/2) = T hold with springs too."""
    if not has_extras(robot):
        return sp.zeros(robot.n, 1)
    bare = Robot(q=robot.q, dq=robot.dq, ddq=robot.ddq, joints=robot.joints, gravity=None,
                 kinetic_extra=robot.kinetic_extra, potential_extra=robot.potential_extra, friction=robot.friction,
                 given_B=robot.given_B, given_U=robot.given_U, given_g=robot.given_g)
    dm = derive(bare)
    lhs = dm.lhs if potential else dm.lhs - dm.g
    subs = {**dict(zip(robot.dq, dq)), **dict(zip(robot.ddq, ddq)), **(dict(zip(robot.q, q)) if q else {})}
    return lhs.xreplace(subs) if subs else lhs


# ------------------------------------------------------------------------------------------------ the ask
ROUTINES = ("gravity", "coriolis", "static", "inertia", "kinetic_energy")


class NECall(Strict):
    """One call NE_γ(q, q̇, q̈) of the routine."""

    name: str = Field(description="result name of the output vector (letters, digits, _)")
    q: ExprT | None = Field(None, description="configuration (default: the symbolic q)")
    dq: ExprT = Field(0, description="velocity argument: a list of n expressions, or 0")
    ddq: ExprT = Field(0, description="acceleration argument: a list of n expressions, or 0")
    gravity: bool = Field(True, description="with gravity (NE_g) or without (NE_0: without all of g(q), springs and "
                                            "given potential terms too)")
    dot_with: ExprT | None = Field(None, description="also the scalar product vᵀ y with this vector "
                                                         "(result <name>_dot), e.g. dq for T = q̇ᵀ NE₀(q, 0, q̇/2)")


class NewtonEulerAsk(Strict):
    """The recursive Newton–Euler algorithm on a DH robot."""

    kind: Literal["newton_euler"]
    title: str | None = Field(None, description="heading of this part in the report")
    model: bool = Field(True, description="run NE(q, q̇, q̈) symbolically, recursions shown step by step (results "
                                          "ne_w<i>, ne_dw<i>, ne_a<i>, ne_ac<i>, ne_f<i>, ne_tau<i>, ne_u)")
    gravity: bool = Field(True, description="gravity in the model run (a₀ = −g₀); false: NE₀, without all of g(q)")
    routines: list[Literal["gravity", "coriolis", "static", "inertia", "kinetic_energy"]] = Field(
        [], description="NE used as a routine: gravity = NE(q,0,0) -> ne_g; coriolis = NE₀(q,q̇,0) -> ne_c "
                        "(c + F_v q̇ when the robot has friction); "
                        "static = NE(q,0,q̈) -> ne_static (B q̈ + g); inertia = NE₀(q,0,e_j), j = 1..n -> ne_B; "
                        "kinetic_energy = q̇ᵀ NE₀(q,0,q̇/2) -> ne_T")
    calls: list[NECall] = Field([], description="further calls with given arguments")
    check: bool = Field(True, description="compare with the Lagrangian model (result ne_equals_lagrange)")
    at: dict[str, str | int | float] | None = Field(
        None, description="a state (q, dq, ddq values) where ne_u is also evaluated (ne_u_at)")


def _vector_arg(value: Any, n: int, place, what: str) -> list[sp.Expr]:  # type: ignore[no-untyped-def]
    if isinstance(value, list) and len(value) == n:
        return [sp.sympify(v) for v in value]
    if isinstance(value, sp.MatrixBase) and len(value) == n:
        return list(value)
    if not isinstance(value, (list, sp.MatrixBase)) and sp.sympify(value) == 0:
        return [sp.Integer(0)] * n
    raise UserError(f"{what} must be a list of {n} expressions or 0", place, "e.g. [dq1, dq2]")


def _dh_robot(problem) -> Robot:  # type: ignore[no-untyped-def]
    robot = require_model(problem)
    if not robot.frames or not robot.bodies:
        raise UserError("newton_euler needs the link frames: give the robot by dh:",
                        problem.located.place(("robot",)), "write the robot as a DH table with dh: {table, links}")
    return robot


def _call_args(problem, ctx, c, k: int, n: int) -> tuple:  # type: ignore[no-untyped-def]
    """The arguments of call k of the routine: q (None: the robot's), q̇, q̈ and the vector of dot_with (or None)."""
    if not c.name.replace("_", "").isalnum() or not c.name[0].isalpha():
        raise UserError(f"call name '{c.name}' is not a plain name", problem.located.place(ctx.path + ("calls", k, "name")),
                        "use letters, digits and _")

    def place(f: str):  # type: ignore[no-untyped-def]
        return problem.located.place(ctx.path + ("calls", k, f))

    qa = _vector_arg(ctx.expr("calls", k, "q"), n, place("q"), "q") if c.q is not None else None
    dqa = _vector_arg(ctx.expr("calls", k, "dq"), n, place("dq"), "dq")
    ddqa = _vector_arg(ctx.expr("calls", k, "ddq"), n, place("ddq"), "ddq")
    v = _vector_arg(ctx.expr("calls", k, "dot_with"), n, place("dot_with"), "dot_with") if c.dot_with is not None \
        else None
    return qa, dqa, ddqa, v


def _state(problem, options: NewtonEulerAsk, ctx, robot: Robot) -> dict:  # type: ignore[no-untyped-def]
    """The ``at:`` state by coordinate, velocity or acceleration symbol."""
    state = {}
    for name in options.at or {}:
        sym = problem.names.get(name)
        if sym is None or sym not in robot.q + robot.dq + robot.ddq:
            raise UserError(f"'{name}' in at: is not a coordinate, velocity or acceleration",
                            problem.located.place(ctx.path + ("at", name)), "use q1, dq1, ddq1, ...")
        state[sym] = ctx.expr("at", name)
    return state


def validate_newton_euler(problem, options: NewtonEulerAsk, ctx) -> None:  # type: ignore[no-untyped-def]
    """The ask's options read and checked as :func:`solve_newton_euler` reads them (the DH robot, the calls, the
    state of the model's value), without the recursions."""
    robot = _dh_robot(problem)
    for k, c in enumerate(options.calls):
        _call_args(problem, ctx, c, k, robot.n)
    if options.model:
        _state(problem, options, ctx, robot)


@ask_kind("newton_euler", NewtonEulerAsk, "recursive Newton–Euler: forward/backward recursions, NE as a routine",
          validate=validate_newton_euler)
def solve_newton_euler(problem, options: NewtonEulerAsk, ctx) -> Solution:  # type: ignore[no-untyped-def]
    """Results: ne_u (+ per link ne_w<i>, ne_dw<i>, ne_a<i>, ne_ac<i>, ne_f<i>, ne_tau<i>), ne_g, ne_c, ne_static,
    ne_B, ne_T, the calls' names, ne_equals_lagrange, ne_u_at."""
    robot = _dh_robot(problem)
    n = robot.n
    sol = Solution("newton_euler", title=options.title or "Newton–Euler algorithm")
    joints = joints_of(robot)
    sol.step("setup", joints=joints, robot=robot, modified=robot.dh_convention == "modified",
             extras=has_extras(robot))
    zero = [sp.Integer(0)] * n
    ne_u = None
    if options.model:
        res = newton_euler(robot, robot.dq, robot.ddq, options.gravity)
        ne_u = res.u
        for i, s in enumerate(res.links, 1):
            sol.add(f"ne_w{i}", s.w, "vector", label=f"{{}}^{i}\\omega_{{{i}}}")
            sol.add(f"ne_dw{i}", s.dw, "vector", label=f"{{}}^{i}\\dot\\omega_{{{i}}}")
            sol.add(f"ne_a{i}", s.a, "vector", label=f"{{}}^{i}a_{{{i}}}")
            sol.add(f"ne_ac{i}", s.ac, "vector", label=f"{{}}^{i}a_{{c{i}}}")
            sol.add(f"ne_f{i}", s.f, "vector", label=f"{{}}^{i}f_{{{i}}}")
            sol.add(f"ne_tau{i}", s.tau, "vector", label=f"{{}}^{i}\\tau_{{{i}}}")
        sol.add("ne_u", res.u, "vector", label="u")
        sol.step("model", res=res, gravity=options.gravity, modified=robot.dh_convention == "modified",
                 abbr=abbreviated(res, robot), **({"potential": True} if has_potential(robot) else {}))
    routine_out = []
    friction = has_friction(robot)
    c_label = "c(q,\\dot q) + F_v\\dot q" if friction else "c(q,\\dot q)"   # the friction is in the recursion's u
    names = {"gravity": ("ne_g", "g(q) = NE(q, 0, 0)"), "coriolis": ("ne_c", c_label + " = NE_0(q, \\dot q, 0)"),
             "static": ("ne_static", "B(q)\\ddot q + g(q) = NE(q, 0, \\ddot q)"),
             "inertia": ("ne_B", "B(q) = \\big[NE_0(q, 0, e_1)\\ \\cdots\\ NE_0(q, 0, e_n)\\big]"),
             "kinetic_energy": ("ne_T", "T = \\dot q^T NE_0(q, 0, \\tfrac12 \\dot q)")}
    for r in options.routines:
        if r == "gravity":
            val = newton_euler(robot, zero, zero, True, links=False).u
        elif r == "coriolis":
            val = newton_euler(robot, robot.dq, zero, False, links=False).u
        elif r == "static":
            val = newton_euler(robot, zero, robot.ddq, True, links=False).u
        elif r == "inertia":
            cols = [newton_euler(robot, zero, [sp.Integer(int(k == j)) for k in range(n)], False, links=False).u
                    for j in range(n)]
            val = sp.Matrix.hstack(*cols)
        else:
            y = newton_euler(robot, zero, [v / 2 for v in robot.dq], False, links=False).u
            val = tidy((sp.Matrix(robot.dq).T * y)[0])
        name, label = names[r]
        sol.add(name, val, label=label.split(" = ")[0])
        routine_out.append((r, label, val))
    calls_out = []
    for k, c in enumerate(options.calls):
        qa, dqa, ddqa, v = _call_args(problem, ctx, c, k, n)
        y = newton_euler(robot, dqa, ddqa, c.gravity, q=qa, links=False).u
        sol.add(c.name, y, "vector", label=c.name)
        dot = None
        if v is not None:
            dot = tidy((sp.Matrix(v).T * y)[0])
            sol.add(f"{c.name}_dot", dot, "scalar", label=f"v^T {c.name}")
        calls_out.append((c, qa, dqa, ddqa, y, dot))
    if routine_out or calls_out:
        sol.step("routines", routines=routine_out, calls=calls_out, robot=robot,
                 **({"potential": True} if has_potential(robot) else {}))
    if options.check:
        dm = derive(robot)

        def lag(grav: bool, dq: list, ddq: list) -> sp.Matrix:
            """The Lagrangian left-hand side B q̈ + c + g (+ F_v q̇) with g(q) on/off, at (q̇, q̈)."""
            return (dm.lhs if grav else dm.lhs - dm.g).xreplace({**dict(zip(robot.dq, dq)), **dict(zip(robot.ddq, ddq))})

        ok = True
        if ne_u is not None:
            ok = same_function(ne_u, lag(options.gravity, robot.dq, robot.ddq))
        ref = {"gravity": lambda: lag(True, zero, zero), "coriolis": lambda: lag(False, robot.dq, zero),
               "static": lambda: lag(True, zero, robot.ddq),
               "inertia": lambda: sp.Matrix.hstack(*[lag(False, zero, [int(k == j) for k in range(n)])
                                                     for j in range(n)]),
               "kinetic_energy": lambda: sp.Matrix([dm.T])}
        for r, _, val in routine_out:
            ok = ok and same_function(val if isinstance(val, sp.MatrixBase) else sp.Matrix([val]), ref[r]())
        sol.add("ne_equals_lagrange", bool(ok), "bool", label="\\text{NE} = \\text{Lagrange}")
        sol.step("check", ok=ok, dm=dm, **({"friction": True} if friction else {}))
    if options.at and ne_u is not None:
        state = _state(problem, options, ctx, robot)
        subs = {**problem.values, **{x: v.subs(problem.values) for x, v in state.items()}}
        val = ne_u.subs(subs).applyfunc(lambda e: sp.nsimplify(e) if e.is_number and not e.atoms(sp.Float) else e)
        sol.add("ne_u_at", val, "vector", label="u\\big|_{*}")
        sol.step("at", state=state, value=val)
    return sol

