"""What a motion-graph build kept of its input, and what the library can do.

:func:`source_report` accounts for every second of every input file: kept in the graph
(its own frames, and its mirrored copy's), or dropped with the reason -- the derived labels'
reasons (:data:`.derive.DROPPED`: not walking-like, uneven ground), no transition (frames
before the first or after the last hub pose of their take: they share no pose with the rest
of the data within the threshold), pruned (edges between hubs that are dead ends or not
strongly connected with the rest, Sung, Kovar and Gleicher 2005, section 4), or dropped for
foot slide (edges whose planted feet slide faster than in the capture after snapping).

:func:`capabilities` says what goals the library can serve: which node labels it has, whether
a character can stand still on a node (an idle self-loop within the adjustment tolerance),
stop from walking and start again, turn on the spot; and, plainly, what is missing.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from runtime.crowd.idle import still_nodes
from runtime.motion.graph import MotionGraph

from .derive import DROPPED

__all__ = ["source_report", "capabilities", "format_report", "NO_TRANSITION", "PRUNED", "SLID"]

NO_TRANSITION = "no transition: shares no pose with the rest of the data within the threshold"
PRUNED = "pruned: dead ends, or not strongly connected with the rest"
SLID = "foot slide: planted feet slide after snapping"
STAND_LABELS = ("idle", "turn", "stand", "stop", "start")
WALK_LABELS = ("walk", "run")
DEFAULT_EPS = (0.02, 2.0, 1.0 / 15.0)


def _interval_reasons(labels) -> list:
    """Per frame interval (i, i + 1) of a file: the drop reason of a derived label, or None."""
    out = []
    for a, b in zip(labels[:-1], labels[1:]):
        out.append(DROPPED.get(b) or DROPPED.get(a))
    return out


def source_report(graph: MotionGraph, files) -> list[dict]:
    """Per input file (:class:`.sources.SourceFile`): ``given_s`` (seconds of motion read),
    ``kept_s`` (seconds of it on the graph's edges), ``kept_mirrored_s`` (seconds of its
    mirrored copy on the graph's edges) and ``dropped`` ({reason: seconds}, summing with
    ``kept_s`` to ``given_s``)."""
    fps = graph.fps
    spans = graph.meta.get("occurrence_span", {})
    kept_edges: dict[str, list] = {}
    for eo in graph.meta.get("edge_origin", []):
        kept_edges.setdefault(eo["take"], []).append((int(eo["start"]), int(eo["end"])))
    slid_edges: dict[str, list] = {}
    for eo in (graph.meta.get("foot_slide") or {}).get("dropped", []):
        slid_edges.setdefault(eo["take"], []).append((int(eo["start"]), int(eo["end"])))
    out = []
    for f in files:
        n = max(0, f.frames - 1)
        base = _interval_reasons(f.labels) if f.derived else [None] * n
        tallies = []
        for mirrored in (False, True):
            cat = [r if r is not None else NO_TRANSITION for r in base]
            for name, off in f.takes.items():
                if (name in f.mirrored) != mirrored:
                    continue
                span = spans.get(name)
                if span is None:
                    continue
                covered = np.zeros(n, dtype=bool)
                for s, e in kept_edges.get(name, []):
                    covered[off + s:off + e] = True
                slid = np.zeros(n, dtype=bool)
                for s, e in slid_edges.get(name, []):
                    slid[off + s:off + e] = True
                for i in range(off + span[0], off + span[1]):
                    cat[i] = "kept" if covered[i] else SLID if slid[i] else PRUNED
            tallies.append(cat)
        own, mir = tallies
        dropped: dict[str, float] = {}
        for c in own:
            if c != "kept":
                dropped[c] = dropped.get(c, 0.0) + 1.0 / fps
        out.append({"file": Path(f.path).name, "given_s": round(n / fps, 2),
                    "kept_s": round(sum(c == "kept" for c in own) / fps, 2),
                    "kept_mirrored_s": round(sum(c == "kept" for c in mir) / fps, 2) if f.mirrored else None,
                    "dropped": {k: round(v, 2) for k, v in sorted(dropped.items(), key=lambda kv: -kv[1])}})
    return out


def _edge_ends(graph: MotionGraph, takes) -> tuple[list, list]:
    """First and last frame label of every edge (from its take's labels)."""
    labels = {t.name: t.labels for t in takes}
    first, last = [], []
    for eo in graph.meta.get("edge_origin", []):
        lab = labels.get(eo["take"])
        first.append(lab[int(eo["start"])] if lab else "")
        last.append(lab[int(eo["end"])] if lab else "")
    return first, last


def capabilities(graph: MotionGraph, takes, eps=DEFAULT_EPS) -> dict:
    """What goals the library can serve (see the module docstring). ``takes``: the
    :class:`.build.SourceClip` list the graph was built from (their labels)."""
    g = graph
    first, last = _edge_ends(g, takes)
    still = still_nodes(g, eps, g.fps)
    labels = g.node_labels_all()
    walking = g.edge_state == 0
    dist = np.hypot(g.edge_disp[:, 0], g.edge_disp[:, 1])
    turn = np.degrees(g.edge_disp[:, 2])
    stop = np.array([a in WALK_LABELS and b in STAND_LABELS for a, b in zip(first, last)], dtype=bool) & walking
    start = np.array([a in STAND_LABELS and b in WALK_LABELS for a, b in zip(first, last)], dtype=bool) & walking
    on_spot = walking & (dist < 0.5) & (np.abs(turn) >= 45.0)
    walk_e = walking & (dist >= 0.5)
    speed = dist[walk_e] / np.maximum(g.edge_duration[walk_e], 1e-9)
    out = {
        "node_labels": {lab: int(len(g.nodes_with_label(lab))) for lab in labels},
        "still_nodes": int(still.sum()),
        "stop_edges": int(stop.sum()), "start_edges": int(start.sum()),
        "turn_on_spot_edges": int(on_spot.sum()),
        "turn_on_spot_deg": [round(float(turn[on_spot].min()), 1), round(float(turn[on_spot].max()), 1)] if on_spot.any() else None,
        "walk_edges": int(walk_e.sum()),
        "walk_turn_deg": [round(float(turn[walk_e].min()), 1), round(float(turn[walk_e].max()), 1)] if walk_e.any() else None,
        "walk_speed_m_s": [round(float(speed.min()), 2), round(float(speed.max()), 2)] if walk_e.any() else None,
    }
    missing = []
    if "stand" not in labels:
        missing.append("stand: no standing pose (goals and starts with pose \"stand\" are impossible)")
    elif not still.any():
        missing.append("still: no standing node with an idle self-loop within eps (characters cannot wait in place)")
    if "walk" not in labels:
        missing.append("walk: no walking pose")
    if "stand" in labels and not stop.any():
        missing.append("stop: no motion from walking to standing")
    if "stand" in labels and not start.any():
        missing.append("start: no motion from standing to walking")
    if not on_spot.any():
        missing.append("turn on the spot: no edge turning 45 deg or more within 0.5 m")
    for lab, what in (("sit", "sitting (seats, pose \"sit\")"), ("carry", "carrying (boxes, pose \"carry\")")):
        if lab not in labels:
            missing.append(f"{lab}: no {what}")
    out["missing"] = missing
    return out


def format_report(sources: list[dict], caps: dict) -> list[str]:
    """Lines for the terminal: per file seconds kept of seconds given and why the rest was
    dropped, then what the library can do and what it lacks."""
    lines = ["per file: seconds kept of seconds given (dropped: reason)"]
    for r in sources:
        mir = f" + {r['kept_mirrored_s']:.1f} s mirrored" if r.get("kept_mirrored_s") is not None else ""
        lines.append(f"  {r['file']}: {r['kept_s']:.1f} of {r['given_s']:.1f} s{mir}")
        for reason, s in r["dropped"].items():
            lines.append(f"      {s:5.1f} s {reason}")
    tk = sum(r["kept_s"] for r in sources)
    tg = sum(r["given_s"] for r in sources)
    lines.append(f"  total: {tk:.1f} of {tg:.1f} s kept ({100 * tk / max(tg, 1e-9):.0f}%)")
    c = caps
    lines.append(f"library: node labels {c['node_labels']}, {c['still_nodes']} still node(s), "
                 f"{c['stop_edges']} stop / {c['start_edges']} start edges, "
                 f"{c['turn_on_spot_edges']} turn-on-the-spot edges {c['turn_on_spot_deg'] or ''}, "
                 f"{c['walk_edges']} walking edges (turning {c['walk_turn_deg']} deg, {c['walk_speed_m_s']} m/s)")
    for m in c["missing"]:
        lines.append(f"  missing: {m}")
    return lines
