"""Idling: what a character does while it waits on a motion-graph node.

A node's idle clip is its self-loop clip with the least drift among its *idle* loops, those
whose every frame label is one of :data:`IDLE_LABELS` (standing, sitting, standing with a box);
idling repeats it, each repeat bent back onto the start so the character stays on its spot.
A self loop that walks, turns, starts, stops, sits down or picks up is never played to wait:
with the root held, its legs would step on the spot. A node without an idle loop holds its hub
pose. A node whose idle clip drifts within the adjustment tolerance is *still*: a character can
wait there (a walking hub's self loops are walk cycles: it has no idle loop and is not still).
"""
from __future__ import annotations

import numpy as np

from ..motion.cylinders import blend_cylinders
from ..motion.planar import compose
from .planner.library import MotionLibrary
from .planner.types import Config
from .tracks import Track

__all__ = ["IDLE_LABELS", "idle_loops", "idle_loop", "track_cylinders", "idle_track", "still_nodes", "hold_tail",
           "idle_for"]

IDLE_LABELS = frozenset({"idle", "stand", "sit", "carry_idle"})   # frame labels of motion that stays put


def idle_loops(g, node: int) -> np.ndarray:
    """The node's self loops whose every frame is labelled as idling (:data:`IDLE_LABELS`)."""
    loops = np.flatnonzero((g.edge_src == node) & (g.edge_dst == node))
    return np.array([e for e in loops if g.edge_labels[e] and IDLE_LABELS.issuperset(g.edge_labels[e])],
                    dtype=np.int64)


def idle_loop(g, node: int) -> int:
    """The node's idle loop (:func:`idle_loops`) with the least drift (the one idling repeats),
    or -1 when it has none."""
    memo = g.__dict__.setdefault("_idle_loop_memo", {})    # per graph: every wait asks again
    e = memo.get(int(node))
    if e is None:
        loops = idle_loops(g, node)
        if len(loops) == 0:
            e = -1
        else:
            drift = np.hypot(g.edge_disp[loops, 0], g.edge_disp[loops, 1]) + 0.3 * np.abs(g.edge_disp[loops, 2])
            e = int(loops[np.argmin(drift)])
        memo[int(node)] = e
    return e


def track_cylinders(graph, track: Track) -> tuple[np.ndarray, np.ndarray]:
    """Per frame of ``track``, its bounding cylinder: axis position (F, 2) and radius (F,) (the
    circle holding the cylinders of the two library frames it blends)."""
    return blend_cylinders(graph, track.frames_a, track.frames_b, track.root)


def idle_track(lib: MotionLibrary, cfg: Config, n_frames: int, turn: bool = False) -> Track:
    """``n_frames`` frames (including the start frame) of idling at ``cfg``: the node's
    self-loop clip with the least drift, repeated, each repeat bent back onto the start
    configuration; a held pose when the node has no self loop. ``turn``: each repeat is bent
    back onto the start position only and keeps the clip's turn, so the idling ends turned by
    the clips' own small turns -- what a wait before a motion needs: bent back onto the
    heading, a wait of 30 s leaves the raw clips integrated from its start a few degrees off
    the motion after it, which the checker's per-frame adjustment sees as the whole walk
    rotated."""
    g = lib.g
    e = idle_loop(g, cfg.node)
    start = np.array([cfg.x, cfg.z, cfg.heading])
    if e < 0 or n_frames <= 1:
        into = np.flatnonzero(g.edge_dst == cfg.node)
        last = g.edge_start[into[0] + 1] - 1 if len(into) else 0
        fa = np.full(n_frames, last, dtype=np.int64)
        return Track(fa, fa.copy(), np.zeros(n_frames, np.float32), np.repeat(start[None], n_frames, 0), cfg.frame)
    a, b = g.edge_start[e], g.edge_start[e + 1]
    L = b - a                                   # frames in the loop including both hub frames
    local = np.stack([g.frame_xz[a:b, 0], g.frame_xz[a:b, 1], g.frame_heading[a:b]], axis=1)
    ramp = np.linspace(0.0, 1.0, L)[:, None] * g.edge_disp[e][None, :]
    if turn:
        ramp[:, 2] = 0.0
    local = local - ramp                        # each repeat returns exactly to the start
    reps = int(np.ceil((n_frames - 1) / (L - 1)))
    idx = np.concatenate([[0]] + [np.arange(1, L)] * reps)[:n_frames]
    frames = a + idx
    if turn:
        rep = np.concatenate([[0], np.repeat(np.arange(reps), L - 1)])[:n_frames]
        starts = np.repeat(start[None], reps, 0)
        starts[:, 2] += np.arange(reps) * float(g.edge_disp[e, 2])
        root = compose(starts[rep], local[idx])
    else:
        root = compose(start[None], local[idx])
    return Track(frames, frames.copy(), np.zeros(n_frames, np.float32), root, cfg.frame)


def still_nodes(graph, eps, fps: float = 30.0) -> np.ndarray:
    """Per node: whether idling on it stands still -- its least-drifting self-loop clip (the
    one :func:`idle_track` repeats, its drift removed as a ramp) drifts within the per-frame
    adjustment tolerance ``eps`` (m/s, deg/s, ...). A walking hub's self loops are walk
    cycles: idling there would walk on the spot."""
    g = graph
    ep, eh = float(eps[0]), float(eps[1])
    still = np.zeros(g.num_nodes, dtype=bool)
    for n in range(g.num_nodes):
        e = idle_loop(g, n)
        if e < 0:
            continue
        d = g.edge_disp[e]
        dur = (g.edge_frames[e] - 1) / fps
        still[n] = dur > 0 and np.hypot(d[0], d[1]) / dur <= ep and np.degrees(abs(d[2])) / dur <= eh
    return still


def hold_tail(lib, graph, end: Config, n_total: int):
    """(frames, xz, radius) of idling at ``end`` from the frame after it to the scenario's end
    (what the scheduler appends after a character's last goal)."""
    n = n_total - end.frame
    if n <= 1:
        return None
    tr = idle_track(lib, end, n)
    frames = end.frame + np.arange(1, n)
    xz, rad = track_cylinders(graph, tr)
    return frames, xz[1:], rad[1:]


def idle_for(lib, graph, cfg: Config, seconds: float, fps: float) -> Track:
    """About ``seconds`` of idling at ``cfg`` (:func:`idle_track`) in whole repeats of its
    loop clip, so that the last frame is back on ``cfg``'s node and position (turned by the
    clip's own turns, see ``turn``); its clock starts at ``cfg.frame``."""
    e = idle_loop(graph, cfg.node)             # the clip idle_track repeats
    step = int(graph.edge_start[e + 1] - graph.edge_start[e]) - 1 if e >= 0 else 1   # a held pose: any length
    n = 1 + max(1, int(round(seconds * fps / step))) * step
    tr = idle_track(lib, cfg, n, turn=True)
    tr.start_frame = cfg.frame
    return tr
