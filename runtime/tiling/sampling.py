"""Algorithm 1 of Kim, Hwang, Hyun and Lee 2012 (section 5.1): stochastic sampling of patch
instances, accepted by simulated annealing on the tiling energy Eq. 6.

Each sample draws a patch and a placement -- uniform in the region with probability from the
preference function Eq. 7 times a size bias, so larger patches come first; or (with
``anchor_prob``) a patch with a matching port, by Eq. 7 without the size bias, aligned to a
random dangling port -- stitches it to every dangling port its own ports match within
``match_*``, and accepts it with probability ``exp(-dE / kT)`` followed by ``IsValid``; ``T``
falls by ``dT`` per sample from ``T_max``; the phase stops after ``i_max`` samples in a row
without an acceptance. ``seeds`` caps the number of free (unanchored) placements, which is how a
density is asked for.
"""
from __future__ import annotations

import math
import time as _time

import numpy as np

from .state import tiling_energy

__all__ = ["sample_tiling"]


def _random_place(til, p):
    """A placement of patch ``p`` uniform in the region, kept with probability Eq. 7 (at most
    20 draws; the last one otherwise)."""
    pp = til.lib.patches[p]
    reg = til.region
    best = None
    for _ in range(20):
        x = til.rng.uniform(reg.x0, reg.x1)
        z = til.rng.uniform(reg.z0, reg.z1)
        th = til.rng.uniform(-np.pi, np.pi)
        t = til.rng.uniform(reg.t0 - 0.5 * pp.t_end, reg.t1 - 0.5 * pp.t_end)
        best = (x, z, th, t)
        lf = til.pref.place_log(np.array([x, z]), th, t + 0.5 * pp.t_end)
        if til.rng.random() < math.exp(float(lf)):
            break
    return best


def _anchored_candidate(til):
    """A patch hung on a random dangling port (None if nothing can be)."""
    D = til.dang
    live = np.flatnonzero(D.live[:D.n] & (D.rows[:D.n, 9] > 0) & (D.rows[:D.n, 8] > 0))
    if len(live) == 0:
        return None
    row_i = int(live[til.rng.integers(len(live))])
    key = D.key[row_i]
    row, ports = til.ports_matching(key)
    if ports is None or len(ports) == 0:
        return None
    # Eq. 7 as the sampling distribution: label weights times the preference of each
    # placement (no size bias here: a large patch hung on one port adds many danglings)
    logw = np.log(np.maximum(til.anchor_weights[ports[:, 0]], 1e-300))
    if til.pref.places:
        pl = np.array([til.lib.patches[int(p)].align(int(j), row) for p, j in ports])
        tc = pl[:, 3] + np.array([0.5 * til.lib.patches[int(p)].t_end for p in ports[:, 0]])
        logw = logw + til.pref.place_log(pl[:, :2], pl[:, 2], tc)
    w = np.exp(logw - logw.max())
    k = int(til.rng.choice(len(ports), p=w / w.sum()))
    p, j = int(ports[k, 0]), int(ports[k, 1])
    return til.evaluate(p, til.lib.patches[p].align(j, row), forced=[(j, key)])


def _free_candidate(til):
    """A patch drawn by size and label weight, placed by :func:`_random_place`."""
    w = til.weights / til.weights.sum()
    p = int(til.rng.choice(len(w), p=w))
    return til.evaluate(p, _random_place(til, p))


def _accepts(til, cand, T) -> bool:
    """The annealing test on the energy change Eq. 6 (one random draw when uphill)."""
    cfg = til.cfg
    nd = til.num_danglings
    e0 = tiling_energy(til.nc, nd, cfg.alpha)
    e1 = tiling_energy(til.nc + cand.d_connected, nd + cand.d_danglings, cfg.alpha)
    de = e1 - e0
    if de <= 0:
        return True
    if T > 0:
        return math.exp(-de / (cfg.k * T)) > til.rng.random()
    return False


def sample_tiling(til, max_seconds: float | None = None, max_patches: int | None = None) -> dict:
    """Run Algorithm 1 on the :class:`~runtime.tiling.tiler.Tiler` ``til`` (a tiling state with
    patch ``weights``, ``anchor_weights`` and a ``free_placements`` count). Stops early after
    ``max_seconds`` of wall clock or at ``max_patches`` instances. Returns its figures
    (samples, accepted, patches, danglings, seconds)."""
    cfg = til.cfg
    t_start = _time.perf_counter()
    T = cfg.T_max
    i = 0
    tried = accepted = 0
    while i < cfg.i_max:
        if max_seconds is not None and _time.perf_counter() - t_start > max_seconds:
            break
        if max_patches is not None and len(til.inst) >= max_patches:
            break
        free_ok = cfg.seeds is None or til.free_placements < cfg.seeds
        anchored = (not free_ok) or (til.num_danglings > 0 and til.rng.random() < cfg.anchor_prob)
        cand = _anchored_candidate(til) if anchored else _free_candidate(til)
        tried += 1
        if cand is not None and _accepts(til, cand, T) and til.valid(cand):
            til.commit(cand)
            accepted += 1
            if not anchored:
                til.free_placements += 1
            i = 0
        T -= cfg.dT
        i += 1
    til.timing["phase1"] += _time.perf_counter() - t_start
    return {"samples": tried, "accepted": accepted, "patches": len(til.inst), "danglings": til.num_danglings,
            "seconds": _time.perf_counter() - t_start}
