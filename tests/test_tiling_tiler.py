"""Tiling (Kim, Hwang, Hyun and Lee 2012, section 5): Algorithms 1 and 2, control, determinism;
checked by the independent checker."""
import math

import numpy as np
import pytest

from runtime.tiling.check import check_repeating, check_tiling
from runtime.tiling.config import TilerConfig
from runtime.tiling.preference import Preference
from runtime.tiling.region import Obstacle, Portal, Region
from runtime.tiling.result import TilingResult
from runtime.tiling.state import tiling_energy
from runtime.tiling.tiler import Tiler
from test_tiling_util import graph, meet_library, prepared, singles  # noqa: F401  (fixtures)


def _run(prepared, seed=1, size=6.0, secs=8.0, seeds=6, **kw):
    til = Tiler(prepared, Region(0, 0, size, size, 0, secs, kw.pop("wrap_space", False)),
                config=TilerConfig(seeds=seeds), seed=seed, **kw)
    til.phase1()
    til.phase2()
    return til, til.result()


def test_energy_eq6():
    assert tiling_energy(8, 2, 0.2) == pytest.approx(2 / 10 + 0.2 / 10)
    assert tiling_energy(0, 0, 0.2) > tiling_energy(0, 4, 0.2) > tiling_energy(2, 2, 0.2)


def test_small_tiling_is_perfect_and_reproducible(prepared, tmp_path):
    til, res = _run(prepared)
    assert til.num_danglings == 0 and res.num_instances > 20
    rep = check_tiling(res)
    assert rep.ok, str(rep)
    assert rep.stitches > 10 and rep.links_disagree == 0 and rep.constraint_error < 1e-6
    # identity: every character is a chain of stitched fragments; tracks are continuous
    for tr in res.tracks():
        step = np.hypot(*np.diff(tr.root[:, :2], axis=0).T)
        assert step.max() < 0.12                     # < 3.6 m/s: no jumps at stitches
        assert np.abs(np.diff(tr.root[:, 2])).max() < 0.3
    # same seed -> the same tiling, another seed -> another one
    _, res2 = _run(prepared)
    assert res2.patch == res.patch and all(np.array_equal(a, b) for a, b in zip(res.xz, res2.xz))
    _, res3 = _run(prepared, seed=2)
    assert res3.patch != res.patch
    # pack round trip keeps what the checker sees
    res.save(tmp_path / "t.cwpack")
    back = TilingResult.load(tmp_path / "t.cwpack", prepared.library)
    assert check_tiling(back).summary() == rep.summary()


def test_phase2_removes_the_danglings_phase1_leaves(prepared):
    til = Tiler(prepared, Region(0, 0, 6, 6, 0, 8), config=TilerConfig(seeds=6, i_max=40), seed=3)
    s1 = til.phase1()
    assert s1["danglings"] > 0                       # a short phase 1 leaves work
    s2 = til.phase2()
    assert s2["danglings"] == 0 and check_tiling(til.result()).ok


def test_keyframe_stays_fixed_and_obstacles_are_avoided(prepared):
    meet = prepared.library.index("meet0")
    ob = Obstacle(np.array([5.4, 5.4]), (0.4, 0.4), 0.3, 2.0)
    moving = np.stack([np.linspace(0.5, 5.5, 241), np.full(241, 0.4)], 1)
    til = Tiler(prepared, Region(0, 0, 6, 6, 0, 8), obstacles=[ob, Obstacle(moving, (0.3, 0.3), 0.0, 2.0)],
                config=TilerConfig(seeds=4), seed=4)
    iid = til.add_keyframe(meet, 3.0, 3.0, math.radians(90), 1.0)
    til.phase1()
    til.phase2()
    res = til.result()
    k = res.fixed.index(True)
    assert res.patch[k] == meet and res.place[k] == pytest.approx((3.0, 3.0, math.radians(90), 1.0))
    # the keyframe is not deformed: it is the rigid placement of the rest patch
    d = prepared.patches[meet].deformer
    c, s = math.cos(math.radians(90)), math.sin(math.radians(90))
    rigid = np.stack([c * d.xz[:, 0] + s * d.xz[:, 1] + 3, -s * d.xz[:, 0] + c * d.xz[:, 1] + 3], 1)
    assert np.abs(res.xz[k] - rigid).max() < 1e-9 and np.abs(res.time[k] - (d.time + 1.0)).max() < 1e-9
    rep = check_tiling(res)
    assert rep.ok, str(rep)
    assert til.inst[iid].fixed


def test_portals_allow_danglings(prepared):
    til, res = _run(prepared, seed=5, seeds=4, portals=[Portal(3.0, 3.0, 10.0, "both")])
    # everything is inside a source/sink: nothing needs stitching and the checker agrees
    assert til.num_danglings == 0 and check_tiling(res).ok
    rep = check_tiling(TilingResult(res.library, res.region, res.patch, res.place, res.fixed, res.xz, res.heading,
                                    res.time, res.links, [], [], res.fps))
    assert rep.ok == (len(rep.danglings) == 0)


def test_preference_pulls_patches_to_the_target(prepared):
    # over a few seeds (one tiling is a random draw): with the preference, the patches lie nearer
    # the target on average by half a metre or more, and nearer on most seeds
    far = Preference(target=(1.0, 1.0), sigma_pos=1.0)
    dist = lambda t: np.mean([math.hypot(i.place[0] - 1, i.place[1] - 1) for i in t.inst.values()])  # noqa: E731
    gains = []
    for seed in (6, 7, 8, 9):
        til = Tiler(prepared, Region(0, 0, 8, 8, 0, 6), config=TilerConfig(seeds=8, i_max=60), seed=seed, preference=far)
        til.phase1()
        free = Tiler(prepared, Region(0, 0, 8, 8, 0, 6), config=TilerConfig(seeds=8, i_max=60), seed=seed)
        free.phase1()
        gains.append(dist(free) - dist(til))
    assert np.mean(gains) > 0.5 and sum(g > 0 for g in gains) >= 3, gains


@pytest.mark.slow
def test_repeating_tile_is_seamless_3x3(prepared):
    til, res = _run(prepared, seed=7, size=6.0, secs=6.0, seeds=4, wrap_space=True)
    assert til.num_danglings == 0
    rep = check_repeating(res)
    assert rep.ok, str(rep)
    assert rep.stitches > 0
