"""The compiled monomial arithmetic of sympy's polynomial rings, kept across processes.

A ``PolyRing`` with a new number of generators n makes sympy generate the source of seven functions on exponent
tuples (product, power, quotients, lcm, gcd, unrolled over the n entries) and compile it: ~1 ms each, so that
the first ring of a process costs more than loading a small spec. :func:`install` wraps sympy's
``MonomialOps._build`` so that the code object compiled from that source is kept in memory and in a per-user
folder (``$XDG_CACHE_HOME/robosolve`` or ``~/.cache/robosolve``, created 0700, used only when it is the user's and
closed to others), keyed by the Python version and the source itself: the same functions, without compiling
them again. Entries that cannot be read are compiled again; nothing is written where the folder is unsafe.
"""
from __future__ import annotations

import hashlib
import marshal
import os
import stat
import sys
import tempfile
import types
from pathlib import Path
from typing import Any, Callable

_MEMORY: dict[str, types.CodeType] = {}
_MAX_BYTES = 1 << 20  # an entry is a few kB; anything larger is not ours


def cache_dir() -> Path | None:
    """The per-user folder (created 0700), or None when it cannot be made safe (another owner, open to others)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    path = Path(base) / "robosolve"
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
        st = os.stat(path, follow_symlinks=False)
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode) or (hasattr(os, "getuid") and st.st_uid != os.getuid()) \
            or st.st_mode & 0o022:
        return None
    return path


def compiled(source: str) -> types.CodeType:
    """``compile(source, "<string>", "exec")``, from memory or the per-user folder when it was compiled before."""
    key = hashlib.sha256(f"{sys.version}\0{source}".encode()).hexdigest()[:40]
    code = _MEMORY.get(key)
    if code is not None:
        return code
    folder = cache_dir()
    entry = folder / f"monomial-ops-{key}.marshal" if folder is not None else None
    if entry is not None:
        try:
            with open(entry, "rb") as f:
                data = f.read(_MAX_BYTES + 1)
            loaded = marshal.loads(data) if len(data) <= _MAX_BYTES else None
            if isinstance(loaded, types.CodeType):
                code = loaded
        except (OSError, ValueError, EOFError, TypeError):
            code = None
    if code is None:
        code = compile(source, "<string>", "exec")
        if entry is not None:
            _store(entry, marshal.dumps(code))
    _MEMORY[key] = code
    return code


def _store(entry: Path, data: bytes) -> None:
    """Write ``entry`` atomically (a temporary file in the same folder, renamed); failures are ignored."""
    try:
        fd, tmp = tempfile.mkstemp(dir=entry.parent, prefix=".tmp-")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, entry)
        except OSError:
            os.unlink(tmp)
    except OSError:
        pass


def install() -> None:
    """Route sympy's ``MonomialOps._build(code, name)`` (exec of the generated source) through :func:`compiled`."""
    from sympy.polys.monomials import MonomialOps
    if getattr(MonomialOps._build, "_robosolve", False):
        return

    def _build(self: Any, code: str, name: str) -> Callable[..., Any]:
        ns: dict[str, Any] = {}
        exec(compiled(code), ns)
        return ns[name]

    _build._robosolve = True  # type: ignore[attr-defined]
    MonomialOps._build = _build  # type: ignore[method-assign]
