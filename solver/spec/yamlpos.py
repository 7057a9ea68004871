"""Read YAML (or JSON) into plain Python data, remembering where every value stands in the file."""
from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import MarkedYAMLError, YAMLError

from solver.spec.errors import Place, UserError

PathT = tuple[Any, ...]


@dataclass
class Located:
    """Plain data from a YAML file plus the (line, col) of each value, keyed by its path of keys/indices."""

    data: Any
    file: str
    positions: dict[PathT, tuple[int, int]] = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)

    def place(self, path: PathT) -> Place:
        """The place of the value at ``path``, or of its nearest located ancestor."""
        p = tuple(path)
        while p and p not in self.positions:
            p = p[:-1]
        line, col = self.positions.get(p, (0, 0))
        return Place(self.file, line, col)

    def text_offset(self, path: PathT) -> tuple[Place, int]:
        """Place of a scalar and the column shift from its first character to the text it holds (quotes)."""
        place = self.place(path)
        if place.line and place.line <= len(self.lines):
            ch = self.lines[place.line - 1][place.col - 1:place.col]
            if ch in "'\"":
                return place, 1
            if ch in "|>":
                return Place(place.file, place.line + 1, 0), 0
        return place, 0


def _plain(node: Any, path: PathT, positions: dict[PathT, tuple[int, int]]) -> Any:
    if isinstance(node, CommentedMap):
        out = {}
        for key in node:
            try:
                line, col = node.lc.value(key)
            except (KeyError, TypeError):
                line, col = node.lc.line, node.lc.col
            positions[path + (str(key),)] = (line + 1, col + 1)
            out[str(key)] = _plain(node[key], path + (str(key),), positions)
        return out
    if isinstance(node, CommentedSeq):
        out_l = []
        for i, item in enumerate(node):
            try:
                line, col = node.lc.item(i)
                positions[path + (i,)] = (line + 1, col + 1)
            except (KeyError, TypeError, IndexError):
                pass
            out_l.append(_plain(item, path + (i,), positions))
        return out_l
    if isinstance(node, str):
        return str(node)
    return node


def load_text(text: str, file: str = "<input>") -> Located:
    """Parse YAML text; a syntax error becomes a :class:`UserError` at its line and column."""
    yaml = YAML(typ="rt")
    yaml.allow_duplicate_keys = False
    try:
        node = yaml.load(io.StringIO(text))
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        place = Place(file, mark.line + 1, mark.column + 1) if mark else Place(file)
        problem = (exc.problem or "invalid YAML").strip()
        if "duplicate key" in str(exc):
            problem = "duplicate key"
        raise UserError(f"YAML syntax: {problem}", place,
                        "check indentation, a missing ':' or an unclosed quote/bracket") from None
    except YAMLError as exc:
        raise UserError(f"YAML syntax: {exc}", Place(file)) from None
    positions: dict[PathT, tuple[int, int]] = {}
    if isinstance(node, (CommentedMap, CommentedSeq)):
        positions[()] = (node.lc.line + 1, node.lc.col + 1)
    data = _plain(node, (), positions)
    return Located(data, file, positions, text.splitlines())


def load_file(path: str | Path) -> Located:
    """Read and parse a YAML/JSON file (JSON is YAML)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"no such file: {p}", None, "check the path") from None
    except UnicodeDecodeError:
        raise UserError("file is not UTF-8 text", Place(str(p))) from None
    except IsADirectoryError:
        raise UserError(f"{p} is a directory, a file was expected", None) from None
    return load_text(text, str(p))
