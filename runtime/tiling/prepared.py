"""A patch library prepared for tiling: every patch's factorised deformer (:mod:`.deform`) and
the flat port and box tables the tiler, the interactive tiling and their collision queries
read, built once per library."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..motion.planar import rotate_xz_scalar
from .deform import PatchDeformer
from .patch import PatchLibrary

__all__ = ["PreparedPatch", "PreparedLibrary", "RestTables", "align_on_port"]


def align_on_port(port_xz, port_dir: float, port_time: float, row) -> tuple:
    """The rigid placement ``(x, z, heading, t)`` of a patch that puts one of its ports (patch
    frame ``port_xz``, ``port_dir``, ``port_time``) exactly on a dangling port.

    Args:
        port_xz: (2,) the port's position in the patch frame.
        port_dir: its heading in the patch frame (rad).
        port_time: its time in the patch (s).
        row: the dangling port's table row (x, z, heading, time, ...).
    """
    th = float(row[2] - port_dir)
    pos = row[:2] - rotate_xz_scalar(port_xz, th)
    return (float(pos[0]), float(pos[1]), th, float(row[3] - port_time))


class RestTables(NamedTuple):
    """Every prepared patch's rest frames, flat over the library (patch ``p`` owns rows
    ``start[p]:start[p + 1]``): root ``xz`` (T, 2), ``heading`` (T,), dilated boxes ``box``
    (T, 6), and ``t0`` (P,) the patch time of each patch's first frame."""
    xz: np.ndarray
    heading: np.ndarray
    box: np.ndarray
    start: np.ndarray
    t0: np.ndarray


class PreparedPatch:
    """A library patch with its factorised deformer and flat tables for the tiler."""

    def __init__(self, patch, index: int):
        self.patch = patch
        self.index = index
        d = PatchDeformer(patch)
        self.deformer = d
        self.N = d.N
        self.K = d.K
        self.frag_start = d.frag_start
        # per-frame boxes dilated over the neighbouring frames of the same fragment: samples
        # between frames (clock resampling, time deformation) stay inside
        bx = []
        for b in patch.boxes:
            b = b.astype(np.float64)
            lo = np.minimum(np.minimum(b[:, :3], np.roll(b[:, :3], 1, 0)), np.roll(b[:, :3], -1, 0))
            hi = np.maximum(np.maximum(b[:, 3:], np.roll(b[:, 3:], 1, 0)), np.roll(b[:, 3:], -1, 0))
            lo[0], lo[-1] = np.minimum(b[0, :3], b[1, :3]), np.minimum(b[-1, :3], b[-2, :3])
            hi[0], hi[-1] = np.maximum(b[0, 3:], b[1, 3:]), np.maximum(b[-1, 3:], b[-2, 3:])
            bx.append(np.concatenate([lo, hi], 1))
        self.box = np.concatenate(bx)
        self.port_frame = d.port_frame
        self.port_nb = d.port_nb
        self.port_xz = d.xz[d.port_frame]
        self.port_dir = d.heading[d.port_frame]
        self.port_time = d.time[d.port_frame]
        self.port_kind = np.tile([0, 1], self.K)
        self.port_class = np.array([[f.entry_class, f.exit_class] for f in patch.fragments]).reshape(-1)
        self.port_open = np.array([[f.entry_open, f.exit_open] for f in patch.fragments]).reshape(-1)
        hd = np.hypot(np.maximum(-self.box[:, 0], self.box[:, 3]), np.maximum(-self.box[:, 2], self.box[:, 5]))
        self.radius = float(np.max(np.hypot(d.xz[:, 0], d.xz[:, 1]) + hd))
        self.size = patch.num_characters * max(patch.duration, 1.0 / patch.fps)
        self.half_diag = float(np.max(np.hypot(0.5 * (self.box[:, 3] - self.box[:, 0]), 0.5 * (self.box[:, 5] - self.box[:, 2]))))
        self.t_start = float(d.time.min())
        self.t_end = float(d.time.max())

    def align(self, j: int, row) -> tuple:
        """The rigid placement that puts port ``j`` exactly on the dangling ``row``
        (:func:`align_on_port`)."""
        return align_on_port(self.port_xz[j], self.port_dir[j], self.port_time[j], row)


class PreparedLibrary:
    """Prepared patches of a :class:`~runtime.tiling.patch.PatchLibrary`, and its open ports
    by (kind, pose class): ``by_port[(kind, cls)]`` is an (n, 2) array of (patch, port)."""

    def __init__(self, library: PatchLibrary):
        self.library = library
        self.patches = [PreparedPatch(p, i) for i, p in enumerate(library.patches)]
        self.by_port: dict = {}
        for pp in self.patches:
            for j in range(2 * pp.K):
                if pp.port_open[j]:
                    self.by_port.setdefault((int(pp.port_kind[j]), int(pp.port_class[j])), []).append((pp.index, j))
        self.by_port = {k: np.array(v, np.int64) for k, v in self.by_port.items()}
        self._rest: RestTables | None = None

    def __len__(self):
        return len(self.patches)

    @property
    def rest(self) -> RestTables:
        """The flat rest tables of all patches (:class:`RestTables`), built on first use."""
        if self._rest is None:
            self._rest = RestTables(np.concatenate([pp.deformer.xz for pp in self.patches]),
                                    np.concatenate([pp.deformer.heading for pp in self.patches]),
                                    np.concatenate([pp.box for pp in self.patches]),
                                    np.concatenate([[0], np.cumsum([pp.N for pp in self.patches])]).astype(np.int64),
                                    np.array([pp.deformer.time[0] for pp in self.patches]))
        return self._rest
