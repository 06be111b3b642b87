"""The summary of a batch: ``summary.csv``, ``summary.md`` and the plot ``sweep.png``.

One row per variant, in the sweep's order: its axis values, the outcome (``passed``: the
checker passed; ``failed``: the checker failed; ``error``: the variant could not be baked, with
the reason; ``lost``: its worker died every time it ran), the checker's figures, the timings,
how many times it was started (more than one: its worker was lost and it ran again) and the
worker that wrote it.

The plot has two panels against the sweep's first numeric axis other than ``seed``: planning
seconds per character and the share of characters whose adjustment the checker found within
eps; one line per combination of the other axes, the mean over seeds with their range.
All files are written atomically.
"""
from __future__ import annotations

import csv
import io
import itertools
import math

from runtime.assets import atomic_write_bytes

__all__ = ["COLUMNS", "summary_rows", "write_summary", "plot_sweep"]

COLUMNS = ("status", "characters", "within_eps", "overlap_pairs", "in_obstacles", "arrivals_in_window",
           "max_position_error_mm", "plan_s", "write_s", "wall_s", "attempts", "worker", "error")


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 1e-3 and v else f"{v:.2f}"
    if isinstance(v, list):
        return " ".join(_fmt(x) for x in v)
    return str(v)


def summary_rows(variants, records: dict, attempts: dict) -> list[dict]:
    """One dict per variant: ``variant``, its axis values, then :data:`COLUMNS`."""
    rows = []
    for v in variants:
        r = records.get(v.id) or {"status": "lost", "error": "no result"}
        n = r.get("characters")
        row = {"variant": v.id, **{k: val for k, val in v.params.items()}}
        row.update({
            "status": r.get("status"),
            "characters": n if n is not None else v.characters,
            "within_eps": r.get("characters_within_eps"),
            "overlap_pairs": r.get("character_overlap_pairs"),
            "in_obstacles": r.get("obstacle_overlap_characters"),
            "arrivals_in_window": (f"{r['goals_in_window']}/{r['goals']}" if "goals" in r else None),
            "max_position_error_mm": r.get("max_position_error_mm"),
            "plan_s": r.get("plan_seconds"), "write_s": r.get("write_seconds"), "wall_s": r.get("seconds"),
            "attempts": attempts.get(v.id, 0), "worker": r.get("worker"), "error": r.get("error") or "",
        })
        rows.append(row)
    return rows


def _csv(rows, header) -> bytes:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:        # full precision for analysis; lists (eps) as space-separated numbers
        w.writerow(["" if row.get(h) is None else " ".join(map(str, row[h])) if isinstance(row[h], list)
                    else row[h] for h in header])
    return buf.getvalue().encode()


def _markdown(title: str, rows, header, counts: dict, plot_name: str | None) -> bytes:
    cell = lambda x: _fmt(x).replace("|", "\\|")                                    # noqa: E731
    lines = [f"# Batch {title}", "",
             ", ".join(f"{n} {k}" for k, n in counts.items()) + f" of {len(rows)} variants.", ""]
    if plot_name:
        lines += [f"![sweep]({plot_name})", ""]
    lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(row.get(h)) for h in header) + " |" for row in rows]
    return ("\n".join(lines) + "\n").encode()


def _x_axis(axes: dict) -> str | None:
    numeric = [k for k, vals in axes.items()
               if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in vals)]
    return next((k for k in numeric if k != "seed"), numeric[0] if numeric else None)


def plot_sweep(axes: dict, rows: list[dict], title: str) -> bytes:
    """PNG bytes of the sweep's plot (see the module docstring)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    x_key = _x_axis(axes)
    others = [k for k in axes if k not in (x_key, "seed")]
    fig = Figure(figsize=(10, 4.2), dpi=100)
    FigureCanvasAgg(fig)
    ax_t, ax_c = fig.subplots(1, 2)
    groups = itertools.product(*(axes[k] for k in others)) if others else [()]
    for combo in groups:
        sel = [r for r in rows if all(repr(r.get(k)) == repr(v) for k, v in zip(others, combo))]
        label = ", ".join(f"{k} {_fmt(v)}" for k, v in zip(others, combo)) or None
        xs = sorted({r.get(x_key) if x_key else r["variant"] for r in sel}, key=lambda x: (str(type(x)), x))
        tm, tlo, thi, cm, clo, chi, bad = [], [], [], [], [], [], []
        for x in xs:
            at = [r for r in sel if (r.get(x_key) if x_key else r["variant"]) == x]
            ok = [r for r in at if r["status"] in ("passed", "failed") and r.get("plan_s") is not None]
            per = [r["plan_s"] / max(1, r["characters"]) for r in ok]
            clean = [100.0 * (r["within_eps"] or 0) / max(1, r["characters"]) for r in ok]
            tm.append(sum(per) / len(per) if per else math.nan)
            tlo.append(min(per) if per else math.nan)
            thi.append(max(per) if per else math.nan)
            cm.append(sum(clean) / len(clean) if clean else math.nan)
            clo.append(min(clean) if clean else math.nan)
            chi.append(max(clean) if clean else math.nan)
            if len(ok) < len(at):
                bad.append(x)
        pos = list(range(len(xs))) if x_key is None else xs
        for ax, m, lo, hi in ((ax_t, tm, tlo, thi), (ax_c, cm, clo, chi)):
            err = [[a - b for a, b in zip(m, lo)], [b - a for a, b in zip(m, hi)]]
            ax.errorbar(pos, m, yerr=err, marker="o", capsize=3, label=label)
        for x in bad:
            ax_c.plot([pos[xs.index(x)]], [0.0], marker="x", color="red", markersize=9, linestyle="none")
    ax_t.set_ylabel("planning seconds per character")
    ax_c.set_ylabel("characters within eps (%)  (x: a variant not baked)")
    ax_c.set_ylim(-5, 105)
    for ax in (ax_t, ax_c):
        ax.set_xlabel(x_key or "variant")
        ax.grid(alpha=0.3)
    if others:
        ax_t.legend(fontsize=8)
    fig.suptitle(f"batch {title}" + (" (mean over seeds, bars: range)" if "seed" in axes and x_key != "seed" else ""))
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def write_summary(out, sweep, variants, records: dict, attempts: dict) -> dict:
    """Write ``summary.csv``, ``summary.md`` and ``sweep.png`` into ``out``; returns the counts
    of each status."""
    from pathlib import Path
    out = Path(out)
    rows = summary_rows(variants, records, attempts)
    header = ["variant", *sweep.axes.keys(), *COLUMNS]
    counts = {s: sum(r["status"] == s for r in rows) for s in ("passed", "failed", "error", "lost")}
    atomic_write_bytes(out / "summary.csv", _csv(rows, header))
    atomic_write_bytes(out / "sweep.png", plot_sweep(sweep.axes, rows, sweep.name))
    atomic_write_bytes(out / "summary.md", _markdown(sweep.name, rows, header, counts, "sweep.png"))
    return counts
