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
