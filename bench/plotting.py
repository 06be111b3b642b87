"""What the benchmarks' ``--plot PNG`` pictures share: a headless (Agg) figure, one colour for
what this run measured and one for a paper's own values, value labels on bars, a check of the
output path before the run starts, and an atomic PNG write (a temporary file in the same
directory, then ``os.replace``)."""
from __future__ import annotations

import os
import tempfile

OURS = "#2a6fb0"        # measured by the bench in this run
OURS_LIGHT = "#8fb8de"  # a second series of ours (e.g. phase 2 beside phase 1)
PAPER = "#c0772a"       # the paper's values, as printed in its text or tables
PAPER_LIGHT = "#e8c39b"
PASS = "#2a7a2a"
FAIL = "#b02a2a"
DPI = 120


def check_png_path(path: str) -> str | None:
    """Why ``path`` cannot take a PNG (a one-line reason naming it), or None: checked before a
    long benchmark runs, so a typo does not cost the run."""
    if not str(path).lower().endswith(".png"):
        return f"{path}: the picture is written as PNG; give a file name ending in .png"
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        return f"{path}: directory {d} does not exist"
    if not os.access(d, os.W_OK):
        return f"{path}: directory {d} cannot be written"
    if os.path.isdir(path):
        return f"{path}: is a directory"
    return None


def figure(ncols: int = 1, width: float = 6.0, height: float = 3.6):
    """A new figure with ``ncols`` axes side by side, drawn headless (Agg); returns (fig, axes),
    axes a list."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, ncols, figsize=(width, height), dpi=DPI, squeeze=False)
    return fig, list(axes[0])


def value_text(v: float) -> str:
    """A bar's value as people write it: 7,200 and 2,400; 45.2, 2.5, 0.012."""
    return f"{v:,.0f}" if abs(v) >= 1000 else f"{v:.3g}"


def bar_labels(ax, bars, fontsize: float = 7):
    """Each bar's value written above it."""
    for b in bars:
        h = b.get_height()
        ax.annotate(value_text(h), (b.get_x() + b.get_width() / 2, h), textcoords="offset points",
                    xytext=(0, 2), ha="center", va="bottom", fontsize=fontsize)


def log_bars_axis(ax, values):
    """A log value axis for bars: from the power of ten below the smallest value (where every
    bar starts) to room for the labels above the tallest."""
    import math
    vals = [v for v in values if v > 0 and math.isfinite(v)]
    if not vals:
        return
    ax.set_yscale("log")
    ax.set_ylim(10 ** math.floor(math.log10(min(vals)) - 0.3), max(vals) * 4)


def verdict_label(ax, x, y, ok: bool, fontsize: float = 8):
    """'pass' (green) or 'FAIL' (red) just above a measured point: the independent checker's verdict."""
    ax.annotate("pass" if ok else "FAIL", (x, y), textcoords="offset points", xytext=(0, 7), ha="center",
                fontsize=fontsize, color=PASS if ok else FAIL)


def save_atomic(fig, path: str) -> None:
    """Write ``fig`` as PNG to ``path`` atomically and close it: a reader sees the old file or
    the new one, never a partial one, and no temporary is left behind on error."""
    import matplotlib.pyplot as plt
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=d)
    os.close(fd)
    try:
        fig.savefig(tmp, format="png")
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)    # a temporary is private (0600); the picture is not
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
