"""Boids recorder, DDG construction (Lai, Chenney and Fan 2005, section 4.3), DDG packs and
``crowdweave author flock``."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

import authoring.ddg as ddg_build
from authoring.boids import BoidsParams, BoidsSim, record_flock
from authoring.ddg import DDGBuildParams, build_ddg, find_transitions
from runtime.assets import AssetError, load_pack, save_pack
from runtime.flock.ddg import DDG, hermite_weights, load_ddg, save_ddg
from runtime.flock.coords import apply_transform


# ---------------------------------------------------------------- recorder
@pytest.mark.parametrize("dim", [2, 3])
def test_recorder_is_seeded_and_physical(dim):
    p = BoidsParams(dim=dim, warmup=2.0)
    a = record_flock(p, 8.0, seed=4)
    b = record_flock(p, 8.0, seed=4)
    c = record_flock(p, 8.0, seed=5)
    assert a.positions.shape == (241, 20, dim)
    assert a.positions.tobytes() == b.positions.tobytes()
    assert a.velocities.tobytes() == b.velocities.tobytes()
    assert not np.array_equal(a.positions, c.positions)
    speed = np.linalg.norm(a.velocities, axis=-1)
    assert speed.min() >= p.min_speed - 1e-9 and speed.max() <= p.max_speed + 1e-9
    # semi-implicit Euler at the recording rate: velocity == backward difference
    np.testing.assert_allclose(np.diff(a.positions, axis=0) * p.fps, a.velocities[1:], atol=1e-9)
    assert a.max_step <= p.max_speed / p.fps + 1e-12
    assert a.cost_per_virtual_second > 0
    # the group stays together (one flock, not scattered agents)
    spread = np.linalg.norm(a.positions - a.positions.mean(1, keepdims=True), axis=-1).max()
    assert spread < 15.0


def test_batched_simulation_matches_flocks_shape():
    sim = BoidsSim(BoidsParams(dim=3), n_flocks=7, seed=1)
    for _ in range(5):
        sim.step()
    assert sim.x.shape == (7, 20, 3) and np.all(np.isfinite(sim.x))


# ---------------------------------------------------------------- pruned == brute force
@pytest.fixture(scope="module", params=[2, 3], ids=["2d", "3d"])
def small_recording(request):
    return record_flock(BoidsParams(dim=request.param, warmup=3.0), 45.0, seed=21 + request.param)


def _transitions_key(trans):
    return [(t.src, t.dst, t.blend, round(t.cost, 12), round(t.yaw, 12), tuple(t.perm.tolist())) for t in trans]


@pytest.mark.parametrize("cap", ["tight", "loose"])
def test_pruned_build_chooses_exactly_the_brute_force_transitions(small_recording, cap):
    rec = small_recording
    max_rms = {(2, "tight"): 0.32, (2, "loose"): 0.5, (3, "tight"): 0.75, (3, "loose"): 0.9}[rec.dim, cap]
    base = DDGBuildParams(candidate_stride=10, transitions_per_minute=20.0, max_rms=max_rms,
                       min_gap_seconds=3.0, first_round_cells=200, batch=512)
    brute, bi = find_transitions(rec.positions, rec.velocities, rec.fps,
                                 dataclasses.replace(base, use_bound=False), max_step=rec.max_step)
    pruned, pi = find_transitions(rec.positions, rec.velocities, rec.fps, base, max_step=rec.max_step)
    assert bi["stats"].exact_evaluations == bi["stats"].pairs
    assert len(brute) > 0
    assert _transitions_key(pruned) == _transitions_key(brute)
    assert pi["chosen"] == bi["chosen"]
    # every exact value the pruned build computed is the brute-force value, bit for bit
    ev = ~np.isnan(pi["values"])
    assert np.array_equal(pi["values"][ev], bi["values"][ev])
    # the bound never exceeds the metric, and with a tight cap it really skips work
    if cap == "tight":
        assert pi["stats"].exact_evaluations < pi["stats"].pairs
    lb = pi["lower_bound"]
    dom = np.isfinite(bi["values"])
    assert np.all(lb[dom] <= bi["values"][dom])


def test_pruning_comparison_can_fail(small_recording, monkeypatch):
    """The equality above is not vacuous: a bound that overshoots skips real minima."""
    rec = small_recording
    base = DDGBuildParams(candidate_stride=10, transitions_per_minute=20.0, max_rms=0.8, min_gap_seconds=3.0,
                       first_round_cells=200)
    brute, _ = find_transitions(rec.positions, rec.velocities, rec.fps,
                                dataclasses.replace(base, use_bound=False), max_step=rec.max_step)
    real = ddg_build.lower_bound_matrix
    monkeypatch.setattr(ddg_build, "lower_bound_matrix", lambda a, b, n: real(a, b, n) * 4.0)
    wrong, _ = find_transitions(rec.positions, rec.velocities, rec.fps, base, max_step=rec.max_step)
    assert _transitions_key(wrong) != _transitions_key(brute)


# ---------------------------------------------------------------- graph
@pytest.fixture(scope="module")
def built(small_recording):
    return build_ddg(small_recording, DDGBuildParams(candidate_stride=10, transitions_per_minute=30.0))


def test_graph_is_strongly_connected_without_dead_ends(built):
    g, st = built
    g.validate()
    assert g.n_transitions > 0 and st.transitions == g.n_transitions
    adj = csr_matrix((np.ones(g.n_edges), (g.edge_src, g.edge_dst)), shape=(g.n_nodes, g.n_nodes))
    n, _ = connected_components(adj, directed=True, connection="strong")
    assert n == 1
    assert np.all(np.bincount(g.edge_src, minlength=g.n_nodes) > 0)


def test_transitions_blend_continuously_within_step_limit(built, small_recording):
    g, _ = built
    rec = small_recording
    limit = 1.1 * rec.max_step
    d = g.derived()
    checked = 0
    for e in np.nonzero(g.is_transition())[0]:
        arrive = rec.positions[g.node_frame[g.edge_src[e]]]          # configuration A at the node
        prev = rec.positions[g.node_frame[g.edge_src[e]] - 1]
        blended = g.edge_positions(e)                                 # segment coords, slots of B
        # agent in slot a of A continues as slot perm[a] of B
        in_a = apply_transform(g.edge_yaw[e], g.edge_trans[e], blended)[:, g.edge_perm[e]]
        np.testing.assert_allclose(in_a[0], arrive, atol=1e-4)       # no jump at the node
        steps = np.linalg.norm(np.diff(np.concatenate([prev[None], in_a]), axis=0), axis=-1)
        assert steps.max() <= limit
        checked += 1
    assert checked == g.n_transitions
    # the centroid tracks the look-ahead uses are the blended centroids
    e = int(np.nonzero(g.is_transition())[0][0])
    tr = d["track"][d["track_start"][e]:d["track_start"][e + 1]]
    cen = apply_transform(g.edge_yaw[e], g.edge_trans[e], g.edge_positions(e).mean(1))
    np.testing.assert_allclose(tr[:, [0, 2]] if g.dim == 2 else tr, cen, atol=1e-5)


def test_hermite_weights():
    h00, h10 = hermite_weights(np.arange(12), 10)
    assert h00[0] == 1 and h10[0] == 0
    assert np.all(h00[10:] == 0) and np.all(h10[10:] == 0)
    # unit initial slope in frames: the first step carries the velocity gap d1
    assert abs(h10[1] - 1.0) < 0.25 and abs(h00[1] - 1.0) < 0.05


# ---------------------------------------------------------------- packs
def test_pack_roundtrip_and_errors(built, tmp_path):
    g, _ = built
    path = tmp_path / "flock.cwpack"
    save_ddg(path, g)
    h = load_ddg(path)
    for name, a in g.to_arrays().items():
        assert np.array_equal(getattr(h, name), a), name
    assert h.dim == g.dim and h.max_step == g.max_step and h.fps == g.fps
    save_ddg(tmp_path / "again.cwpack", h)
    assert (tmp_path / "again.cwpack").read_bytes() == path.read_bytes()
    # wrong kind
    save_pack(tmp_path / "other.cwpack", "graph", 1, {}, {"x": np.zeros(3)})
    with pytest.raises(AssetError, match="other.cwpack.*kind"):
        load_ddg(tmp_path / "other.cwpack")
    # a broken correspondence is named
    pack = load_pack(path)
    pack.arrays["edge_perm"][0, :2] = 0
    save_pack(tmp_path / "bad.cwpack", pack.kind, pack.version, pack.meta, pack.arrays)
    with pytest.raises(AssetError, match="bad.cwpack.*edge_perm"):
        load_ddg(tmp_path / "bad.cwpack")
    # truncation
    (tmp_path / "cut.cwpack").write_bytes(path.read_bytes()[:200])
    with pytest.raises(AssetError, match="cut.cwpack"):
        load_ddg(tmp_path / "cut.cwpack")


def test_validate_rejects_dead_end(built):
    g, _ = built
    arrays = g.to_arrays()
    keep = arrays["edge_src"] != 0
    arrays = {k: (v[keep] if k.startswith("edge_") else v) for k, v in arrays.items()}
    bad = DDG(dim=g.dim, fps=g.fps, max_step=g.max_step, **arrays)
    with pytest.raises(ValueError, match="dead end"):
        bad.validate()


# ---------------------------------------------------------------- CLI
def test_author_flock_cli(tmp_path, capsys):
    from authoring.cli import main
    out = tmp_path / "f.cwpack"
    args = ["author", "flock", "--agents", "12", "--dim", "2", "--seconds", "40", "--seed", "3",
            "--out", str(out), "--quiet", "--stride", "10"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "transitions" in text and "skipped by the lower bound" in text and "wrote" in text
    g = load_ddg(out)
    assert g.n_agents == 12 and g.dim == 2
    first = out.read_bytes()
    assert main(args) == 0
    assert out.read_bytes() == first                   # same inputs and seed, same bytes
    assert main(["author", "flock", "--seconds", "0", "--out", str(tmp_path / "x.cwpack")]) == 2
    assert "argument --seconds: must be a finite number greater than 0" in capsys.readouterr().err
