"""Collision tests of the segment planner: bounding cylinders against the static environment
(a signed distance field) and against characters planned earlier (moving obstacles in a
space-time index), Sung, Kovar and Gleicher 2005, sections 3.1-3.3.

The planner does not own the obstacles: it is given callables.

* ``static(xz) -> distance``: signed distance to the nearest obstacle (may be None).
* ``collide(frames, xz, radius) -> bool array``: which samples hit a planned character.
* ``collide_first(frames, xz, radius) -> int``: the first sample that hits, or -1 (the final
  tests need no more; a space-time index can stop there). Derived from ``collide`` if not given.
* ``collide_runs(frames, xz, radius, counts) -> bool array``: per run of ``counts`` consecutive
  samples, whether any hits (the seeds test many candidate clips at once). Derived from
  ``collide`` if not given.
"""
from __future__ import annotations

import numpy as np

from ...motion.cylinders import blend_cylinders
from ...motion.planar import compose
from . import kernels
from .library import MotionLibrary
from .params import SearchParams
from .types import SegmentResult

__all__ = ["Collider"]


class Collider:
    """The planner's view of what it must not run into.

    Args:
        lib: the motion library (collision samples per edge, bounding radii per frame).
        params: ``margin``, ``static_seed_margin``, ``static_prefer``, ``seed_margin``.
        static, collide, collide_first, collide_runs: see the module docstring; any may be None.

    Attributes:
        hold: ``hold(res) -> (frames, xz, radius)`` or None: where the character stays after the
            segment (its idling after a last goal), tested with the segment in the final test.
        deadline: the last frame a motion may end on (an offline scenario's last frame), or None.
        still_static: the static clearance with the discs of the characters who stay put for
            the whole segment (:meth:`.segment.SegmentPlanner.run` sets it), read by the
            search's static filter only; or None.
    """

    def __init__(self, lib: MotionLibrary, params: SearchParams, static=None, collide=None, collide_first=None,
                 collide_runs=None):
        self.lib = lib
        self.p = params
        self.static = static
        self.collide = collide
        if collide_first is None and collide is not None:
            def collide_first(f, xz, r):
                hit = np.flatnonzero(np.asarray(collide(f, xz, r), dtype=bool))
                return int(hit[0]) if len(hit) else -1
        self.collide_first = collide_first
        if collide_runs is None and collide is not None:
            def collide_runs(f, xz, r, cnt):
                return np.logical_or.reduceat(np.asarray(collide(f, xz, r), dtype=bool), np.cumsum(cnt) - cnt)
        self.collide_runs = collide_runs
        self.hold = None
        self.deadline = None
        self.still_static = None

    def clear_edges(self, edges: np.ndarray, cfg: np.ndarray, frames0: np.ndarray, moving: bool,
                    compiled: bool) -> tuple[np.ndarray, np.ndarray]:
        """(collision-free, and also ``static_prefer`` further from static obstacles) per
        candidate clip ``edges`` placed at the configuration ``cfg`` ((3,), or (n, 3): where
        each clip starts), clip k starting at frame ``frames0[k]``. Vectorized over candidates
        (one compiled gather of their collision samples with numba); the moving test stops
        each clip at its first hit.

        Args:
            moving: test against planned characters too (their frames mean something).
            compiled: gather the samples with the numba kernel.
        """
        lib, g = self.lib, self.lib.g
        n = len(edges)
        ok = np.ones(n, dtype=bool)
        if n == 0 or (self.static is None and (self.collide is None or not moving)):
            return ok, ok.copy()
        if compiled:
            xz, rad, frames, cnt = kernels.edge_samples(lib, edges, cfg, frames0, self.p.margin)
        else:
            cnt = lib.samp_ptr[edges + 1] - lib.samp_ptr[edges]
            which = np.repeat(np.arange(n), cnt)
            sidx = lib.samp_ptr[edges][which] + (np.arange(int(cnt.sum())) - (np.cumsum(cnt) - cnt)[which])
            gf = lib.samp_frame[sidx]
            local = np.stack([g.frame_cxz[gf, 0], g.frame_cxz[gf, 1], g.frame_heading[gf]], axis=1)
            cfg = np.asarray(cfg, dtype=np.float64)
            xz = compose(cfg[None] if cfg.ndim == 1 else cfg[which], local)[:, :2]
            rad = g.frame_radius[gf].astype(np.float64) + self.p.margin
            frames = frames0[which] + lib.samp_off[sidx]
        starts = np.cumsum(cnt) - cnt
        roomier = ok.copy()
        if self.static is not None:
            # samples are every few frames: keep the distance a character covers between two
            # samples from obstacles too, or a seed that grazes one fails the per-frame test
            d = self.static(xz)
            ok &= ~np.logical_or.reduceat(d < rad + self.p.static_seed_margin, starts)
            roomier &= ~np.logical_or.reduceat(d < rad + self.p.static_seed_margin + self.p.static_prefer, starts)
        if moving and self.collide is not None:
            # seeds keep a wider berth from moving characters: the splice later shifts the
            # motion in space (displacement maps) and in time (resampling)
            ok &= ~self.collide_runs(frames, xz, rad + self.p.seed_margin, cnt)
        return ok, ok & roomier

    def first_hit(self, frames, xz, rad) -> int:
        """Index of the first sample whose cylinder (``rad`` includes the margin) hits an
        obstacle or a planned character, or -1."""
        first = len(xz)
        rad = np.broadcast_to(rad, (first,))
        if self.static is not None:
            hit = np.flatnonzero(self.static(xz) < rad)
            first = int(hit[0]) if len(hit) else first
        if self.collide_first is not None and first:
            k = self.collide_first(frames[:first], xz[:first], rad[:first])
            first = k if k >= 0 else first
        return first if first < len(xz) else -1

    def hits_runs(self, frames, xz, rad, counts) -> np.ndarray:
        """Per run of ``counts`` consecutive samples: whether any sample's cylinder (``rad``
        includes the margin) hits an obstacle or a planned character -- :meth:`first_hit`
        ``>= 0`` of each run, for many runs at once."""
        counts = np.asarray(counts, dtype=np.int64)
        out = np.zeros(len(counts), dtype=bool)
        some = counts > 0
        if not some.any():
            return out
        starts = (np.cumsum(counts) - counts)[some]
        if self.static is not None:
            out[some] |= np.logical_or.reduceat(self.static(xz) < rad, starts)
        if self.collide_runs is not None:
            out |= self.collide_runs(frames, xz, rad, counts)
        return out

    def hits_between(self, res: SegmentResult, lo: int, hi: int) -> bool:
        """Whether an output frame of ``res`` in ``[lo, hi)`` hits an obstacle or a planned
        character: part of :meth:`final_collision`'s test, so True means it returns a hit."""
        lo, hi = max(int(lo), 0), min(int(hi), len(res.root))
        if hi <= lo:
            return False
        xz, rad = blend_cylinders(self.lib.g, res.frames_a[lo:hi], res.frames_b[lo:hi], res.root[lo:hi])
        return self.first_hit(res.start_frame + np.arange(lo, hi), xz, rad + self.p.margin) >= 0

    def final_collision(self, res: SegmentResult):
        """First output frame whose bounding cylinder hits an obstacle or a planned character,
        or None (the final test of section 3.3); ``len(res.root)`` when the motion is clear but
        ends after :attr:`deadline`, or standing at its end afterwards (:attr:`hold`) would be
        in someone's way."""
        g, p = self.lib.g, self.p
        xz, rad = blend_cylinders(g, res.frames_a, res.frames_b, res.root)
        hit = self.first_hit(res.start_frame + np.arange(len(res.root)), xz, rad + p.margin)
        if hit >= 0:
            return hit
        if self.deadline is not None and res.start_frame + len(res.root) - 1 > self.deadline:
            return len(res.root)
        if self.hold is not None:
            tail = self.hold(res)
            if tail is not None and len(tail[0]):
                f2, xz2, r2 = tail
                r2 = np.asarray(r2, dtype=np.float64) + p.margin
                if self.first_hit(np.asarray(f2), np.asarray(xz2, dtype=np.float64), r2) >= 0:
                    return len(res.root)
        return None
