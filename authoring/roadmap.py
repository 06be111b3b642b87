"""Building the probabilistic roadmap of a world (Sung, Kovar and Gleicher 2005, section 3.2; Kavraki & Latombe 1994).

Nodes are random free positions: uniform samples over the world's bounds (grown by
``connect_distance``) whose clearance exceeds the character ``radius`` (free space = outside
the obstacles grown by the radius), plus up to a fifth of them from the bridge test (Hsu et al.
2003: the midpoint of two nearby blocked samples, kept if free), which puts nodes into
doorways and corridors that uniform sampling misses. Edges join node pairs closer than
``connect_distance`` (``cKDTree.query_pairs``) whose segment keeps ``radius`` from every
obstacle (``Environment.segment_clear``, vectorized over all pairs). A pair is accepted
without the exact test when the end clearances alone prove it: a segment of length L whose
ends have clearances d_a, d_b keeps ``r`` from obstacles if ``d_a + d_b - L >= 2 r`` (the
distance is 1-Lipschitz). Finally, nodes of different connected components are tried
against their nearest neighbours up to twice ``connect_distance``, which joins components
split only by sparse sampling.

Everything random comes from ``numpy.random.default_rng(seed)``: the same environment and
parameters give the same roadmap, bit for bit.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from runtime.assets import AssetError
from runtime.crowd.environment import Environment
from runtime.crowd.roadmap import Roadmap

__all__ = ["build_roadmap", "load_or_build_roadmap", "NODES_PER_M2", "MIN_NODES", "WALK_RADIUS"]

WALK_RADIUS = 0.6         # obstacles grown by a walking character's bounding cylinder (the default
                          # library's walking frames: median 0.38 m, 99th percentile 0.58 m)

NODES_PER_M2 = 2.0       # auto sample count: two nodes per m^2 of free ground (docs/decisions.md)
MIN_NODES = 50
BRIDGE_FRACTION = 0.2    # share of nodes from the bridge test
_BATCH = 4096


def _free_area(env: Environment, box, rng) -> float:
    """Monte-Carlo estimate (4096 samples) of the free ground area of ``box``."""
    x0, z0, x1, z1 = box
    p = rng.uniform((x0, z0), (x1, z1), size=(_BATCH, 2))
    return float(np.mean(env.distance(p) > 0)) * (x1 - x0) * (z1 - z0)


def _sample_nodes(env, box, n, radius, rng, progress):
    """``n`` free nodes: up to BRIDGE_FRACTION of them from the bridge test (bounded effort),
    the rest uniform."""
    x0, z0, x1, z1 = box
    n_bridge = int(round(BRIDGE_FRACTION * n)) if env.num_obstacles else 0
    out, got, tries = [], 0, 0
    sigma = max(2.0 * radius, 0.25)

    def keep(points):
        nonlocal got
        out.append(points)
        got += len(points)
        if progress:
            progress("sampling", got, n)

    while got < n_bridge and tries < 8:  # bridge samples are rare in open worlds: bounded effort
        a = rng.uniform((x0, z0), (x1, z1), size=(_BATCH, 2))
        b = a + rng.normal(scale=sigma, size=(_BATCH, 2))
        m = 0.5 * (a + b)
        da, db = env.distance(a) <= radius, env.distance(b) <= radius
        cand = m[da & db]
        keep(cand[env.distance(cand) > radius][: n_bridge - got])
        tries += 1
    tries = 0
    while got < n:
        p = rng.uniform((x0, z0), (x1, z1), size=(_BATCH, 2))
        keep(p[env.distance(p) > radius][: n - got])
        tries += 1
        if tries > 200 and got < 0.01 * tries * _BATCH:
            raise ValueError(f"almost no free space for a character of radius {radius} m in the world's bounds")
    return np.concatenate(out) if out else np.zeros((0, 2))


def _connect(env, nodes, clearance, pairs, radius, progress, stage):
    """Keep the pairs whose segment is clear (clearance shortcut, then the exact test)."""
    if len(pairs) == 0:
        return pairs
    a, b = nodes[pairs[:, 0]], nodes[pairs[:, 1]]
    L = np.hypot(*(b - a).T)
    sure = clearance[pairs[:, 0]] + clearance[pairs[:, 1]] - L >= 2 * radius
    ok = sure.copy()
    todo = np.flatnonzero(~sure)
    step = 8192
    for s in range(0, len(todo), step):
        k = todo[s:s + step]
        ok[k] = env.segment_clear(a[k], b[k], radius)
        if progress:
            progress(stage, min(s + step, len(todo)), len(todo))
    return pairs[ok]


def _csr(M, pairs, nodes):
    rows = np.concatenate([pairs[:, 0], pairs[:, 1]])
    cols = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.argsort(rows * M + cols, kind="stable")     # by row, then column (pairs are unique)
    rows, cols = rows[order], cols[order]
    indptr = np.zeros(M + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=M), out=indptr[1:])
    w = np.hypot(*(nodes[rows] - nodes[cols]).T)
    return indptr, cols.astype(np.int64), w


def build_roadmap(env: Environment, radius: float = WALK_RADIUS, n_samples: int | None = None,
                  connect_distance: float = 3.0, seed: int = 0, progress=None) -> Roadmap:
    """PRM of ``env``'s free space for a character of ``radius`` metres (see module docstring).

    ``n_samples`` defaults to ``max(MIN_NODES, NODES_PER_M2 * free area)``. ``progress``, if
    given, is called as ``progress(stage, done, total)`` with stage "sampling", "connecting"
    or "joining components". Deterministic for a seed.
    """
    from scipy.spatial import cKDTree

    if not radius >= 0:
        raise ValueError(f"radius must be >= 0, got {radius}")
    if not connect_distance > 0:
        raise ValueError(f"connect_distance must be > 0, got {connect_distance}")
    rng = np.random.default_rng(seed)
    box = env.bounds(margin=max(connect_distance, 2 * radius))
    if box[2] - box[0] < 2 * connect_distance or box[3] - box[1] < 2 * connect_distance:
        cx, cz = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
        h = max(connect_distance, 0.5 * (box[2] - box[0]), 0.5 * (box[3] - box[1]))
        box = (cx - h, cz - h, cx + h, cz + h)
    area = _free_area(env, box, rng)
    if n_samples is None:
        n_samples = max(MIN_NODES, int(math.ceil(NODES_PER_M2 * area)))
    n_samples = int(n_samples)
    if n_samples < 2:
        raise ValueError(f"n_samples must be >= 2, got {n_samples}")
    nodes = _sample_nodes(env, box, n_samples, radius, rng, progress)
    M = len(nodes)
    clearance = env.distance(nodes)  # > radius; +inf on open ground
    clearance = np.where(np.isfinite(clearance), clearance, 1e30)
    tree = cKDTree(nodes)
    pairs = tree.query_pairs(connect_distance, output_type="ndarray").astype(np.int64)
    pairs = np.sort(pairs, axis=1)
    pairs = pairs[np.argsort(pairs[:, 0] * M + pairs[:, 1], kind="stable")]
    edges = _connect(env, nodes, clearance, pairs, radius, progress, "connecting")

    # join components that sparse sampling left apart
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    ncomp, comp = connected_components(coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(M, M)),
                                       directed=False)
    if ncomp > 1:
        k = min(12, M)
        d, nb = tree.query(nodes, k=k, distance_upper_bound=2 * connect_distance)
        i = np.repeat(np.arange(M), k)
        j = nb.reshape(-1)
        valid = (j < M) & np.isfinite(d.reshape(-1))
        i, j = i[valid], j[valid]
        cross = comp[i] != comp[j]
        extra = np.sort(np.stack([i[cross], j[cross]], axis=1), axis=1)
        if len(extra):
            extra = np.unique(extra, axis=0)
            extra = _connect(env, nodes, clearance, extra, radius, progress, "joining components")
            edges = np.unique(np.concatenate([edges, extra]), axis=0)
    indptr, indices, weights = _csr(M, edges, nodes)
    meta = {"seed": int(seed), "n_samples": int(n_samples), "bounds": [float(v) for v in box],
            "free_area_m2": round(area, 3)}
    return Roadmap(nodes, indptr, indices, weights, radius, connect_distance, env.fingerprint(), meta)


def load_or_build_roadmap(world_path, cache_dir, radius: float = WALK_RADIUS, seed: int = 0,
                          connect_distance: float = 3.0, n_samples: int | None = None,
                          progress=None, env: Environment | None = None) -> Roadmap:
    """The roadmap of a world, from ``cache_dir`` if a pack for the same obstacles (environment
    fingerprint) and parameters is there, else built and cached (written atomically).

    ``world_path`` is a world USD stage, or an :class:`Environment` directly (then ``env`` is
    ignored); pass ``env`` to avoid reading the stage twice. A corrupt or stale cache file is
    rebuilt, never trusted."""
    if isinstance(world_path, Environment):
        env = world_path
    elif env is None:
        from usd_io.world import read_world
        env = read_world(world_path)
    fp = env.fingerprint()
    n = f"auto{NODES_PER_M2:g}" if n_samples is None else str(int(n_samples))
    name = f"roadmap-{fp[:16]}-r{radius:g}-c{connect_distance:g}-n{n}-s{int(seed)}.cwpack"
    path = Path(cache_dir) / name
    if path.is_file():
        try:
            rm = Roadmap.load(path)
            if rm.matches(env) and rm.radius == float(radius) and rm.connect_distance == float(connect_distance):
                return rm
        except AssetError:
            pass
    rm = build_roadmap(env, radius=radius, n_samples=n_samples, connect_distance=connect_distance, seed=seed,
                       progress=progress)
    rm.save(path)
    return rm
