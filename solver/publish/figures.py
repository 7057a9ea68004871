"""Drawing the figures of solutions (matplotlib, headless) beside a written report."""
from __future__ import annotations

import math
import os
import pickle
import queue
import threading
from pathlib import Path
from typing import Callable, NoReturn

from solver.results import Figure, RobotPose, Sketch, Solution
from solver.sandbox import HEADER, read_all, read_exactly, stop, write_all, write_message


def _categorical(ax, curves: list) -> None:  # type: ignore[no-untyped-def]
    """Values at integer x (one per joint): each solid curve as points, side by side; each dashed curve (a bound)
    as a short red tick at every x. No line joins different joints."""
    solid = [c for c in curves if not c.dashed]
    width = 0.6 / max(1, len(solid))
    for k, c in enumerate(solid):
        off = (k - (len(solid) - 1) / 2) * width
        ax.plot([x + off for x in c.x], c.y, "o", markersize=6, label=c.label)
    labelled = False
    for c in curves:
        if c.dashed:
            for x, y in zip(c.x, c.y):
                ax.plot([x - 0.4, x + 0.4], [y, y], color="tab:red", linestyle="--", linewidth=1.2,
                        label=None if labelled or not c.label else c.label)
                labelled = labelled or bool(c.label)
    xs = sorted({x for c in curves for x in c.x})
    ax.set_xticks(xs)
    ax.set_xticklabels([f"{x:g}" for x in xs])


def _angle_ticks(ax, lo: float, hi: float) -> None:  # type: ignore[no-untyped-def]
    names = {-4: r"$-2\pi$", -3: r"$-3\pi/2$", -2: r"$-\pi$", -1: r"$-\pi/2$", 0: "0", 1: r"$\pi/2$", 2: r"$\pi$",
             3: r"$3\pi/2$", 4: r"$2\pi$"}
    ks = [k for k in range(-4, 5) if lo - 1e-9 <= k * math.pi / 2 <= hi + 1e-9]
    ax.set_xticks([k * math.pi / 2 for k in ks])
    ax.set_xticklabels([names[k] for k in ks])


def draw(fig: Figure, path: Path) -> None:
    """Write ``fig`` to ``path`` (format from the suffix: .pdf, .png, .svg)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(fig.panels)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    height = 4.2 if any(p.sketch is not None for p in fig.panels) else 3.2
    f, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, height * rows), squeeze=False)
    for ax, panel in zip(axes.flat, fig.panels):
        if panel.sketch is not None:
            draw_sketch(ax, panel.sketch)
            continue
        if panel.categorical:
            _categorical(ax, panel.curves)
        for c in ([] if panel.categorical else panel.curves):
            if c.filled:
                ax.fill(c.x, c.y, color="0.7", linewidth=0, zorder=1.8, label=c.label or None)
            else:
                ax.plot(c.x, c.y, label=c.label, linewidth=1.6, linestyle="--" if c.dashed else "-")
        for y, label in panel.hlines:
            ax.axhline(y, color="tab:red", linestyle="--", linewidth=1.0, label=label or None)
        for x, y, label in panel.markers:
            ax.plot([x], [y], "o", color="black", markersize=4)
            if label:
                ax.annotate(label, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
        if panel.equal_axes:
            ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(panel.xlabel)
        if panel.ylabel:
            ax.set_ylabel(panel.ylabel)
        if panel.x_is_angle and panel.curves:
            _angle_ticks(ax, panel.curves[0].x[0], panel.curves[0].x[-1])
        if not any(c.filled for c in panel.curves):  # y = 0 is no reference on a map
            ax.axhline(0, color="0.6", linewidth=0.8)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[1]:  # (a single unnamed curve: its axis names it)
            ax.legend(fontsize=8, loc="best")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    f.tight_layout()
    f.set_layout_engine(None)  # laid out: savefig need not lay it out again (a whole extra pass of the text)
    kwargs: dict = {"metadata": {"CreationDate": None}} if path.suffix == ".pdf" else {}
    if any(p.sketch is not None for p in fig.panels):
        kwargs["bbox_inches"] = "tight"  # the legend sits above the drawing
    f.savefig(path, dpi=130, **kwargs)
    plt.close(f)


def _plan(solutions: list[Solution], output: Path, fmt: str, first: int = 1) -> list[tuple[Figure, Path]]:
    """Each figure and its file beside ``output``, <stem>-<k>-<name>.pdf (LaTeX) or .png (Markdown, HTML), k the
    ask's number (``first`` for the first solution given); ``figure.path`` set relative to the output's
    directory."""
    suffix = ".pdf" if fmt == "tex" else ".png"
    jobs = []
    for k, sol in enumerate(solutions, first):
        for fig in sol.figures:
            fig.path = f"{output.stem}-{k}-{fig.name}{suffix}"
            jobs.append((fig, output.parent / fig.path))
    return jobs


def write_figures(solutions: list[Solution], output: Path, fmt: str) -> list[Path]:
    """Draw every figure beside ``output`` (see :func:`_plan`). Returns the files written."""
    jobs = _plan(solutions, output, fmt)
    for fig, path in jobs:
        draw(fig, path)
    return [path for _, path in jobs]


def _warm_up(fmt: str) -> None:
    """Import matplotlib and draw a small figure with mathtext (fonts, the mathtext parser, the backend)."""
    import io

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    f, ax = plt.subplots(figsize=(1, 1))
    ax.plot([0, 1], [0, 1], label=r"$\dot q_1$")
    ax.set_xlabel(r"$t$ [s]")
    ax.legend()
    f.savefig(io.BytesIO(), format="pdf" if fmt == "tex" else "png", dpi=30)
    plt.close(f)


def _paint(fmt: str, jobs_fd: int, status_fd: int) -> None:
    """The painter process: warm up, then read messages (length, pickled (last, [(name, panels, path)])) until the
    pipe ends, drawing each as it comes while the asks after it are solved; the last one (the report is being
    written by then) two ways. Answers b"ok" or the error; never returns. Its other inherited descriptors are
    closed first (a parent reading to EOF, like the sandbox, must not wait for it)."""
    def read(inbox: queue.Queue) -> None:  # a thread: the sender never blocks on a full pipe during the warm-up
        try:
            while (head := read_exactly(jobs_fd, HEADER)) is not None:
                item = pickle.loads(read_exactly(jobs_fd, int.from_bytes(head, "big")) or b"")
                inbox.put(item)
                if item[0]:
                    return
            inbox.put(None)
        except BaseException as exc:  # noqa: BLE001 - raised by the drawing thread
            inbox.put(exc)

    def work() -> None:
        keep = sorted((jobs_fd, status_fd))
        os.closerange(3, keep[0])
        os.closerange(keep[0] + 1, keep[1])
        os.closerange(keep[1] + 1, 1 << 16)
        _fresh_fonts()  # (a parent that drew figures itself, as the tests do)
        inbox: queue.Queue = queue.Queue()
        reader = threading.Thread(target=read, args=(inbox,), daemon=True)
        reader.start()
        _warm_up(fmt)
        while (item := inbox.get()) is not None:
            if isinstance(item, BaseException):
                raise item
            last, jobs = item
            if last:
                reader.join()  # (it has returned) no thread left when _draw_two_ways forks
                _draw_two_ways(jobs)
                return
            _draw_all(jobs)
    _run_and_exit(work, status_fd)


def _run_and_exit(work: Callable[[], None], status_fd: int) -> NoReturn:
    """In a forked process: run ``work``, write b"ok" or its error to ``status_fd``, exit without cleanup."""
    status = b"ok"
    try:
        work()
    except BaseException as exc:  # noqa: BLE001 - reported to the parent
        status = f"{exc.__class__.__name__}: {exc}".encode()[:2000] or b"failed"
    try:
        write_all(status_fd, status)
    finally:
        os._exit(0)


def _fresh_fonts() -> None:
    """In a forked process, before any font is opened: the parent's font objects are dropped and collected now.
    matplotlib empties its font cache at a fork; the memoized methods of mathtext (parsed layouts, sized symbols)
    hold fonts too and are emptied here. Collected later, in the middle of a drawing, a dropped font closes its
    file descriptor, which may by then be the number of a font opened here (the painter closes the descriptors it
    inherits): FreeType then fails with "invalid stream operation" (seen when the painter is forked from a
    process that drew figures itself, as the tests do)."""
    import gc
    import sys
    for name in ("matplotlib.mathtext", "matplotlib._mathtext"):
        module = sys.modules.get(name)
        for cls in (vars(module).values() if module is not None else ()):
            if isinstance(cls, type) and cls.__module__ == name:
                for attr in vars(cls).values():
                    if callable(getattr(attr, "cache_clear", None)):
                        attr.cache_clear()
    if "matplotlib" in sys.modules:
        gc.collect()


def _draw_all(jobs: list) -> None:
    for name, panels, path in jobs:
        draw(Figure(name, "", lambda p=panels: p), Path(path))


def _draw_two_ways(jobs: list) -> None:
    """Draw the (name, panels, path) jobs, every other one in a forked copy of this warmed-up painter (the other
    core: the report is written by then); RuntimeError with the copy's message if it failed."""
    if len(jobs) < 2:
        _draw_all(jobs)
        return
    try:
        r, w = os.pipe()
    except OSError:
        _draw_all(jobs)
        return
    try:
        pid = os.fork()
    except OSError:
        os.close(r)
        os.close(w)
        _draw_all(jobs)
        return
    if pid == 0:  # the copy: the odd jobs
        os.close(r)
        _fresh_fonts()
        _run_and_exit(lambda: _draw_all(jobs[1::2]), w)
    os.close(w)
    try:
        _draw_all(jobs[0::2])
    finally:
        try:
            status = read_all(r)
        finally:
            os.close(r)
            os.waitpid(pid, 0)
    if status != b"ok":
        raise RuntimeError(status.decode(errors="replace") or "crashed")


class Painter:
    """Figures drawn on the other core: a helper process forked before the problem is solved imports and warms
    up matplotlib (about a second) meanwhile, then draws the figures of each ask that :meth:`send` gives it as
    soon as that ask is solved (while the next asks are solved and the report is rendered); :meth:`wait` joins
    it. Without fork (or when the fork fails) :meth:`send` draws in-process. The helper inherits this process's
    limits (the sandbox's memory and CPU time)."""

    def __init__(self, fmt: str) -> None:
        self.fmt = fmt
        self.pid, self._jobs, self._status = 0, -1, -1
        if not hasattr(os, "fork"):
            return
        try:
            jobs_r, jobs_w = os.pipe()
            status_r, status_w = os.pipe()
            pid = os.fork()
        except OSError:
            return
        if pid == 0:  # the painter
            os.close(jobs_w)
            os.close(status_r)
            _paint(fmt, jobs_r, status_w)
        os.close(jobs_r)
        os.close(status_w)
        self.pid, self._jobs, self._status = pid, jobs_w, status_r

    def write(self, solutions: list[Solution], output: Path, fmt: str) -> list[Path]:
        """Send every figure to the painter (or draw it here); ``figure.path`` is set at once. The files."""
        files = self.send(solutions, output, fmt, last=True)
        if not files:  # nothing to draw: do not wait for the warm-up
            self.cancel()
        return files

    def send(self, solutions: list[Solution], output: Path, fmt: str, first: int = 1, last: bool = False
             ) -> list[Path]:
        """Send the figures of ``solutions`` (asks ``first``, ``first`` + 1, ...) to the painter, or draw them
        here; ``figure.path`` is set at once. ``last``: no more will be sent. The files."""
        jobs = _plan(solutions, output, fmt, first)
        if not self.pid:
            for fig, path in jobs:
                draw(fig, path)
        elif self._jobs >= 0 and (jobs or last):
            data = pickle.dumps((last, [(fig.name, fig.panels, str(path)) for fig, path in jobs]))
            try:
                write_message(self._jobs, data)
            finally:
                if last:
                    os.close(self._jobs)
                    self._jobs = -1
        return [path for _, path in jobs]

    def wait(self) -> None:
        """Wait until the painter has drawn every figure sent; RuntimeError with its message if it failed."""
        if not self.pid:
            return
        if self._jobs >= 0:
            os.close(self._jobs)
            self._jobs = -1
        try:
            status = read_all(self._status)
        finally:
            os.close(self._status)
            os.waitpid(self.pid, 0)
            self.pid = 0
        if status != b"ok":
            raise RuntimeError(f"drawing the figures failed: {status.decode(errors='replace') or 'crashed'}")

    def cancel(self) -> None:
        """Stop the painter (the work failed): kill and reap it."""
        if not self.pid:
            return
        for fd in (self._jobs, self._status):
            if fd >= 0:
                os.close(fd)
        self._jobs = self._status = -1
        stop(self.pid)
        self.pid = 0


_PRESTARTED: Painter | None = None


def prestart_painter(fmt: str) -> None:
    """Fork the painter for ``fmt`` now (before the heavy imports), for :func:`painter_for` to hand out."""
    global _PRESTARTED
    _PRESTARTED = Painter(fmt)


def painter_for(fmt: str) -> Painter:
    """The painter started by :func:`prestart_painter` when it was for ``fmt`` (another one is stopped), else a
    new one."""
    global _PRESTARTED
    painter, _PRESTARTED = _PRESTARTED, None
    if painter is not None and painter.fmt == fmt:
        return painter
    if painter is not None:
        painter.cancel()
    return Painter(fmt)


# ------------------------------------------------------------------------------------------------ robot sketches
_POSE_COLORS = ["#1f4e9c", "#c0392b", "#2e8b57", "#8e44ad", "#d35400", "#16a085", "#7f8c8d", "#b7950b"]


def _unit(dx: float, dy: float) -> tuple[float, float]:
    n = math.hypot(dx, dy)
    return (dx / n, dy / n) if n > 1e-12 else (1.0, 0.0)


def _scale(sk: Sketch) -> float:
    xs = [x for p in sk.poses for x, _ in p.points] + [a.x + a.dx for a in sk.arrows]
    ys = [y for p in sk.poses for _, y in p.points] + [a.y + a.dy for a in sk.arrows]
    for c in sk.paths:
        xs += c.x
        ys += c.y
    if not xs:
        return 1.0
    return max(max(xs) - min(xs), max(ys) - min(ys), 1e-3)


def _draw_pose(ax, pose: RobotPose, color: str, L: float, z: int) -> None:  # type: ignore[no-untyped-def]
    from matplotlib.patches import Circle, Polygon

    pts = pose.points
    r = 0.028 * L
    for i, kind in enumerate(pose.joints):
        (x0, y0), (x1, y1) = pts[i], pts[i + 1]
        if kind == "P":
            ux, uy = pose.slides[i] or _unit(x1 - x0, y1 - y0)
            ax.plot([x0, x1], [y0, y1], color=color, lw=2.6, solid_capstyle="butt", zorder=z)
            # the sleeve: a box along the sliding direction at the joint (a first joint: the cart on the rail)
            if i == 0:
                x0, y0 = x1, y1
            h, w = 0.09 * L, 0.035 * L
            nx, ny = -uy, ux
            box = [(x0 - ux * h / 2 + nx * w, y0 - uy * h / 2 + ny * w), (x0 + ux * h / 2 + nx * w, y0 + uy * h / 2 + ny * w),
                   (x0 + ux * h / 2 - nx * w, y0 + uy * h / 2 - ny * w), (x0 - ux * h / 2 - nx * w, y0 - uy * h / 2 - ny * w)]
            ax.add_patch(Polygon(box, closed=True, facecolor="white", edgecolor=color, lw=1.6, zorder=z + 2))
        else:
            ax.plot([x0, x1], [y0, y1], color=color, lw=4.5, solid_capstyle="round", alpha=0.9, zorder=z)
    for i, kind in enumerate(pose.joints):
        if kind == "R":
            x0, y0 = pts[i]
            ax.add_patch(Circle((x0, y0), r, facecolor="white", edgecolor="black", lw=1.3, zorder=z + 3))
    # end effector: a small gripper along the last link
    (xa, ya), (xb, yb) = pts[-2], pts[-1]
    dx, dy = _unit(xb - xa, yb - ya)
    nx, ny = -dy, dx
    g = 0.045 * L
    ax.plot([xb + nx * g, xb - nx * g], [yb + ny * g, yb - ny * g], color="black", lw=1.6, zorder=z + 3)
    for sgn in (1, -1):
        ax.plot([xb + sgn * nx * g, xb + sgn * nx * g + dx * g], [yb + sgn * ny * g, yb + sgn * ny * g + dy * g],
                color="black", lw=1.6, zorder=z + 3)


def _draw_base(ax, pose: RobotPose, L: float, extent: tuple[float, float, float, float]) -> None:  # type: ignore[no-untyped-def]
    from matplotlib.patches import Polygon

    x0, y0 = pose.points[0]
    h = 0.06 * L
    if pose.joints and pose.joints[0] == "P":
        ux, uy = pose.slides[0] or (1.0, 0.0)
        nx, ny = uy, -ux  # hatch on the right of the rail direction
        xmin, xmax, ymin, ymax = extent
        span = 1.2 * max(xmax - xmin, ymax - ymin)
        a = (x0 - ux * span, y0 - uy * span)
        b = (x0 + ux * span, y0 + uy * span)
        ax.plot([a[0], b[0]], [a[1], b[1]], color="0.3", lw=1.4, zorder=1)
        k = 40
        for t in range(k + 1):
            px, py = a[0] + (b[0] - a[0]) * t / k, a[1] + (b[1] - a[1]) * t / k
            ax.plot([px, px + (nx - ux) * h * 0.6], [py, py + (ny - uy) * h * 0.6], color="0.55", lw=0.7, zorder=1)
        return
    tri = [(x0, y0), (x0 - h, y0 - 1.6 * h), (x0 + h, y0 - 1.6 * h)]
    ax.add_patch(Polygon(tri, closed=True, facecolor="0.85", edgecolor="0.3", lw=1.0, zorder=1))
    ax.plot([x0 - 1.8 * h, x0 + 1.8 * h], [y0 - 1.6 * h] * 2, color="0.3", lw=1.2, zorder=1)
    for t in range(7):
        xx = x0 - 1.8 * h + t * 0.6 * h
        ax.plot([xx, xx - 0.5 * h], [y0 - 1.6 * h, y0 - 2.1 * h], color="0.55", lw=0.7, zorder=1)


def draw_sketch(ax, sk: Sketch) -> None:  # type: ignore[no-untyped-def]
    """A planar robot to scale: base (a ground symbol, or a rail for a first prismatic joint), links as bars,
    revolute joints as circles, prismatic ones as sleeves, the end effector as a gripper; several poses in
    different colours, arrows and dashed paths on top."""
    from matplotlib.lines import Line2D

    L = _scale(sk)
    xs = [x for p in sk.poses for x, _ in p.points]
    ys = [y for p in sk.poses for _, y in p.points]
    extent = (min(xs, default=0.0), max(xs, default=1.0), min(ys, default=0.0), max(ys, default=1.0))
    for c in sk.paths:
        ax.plot(c.x, c.y, ls="--", color="0.35", lw=1.2, label=c.label or None, zorder=2)
    if sk.poses:
        _draw_base(ax, sk.poses[0], L, extent)
    handles = []
    for k, pose in enumerate(sk.poses):
        color = _POSE_COLORS[k % len(_POSE_COLORS)]
        _draw_pose(ax, pose, color, L, 3 + 5 * k)
        if pose.label:
            handles.append(Line2D([0], [0], color=color, lw=4, label=pose.label))
    for a in sk.arrows:
        ax.annotate("", xy=(a.x + a.dx, a.y + a.dy), xytext=(a.x, a.y),
                    arrowprops={"arrowstyle": "-|>", "color": "#e67e22", "lw": 2.0}, zorder=50)
        if a.label:
            ax.annotate(a.label, xy=(a.x + a.dx, a.y + a.dy), xytext=(4, 4), textcoords="offset points",
                        color="#e67e22", fontsize=10, zorder=50)
    ax.set_aspect("equal", adjustable="box")
    pad = 0.15 * L
    ax.set_xlim(extent[0] - pad, extent[1] + pad)
    ax.set_ylim(extent[2] - pad, extent[3] + pad)
    ax.set_xlabel(sk.xlabel)
    ax.set_ylabel(sk.ylabel)
    ax.grid(True, alpha=0.25)
    if handles or any(c.label for c in sk.paths):
        extra = [h for h in ax.get_lines() if h.get_label() and not h.get_label().startswith("_")]
        ax.legend(handles=handles + extra, fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.01),
                  ncol=min(2, len(handles) + len(extra)), frameon=False)
