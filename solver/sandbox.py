"""Bounded work: each file is read, parsed, solved or graded in a child process with hard limits.

A child gets an address-space limit (RLIMIT_AS = its size at start + ``memory_mb``) and a CPU-time limit, and the
parent kills it (SIGKILL) when its wall-clock time runs out, so that no file — an alias bomb, a huge number, a
tower of powers, C code that ignores signals — can hang or exhaust the machine. At most ``jobs`` children run at
once; a child that dies is simply not replaced by itself: the next item gets a fresh child. One bad item never
stops a batch: its outcome says why it failed (``time``, ``memory``, ``crashed`` or the exception).

POSIX only (fork); elsewhere the work runs in-process, unbounded.
"""
from __future__ import annotations

import math
import os
import pickle
import select
import signal
import time
from dataclasses import dataclass
from typing import Any, Callable, Sequence, TypeVar

from solver.spec.errors import UserError

T = TypeVar("T")

TIME, MEMORY, CRASHED, EXCEPTION, USER = "time", "memory", "crashed", "exception", "user"


@dataclass
class Outcome:
    """What became of one item: ``value`` when ``ok``; else ``failure`` (time | memory | crashed | exception |
    user: a UserError, whose formatted text is the ``message``) and a ``message``."""

    value: Any = None
    failure: str | None = None
    message: str = ""
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.failure is None


@dataclass
class Limits:
    seconds: float = 600.0     # wall-clock time per item
    memory_mb: int = 4096      # address space per item, above the child's size at start

    def describe(self, failure: str) -> str:
        if failure == TIME:
            return f"stopped after {self.seconds:g} s (time limit)"
        if failure == MEMORY:
            return f"stopped: more than {self.memory_mb} MB of memory (memory limit)"
        return "the worker process crashed"


def _vm_bytes() -> int:
    """This process's address-space size (Linux /proc; 0 when unknown)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _child(fn: Callable[[T], Any], item: T, limits: Limits, w: int) -> None:
    """Run in the forked child: set the limits, run, send (status, value) through ``w``, exit without cleanup."""
    try:
        import resource
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        base = _vm_bytes()
        if base:
            cap = base + limits.memory_mb * 1024 * 1024
            resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
        used = resource.getrusage(resource.RUSAGE_SELF)  # (a prestarted worker has spent some on its imports)
        cpu = math.ceil(limits.seconds + used.ru_utime + used.ru_stime) + 1
        resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 1))
    except (ImportError, ValueError, OSError):
        pass
    try:
        payload = pickle.dumps(("ok", fn(item)))
    except MemoryError:
        payload = pickle.dumps((MEMORY, ""))
    except RecursionError:
        payload = pickle.dumps((EXCEPTION, "nested too deeply"))
    except UserError as exc:
        payload = pickle.dumps((USER, str(exc)))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, never raised there
        try:
            payload = pickle.dumps((EXCEPTION, f"{exc.__class__.__name__}: {exc}"[:2000]))
        except BaseException:  # noqa: BLE001
            payload = pickle.dumps((EXCEPTION, exc.__class__.__name__))
    try:
        write_all(w, payload)
    finally:
        os._exit(0)


def write_all(fd: int, data: bytes) -> None:
    """Write all of ``data`` to the (blocking) descriptor ``fd``."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


HEADER = 8  # bytes of a message's length (big-endian) before its data, in the pipes between robosolve's processes


def write_message(fd: int, data: bytes) -> None:
    """Write one message to ``fd``: the length of ``data`` in HEADER bytes (big-endian), then ``data``."""
    write_all(fd, len(data).to_bytes(HEADER, "big") + data)


def read_all(fd: int) -> bytes:
    """Read the (blocking) descriptor ``fd`` to its end."""
    chunks = []
    while True:
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)


@dataclass
class _Running:
    index: int
    pid: int
    fd: int
    start: float
    buf: bytearray


def _fork(fn: Callable[[T], Any], item: T, limits: Limits) -> tuple[int, int]:
    """A child running ``fn(item)`` bounded: (its pid, the descriptor its answer comes from)."""
    discard_prestarted()  # (it would inherit the prestarted worker's job pipe)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child
        os.close(r)
        _child(fn, item, limits, w)
    os.close(w)
    return pid, r


def run_many(fn: Callable[[T], Any], items: Sequence[T], jobs: int = 0, limits: Limits | None = None,
             on_done: Callable[[int, Outcome], None] | None = None,
             spawn: Callable[[int], tuple[int, int]] | None = None) -> list[Outcome]:
    """``fn(item)`` for every item, each in its own bounded child process, ``jobs`` at a time (0: one per core).
    Outcomes in the order of ``items``; ``on_done(index, outcome)`` is called in the parent as each finishes.
    ``fn`` must return picklable values; exceptions become failed outcomes. ``spawn(index)``: another way to get
    a child running item ``index`` ((pid, answer descriptor); default: fork one)."""
    limits = limits or Limits()
    outcomes: list[Outcome | None] = [None] * len(items)
    if not hasattr(os, "fork"):
        for i, item in enumerate(items):
            t0 = time.monotonic()
            try:
                out = Outcome(fn(item), seconds=time.monotonic() - t0)
            except Exception as exc:  # noqa: BLE001
                out = Outcome(None, EXCEPTION, f"{exc.__class__.__name__}: {exc}", time.monotonic() - t0)
            outcomes[i] = out
            if on_done:
                on_done(i, out)
        return [o for o in outcomes if o is not None]
    jobs = max(1, jobs or cores())
    pending = list(range(len(items)))[::-1]
    running: dict[int, _Running] = {}
    try:
        while pending or running:
            while pending and len(running) < jobs:
                i = pending.pop()
                pid, r = spawn(i) if spawn else _fork(fn, items[i], limits)
                os.set_blocking(r, False)
                running[r] = _Running(i, pid, r, time.monotonic(), bytearray())
            now = time.monotonic()
            timeout = max(0.0, min(run.start + limits.seconds for run in running.values()) - now)
            ready, _, _ = select.select(list(running), [], [], min(timeout, 1.0))
            for fd in ready:
                run = running[fd]
                try:
                    chunk = os.read(fd, 1 << 20)
                except BlockingIOError:
                    continue
                if chunk:
                    run.buf += chunk
                    continue
                del running[fd]
                _finish(run, limits, outcomes, on_done)
            now = time.monotonic()
            for fd, run in list(running.items()):
                if now - run.start > limits.seconds:
                    del running[fd]
                    _kill(run)
                    out = Outcome(None, TIME, limits.describe(TIME), now - run.start)
                    outcomes[run.index] = out
                    if on_done:
                        on_done(run.index, out)
    finally:
        for run in running.values():
            _kill(run)
    return [o for o in outcomes if o is not None]


def _kill(run: _Running) -> None:
    stop(run.pid)
    os.close(run.fd)


def stop(pid: int) -> None:
    """Kill a child process (SIGKILL) and reap it."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def _finish(run: _Running, limits: Limits, outcomes: list[Outcome | None],
            on_done: Callable[[int, Outcome], None] | None) -> None:
    _, status = os.waitpid(run.pid, 0)
    os.close(run.fd)
    seconds = time.monotonic() - run.start
    out: Outcome
    try:
        tag, value = pickle.loads(bytes(run.buf)) if run.buf else (None, None)
    except Exception:  # noqa: BLE001 - a truncated message: the child died while writing
        tag, value = None, None
    if tag == "ok":
        out = Outcome(value, seconds=seconds)
    elif tag == MEMORY:
        out = Outcome(None, MEMORY, limits.describe(MEMORY), seconds)
    elif tag in (EXCEPTION, USER):
        out = Outcome(None, tag, str(value), seconds)
    elif os.WIFSIGNALED(status) and os.WTERMSIG(status) in (signal.SIGXCPU, signal.SIGKILL):
        out = Outcome(None, TIME, limits.describe(TIME), seconds)
    else:
        out = Outcome(None, CRASHED, limits.describe(CRASHED), seconds)
    outcomes[run.index] = out
    if on_done:
        on_done(run.index, out)


def run_one(fn: Callable[[], Any], limits: Limits | None = None) -> Outcome:
    """``fn()`` in one bounded child process: the prestarted worker when there is one and ``fn`` pickles (a
    module-level function or a ``functools.partial`` of one), else a fresh fork."""
    limits = limits or Limits()
    warm = _take_prestarted()
    if warm is not None:
        try:
            job = pickle.dumps((fn, limits))
            write_message(warm.jobs, job)
        except Exception:  # noqa: BLE001 - not picklable (a closure), or the worker is gone: fork as usual
            warm.stop()
        else:
            os.close(warm.jobs)
            return run_many(lambda _: fn(), [None], 1, limits, spawn=lambda _: (warm.pid, warm.answer))[0]
    return run_many(lambda _: fn(), [None], 1, limits)[0]


# ------------------------------------------------------------------------------- the prestarted worker
@dataclass
class _Prestarted:
    pid: int
    jobs: int     # the job is written here (length-prefixed pickle of (fn, limits)); closed unused: the worker exits
    answer: int   # its answer comes from here, as a forked child's does

    def stop(self) -> None:
        for fd in (self.jobs, self.answer):
            try:
                os.close(fd)
            except OSError:
                pass
        stop(self.pid)


_PRESTARTED: _Prestarted | None = None


def prestart(warm_up: Callable[[], None]) -> None:
    """Fork now the worker of the next :func:`run_one`: it runs ``warm_up()`` (the heavy imports) while this
    process goes on (importing typer and parsing the command line: on two cores the two overlap), then waits
    for its job and runs it bounded like any child. Unused (the command failed, or ran something else), it is
    stopped at exit or before another child is forked. No-op without fork."""
    global _PRESTARTED
    if _PRESTARTED is not None or not hasattr(os, "fork"):
        return
    try:
        jobs_r, jobs_w = os.pipe()
        answer_r, answer_w = os.pipe()
        pid = os.fork()
    except OSError:
        return
    if pid == 0:
        os.close(jobs_w)
        os.close(answer_r)
        _serve(warm_up, jobs_r, answer_w)
    os.close(jobs_r)
    os.close(answer_w)
    _PRESTARTED = _Prestarted(pid, jobs_w, answer_r)
    import atexit
    atexit.register(discard_prestarted)


def _serve(warm_up: Callable[[], None], jobs: int, answer: int) -> None:
    """The prestarted worker: warm up, read one job, run it as :func:`_child` does; exit at once without one."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            warm_up()
        except Exception:  # noqa: BLE001 - the job imports the same modules again and reports what fails
            pass
        head = read_exactly(jobs, HEADER)
        if head is None:
            os._exit(0)
        fn, limits = pickle.loads(read_exactly(jobs, int.from_bytes(head, "big")) or b"")
    except BaseException:  # noqa: BLE001 - a job that cannot be read: the parent reports a crashed worker
        os._exit(1)
    _child(lambda _: fn(), None, limits, answer)


def read_exactly(fd: int, n: int) -> bytes | None:
    """``n`` bytes from the (blocking) descriptor ``fd``; None at its end (before the first byte)."""
    chunks, left = [], n
    while left:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            if left == n:
                return None
            raise EOFError("the message ended in the middle")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _take_prestarted() -> _Prestarted | None:
    global _PRESTARTED
    warm, _PRESTARTED = _PRESTARTED, None
    return warm


def discard_prestarted() -> None:
    """Stop the prestarted worker if it was not used."""
    warm = _take_prestarted()
    if warm is not None:
        warm.stop()
