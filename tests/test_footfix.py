"""Planted feet through the motion-graph build: leg IK after snapping, per-edge foot slide."""
import numpy as np
import pytest


@pytest.fixture(scope="module")
def short_takes(tmp_path_factory):
    from authoring.motion_graph.sources import load_takes
    from authoring.procedural import write_session
    d = tmp_path_factory.mktemp("capture")
    write_session(d, 2.0, 3, take_minutes=1.0)
    return load_takes([d])


def _slide(graph):
    from authoring.motion_graph.footfix import edge_slide
    v = np.concatenate([edge_slide(graph.edge_clip(e)).reshape(-1) for e in range(graph.num_edges)])
    return v[np.isfinite(v)]


def test_pinning_keeps_planted_feet_and_hub_poses(short_takes):
    from authoring.motion_graph.build import GraphBuildParams, build_graph
    quiet = lambda *a: None
    raw = build_graph(short_takes, GraphBuildParams(pin_feet=False, max_foot_slide=1e9), log=quiet)
    g = build_graph(short_takes, GraphBuildParams(), log=quiet)
    before, after = _slide(raw), _slide(g)
    assert before.mean() > 0.04 and np.percentile(before, 95) > 0.2          # snapping alone slides
    assert after.mean() < 0.35 * before.mean() and np.percentile(after, 95) < 0.10
    assert g.meta["foot_slide"]["p95_cm_s"] == pytest.approx(100 * np.percentile(after, 95), abs=0.01)
    # every edge still starts and ends exactly in its hub poses: edges join seamlessly
    for e in range(g.num_edges):
        a, b = g.edge_start[e], g.edge_start[e + 1] - 1
        for f, n in ((a, g.edge_src[e]), (b, g.edge_dst[e])):
            q, h = g.frame_rotations[f], g.node_rotations[n]
            sign = np.where(np.sum(q * h, axis=-1, keepdims=True) < 0, -1.0, 1.0)
            assert np.abs(q - sign * h).max() < 1e-6
            assert g.frame_height[f] == pytest.approx(g.node_height[n], abs=1e-9)


def test_edges_over_the_slide_limit_are_dropped_and_reported(short_takes):
    from authoring.motion_graph.build import GraphBuildParams, build_graph
    from authoring.motion_graph.report import SLID, source_report
    from authoring.motion_graph.sources import SourceFile
    g = build_graph(short_takes, GraphBuildParams(max_foot_slide=1.0), log=lambda *a: None)
    dropped = g.meta["foot_slide"]["dropped"]
    assert dropped and all(d["added_cm_s"] >= 0.95 for d in dropped)
    assert max(g.meta["foot_slide"]["edge_max_cm_s"]) <= 1.5     # the generated takes' own feet do not slide
    kept = {(eo["take"], eo["start"]) for eo in g.meta["edge_origin"]}
    assert not kept & {(d["take"], d["start"]) for d in dropped}
    t = short_takes[0]
    files = [SourceFile(t.path, 30.0, t.labels, derived=False, takes={t.name: 0})]
    rep = source_report(g, files)[0]
    mine = [d for d in dropped if d["take"] == t.name]
    if mine:
        assert rep["dropped"].get(SLID, 0.0) >= (mine[0]["end"] - mine[0]["start"]) / 30.0 - 1e-6
    from runtime.motion.graph import MotionGraph
    assert "foot_slide" in MotionGraph.summary(g) and g.summary()["foot_slide"]["dropped_edges"] == len(dropped)
