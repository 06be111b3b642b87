"""Playing DDG edges for many flocks at once: the frames as structure of arrays and the per-tick
evaluation of every agent's position and velocity.

The frames are one flat float32 array per coordinate (x, [y,] z), agent-major within a frame.
The blended opening frames ``s = 0..K`` of every transition edge (Lai, Chenney and Fan 2005,
section 4.3; :func:`runtime.flock.ddg.hermite_weights`) are appended once, so a tick only
gathers: edge ``e`` at frame ``s`` reads row ``blend_row0[e] + s`` while ``s < K``, else
``row0[e] + s``.
"""
from __future__ import annotations

import numpy as np

from .ddg import DDG

__all__ = ["FramePool"]


class FramePool:
    """The frames of a :class:`DDG` laid out for :meth:`evaluate`.

    Args:
        ddg: the graph (validated).
    """

    def __init__(self, ddg: DDG):
        self.n_agents = ddg.n_agents
        self.dim = ddg.dim
        self.fps = ddg.fps
        self._row0 = ddg.seg_start[ddg.edge_seg].astype(np.int64)
        self._elen = ddg.derived()["edge_len"].astype(np.int64)
        self._eblend = ddg.edge_blend.astype(np.int64)
        blended, brow0 = [], np.full(ddg.n_edges, -1, np.int64)
        nxt = ddg.frames.shape[0]
        for e in np.nonzero(ddg.edge_blend > 0)[0]:
            K = int(ddg.edge_blend[e])
            blended.append(ddg.edge_positions(int(e))[:K + 1].astype(np.float32))
            brow0[e] = nxt
            nxt += K + 1
        pool = np.concatenate([ddg.frames] + blended) if blended else ddg.frames
        self._fcomp = [np.ascontiguousarray(pool[..., k].reshape(-1)) for k in range(ddg.dim)]
        self._brow0 = brow0
        self.nbytes = int(sum(a.nbytes for a in self._fcomp))

    def evaluate(self, edge, phase, perm, yaw, trans):
        """Positions and velocities (flocks, agents, 3) float32 of every agent of every flock, in
        one pass: gather the two frames around each flock's phase through its correspondence
        (blended frames while a transition blends), interpolate, place in the world.

        Args:
            edge: (flocks,) the edge each flock plays.
            phase: (flocks,) frames played of it (fractional, below the edge's length).
            perm: (flocks, agents) the clip slot each agent plays.
            yaw: (flocks,) the clip's yaw about +Y in the world.
            trans: (flocks, 3) the clip's translation in the world (after the yaw).

        The placement rotates float32 frames by float32 cosines of float64 yaws (not
        :func:`runtime.motion.planar.rotate_xz`, which would compute in float64).
        """
        N = self.n_agents
        e = edge
        k0 = np.minimum(np.floor(phase).astype(np.int64), self._elen[e] - 1)
        frac = phase - k0
        row = np.where(k0 < self._eblend[e], self._brow0[e], self._row0[e]) + k0
        idx = (row * N)[:, None] + perm
        idx1 = idx + N
        comps0 = [np.take(fc, idx) for fc in self._fcomp]
        deltas = [np.take(fc, idx1) for fc in self._fcomp]
        for c0, d in zip(comps0, deltas):
            np.subtract(d, c0, out=d)
        if np.any(frac):
            u = frac.astype(np.float32)[:, None]
            pts = [c0 + u * d for c0, d in zip(comps0, deltas)]
        else:
            pts = comps0
        c = np.cos(yaw).astype(np.float32)[:, None]
        s = np.sin(yaw).astype(np.float32)[:, None]
        t = trans.astype(np.float32)
        fps = np.float32(self.fps)
        x, z = pts[0], pts[-1]
        vx, vz = deltas[0], deltas[-1]
        X = c * x
        X += s * z
        X += t[:, 0:1]
        Z = c * z
        Z -= s * x
        Z += t[:, 2:3]
        cf, sf = c * fps, s * fps
        VX = cf * vx
        VX += sf * vz
        VZ = cf * vz
        VZ -= sf * vx
        if self.dim == 3:
            Y = pts[1] + t[:, 1:2]
            VY = deltas[1] * fps
        else:
            Y = np.broadcast_to(t[:, 1:2], X.shape)
            VY = np.zeros_like(X)
        return np.stack([X, Y, Z], axis=-1), np.stack([VX, VY, VZ], axis=-1)
