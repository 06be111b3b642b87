"""Counter-based random numbers for flock walks.

A number is a hash (SplitMix64 finalizer, chained) of ``(seed, flock, counter, salt)``: every
flock's walk is reproducible and independent of the other flocks and of how many flocks share
a :class:`~runtime.flock.walk.FlockSystem`, and a draw does not depend on the tick size. The
``salt`` keeps the uses of one counter value apart (``SALT_*`` below).
"""
from __future__ import annotations

import random

import numpy as np

__all__ = ["uniform", "python_random", "SALT_RANDOM_WALK", "SALT_SEARCH", "SALT_RECOVERY",
           "SALT_START_NODE"]

SALT_RANDOM_WALK = 1     # the out-edge a free flock takes at a node
SALT_SEARCH = 3          # the look-ahead's edge order
SALT_RECOVERY = 5        # the random walks a recovery path is chosen from
SALT_START_NODE = 7      # the nodes a new flock may start at

_M64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def _splitmix(x: np.ndarray) -> np.ndarray:
    x = (x + np.uint64(0x9E3779B97F4A7C15)) & _M64
    x = ((x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)) & _M64
    x = ((x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)) & _M64
    return x ^ (x >> np.uint64(31))


def uniform(seed: int, flock, counter, salt=0) -> np.ndarray:
    """Deterministic uniforms in [0, 1) from (seed, flock, counter, salt), vectorized.

    Args:
        seed: the walk's seed.
        flock: flock index (or array of them).
        counter: the flock's stream position (uint64, or an array of them).
        salt: which use of the draw (``SALT_*``).
    """
    with np.errstate(over="ignore"):
        h = _splitmix(np.asarray(seed, dtype=np.uint64) ^ np.uint64(0x5851F42D4C957F2D))
        h = _splitmix(h ^ np.asarray(flock, dtype=np.uint64))
        h = _splitmix(h ^ np.asarray(counter, dtype=np.uint64))
        h = _splitmix(h ^ np.asarray(salt, dtype=np.uint64))
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


def python_random(seed: int, flock: int, counter, salt: int) -> random.Random:
    """A :class:`random.Random` seeded by one :func:`uniform` draw (53 bits), for the
    plain-Python look-ahead loops."""
    return random.Random(int(uniform(seed, flock, counter, salt) * 2.0 ** 53))
