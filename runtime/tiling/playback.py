"""Playback of an interactive tiling: committed samples written into per-character ring
buffers indexed by clock frame, so the poses of all characters at a frame are array gathers
(no per-character Python per tick); with ``record`` every sample is also kept for
:meth:`Playback.tracks`."""
from __future__ import annotations

import numpy as np

from ..crowd.tracks import evaluate_poses
from .result import CharacterTrack, continue_heading

__all__ = ["Playback", "RING"]

RING = 2048   # frames of playback buffered per character (> horizon + longest fragment)


class Playback:
    """Ring buffers of every character: library frames ``a``/``b`` and blend ``w`` into the
    patch library's flat pose tables, and the root (x, z, heading; heading continuous).

    Args:
        prepared: the :class:`~runtime.tiling.prepared.PreparedLibrary`.
        record: keep every written sample (for :meth:`tracks`).
    """

    def __init__(self, prepared, record: bool):
        self.lib = prepared
        self.library = prepared.library
        self.record = record
        self.ring_q = np.full((0, RING), -1, np.int64)
        self.ring_ab = np.zeros((0, RING, 2), np.int64)
        self.ring_w = np.zeros((0, RING), np.float32)
        self.ring_root = np.zeros((0, RING, 3))
        self.last_h = np.zeros(0)
        self.hist: list = []
        self.seg: list = []                       # per character: (instance, fragment, frames, previous heading)

    def add_character(self) -> None:
        self.ring_q = np.concatenate([self.ring_q, np.full((1, RING), -1, np.int64)])
        self.ring_ab = np.concatenate([self.ring_ab, np.zeros((1, RING, 2), np.int64)])
        self.ring_w = np.concatenate([self.ring_w, np.zeros((1, RING), np.float32)])
        self.ring_root = np.concatenate([self.ring_root, np.zeros((1, RING, 3))])
        self.last_h = np.append(self.last_h, np.nan)
        self.hist.append([])
        self.seg.append([])

    def write(self, cid: int, iid: int, p: int, frag: int, samples) -> None:
        """Put fragment ``frag`` of instance ``iid`` (patch ``p``; its clock ``samples``) into
        character ``cid``'s ring."""
        fr, fg, s, xz, hd = samples[:5]
        m = fg == frag
        q, s, xz, hd = fr[m], s[m], xz[m], hd[m]
        if len(q) == 0:
            return
        pp = self.lib.patches[p]
        a0 = pp.frag_start[frag]
        off = self.library.fragment_offset(p, frag)
        i0 = np.floor(s).astype(np.int64)
        i1 = np.minimum(i0 + 1, pp.frag_start[frag + 1] - 1)
        w = (s - i0).astype(np.float32)
        prev_h = self.last_h[cid]
        if not np.isnan(prev_h):
            hd = continue_heading(hd, prev_h)
        self.last_h[cid] = hd[-1]
        self.seg[cid].append((iid, frag, q, prev_h))
        slot = q % RING
        self.ring_q[cid, slot] = q
        self.ring_ab[cid, slot, 0] = off + i0 - a0
        self.ring_ab[cid, slot, 1] = off + i1 - a0
        self.ring_w[cid, slot] = w
        self.ring_root[cid, slot, 0] = xz[:, 0]
        self.ring_root[cid, slot, 1] = xz[:, 1]
        self.ring_root[cid, slot, 2] = hd
        if self.record:
            self.hist[cid].append((q, off + i0 - a0, off + i1 - a0, w, np.column_stack([xz, hd]), iid, frag))

    def take_back(self, cid: int, iid: int) -> None:
        """Undo the last :meth:`write` of character ``cid`` (instance ``iid``, not played yet)."""
        _, _, q, prev_h = self.seg[cid].pop()
        slot = q % RING
        stale = self.ring_q[cid, slot] == q
        self.ring_q[cid, slot[stale]] = -1
        self.last_h[cid] = prev_h
        if self.record and self.hist[cid] and self.hist[cid][-1][5] == iid:
            self.hist[cid].pop()

    def _slot(self, frame):
        slot = frame % RING
        ok = self.ring_q[:, slot] == frame
        return slot, ok

    def root_states(self, frame: int) -> np.ndarray:
        """(C, 3) x, z, heading of every character at the clock frame (NaN if not buffered)."""
        slot, ok = self._slot(frame)
        out = self.ring_root[:, slot].copy()
        out[~ok] = np.nan
        return out

    def pose_refs(self, frame: int):
        """(frames_a (C,), frames_b (C,), blend (C,), root (C, 3)) into the library's flat pose
        tables (``library.frame_rotations`` / ``frame_height``)."""
        slot, _ = self._slot(frame)
        return self.ring_ab[:, slot, 0], self.ring_ab[:, slot, 1], self.ring_w[:, slot], self.ring_root[:, slot]

    def poses(self, frame: int):
        """Root positions (C, 3) and local rotations (C, J, 4) (entry 0 = root world rotation)."""
        a, b, w, root = self.pose_refs(frame)
        return evaluate_poses(self.library, a, b, w, root)

    def tracks(self) -> list[CharacterTrack]:
        """One track per character from its first frame to the last written one (``record``)."""
        if not self.record:
            raise RuntimeError("InteractiveTiling(record=False) keeps no history")
        out = []
        for h in self.hist:
            if not h:
                continue
            q = np.concatenate([x[0] for x in h])
            order = np.argsort(q, kind="stable")
            q = q[order]
            keep = np.r_[True, q[1:] != q[:-1]]
            sel = order[keep]
            fa = np.concatenate([x[1] for x in h])[sel]
            fb = np.concatenate([x[2] for x in h])[sel]
            w = np.concatenate([x[3] for x in h])[sel]
            root = np.concatenate([x[4] for x in h])[sel]
            segs = [(x[5], x[6], int(x[0][0])) for x in h]
            out.append(CharacterTrack(fa, fb, w.astype(np.float32), root, int(q[keep][0]), segments=segs))
        return out
