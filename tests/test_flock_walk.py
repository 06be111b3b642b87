"""Walking DDGs (Lai, Chenney and Fan 2005, section 5): correspondence tracking, random and region-constrained
walks of many flocks, regions, determinism; the runtime never imports authoring."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from authoring.boids import BoidsParams, record_flock
from authoring.ddg import DDGBuildParams, build_ddg
from runtime.flock.check import WalkChecker
from runtime.flock.containment import EdgeContainment
from runtime.flock.coords import yaw_rotate
from runtime.flock.region import Box, Polygon
from runtime.flock.walk import FlockSystem
from runtime.motion import quat

REPO = Path(__file__).resolve().parents[1]

L_SHAPE = Polygon([[-40, -40], [40, -40], [40, 0], [0, 0], [0, 40], [-40, 40]])
BOX = Box([-35, 0, -35], [35, 40, 35])


@pytest.fixture(scope="module", params=[2, 3], ids=["2d", "3d"])
def ddg(request):
    rec = record_flock(BoidsParams(dim=request.param), 150.0, seed=1)
    g, _ = build_ddg(rec, DDGBuildParams())
    return g


def _start(ddg, n):
    if ddg.dim == 2:
        pos = np.zeros((n, 3))
        pos[:, 0] = pos[:, 2] = -20.0
        return pos, L_SHAPE
    pos = np.zeros((n, 3))
    pos[:, 1] = 20.0
    return pos, BOX


@pytest.mark.slow
def test_region_walk_20_flocks_10_minutes(ddg):
    """Acceptance: centroids never leave; no agent steps more than the recorder's largest step
    + 10%, transitions included; every agent keeps its identity (M' = M_e(M) at each edge)."""
    n, ticks, dt = 20, 10 * 60 * 30, 1.0 / 30.0
    pos0, region = _start(ddg, n)
    fs = FlockSystem(ddg, seed=7)
    fs.add_flocks(pos0, np.linspace(0, 6, n, endpoint=False), region)
    checker = WalkChecker(ddg.max_step, ddg.fps, [region] * n, tolerance=0.1)
    checker.update(fs.positions(), dt)
    edges, slots = fs.current_edges(), fs.slots()
    transitions = 0
    for _ in range(ticks):
        fs.step(dt)
        checker.update(fs.positions(), dt)
        e = fs.current_edges()
        moved = np.nonzero(e != edges)[0]
        if moved.size:
            transitions += moved.size
            s = fs.slots()
            np.testing.assert_array_equal(s[moved], np.take_along_axis(ddg.edge_perm[e[moved]], slots[moved], 1))
            slots[moved] = s[moved]
            edges = e
    report = checker.summary()
    assert report["frames_outside"] == 0, report
    assert report["step_violations"] == 0 and report["worst_step_ratio"] <= 1.1, report
    assert report["worst_step_ratio"] > 0.9           # the walk does move at full speed at times
    assert transitions > 20 * 100
    assert fs.stats["fallbacks"] == 0


def test_checker_flags_jumps_and_escapes():
    region = Box([-1, -1, -1], [1, 1, 1])
    ch = WalkChecker(0.1, 30.0, [region], tolerance=0.1)
    p = np.zeros((1, 3, 3))
    ch.update(p, 1 / 30)
    p[0, 0, 0] = 0.105                                 # within 10%
    ch.update(p, 1 / 30)
    assert ch.summary()["ok"]
    p[0, 0, 0] = 0.3                                   # a jump
    ch.update(p, 1 / 30)
    p[0, :, 0] = 5.0                                   # and out of the region
    ch.update(p, 1 / 30)
    r = ch.summary()
    assert not r["ok"] and r["step_violations"] >= 2 and r["frames_outside"] == 1
    rep = ch.report()
    assert rep.kind == "flock" and not rep.passed and rep.summary() == r
    assert r["kind"] == "flock" and r["passed"] is False
    assert rep.to_dict()["frames_outside"] == [1]
    assert str(rep).startswith("flock check: FAILED | ticks 4 | flocks 1 | frames outside 1")


def test_correspondence_keeps_identities_through_transitions(ddg):
    fs = FlockSystem(ddg, seed=3)
    fs.add_flock((0.0, 5.0, 0.0), 1.0)
    limit = 1.1 * ddg.max_step
    prev, slots, edge = fs.positions().copy(), fs.slots(), fs.current_edges()[0]
    checked = 0
    for _ in range(30 * 120):
        fs.step(1 / 30)
        p, e = fs.positions(), fs.current_edges()[0]
        assert np.sqrt(((p - prev) ** 2).sum(-1)).max() <= limit
        if e != edge and ddg.is_transition()[e] and not np.array_equal(ddg.edge_perm[e], np.arange(ddg.n_agents)):
            new = fs.slots()
            np.testing.assert_array_equal(new[0], ddg.edge_perm[e][slots[0]])
            # without the correspondence agent i would take over the clip slot it had before
            wrong = p[0][np.argsort(new[0])[slots[0]]]
            assert np.sqrt(((wrong - prev[0]) ** 2).sum(-1)).max() > 3 * ddg.max_step
            checked += 1
        prev, slots, edge = p.copy(), fs.slots(), e
    assert checked >= 3


def test_random_walk_is_seeded_and_flocks_are_independent(ddg):
    def run(seed, n):
        fs = FlockSystem(ddg, seed=seed)
        fs.add_flocks(np.arange(n)[:, None] * [30.0, 0.0, 0.0], np.arange(n) * 0.5)
        for _ in range(900):
            fs.step(1 / 30)
        return fs.positions().copy(), fs.stats["transitions"]

    a, ta = run(4, 3)
    b, _ = run(4, 3)
    c, _ = run(5, 3)
    d, _ = run(4, 5)
    assert ta > 3 * 5
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, c)
    np.testing.assert_array_equal(a, d[:3])                 # adding flocks changes nobody's walk


def test_step_size_does_not_change_the_walk(ddg):
    pos0, region = _start(ddg, 2)
    out = []
    for dt, n in ((1 / 30, 90), (1 / 60, 180), (1 / 10, 30)):
        fs = FlockSystem(ddg, seed=2)
        fs.add_flocks(pos0, [0.0, 2.0], region)
        fs.add_flock(pos0[0], 1.0)
        for _ in range(n):
            fs.step(dt)
        out.append(fs.positions().copy())
    np.testing.assert_allclose(out[1], out[0], atol=1e-3)
    np.testing.assert_allclose(out[2], out[0], atol=1e-3)


def test_outputs(ddg):
    fs = FlockSystem(ddg, seed=1)
    fs.add_flocks([[0, 10, 0], [50, 10, 0]], [0.0, 1.0])
    for _ in range(45):
        fs.step(1 / 30)
    p, v, h, q = fs.positions(), fs.velocities(), fs.headings(), fs.orientations()
    assert p.shape == v.shape == (2, ddg.n_agents, 3) and h.shape == (2, ddg.n_agents) and q.shape == (2, ddg.n_agents, 4)
    if ddg.dim == 2:
        assert np.all(p[..., 1] == 10.0) and np.all(v[..., 1] == 0.0)
    np.testing.assert_allclose(h, np.arctan2(v[..., 0], v[..., 2]), atol=1e-6)
    fwd = quat.rotate(q, np.broadcast_to([0.0, 0.0, 1.0], v.shape))
    np.testing.assert_allclose(fwd, v / np.linalg.norm(v, axis=-1, keepdims=True), atol=1e-5)
    np.testing.assert_allclose(fs.centroids(), p.mean(1), atol=1e-5)
    speed = np.linalg.norm(v, axis=-1)
    assert speed.max() <= 1.1 * ddg.max_step * ddg.fps + 1e-3


def test_start_outside_region_is_refused(ddg):
    fs = FlockSystem(ddg)
    with pytest.raises(ValueError, match="outside its region"):
        fs.add_flock((100.0, 20.0, 100.0), 0.0, L_SHAPE if ddg.dim == 2 else BOX)


# ---------------------------------------------------------------- regions
def test_polygon_region():
    pts = np.array([[-20, 0, -20], [20, 0, 20], [20, 0, -20], [-39.5, 3, 39.5], [41, 0, 0], [10, 0, 10]], float)
    np.testing.assert_array_equal(L_SHAPE.contains(pts), [True, False, True, True, False, False])
    d = L_SHAPE.depth(pts)
    np.testing.assert_allclose(d[[0, 2, 3, 4]], [20.0, 20.0, 0.5, -1.0])
    assert d[1] < 0 and d[5] == pytest.approx(-10.0)
    fn, err = L_SHAPE.depth_bound()
    rng = np.random.default_rng(0)
    q = rng.uniform(-45, 45, (2000, 3))
    exact = L_SHAPE.depth(q)
    lb = np.array([fn(*p) for p in q])
    assert np.all(lb <= exact + 1e-12)
    fin = np.isfinite(lb)
    assert fin.mean() > 0.7 and np.all(exact[fin] <= lb[fin] + err + 1e-12)
    with pytest.raises(ValueError):
        Polygon([[0, 0], [1, 1], [2, 2]])


def test_box_region():
    pts = np.array([[0, 20, 0], [0, -1, 0], [34, 39, -34], [36, 20, 0]], float)
    np.testing.assert_array_equal(BOX.contains(pts), [True, False, True, False])
    np.testing.assert_allclose(BOX.depth(pts), [20.0, -1.0, 1.0, -1.0])
    fn, err = BOX.depth_bound()
    assert err == 0 and fn(0, 20, 0) == 20.0
    with pytest.raises(ValueError):
        Box([0, 0, 0], [1, -1, 1])


def test_runtime_does_not_import_authoring():
    code = ("import sys, runtime.flock.walk, runtime.flock.ddg, runtime.flock.metric, runtime.flock.region; "
            "bad = [m for m in sys.modules if m.split('.')[0] in ('authoring', 'usd_io')]; "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True)


@pytest.mark.parametrize("frame_exact", [True, False])
def test_lookahead_containment_matches_brute_force(ddg, frame_exact):
    """The circle shortcuts of the look-ahead never accept an edge whose centroid leaves the
    region; with ``frame_exact`` they accept exactly the edges that stay inside."""
    containment = EdgeContainment(ddg, frame_exact=frame_exact)
    region = L_SHAPE if ddg.dim == 2 else BOX
    d = ddg.derived()
    rng = np.random.default_rng(1)
    strict = 0
    for _ in range(400):
        v = int(rng.integers(ddg.n_nodes))
        yaw = rng.uniform(-np.pi, np.pi)
        t = np.array([rng.uniform(-45, 45), rng.uniform(0, 40) if ddg.dim == 3 else 0.0, rng.uniform(-45, 45)])
        got, depth = containment.inside_edges(region, v, yaw, *t)
        truth = []
        for k in range(d["out_start"][v], d["out_start"][v + 1]):
            e = int(d["out_edges"][k])
            tr = d["track"][d["track_start"][e] + 1:d["track_start"][e + 1]]
            w = yaw_rotate(tr, np.full(len(tr), yaw)) + t
            if region.contains(w).all():
                truth.append(e)
                if e in got:
                    assert depth[got.index(e)] <= region.depth(w[-1][None])[0] + 1e-9
        assert set(got) <= set(truth)
        if frame_exact:
            assert sorted(got) == sorted(truth)
        strict += len(truth) - len(got)
    assert frame_exact or strict > 0


# ---------------------------------------------------------------- look-ahead depth and recovery
def test_every_edge_taken_is_followed_by_the_kept_look_ahead(ddg):
    """When a region flock takes an edge, its verified plan beyond that edge runs at least
    ``(search_factor - 1) * horizon``: the look-ahead for a node runs before the edge taken
    there is committed, and extends the plan from its end, so a long edge taken next never
    leaves only a few seconds of verified future -- too little to turn away from a dead end."""
    pos0, region = _start(ddg, 4)
    fs = FlockSystem(ddg, seed=11)
    fs.add_flocks(pos0, [0.0, 1.5, 3.0, 4.5], region)
    edges, taken = fs.current_edges(), 0
    for _ in range(30 * 120):
        fs.step(1 / 30)
        e = fs.current_edges()
        moved = np.nonzero(e != edges)[0]
        if moved.size:
            planned = fs.planned_frames()[moved]
            assert np.all(planned >= fs.keep_frames), (planned, fs.keep_frames)
            taken += moved.size
        edges = e
    assert taken > 4 * 20 and fs.stats["search_failures"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("dim, recording_seed", [(3, 6), (2, 4)])
def test_region_walk_turns_away_from_dead_ends(dim, recording_seed):
    """Sparser graphs in smaller regions have dead ends tens of seconds deep (states from which
    every path leaves the region sooner or later); the look-ahead sees far enough to turn away
    in time."""
    rec = record_flock(BoidsParams(dim=dim), 150.0, seed=recording_seed)
    g, _ = build_ddg(rec, DDGBuildParams())
    n, ticks, dt = 20, 5 * 60 * 30, 1.0 / 30.0
    pos0 = np.zeros((n, 3))
    if dim == 3:
        region = Box([-25, 0, -25], [25, 30, 25])
        pos0[:, 1] = 15.0
    else:
        region = Polygon([[-30, -30], [30, -30], [30, 0], [0, 0], [0, 30], [-30, 30]])
        pos0[:, 0] = pos0[:, 2] = -15.0
    fs = FlockSystem(g, seed=1)
    fs.add_flocks(pos0, np.linspace(0, 6, n, endpoint=False), region)
    checker = WalkChecker(g.max_step, g.fps, [region] * n, tolerance=0.1)
    checker.update(fs.positions(), dt)
    for _ in range(ticks):
        fs.step(dt)
        checker.update(fs.positions(), dt)
    report = checker.summary()
    assert report["frames_outside"] == 0 and report["step_violations"] == 0, report
    assert fs.stats["fallbacks"] == 0


def test_a_flock_outside_its_new_region_walks_into_it(ddg):
    """A flock with no inside path left -- here: given a region it is not in -- follows recovery
    paths into the region and mostly stays in once there."""
    a = Box([-35, 0, -35], [35, 40, 35])
    b = Box([45, 0, -35], [115, 40, 35])
    n, ticks = 3, 30 * 240
    fs = FlockSystem(ddg, seed=5)
    fs.add_flocks([[0.0, 20.0, 0.0]] * n, [0.0, 2.0, 4.0], a)
    for _ in range(300):
        fs.step(1 / 30)
    for f in range(n):
        fs.set_region(f, b)
    entered = np.full(n, -1)
    inside = np.zeros(n, int)
    for t in range(ticks):
        fs.step(1 / 30)
        ins = b.contains(fs.centroids())
        entered[(entered < 0) & ins] = t
        inside += ins
    assert np.all((entered >= 0) & (entered < 30 * 180)), entered
    assert np.all(inside >= 0.6 * (ticks - entered)), (entered, inside)
    assert fs.stats["fallbacks"] > 0
