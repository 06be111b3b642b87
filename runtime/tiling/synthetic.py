"""Synthetic multi-character patches composed from motion-graph edges.

Stand-ins for the detected patches of the authoring side (:mod:`authoring.patches`), used by tests,
benchmarks and samples so they need nothing but the runtime motion graph. Each character's
fragment is a chain of graph edges (hub poses make the chain seamless), placed in the patch frame
and tied to its partners by interpersonal constraints measured from the placement:

* :func:`meet_patch` -- two walkers approach head on, stop face to face ``distance`` apart, stand
  (the "handshake" moment, constrained), turn away and leave;
* :func:`rows_patch` -- ``pairs`` couples in two facing rows (the keyframed "bowing rows" of
  Figure 7): walk in on parallel lanes, stop, stand facing the partner (constrained), turn round
  and walk back out;
* :func:`pass_patch` -- a box pass: A walks in carrying, stops and puts the box down; B, facing
  A, picks it up (constrained to A's put-down) and carries it away while A walks off.

Entry/exit pose classes are graph hub ids, as in :func:`~runtime.tiling.patch.single_character_patches`.
"""
from __future__ import annotations

import numpy as np

from ..motion.planar import rotate_xz
from .patch import Constraint, Fragment, Patch, PatchLibrary, single_character_patches

__all__ = ["chain_edges", "meet_patch", "rows_patch", "pass_patch", "synthetic_library"]


def chain_edges(graph, edges):
    """Concatenate graph edges (each starts where the previous ends; shared hub frames once).
    Returns (xz (F, 2), heading (F,), height (F,), rotations (F, J, 4), starts) relative to the
    first frame; ``starts[i]`` is the chain frame where edge i begins."""
    xz, hd, ht, rot, starts = [], [], [], [], []
    ox, oz, oh = 0.0, 0.0, 0.0
    n = 0
    for k, e in enumerate(edges):
        if k and graph.edge_src[e] != graph.edge_dst[edges[k - 1]]:
            raise ValueError(f"edge {e} does not start where edge {edges[k - 1]} ends")
        a, b = graph.edge_start[e], graph.edge_start[e + 1]
        p = rotate_xz(graph.frame_xz[a:b], oh) + (ox, oz)
        h = graph.frame_heading[a:b] + oh
        s = 0 if k == 0 else 1
        starts.append(n - (0 if k == 0 else 1))
        xz.append(p[s:]), hd.append(h[s:]), ht.append(graph.frame_height[a:b][s:]), rot.append(graph.frame_rotations[a:b][s:])
        n += (b - a) - s
        ox, oz, oh = p[-1, 0], p[-1, 1], h[-1]
    return np.concatenate(xz), np.concatenate(hd), np.concatenate(ht), np.concatenate(rot), starts


def _edges(graph, src, dst, label=None, dh=None, max_dist=None):
    es = [e for e in range(graph.num_edges) if graph.edge_src[e] == src and graph.edge_dst[e] == dst
          and (label is None or label in graph.edge_labels[e])]
    if dh is not None:
        lo, hi = np.radians(dh[0]), np.radians(dh[1])
        es = [e for e in es if lo <= graph.edge_disp[e, 2] <= hi]
    if max_dist is not None:
        es = [e for e in es if np.hypot(*graph.edge_disp[e, :2]) <= max_dist]
    return es


def _pick(rng, es, what):
    if not es:
        raise ValueError(f"the motion graph has no edge for {what}")
    return int(es[rng.integers(len(es))])


def _walker(graph, rng, n_in, n_idle, turn_sign, n_turn=1, n_out=1):
    """Walk in (straight, from the walking hub), stop, stand, turn in place ``n_turn`` times
    (sign), start, walk out. Returns the edge list and the index of the first standing edge."""
    W, S = 1, 0          # walking and standing hubs of the default graph
    e = [_pick(rng, _edges(graph, W, W, "walk", (-4, 4)), "straight walk") for _ in range(n_in)]
    e += [_pick(rng, _edges(graph, W, S, "stop", (-20, 0)), "stop")]
    stand = len(e)
    e += [_pick(rng, _edges(graph, S, S, "idle", (-3, 3), 0.03), "idle") for _ in range(n_idle)]
    rng_deg = (55, 80) if turn_sign > 0 else (-80, -55)
    e += [_pick(rng, _edges(graph, S, S, None, rng_deg, 0.1), "turn in place") for _ in range(n_turn)]
    e += [_pick(rng, _edges(graph, S, W, "start", (-4, 4)), "start")]
    e += [_pick(rng, _edges(graph, W, W, "walk", (-10, 10)), "walk") for _ in range(n_out)]
    return e, stand


def _place(graph, edges, stand_idx, at_xz, at_heading):
    """Fragment arrays with the frame where ``edges[stand_idx]`` begins put at (xz, heading)."""
    xz, hd, ht, rot, starts = chain_edges(graph, edges)
    f = starts[stand_idx]
    th = at_heading - hd[f]
    p = rotate_xz(xz - xz[f], th) + at_xz
    return p, hd + th, ht, rot, f


def meet_patch(graph, seed: int = 0, distance: float = 1.0, n_in: int = 1, n_idle: int = 1, name=None) -> Patch:
    rng = np.random.default_rng(seed)
    frags = []
    for side in (0, 1):
        e, s = _walker(graph, rng, n_in, n_idle, +1)
        at = np.array([0.0, -0.5 * distance if side == 0 else 0.5 * distance])
        p, h, ht, rot, f = _place(graph, e, s, at, 0.0 if side == 0 else np.pi)
        frags.append((p, h, ht, rot, f, int(graph.edge_src[e[0]]), int(graph.edge_dst[e[-1]])))
    # both arrive (reach their standing spot) at t = 0 of the encounter
    t0 = [-f[4] / graph.fps for f in frags]
    fr = [Fragment(t0[k], f[0], f[1], f[2], f[3], f[5], f[6]) for k, f in enumerate(frags)]
    # constrain at the middle of the common standing window
    ca = frags[0][4] + int(0.5 * n_idle * 0.67 * graph.fps)
    cb = ca - frags[0][4] + frags[1][4]
    cb = min(cb, fr[1].num_frames - 1)
    con = Constraint.measure(fr, 0, ca, 1, cb, "contact", graph.fps)
    return Patch.from_fragments(name or f"meet_s{seed}", ("meet", "handshake", "friendly"), graph.skeleton, fr, [con], graph.fps)


def rows_patch(graph, pairs: int = 5, spacing: float = 1.3, distance: float = 1.2, seed: int = 0, name=None) -> Patch:
    rng = np.random.default_rng(seed)
    fr, stand = [], []
    for k in range(pairs):
        x = (k - 0.5 * (pairs - 1)) * spacing
        for side in (0, 1):
            e, s = _walker(graph, rng, 1, 2, +1 if side == 0 else -1, n_turn=2, n_out=1)
            at = np.array([x, -0.5 * distance if side == 0 else 0.5 * distance])
            p, h, ht, rot, f = _place(graph, e, s, at, 0.0 if side == 0 else np.pi)
            fr.append(Fragment(-f / graph.fps, p, h, ht, rot, int(graph.edge_src[e[0]]), int(graph.edge_dst[e[-1]])))
            stand.append(f)
    cons = []
    for k in range(pairs):
        a, b = 2 * k, 2 * k + 1
        fa = stand[a] + int(0.9 * graph.fps)
        fb = min(fa - stand[a] + stand[b], fr[b].num_frames - 1)
        cons.append(Constraint.measure(fr, a, fa, b, fb, "bow", graph.fps))
    return Patch.from_fragments(name or f"rows{pairs}_s{seed}", ("bow", "rows", "keyframe"), graph.skeleton, fr, cons, graph.fps)


def pass_patch(graph, seed: int = 0, distance: float = 1.1, name=None) -> Patch:
    """Box pass between two characters (graph hubs: 3 carry-walk, 2 carry-stand, 0 stand, 1 walk)."""
    rng = np.random.default_rng(seed)
    CW, CS, S, W = 3, 2, 0, 1
    # A: carry walk in, stop carrying, put down, stand, turn, start, walk
    ea = [_pick(rng, _edges(graph, CW, CW, "carry", (-4, 4)), "carry walk") for _ in range(1)]
    ea += [_pick(rng, _edges(graph, CW, CS, "carry"), "carry stop")]
    put = len(ea)
    ea += [_pick(rng, _edges(graph, CS, S, "put_down"), "put down")]
    ea += [_pick(rng, _edges(graph, S, S, None, (55, 80), 0.1), "turn") for _ in range(2)]
    ea += [_pick(rng, _edges(graph, S, W, "start", (-4, 4)), "start")]
    ea += [_pick(rng, _edges(graph, W, W, "walk", (-10, 10)), "walk") for _ in range(1)]
    # B: walk in, stop, stand while A puts down, pick up, start carrying, carry walk out (after turning)
    eb = [_pick(rng, _edges(graph, W, W, "walk", (-4, 4)), "walk") for _ in range(2)]
    eb += [_pick(rng, _edges(graph, W, S, "stop", (-20, 0)), "stop")]
    stand_b = len(eb)
    eb += [_pick(rng, _edges(graph, S, S, "idle", (-3, 3), 0.03), "idle") for _ in range(2)]
    pick = len(eb)
    eb += [_pick(rng, _edges(graph, S, CS, "pick_up"), "pick up")]
    eb += [_pick(rng, _edges(graph, CS, CW, "carry"), "carry start")]
    eb += [_pick(rng, _edges(graph, CW, CW, "carry", (40, 70)), "carry turn")]
    pa, ha, hta, ra, fa = _place(graph, ea, put, np.array([0.0, -0.5 * distance]), 0.0)
    pb, hb, htb, rb, fb = _place(graph, eb, stand_b, np.array([0.0, 0.5 * distance]), np.pi)
    _, _, _, _, sb = chain_edges(graph, eb)
    _, _, _, _, sa = chain_edges(graph, ea)
    a_put_end = sa[put + 1]                 # A has put the box down
    b_pick = sb[pick]                       # B starts picking up
    ta = -a_put_end / graph.fps             # A's put-down ends at t = 0 ...
    tb = -b_pick / graph.fps + 0.2          # ... B starts picking up 0.2 s later
    fr = [Fragment(ta, pa, ha, hta, ra, int(graph.edge_src[ea[0]]), int(graph.edge_dst[ea[-1]])),
          Fragment(tb, pb, hb, htb, rb, int(graph.edge_src[eb[0]]), int(graph.edge_dst[eb[-1]]))]
    # B must already stand there when A's put-down ends: check the timing is sane
    if tb + fb / graph.fps > 0.0:
        shift = tb + fb / graph.fps
        raise ValueError(f"pass_patch: B arrives {shift:.2f} s after the box is down; use more idle")
    con = Constraint.measure(fr, 0, a_put_end, 1, b_pick, "handoff", graph.fps)
    return Patch.from_fragments(name or f"pass_s{seed}", ("pass", "box", "friendly"), graph.skeleton, fr, [con], graph.fps)


def synthetic_library(graph, meets: int = 4, passes: int = 0, rows: int = 0, singles: PatchLibrary | None = None,
                      seed: int = 0, carry: bool = False) -> PatchLibrary:
    """Single-character patches of ``graph`` plus ``meets`` meet patches, ``passes`` box passes
    and ``rows`` bowing-rows patches (different edge choices per seed)."""
    lib = singles or single_character_patches(
        graph, labels=("walk", "turn", "idle", "start", "stop") + (("carry", "pick_up", "put_down") if carry else ()),
        states=("walking", "carrying") if carry else ("walking",), include_transitions=carry)
    extra = [meet_patch(graph, seed=seed + i, name=f"meet{i}") for i in range(meets)]
    extra += [pass_patch(graph, seed=seed + i, name=f"pass{i}") for i in range(passes)]
    extra += [rows_patch(graph, seed=seed + i, name=f"rows{i}") for i in range(rows)]
    return PatchLibrary(lib.skeleton, lib.patches + extra, lib.pose_class_names, lib.pose_class_rotations,
                        lib.pose_class_height, lib.fps, {**lib.meta, "synthetic": {"meets": meets, "passes": passes,
                                                                                    "rows": rows, "seed": seed}})
