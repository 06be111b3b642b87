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


def test_carried_box_moves_with_the_hands(default_graph):
    from pathlib import Path
    from runtime.crowd.tracks import box_trajectories, joint_positions
    from usd_io.world import read_world
    env = read_world(Path(__file__).resolve().parents[1] / "samples" / "example_world" / "world.usda")
    box = sorted(m.path for m in env.markers_with_role("box"))[0]
    m = env.markers[box]
    sc = parse_scenario({"name": "t", "duration": 20.0, "character": [
        {"name": "a", "start": {"position": [float(m.position[0]) + 2.5, float(m.position[1]) + 2.5], "pose": "stand"},
         "goal": [{"box": box}, {"position": [float(m.position[0]) + 2.0, float(m.position[1]) + 3.5], "pose": "stand"}]}]},
        env=env)
    res = plan_scenario(sc, default_graph, env)
    c = res.characters[0]
    pos, head = box_trajectories(sc, res.characters, default_graph, env, res.num_frames)[box]
    f_pick, f_put = c.arrivals
    np.testing.assert_allclose(pos[0, [0, 2]], m.position, atol=1e-9)          # waits at its marker
    sk = default_graph.skeleton
    hands = joint_positions(default_graph, c.track)[:, [sk.index("LeftHand"), sk.index("RightHand")]].mean(axis=1)
    for f in (f_pick, f_pick + 5, (f_pick + f_put) // 2, f_put):
        np.testing.assert_allclose(pos[f], hands[f], atol=1e-9)                 # carried between the hands
    assert pos[f_pick + 5, 1] > 0.6                                              # held up, not dragged
    assert abs(pos[-1, 1] - 0.2) < 1e-9 and np.linalg.norm(pos[-1, [0, 2]] - m.position) > 0.5   # put down elsewhere
