"""Tiling motion patches in a space-time region (paper 003, section 5).

Concepts
--------
* A *patch instance* is a library patch placed rigidly (x, z, heading, time) and then deformed
  by its :class:`~runtime.tiling.deform.PatchDeformer` (Laplacian path deformation, section 3):
  the ports stitched to ports already in the tiling are dragged onto them (Eq. 1-3), the other
  ports are held where the placement put them. Only the new instance deforms; instances already
  in the tiling stay pinned (the interactive rule of section 5.3, also used for the static
  tiler: a simplification of "adjacent patches deform", listed in the report).
* A *dangling* entry/exit is an open port of an instance that is not stitched and lies inside
  the region (strictly inside its rectangle -- unless the space wraps -- and strictly inside its
  time interval -- unless time wraps) and not on a source (entries) or sink (exits). A closed
  port (pose class -1) can only be outside the region or on a source/sink.
* ``IsValid``: the deformation is within :class:`~runtime.tiling.deform.Limits` on every frame
  and the instance's per-frame boxes (resampled on the 30 Hz clock) overlap neither obstacles
  nor boxes of other instances (:class:`~runtime.tiling.boxindex.BoxIndex`).

Algorithm 1 (stochastic sampling, section 5.1): draw a patch and a placement -- uniform in the
region with probability from the preference function Eq. 7 times a size bias, so larger patches
come first; or (with ``anchor_prob``) a patch with a matching port, by Eq. 7 without the size
bias, aligned to a random dangling port -- stitch it to every
dangling port its own ports match within ``match_*``, and accept with probability
``exp(-dE / kT)`` on the tiling energy Eq. 6 ``E = N_d / (N_c + N_d) + alpha / (N_c + N_d)``
followed by IsValid; ``T`` falls by ``dT`` per sample from ``T_max``; the phase stops after
``i_max`` samples in a row without an acceptance. ``seeds`` caps the number of free (unanchored)
placements, which is how a density is asked for.

Algorithm 2 (deterministic search, section 5.2): for each dangling port ``d`` every library port
that matches it (opposite kind, same pose class) is tried in the order of the preference
function (stitches that also close other danglings first); a candidate that would increase the
number of danglings is skipped (line 5); an invalid one is jittered up to ``jitter_tries`` times
with a range growing from 0.6 m / 15 deg / 0.3 s to 1.0 m / 25 deg / 0.5 s (line 11); if nothing
fits, the instance owning ``d`` is removed (line 16) and its patch is recorded in the sampling
history of the ports it was stitched to, so it is not chosen there again.

Control (section 5.3): :class:`Preference` (Eq. 7: target location, orientation, time, labels),
keyframes (:meth:`Tiler.add_keyframe`: fixed instances, never removed), repeating tiles
(``Region(wrap_space=True)``: the index and the port matching use the minimum image),
static and moving :class:`Obstacle` s, and :class:`Portal` sources/sinks.

Everything random draws from one ``numpy.random.Generator(seed)``; the same library, settings
and seed give the same tiling (unless a wall-clock budget cuts a phase short).
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np

from .boxindex import BoxIndex, box_samples, obb_overlap
from .deform import DEFAULT_LIMITS, Limits, PatchDeformer, deformation_measures
from .patch import PatchLibrary

__all__ = ["Region", "Obstacle", "Portal", "Preference", "TilerConfig", "PreparedLibrary", "TilingState",
           "Tiler", "TilingResult", "tiling_energy"]


def braking(k, n):
    """Distance (in frames of the last velocity) covered ``k`` frames into a stop that takes
    ``n`` frames with constant deceleration."""
    k = np.minimum(np.asarray(k, np.float64), n)
    return k - 0.5 * k * k / n


def _rot(xz, th: float):
    """rotate_xz for a scalar heading (no stacking overhead)."""
    c, s = math.cos(th), math.sin(th)
    out = np.empty_like(xz, dtype=np.float64)
    out[..., 0] = c * xz[..., 0] + s * xz[..., 1]
    out[..., 1] = c * xz[..., 1] - s * xz[..., 0]
    return out


# ---------------------------------------------------------------------------------------------
@dataclass
class Region:
    x0: float
    z0: float
    x1: float
    z1: float
    t0: float = 0.0
    t1: float = 20.0
    wrap_space: bool = False
    wrap_time: bool = False

    @property
    def size(self):
        return (self.x1 - self.x0, self.z1 - self.z0)

    def inside(self, xz, t):
        """Strictly inside (the boundary counts as outside), per wrapped dimension always."""
        xz = np.atleast_2d(xz)
        t = np.atleast_1d(t)
        ok = np.ones(len(t), bool)
        if not self.wrap_space:
            ok &= (xz[:, 0] > self.x0) & (xz[:, 0] < self.x1) & (xz[:, 1] > self.z0) & (xz[:, 1] < self.z1)
        if not self.wrap_time:
            ok &= (t > self.t0 + 1e-9) & (t < self.t1 - 1e-9)
        return ok


@dataclass
class Obstacle:
    """An oriented box obstacle: ``center`` (2,) static or (F, 2) per clock frame from the region
    start (moving; held at the last row afterwards), ``half`` (hx, hz) half extents along its
    lateral/forward axes, ``heading`` (scalar or (F,)), ``height`` (top, m)."""
    center: np.ndarray
    half: tuple
    heading: float | np.ndarray = 0.0
    height: float = 2.0
    name: str = ""

    def __post_init__(self):
        self.center = np.asarray(self.center, np.float64)
        self.half = tuple(float(h) for h in self.half)
        self.heading = np.asarray(self.heading, np.float64)

    @property
    def moving(self) -> bool:
        return self.center.ndim == 2

    def at(self, frames):
        """(centre (n, 2), heading (n,)) at clock frames (relative to the region start)."""
        frames = np.asarray(frames, np.int64)
        if self.moving:
            f = np.clip(frames, 0, len(self.center) - 1)
            c = self.center[f]
            h = self.heading[f] if self.heading.ndim else np.full(len(frames), float(self.heading))
        else:
            c = np.broadcast_to(self.center, (len(frames), 2))
            h = np.full(len(frames), float(self.heading))
        return c, h


@dataclass
class Portal:
    """Source (characters may enter: dangling entries allowed), sink (may leave: dangling exits
    allowed) or both, a disc of ``radius`` about (x, z)."""
    x: float
    z: float
    radius: float
    kind: str = "both"

    def __post_init__(self):
        if self.kind not in ("source", "sink", "both"):
            raise ValueError(f"portal kind must be source, sink or both, not {self.kind!r}")


@dataclass
class Preference:
    """Eq. 7: ``F = exp(-f1/s1) exp(-f2/s2) exp(-f3/s3) exp(-f4/s4)`` with ``f1`` the squared
    distance of the instance (``at="centre"``) or of its exits' mean (``at="exits"``) to
    ``target``, ``f2`` the squared heading difference to ``heading``, ``f3`` the squared time
    difference to ``time``, ``f4`` the summed ``label_cost`` of the patch's labels. ``size_power``
    biases Algorithm 1 towards larger patches (characters x seconds)."""
    target: tuple | None = None
    sigma_pos: float = 8.0
    heading: float | None = None
    sigma_dir: float = 1.0
    time: float | None = None
    sigma_time: float = 8.0
    label_cost: dict = field(default_factory=dict)
    sigma_label: float = 1.0
    at: str = "centre"
    size_power: float = 1.0

    def label_factor(self, labels) -> float:
        f4 = sum(float(self.label_cost.get(l, 0.0)) for l in labels)
        return math.exp(-f4 / self.sigma_label)

    def place_log(self, pos, heading, t):
        """log F without the label term, vectorized over candidates."""
        out = np.zeros(np.shape(t), np.float64)
        if self.target is not None:
            d = np.asarray(pos) - np.asarray(self.target, np.float64)
            out -= np.sum(d * d, axis=-1) / self.sigma_pos
        if self.heading is not None:
            dh = (np.asarray(heading) - self.heading + np.pi) % (2 * np.pi) - np.pi
            out -= dh * dh / self.sigma_dir
        if self.time is not None:
            dt = np.asarray(t) - self.time
            out -= dt * dt / self.sigma_time
        return out


@dataclass
class TilerConfig:
    alpha: float = 0.2
    k: float = 0.03
    T_max: float = 200.0
    dT: float = 1.0
    i_max: int = 300                  # Algorithm 1: samples in a row without acceptance
    seeds: int | None = None          # Algorithm 1: at most this many unanchored placements
    anchor_prob: float = 0.5
    match_pos: float = 0.35           # m: a port stitches to a dangling port this close ...
    match_dir: float = 20.0           # deg
    match_time: float = 0.3           # s
    jitter_min: tuple = (0.6, 15.0, 0.3)
    jitter_max: tuple = (1.0, 25.0, 0.5)
    jitter_tries: int = 8
    max_candidates: int = 32          # Algorithm 2: candidates tried per dangling port per visit
    margin: float = 0.01              # collision margin (m): covers pose blending between frames
    cell: float | None = None         # space-time hash cell (m); default: from the library's largest box
    max_query_margin: float = 0.25    # largest margin a query may use (sets the default cell)
    limits: Limits = DEFAULT_LIMITS
    fps: float = 30.0
    max_removals: int = 100000
    rigid_step: float = 0.005         # m: an exactly aligned stitch whose Eq. 2 step differs by less stays rigid


def tiling_energy(nc: int, nd: int, alpha: float) -> float:
    """Eq. 6."""
    n = nc + nd
    if n == 0:
        return 1.0 + alpha
    return nd / n + alpha / n


# ---------------------------------------------------------------------------------------------
class PreparedPatch:
    """A library patch with its factorised deformer and flat tables for the tiler."""

    def __init__(self, patch, index: int):
        self.patch = patch
        self.index = index
        d = PatchDeformer(patch)
        self.deformer = d
        self.N = d.N
        self.K = d.K
        self.frag_start = d.frag_start
        # per-frame boxes dilated over the neighbouring frames of the same fragment: samples
        # between frames (clock resampling, time deformation) stay inside
        bx = []
        for b in patch.boxes:
            b = b.astype(np.float64)
            lo = np.minimum(np.minimum(b[:, :3], np.roll(b[:, :3], 1, 0)), np.roll(b[:, :3], -1, 0))
            hi = np.maximum(np.maximum(b[:, 3:], np.roll(b[:, 3:], 1, 0)), np.roll(b[:, 3:], -1, 0))
            lo[0], lo[-1] = np.minimum(b[0, :3], b[1, :3]), np.minimum(b[-1, :3], b[-2, :3])
            hi[0], hi[-1] = np.maximum(b[0, 3:], b[1, 3:]), np.maximum(b[-1, 3:], b[-2, 3:])
            bx.append(np.concatenate([lo, hi], 1))
        self.box = np.concatenate(bx)
        self.port_frame = d.port_frame
        self.port_nb = d.port_nb
        self.port_xz = d.xz[d.port_frame]
        self.port_dir = d.heading[d.port_frame]
        self.port_time = d.time[d.port_frame]
        self.port_kind = np.tile([0, 1], self.K)
        self.port_class = np.array([[f.entry_class, f.exit_class] for f in patch.fragments]).reshape(-1)
        self.port_open = np.array([[f.entry_open, f.exit_open] for f in patch.fragments]).reshape(-1)
        hd = np.hypot(np.maximum(-self.box[:, 0], self.box[:, 3]), np.maximum(-self.box[:, 2], self.box[:, 5]))
        self.radius = float(np.max(np.hypot(d.xz[:, 0], d.xz[:, 1]) + hd))
        self.size = patch.num_characters * max(patch.duration, 1.0 / patch.fps)
        self.half_diag = float(np.max(np.hypot(0.5 * (self.box[:, 3] - self.box[:, 0]), 0.5 * (self.box[:, 5] - self.box[:, 2]))))
        self.t_start = float(d.time.min())
        self.t_end = float(d.time.max())


class PreparedLibrary:
    def __init__(self, library: PatchLibrary):
        self.library = library
        self.patches = [PreparedPatch(p, i) for i, p in enumerate(library.patches)]
        # library ports by (kind, class): arrays of (patch, port)
        self.by_port: dict = {}
        for pp in self.patches:
            for j in range(2 * pp.K):
                if pp.port_open[j]:
                    self.by_port.setdefault((int(pp.port_kind[j]), int(pp.port_class[j])), []).append((pp.index, j))
        self.by_port = {k: np.array(v, np.int64) for k, v in self.by_port.items()}

    def __len__(self):
        return len(self.patches)


# ---------------------------------------------------------------------------------------------
@dataclass
class Candidate:
    p: int
    place: tuple                       # x, z, heading, t
    conns: list                        # [(port, dangling key)]
    xz: np.ndarray                     # deformed world arrays (N, 2)
    heading: np.ndarray
    time: np.ndarray
    r: np.ndarray                      # handle offsets (patch frame), zero for held ports
    limits_ok: bool
    worst: tuple
    d_danglings: int = 0               # N' - N
    d_connected: int = 0               # N_c' - N_c
    _samples: tuple | None = None


@dataclass
class _Inst:
    id: int
    p: int
    place: tuple
    xz: np.ndarray
    heading: np.ndarray
    time: np.ndarray
    r: np.ndarray
    fixed: bool
    links: list                        # per port: (inst id, port) or None
    samples: tuple | None = None       # frames, frag, sidx, xz, heading (for tracks)


class _Danglings:
    """Open-port table (unstitched ports of all instances), arrays for vectorized matching."""
    COLS = 10   # x, z, dir, time, stepx, stepz, kind, class, open, counts

    def __init__(self):
        self.rows = np.zeros((256, self.COLS))
        self.live = np.zeros(256, bool)
        self.key = [None] * 256
        self.where: dict = {}
        self.n = 0
        self.free: list = []

    def add(self, key, vals):
        if self.free:
            i = self.free.pop()
        else:
            if self.n == len(self.live):
                self.rows = np.concatenate([self.rows, np.zeros_like(self.rows)])
                self.live = np.concatenate([self.live, np.zeros_like(self.live)])
                self.key += [None] * len(self.key)
            i = self.n
            self.n += 1
        self.rows[i] = vals
        self.live[i] = True
        self.key[i] = key
        self.where[key] = i

    def remove(self, key):
        i = self.where.pop(key)
        self.live[i] = False
        self.key[i] = None
        self.free.append(i)

    def counting(self):
        return int(np.count_nonzero(self.live[:self.n] & (self.rows[:self.n, 9] > 0)))


class TilingState:
    """The tiling under construction: instances, dangling ports, box index, obstacles.

    Shared by the static :class:`Tiler` and :class:`~runtime.tiling.interactive.InteractiveTiling`.
    """

    def __init__(self, prepared: PreparedLibrary, region: Region, obstacles=(), portals=(),
                 config: TilerConfig | None = None, seed: int = 0, preference: Preference | None = None):
        self.lib = prepared
        self.region = region
        self.obstacles = list(obstacles)
        self.portals = list(portals)
        self.cfg = config or TilerConfig()
        self.pref = preference or Preference()
        self.rng = np.random.default_rng(seed)
        self.fps = self.cfg.fps
        self.F0 = int(round(region.t0 * self.fps))
        self.F1 = int(round(region.t1 * self.fps))
        w, h = region.size
        self.period = np.array([w, h]) if region.wrap_space else None
        self.tperiod = (region.t1 - region.t0) if region.wrap_time else None
        hd = max(pp.half_diag for pp in prepared.patches)
        cell = self.cfg.cell or (2 * hd + max(self.cfg.margin, self.cfg.max_query_margin) + 0.05)
        self.index = BoxIndex(cell, origin=(region.x0, region.z0), max_half_diag=hd + 1e-6,
                              period_x=w if region.wrap_space else None, period_z=h if region.wrap_space else None,
                              period_t=(self.F1 - self.F0) if region.wrap_time else None)
        self.inst: dict[int, _Inst] = {}
        self.dang = _Danglings()
        self.nc = 0
        self.next_id = 0
        self.history: dict = {}
        self.stats = {"evaluated": 0, "invalid_limits": 0, "invalid_collision": 0, "committed": 0, "removed": 0}

    # -- geometry helpers -----------------------------------------------------------------------
    def _wrap_d(self, d):
        if self.period is not None:
            d = d - self.period * np.round(d / self.period)
        return d

    def _wrap_t(self, dt):
        if self.tperiod is not None:
            dt = dt - self.tperiod * np.round(dt / self.tperiod)
        return dt

    def _counts(self, kind, cls, open_, pos, t):
        """Whether an unstitched port would count as dangling."""
        reg = self.region
        x, z, t = float(pos[0]), float(pos[1]), float(t)
        if not reg.wrap_space and not (reg.x0 < x < reg.x1 and reg.z0 < z < reg.z1):
            return False
        if not reg.wrap_time and not (reg.t0 + 1e-9 < t < reg.t1 - 1e-9):
            return False
        for pt in self.portals:
            if math.hypot(pos[0] - pt.x, pos[1] - pt.z) <= pt.radius:
                if (kind == 0 and pt.kind in ("source", "both")) or (kind == 1 and pt.kind in ("sink", "both")):
                    return False
        return True

    def energy(self) -> float:
        return tiling_energy(self.nc, self.dang.counting(), self.cfg.alpha)

    @property
    def num_danglings(self) -> int:
        return self.dang.counting()

    # -- candidates --------------------------------------------------------------------------------
    def place_ports(self, p, place):
        pp = self.lib.patches[p]
        x, z, th, t = place
        return _rot(pp.port_xz, th) + (x, z), pp.port_dir + th, pp.port_time + t

    def plan(self, p: int, place, forced=(), match_others: bool = True):
        """Stitch plan of patch ``p`` at a rigid placement: the ports to stitch (``forced``
        [(port, dangling key)] plus every other open port within the matching thresholds of a
        dangling port, best first, one partner each) and the change in dangling and connected
        port counts. Cheap (no deformation)."""
        pp = self.lib.patches[p]
        cfg = self.cfg
        ppos, pdir, ptime = self.place_ports(p, place)
        conns = list(forced)
        used_ports = {j for j, _ in conns}
        D = self.dang
        used_rows = {D.where[k] for _, k in conns}
        if match_others and D.n:
            js = np.array([j for j in range(2 * pp.K) if j not in used_ports and pp.port_open[j]], np.int64)
            live = np.flatnonzero(D.live[:D.n] & (D.rows[:D.n, 8] > 0))
            if len(live) and len(js):
                R = D.rows[live]
                # ports x danglings
                m = (R[None, :, 6] == (1 - pp.port_kind[js])[:, None]) & (R[None, :, 7] == pp.port_class[js][:, None])
                if m.any():
                    jj, ii = np.nonzero(m)
                    dd = self._wrap_d(R[ii, :2] - ppos[js[jj]])
                    dist = np.hypot(dd[:, 0], dd[:, 1])
                    da = np.degrees(np.abs((R[ii, 2] - pdir[js[jj]] + np.pi) % (2 * np.pi) - np.pi))
                    dt = np.abs(self._wrap_t(R[ii, 3] - ptime[js[jj]]))
                    ok = (dist <= cfg.match_pos) & (da <= cfg.match_dir) & (dt <= cfg.match_time)
                    if ok.any():
                        sc = dist / cfg.match_pos + da / cfg.match_dir + dt / cfg.match_time
                        for q in np.flatnonzero(ok)[np.argsort(sc[ok], kind="stable")]:
                            j, row = int(js[jj[q]]), int(live[ii[q]])
                            if j in used_ports or row in used_rows:
                                continue
                            used_ports.add(j)
                            used_rows.add(row)
                            conns.append((j, D.key[row]))
        dn = -sum(1 for _, key in conns if D.rows[D.where[key], 9] > 0)
        for j in range(2 * pp.K):
            if j not in used_ports and self._counts(pp.port_kind[j], pp.port_class[j], pp.port_open[j], ppos[j], ptime[j]):
                dn += 1
        return conns, dn, 2 * len(conns)

    def evaluate(self, p: int, place, forced=(), match_others: bool = True, plan=None) -> Candidate:
        """Place patch ``p`` rigidly, stitch it (:meth:`plan`), deform it (stitched ports dragged
        onto their partners, Eq. 1-3; the others held) and check the limits (collisions are left
        to :meth:`valid`)."""
        self.stats["evaluated"] += 1
        pp = self.lib.patches[p]
        cfg = self.cfg
        x, z, th, t = place
        conns, dn, dc = plan if plan is not None else self.plan(p, place, forced, match_others)
        ppos, pdir, ptime = self.place_ports(p, place)
        D = self.dang
        d = pp.deformer
        r = np.zeros(d.num_port_rows)
        cols = []
        for j, key in conns:
            row = D.rows[D.where[key]]
            tgt = ppos[j] + self._wrap_d(row[:2] - ppos[j])
            tt = ptime[j] + self._wrap_t(row[3] - ptime[j])
            lp = _rot(tgt - (x, z), -th)
            step = _rot(row[4:6], -th)
            f, nb = d.port_frame[j], d.port_nb[j]
            dth = (row[2] - th) - d.heading[f]
            dth = (dth + np.pi) % (2 * np.pi) - np.pi
            r[6 * j:6 * j + 6] = [lp[0] - d.xz[f, 0], lp[1] - d.xz[f, 1],
                                  lp[0] + step[0] - d.xz[nb, 0], lp[1] + step[1] - d.xz[nb, 1],
                                  dth, (tt - t) - d.time[f]]
            cols.extend(range(6 * j, 6 * j + 6))
        if cols:
            cols = np.array(cols)
        rc = r.reshape(-1, 6)
        if len(cols) and (np.max(np.abs(rc[:, [0, 1, 4, 5]])) > 1e-6 or np.max(np.abs(rc[:, 2:4])) > cfg.rigid_step):
            lxz, lh, lt = d.deform(r, cols)
            st, be, sh = deformation_measures(d.xz, d.heading, d.time, lxz, lh, lt, d.seg_valid, cfg.limits.min_segment)
            worst = (float(st.max(initial=0)), float(be.max(initial=0)), float(sh.max(initial=0)))
            ok = cfg.limits.ok(*worst)
        else:
            lxz, lh, lt = d.xz, d.heading, d.time
            worst, ok = (0.0, 0.0, 0.0), True
        wxz = _rot(lxz, th) + (x, z)
        return Candidate(p, tuple(float(v) for v in place), conns, wxz, lh + th, lt + t, r, ok, worst, dn, dc)

    def samples(self, cand_or_inst):
        """Clock-frame samples of an instance: (frames, frag, source index (float), xz, heading,
        box centre, lateral axis, hx, hz, ylo, yhi); frames inside the scene only (or wrapped)."""
        c = cand_or_inst
        cached = c._samples if isinstance(c, Candidate) else c.samples
        if cached is not None:
            return cached
        pp = self.lib.patches[c.p]
        fs = pp.frag_start
        fr, fg, si = [], [], []
        for k in range(pp.K):
            a, b = fs[k], fs[k + 1]
            tau = c.time[a:b]
            q0 = math.ceil(tau[0] * self.fps - 1e-6)
            q1 = math.ceil(tau[-1] * self.fps - 1e-6)
            if not self.region.wrap_time:
                q0, q1 = max(q0, self.F0), min(q1, self.F1 + 1)
            if q1 <= q0:
                continue
            q = np.arange(q0, q1)
            fr.append(q)
            fg.append(np.full(len(q), k))
            si.append(a + np.interp(q / self.fps, tau, np.arange(b - a, dtype=np.float64)))
        if fr:
            frames = np.concatenate(fr)
            frag = np.concatenate(fg)
            s = np.concatenate(si)
        else:
            frames = np.zeros(0, np.int64)
            frag = np.zeros(0, np.int64)
            s = np.zeros(0)
        i0 = np.floor(s).astype(np.int64)
        i1 = np.minimum(i0 + 1, pp.N - 1)
        w = (s - i0)[:, None]
        xz = c.xz[i0] * (1 - w) + c.xz[i1] * w
        hd = c.heading[i0] * (1 - w[:, 0]) + c.heading[i1] * w[:, 0]
        box = pp.box[np.rint(s).astype(np.int64)]
        out = (frames, frag, s, xz, hd) + box_samples(xz, hd, box)
        if isinstance(c, Candidate):
            c._samples = out
        else:
            c.samples = out
        return out

    def rigid_candidate(self, p: int, place, conns) -> Candidate:
        """A candidate placed exactly on its stitched ports (no deformation: the caller aligned
        it, e.g. on a character's tail); limits trivially hold."""
        pp = self.lib.patches[p]
        d = pp.deformer
        x, z, th, t = place
        return Candidate(p, tuple(float(v) for v in place), list(conns), _rot(d.xz, th) + (x, z), d.heading + th,
                         d.time + t, np.zeros(d.num_port_rows), True, (0.0, 0.0, 0.0), 0, 2 * len(conns))

    def rigid_batch_free(self, ps, places, margin: float | None = None, counts: bool = False, probe: int = 0,
                         ignore=None):
        """:meth:`first_free` for rigidly placed *single-fragment* patches, with every
        candidate's clock samples built in one vectorized pass (no per-candidate Python).

        ``probe`` > 0 also extrapolates each candidate ``probe`` frames past its end (braking to
        a stop from its last velocity, last box) and returns ``(first free, main hits, probe
        hits)``: a look-ahead for room to stop safely after the patch."""
        lib = self.lib
        ps = np.asarray(ps, np.int64)
        pl = np.asarray(places, np.float64).reshape(-1, 4)
        n = len(ps)
        if n == 0:
            return (-1, np.zeros(0, np.int64)) if counts else -1
        if not hasattr(lib, "_flat_rest"):
            lib._flat_rest = (np.concatenate([pp.deformer.xz for pp in lib.patches]),
                              np.concatenate([pp.deformer.heading for pp in lib.patches]),
                              np.concatenate([pp.box for pp in lib.patches]),
                              np.concatenate([[0], np.cumsum([pp.N for pp in lib.patches])]).astype(np.int64),
                              np.array([pp.deformer.time[0] for pp in lib.patches]))
        rxz, rh, rbox, start, t0 = lib._flat_rest
        fps = self.fps
        ta = (pl[:, 3] + t0[ps]) * fps                     # source frame 0 on the clock (frames)
        Nf = start[ps + 1] - start[ps]
        q0 = np.ceil(ta - 1e-6).astype(np.int64)
        q1 = np.ceil(ta + (Nf - 1) - 1e-6).astype(np.int64)
        if not self.region.wrap_time:
            q0 = np.maximum(q0, self.F0)
            q1 = np.minimum(q1, self.F1 + 1)
        cnt = np.maximum(q1 - q0, 0)
        tot = int(cnt.sum())
        owner = np.repeat(np.arange(n), cnt)
        q = np.repeat(q0 - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(tot)
        s = q - ta[owner]
        i0 = np.floor(s).astype(np.int64)
        w = s - i0
        i1 = np.minimum(i0 + 1, Nf[owner] - 1)
        g0 = start[ps][owner] + i0
        g1 = start[ps][owner] + i1
        lxz = rxz[g0] * (1 - w)[:, None] + rxz[g1] * w[:, None]
        th = pl[owner, 2]
        c, sn = np.cos(th), np.sin(th)
        xz = np.stack([c * lxz[:, 0] + sn * lxz[:, 1] + pl[owner, 0], c * lxz[:, 1] - sn * lxz[:, 0] + pl[owner, 1]], 1)
        hd = rh[g0] * (1 - w) + rh[g1] * w + th
        box = rbox[start[ps][owner] + np.rint(s).astype(np.int64)]
        if probe and tot:
            last = np.cumsum(cnt) - 1
            has = cnt >= 2
            li = last[has]
            v = xz[li] - xz[li - 1]
            k = np.tile(np.arange(1, probe + 1), len(li))
            rep = np.repeat(np.arange(len(li)), probe)
            q = np.concatenate([q, q[li][rep] + k])
            xz = np.concatenate([xz, xz[li][rep] + v[rep] * braking(k, probe)[:, None]])
            hd = np.concatenate([hd, hd[li][rep]])
            box = np.concatenate([box, box[li][rep]])
            owner = np.concatenate([owner, n + np.flatnonzero(has)[rep]])
            tot = len(q)
        cen, lat, hx, hz, ylo, yhi = box_samples(xz, hd, box)
        nb = 2 * n if probe else n
        bad = np.zeros(nb, np.int64)
        m = self.cfg.margin if margin is None else margin
        for ob in self.obstacles:
            oc, oh = ob.at(q - self.F0)
            d = self._wrap_d(oc - cen)
            olat = np.stack([np.cos(oh), -np.sin(oh)], 1)
            hit = obb_overlap(np.zeros_like(d), lat, hx, hz, d, olat, np.full(tot, ob.half[0]),
                              np.full(tot, ob.half[1]), m) & (ylo < ob.height)
            bad += np.bincount(owner[hit], minlength=nb)
        if tot:
            hit = self.index.query(q, cen, lat, hx, hz, ylo, yhi, margin=m, first_only=False, ignore=ignore)
            bad += np.bincount(owner[hit], minlength=nb)
        if probe:
            main, pr = bad[:n], bad[n:]
            free = np.flatnonzero((main == 0) & (pr == 0))
            return (int(free[0]) if len(free) else -1), main, pr
        free = np.flatnonzero(bad == 0)
        f = int(free[0]) if len(free) else -1
        return (f, bad) if counts else f

    def first_free(self, cands, margin: float | None = None, counts: bool = False):
        """Index of the first candidate (in order) that collides with nothing, -1 if none: one
        batched space-time query for all of them. ``counts``: also return the number of
        colliding samples per candidate."""
        if not cands:
            return (-1, np.zeros(0, np.int64)) if counts else -1
        parts = [self.samples(c) for c in cands]
        owner = np.concatenate([np.full(len(s[0]), k) for k, s in enumerate(parts)])
        cols = [np.concatenate([s[i] for s in parts]) for i in range(11)]
        fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = cols
        bad = np.zeros(len(cands), np.int64)
        m = self.cfg.margin if margin is None else margin
        for ob in self.obstacles:
            oc, oh = ob.at(fr - self.F0)
            d = self._wrap_d(oc - cen)
            olat = np.stack([np.cos(oh), -np.sin(oh)], 1)
            hit = obb_overlap(np.zeros_like(d), lat, hx, hz, d, olat, np.full(len(fr), ob.half[0]),
                              np.full(len(fr), ob.half[1]), m) & (ylo < ob.height)
            bad += np.bincount(owner[hit], minlength=len(cands))
        if len(fr):
            hit = self.index.query(fr, cen, lat, hx, hz, ylo, yhi, margin=m, first_only=False)
            bad += np.bincount(owner[hit], minlength=len(cands))
        free = np.flatnonzero(bad == 0)
        f = int(free[0]) if len(free) else -1
        return (f, bad) if counts else f

    def collides(self, cand, ignore=None, margin: float | None = None) -> bool:
        fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = self.samples(cand)
        if len(fr) == 0:
            return False
        m = self.cfg.margin if margin is None else margin
        for ob in self.obstacles:
            oc, oh = ob.at(fr - self.F0)
            d = self._wrap_d(oc - cen)
            ylap = ylo < ob.height
            if not ylap.any():
                continue
            olat = np.stack([np.cos(oh), -np.sin(oh)], 1)
            hit = obb_overlap(np.zeros_like(d), lat, hx, hz, d, olat, np.full(len(fr), ob.half[0]),
                              np.full(len(fr), ob.half[1]), m) & ylap
            if hit.any():
                return True
        return bool(self.index.query(fr, cen, lat, hx, hz, ylo, yhi, margin=m, ignore=ignore))

    def reserve(self, owner: int, frames, xz, heading, box) -> None:
        """(Re)place extra boxes owned by ``owner`` (not an instance): e.g. where a character is
        expected to be just after its last committed frame."""
        self.index.remove_owner(owner)
        cen, lat, hx, hz, ylo, yhi = box_samples(np.asarray(xz, np.float64), np.asarray(heading, np.float64), box)
        self.index.insert(owner, frames, cen, lat, hx, hz, ylo, yhi)

    def valid(self, cand) -> bool:
        if not cand.limits_ok:
            self.stats["invalid_limits"] += 1
            return False
        if self.collides(cand):
            self.stats["invalid_collision"] += 1
            return False
        return True

    # -- commit / remove ----------------------------------------------------------------------------
    def _port_values(self, inst, j):
        pp = self.lib.patches[inst.p]
        f, nb = pp.port_frame[j], pp.port_nb[j]
        pos = inst.xz[f]
        return pos, float(inst.heading[f]), float(inst.time[f]), pos - inst.xz[nb]

    def _add_dangling(self, inst, j):
        pp = self.lib.patches[inst.p]
        pos, hd, t, step = self._port_values(inst, j)
        kind, cls, op = int(pp.port_kind[j]), int(pp.port_class[j]), bool(pp.port_open[j])
        counts = self._counts(kind, cls, op, pos, t)
        self.dang.add((inst.id, j), [pos[0], pos[1], hd, t, step[0], step[1], kind, cls, float(op), float(counts)])

    def commit(self, cand: Candidate, fixed: bool = False) -> int:
        iid = self.next_id
        self.next_id += 1
        pp = self.lib.patches[cand.p]
        inst = _Inst(iid, cand.p, cand.place, cand.xz, cand.heading, cand.time, cand.r, fixed, [None] * (2 * pp.K))
        inst.samples = cand._samples
        self.inst[iid] = inst
        fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = self.samples(inst)
        self.index.insert(iid, fr, cen, lat, hx, hz, ylo, yhi)
        for j, key in cand.conns:
            oi, oj = key
            self.dang.remove(key)
            self.inst[oi].links[oj] = (iid, j)
            inst.links[j] = (oi, oj)
            self.nc += 2
        for j in range(2 * pp.K):
            if inst.links[j] is None:
                self._add_dangling(inst, j)
        self.stats["committed"] += 1
        return iid

    def remove(self, iid: int) -> None:
        inst = self.inst.pop(iid)
        self.index.remove_owner(iid)
        for j, link in enumerate(inst.links):
            if link is None:
                self.dang.remove((iid, j))
            else:
                oi, oj = link
                other = self.inst[oi]
                other.links[oj] = None
                self.nc -= 2
                self._add_dangling(other, oj)
                self.history.setdefault((oi, oj), set()).add(inst.p)
        self.stats["removed"] += 1

    # -- results ------------------------------------------------------------------------------------
    def result(self, **info) -> "TilingResult":
        ids = sorted(self.inst)
        insts = [self.inst[i] for i in ids]
        pos = {iid: k for k, iid in enumerate(ids)}
        links = []
        for k, inst in enumerate(insts):
            for j, l in enumerate(inst.links):
                if l is not None and j % 2 == 1:
                    links.append((k, j // 2, pos[l[0]], l[1] // 2))
        return TilingResult(self.lib.library, self.region, [i.p for i in insts], [i.place for i in insts],
                            [i.fixed for i in insts], [i.xz for i in insts], [i.heading for i in insts],
                            [i.time for i in insts], np.array(links, np.int64).reshape(-1, 4),
                            self.obstacles, self.portals, self.fps, dict(info))


# ---------------------------------------------------------------------------------------------
class Tiler(TilingState):
    """Static tiling: keyframes, then :meth:`phase1` (Algorithm 1), then :meth:`phase2`
    (Algorithm 2). :meth:`run` does all and returns a :class:`TilingResult`."""

    def __init__(self, library, region: Region, obstacles=(), portals=(), config: TilerConfig | None = None,
                 seed: int = 0, preference: Preference | None = None):
        prepared = library if isinstance(library, PreparedLibrary) else PreparedLibrary(library)
        super().__init__(prepared, region, obstacles, portals, config, seed, preference)
        lib = prepared.library
        self.weights = np.array([pp.size ** self.pref.size_power * self.pref.label_factor(pp.patch.labels)
                                 for pp in prepared.patches])
        self.anchor_weights = np.array([self.pref.label_factor(pp.patch.labels) for pp in prepared.patches])
        self.timing = {"phase1": 0.0, "phase2": 0.0}
        self.free_placements = 0
        self._name_index = {p.name: i for i, p in enumerate(lib.patches)}

    # -- control ---------------------------------------------------------------------------------
    def add_keyframe(self, patch, x: float, z: float, heading: float, t: float, check: bool = True) -> int:
        """Place a patch instance the user chose (fixed; never deformed or removed). ``patch`` is
        a library index or name; ``(x, z, heading)`` place the patch frame's origin; ``t`` is the
        time of the patch's t=0."""
        p = self._name_index[patch] if isinstance(patch, str) else int(patch)
        cand = self.evaluate(p, (x, z, heading, t), match_others=True)
        if check and self.collides(cand):
            raise ValueError(f"keyframe {self.lib.patches[p].patch.name!r} at ({x}, {z}, t={t}) collides with the tiling")
        return self.commit(cand, fixed=True)

    # -- sampling --------------------------------------------------------------------------------
    def _random_place(self, p):
        pp = self.lib.patches[p]
        reg = self.region
        best = None
        for _ in range(20):
            x = self.rng.uniform(reg.x0, reg.x1)
            z = self.rng.uniform(reg.z0, reg.z1)
            th = self.rng.uniform(-np.pi, np.pi)
            t = self.rng.uniform(reg.t0 - 0.5 * pp.t_end, reg.t1 - 0.5 * pp.t_end)
            best = (x, z, th, t)
            lf = self.pref.place_log(np.array([x, z]), th, t + 0.5 * pp.t_end)
            if self.rng.random() < math.exp(float(lf)):
                break
        return best

    def _align(self, p, j, row):
        """Placement that puts port ``j`` of patch ``p`` on dangling row values."""
        pp = self.lib.patches[p]
        th = float(row[2] - pp.port_dir[j])
        pos = row[:2] - _rot(pp.port_xz[j], th)
        return (float(pos[0]), float(pos[1]), float(th), float(row[3] - pp.port_time[j]))

    def _anchored_candidate(self):
        D = self.dang
        live = np.flatnonzero(D.live[:D.n] & (D.rows[:D.n, 9] > 0) & (D.rows[:D.n, 8] > 0))
        if len(live) == 0:
            return None
        row_i = int(live[self.rng.integers(len(live))])
        row = D.rows[row_i]
        ports = self.lib.by_port.get((1 - int(row[6]), int(row[7])))
        if ports is None or len(ports) == 0:
            return None
        # Eq. 7 as the sampling distribution: label weights times the preference of each
        # placement (no size bias here: a large patch hung on one port adds many danglings)
        logw = np.log(np.maximum(self.anchor_weights[ports[:, 0]], 1e-300))
        if self.pref.target is not None or self.pref.heading is not None or self.pref.time is not None:
            pl = np.array([self._align(int(p), int(j), row) for p, j in ports])
            tc = pl[:, 3] + np.array([0.5 * self.lib.patches[int(p)].t_end for p in ports[:, 0]])
            logw = logw + self.pref.place_log(pl[:, :2], pl[:, 2], tc)
        w = np.exp(logw - logw.max())
        k = int(self.rng.choice(len(ports), p=w / w.sum()))
        p, j = int(ports[k, 0]), int(ports[k, 1])
        return self.evaluate(p, self._align(p, j, row), forced=[(j, D.key[row_i])])

    def _free_candidate(self):
        w = self.weights / self.weights.sum()
        p = int(self.rng.choice(len(w), p=w))
        return self.evaluate(p, self._random_place(p))

    # -- Algorithm 1 -------------------------------------------------------------------------------
    def phase1(self, max_seconds: float | None = None, max_patches: int | None = None) -> dict:
        cfg = self.cfg
        t_start = _time.perf_counter()
        T = cfg.T_max
        i = 0
        tried = accepted = 0
        while i < cfg.i_max:
            if max_seconds is not None and _time.perf_counter() - t_start > max_seconds:
                break
            if max_patches is not None and len(self.inst) >= max_patches:
                break
            free_ok = cfg.seeds is None or self.free_placements < cfg.seeds
            anchored = (not free_ok) or (self.num_danglings > 0 and self.rng.random() < cfg.anchor_prob)
            cand = self._anchored_candidate() if anchored else self._free_candidate()
            tried += 1
            if cand is not None:
                nd = self.num_danglings
                e0 = tiling_energy(self.nc, nd, cfg.alpha)
                e1 = tiling_energy(self.nc + cand.d_connected, nd + cand.d_danglings, cfg.alpha)
                de = e1 - e0
                if de <= 0:
                    acc = True
                elif T > 0:
                    acc = math.exp(-de / (cfg.k * T)) > self.rng.random()
                else:
                    acc = False
                if acc and self.valid(cand):
                    self.commit(cand)
                    accepted += 1
                    if not anchored:
                        self.free_placements += 1
                    i = 0
            T -= cfg.dT
            i += 1
        self.timing["phase1"] += _time.perf_counter() - t_start
        return {"samples": tried, "accepted": accepted, "patches": len(self.inst), "danglings": self.num_danglings,
                "seconds": _time.perf_counter() - t_start}

    # -- Algorithm 2 -------------------------------------------------------------------------------
    def _jitter(self, place, i, n):
        a = i / max(n - 1, 1)
        r_max = self.cfg.jitter_min[0] + a * (self.cfg.jitter_max[0] - self.cfg.jitter_min[0])
        ang = math.radians(self.cfg.jitter_min[1] + a * (self.cfg.jitter_max[1] - self.cfg.jitter_min[1]))
        tm = self.cfg.jitter_min[2] + a * (self.cfg.jitter_max[2] - self.cfg.jitter_min[2])
        rr = r_max * math.sqrt(self.rng.random())
        phi = self.rng.uniform(-np.pi, np.pi)
        x, z, th, t = place
        return (x + rr * math.cos(phi), z + rr * math.sin(phi), th + self.rng.uniform(-ang, ang),
                t + self.rng.uniform(-tm, tm))

    def _ordered_candidates(self, row_i):
        D = self.dang
        row = D.rows[row_i].copy()
        key = D.key[row_i]
        ports = self.lib.by_port.get((1 - int(row[6]), int(row[7])))
        if ports is None:
            return []
        hist = self.history.get(key, set())
        out = []
        for p, j in ports:
            p, j = int(p), int(j)
            if p in hist:
                continue
            place = self._align(p, j, row)
            pp = self.lib.patches[p]
            ppos, pdir, ptime = self.place_ports(p, place)
            centre = np.array(place[:2]) if self.pref.at == "centre" else ppos[pp.port_kind == 1].mean(0)
            lf = float(self.pref.place_log(centre, place[2], place[3] + 0.5 * pp.t_end))
            lf += math.log(max(self.weights[p], 1e-300)) if self.pref.label_cost else 0.0
            out.append((lf + 1e-3 * self.rng.random(), p, j, place))
        # delta-N from the stitch plan: closing stitches first, growing ones dropped (line 5)
        scored = []
        for lf, p, j, place in out:
            plan = self.plan(p, place, forced=[(j, key)])
            if plan[1] > 0:
                continue
            scored.append((plan[1], -lf, p, j, place, plan))
        scored.sort(key=lambda s: (s[0], s[1]))
        return scored[:self.cfg.max_candidates]

    def _blockers(self, key) -> list:
        """Non-keyframe instances overlapping the preferred exact stitch at dangling ``key``."""
        D = self.dang
        row = D.rows[D.where[key]].copy()
        ports = self.lib.by_port.get((1 - int(row[6]), int(row[7])))
        if ports is None:
            return []
        best = None
        for p, j in ports:
            p, j = int(p), int(j)
            if self.lib.patches[p].K != 1:
                continue
            cand = self.evaluate(p, self._align(p, j, row), forced=[(j, key)], match_others=False)
            if not cand.limits_ok:
                continue
            fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = self.samples(cand)
            _, owners = self.index.query(fr, cen, lat, hx, hz, ylo, yhi, margin=self.cfg.margin, first_only=False,
                                         return_owners=True)
            owners = sorted(o for o in owners if o != key[0])
            if any(self.inst[o].fixed for o in owners):
                continue
            if best is None or len(owners) < len(best):
                best = owners
        return best or []

    def _fix(self, key) -> bool:
        """Lines 3-12 of Algorithm 2 for one dangling port: True if a stitched patch was added."""
        cfg = self.cfg
        for dn, _, p, j, place, plan in self._ordered_candidates(self.dang.where[key]):
            n = cfg.jitter_tries
            for i in range(n + 1):
                if i == 0:
                    cand = self.evaluate(p, place, plan=plan)
                else:
                    cand = self.evaluate(p, self._jitter(place, i - 1, n), forced=[(j, key)])
                    if cand.d_danglings > 0:
                        continue
                if self.valid(cand):
                    self.new_id = self.commit(cand)
                    return True
        return False

    def _dangling_ports(self, iid) -> list:
        inst = self.inst.get(iid)
        if inst is None:
            return []
        return [(iid, j) for j, l in enumerate(inst.links)
                if l is None and (iid, j) in self.dang.where and self.dang.rows[self.dang.where[(iid, j)], 9] > 0]

    def phase2(self, max_seconds: float | None = None, max_passes: int = 50, max_steps: int = 200000) -> dict:
        """Algorithm 2. Dangling ports are taken earliest first; the danglings a fix or a removal
        creates are handled right after it (depth first), so a chain is followed to its end."""
        cfg = self.cfg
        t_start = _time.perf_counter()
        removals = 0
        passes = 0
        steps = 0
        stuck = set()
        evictions: dict = {}
        D = self.dang
        while passes < max_passes and steps < max_steps:
            passes += 1
            rows = np.flatnonzero(D.live[:D.n] & (D.rows[:D.n, 9] > 0))
            keys = [D.key[i] for i in rows if D.key[i] not in stuck]
            if not keys:
                break
            order = np.argsort([D.rows[D.where[k], 3] for k in keys], kind="stable")
            stack = [keys[i] for i in order[::-1]]
            changed = False
            while stack and steps < max_steps:
                if max_seconds is not None and _time.perf_counter() - t_start > max_seconds:
                    passes = max_passes
                    break
                key = stack.pop()
                if key in stuck or key not in D.where or D.rows[D.where[key], 9] <= 0:
                    continue
                steps += 1
                if self._fix(key):
                    changed = True
                    stack.extend(self._dangling_ports(self.new_id)[::-1])
                    continue
                owner = key[0]
                if self.inst[owner].fixed and removals < cfg.max_removals and evictions.get(key, 0) < 3:
                    # a keyframe cannot go: remove the (non-keyframe) instances that block the best
                    # stitch at its port instead, and come back to it
                    evictions[key] = evictions.get(key, 0) + 1
                    blockers = self._blockers(key)
                    if blockers:
                        for b in blockers:
                            partners = [l for l in self.inst[b].links if l is not None]
                            self.remove(b)
                            removals += 1
                            stack.extend(partners)
                        stack.append(key)
                        changed = True
                        continue
                if self.inst[owner].fixed or removals >= cfg.max_removals:
                    stuck.add(key)
                    continue
                partners = [l for l in self.inst[owner].links if l is not None]
                self.remove(owner)
                removals += 1
                stack.extend(partners)
                changed = True
            if not changed:
                break
        self.timing["phase2"] += _time.perf_counter() - t_start
        return {"passes": passes, "steps": steps, "removals": removals, "patches": len(self.inst),
                "danglings": self.num_danglings, "stuck": len(stuck), "seconds": _time.perf_counter() - t_start}

    def run(self, max_seconds1: float | None = None, max_seconds2: float | None = None) -> "TilingResult":
        s1 = self.phase1(max_seconds1)
        s2 = self.phase2(max_seconds2)
        return self.result(phase1=s1, phase2=s2, stats=dict(self.stats))


# ---------------------------------------------------------------------------------------------
from .result import TilingResult  # noqa: E402  (result imports nothing from here)
