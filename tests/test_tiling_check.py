"""The tiling checker finds what is wrong without trusting the tiler."""
import numpy as np
import pytest

from runtime.tiling.check import check_repeating, check_tiling, layout_copies
from runtime.tiling.config import TilerConfig
from runtime.tiling.region import Obstacle, Region
from runtime.tiling.result import TilingResult
from runtime.tiling.tiler import Tiler
from test_tiling_util import graph, meet_library, prepared, singles  # noqa: F401  (fixtures)


@pytest.fixture(scope="module")
def base(prepared):
    til = Tiler(prepared, Region(0, 0, 6, 6, 0, 8), config=TilerConfig(seeds=6), seed=11)
    til.add_keyframe("meet0", 3.0, 3.0, 0.0, 0.5)
    til.phase1()
    til.phase2()
    res = til.result()
    assert check_tiling(res).ok
    return res


def _copy(res, **ch):
    kw = dict(library=res.library, region=res.region, patch=list(res.patch), place=list(res.place), fixed=list(res.fixed),
              xz=[a.copy() for a in res.xz], heading=[a.copy() for a in res.heading], time=[a.copy() for a in res.time],
              links=res.links.copy(), obstacles=list(res.obstacles), portals=list(res.portals), fps=res.fps)
    kw.update(ch)
    return TilingResult(**kw)


def _inside_instance(res):
    """An instance whose ports are all well inside the region."""
    for i in range(res.num_instances):
        t = res.time[i]
        if res.library.patches[res.patch[i]].num_characters == 1 and t[0] > 1 and t[-1] < 7 \
                and np.all((res.xz[i] > 0.5) & (res.xz[i] < 5.5)):
            return i
    raise AssertionError("no inner instance")


def test_removed_instance_leaves_danglings(base):
    i = _inside_instance(base)
    keep = [k for k in range(base.num_instances) if k != i]
    cut = _copy(base, patch=[base.patch[k] for k in keep], place=[base.place[k] for k in keep],
                fixed=[base.fixed[k] for k in keep], xz=[base.xz[k] for k in keep], heading=[base.heading[k] for k in keep],
                time=[base.time[k] for k in keep], links=np.zeros((0, 4), np.int64))
    rep = check_tiling(cut)
    assert len(rep.danglings) == 2 and not rep.ok
    assert {d[2] for d in rep.danglings} == {"entry", "exit"}


def test_overlap_interpenetration_and_obstacle(base):
    tr = base.tracks()
    # move a whole character chain onto another character's position
    a, b = np.argsort([-len(t) for t in tr])[:2]
    f = max(tr[a].start_frame, tr[b].start_frame) + 5
    assert f < min(tr[a].start_frame + len(tr[a]), tr[b].start_frame + len(tr[b]))
    pa = tr[a].root[f - tr[a].start_frame, :2]
    pb = tr[b].root[f - tr[b].start_frame, :2]
    bad = _copy(base)
    for i, k, _ in tr[a].segments:
        sl = bad.frag_slices(i)[k]
        bad.xz[i][sl] += pb - pa
    rep = check_tiling(bad)
    assert rep.interpenetrations > 0
    ob = _copy(base, obstacles=[Obstacle(pb, (0.3, 0.3), 0.0, 2.0)])
    assert check_tiling(ob).obstacle_hits > 0


def test_deformation_and_constraint_errors(base):
    i = _inside_instance(base)
    bad = _copy(base)
    bad.xz[i][10] += [0.06, 0.0]               # a 6 cm kink in one frame
    rep = check_tiling(bad)
    assert rep.frames_over_limits > 0 and rep.max_stretch > 0.03
    slow = _copy(base)
    slow.time[i] = slow.time[i][0] + (slow.time[i] - slow.time[i][0]) * 1.8   # 80 % slower: 0.027 s per frame
    assert check_tiling(slow).max_time_shift > 0.018
    m = base.fixed.index(True)
    pulled = _copy(base)
    sl = pulled.frag_slices(m)[1]
    pulled.xz[m][sl] += [0.1, 0.0]
    assert check_tiling(pulled).constraint_error > 0.09


def test_repeating_layout_is_not_seamless_when_a_border_breaks(prepared):
    til = Tiler(prepared, Region(0, 0, 6, 6, 0, 5, True), config=TilerConfig(seeds=3), seed=12)
    til.phase1()
    til.phase2()
    res = til.result()
    lay = layout_copies(res, near=None)
    assert lay.num_instances == 9 * res.num_instances
    assert res.num_instances < layout_copies(res).num_instances < lay.num_instances
    # a chain crossing the x border: shift the instance that starts beyond x1 by 0.4 m
    cross = [i for i in range(res.num_instances) if res.xz[i][:, 0].max() > res.region.x1 and res.xz[i][:, 0].min() < res.region.x1]
    assert cross, "no instance crosses the border"
    bad = _copy(res)
    bad.xz[cross[0]] = bad.xz[cross[0]] + [0.0, 0.4]
    assert len(check_repeating(bad).danglings) > 0
