"""Algorithm 2 of Kim, Hwang, Hyun and Lee 2012 (section 5.2): deterministic search that closes
the dangling ports left by Algorithm 1, with jitter.

For each dangling port ``d`` every library port that matches it (opposite kind, same pose
class) is tried in the order of the preference function (stitches that also close other
danglings first); a candidate that would increase the number of danglings is skipped (line 5);
an invalid one is jittered up to ``jitter_tries`` times with a range growing from
``jitter_min`` to ``jitter_max`` (line 11); if nothing fits, the instance owning ``d`` is
removed (line 16) and its patch is recorded in the sampling history of the ports it was
stitched to, so it is not chosen there again. A keyframe is never removed: the instances that
block the best stitch at its port are removed instead.
"""
from __future__ import annotations

import math
import time as _time

import numpy as np

__all__ = ["close_danglings"]


def _jitter(til, place, i, n):
    """Try ``i`` of ``n``: the placement moved within a range growing linearly from
    ``jitter_min`` to ``jitter_max`` (metres, degrees, seconds)."""
    cfg = til.cfg
    a = i / max(n - 1, 1)
    r_max = cfg.jitter_min[0] + a * (cfg.jitter_max[0] - cfg.jitter_min[0])
    ang = math.radians(cfg.jitter_min[1] + a * (cfg.jitter_max[1] - cfg.jitter_min[1]))
    tm = cfg.jitter_min[2] + a * (cfg.jitter_max[2] - cfg.jitter_min[2])
    rr = r_max * math.sqrt(til.rng.random())
    phi = til.rng.uniform(-np.pi, np.pi)
    x, z, th, t = place
    return (x + rr * math.cos(phi), z + rr * math.sin(phi), th + til.rng.uniform(-ang, ang),
            t + til.rng.uniform(-tm, tm))


def _ordered_candidates(til, key):
    """The stitches at dangling ``key`` to try, best first: (delta N, -log F, patch, port,
    placement, stitch plan), at most ``max_candidates``."""
    row, ports = til.ports_matching(key)
    if ports is None:
        return []
    hist = til.history.get(key, set())
    out = []
    for p, j in ports:
        p, j = int(p), int(j)
        if p in hist:
            continue
        pp = til.lib.patches[p]
        place = pp.align(j, row)
        ppos, pdir, ptime = til.place_ports(p, place)
        centre = np.array(place[:2]) if til.pref.at == "centre" else ppos[pp.port_kind == 1].mean(0)
        lf = float(til.pref.place_log(centre, place[2], place[3] + 0.5 * pp.t_end))
        lf += math.log(max(til.weights[p], 1e-300)) if til.pref.label_cost else 0.0
        out.append((lf + 1e-3 * til.rng.random(), p, j, place))
    # delta-N from the stitch plan: closing stitches first, growing ones dropped (line 5)
    scored = []
    for lf, p, j, place in out:
        plan = til.plan(p, place, forced=[(j, key)])
        if plan[1] > 0:
            continue
        scored.append((plan[1], -lf, p, j, place, plan))
    scored.sort(key=lambda s: (s[0], s[1]))
    return scored[:til.cfg.max_candidates]


def _blockers(til, key) -> list:
    """Non-keyframe instances overlapping the preferred exact stitch at dangling ``key``."""
    row, ports = til.ports_matching(key)
    if ports is None:
        return []
    best = None
    for p, j in ports:
        p, j = int(p), int(j)
        if til.lib.patches[p].K != 1:
            continue
        cand = til.evaluate(p, til.lib.patches[p].align(j, row), forced=[(j, key)], match_others=False)
        if not cand.limits_ok:
            continue
        owners = sorted(o for o in til.occupancy.owners_hit(cand) if o != key[0])
        if any(til.inst[o].fixed for o in owners):
            continue
        if best is None or len(owners) < len(best):
            best = owners
    return best or []


def _fix(til, key):
    """Lines 3-12 of Algorithm 2 for one dangling port: the id of the stitched instance added,
    or None."""
    n = til.cfg.jitter_tries
    for dn, _, p, j, place, plan in _ordered_candidates(til, key):
        for i in range(n + 1):
            if i == 0:
                cand = til.evaluate(p, place, plan=plan)
            else:
                cand = til.evaluate(p, _jitter(til, place, i - 1, n), forced=[(j, key)])
                if cand.d_danglings > 0:
                    continue
            if til.valid(cand):
                return til.commit(cand)
    return None


def _dangling_ports(til, iid) -> list:
    """The ports of instance ``iid`` that count as dangling."""
    inst = til.inst.get(iid)
    if inst is None:
        return []
    D = til.dang
    return [(iid, j) for j, l in enumerate(inst.links)
            if l is None and (iid, j) in D.where and D.row((iid, j))[9] > 0]


def _remove_with_partners(til, iid, stack) -> None:
    """Remove instance ``iid``; the ports it was stitched to go on the ``stack``."""
    partners = [l for l in til.inst[iid].links if l is not None]
    til.remove(iid)
    stack.extend(partners)


def close_danglings(til, max_seconds: float | None = None, max_passes: int = 50, max_steps: int = 200000) -> dict:
    """Run Algorithm 2 on the :class:`~runtime.tiling.tiler.Tiler` ``til``. Dangling ports are
    taken earliest first; the danglings a fix or a removal creates are handled right after it
    (depth first), so a chain is followed to its end. Returns its figures (passes, steps,
    removals, patches, danglings, stuck, seconds)."""
    cfg = til.cfg
    t_start = _time.perf_counter()
    removals = 0
    passes = 0
    steps = 0
    stuck = set()
    evictions: dict = {}
    D = til.dang
    while passes < max_passes and steps < max_steps:
        passes += 1
        keys = [D.key[i] for i in D.counting_rows() if D.key[i] not in stuck]
        if not keys:
            break
        order = np.argsort([D.row(k)[3] for k in keys], kind="stable")
        stack = [keys[i] for i in order[::-1]]
        changed = False
        while stack and steps < max_steps:
            if max_seconds is not None and _time.perf_counter() - t_start > max_seconds:
                passes = max_passes
                break
            key = stack.pop()
            if key in stuck or key not in D.where or D.row(key)[9] <= 0:
                continue
            steps += 1
            new_id = _fix(til, key)
            if new_id is not None:
                changed = True
                stack.extend(_dangling_ports(til, new_id)[::-1])
                continue
            owner = key[0]
            if til.inst[owner].fixed and removals < cfg.max_removals and evictions.get(key, 0) < 3:
                # a keyframe cannot go: remove the (non-keyframe) instances that block the best
                # stitch at its port instead, and come back to it
                evictions[key] = evictions.get(key, 0) + 1
                blockers = _blockers(til, key)
                if blockers:
                    for b in blockers:
                        _remove_with_partners(til, b, stack)
                        removals += 1
                    stack.append(key)
                    changed = True
                    continue
            if til.inst[owner].fixed or removals >= cfg.max_removals:
                stuck.add(key)
                continue
            _remove_with_partners(til, owner, stack)
            removals += 1
            changed = True
        if not changed:
            break
    til.timing["phase2"] += _time.perf_counter() - t_start
    return {"passes": passes, "steps": steps, "removals": removals, "patches": len(til.inst),
            "danglings": til.num_danglings, "stuck": len(stuck), "seconds": _time.perf_counter() - t_start}
