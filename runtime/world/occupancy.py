"""Who stands where, when: the occupancy that a character's plan is tested against in the
World.

Planned motion lives in a space-time index of bounding cylinders
(:class:`~runtime.crowd.spacetime.SpaceTimeIndex`); idling lives in :class:`IdleStretches` (a
disc per stretch of idle clips); beyond its buffer every character counts as standing where it
ends (it may never be planned again). :class:`Occupancy` answers the World's questions over a
:class:`~runtime.world.playback.Playback`, vectorized over samples and nearby characters.
"""
from __future__ import annotations

import numpy as np

from ..motion.cylinders import blend_cylinders

STANDING_STATES = ("idle", "queued")   # CharacterState values of characters who stand until planned

__all__ = ["IdleStretches", "Occupancy", "PlanningView"]


class IdleStretches:
    """Where characters stand idling, as discs over frame intervals: rows (owner, first frame,
    last frame, x, z, radius). Idle clips are appended to every character all the time; kept
    out of the space-time index (which then holds only planned motion), they cost one row per
    stretch instead of one sample per frame. The radius covers the idle loop's bounding
    cylinders and its root's excursion (:meth:`~runtime.world.playback.Playback.stay_radii`). Queries are vectorized over
    samples and the rows near them."""

    def __init__(self):
        self.rows = np.zeros((0, 6))

    def add(self, owner, f0, f1, x, z, r) -> None:
        rows = self.rows
        own = np.flatnonzero(rows[:, 0] == owner)
        if len(own):
            last = own[np.argmax(rows[own, 2])]
            if rows[last, 2] >= f0 - 1 and abs(rows[last, 3] - x) < 1e-6 and abs(rows[last, 4] - z) < 1e-6:
                rows[last, 2] = max(rows[last, 2], f1)        # the same spot: extend
                rows[last, 5] = max(rows[last, 5], r)
                return
        self.rows = np.vstack([rows, [[owner, f0, f1, x, z, r]]])

    def cut(self, owner, frame) -> None:
        """Forget ``owner``'s stretches from ``frame`` on (its buffer is replaced there)."""
        rows = self.rows
        mine = rows[:, 0] == owner
        rows[mine & (rows[:, 2] >= frame), 2] = frame - 1
        self.rows = rows[~mine | (rows[:, 2] >= rows[:, 1])]

    def remove(self, owner) -> None:
        self.rows = self.rows[self.rows[:, 0] != owner]

    def forget_before(self, frame) -> None:
        self.rows = self.rows[self.rows[:, 2] >= frame]

    def overlaps(self, frames, xz, radius, ignore_owner=None) -> np.ndarray:
        n = len(frames)
        hit = np.zeros(n, dtype=bool)
        rows = self.rows
        if n == 0 or len(rows) == 0:
            return hit
        reach = float(np.max(radius)) + (rows[:, 5].max() if len(rows) else 0.0)
        lo, hi = xz.min(axis=0) - reach, xz.max(axis=0) + reach
        m = ((rows[:, 3] > lo[0]) & (rows[:, 3] < hi[0]) & (rows[:, 4] > lo[1]) & (rows[:, 4] < hi[1])
             & (rows[:, 2] >= frames.min()) & (rows[:, 1] <= frames.max()))
        if ignore_owner is not None:
            m &= rows[:, 0] != ignore_owner
        if not m.any():
            return hit
        r = rows[m]
        inside = (frames[:, None] >= r[None, :, 1]) & (frames[:, None] <= r[None, :, 2])
        d = np.hypot(xz[:, None, 0] - r[None, :, 3], xz[:, None, 1] - r[None, :, 4])
        return np.any(inside & (d < radius[:, None] + r[None, :, 5]), axis=1)


class Occupancy:
    """Collision questions over every character's buffered future.

    Args:
        playback: the characters' buffers (:class:`~runtime.world.playback.Playback`), with its
            space-time ``index`` and idle ``stretches``.
        stay_r: per node, the radius a character idling there covers
            (:meth:`~runtime.world.playback.Playback.stay_radii`).
    """

    def __init__(self, playback, stay_r: np.ndarray):
        self.pb = playback
        self.stay_r = stay_r

    def occupied(self, frames, xz, radius, owner):
        """Samples that overlap another character's buffered future: its planned motion (the
        space-time index) or its idling (the idle stretches)."""
        frames = np.asarray(frames, dtype=np.int64)
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        hit = self.pb.index.overlaps(frames, xz, radius, ignore_owner=owner)
        return hit | self.pb.stretches.overlaps(frames, xz, radius, ignore_owner=owner)

    def collide(self, frames, xz, radius, owner):
        """Samples that hit another character: its buffered future, and, beyond its last
        buffered frame, the place where it stands idling. Every character counts as standing
        there, also one with goals still to plan: its plan may fail or wait long in the queue,
        and then it keeps idling there (a goal on such a spot waits, see :meth:`goal_taken`)."""
        pb = self.pb
        hit = self.occupied(frames, xz, radius, owner)
        if len(frames) == 0:
            return hit
        others = pb.active & (pb.tail < frames.max())
        if 0 <= owner < pb.cap:
            others[owner] = False
        s = np.flatnonzero(others)
        if len(s) == 0:
            return hit
        txz = pb.buf_root[s, pb.tail[s] % pb.size, :2]
        reach = float(radius.max()) + self.stay_r.max()
        lo, hi = xz.min(axis=0) - reach, xz.max(axis=0) + reach
        m = (txz[:, 0] > lo[0]) & (txz[:, 0] < hi[0]) & (txz[:, 1] > lo[1]) & (txz[:, 1] < hi[1])
        if not m.any():
            return hit
        s, txz = s[m], txz[m]
        sr = self.stay_r[pb.tail_node[s]]
        late = frames[:, None] > pb.tail[s][None, :]
        d = np.hypot(xz[:, None, 0] - txz[None, :, 0], xz[:, None, 1] - txz[None, :, 1])
        hit |= np.any(late & (d < radius[:, None] + sr[None, :]), axis=1)
        return hit

    def end_blocked(self, slot: int, end) -> bool:
        """Would the character in ``slot``, standing at ``end`` (a Config) after it arrives, be
        in the way of another character's buffered future? (The planner tests the segment's
        frames; the idling after them is tested here.)"""
        pb = self.pb
        act = pb.active.copy()
        act[slot] = False
        if not act.any():
            return False
        last = int(min(pb.tail[act].max(), end.frame + pb.size))
        if last <= end.frame:
            return False
        frames = np.arange(end.frame + 1, last + 1)
        xz = np.broadcast_to(np.array([end.x, end.z]), (len(frames), 2))
        r = np.full(len(frames), self.stay_r[end.node])
        return bool(self.occupied(frames, xz, r, slot).any())

    def goal_taken(self, slot: int, goal) -> bool:
        """Does another character stand (where its buffered motion ends) on ``goal``?"""
        pb = self.pb
        others = pb.active.copy()
        others[slot] = False
        s = np.flatnonzero(others)
        if len(s) == 0:
            return False
        xz = pb.buf_root[s, pb.tail[s] % pb.size, :2]
        d = np.hypot(xz[:, 0] - goal.position[0], xz[:, 1] - goal.position[1])
        r_goal = self.stay_r[goal.nodes].max() if goal.nodes is not None else self.stay_r.max()
        return bool(np.any(d < self.stay_r[pb.tail_node[s]] + r_goal))


class PlanningView:
    """What the crowd planner's ladder of alternatives (:mod:`runtime.crowd.goals`) asks of the
    world it plans in, for one character of the World: the occupancy of everyone else as a
    space-time query, and where they are at a frame (for a space-time route).

    Args:
        crowd: the World's :class:`~runtime.world.crowd.CrowdSystem`.
        owner: the character's slot (left out of every query).
    """

    def __init__(self, crowd, owner: int):
        self.crowd, self.owner = crowd, owner
        self.graph, self.params, self.policy, self.lib = crowd.graph, crowd.params, crowd.policy, crowd.lib
        self.fps, self.static, self.still = crowd.world.fps, crowd.static, crowd.still
        pb = crowd.playback
        self.n_total = int(crowd.world.frame + pb.size - 1)   # as far as a buffer reaches
        self.index = self

    def standing(self, frame: int):
        """(xz (M, 2), radius (M,)) of the other characters who stand where they are until
        they are planned (no goal, or one waiting for the planner): the discs the way points
        bend round (:attr:`runtime.crowd.planner.SegmentPlanner.standing`)."""
        crowd, pb = self.crowd, self.crowd.playback
        s = np.flatnonzero(pb.active)
        s = s[s != self.owner]
        waiting = np.fromiter((crowd.slots[k].state.value in STANDING_STATES for k in s), dtype=bool, count=len(s))
        s = s[waiting]
        f = np.minimum(frame, pb.tail[s])
        return pb.buf_root[s, f % pb.size, :2].astype(np.float64), self.crowd.occupancy.stay_r[pb.tail_node[s]]

    # -- the space-time queries of the planner (the World's occupancy stands in for the index) --
    def overlaps(self, frames, xz, radius):
        frames = np.asarray(frames, dtype=np.int64)
        return self.crowd.occupancy.collide(frames, np.asarray(xz, dtype=np.float64),
                                            np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape),
                                            self.owner)

    def first_overlap(self, frames, xz, radius) -> int:
        hit = np.flatnonzero(self.overlaps(frames, xz, radius))
        return int(hit[0]) if len(hit) else -1

    def any_overlap_runs(self, frames, xz, radius, counts):
        counts = np.asarray(counts, dtype=np.int64)
        out = np.zeros(len(counts), dtype=bool)
        if len(frames) == 0:
            return out
        hit = self.overlaps(frames, xz, radius)
        nz = counts > 0
        out[nz] = np.logical_or.reduceat(hit, (np.cumsum(counts) - counts)[nz])
        return out

    def overlapping_owners(self, frames, xz, radius, margin: float = 0.0) -> dict:
        return {}

    def at_frame(self, frame: int):
        """(xz (M, 2), radius (M,)) of every other character at ``frame`` (standing at the end
        of its buffer beyond it)."""
        pb = self.crowd.playback
        s = np.flatnonzero(pb.active)
        s = s[s != self.owner]
        f = np.minimum(frame, pb.tail[s])
        k = f % pb.size
        xz, r = blend_cylinders(self.graph, pb.buf_a[s, k], pb.buf_b[s, k], pb.buf_root[s, k])
        beyond = frame > pb.tail[s]
        xz[beyond] = pb.buf_root[s[beyond], k[beyond], :2]
        r[beyond] = self.crowd.occupancy.stay_r[pb.tail_node[s[beyond]]]
        return xz, r
