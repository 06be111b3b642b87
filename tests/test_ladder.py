"""Never write a colliding motion: the space-time route, the ladder of alternatives, the World.

What is asserted comes from the independent checker (overlaps, windows, eps) and from direct
geometric tests of the tracks, not from the planner's own flags."""
import numpy as np
import pytest

from runtime.crowd.checker import check_crowd, overlapping_pairs
from runtime.crowd.planner.route import ROOMY, SLICE, STEP, timed_route, timed_route_steps
from runtime.crowd.reservations import Reservations
from runtime.crowd.scenario import parse_scenario
from runtime.crowd.scheduler import plan_scenario
from runtime.motion.cylinders import blend_cylinders


def _walkers(n=5, frames=600):
    """A line of ``n`` characters walking along +x across z = 5."""
    idx = Reservations(1.6, 1500)
    f = np.arange(frames)
    for o in range(n):
        idx.insert(o, f, np.stack([-6 + f * 0.02 + o * 1.2, np.full(frames, 5.0)], 1), np.full(frames, 0.4))
    return idx


def _sample(pts, frames):
    """The route walked straight between its way points at their frames, one sample a frame."""
    xs = [np.linspace(pts[i], pts[i + 1], frames[i + 1] - frames[i], endpoint=False) for i in range(len(pts) - 1)]
    xz = np.concatenate(xs + [pts[-1:]])
    return frames[0] + np.arange(len(xz)), xz


def test_timed_route_keeps_clear_of_planned_characters():
    idx = _walkers()
    straight = np.array([[0.0, 0.0], [0.0, 10.0]])
    # the straight walk at 1.2 m/s runs into the line of walkers
    f = np.arange(0, 250)
    walk = np.stack([np.zeros(len(f)), np.minimum(f / 30 * 1.2, 10.0)], 1)
    assert idx.overlaps(f, walk, np.full(len(f), 0.4)).any()
    pts, frames, delay, _ = timed_route(straight, 0, idx.at_frame, None, 0.52, 1200)
    assert np.allclose(pts[0], [0, 0]) and np.allclose(pts[-1], [0, 10])
    ff, xz = _sample(pts, frames)
    assert not idx.overlaps(ff, xz, np.full(len(ff), 0.4)).any()
    speeds = np.hypot(*np.diff(xz, axis=0).T) * 30
    assert speeds.max() < 1.7                     # a walk, not a dash
    # nobody in the way: the route is the straight line, leaving at once
    empty = Reservations(1.6, 1500)
    pts2, frames2, delay2, _ = timed_route(straight, 0, empty.at_frame, None, 0.52, 1200)
    assert delay2 == 0 and len(pts2) == 2 and frames2[-1] <= 10 / 1.0 * 30


def test_timed_route_keeps_room_from_obstacles_where_it_can():
    """A post 0.6 m beside the straight line (clear for the walking disc, but tight): the route
    bends round it with ROOMY more clearance, arriving no later; with no roomy way within
    ROOMY_WAIT steps (a wall with a gap 0.6 m either side of the line) it goes through the tight cells."""
    empty = Reservations(1.6, 1500)
    straight = np.array([[0.0, 0.0], [0.0, 10.0]])
    post = np.array([0.9, 5.0])

    def one_post(p):
        return np.hypot(*(np.asarray(p) - post).T) - 0.3
    pts, frames, _, _ = timed_route(straight, 0, empty.at_frame, one_post, 0.52, 1200)
    _, walk = _sample(pts, frames)
    assert one_post(walk).min() >= 0.52 + ROOMY - 0.05
    assert frames[-1] == timed_route(straight, 0, empty.at_frame, None, 0.52, 1200)[1][-1]

    def gap(p):                 # a wall across the way, with a gap 0.6 m either side of the line
        p = np.asarray(p, dtype=np.float64)
        x = np.abs(p[:, 0])
        along = np.maximum(0.9 - x, 0.0) + np.maximum(x - 6.0, 0.0)
        return np.hypot(along, p[:, 1] - 5.0) - 0.3
    pts, frames, _, _ = timed_route(straight, 0, empty.at_frame, gap, 0.52, 1200)
    _, walk = _sample(pts, frames)
    assert 0.52 - 0.05 <= gap(walk).min() < 0.52 + ROOMY


def test_timed_route_gives_up_when_the_goal_stays_taken():
    idx = Reservations(1.6, 1500)
    f = np.arange(1500)
    idx.insert(0, f, np.broadcast_to([0.0, 10.0], (1500, 2)), np.full(1500, 0.4))
    assert timed_route(np.array([[0.0, 0.0], [0.0, 10.0]]), 0, idx.at_frame, None, 0.52, 1200) is None


def test_timed_route_is_time_sliced():
    """The route search yields every SLICE time steps of its wavefront (so the World can spread
    it over ticks) and returns what the whole search returns; a search that never reaches the
    goal yields as many times as its time steps allow."""
    idx = _walkers()
    straight = np.array([[0.0, 0.0], [0.0, 10.0]])
    steps = timed_route_steps(straight, 0, idx.at_frame, None, 0.52, 1200)
    yields = 0
    while True:
        try:
            next(steps)
            yields += 1
        except StopIteration as stop:
            sliced = stop.value
            break
    whole = timed_route(straight, 0, idx.at_frame, None, 0.52, 1200)
    assert all(np.array_equal(a, b) for a, b in zip(sliced[:2], whole[:2])) and sliced[2] == whole[2]
    assert yields == whole[1][-1] // STEP // SLICE
    taken = Reservations(1.6, 1500)
    taken.insert(0, np.arange(1500), np.broadcast_to([0.0, 10.0], (1500, 2)), np.full(1500, 0.4))
    steps = timed_route_steps(straight, 0, taken.at_frame, None, 0.52, 1200)
    assert sum(1 for _ in steps) == (1200 // STEP) // SLICE


def _blocked_goal_scenario():
    """c0 walks to (0, 6) and stands there to the end; c1, planned after it, must go to the
    same spot: no clean plan exists for c1."""
    return parse_scenario({"name": "blocked", "duration": 14.0, "seed": 0, "synthesis": {"passes": 1},
                           "character": [
                               {"name": "c0", "start": {"position": [0.0, 0.0], "heading": 0.0, "pose": "stand"},
                                "goal": [{"position": [0.0, 6.0]}]},
                               {"name": "c1", "start": {"position": [4.0, 3.0], "heading": -90.0, "pose": "stand"},
                                "goal": [{"position": [0.3, 6.0], "time": [6.0, 7.0]}]}]})


@pytest.mark.slow
def test_a_goal_that_cannot_be_reached_clear_of_everyone_is_given_up_not_walked_into(default_graph):
    sc = _blocked_goal_scenario()
    res = plan_scenario(sc, default_graph)
    c0, c1 = res.characters
    assert not c0.warnings
    assert c1.warnings and c1.ladder and c1.ladder[-1].kind == "waiting"
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph)
    assert rep.summary()["character_overlap_pairs"] == 0, rep.character_overlaps
    # c1 stands where it started, the whole time
    assert np.hypot(*(c1.track.root[:, :2] - [4.0, 3.0]).T).max() < 0.3
    # and the checker sees the goal was not met: nothing is hidden
    assert not rep.summary()["passed"]


@pytest.mark.slow
def test_the_world_never_plays_a_colliding_plan(default_graph):
    """Live: a character sent onto a spot where another stands waits clear of everyone, with a
    warning saying why; the recorded frames overlap nobody."""
    from runtime.world import World
    w = World(default_graph, seed=3, budget_ms=1e6)
    w.spawn("stays", (0.0, 5.0), heading=0.0)
    w.spawn("goes", (4.0, 0.0), heading=0.0)
    warnings = []
    w.on("warning", warnings.append)
    w.go_to("goes", (0.2, 5.0))
    g = default_graph
    xz, rad = [], []
    for _ in range(30 * 12):
        w.tick()
        s, a, b, t, root = w.playback.gather(0)
        cxz, r = blend_cylinders(g, a, b, root)
        xz.append(cxz)
        rad.append(r)
    assert overlapping_pairs(np.array(xz), np.array(rad, dtype=np.float64)) == {}
    assert any(e.character == "goes" for e in warnings), [e.data for e in warnings]
    msg = next(e.data["message"] for e in warnings if e.character == "goes")
    assert "clear of everyone" in msg


def test_held_starts_give_way_to_a_swap_of_places(default_graph, monkeypatch):
    """Starts are held until their characters are planned (reserve_starts "all"), but not
    against a character whose goal is that start: two characters swapping places both arrive,
    clean and clear of each other in one pass; holding every start blindly, the first one does
    not arrive within the scenario."""
    from runtime.crowd.planner import CrowdPolicy
    from runtime.crowd.scheduler import goal_holds
    sc = parse_scenario({"name": "swap", "duration": 20.0, "seed": 0, "synthesis": {"passes": 1}, "character": [
        {"name": "a", "start": {"position": [0.0, 0.0], "heading": 90.0}, "goal": [{"position": [6.0, 0.0]}]},
        {"name": "b", "start": {"position": [6.0, 0.0], "heading": -90.0}, "goal": [{"position": [0.0, 0.0]}]}]})
    res = plan_scenario(sc, default_graph, policy=CrowdPolicy(reserve_starts="all"))
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph)
    assert rep.passed and not rep.character_overlaps
    assert all(not c.ladder or c.ladder[0].keeps_constraints for c in res.characters)
    # the same with every start held blindly: the first one planned cannot arrive within the
    # scenario (a repair pass would plan it again once the other has left)
    import runtime.crowd.scheduler as scheduler
    monkeypatch.setattr(scheduler, "goal_holds", lambda ctx, ci, holds: [])
    blind = plan_scenario(sc, default_graph, policy=CrowdPolicy(reserve_starts="all"))
    assert blind.characters[0].warnings
    monkeypatch.undo()

    class Ctx:        # what goal_holds reads
        pass
    ctx = Ctx()
    ctx.sc, ctx.lib, ctx.params = sc, type("L", (), {"max_radius": 0.5, "max_reach": 0.5})(), type("P", (), {"margin": 0.02})()
    far = {1: (np.array([6.0, 0.0]), 0.4, 100), 2: (np.array([3.0, 3.0]), 0.4, 100)}
    assert goal_holds(ctx, 0, far) == [1]


def test_a_seed_keeps_to_the_timing_of_its_route(default_graph):
    """A route that waits 3 s where it starts, then walks 6 m in 6 s (5 m along at frame 240):
    the seed keeping to it stands until the route moves on and is 5 m along no more than its
    1 s lead ahead of the route; without the timing it sets off at once and is there sooner."""
    from runtime.crowd.planner import MotionLibrary, SegmentPlanner, run_to_completion
    from runtime.motion.graph import STATES
    from runtime.motion.planar import compose1
    g = default_graph
    lib = MotionLibrary(g)
    walking = STATES.index("walking")
    loops = np.flatnonzero((g.edge_src == g.edge_dst) & (np.hypot(g.edge_disp[:, 0], g.edge_disp[:, 1]) < 0.1))
    node = int(np.bincount(g.edge_src[loops]).argmax())          # a node with idle clips
    planner = SegmentPlanner(lib)
    wps = np.array([[0.0, 0.0], [0.0, 6.0]])

    def walk(schedule):
        """(frame the seed is first 0.5 m from the start, frame it is first 5 m along)."""
        s = planner.seed(node, np.zeros(3), 0, wps, None, walking, None, False, schedule=schedule)
        edges, _ = run_to_completion(s.steps())
        cfg, f, leave, far = np.zeros(3), 0, None, None
        for e in edges:
            cfg = compose1(cfg, lib.disp[e])
            f += int(lib.nframes[e]) - 1
            if leave is None and np.hypot(cfg[0], cfg[1]) > 0.5:
                leave = f
            if far is None and cfg[1] > 5.0:
                far = f
        return leave, far

    route = (np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 6.0]]), np.array([0, 90, 270]))
    leave, far = walk(route)
    leave0, far0 = walk(None)
    assert leave0 < 45 and leave >= 75
    assert far is not None and far >= 220 > far0
