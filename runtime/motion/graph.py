"""MotionGraph: the runtime form of a snap-together motion graph (Sung, Kovar and Gleicher 2005, Figure 1).

Nodes are hub poses shared by the end of every incoming clip and the start of every
outgoing clip; edges are clips. All edge frames live in flat arrays (structure of arrays)
indexed through ``edge_start``, so synthesis gathers frames of many edges in one numpy call.

Per-edge tables the synthesis needs are precomputed:
``edge_duration`` (s), ``edge_disp`` (dx, dz, dheading: the planar rigid transform the edge
applies, in its start frame), the per-frame root path (``frame_xz``, ``frame_heading``
relative to the edge start), per-frame minimum bounding cylinder (``frame_axis``: its axis from
the root in the root's heading frame, ``frame_radius``, ``frame_reach`` about the root,
``frame_top``; :mod:`runtime.motion.cylinders`), per-frame foot contacts (``frame_contacts``
(T, 4) bool, columns :data:`~runtime.motion.contacts.CONTACT_POINTS`), and labels.

Pack: kind ``"motion_graph"``, version :data:`PACK_VERSION` (version 2 added the contacts,
version 3 the cylinders' axes; an older pack is refused with a message saying to rebuild it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..assets import AssetError, pack_fields, save_pack
from .clip import Clip
from .contacts import contact_summary, contacts_of
from .cylinders import pose_cylinders
from .skeleton import Skeleton, load_motion_pack

__all__ = ["MotionGraph", "PACK_KIND", "PACK_VERSION", "STATES"]

PACK_KIND = "motion_graph"
PACK_VERSION = 3
STATES = ("walking", "carrying", "sitting")
TRANSITION = -1  # edge_state of edges that change state


@dataclass
class MotionGraph:
    skeleton: Skeleton
    fps: float
    node_rotations: np.ndarray      # (N, J, 4) float32 hub poses (root entry heading-free)
    node_height: np.ndarray         # (N,)
    node_state: np.ndarray          # (N,) int index into STATES
    node_labels: list               # N lists of str
    edge_src: np.ndarray            # (E,) int
    edge_dst: np.ndarray            # (E,) int
    edge_state: np.ndarray          # (E,) int, -1 = transition between states
    edge_labels: list               # E lists of str
    edge_start: np.ndarray          # (E+1,) offsets into the frame arrays
    frame_rotations: np.ndarray     # (T, J, 4) float32
    frame_xz: np.ndarray            # (T, 2) root path relative to the edge start
    frame_heading: np.ndarray       # (T,)
    frame_height: np.ndarray        # (T,)
    frame_radius: np.ndarray        # (T,) float32
    frame_top: np.ndarray           # (T,) float32
    frame_contacts: np.ndarray | None = None   # (T, 4) bool, CONTACT_POINTS order
    frame_axis: np.ndarray | None = None       # (T, 2) float32 cylinder axis from the root (root frame)
    frame_reach: np.ndarray | None = None      # (T,) float32 radius about the root's axis
    meta: dict = field(default_factory=dict)
    path: str | None = None

    def __post_init__(self):
        if self.frame_contacts is None:
            self.frame_contacts = np.zeros((len(self.frame_heading), 4), dtype=bool)
        self.frame_contacts = np.asarray(self.frame_contacts, dtype=bool)
        if self.frame_axis is None:
            self.frame_axis = np.zeros((len(self.frame_heading), 2), dtype=np.float32)
        # the cylinders' axes in the edge-start frame, as frame_xz: where a placed clip's
        # collision samples stand
        ax = self.frame_axis.astype(np.float64)
        ch, sh = np.cos(self.frame_heading), np.sin(self.frame_heading)
        self.frame_cxz = np.stack([self.frame_xz[:, 0] + ch * ax[:, 0] + sh * ax[:, 1],
                                   self.frame_xz[:, 1] - sh * ax[:, 0] + ch * ax[:, 1]], axis=1)
        self.edge_frames = np.diff(self.edge_start)
        self.edge_duration = (self.edge_frames - 1) / self.fps
        last = self.edge_start[1:] - 1
        self.edge_disp = np.stack([self.frame_xz[last, 0], self.frame_xz[last, 1], self.frame_heading[last]], axis=1)
        self.edge_radius = np.maximum.reduceat(self.frame_radius, self.edge_start[:-1]) if len(self.edge_src) else np.zeros(0)
        if self.frame_reach is None:     # the circle about the root holding the cylinder
            self.frame_reach = (np.hypot(ax[:, 0], ax[:, 1]) + self.frame_radius).astype(np.float32)
        self.edge_reach = np.maximum.reduceat(self.frame_reach, self.edge_start[:-1]) if len(self.edge_src) else np.zeros(0)
        # parallel edges: same (src, dst)
        key = self.edge_src * max(1, self.num_nodes) + self.edge_dst
        _, self.edge_pair, counts = np.unique(key, return_inverse=True, return_counts=True)
        self.pair_count = counts
        order = np.argsort(self.edge_src, kind="stable")
        self._out_order = order
        self._out_ptr = np.searchsorted(self.edge_src[order], np.arange(self.num_nodes + 1))

    # -- sizes -----------------------------------------------------------------------------
    @property
    def num_nodes(self) -> int:
        """Hub poses: where clips meet."""
        return len(self.node_height)

    @property
    def num_edges(self) -> int:
        """Clips between hubs."""
        return len(self.edge_src)

    @property
    def total_seconds(self) -> float:
        """Seconds of motion in all clips."""
        return float(self.edge_duration.sum())

    # -- queries ------------------------------------------------------------------------------
    def out_edges(self, node: int) -> np.ndarray:
        return self._out_order[self._out_ptr[node]:self._out_ptr[node + 1]]

    def random_walk(self, node: int, length: int, rng: np.random.Generator) -> list[int]:
        """``length`` edges from ``node``, each drawn uniformly among the out-edges of the node
        reached (test and benchmark data for the synthesis search)."""
        edges = []
        for _ in range(int(length)):
            out = self.out_edges(node)
            e = int(out[rng.integers(len(out))])
            edges.append(e)
            node = int(self.edge_dst[e])
        return edges

    def in_edges(self, node: int) -> np.ndarray:
        return np.flatnonzero(self.edge_dst == node)

    def parallel_edges(self, edge: int) -> np.ndarray:
        """Edges between the same two nodes as ``edge`` (itself included)."""
        return np.flatnonzero(self.edge_pair == self.edge_pair[edge])

    def nodes_with_label(self, label: str) -> np.ndarray:
        return np.array([i for i, labs in enumerate(self.node_labels) if label in labs], dtype=np.int64)

    def node_labels_all(self) -> list[str]:
        return sorted({lab for labs in self.node_labels for lab in labs})

    def state_index(self, state: str) -> int:
        return STATES.index(state)

    def edges_in_state(self, state: int | str) -> np.ndarray:
        s = self.state_index(state) if isinstance(state, str) else state
        return np.flatnonzero(self.edge_state == s)

    def edge_clip(self, e: int) -> Clip:
        a, b = self.edge_start[e], self.edge_start[e + 1]
        return Clip(self.skeleton, self.fps, self.frame_xz[a:b], self.frame_heading[a:b],
                    self.frame_height[a:b], self.frame_rotations[a:b], contacts=self.frame_contacts[a:b])

    def node_pose_clip(self, n: int) -> Clip:
        """A one-frame clip of a hub pose (for previews and tests)."""
        return Clip(self.skeleton, self.fps, np.zeros((1, 2)), np.zeros(1), self.node_height[n:n + 1],
                    self.node_rotations[n:n + 1])

    # -- construction --------------------------------------------------------------------------
    @classmethod
    def from_clips(cls, skeleton, fps, node_rotations, node_height, node_state, node_labels,
                   edge_src, edge_dst, edge_state, edge_labels, clips, meta=None, cylinders=None) -> "MotionGraph":
        """``cylinders``: per clip its frames' collision cylinders (axis (F, 2), radius (F,), reach
        (F,), top (F,)) when not the clips' own minimum bounding cylinders
        (:func:`~runtime.motion.cylinders.pose_cylinders`), e.g. a build that corrects feet after
        snapping keeps both bodies inside."""
        starts = np.concatenate([[0], np.cumsum([c.num_frames for c in clips])]).astype(np.int64)
        if cylinders is None:
            cylinders = [pose_cylinders(c) for c in clips]
        top = [c[3] for c in cylinders]
        axis = [np.asarray(c[0], dtype=np.float64).reshape(-1, 2) for c in cylinders]
        # stored as float32: pad the radii so rounding never leaves a point outside
        radius = [np.asarray(c[1], dtype=np.float64) + 1e-5 for c in cylinders]
        reach = [np.asarray(c[2], dtype=np.float64) + 1e-5 for c in cylinders]
        contacts = [contacts_of(c) for c in clips]
        return cls(
            skeleton=skeleton, fps=float(fps),
            node_rotations=np.asarray(node_rotations, dtype=np.float32),
            node_height=np.asarray(node_height, dtype=np.float64),
            node_state=np.asarray(node_state, dtype=np.int64), node_labels=[list(x) for x in node_labels],
            edge_src=np.asarray(edge_src, dtype=np.int64), edge_dst=np.asarray(edge_dst, dtype=np.int64),
            edge_state=np.asarray(edge_state, dtype=np.int64), edge_labels=[list(x) for x in edge_labels],
            edge_start=starts,
            frame_rotations=np.concatenate([c.rotations for c in clips]).astype(np.float32),
            frame_xz=np.concatenate([c.root_xz for c in clips]),
            frame_heading=np.concatenate([c.root_heading for c in clips]),
            frame_height=np.concatenate([c.root_height for c in clips]),
            frame_radius=np.concatenate(radius).astype(np.float32),
            frame_top=np.concatenate(top).astype(np.float32),
            frame_contacts=np.concatenate(contacts).astype(bool),
            frame_axis=(np.concatenate(axis) if axis else np.zeros((0, 2))).astype(np.float32),
            frame_reach=np.concatenate(reach).astype(np.float32),
            meta=dict(meta or {}))

    # -- packs ----------------------------------------------------------------------------------
    _ARRAYS = ("node_rotations", "node_height", "node_state", "edge_src", "edge_dst", "edge_state",
               "edge_start", "frame_rotations", "frame_xz", "frame_heading", "frame_height",
               "frame_radius", "frame_top", "frame_contacts", "frame_axis", "frame_reach")

    def save(self, path) -> None:
        meta = dict(self.meta)
        meta.update({"skeleton": self.skeleton.to_dict(), "fps": self.fps, "node_labels": self.node_labels,
                     "edge_labels": self.edge_labels, "states": list(STATES)})
        save_pack(path, PACK_KIND, PACK_VERSION, meta, {k: getattr(self, k) for k in self._ARRAYS})

    @classmethod
    def load(cls, path) -> "MotionGraph":
        pk, meta, sk, fps = load_motion_pack(path, PACK_KIND, PACK_VERSION, "motion graph pack is inconsistent")
        with pack_fields(path, "motion graph pack is inconsistent"):
            node_labels = meta.pop("node_labels")
            edge_labels = meta.pop("edge_labels")
            meta.pop("states", None)
            g = cls(skeleton=sk, fps=fps, node_labels=node_labels, edge_labels=edge_labels, meta=meta,
                    path=str(path), **{k: pk.arrays[k] for k in cls._ARRAYS})
        g.validate(path)
        return g

    def validate(self, path="<graph>") -> None:
        """Structural checks (index ranges, array lengths) so a bad pack fails at load time."""
        E, N, T = self.num_edges, self.num_nodes, len(self.frame_heading)
        J = self.skeleton.num_joints
        problems = []
        if self.node_rotations.shape != (N, J, 4):
            problems.append(f"node_rotations shape {self.node_rotations.shape}")
        if E and (self.edge_src.min() < 0 or self.edge_src.max() >= N or self.edge_dst.min() < 0 or self.edge_dst.max() >= N):
            problems.append("edge endpoints out of range")
        if len(self.edge_start) != E + 1 or self.edge_start[0] != 0 or self.edge_start[-1] != T or np.any(np.diff(self.edge_start) < 2):
            problems.append("edge_start offsets invalid")
        if self.frame_rotations.shape != (T, J, 4) or len(self.frame_xz) != T:
            problems.append("frame arrays have inconsistent lengths")
        if self.frame_axis.shape != (T, 2) or len(self.frame_radius) != T or len(self.frame_reach) != T:
            problems.append(f"cylinder arrays: frame_axis {self.frame_axis.shape}, frame_radius "
                            f"{len(self.frame_radius)}, frame_reach {len(self.frame_reach)} for {T} frames")
        if self.frame_contacts.shape != (T, 4):
            problems.append(f"frame_contacts shape {self.frame_contacts.shape}")
        if len(self.node_labels) != N or len(self.edge_labels) != E:
            problems.append("label lists have the wrong length")
        if problems:
            raise AssetError(path, "motion graph pack is inconsistent: " + "; ".join(problems))

    # -- summary ----------------------------------------------------------------------------------
    def summary(self) -> dict:
        from collections import Counter
        pairs = self.pair_count
        lab = Counter(l for labs in self.edge_labels for l in labs)
        per_state = {}
        for s, name in enumerate(STATES):
            m = self.edge_state == s
            per_state[name] = {"nodes": int((self.node_state == s).sum()), "edges": int(m.sum()),
                               "seconds": round(float(self.edge_duration[m].sum()), 2)}
        per_state["transition"] = {"edges": int((self.edge_state == TRANSITION).sum())}
        heading_ranges = []
        for p in np.unique(self.edge_pair):
            es = np.flatnonzero(self.edge_pair == p)
            if len(es) > 1:
                h = np.degrees(self.edge_disp[es, 2])
                heading_ranges.append((int(self.edge_src[es[0]]), int(self.edge_dst[es[0]]), len(es),
                                       round(float(h.min()), 1), round(float(h.max()), 1)))
        heading_ranges.sort(key=lambda r: -(r[4] - r[3]))
        return {
            "nodes": self.num_nodes, "edges": self.num_edges, "seconds": round(self.total_seconds, 2),
            "fps": self.fps, "family": self.skeleton.family,
            "node_labels": {lab: int(len(self.nodes_with_label(lab))) for lab in self.node_labels_all()},
            "edge_label_counts": dict(sorted(lab.items())),
            "states": per_state,
            "parallel": {"pairs": int(len(pairs)), "pairs_with_parallel": int((pairs > 1).sum()),
                         "median_parallel": float(np.median(pairs)) if len(pairs) else 0.0,
                         "max_parallel": int(pairs.max()) if len(pairs) else 0},
            "heading_change_per_pair": heading_ranges[:10],
            "pruned_edges": self.meta.get("pruned_edges"), "pruned_nodes": self.meta.get("pruned_nodes"),
            "contacts": contact_summary(self.frame_contacts, "pack"),
            "foot_slide": self._foot_slide_summary(),
        }

    def _foot_slide_summary(self):
        """The build's foot-slide figures (``meta["foot_slide"]``): over all edges, the edges with
        the most, and the edges dropped for it; None for a library built without them."""
        fs = self.meta.get("foot_slide")
        if not isinstance(fs, dict):
            return None
        per_edge = np.asarray(fs.get("edge_max_cm_s", []), dtype=float)
        worst = np.argsort(-per_edge, kind="stable")[:5]
        return {k: fs.get(k) for k in ("mean_cm_s", "p95_cm_s", "sliding", "limit_cm_s")} | {
            "dropped_edges": len(fs.get("dropped", [])),
            "worst_edges": [(int(e), float(per_edge[e])) for e in worst]}
