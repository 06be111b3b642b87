"""Probabilistic roadmap (paper 000 section 3.2): free nodes, clear edges, determinism,
connectivity through a doorway, way points that avoid obstacles, errors, packs and caching."""
from pathlib import Path

import numpy as np
import pytest

from authoring.roadmap import build_roadmap, load_or_build_roadmap
from runtime.assets import AssetError
from runtime.crowd.environment import Environment
from runtime.crowd.roadmap import Roadmap, RoadmapError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "samples" / "example_world" / "world.usda"
R = 0.35


def _rect(x0, z0, x1, z1):
    return [[x0, z0], [x1, z0], [x1, z1], [x0, z1]]


def two_rooms():
    """Two 8 x 8 m rooms side by side; the dividing wall has a 1.2 m door; a pillar and a table."""
    polys = [_rect(-8.2, -4.2, 8.2, -4.0), _rect(-8.2, 4.0, 8.2, 4.2),      # south, north walls
             _rect(-8.2, -4.0, -8.0, 4.0), _rect(8.0, -4.0, 8.2, 4.0),      # west, east walls
             _rect(-0.1, -4.0, 0.1, -0.6), _rect(-0.1, 0.6, 0.1, 4.0),      # divider with a door at z in [-0.6, 0.6]
             _rect(3.0, 1.0, 5.0, 2.0)]                                     # a table
    return Environment(polys, [[-4.0, 0.0, 0.5]], obstacle_paths=[f"/World/Obstacles/P{i}" for i in range(7)]
                       + ["/World/Obstacles/Pillar"])


@pytest.fixture(scope="module")
def rooms():
    env = two_rooms()
    return env, build_roadmap(env, radius=R, seed=0)


def _sampled_clearance(env, a, b, n=400):
    t = np.linspace(0, 1, n)[None, :, None]
    return env.distance(a[:, None, :] + t * (b - a)[:, None, :]).min(axis=1)


def test_nodes_free_and_edges_clear(rooms):
    env, rm = rooms
    assert rm.num_nodes >= 50
    assert np.all(env.distance(rm.nodes) > R)
    i = np.repeat(np.arange(rm.num_nodes), np.diff(rm.indptr))
    j = rm.indices
    assert np.all(i != j)
    a, b = rm.nodes[i], rm.nodes[j]
    assert np.all(env.segment_clear(a, b, R))
    # independent of segment_clear: sampled clearance along each edge (sampling only over-estimates)
    up = i < j
    assert np.all(_sampled_clearance(env, a[up], b[up], n=150) >= R - 1e-9)
    np.testing.assert_allclose(rm.weights, np.hypot(*(a - b).T))
    assert np.all(rm.weights <= 2 * rm.connect_distance + 1e-9)
    # symmetric adjacency
    A = rm.matrix()
    assert (A != A.T).nnz == 0


def test_roadmap_is_connected_through_the_door(rooms):
    env, rm = rooms
    s = rm.summary()
    assert s["components"] == 2 and s["isolated"] == 0, s  # inside the building, and around it
    comp = rm.components()
    inside = (np.abs(rm.nodes[:, 0]) < 8) & (np.abs(rm.nodes[:, 1]) < 4)
    assert len(set(comp[inside])) == 1 and len(set(comp[~inside])) == 1
    assert set(comp[inside]) != set(comp[~inside])
    assert inside[rm.nodes[:, 0] < 0].any() and inside[rm.nodes[:, 0] > 0].any()
    # some node lies in the doorway region (bridge sampling helps here)
    door = (np.abs(rm.nodes[:, 0]) < 0.5) & (np.abs(rm.nodes[:, 1]) < 0.6)
    assert door.any()


def test_deterministic_for_a_seed():
    env = two_rooms()
    a = build_roadmap(env, radius=R, seed=3, n_samples=120)
    b = build_roadmap(env, radius=R, seed=3, n_samples=120)
    c = build_roadmap(env, radius=R, seed=4, n_samples=120)
    for k in ("nodes", "indptr", "indices", "weights"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert a.nodes.tobytes() != c.nodes.tobytes()
    assert a.num_nodes == 120


def test_waypoints_avoid_obstacles(rooms):
    env, rm = rooms
    start, goal = np.array([-6.0, 3.0]), np.array([6.0, 3.0])
    w = rm.waypoints(env, start, goal)
    np.testing.assert_array_equal(w[0], start)
    np.testing.assert_array_equal(w[-1], goal)
    assert len(w) >= 3  # the wall is in the way
    assert np.all(env.segment_clear(w[:-1], w[1:], R))
    assert np.all(_sampled_clearance(env, w[:-1], w[1:]) >= R - 1e-9)
    # the path goes through the door
    crossing = np.flatnonzero(np.sign(w[:-1, 0]) != np.sign(w[1:, 0]))
    assert len(crossing) == 1
    k = crossing[0]
    t = -w[k, 0] / (w[k + 1, 0] - w[k, 0])
    assert abs(w[k, 1] + t * (w[k + 1, 1] - w[k, 1])) < 0.6 - R + 1e-9
    # shortcutting never lengthens the path (beyond pushing its way points off corners)
    from runtime.crowd.roadmap import PUSH_ITERS, PUSH_STEP
    full = rm.waypoints(env, start, goal, shortcut=False)
    assert np.all(env.segment_clear(full[:-1], full[1:], R))
    length = lambda p: np.hypot(*np.diff(p, axis=0).T).sum()
    assert length(w) <= length(full) + 2 * PUSH_STEP * PUSH_ITERS * (len(w) - 2) and len(w) <= len(full)


def test_way_points_are_pushed_off_corners(rooms, monkeypatch):
    """String pulling leaves way points on roadmap nodes barely ``radius`` from a door jamb or a
    table corner; pushing moves them away (towards radius + SHORTCUT_EXTRA) and keeps every
    segment clear."""
    import runtime.crowd.roadmap as rmod
    env, rm = rooms
    ends = [((-6.0, 3.0), (6.0, 3.0)), ((-6.0, -3.0), (6.0, 3.0)), ((-3.0, 3.0), (7.0, -3.0))]

    def clearances():
        out = []
        for s, g in ends:
            w = rm.waypoints(env, np.array(s), np.array(g))
            assert np.all(env.segment_clear(w[:-1], w[1:], R))
            out.append(env.distance(w[1:-1]))
        return np.concatenate(out)

    pushed = clearances()
    monkeypatch.setattr(rmod, "PUSH_ITERS", 0)
    plain = clearances()
    assert len(pushed) == len(plain)
    assert np.all(pushed >= plain - 1e-12) and np.sum(pushed > plain + 0.03) >= 2
    assert pushed.min() > R + 0.15


def test_straight_line_when_visible(rooms):
    env, rm = rooms
    w = rm.waypoints(env, [-6.0, -3.0], [-2.0, -3.0])
    np.testing.assert_array_equal(w, [[-6.0, -3.0], [-2.0, -3.0]])
    w = rm.waypoints(env, [-6.0, 0.0], [-2.0, 0.0])  # the pillar is in between
    assert len(w) > 2 and np.all(env.segment_clear(w[:-1], w[1:], R))


def test_direct_segment_keeps_the_shortcut_clearance(rooms):
    """A straight start-goal segment is used only when it keeps radius + SHORTCUT_EXTRA from
    every obstacle (both ends being that far away): one grazing the pillar by less is routed."""
    from runtime.crowd.roadmap import SHORTCUT_EXTRA
    env, rm = rooms
    wide = R + SHORTCUT_EXTRA
    # passes the pillar (x -4, radius 0.5) with between R and R + SHORTCUT_EXTRA to spare
    gap = 0.5 + 0.5 * (R + wide)
    start, goal = np.array([-7.0, gap]), np.array([-1.5, gap])
    assert env.segment_clear(start, goal, R) and not env.segment_clear(start, goal, wide)
    assert env.distance(np.stack([start, goal])).min() > wide
    w = rm.waypoints(env, start, goal)
    assert len(w) > 2
    # one with room to spare stays straight
    w = rm.waypoints(env, [-7.0, 2.5], [-1.5, 2.5])
    assert len(w) == 2


def test_end_point_closer_than_radius_to_an_obstacle(rooms):
    """A goal 0.2 m from the table (a seat): joined with the clearance it has."""
    env, rm = rooms
    goal = np.array([4.0, 0.8])
    assert 0 < env.distance(goal) < R
    w = rm.waypoints(env, [-6.0, 3.0], goal)
    np.testing.assert_array_equal(w[-1], goal)
    assert env.segment_clear(w[-2], w[-1], 0.999 * float(env.distance(goal)))
    assert np.all(env.segment_clear(w[:-2], w[1:-1], R))


def test_unreachable_and_inside_errors_name_start_and_goal(rooms):
    env, rm = rooms
    with pytest.raises(RoadmapError, match=r"goal \(4\.000, 1\.500\) is inside obstacle /World/Obstacles/P6"):
        rm.waypoints(env, [-6.0, 3.0], [4.0, 1.5])
    with pytest.raises(RoadmapError, match=r"start \(-4\.000, 0\.000\) is inside obstacle /World/Obstacles/Pillar"):
        rm.waypoints(env, [-4.0, 0.0], [6.0, 3.0])
    # a goal outside the building: the rooms are closed, so it cannot be reached
    with pytest.raises(RoadmapError, match=r"from start \(-6\.000, 3\.000\) to goal \(0\.000, 9\.000\)"):
        rm.waypoints(env, [-6.0, 3.0], [0.0, 9.0])


def test_closed_room_is_unreachable():
    polys = [_rect(-3, -3, 3, -2.8), _rect(-3, 2.8, 3, 3), _rect(-3, -2.8, -2.8, 2.8), _rect(2.8, -2.8, 3, 2.8)]
    env = Environment(polys)
    rm = build_roadmap(env, radius=R, seed=0, n_samples=150)
    assert rm.summary()["components"] >= 2  # inside and outside
    with pytest.raises(RoadmapError, match=r"no path from start \(0\.000, 0\.000\) to goal \(5\.000, 5\.000\)"):
        rm.waypoints(env, [0.0, 0.0], [5.0, 5.0])
    w = rm.waypoints(env, [-2.0, -2.0], [2.0, 2.0])  # inside to inside works
    assert len(w) == 2


def test_open_ground():
    env = Environment.open_ground()
    rm = build_roadmap(env, radius=R, seed=0)
    assert rm.num_nodes >= 50
    np.testing.assert_array_equal(rm.waypoints(env, [0, 0], [40, -3]), [[0, 0], [40, -3]])


def test_pack_round_trip_and_stale_detection(tmp_path, rooms):
    env, rm = rooms
    p = tmp_path / "rm.cwpack"
    rm.save(p)
    back = Roadmap.load(p)
    for k in ("nodes", "indptr", "indices", "weights"):
        np.testing.assert_array_equal(getattr(back, k), getattr(rm, k))
    assert back.radius == rm.radius and back.env_fingerprint == env.fingerprint()
    np.testing.assert_array_equal(back.waypoints(env, [-6, 3], [6, -3]), rm.waypoints(env, [-6, 3], [6, -3]))
    moved = Environment([q + [0.0, 0.01] for q in env.polygons], env.circles)
    with pytest.raises(RoadmapError, match="rebuild"):
        back.waypoints(moved, [-6, 3], [6, -3])
    with pytest.raises(AssetError, match="wrong kind"):
        from runtime.assets import save_pack
        save_pack(tmp_path / "g.cwpack", "motion_graph", 1, {}, {})
        Roadmap.load(tmp_path / "g.cwpack")
    data = bytearray(p.read_bytes())
    data[len(data) // 2] ^= 0xFF
    (tmp_path / "bad.cwpack").write_bytes(bytes(data))
    with pytest.raises(AssetError, match="bad.cwpack"):
        Roadmap.load(tmp_path / "bad.cwpack")


def test_load_or_build_caches_by_fingerprint(tmp_path):
    env = two_rooms()
    a = load_or_build_roadmap(env, tmp_path, radius=R, seed=1)
    files = list(tmp_path.glob("*.cwpack"))
    assert len(files) == 1 and env.fingerprint()[:16] in files[0].name
    mtime = files[0].stat().st_mtime_ns
    b = load_or_build_roadmap(env, tmp_path, radius=R, seed=1)
    assert files[0].stat().st_mtime_ns == mtime  # loaded, not rebuilt
    np.testing.assert_array_equal(a.nodes, b.nodes)
    # a corrupt cache is rebuilt, not trusted
    files[0].write_bytes(b"garbage")
    c = load_or_build_roadmap(env, tmp_path, radius=R, seed=1)
    np.testing.assert_array_equal(c.nodes, a.nodes)
    assert Roadmap.load(files[0]).num_nodes == a.num_nodes
    # other obstacles: another cache entry
    moved = Environment([q + [0.0, 0.01] for q in env.polygons], env.circles)
    load_or_build_roadmap(moved, tmp_path, radius=R, seed=1)
    assert len(list(tmp_path.glob("*.cwpack"))) == 2
    # from a world stage path
    rm = load_or_build_roadmap(EXAMPLE, tmp_path, radius=R, seed=0)
    assert rm.summary()["components"] == 1


def test_author_roadmap_cli(tmp_path, capsys):
    from authoring.cli import main
    out = tmp_path / "rm.cwpack"
    assert main(["author", "roadmap", str(EXAMPLE), "--out", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "nodes" in text and "1 component" in text
    rm = Roadmap.load(out)
    from usd_io.world import read_world
    env = read_world(EXAMPLE)
    assert rm.matches(env)
    seats = [m.position for m in env.markers_with_role("seat")]
    w = rm.waypoints(env, seats[0], seats[2])  # around the table
    assert len(w) > 2 and np.all(env.segment_clear(w[:-1], w[1:], R))
    assert main(["author", "roadmap", str(tmp_path / "missing.usda"), "--out", str(out)]) == 2
    assert "missing.usda: file not found" in capsys.readouterr().err


def _grid_geodesic(env, radius, start, goals, h=0.2):
    """Shortest free-space distances from ``start`` to each of ``goals`` on an 8-connected grid
    of ``h`` m cells (cells farther than ``radius`` from every obstacle): an independent
    reference for the roadmap's routes."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    x0, z0, x1, z1 = env.bounds(margin=0.0)
    xs, zs = np.arange(x0, x1 + h, h), np.arange(z0, z1 + h, h)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    free = env.distance(np.stack([X.ravel(), Z.ravel()], 1)).reshape(X.shape) > radius
    idx = np.arange(X.size).reshape(X.shape)
    rows, cols, w = [], [], []
    for dx, dz in ((1, 0), (0, 1), (1, 1), (1, -1)):
        a = idx[max(0, -dx):X.shape[0] - max(0, dx), max(0, -dz):X.shape[1] - max(0, dz)]
        b = idx[max(0, dx):, max(0, dz):][:a.shape[0], :a.shape[1]] if dz >= 0 else \
            idx[dx:, :X.shape[1] + dz][:a.shape[0], :a.shape[1]]
        ok = free.ravel()[a.ravel()] & free.ravel()[b.ravel()]
        rows.append(a.ravel()[ok]); cols.append(b.ravel()[ok]); w.append(np.full(ok.sum(), h * np.hypot(dx, dz)))
    A = coo_matrix((np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))), shape=(X.size, X.size)).tocsr()
    cell = lambda p: int(idx[int(round((p[0] - x0) / h)), int(round((p[1] - z0) / h))])
    d = dijkstra(A, directed=False, indices=cell(start))
    return np.array([d[cell(g)] for g in goals])


def test_theater_routes_are_near_the_shortest():
    """In theater40's hall (rows entered from 4 m side aisles through 2 m lanes) every lobby
    character's route to its seat is within 15% of the grid geodesic (at 0.5 nodes per m^2 the
    left aisle's lanes were not connected and 12 of 40 routes crossed the whole hall)."""
    from runtime.crowd.scenario import load_scenario
    from usd_io.world import read_world
    folder = ROOT / "samples" / "theater40"
    env = read_world(folder / "world.usda")
    sc = load_scenario(folder / "scenario.toml", env=env)
    rm = build_roadmap(env, seed=0)
    ratios = []
    for c in sc.characters[16:]:                  # the three front rows
        goal = np.asarray(c.goals[0].position, float)
        w = rm.waypoints(env, np.asarray(c.position, float), goal)
        length = float(np.hypot(*np.diff(w, axis=0).T).sum())
        ref = _grid_geodesic(env, rm.radius, np.asarray(c.position, float), [goal])[0]
        assert np.isfinite(ref)
        ratios.append(length / ref)
    assert max(ratios) < 1.15, np.round(ratios, 2)
