"""Read YAML (or JSON) into plain Python data, remembering where every value stands in the file."""
from __future__ import annotations

import datetime
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq, TaggedScalar
from ruamel.yaml.error import MarkedYAMLError, YAMLError

from solver.spec.errors import Place, UserError

PathT = tuple[Any, ...]

MAX_FILE_BYTES = 1_000_000  # a spec or a submission is a few kB; reading is bounded before parsing
MAX_NODES = 100_000         # values after expanding YAML aliases (an alias bomb expands to billions)
MAX_NESTING = 50            # levels of mappings and lists


class _TooMuch(Exception):
    pass


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


class _Builder:
    """Plain data from ruamel's round-trip nodes, with positions; bounded in values and nesting."""

    def __init__(self) -> None:
        self.positions: dict[PathT, tuple[int, int]] = {}
        self.count = 0

    def plain(self, node: Any, path: PathT) -> Any:
        self.count += 1
        if self.count > MAX_NODES:
            raise _TooMuch(f"more than {MAX_NODES} values (YAML aliases *name expand to copies)")
        if len(path) > MAX_NESTING:
            raise _TooMuch(f"nested more than {MAX_NESTING} levels deep")
        positions = self.positions
        tag = getattr(getattr(node, "tag", None), "value", None)
        if tag or isinstance(node, (TaggedScalar, bytes)):
            raise _TooMuch(f"YAML tags ({tag or '!!binary'}) are not allowed: write plain values")
        if isinstance(node, CommentedMap):
            out = {}
            for key in node:
                try:
                    line, col = node.lc.value(key)
                except (KeyError, TypeError):
                    line, col = node.lc.line, node.lc.col
                positions[path + (str(key),)] = (line + 1, col + 1)
                out[_text(key)] = self.plain(node[key], path + (str(key),))
            return out
        if isinstance(node, CommentedSeq):
            out_l = []
            for i, item in enumerate(node):
                try:
                    line, col = node.lc.item(i)
                    positions[path + (i,)] = (line + 1, col + 1)
                except (KeyError, TypeError, IndexError):
                    pass
                out_l.append(self.plain(item, path + (i,)))
            return out_l
        if isinstance(node, str):
            return _text(node)
        if node is None or isinstance(node, (int, float, datetime.date)):
            return node
        raise _TooMuch(f"a YAML {type(node).__name__} is not allowed: write plain values")


def _text(s: Any) -> str:
    """A string as valid Unicode: JSON-escaped surrogate pairs (\\ud83d\\udca5) joined, a lone one refused."""
    s = str(s)
    try:
        s.encode("utf-8")
        return s
    except UnicodeEncodeError:
        pass
    try:
        joined = s.encode("utf-16", "surrogatepass").decode("utf-16")
        joined.encode("utf-8")
        return joined
    except UnicodeError:
        raise _TooMuch("a text holds an invalid character (a lone UTF-16 surrogate)") from None


class _NotPlain(Exception):
    """Something the fast reader leaves to ruamel's round-trip loader (its errors and its rules)."""


_PLAIN_TAGS = {"tag:yaml.org,2002:" + t for t in ("str", "int", "float", "bool", "null", "timestamp")}


class _NodeBuilder:
    """Plain data with positions from the nodes of libyaml's composer (ruamel.yaml.clib): about 8× faster than
    the round-trip loader. Only untagged mappings (keys of plain text, each once, no merge keys), sequences and
    scalars of the core schema; anything else (:class:`_NotPlain`) is read again by the round-trip loader, whose
    results and messages stay the reference."""

    def __init__(self, constructor: Any) -> None:
        self.positions: dict[PathT, tuple[int, int]] = {}
        self.count = 0
        self.construct = constructor.construct_object

    def plain(self, node: Any, path: PathT) -> Any:
        from ruamel.yaml.nodes import MappingNode, ScalarNode, SequenceNode
        self.count += 1
        if self.count > MAX_NODES or len(path) > MAX_NESTING:
            raise _NotPlain()
        if isinstance(node, ScalarNode):
            if node.tag not in _PLAIN_TAGS or (node.style is None and node.value[:1] in ("!", "&", "*")):
                raise _NotPlain()
            value = self.construct(node, deep=True)
            if isinstance(value, str):
                return _text(value)
            if value is None or isinstance(value, (int, float, datetime.date)):
                return value
            raise _NotPlain()
        if isinstance(node, MappingNode):
            if node.tag != "tag:yaml.org,2002:map":
                raise _NotPlain()
            out: dict[str, Any] = {}
            for k, v in node.value:
                if not isinstance(k, ScalarNode) or k.tag != "tag:yaml.org,2002:str" or k.value == "<<":
                    raise _NotPlain()
                key = _text(k.value)
                if key in out:
                    raise _NotPlain()   # a duplicate key: the round-trip loader's message
                self.positions[path + (key,)] = (v.start_mark.line + 1, v.start_mark.column + 1)
                out[key] = self.plain(v, path + (key,))
            return out
        if isinstance(node, SequenceNode):
            if node.tag != "tag:yaml.org,2002:seq":
                raise _NotPlain()
            items = []
            for i, v in enumerate(node.value):
                self.positions[path + (i,)] = (v.start_mark.line + 1, v.start_mark.column + 1)
                items.append(self.plain(v, path + (i,)))
            return items
        raise _NotPlain()


def _load_fast(text: str, file: str) -> Optional[Located]:
    """:func:`load_text` through libyaml when ruamel.yaml.clib is installed and the text is plain YAML (see
    :class:`_NodeBuilder`); None otherwise (the caller reads it with the round-trip loader)."""
    from ruamel.yaml.main import CParser
    if CParser is None:
        return None
    yaml = YAML(typ="safe", pure=False)
    try:
        node = yaml.compose(io.StringIO(text))
        if node is None:
            return None
        builder = _NodeBuilder(yaml.constructor)
        data = builder.plain(node, ())
    except (YAMLError, _NotPlain, _TooMuch, RecursionError, ValueError, TypeError, OverflowError, AttributeError):
        return None
    builder.positions[()] = (node.start_mark.line + 1, node.start_mark.column + 1)
    if not isinstance(data, (dict, list)):
        del builder.positions[()]
    return Located(data, file, builder.positions, text.splitlines())


def load_text(text: str, file: str = "<input>") -> Located:
    """Parse YAML text; a syntax error becomes a :class:`UserError` at its line and column. Bounded: the text's
    size, the number of values after expanding aliases and the nesting depth are limited. Plain YAML is read by
    libyaml when it is installed (:func:`_load_fast`), anything else by ruamel's round-trip loader."""
    if len(text) > MAX_FILE_BYTES:
        raise UserError(f"file too large ({len(text) // 1000} kB; at most {MAX_FILE_BYTES // 1000} kB)", Place(file),
                        "a spec or an answer file is a few kB")
    fast = _load_fast(text, file)
    if fast is not None:
        return fast
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
        raise UserError(f"YAML syntax: {str(exc)[:300]}", Place(file)) from None
    except RecursionError:
        raise UserError("YAML nested too deeply", Place(file), f"at most {MAX_NESTING} levels") from None
    except (ValueError, TypeError, OverflowError, AttributeError) as exc:  # e.g. a 5000-digit integer
        raise UserError(f"a value cannot be read: {str(exc)[:200]}", Place(file),
                        "numbers have at most 30 digits; quote text") from None
    builder = _Builder()
    if isinstance(node, (CommentedMap, CommentedSeq)):
        builder.positions[()] = (node.lc.line + 1, node.lc.col + 1)
    try:
        data = builder.plain(node, ())
    except _TooMuch as exc:
        raise UserError(f"cannot read this YAML: {exc}", Place(file),
                        "write plain values (no aliases *name, no tags !name)") from None
    except RecursionError:
        raise UserError("YAML nested too deeply", Place(file), f"at most {MAX_NESTING} levels") from None
    return Located(data, file, builder.positions, text.splitlines())


def read_text_bounded(path: str | Path, max_bytes: int = MAX_FILE_BYTES, label: str | None = None) -> str:
    """The UTF-8 text of a regular file of at most ``max_bytes``: never blocks on a FIFO, never reads a device or
    an endless file. Errors are UserErrors naming ``label`` (default: the path)."""
    import os
    import stat
    name = label or str(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise UserError(f"no such file: {name}", None, "check the path") from None
    except IsADirectoryError:
        raise UserError(f"{name} is a directory, a file was expected", None) from None
    except OSError as exc:
        raise UserError(f"cannot read {name}: {exc.strerror}", None) from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise UserError(f"{name} is a directory, a file was expected", None)
        if not stat.S_ISREG(st.st_mode):
            raise UserError(f"{name} is not a regular file (a pipe, a device or a socket)", None, "give a .yaml file")
        if st.st_size > max_bytes:
            raise UserError(f"{name}: file too large ({st.st_size // 1000} kB; at most {max_bytes // 1000} kB)", None)
        data = b""
        while len(data) <= max_bytes:
            chunk = os.read(fd, max_bytes + 1 - len(data))
            if not chunk:
                break
            data += chunk
        if len(data) > max_bytes:
            raise UserError(f"{name}: file too large (at most {max_bytes // 1000} kB)", None)
    finally:
        os.close(fd)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise UserError("file is not UTF-8 text", Place(name)) from None


def load_file(path: str | Path) -> Located:
    """Read and parse a YAML/JSON file (JSON is YAML), bounded (see :func:`read_text_bounded`)."""
    return load_text(read_text_bounded(path), str(path))
