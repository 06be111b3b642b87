"""Data-driven group (DDG) graph: the asset a flock walks (Lai, Chenney and Fan 2005, sections
4.3 and 5).

Layout. A DDG is cut from one recording of a flock (positions at ``fps``, coordinates ``(x, z)``
in 2D or ``(x, y, z)`` in 3D, Y up). *Nodes* are recording frames where transitions leave or
arrive; *segments* are the stretches of recording between consecutive nodes; an *edge* plays
one segment after arriving at its source node:

- a continuation edge plays the segment that starts at its own source node (identity
  transform and correspondence);
- a transition edge ``f -> g`` (from a local minimum of the difference matrix) plays the segment
  that starts at node ``g`` after aligning it onto the configuration at ``f``: it stores the
  rigid transform ``X_{A<-B}`` (yaw about +Y, translation) that maps the segment's coordinates
  into the coordinates of the clip that ended at ``f``, and the correspondence
  ``M_{B<-A}`` (``perm[i]`` = the segment slot that the agent in slot ``i`` of the old clip
  continues as).

A transition is blended over the first ``blend`` frames of its segment with a per-agent cubic
Hermite offset (indexed by the *segment's* slot ``b``)::

    p_b(s) = B_b(s) + H00(s/K) d0_b + H10(s/K) K d1_b,   s = 0..K

with ``d0`` the position gap at the node (so ``p(0)`` equals the arriving configuration) and
``d1`` the per-frame velocity gap (so velocities continue too); ``H00 = 2u^3 - 3u^2 + 1``,
``H10 = u^3 - 2u^2 + u``. The builder checks every blended step against the recorder's largest
per-step displacement.

Packs: kind ``"ddg"``, version 1 (``save_ddg`` / ``load_ddg``). Loading validates every index,
shape and permutation and raises :class:`runtime.assets.AssetError` naming the file and field.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..assets import AssetError, load_pack, pack_fields, save_pack
from .coords import to_xyz, yaw_rotate
from .metric import configuration_heading

__all__ = ["DDG", "save_ddg", "load_ddg", "hermite_weights", "PACK_KIND", "PACK_VERSION"]

PACK_KIND = "ddg"
PACK_VERSION = 1

_ARRAYS = ("frames", "seg_start", "seg_len", "seg_frame", "node_frame", "edge_src", "edge_dst",
           "edge_seg", "edge_yaw", "edge_trans", "edge_perm", "edge_blend", "edge_d0", "edge_d1",
           "edge_cost")


def hermite_weights(s, K):
    """``(H00(s/K), K * H10(s/K))`` for frame ``s`` of a ``K``-frame blend; zero once ``s >= K``."""
    s = np.asarray(s, dtype=np.float64)
    K = np.asarray(K, dtype=np.float64)
    u = np.clip(s / np.maximum(K, 1.0), 0.0, 1.0)
    active = (s < K) & (K > 0)
    h00 = np.where(active, (2.0 * u - 3.0) * u * u + 1.0, 0.0)
    h10 = np.where(active, K * ((u - 2.0) * u + 1.0) * u, 0.0)
    return h00, h10


@dataclass(eq=False)
class DDG:
    """A flock motion graph. Arrays as described in the module docstring:

    ``frames`` (F, N, D) float32 segment frames, concatenated (segment ``s`` occupies
    ``frames[seg_start[s] : seg_start[s] + seg_len[s] + 1]``); ``seg_frame`` (S,) recording frame
    of each segment's first frame; ``node_frame`` (V,) recording frame of each node;
    ``edge_src/edge_dst/edge_seg`` (E,); ``edge_yaw`` (E,), ``edge_trans`` (E, D): ``X_{A<-B}``;
    ``edge_perm`` (E, N): ``M_{B<-A}``; ``edge_blend`` (E,) frames; ``edge_d0/edge_d1`` (E, N, D)
    blend offsets in segment coordinates, per segment slot; ``edge_cost`` (E,) the metric E
    (m^2) of the transition, 0 for continuations. ``max_step`` is the recorder's largest
    per-step displacement (metres).
    """

    dim: int
    fps: float
    max_step: float
    frames: np.ndarray
    seg_start: np.ndarray
    seg_len: np.ndarray
    seg_frame: np.ndarray
    node_frame: np.ndarray
    edge_src: np.ndarray
    edge_dst: np.ndarray
    edge_seg: np.ndarray
    edge_yaw: np.ndarray
    edge_trans: np.ndarray
    edge_perm: np.ndarray
    edge_blend: np.ndarray
    edge_d0: np.ndarray
    edge_d1: np.ndarray
    edge_cost: np.ndarray
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.frames = np.ascontiguousarray(self.frames, dtype=np.float32)
        for name in ("seg_start", "seg_len", "seg_frame", "node_frame"):
            setattr(self, name, np.ascontiguousarray(getattr(self, name), dtype=np.int64))
        for name in ("edge_src", "edge_dst", "edge_seg", "edge_blend"):
            setattr(self, name, np.ascontiguousarray(getattr(self, name), dtype=np.int32))
        self.edge_perm = np.ascontiguousarray(self.edge_perm, dtype=np.int32)
        self.edge_yaw = np.ascontiguousarray(self.edge_yaw, dtype=np.float64)
        self.edge_trans = np.ascontiguousarray(self.edge_trans, dtype=np.float64)
        self.edge_cost = np.ascontiguousarray(self.edge_cost, dtype=np.float64)
        self.edge_d0 = np.ascontiguousarray(self.edge_d0, dtype=np.float32)
        self.edge_d1 = np.ascontiguousarray(self.edge_d1, dtype=np.float32)
        self.dim = int(self.dim)
        self.fps = float(self.fps)
        self.max_step = float(self.max_step)
        self._derived = None

    # ---------------------------------------------------------------- validation
    def validate(self) -> None:
        """Raise ``ValueError("field: problem")`` if the graph is inconsistent."""
        def bad(name, why):
            raise ValueError(f"{name}: {why}")

        if self.dim not in (2, 3):
            bad("dim", f"must be 2 or 3, got {self.dim}")
        if not (self.fps > 0 and np.isfinite(self.fps)):
            bad("fps", f"must be positive, got {self.fps}")
        if not (self.max_step > 0 and np.isfinite(self.max_step)):
            bad("max_step", f"must be positive, got {self.max_step}")
        if self.frames.ndim != 3 or self.frames.shape[2] != self.dim or self.frames.shape[1] < 1:
            bad("frames", f"expected (frames, agents, {self.dim}), got {self.frames.shape}")
        if not np.all(np.isfinite(self.frames)):
            bad("frames", "holds non-finite values")
        F, N, D = self.frames.shape
        S, V, E = len(self.seg_start), len(self.node_frame), len(self.edge_src)
        if S == 0 or V == 0 or E == 0:
            bad("graph", f"is empty ({V} nodes, {S} segments, {E} edges)")
        for name, n in (("seg_len", S), ("seg_frame", S), ("edge_dst", E), ("edge_seg", E),
                        ("edge_yaw", E), ("edge_blend", E), ("edge_cost", E)):
            if getattr(self, name).shape != (n,):
                bad(name, f"expected shape ({n},), got {getattr(self, name).shape}")
        for name, shape in (("edge_trans", (E, D)), ("edge_perm", (E, N)), ("edge_d0", (E, N, D)),
                            ("edge_d1", (E, N, D))):
            if getattr(self, name).shape != shape:
                bad(name, f"expected shape {shape}, got {getattr(self, name).shape}")
        if np.any(self.seg_len < 1):
            bad("seg_len", "every segment needs at least one step")
        if np.any(self.seg_start < 0) or np.any(self.seg_start + self.seg_len >= F):
            bad("seg_start", f"segments run outside the {F} stored frames")
        for name, hi in (("edge_src", V), ("edge_dst", V), ("edge_seg", S)):
            a = getattr(self, name)
            if np.any(a < 0) or np.any(a >= hi):
                bad(name, f"index out of range [0, {hi})")
        if np.any(np.sort(self.edge_perm, axis=1) != np.arange(N)):
            bad("edge_perm", "a row is not a permutation of the agent slots")
        if np.any(self.edge_blend < 0) or np.any(self.edge_blend > self.seg_len[self.edge_seg]):
            bad("edge_blend", "blend longer than its segment")
        for name in ("edge_yaw", "edge_trans", "edge_d0", "edge_d1", "edge_cost"):
            if not np.all(np.isfinite(getattr(self, name))):
                bad(name, "holds non-finite values")
        out_deg = np.bincount(self.edge_src, minlength=V)
        if np.any(out_deg == 0):
            bad("edge_src", f"node {int(np.argmin(out_deg))} has no outgoing edge (dead end)")

    # ---------------------------------------------------------------- sizes
    n_agents = property(lambda self: self.frames.shape[1], doc="Agents in the recording.")
    n_nodes = property(lambda self: len(self.node_frame), doc="Nodes (recorded frames kept).")
    n_edges = property(lambda self: len(self.edge_src), doc="Edges between nodes.")

    @property
    def n_transitions(self) -> int:
        """Edges that jump in the recording (everything but plain continuations)."""
        return int(np.count_nonzero(self.is_transition()))

    @property
    def edge_len(self) -> np.ndarray:
        return self.seg_len[self.edge_seg]

    def is_transition(self) -> np.ndarray:
        """(E,) True for edges that jump in the recording (not plain continuations)."""
        return self.seg_frame[self.edge_seg] != self.node_frame[self.edge_src]

    @property
    def nbytes(self) -> int:
        return int(sum(getattr(self, n).nbytes for n in _ARRAYS))

    # ---------------------------------------------------------------- derived data
    def derived(self) -> dict:
        """Arrays the runtime needs, computed once: out-edge lists, node configurations,
        per-edge centroid tracks (in the source clip's coordinates, blends included)."""
        if self._derived is not None:
            return self._derived
        E, V = self.n_edges, self.n_nodes
        N, D = self.n_agents, self.dim
        order = np.argsort(self.edge_src, kind="stable")
        out_start = np.zeros(V + 1, dtype=np.int64)
        np.cumsum(np.bincount(self.edge_src, minlength=V), out=out_start[1:])
        elen = self.edge_len.astype(np.int64)
        # node configuration: last frame of an incoming edge's segment (+ the frame before it)
        inc = np.full(V, -1, dtype=np.int64)
        inc[self.edge_dst[::-1]] = np.arange(E)[::-1]
        node_pos = np.zeros((V, N, D))
        node_vel = np.zeros((V, N, D))
        has_in = inc >= 0
        e_in = inc[has_in]
        last = self.seg_start[self.edge_seg[e_in]] + elen[e_in]
        node_pos[has_in] = self.frames[last]
        node_vel[has_in] = (self.frames[last].astype(np.float64) - self.frames[last - 1]) * self.fps
        # nodes without an incoming edge (possible only in hand-made graphs): first frame of an out segment
        for v in np.nonzero(~has_in)[0]:
            e = order[out_start[v]]
            f0 = self.seg_start[self.edge_seg[e]]
            node_pos[v] = self.frames[f0]
            node_vel[v] = (self.frames[f0 + 1].astype(np.float64) - self.frames[f0]) * self.fps
        node_centroid = node_pos.mean(axis=1)
        node_heading = configuration_heading(node_vel)
        # per-edge centroid tracks s = 0..L, including the blend, mapped by X_e into source coords
        track_start = np.zeros(E + 1, dtype=np.int64)
        np.cumsum(elen + 1, out=track_start[1:])
        total = int(track_start[-1])
        e_of = np.repeat(np.arange(E), elen + 1)
        s_of = np.arange(total) - track_start[:-1][e_of]
        rows = self.seg_start[self.edge_seg[e_of]] + s_of
        cen = self.frames[rows].astype(np.float64).mean(axis=1)
        h00, h10 = hermite_weights(s_of, self.edge_blend[e_of])
        cen += h00[:, None] * self.edge_d0.mean(axis=1, dtype=np.float64)[e_of] \
            + h10[:, None] * self.edge_d1.mean(axis=1, dtype=np.float64)[e_of]
        tr = yaw_rotate(cen, self.edge_yaw[e_of])
        tr += self.edge_trans[e_of]
        self._derived = {
            "out_start": out_start, "out_edges": order.astype(np.int64),
            "edge_len": elen, "node_pos": node_pos, "node_vel": node_vel,
            "node_centroid": node_centroid, "node_heading": node_heading,
            "track_start": track_start, "track": to_xyz(tr), "edge_trans3": to_xyz(self.edge_trans),
        }
        return self._derived

    # ---------------------------------------------------------------- playback
    def edge_positions(self, e: int) -> np.ndarray:
        """Blended positions (L+1, N, D) of edge ``e`` in its segment's coordinates (float64)."""
        L = int(self.edge_len[e])
        f0 = int(self.seg_start[self.edge_seg[e]])
        p = self.frames[f0:f0 + L + 1].astype(np.float64)
        h00, h10 = hermite_weights(np.arange(L + 1), int(self.edge_blend[e]))
        return p + h00[:, None, None] * self.edge_d0[e].astype(np.float64) + h10[:, None, None] * self.edge_d1[e]

    # ---------------------------------------------------------------- packs
    def to_arrays(self) -> dict:
        return {n: getattr(self, n) for n in _ARRAYS}


def save_ddg(path, ddg: DDG) -> Path:
    """Write ``ddg`` as a pack of kind ``"ddg"`` (atomic)."""
    ddg.validate()
    meta = dict(ddg.meta)
    meta.update({"dim": ddg.dim, "fps": ddg.fps, "max_step": ddg.max_step, "n_agents": ddg.n_agents})
    return save_pack(path, PACK_KIND, PACK_VERSION, meta, ddg.to_arrays())


def load_ddg(path) -> DDG:
    """Load and validate a DDG pack; raises :class:`AssetError` naming the file and the field."""
    pack = load_pack(path, kind=PACK_KIND, version=PACK_VERSION)
    missing = [n for n in _ARRAYS if n not in pack.arrays]
    if missing:
        raise AssetError(path, f"DDG pack lacks arrays {missing}")
    meta = pack.meta
    for key in ("dim", "fps", "max_step"):
        if not isinstance(meta.get(key), (int, float)):
            raise AssetError(path, f"meta field {key!r} missing or not a number")
    with pack_fields(path, "invalid DDG"):
        g = DDG(dim=int(meta["dim"]), fps=float(meta["fps"]), max_step=float(meta["max_step"]),
                meta={k: v for k, v in meta.items() if k not in ("dim", "fps", "max_step", "n_agents")},
                **{n: pack.arrays[n] for n in _ARRAYS})
        g.validate()
    return g
