"""Footstep planning and foot trajectories ("plan footsteps first, then the body").

A locomotion *run* (standing -> start -> walk edges -> stop -> standing) is laid out in
gait phase ``phi`` measured in steps: heel strike ``k`` happens at ``phi = k``. Speed
``v(phi)``, heading ``theta(phi)`` and a gait amplitude ``a(phi)`` are shaped per edge so
that they are exactly the hub values (speed ``v_hub``, no turning, full amplitude) within
0.4 steps of every hub heel strike; in between, each edge dips or raises the speed and
turns by its own amount. From the human cadence relation

    step frequency  f(v) = 1.0 + 0.65 v  steps/s,   step length  L(v) = v / f(v)

time is ``dt/dphi = 1/f`` and the pelvis path advances ``L(v)`` per step along the heading.
Every edge is then stretched by under one frame so that hub heel strikes fall on whole
frames. Footprint ``k`` lies under the pelvis path 0.43 steps after its heel strike (about
its mid-stance), offset sideways by about half the hip width, with a small toe-out.

Each footprint carries its stance timing (heel strike; foot flat 0.14 steps later; heel
off at 0.65 steps; toe off at 1.2 steps, 1.12-1.28 from fast to slow walking, so double
support = 2 x 0.2 steps = 20 % of the gait cycle at 1.3 m/s) and rocker angles.
:func:`foot_tracks` produces, per frame, the world ankle target and foot orientation:
a planted ankle does not move horizontally at all from heel strike to heel off (during the
heel rocker the foot flattens and the ankle only descends, the heel point sliding by about
a centimetre instead); through the toe rocker the heel rises about the ball of the foot,
which stays exactly fixed (``*ToeBase`` is a joint, so this is checkable); the swing is a
cubic Hermite curve whose start tangent matches the toe rocker and which arrives over the
footprint at 93 % of the swing, with the height following a clearance profile that peaks
early in swing and ends in a short vertical descent onto the heel.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runtime.motion import quat
from runtime.motion.planar import wrap_angle

from . import body
from .curves import bump, bump_integral, hermite, smoothstep, smootherstep
from .rig import qx, qy

__all__ = ["Footprint", "GaitStyle", "WALK", "CARRY", "cadence", "step_length", "foot_tracks",
           "RunPlan", "plan_run", "foot_q"]

HUB_MARGIN = 0.4        # steps around a hub heel strike where the gait is exactly canonical


@dataclass(frozen=True)
class GaitStyle:
    name: str
    v_hub: float            # speed at hub heel strikes (m/s)
    cadence_scale: float    # multiplies 1.0 + 0.65 v
    step_width: float       # lateral offset of a walking footprint from the path (m)
    stand_width: float      # lateral offset of a standing foot (m)
    toe_out: float          # radians
    v_min: float
    v_max: float
    alpha: float            # heel-strike dorsiflexion at v_hub (rad)
    beta: float             # toe-off plantarflexion at v_hub (rad)
    clearance: float        # swing arc height at v_hub (m)
    hub_names: tuple        # (left heel strike hub, right heel strike hub)
    label: str | None       # label for every edge (carry), or None (start/walk/stop)


WALK = GaitStyle("walk", 1.3, 1.0, 0.07, 0.10, np.radians(6.0), 0.6, 1.8,
                 np.radians(14.0), np.radians(64.0), 0.055, ("walk_l", "walk_r"), None)
CARRY = GaitStyle("carry", 1.0, 1.06, 0.08, 0.10, np.radians(6.0), 0.6, 1.3,
                  np.radians(10.0), np.radians(52.0), 0.045, ("carry_l", "carry_r"), "carry")


def cadence(v, style: GaitStyle = WALK):
    """Steps per second at speed v (human reference 1.0 + 0.65 v, scaled for carrying)."""
    return style.cadence_scale * (1.0 + 0.65 * np.asarray(v, dtype=np.float64))


def step_length(v, style: GaitStyle = WALK):
    return np.asarray(v, dtype=np.float64) / cadence(v, style)


def foot_q(yaw, pitch):
    """World foot orientation: heading ``yaw``, toes up by ``pitch`` (down if negative)."""
    return quat.mul(qy(yaw), qx(-np.asarray(pitch, dtype=np.float64)))


@dataclass
class Footprint:
    side: int                  # 0 left, 1 right
    x: float
    z: float
    yaw: float
    t_land: float              # heel strike (-inf: already standing here)
    t_flat: float              # foot flat (end of the heel rocker)
    t_heeloff: float           # start of the toe rocker
    t_lift: float              # toe off (+inf: stays)
    alpha: float = 0.0         # foot pitch (toes up) at heel strike
    beta: float = 0.0          # foot pitch (toes down) at toe off
    clearance: float = 0.05    # height of the swing arc that ends here

    def flat_ankle(self):
        return np.array([self.x, body.ANKLE_HEIGHT, self.z])


def _heel_rocker(fp: Footprint, pitch):
    """Ankle positions (N, 3) and foot rotations (N, 4) for the toes raised by ``pitch``
    with the heel on the floor. The ankle stays exactly above its planted position and only
    descends as the foot flattens (the heel point slides by about a centimetre instead),
    so the planted ankle never moves horizontally."""
    pitch = np.atleast_1d(pitch)
    q = foot_q(np.full(pitch.shape, fp.yaw), pitch)
    heel_y = quat.rotate(q, np.broadcast_to(body.HEEL, pitch.shape + (3,)))[:, 1]
    pos = np.tile(fp.flat_ankle(), (len(pitch), 1))
    pos[:, 1] = -heel_y
    return pos, q


def _toe_rocker(fp: Footprint, drop):
    """Ankle positions and foot rotations for the heel raised by ``drop`` about the ball."""
    drop = np.atleast_1d(drop)
    ry = qy(np.full(drop.shape, fp.yaw))
    ball = fp.flat_ankle() + quat.rotate(ry[0], body.BALL)
    q = foot_q(np.full(drop.shape, fp.yaw), -drop)
    return ball - quat.rotate(q, np.broadcast_to(body.BALL, drop.shape + (3,))), q


def _swing_height(s, y0, vy0, y1, vy1, clearance, arrive):
    """Ankle height over the swing (s in [0, 1], tangents per unit s): up to the clearance
    peak early in swing, low over mid swing, then held about 1.5 cm above the landing
    height until the foot is over its footprint, and a short vertical descent last."""
    from scipy.interpolate import CubicSpline

    ks = [0.0, 0.3, 0.62, arrive, 1.0]
    ys = [y0, max(y0, y1) + clearance, y1 + 0.35 * clearance + 0.012, y1 + 0.018, y1]
    cs = CubicSpline(ks, ys, bc_type=((1, vy0), (1, vy1)))
    return cs(np.clip(s, 0.0, 1.0))


MAX_ALPHA = np.radians(18.0)   # heel-strike dorsiflexion never above this
MAX_BETA = np.radians(62.0)    # toe-off plantarflexion never above this
TOE_RISE = 1.6          # heel rise over the toe rocker grows as u ** TOE_RISE
FOOT_AHEAD = 0.43       # footprint k lies under the pelvis path at phase k + FOOT_AHEAD
SWING_ARRIVE = 0.93     # fraction of the swing at which the foot is over its footprint


def foot_tracks(prints: list[Footprint], times: np.ndarray):
    """Per-frame ankle targets (F, 2, 3), foot rotations (F, 2, 4), toe flexion (F, 2) and
    a swing mask (F, 2) and the toe-rocker progress (F, 2) from the footprints of both feet (each foot's prints in time order)."""
    F = len(times)
    swing_mask = np.zeros((F, 2), dtype=bool)
    roll = np.zeros((F, 2))
    ankle = np.zeros((F, 2, 3))
    fq = np.zeros((F, 2, 4))
    toe = np.zeros((F, 2))
    eps = 1e-4
    for side in (0, 1):
        fps_ = [p for p in prints if p.side == side]
        if not fps_:
            raise ValueError("each foot needs at least one footprint")
        if np.isfinite(fps_[0].t_land) and fps_[0].t_land > times[0]:
            raise ValueError("first footprint of a foot must be planted before the first frame")
        for i, p in enumerate(fps_):
            nxt = fps_[i + 1] if i + 1 < len(fps_) else None
            t_end = nxt.t_land if nxt is not None else np.inf
            # ---- stance: [t_land, t_lift]
            a = np.searchsorted(times, p.t_land, side="left") if np.isfinite(p.t_land) else 0
            b = np.searchsorted(times, min(p.t_lift, t_end), side="right")
            t = times[a:b]
            if len(t):
                pa = np.tile(p.flat_ankle(), (len(t), 1))
                pq = np.tile(foot_q(p.yaw, 0.0), (len(t), 1))
                pt = np.zeros(len(t))
                if p.alpha > 0 and np.isfinite(p.t_land):
                    m = t < p.t_flat
                    if np.any(m):
                        u = (t[m] - p.t_land) / (p.t_flat - p.t_land)
                        pa[m], pq[m] = _heel_rocker(p, p.alpha * (1.0 - u) ** 2)
                if p.beta > 0 and np.isfinite(p.t_lift):
                    m = t > p.t_heeloff
                    if np.any(m):
                        u = (t[m] - p.t_heeloff) / (p.t_lift - p.t_heeloff)
                        d = p.beta * u ** TOE_RISE
                        pa[m], pq[m] = _toe_rocker(p, d)
                        pt[m] = d
                        roll[a:b, side][m] = u
                ankle[a:b, side] = pa
                fq[a:b, side] = pq
                toe[a:b, side] = pt
            if nxt is None or not np.isfinite(p.t_lift):
                continue
            # ---- swing: (t_lift, next.t_land)
            T = nxt.t_land - p.t_lift
            a2 = np.searchsorted(times, p.t_lift, side="right")
            b2 = np.searchsorted(times, nxt.t_land, side="left")
            t = times[a2:b2]
            if not len(t):
                continue
            s = (t - p.t_lift) / T
            # start state (end of toe rocker) and its velocity
            d_hr = max(p.t_lift - p.t_heeloff, 1e-3)
            if p.beta > 0:
                q1 = _toe_rocker(p, np.array([p.beta, p.beta - eps]))[0]
                p0 = q1[0]
                v0 = (q1[0] - q1[1]) / eps * (TOE_RISE * p.beta / d_hr)
                r0 = -TOE_RISE * p.beta / d_hr
            else:
                p0 = p.flat_ankle()
                v0 = np.zeros(3)
                r0 = 0.0
            # end state (start of the heel rocker of the next print)
            d_fl = max(nxt.t_flat - nxt.t_land, 1e-3)
            if nxt.alpha > 0:
                q2 = _heel_rocker(nxt, np.array([nxt.alpha, nxt.alpha - eps]))[0]
                p1 = q2[0]
                v1 = (q2[0] - q2[1]) / eps * (-2.0 * nxt.alpha / d_fl)
                r1 = -2.0 * nxt.alpha / d_fl
            else:
                p1 = nxt.flat_ankle()
                v1 = np.zeros(3)
                r1 = 0.0
            # horizontal: Hermite to the footprint, arriving (at rest) before the descent
            s0 = 0.0 if p.beta > 0.1 else 0.12
            arrive = SWING_ARRIVE if nxt.alpha > 0.05 else 0.8      # short steps land gently
            u = np.clip((s - s0) / (arrive - s0), 0.0, 1.0)
            Th = T * (arrive - s0)
            hv0 = v0 * np.array([1.0, 0.0, 1.0])
            dist = np.linalg.norm((p1 - p0)[[0, 2]]) + 0.02
            n = np.linalg.norm(hv0) * Th
            if n > 1.5 * dist:               # short steps: keep the curve from looping
                hv0 = hv0 * (1.5 * dist / n)
            pos = hermite(p0, hv0 * Th, p1, np.zeros(3), u)
            pos[:, 1] = _swing_height(s, p0[1], v0[1] * T, p1[1], v1[1] * T, nxt.clearance, arrive)
            # pitch: -beta -> mid -> +alpha, two Hermite halves
            p_mid = 0.3 * nxt.alpha + 0.02
            sm = 0.6                                  # foot level again at 60 % of the swing
            m0 = np.clip(r0 * T * sm, -0.6 * (p_mid + p.beta), 0.0)
            m1 = np.clip(r1 * T * (1 - sm), -1.0 * max(nxt.alpha - p_mid, 0.0), 0.0)
            first = s < sm
            pitch = np.where(first,
                             hermite(-p.beta, m0, p_mid, 0.0, np.clip(s / sm, 0, 1)),
                             hermite(p_mid, 0.0, nxt.alpha, m1, np.clip((s - sm) / (1 - sm), 0, 1)))
            yaw = p.yaw + wrap_angle(nxt.yaw - p.yaw) * smootherstep(s)
            ankle[a2:b2, side] = pos
            swing_mask[a2:b2, side] = True
            fq[a2:b2, side] = foot_q(yaw, pitch)
            toe[a2:b2, side] = p.beta * (1.0 - smoothstep(s / 0.65))
    return ankle, fq, toe, swing_mask, roll


# --------------------------------------------------------------------------------------------
# locomotion runs
# --------------------------------------------------------------------------------------------
@dataclass
class RunPlan:
    style: GaitStyle
    times: np.ndarray          # (N,) frame times, s (frame i at i / fps)
    phi: np.ndarray            # (N,) gait phase
    path: np.ndarray           # (N, 2) pelvis path (x, z), no oscillations
    heading: np.ndarray        # (N,)
    speed: np.ndarray          # (N,)
    amp: np.ndarray            # (N,) gait amplitude 0 (standing) .. 1 (walking)
    turn_rate: np.ndarray      # (N,) rad/s
    accel: np.ndarray          # (N,) m/s^2
    look: np.ndarray           # (N,) heading change over the next ~1.2 s (rad)
    prints: list               # footprints (both feet)
    first_side: int            # foot that moves first (0 left, 1 right)
    segments: list             # [(start_frame, end_frame, label)]
    hubs: list                 # [(frame, hub name)]
    end_state: tuple           # (x, z, heading) of the final standing pose


def plan_run(style: GaitStyle, edges, x0, z0, theta0, first_side, fps,
             pre=0.45, post=0.6) -> RunPlan:
    """Lay out one run. ``edges`` = [("start", n, dturn), ("walk", n, dturn, dv)...,
    ("stop", n, dturn)] with ``n`` steps per edge; turns in radians, ``dv`` in m/s."""
    if edges[0][0] != "start" or edges[-1][0] != "stop":
        raise ValueError("a run starts with 'start' and ends with 'stop'")
    # phase layout
    k = 0
    bounds = []
    for e in edges:
        bounds.append((k, k + e[1]))
        k += e[1]
    K = k
    res = 200
    phi = np.linspace(-pre, K + post, int(round((K + post + pre) * res)) + 1)
    v = np.zeros_like(phi)
    th = np.full_like(phi, theta0)
    amp = np.zeros_like(phi)
    m = HUB_MARGIN
    for e, (ka, kb) in zip(edges, bounds):
        kind = e[0]
        if kind == "start":
            x = (phi - ka) / (kb - ka - m)
            v += np.where((phi >= ka) & (phi < kb), style.v_hub * smootherstep(x), 0.0)
            th += e[2] * bump_integral((phi - ka - 0.3) / (kb - ka - 0.3 - m))
        elif kind == "walk":
            x = (phi - ka - m) / (kb - ka - 2 * m)
            v += np.where((phi >= ka) & (phi < kb), style.v_hub + e[3] * bump(x), 0.0)
            th += e[2] * bump_integral(x)
        elif kind == "stop":
            x = (phi - ka - m) / (kb - ka - m - 0.5)
            v += np.where((phi >= ka) & (phi < kb), style.v_hub * (1.0 - smootherstep(x)), 0.0)
            th += e[2] * bump_integral(x)
        else:
            raise ValueError(f"unknown edge kind {kind!r}")
    amp = smoothstep((phi + pre) / (pre + 1.2)) * (1.0 - smoothstep((phi - (K - 1.3)) / (1.3 + 0.7 * post)))
    # time and path by integration over phase
    dphi = np.diff(phi)
    f = cadence(v, style)
    tt = np.concatenate([[0.0], np.cumsum(0.5 * (1 / f[1:] + 1 / f[:-1]) * dphi)])
    L = v / f
    dirs = np.stack([np.sin(th), np.cos(th)], axis=-1)
    seg = 0.5 * (L[1:, None] * dirs[1:] + L[:-1, None] * dirs[:-1]) * dphi[:, None]
    path = np.concatenate([np.zeros((1, 2)), np.cumsum(seg, axis=0)]) + np.array([x0, z0])
    # anchors: run start, hub heel strikes, run end -> whole frames
    anchors_phi = [phi[0]] + [b for (_, b) in bounds[:-1]] + [phi[-1]]
    anchors_t = np.interp(anchors_phi, phi, tt)
    frames = np.maximum(np.round(np.diff(anchors_t) * fps), 1).astype(int)
    anchor_frames = np.concatenate([[0], np.cumsum(frames)])
    tw = np.interp(tt, anchors_t, anchor_frames / fps)     # warped time per phase sample
    N = int(anchor_frames[-1]) + 1
    times = np.arange(N) / fps
    phi_f = np.interp(times, tw, phi)

    def at(arr, p):
        return np.interp(p, phi, arr)

    def T(p):
        return np.interp(p, phi, tw)

    path_f = np.stack([at(path[:, 0], phi_f), at(path[:, 1], phi_f)], axis=-1)
    th_f = at(th, phi_f)
    v_f = at(v, phi_f)
    amp_f = at(amp, phi_f)
    dt = 1.0 / fps
    turn = np.gradient(th_f, dt)
    acc = np.gradient(v_f, dt)
    look = at(th, np.minimum(phi_f + 2.2, phi[-1])) - th_f

    # footprints
    prints = []
    sides = {}
    for kk in range(-1, K + 1):
        side = first_side if (kk % 2 != 0) else 1 - first_side
        sides[kk] = side
        sg = 1.0 if side == 0 else -1.0
        if kk <= 0 or kk >= K - 1:
            pp = phi[0] if kk <= 0 else phi[-1]
            c = np.array([at(path[:, 0], pp), at(path[:, 1], pp)])
            yaw = at(th, pp)
            w = style.stand_width
        else:
            pp = kk + FOOT_AHEAD
            c = np.array([at(path[:, 0], pp), at(path[:, 1], pp)])
            yaw = at(th, pp)
            w = style.step_width + (style.stand_width - style.step_width) * (1 - at(amp, kk))
        lat = np.array([np.cos(yaw), -np.sin(yaw)]) * sg * w
        xz = c + lat
        a_land = at(amp, kk)
        v_land = at(v, kk)
        g = np.clip(v_land / style.v_hub, 0.0, 1.3)
        v_lift = at(v, kk + 1.2)
        g2 = np.clip(v_lift / style.v_hub, 0.0, 1.3)
        t_land = -np.inf if kk <= 0 else T(kk)
        toe_off = kk + float(np.clip(1.2 - 0.1 * (at(v, kk + 1.0) - 1.3), 1.12, 1.28))
        t_lift = np.inf if kk >= K - 1 else T(toe_off)
        prints.append(Footprint(
            side=side, x=float(xz[0]), z=float(xz[1]), yaw=float(yaw + sg * style.toe_out),
            t_land=float(t_land), t_flat=float(T(kk + 0.14)) if kk > 0 else -np.inf,
            t_heeloff=float(T(kk + 0.65)) if kk < K - 1 else np.inf,
            t_lift=float(t_lift),
            alpha=float(min(style.alpha * a_land * g, MAX_ALPHA)) if kk > 0 else 0.0,
            beta=float(min(style.beta * at(amp, kk + 1.2) * g2, MAX_BETA)) if kk < K - 1 else 0.0,
            clearance=float(max(0.04, style.clearance * (0.45 + 0.55 * min(g, 1.2))))))
    # the closing step of a stop is a short, flat-footed one
    for p in prints[-1:]:
        p.alpha = min(p.alpha, np.radians(4.0))
        p.clearance = min(p.clearance, 0.04)
    prints.sort(key=lambda p: (p.side, p.t_land))

    # labels and hubs
    segs = []
    hubs = [(0, "stand" if style.label is None else "carry_stand")]
    # anchor_frames: [start, hub1, ..., hub_n, end]; edges map 1:1 to consecutive anchors
    for i, e in enumerate(edges):
        a0 = int(anchor_frames[i])
        a1 = int(anchor_frames[i + 1]) if i + 1 < len(edges) else int(anchor_frames[-1])
        label = style.label or e[0]
        segs.append((a0, a1, label))
        if i + 1 < len(edges):
            kb = bounds[i][1]
            hubs.append((a1, style.hub_names[sides[kb]]))
    end = (float(path[-1, 0]), float(path[-1, 1]), float(th[-1]))
    return RunPlan(style, times, phi_f, path_f, th_f, v_f, amp_f, turn, acc, look, prints,
                   first_side, segs, hubs, end)
