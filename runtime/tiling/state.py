"""The tiling under construction (Kim, Hwang, Hyun and Lee 2012, section 5): patch instances,
their stitches and dangling ports, and the tiling energy Eq. 6.

* A *patch instance* is a library patch placed rigidly (x, z, heading, time) and then deformed
  by its :class:`~runtime.tiling.deform.PatchDeformer` (Laplacian path deformation, section 3):
  the ports stitched to ports already in the tiling are dragged onto them (Eq. 1-3), the other
  ports are held where the placement put them. Only the new instance deforms; instances already
  in the tiling stay pinned (the interactive rule of section 5.3, also used for the static
  tiler: a simplification of "adjacent patches deform").
* A *dangling* entry/exit is an open port of an instance that is not stitched and lies inside
  the region (strictly inside its rectangle -- unless the space wraps -- and strictly inside its
  time interval -- unless time wraps) and not on a source (entries) or sink (exits). A closed
  port (pose class -1) can only be outside the region or on a source/sink.
* ``IsValid``: the deformation is within :class:`~runtime.tiling.deform.Limits` on every frame
  and the instance's per-frame boxes (resampled on the 30 Hz clock) overlap neither obstacles
  nor boxes of other instances (:class:`~runtime.tiling.occupancy.Occupancy`).

:class:`TilingState` is shared by the static :class:`~runtime.tiling.tiler.Tiler` and the
interactive tiling (:class:`~runtime.tiling.interactive.InteractiveTiling`).
"""
from __future__ import annotations

import math

import numpy as np

from ..motion.planar import rotate_xz_scalar, wrap_angle
from .config import TilerConfig
from .deform import deformation_measures
from .instances import Candidate, DanglingTable, Instance
from .occupancy import Occupancy
from .preference import Preference
from .prepared import PreparedLibrary
from .region import Region, minimum_image
from .result import TilingResult

__all__ = ["TilingState", "tiling_energy"]


def tiling_energy(nc: int, nd: int, alpha: float) -> float:
    """Eq. 6: ``E = N_d / (N_c + N_d) + alpha / (N_c + N_d)`` for ``nc`` connected and ``nd``
    dangling ports (``1 + alpha`` for an empty tiling)."""
    n = nc + nd
    if n == 0:
        return 1.0 + alpha
    return nd / n + alpha / n


class TilingState:
    """The tiling under construction: instances, dangling ports, what they occupy.

    Args:
        prepared: the :class:`~runtime.tiling.prepared.PreparedLibrary`.
        region: the :class:`~runtime.tiling.region.Region` to fill.
        obstacles: :class:`~runtime.tiling.region.Obstacle` s.
        portals: :class:`~runtime.tiling.region.Portal` s (sources and sinks).
        config: the :class:`~runtime.tiling.config.TilerConfig` (default settings if None).
        seed: of the one random generator every draw of the tiling comes from.
        preference: the :class:`~runtime.tiling.preference.Preference` (Eq. 7).
    """

    def __init__(self, prepared: PreparedLibrary, region: Region, obstacles=(), portals=(),
                 config: TilerConfig | None = None, seed: int = 0, preference: Preference | None = None):
        self.lib = prepared
        self.region = region
        self.portals = list(portals)
        self.cfg = config or TilerConfig()
        self.pref = preference or Preference()
        self.rng = np.random.default_rng(seed)
        self.fps = self.cfg.fps
        self.occupancy = Occupancy(prepared, region, obstacles, self.cfg)
        self.obstacles = self.occupancy.obstacles
        self.period = self.occupancy.period
        self.tperiod = (region.t1 - region.t0) if region.wrap_time else None
        self.inst: dict[int, Instance] = {}
        self.dang = DanglingTable()
        self.nc = 0
        self.next_id = 0
        self.history: dict = {}
        self.stats = {"evaluated": 0, "invalid_limits": 0, "invalid_collision": 0, "committed": 0, "removed": 0}

    # -- ports ----------------------------------------------------------------------------------
    def _counts_as_dangling(self, kind, pos, t) -> bool:
        """Whether an unstitched port of ``kind`` (0 entry, 1 exit) at ``pos``, ``t`` would count
        as dangling."""
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

    def place_ports(self, p, place):
        """World (positions (2K, 2), headings, times) of patch ``p``'s ports at a rigid
        placement."""
        pp = self.lib.patches[p]
        x, z, th, t = place
        return rotate_xz_scalar(pp.port_xz, th) + (x, z), pp.port_dir + th, pp.port_time + t

    def ports_matching(self, key):
        """The dangling row of ``key`` (a copy) and the library ports that can stitch to it
        (opposite kind, same pose class; (n, 2) patch, port), or None."""
        row = self.dang.row(key).copy()
        return row, self.lib.by_port.get((1 - int(row[6]), int(row[7])))

    # -- candidates -----------------------------------------------------------------------------
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
                    dd = minimum_image(R[ii, :2] - ppos[js[jj]], self.period)
                    dist = np.hypot(dd[:, 0], dd[:, 1])
                    da = np.degrees(np.abs(wrap_angle(R[ii, 2] - pdir[js[jj]])))
                    dt = np.abs(minimum_image(R[ii, 3] - ptime[js[jj]], self.tperiod))
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
        dn = -sum(1 for _, key in conns if D.row(key)[9] > 0)
        for j in range(2 * pp.K):
            if j not in used_ports and self._counts_as_dangling(pp.port_kind[j], ppos[j], ptime[j]):
                dn += 1
        return conns, dn, 2 * len(conns)

    def _handle_offsets(self, pp, place, conns):
        """Handle offsets (patch frame) that drag each stitched port onto its dangling partner
        (Eq. 1-3; the neighbour frame keeps the partner's Eq. 2 step), and their columns."""
        d = pp.deformer
        x, z, th, t = place
        ppos, _, ptime = self.place_ports(pp.index, place)
        r = np.zeros(d.num_port_rows)
        cols = []
        for j, key in conns:
            row = self.dang.row(key)
            tgt = ppos[j] + minimum_image(row[:2] - ppos[j], self.period)
            tt = ptime[j] + minimum_image(row[3] - ptime[j], self.tperiod)
            lp = rotate_xz_scalar(tgt - (x, z), -th)
            step = rotate_xz_scalar(row[4:6], -th)
            f, nb = d.port_frame[j], d.port_nb[j]
            dth = wrap_angle((row[2] - th) - d.heading[f])
            r[6 * j:6 * j + 6] = [lp[0] - d.xz[f, 0], lp[1] - d.xz[f, 1],
                                  lp[0] + step[0] - d.xz[nb, 0], lp[1] + step[1] - d.xz[nb, 1],
                                  dth, (tt - t) - d.time[f]]
            cols.extend(range(6 * j, 6 * j + 6))
        if cols:
            cols = np.array(cols)
        return r, cols

    def evaluate(self, p: int, place, forced=(), match_others: bool = True, plan=None) -> Candidate:
        """Place patch ``p`` rigidly, stitch it (:meth:`plan`), deform it (stitched ports dragged
        onto their partners, Eq. 1-3; the others held) and check the limits (collisions are left
        to :meth:`valid`)."""
        self.stats["evaluated"] += 1
        pp = self.lib.patches[p]
        cfg = self.cfg
        x, z, th, t = place
        conns, dn, dc = plan if plan is not None else self.plan(p, place, forced, match_others)
        d = pp.deformer
        r, cols = self._handle_offsets(pp, place, conns)
        rc = r.reshape(-1, 6)
        if len(cols) and (np.max(np.abs(rc[:, [0, 1, 4, 5]])) > 1e-6 or np.max(np.abs(rc[:, 2:4])) > cfg.rigid_step):
            lxz, lh, lt = d.deform(r, cols)
            st, be, sh, gl = deformation_measures(d.xz, d.heading, d.time, lxz, lh, lt, d.seg_valid,
                                                  cfg.limits.min_segment)
            worst = (float(st.max(initial=0)), float(be.max(initial=0)), float(sh.max(initial=0)))
            ok = cfg.limits.ok(*worst, float(gl.max(initial=0)))
        else:
            lxz, lh, lt = d.xz, d.heading, d.time
            worst, ok = (0.0, 0.0, 0.0), True
        wxz = rotate_xz_scalar(lxz, th) + (x, z)
        return Candidate(p, tuple(float(v) for v in place), conns, wxz, lh + th, lt + t, r, ok, worst, dn, dc)

    def rigid_candidate(self, p: int, place, conns) -> Candidate:
        """A candidate placed exactly on its stitched ports (no deformation: the caller aligned
        it, e.g. on a character's tail); limits trivially hold."""
        d = self.lib.patches[p].deformer
        x, z, th, t = place
        return Candidate(p, tuple(float(v) for v in place), list(conns), rotate_xz_scalar(d.xz, th) + (x, z),
                         d.heading + th, d.time + t, np.zeros(d.num_port_rows), True, (0.0, 0.0, 0.0), 0,
                         2 * len(conns))

    def valid(self, cand) -> bool:
        """``IsValid``: within the deformation limits and free of collisions."""
        if not cand.limits_ok:
            self.stats["invalid_limits"] += 1
            return False
        if self.occupancy.collides(cand):
            self.stats["invalid_collision"] += 1
            return False
        return True

    # -- commit / remove ------------------------------------------------------------------------
    def _add_dangling(self, inst, j):
        pp = self.lib.patches[inst.p]
        f, nb = pp.port_frame[j], pp.port_nb[j]
        pos = inst.xz[f]
        hd, t, step = float(inst.heading[f]), float(inst.time[f]), pos - inst.xz[nb]
        kind, cls, op = int(pp.port_kind[j]), int(pp.port_class[j]), bool(pp.port_open[j])
        counts = self._counts_as_dangling(kind, pos, t)
        self.dang.add((inst.id, j), [pos[0], pos[1], hd, t, step[0], step[1], kind, cls, float(op), float(counts)])

    def commit(self, cand: Candidate, fixed: bool = False) -> int:
        """Add ``cand`` to the tiling (stitching its planned ports); returns the instance id."""
        iid = self.next_id
        self.next_id += 1
        pp = self.lib.patches[cand.p]
        inst = Instance(iid, cand.p, cand.place, cand.xz, cand.heading, cand.time, cand.r, fixed, [None] * (2 * pp.K))
        inst.samples = cand.samples
        self.inst[iid] = inst
        self.occupancy.insert(iid, inst)
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
        """Take instance ``iid`` out: its partners' ports dangle again, and its patch goes into
        their sampling history (not chosen there again)."""
        inst = self.inst.pop(iid)
        self.occupancy.index.remove_owner(iid)
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

    # -- results --------------------------------------------------------------------------------
    def result(self, **info) -> TilingResult:
        """The instances as a :class:`~runtime.tiling.result.TilingResult` (``info`` is kept
        with it)."""
        return result_of(self.lib.library, self.region, [self.inst[i] for i in sorted(self.inst)], self.obstacles,
                         self.portals, self.fps, dict(info))


def result_of(library, region, insts, obstacles, portals, fps, info) -> TilingResult:
    """A :class:`~runtime.tiling.result.TilingResult` of instances in id order (stitches to
    instances not among them are left out)."""
    pos = {inst.id: k for k, inst in enumerate(insts)}
    links = []
    for k, inst in enumerate(insts):
        for j, l in enumerate(inst.links):
            if l is not None and j % 2 == 1 and l[0] in pos:
                links.append((k, j // 2, pos[l[0]], l[1] // 2))
    return TilingResult(library, region, [i.p for i in insts], [i.place for i in insts], [i.fixed for i in insts],
                        [i.xz for i in insts], [i.heading for i in insts], [i.time for i in insts],
                        np.array(links, np.int64).reshape(-1, 4), obstacles, portals, fps, info)
