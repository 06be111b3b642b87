"""Starting a scenario's flocks and tiling zones: shared by the World and the offline bake.

A scenario (:mod:`runtime.crowd.scenario`) names flocks (``[[flock]]``, Lai, Chenney and Fan
2005) and interactive tiling zones (``[[tiling]]``, Kim, Hwang, Hyun and Lee 2012). These
functions turn the entries into the runtime objects that step them, given the world's
environment; the World registers them as systems, and ``crowdweave bake`` steps them for the
whole scenario without a World.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["flock_region", "spread_in_region", "scenario_flock_starts", "scenario_tiling_zones"]


def flock_region(env, spec):
    """The region a ``[[flock]]`` entry is kept in: its ``region`` marker's outline as a
    polygon, or, with ``altitude``, the outline's bounding box between the two heights (3D
    flocks); None without a region."""
    from ..flock import Box, Polygon
    if spec.region is None:
        return None
    poly = env.markers[spec.region].polygon
    if spec.altitude is not None:
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        return Box([lo[0], spec.altitude[0], lo[1]], [hi[0], spec.altitude[1], hi[1]])
    return Polygon(poly)


def spread_in_region(region, k: int, height: float = 0.0, seed: int = 0) -> np.ndarray:
    """``k`` start points well inside a region, far apart (deepest grid points, then farthest
    point sampling); deterministic."""
    if region is None:
        a = np.linspace(0, 2 * math.pi, k, endpoint=False)
        return np.stack([15 * np.sin(a), np.full(k, height), 15 * np.cos(a)], axis=1)
    if hasattr(region, "vertices"):          # polygon (2D flocks walk at ``height``)
        lo, hi = region.vertices.min(axis=0), region.vertices.max(axis=0)
        y = height
    else:                                    # box (3D flocks start at mid altitude)
        lo, hi = region.lo[[0, 2]], region.hi[[0, 2]]
        y = 0.5 * (region.lo[1] + region.hi[1])
    X, Z = np.meshgrid(np.linspace(lo[0], hi[0], 40), np.linspace(lo[1], hi[1], 40))
    pts = np.stack([X.ravel(), np.full(X.size, y), Z.ravel()], axis=1)
    depth = region.depth(pts)
    ok = depth > np.percentile(depth[depth > 0], 60) if np.any(depth > 0) else depth > -np.inf
    cand = pts[ok]
    chosen = [int(np.argmax(region.depth(cand)))]
    d = np.hypot(cand[:, 0] - cand[chosen[0], 0], cand[:, 2] - cand[chosen[0], 2])
    while len(chosen) < k:
        i = int(np.argmax(d))
        chosen.append(i)
        d = np.minimum(d, np.hypot(cand[:, 0] - cand[i, 0], cand[:, 2] - cand[i, 2]))
    return cand[chosen]


def scenario_flock_starts(sc, env):
    """Per ``[[flock]]`` entry (its DDG resolved into ``spec.loaded`` by the caller): (spec,
    DDG, centroid positions (k, 3), headings (k,), regions (k,))."""
    out = []
    for spec in sc.flocks:
        ddg = spec.loaded
        region = flock_region(env, spec)
        if spec.positions is not None:
            pos = np.asarray(spec.positions, dtype=np.float64).reshape(-1, 3)
        else:
            pos = spread_in_region(region, spec.count, 25.0 if ddg.dim == 3 else 0.0, seed=spec.seed)
        headings = np.linspace(0.0, 2 * math.pi, len(pos), endpoint=False)
        out.append((spec, ddg, pos, headings, [region] * len(pos)))
    return out


def scenario_tiling_zones(sc, graph, env, start_time: float, libraries: dict | None = None) -> list:
    """The ``[[tiling]]`` zones of a scenario as :class:`~runtime.tiling.zone.TilingZone`s.
    ``libraries`` maps a spec's ``patches`` to a :class:`~runtime.tiling.patch.PatchLibrary`;
    ``"synthetic"`` (the default) is built from ``graph``
    (:func:`runtime.tiling.synthetic.synthetic_library`)."""
    from ..tiling.patch import PatchLibrary
    from ..tiling.synthetic import synthetic_library
    from ..tiling.zone import TilingZone, environment_obstacles
    libraries = dict(libraries or {})
    zones = []
    for spec in sc.tilings:
        lib = libraries.get(spec.patches)
        if lib is None:
            lib = synthetic_library(graph, meets=4) if spec.patches == "synthetic" else PatchLibrary.load(spec.patches)
            libraries[spec.patches] = lib
        zones.append(TilingZone(spec.name, lib, spec.bounds, spec.teams, period=spec.period, horizon=spec.horizon,
                                seed=spec.seed, obstacles=environment_obstacles(env, spec.bounds),
                                start_time=start_time))
    return zones
