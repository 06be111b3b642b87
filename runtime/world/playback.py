"""Playback: every character's buffered future on the world clock, structure of arrays.

Each character owns a slot: a ring buffer of future frames (library frames a/b/t and the root
x, z, heading). A tick advances every read head at once; the current pose of all characters is
one gather (no per-character Python loop). When a buffer runs low and nothing is planned, idle
clips of the character's node are appended, so a character never freezes. Each slot keeps its
*boundaries*: the frames where it stands exactly on a graph node (the end of an idle loop, the
end of a segment), where a new plan may take over.

Planned motion written into a buffer also goes into the space-time index; idling becomes an idle
stretch (:mod:`runtime.world.occupancy`).

Limits: ``MAX_BUFFER`` frames (60 s at 30 Hz) per character, minus one kept for interpolation.
"""
from __future__ import annotations

import math

import numpy as np

from ..crowd.idle import idle_loop, idle_track
from ..crowd.planner import Config, MotionLibrary
from ..crowd.spacetime import SpaceTimeIndex
from ..crowd.tracks import Track
from ..motion.cylinders import blend_cylinders
from ..motion.planar import compose
from .occupancy import IdleStretches

__all__ = ["Playback", "MAX_BUFFER"]

MAX_BUFFER = 1800          # frames of future per character (60 s at 30 Hz)


class Playback:
    """The buffers of all characters.

    Args:
        lib: the motion library (idle clips, bounding radii).
        fps: the clock's rate.
        index: the space-time index planned motion is written into.
        capacity: slots to start with (doubled when full).

    Attributes (arrays over slots): ``active``, ``head`` (absolute frame of the current pose),
    ``tail`` (absolute frame of the last buffered frame), ``buf_a``, ``buf_b``, ``buf_t``,
    ``buf_root`` (slots x ``size``), ``tail_node``; ``boundaries[slot]``: (frame, Config) list.
    """

    size = MAX_BUFFER

    def __init__(self, lib: MotionLibrary, fps: float, index: SpaceTimeIndex, capacity: int = 64):
        self.lib, self.graph, self.fps = lib, lib.g, fps
        self.index = index
        self.stretches = IdleStretches()
        self._idle_cache: dict = {}
        self._loop_cache: dict = {}
        self.alloc(capacity)

    # -- storage ------------------------------------------------------------------------------------
    def alloc(self, cap: int) -> None:
        self.cap = cap
        self.active = np.zeros(cap, dtype=bool)
        self.head = np.zeros(cap, dtype=np.int64)
        self.tail = np.zeros(cap, dtype=np.int64)
        self.buf_a = np.zeros((cap, MAX_BUFFER), dtype=np.int64)
        self.buf_b = np.zeros((cap, MAX_BUFFER), dtype=np.int64)
        self.buf_t = np.zeros((cap, MAX_BUFFER), dtype=np.float32)
        self.buf_root = np.zeros((cap, MAX_BUFFER, 3))
        self.tail_node = np.zeros(cap, dtype=np.int64)
        self.indexed = np.zeros(cap, dtype=bool)         # the slot's frames are in the space-time index
        self.buf_idle = np.zeros((cap, MAX_BUFFER), dtype=bool)   # frame written as idle (not indexed)
        self.boundaries = [[] for _ in range(cap)]

    def grow(self) -> None:
        """Double the slots, keeping every buffer."""
        names = ("active", "head", "tail", "buf_a", "buf_b", "buf_t", "buf_root", "tail_node", "indexed", "buf_idle")
        old = {k: getattr(self, k) for k in names}
        bounds = self.boundaries
        n = self.cap
        self.alloc(n * 2)
        for k, v in old.items():
            getattr(self, k)[:n] = v
        self.boundaries[:n] = bounds

    def free_slot(self) -> int:
        free = np.flatnonzero(~self.active)
        if len(free) == 0:
            self.grow()
            free = np.flatnonzero(~self.active)
        return int(free[0])

    def place(self, s: int, frame: int, position, heading: float, node: int) -> None:
        """Start slot ``s`` standing on ``node`` at ``position`` (x, z), facing ``heading``, at
        ``frame`` (and the frame before it: interpolation before the first tick)."""
        self.active[s] = True
        self.head[s] = frame
        self.tail[s] = frame
        self.tail_node[s] = node
        g = self.graph
        first = g.edge_start[g.out_edges(node)[0]] if len(g.out_edges(node)) else 0
        for f in (frame - 1, frame):
            self.buf_root[s, f % MAX_BUFFER] = (position[0], position[1], heading)
            self.buf_a[s, f % MAX_BUFFER] = first
            self.buf_b[s, f % MAX_BUFFER] = first
            self.buf_t[s, f % MAX_BUFFER] = 0.0
        self.boundaries[s] = [(frame, Config(node, float(position[0]), float(position[1]), float(heading), frame))]

    def release(self, s: int) -> None:
        self.active[s] = False
        self.index.remove_owner(s)
        self.stretches.remove(s)
        self.indexed[s] = False
        self.boundaries[s] = []

    # -- writing -------------------------------------------------------------------------------------
    def write(self, s: int, track: Track, from_frame: int, idle_radius: float | None = None) -> None:
        """Replace the buffer of slot ``s`` from absolute frame ``from_frame`` with ``track``
        (whose first frame is at ``from_frame``). Planned motion goes into the space-time index
        (the whole buffered future is re-indexed); idle clips (``idle_radius`` given: they stand
        on the track's first root position) become one idle stretch."""
        n = len(track)
        if from_frame + n - 1 - self.head[s] >= MAX_BUFFER - 1:
            # the ring keeps the previous frame (head - 1) too, for render interpolation
            n = int(MAX_BUFFER - 1 - (from_frame - self.head[s]))
            track = track.slice(0, n)
        idx = (from_frame + np.arange(n)) % MAX_BUFFER
        root = track.root
        if self.indexed[s]:
            # headings stay continuous across what is replaced (a plan may be wound 2 pi away)
            turns = np.round((self.buf_root[s, idx[0], 2] - root[0, 2]) / (2 * math.pi))
            if turns:
                root = root.copy()
                root[:, 2] += 2 * math.pi * turns
        append = from_frame == self.tail[s] and self.indexed[s]
        self.buf_a[s, idx] = track.frames_a
        self.buf_b[s, idx] = track.frames_b
        self.buf_t[s, idx] = track.frames_t
        self.buf_root[s, idx] = root
        self.buf_idle[s, idx] = idle_radius is not None
        self.tail[s] = from_frame + n - 1
        self.boundaries[s] = [(f, cfg) for f, cfg in self.boundaries[s] if self.head[s] <= f < from_frame]
        if not append:
            self.stretches.cut(s, from_frame)
        if idle_radius is not None:
            self.stretches.add(s, from_frame, self.tail[s], float(root[0, 0]), float(root[0, 1]), idle_radius)
            if append:
                self.indexed[s] = True
                return
        elif append:
            self.indexed[s] = True
            frames = np.arange(from_frame + 1, self.tail[s] + 1)   # the shared first frame is indexed
            self.index_frames(s, frames)
            return
        # the space-time index holds every character's buffered planned motion
        self.index.remove_owner(s)
        frames = np.arange(max(int(self.head[s]), 0), self.tail[s] + 1)
        self.index_frames(s, frames[~self.buf_idle[s, frames % MAX_BUFFER]])
        self.indexed[s] = True

    def index_frames(self, s: int, frames) -> None:
        if len(frames) == 0:
            return
        k = frames % MAX_BUFFER
        xz, rad = blend_cylinders(self.graph, self.buf_a[s, k], self.buf_b[s, k], self.buf_root[s, k])
        self.index.insert(s, frames, xz, rad)

    def config_at_tail(self, s: int) -> Config:
        r = self.buf_root[s, self.tail[s] % MAX_BUFFER]
        return Config(int(self.tail_node[s]), float(r[0]), float(r[1]), float(r[2]), int(self.tail[s]))

    def append_idle(self, s: int, stay_radius: np.ndarray, seconds: float = 3.0) -> None:
        """Append whole idle loops (the node's self-loop clip, drift removed) after the tail;
        each loop ends exactly on the node, so each loop end is a boundary. ``stay_radius``:
        per node, the radius of the idle stretch (:meth:`stay_radii`)."""
        cfg = self.config_at_tail(s)
        loop = self.loop_len(cfg.node)
        want = max(1, int(round(seconds * self.fps)))
        n = (int(math.ceil(want / loop)) * loop if loop else want) + 1
        self.write(s, self.idle(cfg, n), cfg.frame, idle_radius=stay_radius[cfg.node])
        step = loop if loop else n - 1
        for k in range(step, n, step):
            self.boundaries[s].append((cfg.frame + k, Config(cfg.node, cfg.x, cfg.z, cfg.heading, cfg.frame + k)))

    def idle(self, cfg: Config, n: int) -> Track:
        """:func:`~runtime.crowd.idle.idle_track` at ``cfg``: the track at the origin is cached
        per (node, length) and placed by one composition (the same arithmetic)."""
        key = (cfg.node, n)
        base = self._idle_cache.get(key)
        if base is None:
            base = idle_track(self.lib, Config(cfg.node, 0.0, 0.0, 0.0, 0), n)
            self._idle_cache[key] = base
        root = compose(np.array([cfg.x, cfg.z, cfg.heading])[None], base.root)
        return Track(base.frames_a, base.frames_b, base.frames_t, root, cfg.frame)

    def loop_len(self, node) -> int:
        """Frame steps of the node's idle loop (0 without one)."""
        node = int(node)
        if node not in self._loop_cache:
            e = idle_loop(self.graph, node)
            self._loop_cache[node] = 0 if e < 0 else int(self.graph.edge_frames[e] - 1)
        return self._loop_cache[node]

    def stay_radii(self, margin: float) -> np.ndarray:
        """Per node: the largest reach while idling on it (the circle about the root holding the
        bounding cylinder, over its idle loop's frames, or the node's pose when it has none),
        plus how far the idle loop's root strays from the
        node's spot, plus ``margin``."""
        g = self.graph
        r = np.zeros(g.num_nodes)
        for n in range(g.num_nodes):
            tr = self.idle(Config(n, 0.0, 0.0, 0.0, 0), max(self.loop_len(n), 1) + 1)
            r[n] = (max(g.frame_reach[tr.frames_a].max(), g.frame_reach[tr.frames_b].max())
                    + np.hypot(tr.root[:, 0], tr.root[:, 1]).max())
        return r + margin

    # -- reading -------------------------------------------------------------------------------------
    def gather(self, frame_offset: int):
        """(slots, frames a, frames b, blend, root) of every active slot at ``head +
        frame_offset`` (clamped to what is buffered)."""
        s = np.flatnonzero(self.active)
        k = np.clip(self.head[s] + frame_offset, self.head[s] - 1, self.tail[s]) % MAX_BUFFER
        return s, self.buf_a[s, k], self.buf_b[s, k], self.buf_t[s, k], self.buf_root[s, k]

    def root_at(self, s: int, frame: int) -> np.ndarray:
        """(x, z, heading) of slot ``s`` at absolute ``frame`` (must be buffered)."""
        return self.buf_root[s, frame % MAX_BUFFER]
