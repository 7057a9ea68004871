"""The spec format as pydantic models: validation and the JSON Schema (`robosolve schema`).

The `asks:` list is the union of every registered ask kind's options model (:func:`spec_model`); reading a spec
builds the union of only the kinds it uses (:func:`spec_kinds`), so that only their modules are imported.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model

from solver.registry import ASKS, ask_kinds, kind_modules, load_all

Scalar = Union[str, int, float]
ExprT = Union[str, int, float, list[Any]]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Source(Strict):
    file: str = Field(description="seed file the exercise comes from")
    lines: Optional[list[int]] = Field(None, description="[first, last] line of the exercise in that file")


class SymbolInfo(Strict):
    meaning: str = Field(description="what the symbol is (shown in reports)")
    sign: Literal["positive", "nonnegative", "real", "nonzero", "negative"] = Field(
        "positive", description="assumption on the symbol's value (default: real and positive)")
    latex: Optional[str] = Field(None, description="LaTeX name, e.g. 'I_{2,xx}' (default: derived from the name)")


class Link(Strict):
    """A body in explicit form: what exam solutions write down."""

    name: Optional[str] = Field(None, description="label in the report (default: link i)")
    mass: Scalar = Field(0, description="mass m_i")
    com: ExprT = Field(description="CoM position p_ci(q) in the base frame, 2 (planar) or 3 components")
    angle: Optional[Scalar] = Field(None, description="planar: absolute orientation of the body in the plane (ω = d(angle)/dt about z)")
    rotation: Optional[ExprT] = Field(None, description="spatial: rotation matrix ⁰R_i(q) of the body frame; inertia then in body frame")
    omega: Optional[ExprT] = Field(None, description="spatial: angular velocity (linear in dq), in the frame of `inertia`")
    inertia: ExprT = Field(0, description="barycentric inertia: scalar (about the plane normal), [Ixx, Iyy, Izz] or a 3x3 tensor")


class DHRow(Strict):
    a: Scalar = 0
    alpha: Scalar = 0
    d: Scalar = 0
    theta: Scalar = 0


class DHLink(Strict):
    name: Optional[str] = None
    mass: Scalar = Field(0, description="mass m_i")
    com: ExprT = Field([0, 0, 0], description="CoM position in frame i (3 components)")
    inertia: ExprT = Field(0, description="barycentric inertia in frame i: [Ixx, Iyy, Izz], 3x3, or scalar Izz")


class DH(Strict):
    convention: Literal["standard", "modified"] = Field("standard", description="standard (distal) or modified (Craig) DH")
    table: list[DHRow] = Field(description="one row per joint: a, alpha, d, theta (joint variables q_i inside)")
    links: list[DHLink] = Field(description="inertial data of each link, in its own DH frame")
    base: Optional[ExprT] = Field(None, description="optional 4x4 transform from the world frame to frame 0")


class Extra(Strict):
    kinetic: list[Scalar] = Field([], description="added kinetic energy terms, quadratic in the velocities (motor rotors)")
    potential: list[Scalar] = Field([], description="added potential energy terms (springs of elastic joints)")


class Friction(Strict):
    viscous: Optional[ExprT] = Field(None, description="viscous friction F_v: list (diagonal) or n x n matrix; adds F_v q̇")


class GivenModel(Strict):
    B: Optional[ExprT] = Field(None, description="inertia matrix B(q)")
    U: Optional[Scalar] = Field(None, description="potential energy U(q)")
    g: Optional[ExprT] = Field(None, description="gravity vector g(q)")
    c: Optional[ExprT] = Field(None, description="Coriolis/centrifugal vector c(q, dq), if given instead of derived")


class InputName(Strict):
    name: str = Field(description="the input's name in expressions, e.g. utheta1")
    latex: Optional[str] = Field(None, description="how it prints in LaTeX, e.g. u_{\\theta,1}")


class RobotSpec(Strict):
    joints: list[Literal["R", "P"]] = Field(description="joint types in order; coordinates q1..qn")
    coordinates: Optional[list[str]] = Field(
        None, description="names of all generalized coordinates (default q1..qn); velocities d<name>, accelerations dd<name>")
    gravity: Optional[ExprT] = Field(None, description="gravity acceleration vector g0 in the base frame, e.g. [0, -g0, 0]; U = -Σ m_i g0ᵀ p_ci")
    links: Optional[list[Link]] = Field(None, description="explicit bodies")
    dh: Optional[DH] = Field(None, description="bodies from a DH table")
    extra: Optional[Extra] = None
    friction: Optional[Friction] = None
    input_map: Optional[ExprT] = Field(None, description="G(q): generalized forces = G u (default identity)")
    inputs: Optional[list[Union[str, InputName]]] = Field(
        None, description="names of the inputs u (default u1..um); {name: ..., latex: ...} to choose how one prints")
    model: Optional[GivenModel] = Field(None, description="model given directly instead of (or besides) bodies")


class SpecBase(Strict):
    id: str = Field(description="unique id, e.g. 2004-03-25-ex1")
    title: str = Field(description="one-line title")
    source: Optional[Source] = None
    topics: list[str] = Field([], description="topic tags")
    statement: str = Field("", description="the problem text, Markdown with $...$ math")
    symbols: dict[str, Union[str, SymbolInfo]] = Field(
        {}, description="every parameter with its meaning; real and positive unless `sign` says otherwise")
    values: dict[str, Scalar] = Field({}, description="numeric values of parameters, for numeric results")
    robot: Optional[RobotSpec] = None
    known: list[str] = Field([], description="quantities taken as known (kinematic data), vs. dynamic parameters")
    expected: dict[str, Any] = Field({}, description="printed results for `robosolve verify` (see docs/spec.md)")
    grading: Optional[dict[str, Any]] = Field(None, description="grading options (see docs/grading.md)")
    notes: str = Field("", description="free notes: assumptions, reconstruction of lost figures, errata")
    asks: list[Any] = Field(description="what is asked, in order")  # (typed by spec_model; see validate_spec)


def validate_spec(data: Any) -> SpecBase:
    """``spec_model(spec_kinds(data)).model_validate(data)``. When every ask names a known kind, without building
    that model (pydantic builds the union's schema once per process, more than validating a spec costs): the
    spec's fields by :class:`SpecBase`, each ask by its kind's options model, as the union discriminated by
    `kind` would. Any error: the union model validates, for its errors as they are."""
    kinds = spec_kinds(data)
    found = ask_kinds(kinds) if kinds is not None else None
    if found is not None:
        try:
            spec = SpecBase.model_validate(data)
            spec.asks = [found[k].options.model_validate(a) for k, a in zip(kinds, data["asks"])]
            return spec
        except ValidationError:
            pass
    return spec_model(kinds).model_validate(data)


def spec_model(kinds: tuple[str, ...] | None = None) -> type[BaseModel]:
    """The Spec model with `asks` as the union of the options of the ask kinds ``kinds`` (their modules imported
    on demand), or of every registered ask kind (None, or a name that no module registers; `robosolve schema`).
    The same errors either way for a spec whose asks all have one of ``kinds`` (the union is discriminated by
    `kind`)."""
    if kinds is None or ask_kinds(kinds) is None:
        kinds = tuple(load_all())
    return _spec_model(tuple(sorted(set(kinds), key=_order)))


def _order(name: str) -> tuple[int, str]:
    index = list(kind_modules())
    return (index.index(name), "") if name in index else (len(index), name)


@lru_cache(maxsize=64)
def _spec_model(kinds: tuple[str, ...]) -> type[BaseModel]:
    models = tuple(ASKS[k].options for k in kinds)
    item = Annotated[Union[models], Field(discriminator="kind")]
    return create_model("Spec", __base__=SpecBase,
                        asks=(list[item], Field(description="what is asked, in order")))  # type: ignore[valid-type]


def spec_kinds(data: Any) -> tuple[str, ...] | None:
    """The ask kinds a spec's data names, when every ask is a mapping with a known `kind` (else None: validate
    with every kind, for the errors that list them)."""
    asks = data.get("asks") if isinstance(data, dict) else None
    if not isinstance(asks, list) or not asks:
        return None
    index = kind_modules()
    kinds = []
    for a in asks:
        k = a.get("kind") if isinstance(a, dict) else None
        if not isinstance(k, str) or k not in index:
            return None
        kinds.append(k)
    return tuple(kinds)


def json_schema() -> dict[str, Any]:
    """JSON Schema of the spec format."""
    schema = spec_model().model_json_schema()
    schema["title"] = "robosolve problem spec"
    return schema


def is_exam_data(data: Any) -> bool:
    """Whether parsed YAML is an exam file (problems: list, no robot/asks), as opposed to a problem spec."""
    return isinstance(data, dict) and "problems" in data and "robot" not in data and "asks" not in data


def _inner_model(annotation: Any, node: Any) -> Any:
    """The pydantic model inside Optional[...]/list[...] annotations (for 'did you mean' hints)."""
    args = getattr(annotation, "__args__", None)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for a in args or ():
        m = _inner_model(a, node)
        if m is not None and hasattr(m, "model_fields"):
            if "kind" in m.model_fields and isinstance(node, dict):
                kind_field = m.model_fields["kind"]
                allowed = getattr(kind_field.annotation, "__args__", ())
                if node.get("kind") not in allowed:
                    continue
            return m
    return None
