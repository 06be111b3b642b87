"""The reservation table of an offline crowd plan: the space-time index of planned characters'
bounding cylinders (:class:`~runtime.crowd.spacetime.SpaceTimeIndex`), plus, per character, its
cylinder on every frame as a dense array, so "who is where at frame f" is one slice -- what a
space-time route search (:mod:`runtime.crowd.planner.route`) reads step by step.

Limits: owners are small non-negative ints (character indices); frames are in ``[0, n_frames)``
(a cylinder beyond is kept in the index only).
"""
from __future__ import annotations

import numpy as np

from .spacetime import SpaceTimeIndex

__all__ = ["Reservations"]


class Reservations(SpaceTimeIndex):
    """A space-time index that also keeps every owner's cylinders densely by frame.

    Args:
        cell: the index's cell size (m).
        n_frames: the scenario's frames.
    """

    def __init__(self, cell: float, n_frames: int):
        super().__init__(cell=cell)
        self.n_frames = int(n_frames)
        self._xzr = np.full((0, self.n_frames, 3), np.nan, dtype=np.float32)

    def insert(self, owner: int, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray) -> None:
        super().insert(owner, frames, xz, radius)
        if owner >= len(self._xzr):
            grow = np.full((max(owner + 1, 2 * len(self._xzr)) - len(self._xzr), self.n_frames, 3), np.nan,
                           dtype=np.float32)
            self._xzr = np.concatenate([self._xzr, grow])
        frames = np.asarray(frames, dtype=np.int64)
        ok = (frames >= 0) & (frames < self.n_frames)
        f = frames[ok]
        self._xzr[owner, f, :2] = np.asarray(xz, dtype=np.float64)[ok]
        self._xzr[owner, f, 2] = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)[ok]

    def remove_owner(self, owner: int) -> None:
        super().remove_owner(owner)
        if owner < len(self._xzr):
            self._xzr[owner] = np.nan

    def at_frame(self, frame: int, ignore_owner: int | None = None):
        """(xz (M, 2), radius (M,)) of every stored cylinder at ``frame``."""
        if not (0 <= frame < self.n_frames) or len(self._xzr) == 0:
            return np.zeros((0, 2)), np.zeros(0)
        row = self._xzr[:, frame]
        ok = np.isfinite(row[:, 2])
        if ignore_owner is not None and ignore_owner < len(ok):
            ok[ignore_owner] = False
        return row[ok, :2].astype(np.float64), row[ok, 2].astype(np.float64)
