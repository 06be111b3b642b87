"""Independent checker of a tiling (Kim, Hwang, Hyun and Lee 2012; ARCHITECTURE.md "Verification
is part of the product").

It trusts nothing the tiler computed: it reads the deformed fragments of every instance
(:class:`~runtime.tiling.result.TilingResult`) and the rest patches of the library, and
recomputes

* **stitches** geometrically: an exit and an entry of the same pose class coincide in position,
  heading and time (within ``tol_*``; minimum image when the region wraps). Every unmatched
  entry/exit strictly inside the region (space unless it wraps, time unless it wraps) and not on
  a source (entries) or sink (exits) is **dangling**. The continuity of Eq. 2 across each stitch
  (``p_N - p_{N-1}`` against ``p_1 - p_0``) is reported as ``step_mismatch``;
* **interpenetration**: every character is posed on every clock frame by forward kinematics
  (joints and end sites, not the library's stored boxes), boxed in its heading frame, and every
  pair of characters that are not in the same patch instance on that frame is tested with a
  separating-axis test (brute force over pairs per frame, no space-time index); boxes against
  obstacles likewise;
* **deformation** per frame against the limits (3 cm stretch, 7 deg bend, 0.018 s time shift;
  1 cm of glide: how far a frame where the rest motion stands, under 1 cm a frame, carries the
  toes along the ground by stretch and turn) by comparing each
  deformed fragment with the library's rest fragment (own code, not the tiler's);
* **interpersonal constraints** of every instance (relative position/heading/time error).

:func:`check_repeating` lays a wrap-around tile out 3 x 3 (every instance copied by the lattice
vectors, no wrapping any more) and checks the middle tile: seamless means no dangling port and no
interpenetration there, across the borders included.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..check import CheckReport
from ..motion.fk import end_site_positions, forward_kinematics
from ..motion.planar import rotate_xz, wrap_angle
from .region import Region, minimum_image
from .result import TilingResult

__all__ = ["TilingCheckReport", "check_tiling", "check_repeating", "layout_copies", "check_tiling_feet"]


@dataclass
class TilingCheckReport(CheckReport):
    """What :func:`check_tiling` found (a :class:`runtime.check.CheckReport`, kind ``"tiling"``):
    counts, worst values, the dangling ports (instance, fragment, "entry"/"exit", x, z, t) and
    a few interpenetrations (frame, character, character)."""
    kind = "tiling"

    patches: int = 0
    characters: int = 0
    ports: int = 0
    stitches: int = 0
    danglings: list = field(default_factory=list)        # (instance, fragment, "entry"/"exit", x, z, t)
    interpenetrations: int = 0                           # (frame, pair) overlaps
    interpenetration_examples: list = field(default_factory=list)
    obstacle_hits: int = 0
    max_stretch: float = 0.0
    max_bend_deg: float = 0.0
    max_time_shift: float = 0.0
    max_glide: float = 0.0
    frames_over_limits: int = 0
    constraint_error: float = 0.0
    step_mismatch: float = 0.0
    links_disagree: int = 0
    limits: tuple = (0.03, 7.0, 0.018, 0.01)

    @property
    def ok(self) -> bool:
        return not self.danglings and self.interpenetrations == 0 and self.obstacle_hits == 0 and self.frames_over_limits == 0

    @property
    def passed(self) -> bool:
        return self.ok

    def details(self) -> dict:
        return {"danglings": list(self.danglings), "interpenetration_examples": list(self.interpenetration_examples)}

    def figures(self) -> dict:
        return {"ok": self.ok, "patches": self.patches, "characters": self.characters, "stitches": self.stitches,
                "danglings": len(self.danglings), "interpenetrations": self.interpenetrations,
                "obstacle_hits": self.obstacle_hits, "frames_over_limits": self.frames_over_limits,
                "max_stretch_cm": round(100 * self.max_stretch, 3), "max_bend_deg": round(self.max_bend_deg, 3),
                "max_time_shift_s": round(self.max_time_shift, 5), "max_glide_cm": round(100 * self.max_glide, 3),
                "constraint_error": round(self.constraint_error, 5),
                "step_mismatch_cm": round(100 * self.step_mismatch, 3), "links_disagree": self.links_disagree}

    def __str__(self):
        """One line for the CLI and the samples' READMEs (its own wording: "OK", patches,
        characters and stitches first)."""
        s = self.summary()
        return ("tiling check: " + ("OK" if s["ok"] else "FAILED") + f" | {s['patches']} patches, {s['characters']} characters, "
                f"{s['stitches']} stitches | dangling {s['danglings']} | interpenetrations {s['interpenetrations']} "
                f"| obstacle hits {s['obstacle_hits']} | frames over limits {s['frames_over_limits']} "
                f"(max stretch {s['max_stretch_cm']} cm, bend {s['max_bend_deg']} deg, shift {s['max_time_shift_s']} s, "
                f"glide {s['max_glide_cm']} cm) "
                f"| constraint error {s['constraint_error']}")


def _ports(res):
    """Table of all ports from the deformed arrays: rows (inst, frag, kind, class, open, x, z,
    heading, time, stepx, stepz)."""
    rows = []
    for i in range(res.num_instances):
        p = res.library.patches[res.patch[i]]
        for k, sl in enumerate(res.frag_slices(i)):
            f = p.fragments[k]
            xz, h, t = res.xz[i][sl], res.heading[i][sl], res.time[i][sl]
            rows.append([i, k, 0, f.entry_class, f.entry_open, xz[0, 0], xz[0, 1], h[0], t[0], xz[1, 0] - xz[0, 0], xz[1, 1] - xz[0, 1]])
            rows.append([i, k, 1, f.exit_class, f.exit_open, xz[-1, 0], xz[-1, 1], h[-1], t[-1], xz[-1, 0] - xz[-2, 0], xz[-1, 1] - xz[-2, 1]])
    return np.array(rows, np.float64).reshape(-1, 11)


def _inside(region, xz, t, wrap_space, wrap_time):
    ok = np.ones(len(t), bool)
    if not wrap_space:
        ok &= (xz[:, 0] > region.x0) & (xz[:, 0] < region.x1) & (xz[:, 1] > region.z0) & (xz[:, 1] < region.z1)
    if not wrap_time:
        ok &= (t > region.t0 + 1e-6) & (t < region.t1 - 1e-6)
    return ok


def _match_ports(P, period, tperiod, tol_pos, tol_dir, tol_time):
    """Exits matched to entries: returns {exit row: entry row}."""
    ent = np.flatnonzero((P[:, 2] == 0) & (P[:, 4] > 0))
    ext = np.flatnonzero((P[:, 2] == 1) & (P[:, 4] > 0))
    match = {}
    used = set()
    if len(ent) == 0 or len(ext) == 0:
        return match
    for a in ext:
        m = ent[P[ent, 3] == P[a, 3]]
        if len(m) == 0:
            continue
        d = minimum_image(P[m][:, 5:7] - P[a, 5:7], period)
        dt = minimum_image(P[m, 8] - P[a, 8], tperiod)
        dh = np.abs(wrap_angle(P[m, 7] - P[a, 7]))
        ok = (np.hypot(d[:, 0], d[:, 1]) <= tol_pos) & (np.abs(dt) <= tol_time) & (dh <= tol_dir)
        ok &= ~((P[m, 0] == P[a, 0]) & (P[m, 1] == P[a, 1]))
        for b in m[ok]:
            if int(b) not in used:
                used.add(int(b))
                match[int(a)] = int(b)
                break
    return match


def _char_boxes(res, tracks):
    """Per character: frames (F,), instance per frame, world OBB (centre, lateral axis, hx, hz,
    ylo, yhi), all by FK of the posed track."""
    sk = res.library.skeleton
    out = []
    for tr in tracks:
        pos, rot = res.poses(tr)
        gr, gp = forward_kinematics(sk, pos, rot)
        pts = np.concatenate([gp, end_site_positions(sk, gr, gp)], axis=1)
        h = tr.root[:, 2]
        loc = rotate_xz(pts[..., [0, 2]] - tr.root[:, None, :2], -h[:, None])
        lo = loc.min(1)
        hi = loc.max(1)
        cl = 0.5 * (lo + hi)
        cen = tr.root[:, :2] + rotate_xz(cl, h)
        lat = np.stack([np.cos(h), -np.sin(h)], 1)
        frames = tr.start_frame + np.arange(len(tr))
        inst = np.empty(len(tr), np.int64)
        segs = tr.segments
        for n, (i, k, q0) in enumerate(segs):
            q1 = segs[n + 1][2] if n + 1 < len(segs) else frames[-1] + 1
            inst[(frames >= q0) & (frames < q1)] = i
        out.append((frames, inst, cen, lat, 0.5 * (hi[:, 0] - lo[:, 0]), 0.5 * (hi[:, 1] - lo[:, 1]),
                    pts[..., 1].min(1), pts[..., 1].max(1)))
    return out


def _sat(ca, la, hxa, hza, cb, lb, hxb, hzb, period):
    d = minimum_image(cb - ca, period)
    fa = np.stack([-la[:, 1], la[:, 0]], 1)
    fb = np.stack([-lb[:, 1], lb[:, 0]], 1)
    sep = np.zeros(len(d), bool)
    for L in (la, fa, lb, fb):
        pr = np.abs(np.sum(d * L, 1))
        ra = hxa * np.abs(np.sum(la * L, 1)) + hza * np.abs(np.sum(fa * L, 1))
        rb = hxb * np.abs(np.sum(lb * L, 1)) + hzb * np.abs(np.sum(fb * L, 1))
        sep |= pr >= ra + rb
    return ~sep


def check_tiling(res, tol_pos: float = 2e-3, tol_dir: float = 1e-2, tol_time: float = 2e-3,
                 limits=(0.03, 7.0, 0.018, 0.01), slack: float = 1e-4, region=None, wrap=None,
                 max_examples: int = 10) -> TilingCheckReport:
    """Check a :class:`TilingResult`. ``region``/``wrap`` override the result's (used by
    :func:`check_repeating`). ``slack`` is the numerical allowance on the limits."""
    region = region or res.region
    wrap_space, wrap_time = (region.wrap_space, region.wrap_time) if wrap is None else wrap
    period = np.array([region.x1 - region.x0, region.z1 - region.z0]) if wrap_space else None
    tperiod = (region.t1 - region.t0) if wrap_time else None
    rep = TilingCheckReport(patches=res.num_instances, limits=tuple(limits))
    # -- stitches and danglings ----------------------------------------------------------------
    P = _ports(res)
    rep.ports = len(P)
    match = _match_ports(P, period, tperiod, tol_pos, tol_dir, tol_time)
    rep.stitches = len(match)
    matched = set(match) | set(match.values())
    for a, b in match.items():
        rep.step_mismatch = max(rep.step_mismatch, float(np.hypot(*(P[a, 9:11] - P[b, 9:11]))))
    got = {(int(P[a, 0]), int(P[a, 1]), int(P[b, 0]), int(P[b, 1])) for a, b in match.items()}
    want = {tuple(int(v) for v in l) for l in res.links}
    rep.links_disagree = len(got ^ want)
    if len(P):
        inside = _inside(region, P[:, 5:7], P[:, 8], wrap_space, wrap_time)
        for r in np.flatnonzero(inside):
            if int(r) in matched:
                continue
            kind = int(P[r, 2])
            at_portal = any(math.hypot(P[r, 5] - pt.x, P[r, 6] - pt.z) <= pt.radius and
                            (pt.kind == "both" or pt.kind == ("source" if kind == 0 else "sink")) for pt in res.portals)
            if not at_portal:
                rep.danglings.append((int(P[r, 0]), int(P[r, 1]), "entry" if kind == 0 else "exit",
                                      float(P[r, 5]), float(P[r, 6]), float(P[r, 8])))
    # -- deformation and constraints -----------------------------------------------------------
    lim_s, lim_b, lim_t = limits[:3]
    lim_g = limits[3] if len(limits) > 3 else np.inf
    over = 0
    for i in range(res.num_instances):
        p = res.library.patches[res.patch[i]]
        sls = res.frag_slices(i)
        for k, sl in enumerate(sls):
            f = p.fragments[k]
            r0 = f.root_xz
            t0 = f.t0 + np.arange(f.num_frames) / p.fps
            x1, h1, t1 = res.xz[i][sl], res.heading[i][sl], res.time[i][sl]
            d0, d1 = np.diff(r0, axis=0), np.diff(x1, axis=0)
            l0, l1 = np.linalg.norm(d0, axis=1), np.linalg.norm(d1, axis=1)
            stretch = np.abs(l1 - l0)
            # a standing frame carried along the ground or turned on the spot (feet 0.15 m out)
            glide = np.where(l0 < 0.01, stretch + np.abs(np.diff(h1) - np.diff(f.heading)) * 0.15, 0.0)
            shift = np.abs(np.diff(t1) - np.diff(t0))
            bend_h = np.abs(np.diff(h1) - np.diff(f.heading))
            ang = np.arctan2(d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0], np.einsum("ij,ij->i", d0, d1))
            mv = (l0 > 0.01) & (l1 > 0.01)
            bend_p = np.zeros_like(bend_h)
            both = mv[1:] & mv[:-1]
            bend_p[1:] = np.where(both, np.abs(wrap_angle(np.diff(ang))), 0.0)
            bend = np.degrees(np.maximum(bend_h, bend_p))
            rep.max_stretch = max(rep.max_stretch, float(stretch.max(initial=0)))
            rep.max_bend_deg = max(rep.max_bend_deg, float(bend.max(initial=0)))
            rep.max_time_shift = max(rep.max_time_shift, float(shift.max(initial=0)))
            rep.max_glide = max(rep.max_glide, float(glide.max(initial=0)))
            over += int(np.count_nonzero((stretch > lim_s + slack) | (bend > lim_b + 100 * slack) | (shift > lim_t + slack)
                                         | (glide > lim_g + slack)))
        for c in p.constraints:
            a, b = sls[c.frag_a].start + c.frame_a, sls[c.frag_b].start + c.frame_b
            ha = res.heading[i][a]
            rel = rotate_xz(res.xz[i][b] - res.xz[i][a], -ha)
            e = max(float(np.max(np.abs(rel - c.rel_position))),
                    abs(float(wrap_angle(res.heading[i][b] - ha - c.rel_direction))),
                    abs(float(res.time[i][b] - res.time[i][a] - c.dt)))
            rep.constraint_error = max(rep.constraint_error, e)
    rep.frames_over_limits = over
    # -- interpenetration -------------------------------------------------------------------------
    tracks = res.tracks(crop=not wrap_time)
    rep.characters = len(res.characters())
    boxes = _char_boxes(res, tracks)
    if boxes:
        fr = np.concatenate([b[0] for b in boxes])
        ch = np.concatenate([np.full(len(b[0]), n) for n, b in enumerate(boxes)])
        ins = np.concatenate([b[1] for b in boxes])
        cen = np.concatenate([b[2] for b in boxes])
        lat = np.concatenate([b[3] for b in boxes])
        hx = np.concatenate([b[4] for b in boxes])
        hz = np.concatenate([b[5] for b in boxes])
        ylo = np.concatenate([b[6] for b in boxes])
        yhi = np.concatenate([b[7] for b in boxes])
        if wrap_time and tperiod:
            nT = int(round(tperiod * res.fps))
            fr = (fr - int(round(region.t0 * res.fps))) % nT
        keep = np.ones(len(fr), bool)
        if not wrap_time:
            keep = (fr >= round(region.t0 * res.fps)) & (fr <= round(region.t1 * res.fps))
        idx = np.flatnonzero(keep)
        order = idx[np.argsort(fr[idx], kind="stable")]
        fs = fr[order]
        starts = np.flatnonzero(np.r_[True, fs[1:] != fs[:-1]])
        ends = np.r_[starts[1:], len(fs)]
        rad = np.hypot(hx, hz)
        A, B = [], []
        for s, e in zip(starts, ends):
            n = e - s
            if n < 2:
                continue
            ii, jj = np.triu_indices(n, 1)
            A.append(order[s + ii])
            B.append(order[s + jj])
        if A:
            a = np.concatenate(A)
            b = np.concatenate(B)
            near = np.hypot(*minimum_image(cen[b] - cen[a], period).T) < rad[a] + rad[b]
            near &= (ch[a] != ch[b]) & (ins[a] != ins[b]) & (ylo[a] < yhi[b]) & (ylo[b] < yhi[a])
            a, b = a[near], b[near]
            hit = _sat(cen[a], lat[a], hx[a], hz[a], cen[b], lat[b], hx[b], hz[b], period)
            rep.interpenetrations = int(hit.sum())
            for q in np.flatnonzero(hit)[:max_examples]:
                rep.interpenetration_examples.append((int(fr[a[q]]), int(ch[a[q]]), int(ch[b[q]])))
        for ob in res.obstacles:
            F0 = int(round(region.t0 * res.fps))
            oc, oh = ob.at(fr - F0)
            olat = np.stack([np.cos(oh), -np.sin(oh)], 1)
            n = len(fr)
            hit = _sat(cen, lat, hx, hz, oc, olat, np.full(n, ob.half[0]), np.full(n, ob.half[1]), period)
            hit &= keep & (ylo < ob.height)
            rep.obstacle_hits += int(hit.sum())
    return rep


def layout_copies(res, nx: int = 3, nz: int = 3, near: float | None = 2.0):
    """A repeating tile laid out ``nx`` x ``nz``: every instance shifted so its root-path centre
    lies in the tile, then copied by the lattice vectors; returns a new TilingResult (no wrap)
    whose region is the middle tile. ``near``: keep only copies whose root paths come within
    that many metres of the middle tile (all of them with ``None``)."""
    r = res.region
    W, H = r.x1 - r.x0, r.z1 - r.z0
    out = dict(patch=[], place=[], fixed=[], xz=[], heading=[], time=[])
    n = res.num_instances
    for ix in range(nx):
        for iz in range(nz):
            for i in range(n):
                c = res.xz[i].mean(0)
                s = np.array([-W * math.floor((c[0] - r.x0) / W), -H * math.floor((c[1] - r.z0) / H)])
                s += [(ix - nx // 2) * W, (iz - nz // 2) * H]
                x, z, th, t = res.place[i]
                if near is not None:
                    lo, hi = res.xz[i].min(0) + s, res.xz[i].max(0) + s
                    if hi[0] < r.x0 - near or lo[0] > r.x1 + near or hi[1] < r.z0 - near or lo[1] > r.z1 + near:
                        continue
                out["patch"].append(res.patch[i])
                out["place"].append((x + s[0], z + s[1], th, t))
                out["fixed"].append(res.fixed[i])
                out["xz"].append(res.xz[i] + s)
                out["heading"].append(res.heading[i])
                out["time"].append(res.time[i])
    reg = Region(r.x0, r.z0, r.x1, r.z1, r.t0, r.t1, False, r.wrap_time)
    # links are recomputed by the checker; carry none
    return TilingResult(res.library, reg, out["patch"], out["place"], out["fixed"], out["xz"], out["heading"],
                        out["time"], np.zeros((0, 4), np.int64), res.obstacles, res.portals, res.fps, {})


def check_repeating(res, **kw) -> TilingCheckReport:
    """3 x 3 layout of a wrap-around tile, checked without wrapping (middle tile's danglings;
    interpenetrations anywhere in the layout, which includes every border)."""
    if not res.region.wrap_space:
        raise ValueError("check_repeating needs a tiling made with Region(wrap_space=True)")
    lay = layout_copies(res)
    rep = check_tiling(lay, wrap=(False, res.region.wrap_time), **kw)
    rep.links_disagree = 0
    return rep


def check_tiling_feet(stage_path, roots, knee_range=None) -> dict:
    """Planted-foot slide of tiled characters (their SkelRoot paths ``roots``) as written in a
    baked stage, measured like the crowd's (:func:`runtime.footslide.feet_report`)."""
    from ..footslide import feet_report
    return feet_report(stage_path, roots, knee_range)
