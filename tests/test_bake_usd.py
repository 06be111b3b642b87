"""The bake (issue 6, crowds out): characters carry a skinned capsule-limb body that follows
their joints, the world's geometry is referenced, and the stage validates."""
import numpy as np
from pxr import Usd, UsdGeom, UsdSkel, Vt

from runtime.crowd.scenario import parse_scenario
from runtime.crowd.scheduler import plan_scenario
from usd_io.crowd import build_crowd_stage
from usd_io.stage import save_stage
from usd_io.validate import validate_stage


def test_bake_has_skinned_bodies_and_the_environment(default_graph, tmp_path):
    from pathlib import Path
    world = Path(__file__).resolve().parents[1] / "samples" / "example_world" / "world.usda"
    sc = parse_scenario({"name": "t", "duration": 4.0, "character": [
        {"name": "a", "start": {"position": [-6.0, -6.0], "pose": "stand"}, "goal": [{"position": [-4.0, -3.0]}]}]})
    res = plan_scenario(sc, default_graph)
    out = tmp_path / "bake.usda"
    stage = build_crowd_stage({c.name: c.track for c in res.characters}, default_graph, 30.0, world_path=world,
                              out_path=out)
    save_stage(stage, out)
    assert validate_stage(out) == []
    st = Usd.Stage.Open(str(out))
    assert any(p.IsA(UsdGeom.Gprim) for p in Usd.PrimRange(st.GetPrimAtPath("/World/Environment")))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(st.GetPrimAtPath("/World/Characters/a")), Usd.TraverseInstanceProxies())
    skq = cache.GetSkelQuery(UsdSkel.Skeleton(st.GetPrimAtPath("/World/Characters/a/Skel")))
    body = st.GetPrimAtPath("/World/Characters/a/Body")
    sq = cache.GetSkinningQuery(body)
    assert sq
    ji = np.array(sq.GetJointIndicesPrimvar().Get())
    rest = np.array(UsdGeom.Mesh(body).GetPointsAttr().Get())
    jr = np.array([np.array(m)[3, :3] for m in skq.ComputeJointWorldTransforms(UsdGeom.XformCache(0), True)])
    reach = np.linalg.norm(rest - jr[ji], axis=1)            # each vertex's distance from its joint at rest
    for t in (0.0, 60.0, 119.0):
        pts = Vt.Vec3fArray(UsdGeom.Mesh(body).GetPointsAttr().Get(t))
        assert sq.ComputeSkinnedPoints(skq.ComputeSkinningTransforms(t), pts, t)
        jw = np.array([np.array(m)[3, :3] for m in skq.ComputeJointWorldTransforms(UsdGeom.XformCache(t))])
        d = np.linalg.norm(np.array(pts) - jw[ji], axis=1)
        np.testing.assert_allclose(d, reach, atol=1e-4)     # rigidly bound: the body moves with its bones
    assert np.linalg.norm(jw[0, [0, 2]] - jr[0, [0, 2]]) > 1.0   # and the character did move
