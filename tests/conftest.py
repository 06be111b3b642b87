import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
CMU_DIR = SHARED / "mocap" / "cmu"


@pytest.fixture
def cmu_dir():
    if not CMU_DIR.is_dir():
        pytest.skip(f"CMU motion capture not found at {CMU_DIR} (../shared/mocap/cmu beside the project)")
    return CMU_DIR


def random_skeleton(rng, n=12):
    from runtime.motion import Skeleton
    parents = [-1] + [int(rng.integers(0, i)) for i in range(1, n)]
    names = [f"j{i}" for i in range(n)]
    return Skeleton(names, np.array(parents), rng.normal(size=(n, 3)) * 0.2)


def random_clip(rng, frames=40, n=12, fps=30.0, smooth=True):
    from runtime.motion import Clip, quat
    sk = random_skeleton(rng, n)
    if smooth:
        t = np.linspace(0, 1, frames)[:, None, None]
        axes = rng.normal(size=(1, n, 3))
        ang = rng.uniform(-1.5, 1.5, size=(1, n, 1)) * np.sin(2 * np.pi * t + rng.uniform(0, 6, (1, n, 1)))
        rots = quat.exp(axes / np.linalg.norm(axes, axis=-1, keepdims=True) * ang)
        pos = np.cumsum(rng.normal(size=(frames, 3)) * 0.02, axis=0) + [0.0, 1.0, 0.0]
    else:
        rots = quat.normalize(rng.normal(size=(frames, n, 4)))
        pos = rng.normal(size=(frames, 3))
    return Clip.from_world(sk, fps, pos, rots)


@pytest.fixture(scope="session")
def default_graph():
    """The default motion library (built on first use into CROWDWEAVE_CACHE or ~/.cache)."""
    from authoring.default_library import ensure_library
    from runtime.motion.graph import MotionGraph
    return MotionGraph.load(ensure_library("default", log=lambda *a: None, progress=False))


@pytest.fixture(scope="session")
def random_pairs(default_graph):
    """``make(rng, P, L)``: P random motion pairs of the default library for the search's static
    filter -- forward rows walking from the first clip's node, backward rows from random nodes,
    right-aligned in L columns -- and their cuts: (F, B, i, j)."""
    g = default_graph

    def make(rng, P: int, L: int):
        F = -np.ones((P, L), np.int64)
        B = -np.ones((P, L), np.int64)
        nf, nb = rng.integers(1, L - 2, P), rng.integers(1, L - 2, P)
        for p in range(P):
            F[p, :nf[p]] = g.random_walk(int(g.edge_src[0]), nf[p], rng)
            B[p, L - nb[p]:] = g.random_walk(int(rng.integers(g.num_nodes)), nb[p], rng)
        i = np.array([rng.integers(0, n + 1) for n in nf])
        j = np.array([rng.integers(L - n, L + 1) for n in nb])
        return F, B, i, j
    return make
