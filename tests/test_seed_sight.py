"""The seeds' line-of-sight test (``GreedySeed.in_sight``): the free-disc shortcut answers as the
exact segment test does."""
from types import SimpleNamespace

import numpy as np

from runtime.crowd.clearance import Clearance
from runtime.crowd.planner.seeds import GreedySeed
from test_environment import random_env


def test_in_sight_answers_as_the_exact_segment_test():
    env = random_env(3, n_poly=8, n_circ=5, extent=8.0)
    sdf = env.sdf(resolution=0.1, margin=2.0)
    seed = SimpleNamespace(collider=SimpleNamespace(static=Clearance(sdf, sdf.max_error)), env=env)
    rng = np.random.default_rng(0)
    a_all = rng.uniform(-10.0, 10.0, (400, 2))
    a_all = a_all[env.distance(a_all) > 0.6]
    shortcut = blocked = 0
    for a in a_all:
        pts = a + rng.normal(size=(8, 2)) * rng.uniform(0.3, 4.0)
        got = GreedySeed.in_sight(seed, a, pts, 0.55)
        exact = env.segment_clear(a[None], pts, 0.55)
        assert np.array_equal(got, exact)
        d0 = float(seed.collider.static(a[None])[0])
        shortcut += int((np.hypot(*(pts - a).T) + 0.55 <= d0).sum())
        blocked += int((~exact).sum())
    # both branches ran: moves inside the free disc, and moves the exact test blocks
    assert shortcut > 100 and blocked > 100
    # without a Clearance (any other static callable) every move takes the exact test
    plain = SimpleNamespace(collider=SimpleNamespace(static=lambda xz: np.full(len(xz), 99.0)), env=env)
    a = a_all[0]
    pts = a + rng.normal(size=(8, 2)) * 6.0
    assert np.array_equal(GreedySeed.in_sight(plain, a, pts, 0.55), env.segment_clear(a[None], pts, 0.55))


def test_a_backward_seed_tests_a_clip_where_it_plays_before_the_seed(default_graph):
    """A backward seed at C takes clips that end at C (played back from it): their collision
    samples lie on the way the clip came, not ahead of C, and end at C. An obstacle behind C
    makes the clip not clear, one ahead does not; planned characters count only with
    ``backward_moving``."""
    from dataclasses import replace
    from runtime.crowd.planner import MotionLibrary
    from runtime.crowd.planner import kernels
    from runtime.crowd.planner.collision import Collider
    from runtime.motion.planar import compose
    g = default_graph
    lib = MotionLibrary(g)
    e = int(np.argmax(np.hypot(lib.disp[:, 0], lib.disp[:, 1])))        # the longest clip
    C = np.array([0.0, 0.0, 0.3])
    start = compose(C[None], lib.disp_rev[e][None])[0]                     # where it starts
    middle = 0.5 * (start[:2] + C[:2])
    ahead = C[:2] - (middle - C[:2])                                       # mirrored through C

    def seed(collider, compiled):
        return GreedySeed(lib, collider.p, collider, None, compiled, int(g.edge_dst[e]), C, 300,
                          np.array([C[:2], C[:2] - 5.0]), None, int(g.edge_state[e]), None, True, 10.0)
    for disc, clear in ((middle, False), (ahead, True)):
        def static(xz, disc=disc):
            return np.hypot(xz[:, 0] - disc[0], xz[:, 1] - disc[1]) - 0.2

        def collide(f, xz, r, disc=disc):
            return np.hypot(xz[:, 0] - disc[0], xz[:, 1] - disc[1]) < r + 0.2
        for compiled in ((False, True) if kernels.AVAILABLE else (False,)):
            walls = Collider(lib, lib.params, static=static)
            assert bool(seed(walls, compiled).clear_here(np.array([e]), True)[0]) == clear
            people = Collider(lib, lib.params, collide=collide)
            assert bool(seed(people, compiled).clear_here(np.array([e]), True)[0])      # not counted
            people = Collider(lib, replace(lib.params, backward_moving=True), collide=collide)
            assert bool(seed(people, compiled).clear_here(np.array([e]), True)[0]) == clear
    if not kernels.AVAILABLE:
        return
    # the compiled gather's samples, placed from where the clip starts, end where it ends
    xz, _, frames, _ = kernels.edge_samples(lib, np.array([e]), start[None], np.array([300 - (lib.nframes[e] - 1)]),
                                            0.0)
    assert np.hypot(*(xz[-1] - C[:2])) < 0.1 and frames[-1] == 300
