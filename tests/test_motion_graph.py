"""Motion graph builder: distance, hubs, snapping, pruning, packs."""
import numpy as np
import pytest

from authoring.motion_graph.build import GraphBuildParams, SourceClip, build_graph, prune
from authoring.motion_graph.distance import aligned_distance_reference, distance_rows, frame_features
from runtime.assets import AssetError
from runtime.motion import SkeletonMismatchError, ops, quat
from runtime.motion.graph import MotionGraph

MB_FILES = ["cmu_02_01_walk.bvh", "cmu_07_05_slow_walk.bvh", "cmu_05_01_walk.bvh",
            "cmu_16_11_walk_veer_left_retargeted.bvh", "cmu_09_06_run.bvh", "cmu_01_01_jumps_turn_around.bvh"]


def test_chunked_distance_equals_per_pair_reference():
    rng = np.random.default_rng(0)
    P = [rng.normal(size=(30, 6, 3)), rng.normal(size=(25, 6, 3))]
    jw = np.array([1.0, 2.0, 0.0, 1.0, 3.0, 0.5])
    hw = 2
    f = frame_features(P, jw, half_window=hw)
    D, theta = distance_rows(f, slice(None))
    offs = np.arange(-hw, hw + 1)
    tw = (hw + 1 - np.abs(offs)).astype(float)
    w = (tw[:, None] * jw[None]).reshape(-1)
    def cloud(g):
        t, i = (0, g) if g < 30 else (1, g - 30)
        X = P[t]
        return X[np.clip(i + offs, 0, len(X) - 1)].reshape(-1, 3)
    for a, b in [(3, 17), (12, 40), (44, 44), (0, 54)]:
        d, th, _, _ = aligned_distance_reference(cloud(a), cloud(b), w)
        assert D[a, b] == pytest.approx(d, abs=1e-10)
        assert D[a, b] == pytest.approx(D[b, a], abs=1e-10)
    assert D[44, 44] == pytest.approx(0.0, abs=1e-12)


def test_distance_is_invariant_to_planar_rigid_motion_but_sees_velocity():
    rng = np.random.default_rng(1)
    X = np.cumsum(rng.normal(size=(20, 5, 3)) * 0.05, axis=0)
    R = quat.from_yaw(0.7)
    Y = quat.rotate(R, X) + [2.0, 0.0, -1.0]
    f = frame_features([X, Y, X[::-1]], np.ones(5), half_window=2)
    D, _ = distance_rows(f, slice(None))
    assert D[10, 30] == pytest.approx(0.0, abs=1e-12)       # same frame, moved and turned
    assert D[10, 40 + 9] > 1e-4                             # same pose, time reversed: differs


def test_prune_keeps_state_changes_and_degree():
    # walking nodes 0,1 (rich), sitting node 2 with two self loops, dangling node 3
    src = np.array([0, 0, 1, 1, 0, 2, 2, 2, 1, 3])
    dst = np.array([1, 1, 0, 0, 2, 2, 2, 0, 3, 3])
    node_state = np.array([0, 0, 2, 0])
    edge_state = np.array([0, 0, 0, 0, -1, 2, 2, -1, 0, 0])
    keep_n, keep_e = prune(4, src, dst, node_state, edge_state, min_degree=2)
    assert keep_n.tolist() == [True, True, True, False]
    assert not keep_e[8] and keep_e[4] and keep_e[7]


@pytest.fixture(scope="module")
def cmu_graph(request):
    from conftest import CMU_DIR
    if not CMU_DIR.is_dir():
        pytest.skip(f"CMU motion capture not found at {CMU_DIR}")
    from authoring.motion_graph.sources import load_takes
    takes = load_takes([CMU_DIR / f for f in MB_FILES])
    return build_graph(takes, GraphBuildParams(threshold_cm=8.0), log=lambda *a: None)


def seam_report(g: MotionGraph):
    """For every node and every (incoming, outgoing) pair: root continuity and the rotation
    change across the join vs the largest frame-to-frame change inside either clip."""
    worst_excess = -np.inf
    worst_root = 0.0
    for n in range(g.num_nodes):
        ins, outs = g.in_edges(n), g.out_edges(n)
        for a in ins:
            ca = g.edge_clip(a)
            da = quat.angle(ca.rotations[1:].astype(float), ca.rotations[:-1].astype(float)).max()
            for b in outs:
                cb = g.edge_clip(b)
                db = quat.angle(cb.rotations[1:].astype(float), cb.rotations[:-1].astype(float)).max()
                j = ops.append(ca, cb)
                k = ca.num_frames - 1
                # root: the join frame of the concatenation is where a ends (position, heading)
                worst_root = max(worst_root, float(np.abs(j.root_xz[k] - ca.root_xz[-1]).max()),
                                 float(abs(j.root_heading[k] - ca.root_heading[-1])))
                # the pose a ends in and the pose b starts in are the same hub pose
                join = quat.angle(ca.rotations[-1].astype(float), cb.rotations[0].astype(float)).max()
                across = quat.angle(j.rotations[k + 1].astype(float), j.rotations[k - 1].astype(float)).max() / 2
                step = max(quat.angle(j.rotations[k].astype(float), j.rotations[k - 1].astype(float)).max(),
                           quat.angle(j.rotations[k + 1].astype(float), j.rotations[k].astype(float)).max())
                worst_excess = max(worst_excess, float(np.degrees(max(step, join, across) - max(da, db))))
    return worst_root, worst_excess


def test_cmu_graph_is_seamless_and_connected(cmu_graph):
    g = cmu_graph
    assert g.num_nodes >= 2 and g.num_edges >= 4
    root, excess = seam_report(g)
    assert root < 1e-9
    assert excess <= 1.0, f"rotation change across a join exceeds the clips' own by {excess:.2f} deg"
    # every node has in/out degree >= 2 within its state
    for n in range(g.num_nodes):
        s = g.node_state[n]
        assert np.sum((g.edge_src == n) & (g.edge_state == s)) >= 2
        assert np.sum((g.edge_dst == n) & (g.edge_state == s)) >= 2


def test_pack_round_trip_and_damage(cmu_graph, tmp_path):
    p = tmp_path / "lib.cwpack"
    cmu_graph.save(p)
    g2 = MotionGraph.load(p)
    assert g2.num_edges == cmu_graph.num_edges
    np.testing.assert_array_equal(g2.frame_rotations, cmu_graph.frame_rotations)
    np.testing.assert_array_equal(g2.edge_disp, cmu_graph.edge_disp)
    raw = p.read_bytes()
    p.write_bytes(raw[:-100])
    with pytest.raises(AssetError, match=str(p)):
        MotionGraph.load(p)


def test_mixing_skeleton_families_names_both_files(cmu_dir):
    from authoring.motion_graph.sources import load_takes
    a = cmu_dir / "cmu_02_01_walk.bvh"
    b = cmu_dir / "cmu_16_15_walk_dazfriendly.bvh"
    with pytest.raises(SkeletonMismatchError) as ei:
        load_takes([a, b])
    assert str(a) in str(ei.value) and str(b) in str(ei.value)
    c = cmu_dir / "cmu_131_02_start_walk_stop_maxfriendly.bvh"
    with pytest.raises(SkeletonMismatchError, match="cmu_131_02"):
        load_takes([a, c])
