"""Drawing the figures of solutions (matplotlib, headless) beside a written report."""
from __future__ import annotations

import math
from pathlib import Path

from solver.results import Figure, Solution


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
    f, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
    for ax, panel in zip(axes.flat, fig.panels):
        for c in panel.curves:
            ax.plot(c.x, c.y, label=c.label, linewidth=1.6)
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
        ax.axhline(0, color="0.6", linewidth=0.8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    f.tight_layout()
    kwargs = {"metadata": {"CreationDate": None}} if path.suffix == ".pdf" else {}
    f.savefig(path, dpi=130, **kwargs)
    plt.close(f)


def write_figures(solutions: list[Solution], output: Path, fmt: str) -> list[Path]:
    """Draw every figure beside ``output`` as <stem>-<name>.pdf (LaTeX) or .png (Markdown, HTML) and set
    ``figure.path`` relative to the output's directory. Returns the files written."""
    suffix = ".pdf" if fmt == "tex" else ".png"
    written = []
    for k, sol in enumerate(solutions, 1):
        for fig in sol.figures:
            name = f"{output.stem}-{k}-{fig.name}{suffix}"
            path = output.parent / name
            draw(fig, path)
            fig.path = name
            written.append(path)
    return written
