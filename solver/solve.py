"""Solving a problem: run each ask's registered solver, in order or shared with forked helpers (both cores)."""
from __future__ import annotations

import os
import pickle
import select
import signal
from dataclasses import dataclass
from typing import Callable

from solver.math.nounits import without_units
from solver.registry import get_kind
from solver.results import Solution, sending_optional
from solver.sandbox import HEADER, stop, write_message
from solver.spec.errors import UserError
from solver.spec.problem import Problem

MAX_PARALLEL_ASKS = 30000  # ask numbers are queued in one pipe write (2 bytes each, within its 64 kB buffer)


def solve_problem(problem: Problem, solved: Callable[[int, Solution], None] | None = None, jobs: int = 1,
                  figures: bool = False, early: Callable[[int, Solution], None] | None = None,
                  optional: bool = True) -> list[Solution]:
    """One :class:`Solution` per ask of ``problem`` (only the modules of its ask kinds are imported);
    ``solved(k, solution)`` is called, in the order of the asks, as soon as asks 1..k are solved (the CLI's
    painter draws their figures while the next asks are solved). With helpers, ``early(k, solution)`` is called
    for an ask k solved before an earlier one: its solution as solved from the problem as loaded, which the
    merge keeps unless its names clash (then ``solved`` gives another solution object for k).

    Every ask is solved from the problem as loaded: the names an ask registers (its fresh symbols, its inputs)
    are merged into the problem in the order of the asks once it is solved (:class:`_Names`), so that asks can
    be solved in any order, by any process, with the same solutions. ``jobs`` > 1 (POSIX, three asks or more):
    the asks after the first are shared with up to ``jobs`` − 1 forked helper processes (:func:`_parallel`).
    ``figures``: the helpers sample the figures of their asks (the caller draws them); otherwise a helper's
    figures have no panels. ``optional=False``: the helpers leave out the optional deferred results (those of
    the parts an ask does not show) instead of computing them to send them: for a report, or JSON without
    ``--details``, which read none of them."""
    n = len(problem.asks)
    names = _Names(problem)
    if jobs > 1 and 3 <= n <= MAX_PARALLEL_ASKS and hasattr(os, "fork"):
        out = _parallel(problem, names, solved, jobs, figures, early, optional)
    else:
        out = []
        with without_units():
            for k in range(n):
                out.append(names.settle(k, *names.attempt(k)))
                if solved is not None:
                    solved(k + 1, out[-1])
    names.finish()
    return out


def validate_problem(problem: Problem) -> list[UserError]:
    """The spec errors of ``problem``'s asks found without solving them (``robosolve check``): each ask's options
    read and checked by its kind's ``validate`` hook (``@ask_kind(..., validate=)``; kinds without one are
    skipped), at most one error per ask, in the order of the asks. As in :func:`solve_problem`, an ask is read
    from the problem as loaded, then, if that fails, with the names the earlier asks' hooks registered; an
    unknown name that an earlier ask may register only when it is solved (a law's desired symbols) is looked up
    once more after solving the earlier asks. The problem is left as loaded."""
    names = _Names(problem)
    records = set(problem.__dict__)
    read = names.base.copy()                      # the names the hooks registered, merged in order
    solver: list[_Solved] = []                    # the earlier asks solved in order, on demand
    errors: list[UserError] = []

    def attempt(k: int, state: _State, hook: Callable) -> tuple[UserError | None, _State | None]:
        before = names.reset(state)
        try:
            hook(problem, problem.asks[k].options, problem.asks[k].ctx)
        except UserError as exc:
            return exc, None
        return None, names.registered(before)

    try:
        with without_units():
            for k, ask in enumerate(problem.asks):
                hook = get_kind(ask.kind).validate
                if hook is None:
                    continue
                err, regs = attempt(k, names.base, hook)
                if err is not None and k:
                    err, regs = attempt(k, read, hook)
                if err is not None and k and err.message.startswith("unknown name "):
                    if not solver:
                        names.reset()
                        solver.append(_Solved(_Names(problem)))
                    err, regs = attempt(k, solver[0].upto(k), hook)
                if regs is not None:
                    read.names.update(regs.names)
                    read.latex.update(regs.latex)
                    for key, v in regs.sets.items():
                        read.sets.setdefault(key, set()).update(v)
                if err is not None:
                    errors.append(err)
    finally:
        names.reset()
        for key in set(problem.__dict__) - records:
            del problem.__dict__[key]
    return errors


@dataclass
class _Solved:
    """The asks of a problem solved in order, as far as :func:`validate_problem` needs them (solving may be slow:
    only for an unknown name in a later ask)."""

    names: _Names
    count: int = 0

    def upto(self, k: int) -> _State:
        """The names asks 0..k−1 register when solved in order (an ask that fails is left out)."""
        for j in range(self.count, k):
            try:
                self.names.settle(j, *self.names.attempt(j))
            except Exception:  # noqa: BLE001 - its own error is reported by its hook or by solving, not here
                continue
        self.count = max(self.count, k)
        return self.names.merged


def _solve_ask(problem: Problem, k: int) -> Solution:
    a = problem.asks[k]
    return get_kind(a.kind).solve(problem, a.options, a.ctx)


_MISSING = object()


@dataclass
class _State:
    """What asks register in a problem: names, LaTeX names, name sets (the private sets a solver keeps of the
    names it chose) and records (other private entries: what a law leaves for the simulation and the grader)."""

    names: dict
    latex: dict
    sets: dict
    records: dict

    def copy(self) -> _State:
        return _State(dict(self.names), dict(self.latex), {k: set(v) for k, v in self.sets.items()},
                      dict(self.records))


class _Names:
    """The names and records of a problem across its asks. Each ask is solved from the problem as loaded
    (``base``); what it registers is merged in the order of the asks (``merged``). An ask that fails so (its
    options use a name an earlier ask registered), or whose names clash with those of an earlier ask (the same
    name for another value or another LaTeX form), is solved again from the merged state, as if the asks had
    been solved one after the other (its names then get a suffix; an error is raised)."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.fields = set(problem.__dataclass_fields__)  # type: ignore[attr-defined]
        self.base = self._take()
        self.merged = self.base.copy()

    def _take(self) -> _State:
        p = self.problem
        private = {k: v for k, v in p.__dict__.items() if k not in self.fields}
        return _State(dict(p.names), dict(p.latex_names),
                      {k: set(v) for k, v in private.items() if isinstance(v, set)},
                      {k: v for k, v in private.items() if not isinstance(v, set)})

    def reset(self, state: _State | None = None) -> _State:
        """The problem's names, LaTeX names and name sets as in ``state`` (default: as loaded); records stay.
        What the problem then holds."""
        p, state = self.problem, state or self.base
        p.names.clear()
        p.names.update(state.names)
        p.latex_names.clear()
        p.latex_names.update(state.latex)
        for k in [k for k, v in p.__dict__.items() if k not in self.fields and isinstance(v, set)]:
            del p.__dict__[k]
        for k, v in state.sets.items():
            p.__dict__[k] = set(v)
        return self._take()

    def registered(self, since: _State) -> _State:
        """What the problem holds now that it did not hold in ``since`` (taken before the ask)."""
        now = self._take()
        return _State({x: v for x, v in now.names.items() if since.names.get(x, _MISSING) is not v},
                      {s: t for s, t in now.latex.items() if since.latex.get(s) != t},
                      {k: v - since.sets.get(k, set()) for k, v in now.sets.items() if v - since.sets.get(k, set())},
                      {k: v for k, v in now.records.items() if since.records.get(k, _MISSING) is not v})

    def _clash(self, regs: _State) -> bool:
        base, merged = self.base, self.merged
        for x, v in regs.names.items():
            m = merged.names.get(x, _MISSING)
            if m is base.names.get(x, _MISSING):
                continue  # (no earlier ask registered x)
            if m is _MISSING or m != v or merged.latex.get(m) != regs.latex.get(v, merged.latex.get(m)):
                return True
        return any(s in merged.latex and merged.latex[s] != t and merged.latex[s] != base.latex.get(s)
                   for s, t in regs.latex.items())

    def attempt(self, k: int) -> tuple[Solution | None, _State | None]:
        """Ask k solved from the problem as loaded: (its solution, what it registered), or (None, None) when
        that fails (it may use a name an earlier ask registered)."""
        before = self.reset()
        try:
            sol = _solve_ask(self.problem, k)
        except Exception:  # noqa: BLE001 - solved again from the merged state (settle), which raises
            return None, None
        return sol, self.registered(before)

    def settle(self, k: int, sol: Solution | None, regs: _State | None) -> Solution:
        """Ask k's solution (solved from the problem as loaded, registering ``regs``), merged; solved again from
        the merged state when that failed (None) or its names clash with an earlier ask's: then as if the asks
        had been solved one after the other (an error raises)."""
        if sol is None or regs is None or self._clash(regs):
            before = self.reset(self.merged)
            sol = _solve_ask(self.problem, k)
            regs = self.registered(before)
        m = self.merged
        m.names.update(regs.names)
        m.latex.update(regs.latex)
        for key, v in regs.sets.items():
            m.sets.setdefault(key, set()).update(v)
        m.records.update(regs.records)
        return sol

    def finish(self) -> None:
        """The problem as the asks left it in order: every name, LaTeX name, name set and record merged."""
        self.reset(self.merged)
        self.problem.__dict__.update(self.merged.records)


def _take(queue: int) -> int | None:
    """The next ask number from the shared queue (2 bytes; reads of a pipe are atomic), None when it is empty."""
    data = os.read(queue, 2)
    return int.from_bytes(data, "big") if len(data) == 2 else None


def _parallel(problem: Problem, names: _Names, solved: Callable[[int, Solution], None] | None, jobs: int,
              figures: bool, early: Callable[[int, Solution], None] | None = None,
              optional: bool = True) -> list[Solution]:
    """The asks shared between this process and ``jobs`` − 1 helpers forked once the first ask is solved (they
    inherit the problem, every import and what the first ask derived). The queue is a pipe holding the ask
    numbers: each process reads the next one when it is free, so that a long ask does not hold the others back.
    Each ask is solved from the problem as loaded; a helper sends its solution pickled, with what it registered
    (:class:`_Names`), and this process merges them in order (a failed ask is solved again from the merged
    state, which raises its error as without helpers); an ask a helper could not send (it does not pickle, the
    helper was killed) is solved here. Helpers die with this process (PR_SET_PDEATHSIG)."""
    n = len(problem.asks)
    got: list[tuple[Solution | None, _State | None] | None] = [None] * n  # None: not here (yet)
    out: list[Solution] = []
    queue, queue_w = os.pipe()
    os.write(queue_w, b"".join(k.to_bytes(2, "big") for k in range(n)))
    os.close(queue_w)
    helpers: dict[int, tuple[int, bytearray]] = {}  # result pipe -> (pid, bytes received)
    told: set[int] = set()  # the asks given to ``early``

    def tell() -> None:  # the asks solved ahead of an earlier one, to ``early``
        if early is None:
            return
        for j in range(len(out) + 1, n):
            res = got[j]
            if res is not None and res[0] is not None and j not in told:
                told.add(j)
                early(j + 1, res[0])

    def report(final: bool = False) -> None:  # merge asks in order as they arrive; the callback for each
        while len(out) < n and (got[len(out)] is not None or final):
            k = len(out)
            while got[k] is None and helpers:  # in a helper: wait for it
                receive(next(iter(helpers)), block=True)
                tell()
            if got[k] is None:  # a helper could not send it (it does not pickle, the helper was killed)
                got[k] = names.attempt(k)
            out.append(names.settle(k, *got[k]))  # type: ignore[misc]
            if solved is not None:
                solved(k + 1, out[-1])
        tell()

    def receive(fd: int, block: bool) -> None:
        pid, buf = helpers[fd]
        while True:
            if not block and not select.select([fd], [], [], 0)[0]:
                return
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                os.close(fd)
                os.waitpid(pid, 0)
                del helpers[fd]
                return
            buf += chunk
            _unpack(buf, got)

    try:
        with without_units():
            k = _take(queue)  # the first ask here before forking: the derivations later asks share (the dynamic
            got[k] = names.attempt(k)  # model, the kinematics) are then inherited, not derived again by each helper
            report()
            for _ in range(min(jobs, n - 1) - 1):
                res, res_w = os.pipe()
                pid = os.fork()
                if pid == 0:  # a helper: never returns
                    os.close(res)
                    _helper(problem, names, queue, res_w, figures, optional)
                os.close(res_w)
                helpers[res] = (pid, bytearray())
            while (k := _take(queue)) is not None:
                got[k] = names.attempt(k)
                for fd in list(helpers):
                    receive(fd, block=False)
                report()
            report(final=True)
    finally:
        os.close(queue)
        for fd, (pid, _) in helpers.items():
            os.close(fd)
            stop(pid)
    return out


def _unpack(buf: bytearray, got: list) -> None:
    """Take the complete messages (the length in HEADER bytes, pickled (k, (solution, registered)), (k, (None,
    None)) when the ask failed, (k, None) when it could not be sent) off ``buf``."""
    while len(buf) >= HEADER:
        size = int.from_bytes(buf[:HEADER], "big")
        if len(buf) < HEADER + size:
            return
        k, result = pickle.loads(bytes(buf[HEADER:HEADER + size]))
        del buf[:HEADER + size]
        got[k] = result


def _helper(problem: Problem, names: _Names, queue: int, res: int, figures: bool, optional: bool = True) -> None:
    """A forked helper: solve asks from the queue and send them (see :func:`_parallel`); exits without cleanup."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        sending_optional(optional)
        _die_with_parent()
        while (k := _take(queue)) is not None:
            sol, regs = names.attempt(k)
            try:
                if sol is not None:
                    _sampled(sol, figures)
                data = _dumps((k, (sol, regs)))
            except BaseException:  # noqa: BLE001 - the parent solves this ask again
                data = pickle.dumps((k, None))
            write_message(res, data)
    finally:
        os._exit(0)


def _dumps(obj: object) -> bytes:
    """pickle.dumps, with sympy's Add, Mul, Pow, functions and relations rebuilt unevaluated, as they were made:
    sympy's own pickling calls their constructors, which evaluate (Mul(1/2, a + b) would become a/2 + b/2)."""
    import io
    buf = io.BytesIO()
    _AsMade(buf, pickle.HIGHEST_PROTOCOL).dump(obj)
    return buf.getvalue()


class _AsMade(pickle.Pickler):
    def __init__(self, *args: object) -> None:
        super().__init__(*args)  # type: ignore[arg-type]
        import sympy as sp
        self.made = (sp.Add, sp.Mul, sp.Pow, sp.Function, sp.Derivative, sp.core.relational.Relational)
        self.default = sp.Basic.__reduce_ex__

    def reducer_override(self, obj: object) -> object:
        if isinstance(obj, self.made) and type(obj).__reduce_ex__ is self.default:
            return _unevaluated, (obj.func, obj.args)  # type: ignore[attr-defined]
        return NotImplemented


def _unevaluated(func, args):  # type: ignore[no-untyped-def]
    return func(*args, evaluate=False)


def _sampled(sol: Solution, figures: bool) -> None:
    """A solution's figures made picklable: sampled (``figures``) or left without panels; no sampler kept."""
    for fig in sol.figures:
        fig._panels = fig.panels if figures else []
        fig.sample = _no_sample


def _no_sample() -> list:
    return []


def _die_with_parent() -> None:
    """Linux: SIGKILL this process when its parent dies (the sandbox kills the worker at its time limit)."""
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def all_results(solutions: list[Solution]) -> dict:
    """Results of every ask, by name (a later ask's result of the same name wins)."""
    out = {}
    for s in solutions:
        out.update(s.results)
    return out
