"""The loader that turns a YAML spec into a :class:`~solver.spec.problem.Problem`, every expression parsed by the
allow-list parser (the format itself: :mod:`solver.spec.models`).

Every error is a :class:`~solver.spec.errors.UserError` with file:line:column, what is wrong and how to fix it.
"""
from __future__ import annotations

import difflib
import re
from pathlib import Path
from typing import Any

import sympy as sp
from pydantic import ValidationError

from solver.math.fourier import NotTrigPolynomial
from solver.math.rigid import dh_forms, dh_kinematics, omega_from_rotation
from solver.math.simplify import tidy
from solver.registry import load_all
from solver.results import Deferred
from solver.spec import expr as exprmod
from solver.spec.errors import ExprError, Place, UserError
from solver.spec.models import (DH, Link, RobotSpec, SpecBase, Strict, SymbolInfo, _inner_model, json_schema,
                                spec_model, validate_spec)
from solver.spec.problem import Ask, AskContext, Problem
from solver.spec.robot import Body, Robot
from solver.spec.texmath import math_problem, text_math_problem
from solver.spec.yamlpos import Located, PathT, load_file, load_text

__all__ = ["SpecLoader", "load_problem", "load_problem_text", "validation_error", "latex_of", "Strict", "json_schema",
           "spec_model"]

_RESERVED = set(exprmod.FUNCTIONS) | set(exprmod.CONSTANTS)
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_ASSUME = {"positive": {"positive": True}, "nonnegative": {"nonnegative": True}, "real": {"real": True},
           "nonzero": {"real": True, "nonzero": True}, "negative": {"negative": True}}


def latex_of(name: str) -> str:
    """LaTeX for a plain name: m2 -> m_{2}, I2xx -> I_{2xx}, theta1 -> \\theta_{1}, d_c2 -> d_{c2}."""
    if "_" in name:
        head, tail = name.split("_", 1)
        return f"{latex_of(head)}_{{{tail.replace('_', ',')}}}"
    m = re.fullmatch(r"([A-Za-z]+?)(\d.*)?", name)
    head, tail = (m.group(1), m.group(2)) if m else (name, None)
    if head in exprmod.GREEK:
        head = "\\" + head
    elif len(head) > 1 and not tail:
        return sp.latex(sp.Symbol(name))
    return f"{head}_{{{tail}}}" if tail else head


def dotted(path: PathT) -> str:
    """robot.links[1].com"""
    out = ""
    for k in path:
        out += f"[{k}]" if isinstance(k, int) else (f".{k}" if out else str(k))
    return out or "spec"


_SCALAR_TYPES = {"string_type", "int_type", "float_type", "int_from_float", "int_parsing", "float_parsing"}


def _without_member(err: dict[str, Any]) -> tuple[Any, ...]:
    """The loc of a pydantic error without the member of a ``Scalar`` union (str | int | float) that refused it."""
    loc = tuple(err["loc"])
    return loc[:-1] if err["type"] in _SCALAR_TYPES and loc[-1:] in (("str",), ("int",), ("float",)) else loc


def _pyd_message(err: dict[str, Any], path: PathT) -> tuple[str, str | None]:
    typ, loc = err["type"], err["loc"]
    field = str(loc[-1]) if loc else "spec"
    if typ == "missing":
        return f"missing field '{field}'", f"add '{field}:' here (see docs/spec.md)"
    if typ == "extra_forbidden":
        return f"unknown field '{field}'", None
    if typ in ("literal_error", "enum"):
        return f"{dotted(path)}: {err['msg'][0].lower() + err['msg'][1:]}", None
    if typ == "union_tag_invalid" or typ == "union_tag_not_found":
        kinds = ", ".join(sorted(load_all()))
        return "unknown or missing ask kind", f"use one of: {kinds}"
    return f"{dotted(path)}: {err['msg']}", None


def validation_error(exc: ValidationError, located: Located, prefix: PathT = (), what: str = "spec",
                     hint: str | None = None) -> UserError:
    """The first error of a pydantic validation of the block at ``prefix`` of a YAML file, at its line."""
    err = exc.errors()[0]
    path = tuple(prefix) + tuple(err["loc"])
    return UserError(f"{'.'.join(str(p) for p in path) or what}: {err['msg']}", located.place(path), hint)


class SpecLoader:
    """Turns located YAML data into a Problem; every expression is parsed with positions for errors."""

    def __init__(self, located: Located) -> None:
        self.loc = located
        self.file = located.file

    # -- errors ------------------------------------------------------------------------------------
    def fail(self, path: PathT, message: str, hint: str | None = None) -> UserError:
        return UserError(message, self.loc.place(path), hint)

    def get(self, path: PathT) -> Any:
        node = self.loc.data
        for k in path:
            node = node[k]
        return node

    def parse_at(self, path: PathT, names: dict[str, sp.Expr] | None = None) -> Any:
        """Parse the value at ``path`` (a string, a number or a YAML list of them)."""
        names = self.names if names is None else names
        try:
            value = self.get(path)
        except (KeyError, IndexError):
            default = self._default(path)
            return [exprmod.parse(v, names) for v in default] if isinstance(default, list) else \
                exprmod.parse(default, names)
        if isinstance(value, list):
            return [self.parse_at(path + (i,), names) for i in range(len(value))]
        try:
            return exprmod.parse(value, names)
        except ExprError as exc:
            place, shift = self.loc.text_offset(path)
            col = place.col + shift + exc.col - 1 if place.col and exc.col else place.col
            raise UserError(exc.message, Place(place.file, place.line, col), exc.hint) from None

    def _default(self, path: PathT) -> Any:
        """The model default of a field absent from the YAML (e.g. mass, inertia, DH a/alpha/d/theta)."""
        defaults = {"mass": 0, "inertia": 0, "a": 0, "alpha": 0, "d": 0, "theta": 0, "com": [0, 0, 0]}
        if path and path[-1] in defaults:
            return defaults[path[-1]]
        raise self.fail(path[:-1], f"missing field '{path[-1]}'")

    def matrix_at(self, path: PathT, shape: tuple[int, int] | None = None, what: str = "matrix") -> sp.Matrix:
        val = self.parse_at(path)
        shp = exprmod.shape_of(val)
        try:
            M = exprmod.to_matrix(val)
        except ExprError:
            raise self.fail(path, f"{what} has rows of different lengths", "write [[a, b], [c, d]]") from None
        if len(shp) == 1:
            M = sp.Matrix(val)
        if shape and M.shape != shape:
            raise self.fail(path, f"{what} must be {shape[0]}x{shape[1]}, got {M.shape[0]}x{M.shape[1]}")
        return M

    def vector_at(self, path: PathT, sizes: tuple[int, ...], what: str) -> sp.Matrix:
        val = self.parse_at(path)
        shp = exprmod.shape_of(val)
        if len(shp) != 1 or shp[0] not in sizes:
            want = " or ".join(str(s) for s in sizes)
            raise self.fail(path, f"{what} must be a vector of {want} components, got shape {shp or 'scalar'}",
                            "write [x, y, z]")
        v = list(val) + [sp.Integer(0)] * (3 - len(val)) if 3 in sizes else list(val)
        return sp.Matrix(v)

    def scalar_at(self, path: PathT, what: str) -> sp.Expr:
        val = self.parse_at(path)
        if isinstance(val, list):
            raise self.fail(path, f"{what} must be a single expression, got a list")
        return val

    # -- building ------------------------------------------------------------------------------------
    def load(self) -> Problem:
        data = self.loc.data
        if not isinstance(data, dict):
            raise self.fail((), "a spec must be a mapping (id:, title:, robot:, asks: ...)",
                            "start from an example in problems/")
        try:
            spec = validate_spec(data)
        except ValidationError as exc:
            errors = exc.errors()
            err = errors[0]
            path = self._data_path(err["loc"])
            msg, hint = _pyd_message(err, path)
            if _without_member(err) != err["loc"]:
                # each member of a Scalar union (str | int | float) refused a list or a mapping: one message
                path = self._data_path(_without_member(err))
                got = {list: "a list", dict: "a mapping"}.get(type(err["input"]), "another type")
                msg = f"{dotted(path)}: expected one number or expression, got {got}"
                hint = f"write one value, e.g. {path[-1]}: 0.1" if path and isinstance(path[-1], str) else None
            if err["type"] == "extra_forbidden":
                fields = self._fields_for(path[:-1])
                close = difflib.get_close_matches(str(path[-1]), fields, n=1) if fields else []
                hint = f"did you mean '{close[0]}'?" if close else (
                    f"allowed fields: {', '.join(fields)}" if fields else "remove it")
                if path[-1] is None or str(path[-1]) == "None":
                    hint = 'a bare null: is YAML\'s empty key: quote it, "null": [...]'
            others = {self._data_path(_without_member(e)) for e in errors} - {path}
            more = f" (and {len(others)} more problem(s))" if others else ""  # counted by place
            raise self.fail(path, msg + more, hint) from None
        why = text_math_problem(spec.statement)
        if why:
            raise self.fail(("statement",), f"statement: {why}",
                            "math between $...$ may use symbols, Greek letters, \\frac, \\sqrt, accents, fonts, "
                            "matrices; nothing that reads files or defines commands")
        self._symbols(spec)
        robot = self._robot(spec.robot) if spec.robot else None
        values = {}
        for name in spec.values:
            if name not in self.symbols:
                raise self.fail(("values", name), f"value for undeclared symbol '{name}'", "declare it under symbols:")
            v = self.scalar_at(("values", name), "a value")
            if v.free_symbols:
                raise self.fail(("values", name), f"value of '{name}' must be a number", "write e.g. 0.5 or pi/4")
            values[self.symbols[name]] = v
        known = []
        for i, k in enumerate(spec.known):
            if k not in self.names:
                raise self.fail(("known", i), f"unknown name '{k}' in known:", "declare it under symbols:")
            known.append(self.names[k])
        asks = [Ask(opt.kind, opt, AskContext(("asks", i), self.parse_at)) for i, opt in enumerate(spec.asks)]
        prob = Problem(
            id=spec.id, title=spec.title, statement=spec.statement,
            source=spec.source.model_dump() if spec.source else None,
            symbols=self.symbols, meanings=self.meanings, names=self.names, latex_names=self.latex_names,
            values=values, known=known, robot=robot, asks=asks, expected=spec.expected, located=self.loc,
            file=self.file, topics=spec.topics, notes=spec.notes, parse_at=self.parse_at)
        return prob

    def _data_path(self, loc: tuple[Any, ...]) -> PathT:
        """Pydantic's loc without union tags: the path into the YAML data."""
        node, path = self.loc.data, []
        for k in loc:
            if isinstance(node, dict) and k in node:
                node, path = node[k], path + [k]
            elif isinstance(node, list) and isinstance(k, int) and k < len(node):
                node, path = node[k], path + [k]
            elif isinstance(node, dict) and isinstance(k, str) and k not in node and k == loc[-1]:
                path.append(k)
        return tuple(path)

    def _fields_for(self, path: PathT) -> list[str]:
        model: Any = spec_model()
        node = self.loc.data
        for i, k in enumerate(path):
            node = node[k]
            if isinstance(k, int):
                continue
            field = model.model_fields.get(k) if hasattr(model, "model_fields") else None
            if field is None:
                return []
            item = path[i + 1] if i + 1 < len(path) else None  # a list's model is chosen by its item (its kind)
            model = _inner_model(field.annotation, node[item] if isinstance(item, int) else node)
        return list(model.model_fields) if hasattr(model, "model_fields") else []

    def _symbols(self, spec: SpecBase) -> None:
        robot = spec.robot
        n = len(robot.joints) if robot else 0
        coords = robot.coordinates if robot and robot.coordinates else [f"q{i + 1}" for i in range(n)]
        if robot and len(coords) < n:
            raise self.fail(("robot", "coordinates"), f"{len(coords)} coordinates for {n} joints",
                            "list one name per joint, then any extra (motor) coordinates")
        self.names: dict[str, sp.Expr] = {}
        self.latex_names: dict[sp.Symbol, str] = {}
        self.coords = []
        for c in coords:
            q, dq, ddq = sp.Symbol(c, real=True), sp.Symbol("d" + c, real=True), sp.Symbol("dd" + c, real=True)
            self.coords.append((q, dq, ddq))
            lx = latex_of(c)
            self.latex_names.update({q: lx, dq: f"\\dot{{{lx.split('_')[0]}}}" + lx[len(lx.split('_')[0]):],
                                     ddq: f"\\ddot{{{lx.split('_')[0]}}}" + lx[len(lx.split('_')[0]):]})
            for s in (q, dq, ddq):
                self.names[s.name] = s
        self.symbols: dict[str, sp.Symbol] = {}
        self.meanings: dict[str, str] = {}
        for name, info in spec.symbols.items():
            path = ("symbols", name)
            if not _NAME.match(name):
                raise self.fail(path, f"'{name}' is not a valid symbol name", "use letters, digits and _ (m1, I_2xx)")
            if name in _RESERVED:
                raise self.fail(path, f"'{name}' is a reserved name (function or constant)", "choose another name")
            if name in self.names:
                raise self.fail(path, f"'{name}' is a generalized coordinate/velocity, already defined",
                                "remove it from symbols:")
            meta = info if isinstance(info, SymbolInfo) else SymbolInfo(meaning=info)
            if meta.latex is not None:
                self._check_math(path + ("latex",), meta.latex)
            s = sp.Symbol(name, **_ASSUME[meta.sign])
            self.symbols[name] = s
            self.names[name] = s
            self.meanings[name] = meta.meaning
            self.latex_names[s] = meta.latex or latex_of(name)
        inputs = robot.inputs if robot and robot.inputs else []
        for i, u in enumerate(inputs):
            name, tex = (u, None) if isinstance(u, str) else (u.name, u.latex)
            if tex is not None:
                self._check_math(("robot", "inputs", i, "latex"), tex)
            s = sp.Symbol(name, real=True)
            self.names.setdefault(name, s)
            self.latex_names[s] = tex or latex_of(name)

    def _check_math(self, path: PathT, tex: str) -> None:
        why = math_problem(tex)
        if why:
            raise self.fail(path, f"LaTeX name refused: {why}", "write plain math, e.g. q_{d,1} or \\theta_1")

    def _robot(self, r: RobotSpec) -> Robot:
        q = [c[0] for c in self.coords]
        dq = [c[1] for c in self.coords]
        ddq = [c[2] for c in self.coords]
        n = len(q)
        P = ("robot",)
        robot = Robot(q=q, dq=dq, ddq=ddq, joints=list(r.joints))
        if r.gravity is not None:
            robot.gravity = self.vector_at(P + ("gravity",), (2, 3), "gravity")
        if r.links and r.dh:
            raise self.fail(P + ("dh",), "give either links: (explicit) or dh:, not both")
        if r.links:
            robot.bodies = [self._explicit(P + ("links", i), lk, q, dq, i) for i, lk in enumerate(r.links)]
        if r.dh:
            robot.bodies, robot.frames = self._dh(P + ("dh",), r.dh, q, dq, ddq, len(r.joints), robot.gravity)
            robot.dh_convention = r.dh.convention
        if r.extra:
            robot.kinetic_extra = [self.scalar_at(P + ("extra", "kinetic", i), "a kinetic term")
                                   for i in range(len(r.extra.kinetic))]
            robot.potential_extra = [self.scalar_at(P + ("extra", "potential", i), "a potential term")
                                     for i in range(len(r.extra.potential))]
        if r.friction and r.friction.viscous is not None:
            path = P + ("friction", "viscous")
            v = self.parse_at(path)
            shp = exprmod.shape_of(v)
            if shp == (n,):
                robot.friction = sp.diag(*v)
            elif shp == (n, n):
                robot.friction = sp.Matrix(v)
            elif shp == ():
                robot.friction = v * sp.eye(n)
            else:
                raise self.fail(path, f"viscous friction must be a list of {n} or a {n}x{n} matrix, got shape {shp}")
        if r.input_map is not None:
            G = self.matrix_at(P + ("input_map",), None, "input_map")
            if G.shape[0] != n:
                raise self.fail(P + ("input_map",), f"input_map must have {n} rows (one per coordinate), got {G.shape[0]}")
            robot.input_map = G
        m = robot.input_map.shape[1] if robot.input_map is not None else n
        names = [u if isinstance(u, str) else u.name for u in r.inputs] if r.inputs else [f"u{i + 1}" for i in range(m)]
        if len(names) != m:
            raise self.fail(P + ("inputs",), f"{len(names)} input names for {m} inputs")
        robot.inputs = [sp.Symbol(u, real=True) for u in names]
        for u in robot.inputs:
            self.latex_names.setdefault(u, latex_of(u.name))
        if r.model:
            M = P + ("model",)
            if r.model.B is not None:
                robot.given_B = self.matrix_at(M + ("B",), (n, n), "B")
                if (robot.given_B - robot.given_B.T).applyfunc(tidy) != sp.zeros(n, n):
                    raise self.fail(M + ("B",), "B(q) must be symmetric")
            if r.model.U is not None:
                robot.given_U = self.scalar_at(M + ("U",), "U")
            if r.model.g is not None:
                robot.given_g = self.vector_at(M + ("g",), (n,), "g")
            if r.model.c is not None:
                robot.given_c = self.vector_at(M + ("c",), (n,), "c")
        return robot  # a robot without bodies or model is fine for kinematics; dynamics asks check it

    def _inertia(self, path: PathT, what: str) -> sp.Matrix:
        val = self.parse_at(path)
        shp = exprmod.shape_of(val)
        if shp == ():
            return sp.diag(0, 0, val)
        if shp == (3,):
            return sp.diag(*val)
        if shp == (3, 3):
            M = sp.Matrix(val)
            if M != M.T:
                raise self.fail(path, f"{what} must be symmetric")
            return M
        raise self.fail(path, f"{what} must be a scalar, [Ixx, Iyy, Izz] or a 3x3 matrix, got shape {shp}")

    def _explicit(self, path: PathT, lk: Link, q: list, dq: list, i: int) -> Body:
        mass = self.scalar_at(path + ("mass",), "mass")
        com = self.vector_at(path + ("com",), (2, 3), "com")
        inertia = self._inertia(path + ("inertia",), "inertia")
        given = [k for k in ("angle", "rotation", "omega") if getattr(lk, k) is not None]
        if len(given) > 1:
            raise self.fail(path + (given[1],), f"give only one of angle/rotation/omega (got {', '.join(given)})")
        rotation, frame = None, "base"
        if lk.angle is not None:
            ang = self.scalar_at(path + ("angle",), "angle")
            omega = sp.Matrix([0, 0, sum((sp.diff(ang, qk) * dqk for qk, dqk in zip(q, dq)), sp.Integer(0))])
        elif lk.rotation is not None:
            rotation = self.matrix_at(path + ("rotation",), (3, 3), "rotation")
            omega = omega_from_rotation(rotation, q, dq, "link")
            frame = "link"
        elif lk.omega is not None:
            omega = self.vector_at(path + ("omega",), (3,), "omega")
            if any(sp.diff(omega, a, 2) != sp.zeros(3, 1) for a in dq) or omega.subs({a: 0 for a in dq}) != sp.zeros(3, 1):
                raise self.fail(path + ("omega",), "omega must be linear in the velocities (dq1, dq2, ...)")
            frame = "link"
        else:
            nz = inertia != sp.zeros(3, 3)
            if nz:
                raise self.fail(path + ("inertia",), "a body with inertia needs angle:, rotation: or omega:",
                                "for a planar link give angle: (its absolute orientation, e.g. q1 + q2)")
            omega = sp.zeros(3, 1)
        return Body(lk.name or f"link {i + 1}", mass, com, omega, inertia, rotation, frame)

    def _dh(self, path: PathT, dh: DH, q: list, dq: list, ddq: list, nj: int, gravity: sp.Matrix | None
            ) -> tuple[list[Body], list[sp.Matrix]]:
        """The bodies of a DH robot and its frames ⁰A_0 (the base), ⁰A_1, ..., ⁰A_n."""
        if len(dh.table) != nj:
            raise self.fail(path + ("table",), f"DH table has {len(dh.table)} rows for {nj} joints")
        if len(dh.links) != nj:
            raise self.fail(path + ("links",), f"{len(dh.links)} DH links for {nj} joints")
        rows = [tuple(self.scalar_at(path + ("table", i, k), k) for k in ("a", "alpha", "d", "theta"))
                for i in range(nj)]
        base = sp.eye(4)
        if dh.base is not None:
            base = self.matrix_at(path + ("base",), (4, 4), "base")
        links = []
        for i, lk in enumerate(dh.links):
            lp = path + ("links", i)
            links.append((lk, self.vector_at(lp + ("com",), (3,), "com"), self.scalar_at(lp + ("mass",), "mass"),
                          self._inertia(lp + ("inertia",), "inertia")))
        coms = [r for _, r, _, _ in links]
        given_base = base if dh.base is not None else None
        extra = set(ddq)  # (the dynamic model's symbols: it computes in the same algebra)
        for _, _, mass, inertia in links:
            extra |= mass.free_symbols | inertia.free_symbols
        if gravity is not None:
            extra |= gravity.free_symbols
        try:  # the canonical forms, written when first read (a dynamics ask takes p_c, ω as they are)
            forms = dh_forms(rows, dh.convention, q, dq, coms, given_base, extra)
        except NotTrigPolynomial:
            frames, omegas, centres = dh_kinematics(rows, dh.convention, q, dq, coms,  # type: ignore[arg-type]
                                                    given_base)
            bodies = [Body(lk.name or f"link {i + 1}", mass, com, omega, inertia, A[:3, :3], "link")
                      for i, ((lk, _, mass, inertia), A, omega, com) in enumerate(zip(links, frames, omegas,
                                                                                      centres))]
            return bodies, [base] + frames
        bodies = [Body(lk.name or f"link {i + 1}", mass, Deferred(lambda i=i: forms.centre(i)),
                       Deferred(lambda i=i: forms.omega(i)), inertia, Deferred(lambda i=i: forms.frame(i)[:3, :3]),
                       "link", trig=(forms.algebra, forms.centres[i], forms.omegas[i]))
                  for i, (lk, _, mass, inertia) in enumerate(links)]
        return bodies, Deferred(lambda: [base] + [forms.frame(i) for i in range(nj)])  # type: ignore[return-value]



def load_problem(path: str | Path) -> Problem:
    """Load, validate and parse a spec file."""
    return SpecLoader(load_file(path)).load()


def load_problem_text(text: str, file: str = "<input>") -> Problem:
    """Load a spec from text (tests, stdin)."""
    return SpecLoader(load_text(text, file)).load()
