"""Ambient life (runtime.world.ambient): people going about their day on the plaza, the
[ambient] scenario table, and the viewer's views of them (opening view at a person's scale,
the keys that jump to the tiled zone, the flocks and a random character)."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
PLAZA = ROOT / "samples" / "plaza"


@pytest.fixture(scope="module")
def plaza(default_graph):
    from authoring.commands.bake import load_sample
    from runtime.world import World
    sc, graph, env, roadmap = load_sample(PLAZA, log=lambda *a: None, progress=False)
    w = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=1e6)
    w.apply_scenario(sc)
    w.add_scenario_flocks(sc)
    w.add_scenario_tiling(sc)
    life = w.add_scenario_ambient(sc)
    return sc, w, life


def test_ambient_table_is_checked(default_graph):
    import tomllib

    from runtime.crowd.scenario import ScenarioError, parse_scenario
    from usd_io.world import read_world
    env = read_world(PLAZA / "world.usda")
    data = tomllib.loads((PLAZA / "scenario.toml").read_text())
    sc = parse_scenario(data, str(PLAZA / "scenario.toml"), env=env)
    assert sc.ambient.count == 300 and sc.ambient.bounds == (-34.0, -34.0, 44.0, 34.0)
    for bad, where in (({"count": 300, "colour": 1}, "colour"), ({"count": -1}, "count"),
                       ({"count": 3, "region": "/World/Regions/nowhere"}, "region"),
                       ({"count": 3, "linger": [5.0, 1.0]}, "linger")):
        with pytest.raises(ScenarioError, match=rf"\[ambient\].*{where}|{where}.*\[ambient\]"):
            parse_scenario(dict(data, ambient=bad), str(PLAZA / "scenario.toml"), env=env)


def _day(graph, seed, ticks=60, count=16):
    """A small ambient crowd on open ground: the driver, where everyone is at the end, and the
    World's events."""
    from runtime.world import World
    from runtime.world.ambient import AmbientLife
    w = World(graph, budget_ms=1e6, seed=0)
    life = AmbientLife(w, count, seed=seed, area=(-14.0, -14.0, 14.0, 14.0), start_within=1.5, linger=(1.0, 2.0))
    w.add_system(life)
    most = 0
    for _ in range(ticks):
        w.tick()
        most = max(most, len(w.crowd.commands))     # what the driver queued this tick
    assert most <= 3 * life.per_tick               # a few decisions a tick (a meeting is up to 3 commands)
    return life, w.root_states().copy(), [(e.kind, e.character, e.time) for e in w.events]


def test_driver_is_deterministic_per_seed(default_graph):
    a, ra, ea = _day(default_graph, seed=3)
    b, rb, eb = _day(default_graph, seed=3)
    c, rc, _ = _day(default_graph, seed=4, ticks=1)
    assert a.stats == b.stats and ea == eb
    np.testing.assert_array_equal(ra, rb)
    assert a.stats["strolls"] + a.stats["walks"] + a.stats["sits"] + a.stats["carries"] + a.stats["meetings"] > 0
    assert (a.goals_had > 0).sum() >= 5
    # another seed: another layout
    assert not np.allclose(ra[:len(rc)][:, :2], rc[:, :2])


def test_everyone_spawns_clear_of_each_other_and_of_obstacles(plaza):
    sc, w, life = plaza
    assert len(life.names) == 300 and len(w.names) == 300 + len(sc.characters)
    xz = w.root_states()[:, :2]
    d = np.linalg.norm(xz[:, None] - xz[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    assert d.min() > 0.9
    seated = life.phase == 3
    assert 10 <= seated.sum() <= 30            # some people sit on benches from the start
    assert (life.phase == 8).sum() >= 40      # others stand talking in small groups
    standing = xz[len(sc.characters):][~seated]
    assert (w.environment.distance(standing) > 0.9).all()


def test_opening_view_shows_people_at_least_30_px_tall(plaza):
    """The viewer's opening camera (look_at_landmark on the scene's "plaza" landmark), at
    1280 x 720: every figure whose root projects into the middle of the view is >= 30 px tall
    (the viewer's project on the first frame's joint positions)."""
    from runtime.viewer.camera import OrbitCamera, look_at_landmark, project
    sc, w, life = plaza
    cam = OrbitCamera()
    look_at_landmark(cam, "plaza", w.landmarks()["plaza"])
    P = w.joint_positions()
    px, front = project(cam.view_projection(1280, 720), P, 1280, 720)
    root = px[:, 0]
    mid = front.all(1) & (np.abs(root[:, 0] - 640) < 320) & (np.abs(root[:, 1] - 360) < 180)
    assert mid.sum() >= 8, mid.sum()
    tall = px[mid, :, 1].max(1) - px[mid, :, 1].min(1)
    assert tall.min() >= 30.0, np.sort(tall)[:5]
    # the old overview (the whole square) would not
    far = OrbitCamera()
    far.frame(w.environment.bounds(1.5), margin=0.85)
    pf, _ = project(far.view_projection(1280, 720), P, 1280, 720)
    assert np.median(pf[:, :, 1].max(1) - pf[:, :, 1].min(1)) < 30.0


@pytest.mark.slow
def test_after_5_seconds_most_people_have_had_goals_and_all_are_alive(default_graph):
    """The plaza with its 300 ambient people deciding over the first 2 s, the queue throttle
    lifted (so the result does not depend on how fast this machine plans): after 5 s most have
    been given a goal, the World has used plans, nobody is gone and nobody stands in anybody."""
    from authoring.commands.bake import load_sample
    from runtime.world import World
    sc, graph, env, roadmap = load_sample(PLAZA, log=lambda *a: None, progress=False)
    w = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=8.0, job_slice=30)
    w.apply_scenario(sc)
    life = w.add_scenario_ambient(sc, start_within=2.0, max_queue=1000, per_tick=10)
    for _ in range(150):
        w.tick()
    assert len(w.names) >= 300 + len(sc.characters)
    assert (life.goals_had > 0).mean() > 0.5, life.stats
    assert life.stats["strolls"] > 100 and w.stats["plans_done"] > 0, (life.stats, w.stats)
    xz = w.root_states()[:, :2]
    d = np.linalg.norm(xz[:, None] - xz[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    assert d.min() > 0.3


KEYS = r"""
import json, sys
import numpy as np
from runtime.viewer import headless, make_viewer
headless.configure(True)
from pyglet.window import key
from authoring.commands.bake import load_sample
from runtime.viewer.camera import project
from runtime.world import World
sc, graph, env, roadmap = load_sample(sys.argv[1], log=lambda *a: None, progress=False)
w = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=1e6)
w.apply_scenario(sc); w.add_scenario_flocks(sc); w.add_scenario_tiling(sc); w.add_scenario_ambient(sc)
v = make_viewer(w, headless=True, width=1280, height=720)
v.paused = True
info = v.run(max_frames=1)
P = info.joint_positions
px, front = project(info.view_projection, P, info.width, info.height)
out = {"size": [info.width, info.height], "view": v.view_name, "px": px.tolist(), "front": front.tolist(),
       "landmarks": {k: list(map(float, s)) for k, s in w.landmarks().items()}}
for name, k in (("tiled", key.T), ("flocks", key.B), ("follow", key.R), ("plaza", key.P)):
    v.on_key_press(k, 0)
    v.run(max_frames=1)
    out[name] = {"target": v.camera.target.tolist(), "distance": v.camera.distance, "follow": v.follow,
                 "selected": v.selected, "view": v.view_name,
                 "root": None if v.selected is None else P[v.selected, 0].tolist()}
v.close()
print(json.dumps(out))
"""


@pytest.mark.slow
@pytest.mark.display
def test_viewer_opening_view_and_view_keys_headless(default_graph):
    r = subprocess.run([sys.executable, "-c", KEYS, str(PLAZA)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["size"] == [1280, 720] and out["view"] == "plaza"
    px, front = np.array(out["px"]), np.array(out["front"])
    mid = front.all(1) & (np.abs(px[:, 0, 0] - 640) < 320) & (np.abs(px[:, 0, 1] - 360) < 180)
    tall = px[mid, :, 1].max(1) - px[mid, :, 1].min(1)
    assert mid.sum() >= 8 and tall.min() >= 30.0, np.sort(tall)[:5]
    lm = out["landmarks"]
    tx, _, tz, _ = lm["tiled"]
    assert np.allclose(np.array(out["tiled"]["target"])[[0, 2]], [tx, tz]) and out["tiled"]["view"] == "tiled"
    fx, fy, fz, _ = lm["flocks"]
    assert np.linalg.norm(np.array(out["flocks"]["target"]) - [fx, fy, fz]) < 1.0 and fy > 5.0
    fol = out["follow"]
    assert fol["follow"] and fol["selected"] is not None and fol["distance"] < 12.0
    assert np.linalg.norm(np.array(fol["target"])[[0, 2]] - np.array(fol["root"])[[0, 2]]) < 1.0
    px_, _, pz, _ = lm["plaza"]
    assert np.allclose(np.array(out["plaza"]["target"])[[0, 2]], [px_, pz]) and not out["plaza"]["follow"]


def test_gif_recorder_keeps_frames_at_its_rate_and_writes_an_animated_gif(tmp_path):
    from PIL import Image

    from runtime.viewer.record import GifRecorder
    rec = GifRecorder(tmp_path / "clip.gif", fps=10.0, width=64, max_frames=5)
    kept = 0
    for k in range(40):                      # frames drawn every 0.03 s for 1.2 s
        t = 0.03 * k
        if rec.due(t):
            img = np.zeros((36, 128, 3), np.uint8)
            img[:, (4 * k) % 128] = 255         # a moving bar
            rec.add(img, t)
            kept += 1
    assert kept == 5                          # 10 a second, up to max_frames
    rec.save()
    with Image.open(tmp_path / "clip.gif") as g:
        assert g.n_frames == 5 and g.size == (64, 18) and g.info["duration"] == 100
    with pytest.raises(ValueError, match="no frames"):
        GifRecorder(tmp_path / "empty.gif").save()


@pytest.mark.parametrize("slice_steps", [None, 5])
def test_planning_queue_round_robin_lets_short_jobs_pass_a_long_one(slice_steps):
    """With slice_steps a long job gives way to the ones waiting and resumes where it was;
    without, it runs to its end first. Every job finishes exactly once with its own result."""
    from types import SimpleNamespace

    from runtime.crowd.planner import Step
    from runtime.world.planning import PlanningQueue

    def job(name, n):
        for _ in range(n):
            yield Step.SEARCH
        return f"{name} after {n}"

    finished = []
    chars = {n: SimpleNamespace(name=n, job=None) for n in ("long", "a", "b")}
    q = PlanningQueue(1e6, ready=lambda c: True, start=lambda c: job(c.name, 200 if c.name == "long" else 3),
                      finish=lambda c, res: finished.append(res), failed=lambda *a: pytest.fail(str(a)),
                      slice_steps=slice_steps)
    for n in ("long", "a", "b"):
        q.push(chars[n])
    stats = {}
    while len(q):
        q.run(stats)
    assert sorted(finished) == ["a after 3", "b after 3", "long after 200"]
    assert finished[-1 if slice_steps else 0] == "long after 200"
    assert not q.suspended
