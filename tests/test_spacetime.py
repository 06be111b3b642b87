import numpy as np
import pytest

from runtime.crowd import spacetime
from runtime.crowd.spacetime import SpaceTimeIndex


def brute(stored, frames, xz, r, margin=0.0, ignore=None):
    hit = np.zeros(len(frames), bool)
    for owner, (f, p, rad) in stored.items():
        if owner == ignore:
            continue
        for k in range(len(frames)):
            m = f == frames[k]
            if np.any(np.hypot(*(p[m] - xz[k]).T) < rad[m] + r[k] + margin):
                hit[k] = True
    return hit


@pytest.mark.parametrize("capacity", [0, 300, 5000])
def test_matches_brute_force_through_removals_and_merges(capacity):
    """``capacity``: none, a hint too small (the index grows past it), room for every row (the
    arrays are made once)."""
    rng = np.random.default_rng(0)
    idx = SpaceTimeIndex(cell=1.3, capacity=capacity)
    keys0 = idx._keys
    stored = {}
    for step in range(40):
        o = int(rng.integers(0, 12))
        n = int(rng.integers(5, 80))
        f = rng.integers(0, 30, n)
        p = rng.uniform(-6, 6, (n, 2))
        rad = rng.uniform(0.2, 0.6, n)
        if o in stored and rng.random() < 0.5:
            idx.remove_owner(o)          # a re-plan replaces the character's samples
            del stored[o]
        if o in stored:
            f0, p0, r0 = stored[o]
            stored[o] = (np.concatenate([f0, f]), np.concatenate([p0, p]), np.concatenate([r0, rad]))
        else:
            stored[o] = (f, p, rad)
        idx.insert(o, f, p, rad)
        qf = rng.integers(0, 30, 50)
        qp = rng.uniform(-6, 6, (50, 2))
        qr = rng.uniform(0.2, 0.6, 50)
        ign = int(rng.integers(0, 12))
        want = brute(stored, qf, qp, qr, 0.02, ign)
        np.testing.assert_array_equal(idx.overlaps(qf, qp, qr, margin=0.02, ignore_owner=ign), want)
        assert idx.overlaps(qf, qp, qr, margin=0.02, ignore_owner=ign, first_only=True) == bool(want.any())
        # the compiled query (numba) and the numpy walk find the same (sample, owner) pairs
        pairs = [sorted(zip(*[a.tolist() for a in idx._hits(qf, qp, qr, 0.02, ign, compiled=c)]))
                 for c in ((False, True) if spacetime._nb is not None else (False,))]
        assert pairs[0] == pairs[-1]
        assert sorted({q for q, _ in pairs[0]}) == np.flatnonzero(want).tolist()
        # per run of consecutive samples (the seeds' candidate clips), compiled and numpy
        cuts = np.sort(rng.choice(np.arange(1, 50), size=int(rng.integers(1, 12)), replace=False))
        counts = np.diff(np.concatenate([[0], cuts, [50]]))
        want_runs = np.logical_or.reduceat(want, np.cumsum(counts) - counts)
        np.testing.assert_array_equal(idx.any_overlap_runs(qf, qp, qr, counts, margin=0.02, ignore_owner=ign),
                                      want_runs)
        saved, spacetime._nb = spacetime._nb, None
        try:
            np.testing.assert_array_equal(idx.any_overlap_runs(qf, qp, qr, counts, margin=0.02, ignore_owner=ign),
                                          want_runs)
        finally:
            spacetime._nb = saved
    # compactions keep the stored rows within twice the live ones plus the last batch
    live = sum(len(f) for f, _, _ in stored.values())
    assert idx.count <= max(SpaceTimeIndex.MIN_CAPACITY, 2 * live + 80)
    assert len(idx._head) >= 2 * len(idx._keys)                            # load <= 0.5
    assert (idx._keys is keys0) == (capacity == 5000)


def test_forget_before_drops_played_frames_at_compaction():
    idx = SpaceTimeIndex(cell=1.2)
    idx.insert(0, np.arange(100), np.zeros((100, 2)), 0.3)
    idx.forget_before(50)
    for k in range(40):           # 4100 rows: past the first capacity, so compactions run
        idx.insert(1 + k, np.arange(100), np.full((100, 2), 10.0 + 3 * k), 0.3)
    assert idx.count < 4100
    frames = idx._keys[:idx.count] >> 42
    assert np.sum(frames >= 50) == 50 * 41                   # nothing still to play is dropped
    assert np.sum(frames < 50) <= 0.5 * 50 * 41              # most played rows are gone
    assert idx.overlaps(np.array([60]), np.array([[0.0, 0.0]]), np.array([0.3]))[0]


def test_holds_answer_like_cylinders_on_every_frame():
    """A hold (one disc for frames [0, until), or a goal's from a later frame to the end) gives
    the same answers as the same disc inserted on each of those frames, for every query, in
    both the compiled and the numpy walk; releasing an owner's start hold keeps its goal's."""
    from runtime.crowd import spacetime
    from runtime.crowd.reservations import Reservations
    rng = np.random.default_rng(3)
    n_frames = 120
    held = Reservations(cell=1.2, n_frames=n_frames)
    dense = Reservations(cell=1.2, n_frames=n_frames)
    for o in range(8):
        f = np.arange(0, 100)
        xz = rng.uniform(-5, 5, 2) + np.cumsum(rng.normal(0, 0.05, (100, 2)), 0)
        held.insert(o, f, xz, 0.3)
        dense.insert(o, f, xz, 0.3)
    for o in range(8, 20):
        c, until = rng.uniform(-5, 5, 2), int(rng.integers(20, n_frames))
        held.hold(o, c, 0.35, until)
        dense.insert(o, np.arange(until), np.repeat(c[None], until, 0), 0.35)
    goal_from = {}
    for o in range(20, 26):
        c, start = rng.uniform(-5, 5, 2), int(rng.integers(1, n_frames - 10))
        goal_from[o] = (start, float(c[0]))
        held.hold(o, c, 0.35, n_frames, start=start, kind="goal")
        dense.insert(o, np.arange(start, n_frames), np.repeat(c[None], n_frames - start, 0), 0.35)
    c0, c1 = rng.uniform(-5, 5, 2), rng.uniform(-5, 5, 2)
    held.hold(26, c0, 0.35, 40)
    held.hold(26, c1, 0.35, n_frames, start=70, kind="goal")
    held.release_hold(26)
    dense.insert(26, np.arange(70, n_frames), np.repeat(c1[None], n_frames - 70, 0), 0.35)
    # a start hold covers every frame before its end, negative ones too (a backward seed's)
    c2 = np.array([20.0, 20.0])
    held.hold(27, c2, 0.35, 30)
    assert held.overlaps(np.array([-5, 10, 40]), np.repeat(c2[None], 3, 0), 0.3).tolist() == [True, True, False]
    held.remove_owner(27)
    held.release_hold(9)
    dense.remove_owner(9)
    held.remove_owner(10)
    dense.remove_owner(10)
    q_f = rng.integers(0, n_frames, 400)
    q_xz = rng.uniform(-6, 6, (400, 2))
    for enabled in ([True, False] if spacetime.AVAILABLE else [False]):
        old = spacetime.ENABLED
        spacetime.ENABLED = enabled
        try:
            assert np.array_equal(held.overlaps(q_f, q_xz, 0.3), dense.overlaps(q_f, q_xz, 0.3))
            assert held.overlapping_owners(q_f, q_xz, 0.3) == dense.overlapping_owners(q_f, q_xz, 0.3)
            assert held.first_overlap(q_f, q_xz, 0.3) == dense.first_overlap(q_f, q_xz, 0.3)
            counts = np.full(40, 10)
            assert np.array_equal(held.any_overlap_runs(q_f, q_xz, 0.3, counts),
                                  dense.any_overlap_runs(q_f, q_xz, 0.3, counts))
        finally:
            spacetime.ENABLED = old
    for f in (0, 50, 75, 119):
        a, b = held.at_frame(f), dense.at_frame(f)
        assert sorted(map(tuple, np.round(a[0], 5))) == sorted(map(tuple, np.round(b[0], 5)))
    # standing from a frame on: the goal holds that have begun by then (no start hold lasts)
    xz, r = held.standing(80)
    begun = {round(x, 6) for f, x in goal_from.values() if f <= 80} | {round(float(c1[0]), 6)}
    assert {round(float(x), 6) for x in xz[:, 0]} == begun
    held.remove_owner(26)
    assert len(held.standing(80)[0]) == len(begun) - 1
