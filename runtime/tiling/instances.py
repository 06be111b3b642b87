"""The records of a tiling under construction: a candidate placement of a patch, a committed
patch instance, and the table of open (unstitched) ports.

Ports of a patch are numbered ``2k`` (entry of fragment ``k``) and ``2k + 1`` (its exit); a
dangling port is keyed by ``(instance id, port)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Candidate", "Instance", "DanglingTable"]


@dataclass
class Candidate:
    """A patch placed and deformed but not committed: patch ``p``, rigid ``place`` (x, z,
    heading, t), the stitches ``conns`` [(port, dangling key)], the deformed world arrays, the
    handle offsets ``r`` (patch frame; zero for held ports), whether the deformation is within
    the limits (``worst``: largest stretch, bend, shift) and the change in dangling and
    connected port counts. ``samples``: its clock samples once computed
    (:meth:`~runtime.tiling.occupancy.Occupancy.samples`)."""
    p: int
    place: tuple
    conns: list
    xz: np.ndarray                     # (N, 2)
    heading: np.ndarray
    time: np.ndarray
    r: np.ndarray
    limits_ok: bool
    worst: tuple
    d_danglings: int = 0               # N' - N
    d_connected: int = 0               # N_c' - N_c
    samples: tuple | None = None


@dataclass
class Instance:
    """A committed patch instance: ``links`` per port the (instance id, port) it is stitched
    to, or None; ``fixed`` for keyframes (never removed)."""
    id: int
    p: int
    place: tuple
    xz: np.ndarray
    heading: np.ndarray
    time: np.ndarray
    r: np.ndarray
    fixed: bool
    links: list
    samples: tuple | None = None       # frames, frag, sidx, xz, heading (for tracks)


class DanglingTable:
    """Open-port table (unstitched ports of all instances), arrays for vectorized matching.

    Row columns: x, z, heading, time, step x, step z (the Eq. 2 step to the neighbour frame),
    kind (0 entry, 1 exit), pose class, open, counts (1 if it counts as dangling).
    """
    COLS = 10

    def __init__(self):
        self.rows = np.zeros((256, self.COLS))
        self.live = np.zeros(256, bool)
        self.key = [None] * 256
        self.where: dict = {}
        self.n = 0
        self.free: list = []

    def add(self, key, vals):
        if self.free:
            i = self.free.pop()
        else:
            if self.n == len(self.live):
                self.rows = np.concatenate([self.rows, np.zeros_like(self.rows)])
                self.live = np.concatenate([self.live, np.zeros_like(self.live)])
                self.key += [None] * len(self.key)
            i = self.n
            self.n += 1
        self.rows[i] = vals
        self.live[i] = True
        self.key[i] = key
        self.where[key] = i

    def remove(self, key):
        i = self.where.pop(key)
        self.live[i] = False
        self.key[i] = None
        self.free.append(i)

    def row(self, key) -> np.ndarray:
        """The table row of dangling ``key`` (a view)."""
        return self.rows[self.where[key]]

    def counting_rows(self) -> np.ndarray:
        """Rows of the live ports that count as dangling."""
        return np.flatnonzero(self.live[:self.n] & (self.rows[:self.n, 9] > 0))

    def counting(self) -> int:
        return int(np.count_nonzero(self.live[:self.n] & (self.rows[:self.n, 9] > 0)))
