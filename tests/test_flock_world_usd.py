"""Flocks as a system of the World's tick, drawn by the viewer protocol, baked as USD
PointInstancers."""
import numpy as np
import pytest
from pxr import Usd, UsdGeom

from authoring.boids import BoidsParams, record_flock
from authoring.ddg import DDGBuildParams, build_ddg
from runtime.flock import Polygon, WalkChecker
from runtime.world import World
from usd_io.flock import write_flock_instancer
from usd_io.stage import new_stage, save_stage, set_default_prim
from usd_io.validate import errors, validate_stage

REGION = Polygon([[-40, -40], [40, -40], [40, 40], [-40, 40]])


@pytest.fixture(scope="module")
def ddg2():
    rec = record_flock(BoidsParams(dim=2), 90.0, seed=3)
    return build_ddg(rec, DDGBuildParams())[0]


def test_flocks_tick_with_the_world_and_bake_to_usd(default_graph, ddg2, tmp_path):
    w = World(default_graph, seed=0)
    w.spawn("a", (0.0, 0.0))
    _, rows = w.add_flocks(ddg2, np.array([[-10.0, 0.0, 0.0], [10.0, 0.0, 5.0]]), [0.0, 2.0], REGION)
    checker = WalkChecker(ddg2.max_step, ddg2.fps, [REGION] * 2, tolerance=0.1)
    fs = w.flocks[0]
    pos, ori = [fs.positions().copy()], [fs.orientations().copy()]
    checker.update(fs.positions(), w.dt)
    for _ in range(300):
        w.tick()
        checker.update(fs.positions(), w.dt)
        pos.append(fs.positions().copy())
        ori.append(fs.orientations().copy())
    rep = checker.summary()
    assert rep["frames_outside"] == 0 and rep["step_violations"] == 0, rep
    p, h = w.flock_positions()
    assert p.shape == (2 * ddg2.n_agents, 3) and h.shape == (2 * ddg2.n_agents,)
    pos = np.stack(pos)
    ori = np.stack(ori)
    assert not np.allclose(pos[0], pos[-1])             # the flocks moved with the ticks
    stage = new_stage(30.0, 0, len(pos) - 1)
    world = UsdGeom.Xform.Define(stage, "/World")
    set_default_prim(stage, world.GetPrim())
    for f in range(2):
        write_flock_instancer(stage, f"flock{f}", pos[:, f], ori[:, f])
    out = tmp_path / "flocks.usdc"
    save_stage(stage, out)
    assert not errors(validate_stage(out))
    st = Usd.Stage.Open(str(out))
    inst = UsdGeom.PointInstancer(st.GetPrimAtPath("/World/Flocks/flock1"))
    np.testing.assert_allclose(np.array(inst.GetPositionsAttr().Get(150)), pos[150, 1], atol=1e-4)
    ids = np.array(inst.GetIdsAttr().Get())
    assert ids.tolist() == list(range(ddg2.n_agents))   # identities are stable over the walk
    q = np.array(inst.GetOrientationsAttr().Get(150), dtype=np.float64)   # x, y, z, w
    np.testing.assert_allclose(np.abs(np.sum(q[:, [3, 0, 1, 2]] * ori[150, 1], -1)), 1.0, atol=2e-3)
