"""Interactive tiling (Kim, Hwang, Hyun and Lee 2012, section 5.3): horizon filling per tick, team targets,
tracks."""
import math

import numpy as np
import pytest

from runtime.tiling.check import check_tiling
from runtime.tiling.interactive import InteractiveTiling
from test_tiling_util import graph, meet_library, prepared, singles  # noqa: F401  (fixtures)


def _teams(prepared, seed=0, seconds=8.0, targets=((4.0, 0.0), (-4.0, 0.0))):
    it = InteractiveTiling(prepared, seed=seed, interaction_labels=("meet",))
    for team, (x0, hd) in enumerate(((-5.0, math.pi / 2), (5.0, -math.pi / 2))):
        for k in range(4):
            it.add_character((x0 + 1.5 * (k % 2) * (1 if team == 0 else -1), 1.5 * (k // 2) - 0.75), hd, team)
    it.set_target(0, targets[0])
    it.set_target(1, targets[1])
    states = []
    for f in range(1, int(seconds * 30) + 1):
        it.step(f / 30.0)
        states.append(it.root_states())
    return it, np.array(states)


@pytest.fixture(scope="module")
def run(prepared):
    return _teams(prepared)


def test_targets_steer(prepared):
    it, states = _teams(prepared, seconds=10.0, targets=((-4.5, 7.0), (4.5, -7.0)))
    spots = np.array([it.target_of(c) for c in range(it.n)])
    d = np.hypot(*(states[:, :, :2] - spots).transpose(2, 0, 1))   # (frames, characters)
    assert d[-1].mean() < 0.5 * d[0].mean(), d[::30].mean(1)


def test_every_tick_has_motion(run):
    it, states = run
    assert not np.isnan(states).any()                      # the horizon is always filled
    assert (it.tail_time > it.t).all()
    # the teams cross: everyone moved
    assert np.hypot(*(states[-1, :, :2] - states[0, :, :2]).T).min() > 1.0
    pos, rot = it.poses()
    assert pos.shape == (8, 3) and rot.shape == (8, it.library.skeleton.num_joints, 4)
    assert np.allclose(np.linalg.norm(rot, axis=-1), 1.0, atol=1e-6)


def test_tracks_keep_identity_across_stitches(run):
    it, states = run
    tracks = it.tracks()
    assert len(tracks) == 8
    res = it.result()
    chains = res.characters()
    assert len(chains) == 8                                # one chain per character: identity continuous
    for c, tr in enumerate(tracks):
        assert tr.start_frame == 0 and len(tr) >= len(states)
        step = np.hypot(*np.diff(tr.root[:, :2], axis=0).T)
        assert step.max() < 0.12
        # the playback buffer showed exactly the recorded track
        assert np.allclose(tr.root[1:len(states) + 1, :2], states[:, c, :2])
        # consecutive segments are stitched instances
        insts = [s[0] for s in tr.segments]
        assert len(insts) > 3 and len(set(insts)) == len(insts)


def test_interactive_result_checks(run):
    it, _ = run
    res = it.result()
    rep = check_tiling(res)
    assert it.stats["forced"] == 0
    assert rep.ok, str(rep)
    # every instance but the 8 starting ones is stitched at its entry, and the checker finds the
    # same stitches geometrically as the system recorded
    assert rep.links_disagree == 0 and rep.stitches >= res.num_instances - 8


def test_same_seed_same_run(prepared, run):
    it, states = run
    it2, states2 = _teams(prepared)
    assert np.array_equal(states, states2) and it.stats == it2.stats


# -- the bench's two-team scenario (bench/tiling_interactive.py): its library has four meet patches
@pytest.fixture(scope="module")
def bench_prepared(graph):
    from runtime.tiling.synthetic import synthetic_library
    from runtime.tiling.prepared import PreparedLibrary
    return PreparedLibrary(synthetic_library(graph, meets=4))


def _bench_teams(prepared, seed, seconds=20.0, **kw):
    it = InteractiveTiling(prepared, seed=seed, interaction_labels=("meet",), **kw)
    for team, (x0, hd) in enumerate(((-5.0, math.pi / 2), (5.0, -math.pi / 2))):
        for k in range(4):
            r, c = divmod(k, 2)
            it.add_character((x0 + 1.5 * (c - 0.5), 1.5 * (r - 0.5)), hd, team)
    rng = np.random.default_rng(seed)
    states = []
    for f in range(1, int(seconds * 30) + 1):
        if (f - 1) % 150 == 0:
            for team in range(2):
                it.set_target(team, (4.0 * (1 if team == 0 else -1), 0.0) if f == 1 else tuple(rng.uniform(-4, 4, 2)))
        it.step(f / 30.0)
        states.append(it.root_states())
    return it, np.array(states)


@pytest.mark.slow
def test_interaction_corners_nobody(bench_prepared):
    # seed 5: a meet's walk-out sweeps, seconds later, the spot where a teammate stands; without
    # the park rules (runtime.tiling.cornering) that character has no valid patch left and gets
    # overlapping ones
    it, states = _bench_teams(bench_prepared, seed=5)
    assert it.stats["multi"] >= 1                          # the interaction still happens
    assert not np.isnan(states).any()
    rep = check_tiling(it.result())
    assert rep.interpenetrations == 0, rep.interpenetration_examples
    assert rep.ok, str(rep)


@pytest.mark.slow
def test_bench_scenario_sweep_forces_nothing(bench_prepared):
    # 40 seeds of the bench's two-team scenario (20 s each, targets changing every 5 s): nobody
    # is cornered by an interaction, so no patch is ever forced and nothing interpenetrates
    bad = {}
    multi = 0
    for seed in range(40):
        it, states = _bench_teams(bench_prepared, seed=seed)
        rep = check_tiling(it.result())
        multi += it.stats["multi"]
        if it.stats["forced"] or rep.interpenetrations or np.isnan(states).any():
            bad[seed] = (it.stats["forced"], rep.interpenetrations)
    assert not bad, bad                                    # seed: (forced, interpenetrations)
    assert multi >= 10                                     # interactions still happen


def test_boxed_in_character_stands_rather_than_forcing(bench_prepared):
    # walls 0.8 m from a standing character and a clearance no candidate can keep: the search
    # (one preferred candidate) finds nothing valid, so the last resort keeps the character where
    # it is with a standing patch that touches no wall, instead of forcing one through a wall
    from runtime.tiling.region import Obstacle
    w = 0.8
    walls = [Obstacle((w + 0.2, 0.0), (0.2, 2.0)), Obstacle((-w - 0.2, 0.0), (0.2, 2.0)),
             Obstacle((0.0, w + 0.2), (2.0, 0.2)), Obstacle((0.0, -w - 0.2), (2.0, 0.2))]
    it = InteractiveTiling(bench_prepared, seed=0, obstacles=walls, max_singles=1, clearance=1.5)
    it.add_character((0.0, 0.0), 0.0, 0)
    it.set_target(0, (6.0, 0.0))
    states = []
    for f in range(1, 151):
        it.step(f / 30.0)
        states.append(it.root_states())
    states = np.array(states)
    rep = check_tiling(it.result())
    assert it.stats["extensions"] >= 4 and (it.tail_time > it.t).all()     # it kept moving (in place)
    assert it.stats["forced"] == 0 and rep.obstacle_hits == 0, (it.stats, rep.summary())
    assert np.abs(states[:, 0, :2]).max() < w


def test_bench_scenario_is_reproducible(bench_prepared):
    it, states = _bench_teams(bench_prepared, seed=1, seconds=6.0)
    it2, states2 = _bench_teams(bench_prepared, seed=1, seconds=6.0)
    assert np.array_equal(states, states2) and it.stats == it2.stats
    a, b = it.tracks(), it2.tracks()
    assert all(np.array_equal(x.root, y.root) and np.array_equal(x.frames_a, y.frames_a) for x, y in zip(a, b))


def test_work_budget_spreads_extensions(bench_prepared):
    # the deterministic work budget: after one extension a tick goes on only while the
    # estimated work stays within it (tails about to be reached excepted)
    counts = {}
    for budget in (None, 3.0):
        it = InteractiveTiling(bench_prepared, seed=0, work_budget=budget, max_per_tick=3)
        for k in range(12):
            it.add_character((1.6 * (k % 4), 1.6 * (k // 4)), 0.0, 0)
        it.set_target(0, (2.0, 8.0))
        per = []
        for f in range(1, 91):
            e = it.stats["extensions"]
            it.step(f / 30.0)
            per.append(it.stats["extensions"] - e)
            assert (it.tail_time > it.t).all()              # never starved
        counts[budget] = np.array(per)
    assert counts[None].max() == 3 and counts[3.0].max() < counts[None].max()


def test_long_extensions_are_time_sliced_across_ticks(bench_prepared):
    """Once a tick's work budget is spent, an extension pauses between its steps and goes on
    next tick (restarting in one go if anything was committed meanwhile): some extensions are
    paused, nobody runs out of motion, the recorded tiling checks clean, and the same seed
    gives the same tiling."""
    from runtime.tiling.check import check_tiling

    def run():
        # the benchmark's 50 characters: ten teams of five in a 24 x 24 m arena
        it = InteractiveTiling(bench_prepared, seed=3, work_budget=1.5, interaction_labels=("meet",))
        rng = np.random.default_rng(3)
        for t in range(10):
            cx, cz = -12.0 + 6.0 * (t % 5), -6.0 + 12.0 * (t // 5)
            for k in range(5):
                it.add_character((cx + 1.5 * (k % 3 - 1), cz + 1.5 * (k // 3)), 0.0, t)
            it.set_target(t, tuple(rng.uniform(-12, 12, 2)))
        for f in range(1, 241):
            it.step(f / 30.0)
            assert (it.tail_time > it.t).all()
        return it

    a, b = run(), run()
    assert a.stats["paused"] > 0
    assert a.stats == b.stats
    np.testing.assert_array_equal(a.root_states(), b.root_states())
    s = check_tiling(a.result()).summary()
    assert s["danglings"] == 0 and s["interpenetrations"] == 0 and s["frames_over_limits"] == 0, s
