"""solver.math.ringcode: sympy's generated monomial arithmetic, compiled once per user."""
from __future__ import annotations

import os
import random

import pytest
import sympy as sp
from sympy.polys.domains import QQ
from sympy.core.cache import clear_cache
from sympy.polys.rings import PolyRing

from solver.math import fourier, ringcode

SOURCE = "def f(a, b):\n    return (a + b, a - b)\n"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(ringcode, "_MEMORY", {})
    return tmp_path / "robosolve"


def _run(code) -> tuple:  # type: ignore[no-untyped-def]
    ns: dict = {}
    exec(code, ns)
    return ns["f"](5, 3)


def test_installed_when_the_algebra_is_imported():
    from sympy.polys.monomials import MonomialOps
    assert fourier.ringcode is ringcode and getattr(MonomialOps._build, "_robosolve", False)


def test_code_is_compiled_once_and_read_back(cache):
    assert _run(ringcode.compiled(SOURCE)) == (8, 2)
    entries = list(cache.glob("monomial-ops-*.marshal"))
    assert len(entries) == 1 and (cache.stat().st_mode & 0o777) == 0o700
    ringcode._MEMORY.clear()
    os.utime(entries[0], (0, 0))
    assert _run(ringcode.compiled(SOURCE)) == (8, 2)  # (read from the folder: nothing rewritten)
    assert entries[0].stat().st_mtime == 0


def test_a_damaged_entry_is_compiled_again(cache):
    ringcode.compiled(SOURCE)
    entry, = cache.glob("monomial-ops-*.marshal")
    entry.write_bytes(b"\x00garbage")
    ringcode._MEMORY.clear()
    assert _run(ringcode.compiled(SOURCE)) == (8, 2)
    entry.write_bytes(b"x" * (ringcode._MAX_BYTES + 10))
    ringcode._MEMORY.clear()
    assert _run(ringcode.compiled(SOURCE)) == (8, 2)


def test_a_folder_open_to_others_is_not_used(cache):
    cache.mkdir(mode=0o700)
    os.chmod(cache, 0o777)
    assert ringcode.cache_dir() is None
    assert _run(ringcode.compiled(SOURCE)) == (8, 2)
    assert not list(cache.iterdir())


def test_ring_arithmetic_read_back_from_the_folder(cache):
    """A ring of a new size writes its seven functions; a ring of that size in a fresh memory (sympy's caches
    cleared) reads them back, and they compute the monomial arithmetic."""
    n = 37  # (a size no other test uses)
    clear_cache()
    PolyRing(sp.symbols(f"x:{n}"), QQ)
    entries = sorted(cache.glob("monomial-ops-*.marshal"))
    assert len(entries) == 7
    for e in entries:
        os.utime(e, (0, 0))
    clear_cache()
    ringcode._MEMORY.clear()
    R = PolyRing(sp.symbols(f"y:{n}"), QQ)
    assert sorted(cache.glob("monomial-ops-*.marshal")) == entries and all(e.stat().st_mtime == 0 for e in entries)
    rng = random.Random(3)
    for _ in range(200):
        a = tuple(rng.randint(0, 4) for _ in range(n))
        b = tuple(rng.randint(0, 2) for _ in range(n))
        k = rng.randint(0, 3)
        assert R.monomial_mul(a, b) == tuple(x + y for x, y in zip(a, b))
        assert R.monomial_pow(a, k) == tuple(x * k for x in a)
        assert R.monomial_mulpow(a, b, k) == tuple(x + y * k for x, y in zip(a, b))
        assert R.monomial_ldiv(a, b) == tuple(x - y for x, y in zip(a, b))
        assert R.monomial_div(a, b) == (tuple(x - y for x, y in zip(a, b)) if all(x >= y for x, y in zip(a, b))
                                        else None)
        assert R.monomial_lcm(a, b) == tuple(map(max, a, b)) and R.monomial_gcd(a, b) == tuple(map(min, a, b))
    x = R.gens
    assert (x[0] + x[1]) ** 2 == x[0] ** 2 + 2 * x[0] * x[1] + x[1] ** 2
