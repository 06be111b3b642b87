"""Activities as *groups* of motion that start and end in a shared hub pose.

Every group begins and ends standing still in the canonical ``stand`` pose (feet side by
side, weight centred, arms relaxed), so any group can follow any other. Inside a group the
motion passes through further hub poses that are exactly equal across occurrences up to the
root's planar position and heading: ``walk_l`` / ``walk_r`` (heel strike of the left / right
foot at 1.3 m/s, walking straight), ``seated``, ``carry_stand`` and ``carry_l`` /
``carry_r`` (carrying heel strikes at 1.0 m/s). This is the structure that the
snap-together motion-graph builder discovers as hub nodes (Gleicher et al. 2003): many
different walk edges (turns, speed changes, lengths) connect the same hubs.

Groups:
  walk run   stand -start-> walk_x -walk-> ... -walk-> walk_y -stop-> stand
  idle       stand -idle-> stand                   (weight shifts, looking around)
  turn       stand -turn-> stand                   (turning in place by 45-180 deg)
  sit        stand -sit_down-> seated (-sit-> seated)+ -stand_up-> stand
  box        stand -pick_up-> carry_stand -carry-> carry_x ... -carry-> carry_stand
             (... more carry runs ...) -put_down-> stand

Keyframed activities (sit, pick up, put down, idle) move the pelvis and trunk along C2
splines through a few key poses in the body frame while the feet stay planted (the same leg
IK keeps them exactly on their footprints); locomotion comes from :mod:`.gait`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from runtime.motion import quat

from . import body, gait
from .curves import gaussian, keyframes, lower_envelope, smoothstep, smootherstep
from .gait import CARRY, WALK, Footprint, foot_q, foot_tracks, plan_run
from .rig import Controls, chest_transforms, hip_positions

__all__ = ["Group", "walk_run", "idle", "turn_in_place", "sit_cycle", "box_cycle", "H_STAND",
           "BOX_SIZE", "SEAT_HEIGHT", "CHAIR_OFFSET"]

H_STAND = body.standing_root_height(7.0)
SEAT_HEIGHT = 0.45                  # chair seat surface (m)
SEATED_ROOT = (0.0, 0.585, -0.42)   # pelvis in the standing body frame when seated
CHAIR_OFFSET = -0.40                # chair seat centre behind the standing pelvis (m)
BOX_SIZE = (0.40, 0.30, 0.30)       # width (x), height (y), depth (z), metres
BOX_AHEAD = 0.40                    # box centre ahead of the standing pelvis (m)
# wrist targets when carrying, in the Spine1 (thorax) frame
CARRY_WRIST = np.array([[0.225, -0.22, 0.34], [-0.225, -0.22, 0.34]])
# wrist targets at the box sides on the ground, in the standing body frame
BOX_GRIP = np.array([[0.225, 0.25, BOX_AHEAD - 0.02], [-0.225, 0.25, BOX_AHEAD - 0.02]])
# wrists resting on the thighs when seated, standing body frame
THIGH_REST = np.array([[0.115, 0.60, -0.17], [-0.115, 0.60, -0.17]])

LEG_EXT = 0.9985 * body.leg_length()     # longest hip-ankle distance the planner allows
LEG_EXT_WALK = 0.998 * body.leg_length()  # ... while walking (knees never quite straight)


@dataclass
class Group:
    controls: Controls          # N + 1 frames: frame 0 = start hub, frame N = end hub
    segments: list              # [(start, end_exclusive, label)] covering [0, N)
    hubs: list                  # [(frame, hub)] including frame 0, excluding frame N
    props: list = field(default_factory=list)
    end: tuple = (0.0, 0.0, 0.0)

    @property
    def num_frames(self) -> int:      # frames owned by this group (without the end hub)
        return self.controls.num_frames - 1


# ------------------------------------------------------------------------------------------
# neutral poses
# ------------------------------------------------------------------------------------------
NEUTRAL = {
    "pitch": 0.02, "flex": 0.03, "hpitch": 0.08,
    "swing": 0.05, "abd": 0.12, "elbow": 0.22, "wrist": 0.12, "clav": 0.0,
}
CARRY_NEUTRAL = {"pitch": 0.0, "flex": -0.06, "hpitch": 0.18, "clav": 0.06}


def _rot2(heading):
    c, s = np.cos(heading), np.sin(heading)
    return c, s


def body_to_world(local_xyz, x0, z0, heading):
    """Points in a body frame (x left, y up, z forward) at (x0, z0, heading) to world."""
    p = np.asarray(local_xyz, dtype=np.float64)
    c, s = _rot2(heading)
    wx = x0 + c * p[..., 0] + s * p[..., 2]
    wz = z0 - s * p[..., 0] + c * p[..., 2]
    return np.stack([wx, p[..., 1], wz], axis=-1)


def standing_prints(x0, z0, heading, width=WALK.stand_width, toe_out=WALK.toe_out):
    out = []
    for side in (0, 1):
        sg = 1.0 if side == 0 else -1.0
        p = body_to_world(np.array([sg * width, 0.0, 0.0]), x0, z0, heading)
        out.append(Footprint(side, float(p[0]), float(p[2]), float(heading + sg * toe_out),
                             -np.inf, -np.inf, np.inf, np.inf))
    return out


def neutral_controls(N, x0, z0, heading, carry=False) -> Controls:
    c = Controls.empty(N)
    c.root_pos[:] = [x0, H_STAND, z0]
    c.heading[:] = heading
    c.pelvis[:, 1] = NEUTRAL["pitch"]
    c.spine[:, 0] = NEUTRAL["flex"]
    c.head[:, 0] = NEUTRAL["hpitch"]
    c.arm[:, :, 0] = NEUTRAL["swing"]
    c.arm[:, :, 1] = NEUTRAL["abd"]
    c.arm[:, :, 2] = NEUTRAL["elbow"]
    c.wrist[:] = NEUTRAL["wrist"]
    prints = standing_prints(x0, z0, heading)
    c.ankle[:] = np.array([p.flat_ankle() for p in prints])
    c.foot_q[:] = np.array([foot_q(p.yaw, 0.0) for p in prints])
    if carry:
        _set_carry(c)
    return c


def _set_carry(c: Controls, w=None):
    """Arms on the box held in front of the thorax; trunk leaning back slightly."""
    w = np.ones(c.num_frames) if w is None else w
    c.pelvis[:, 1] = c.pelvis[:, 1] * (1 - w) + CARRY_NEUTRAL["pitch"] * w
    c.spine[:, 0] = c.spine[:, 0] * (1 - w) + CARRY_NEUTRAL["flex"] * w
    c.head[:, 0] = c.head[:, 0] * (1 - w) + CARRY_NEUTRAL["hpitch"] * w
    c.clav[:, :, 0] = c.clav[:, :, 0] * (1 - w[:, None]) + CARRY_NEUTRAL["clav"] * w[:, None]
    c.hand_w[:] = np.maximum(c.hand_w, w[:, None])
    c.hand_attach[:] = np.maximum(c.hand_attach, w[:, None])
    c.hand_thorax[:] = CARRY_WRIST


def allowed_root_height(skel, c: Controls, ext) -> np.ndarray:
    """Highest root height per frame at which both hip-ankle distances are <= ext."""
    hips = hip_positions(skel, c)
    rel = hips - c.root_pos[:, None, :]           # hip offsets from the root
    dxz = np.linalg.norm((c.root_pos[:, None, [0, 2]] + rel[..., [0, 2]]) - c.ankle[..., [0, 2]], axis=-1)
    ext = np.asarray(ext, dtype=np.float64)
    ext = np.broadcast_to(ext if ext.ndim == 2 else ext.reshape(-1, 1) if ext.ndim == 1 else ext, (c.num_frames, 2))
    room = np.sqrt(np.maximum(ext * ext - dxz * dxz, 0.0))
    return (c.ankle[..., 1] - rel[..., 1] + room).min(axis=1)


def limit_reach(skel, c: Controls, ext=LEG_EXT, sigma=2.0) -> float:
    """Lower the root where a leg could not reach its ankle target (one-sided smoothing),
    leaving frames that are within reach alone. Returns the largest lowering (m)."""
    allow = allowed_root_height(skel, c, ext)
    corr = np.minimum(allow - c.root_pos[:, 1], 0.0)
    sm = lower_envelope(corr, sigma)
    c.root_pos[:, 1] += sm
    return float(-sm.min()) if len(sm) else 0.0


def vault_height(skel, c: Controls, ext, phi, gate=None, max_bob=None, sigma=1.0):
    """Walking pelvis height. The pelvis rises over the stance leg and is lowest in double
    support: ``h = cap - depth(phi) * w(phi)`` with ``w = ((1 + cos 2 pi (phi - k - 0.04)) / 2) ** 0.6``
    (1 just after heel strike, 0 half a step later), where each step's depth is
    the smallest that keeps both legs within reach ``ext`` over that step. Any remaining
    excess is removed by one-sided smoothing."""
    allow = allowed_root_height(skel, c, ext)
    cap = c.root_pos[:, 1].copy()
    need = cap - allow
    w = (0.5 + 0.5 * np.cos(2 * np.pi * (phi - 0.04))) ** 0.6
    k = np.floor(phi + 0.46).astype(int)              # step window [k - 0.46, k + 0.54)
    ks = np.arange(k.min(), k.max() + 1)
    depth = np.zeros(len(ks))
    sel = w > 0.2
    np.maximum.at(depth, k[sel] - ks[0], np.maximum(need[sel], 0.0) / w[sel])
    excess = np.zeros_like(depth)
    if max_bob is not None:      # deeper than a human bob: lower the whole step instead
        mb = np.interp(ks + 0.04, phi, max_bob)
        excess = np.maximum(depth - mb, 0.0)
        depth = depth - excess
    if len(ks) > 1:
        depth_f = keyframes(ks + 0.04, depth, phi)
        excess_f = keyframes(ks + 0.04, excess, phi)
    else:
        depth_f, excess_f = np.full_like(phi, depth[0]), np.full_like(phi, excess[0])
    g = 1.0 if gate is None else gate
    h = cap - (np.maximum(depth_f, 0.0) * w + np.maximum(excess_f, 0.0)) * g
    corr = np.minimum(allow - h, 0.0)
    c.root_pos[:, 1] = h + lower_envelope(corr, sigma)


# ------------------------------------------------------------------------------------------
# locomotion
# ------------------------------------------------------------------------------------------
def _run_edges(rng, style, n_edges, steer):
    """Random edge list for a run: start, n_edges walk edges, stop."""
    edges = [("start", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-25, 25))))]
    for _ in range(n_edges):
        n = int(rng.integers(2, 8))
        f_hub = float(gait.cadence(style.v_hub, style))
        width_s = (n - 2 * gait.HUB_MARGIN) / f_hub               # seconds of the turning window
        max_turn = np.radians(90.0) * width_s / 2.0               # peak rate 90 deg/s (sin^2 profile)
        max_turn = min(max_turn, np.radians(120.0))
        turn = rng.choice([-1.0, 1.0]) * np.sqrt(rng.uniform(0.0, 1.0)) * max_turn   # favour big turns
        turn = float(np.clip(turn + steer(), -max_turn, max_turn))
        # speed change: keep |dv/dt| <= ~1.3 m/s^2 for the sin^2 bump
        max_dv = 1.3 * width_s / np.pi
        lo = max(style.v_min - style.v_hub, -max_dv)
        hi = min(style.v_max - style.v_hub, max_dv)
        dv = float((lo if rng.random() < 0.5 else hi) * np.sqrt(rng.uniform(0.0, 1.0)))   # favour extremes
        if rng.random() < 0.15:
            dv = 0.0
        edges.append(("walk", n, turn, dv))
    edges.append(("stop", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-20, 20)))))
    return edges


def run_group(skel, rng, state, fps, style, n_edges, steer) -> Group:
    x0, z0, th0 = state
    edges = _run_edges(rng, style, n_edges, steer)
    first = int(rng.integers(0, 2))
    plan = plan_run(style, edges, x0, z0, th0, first, fps)
    c = run_controls(plan, skel)
    return Group(c, plan.segments, plan.hubs, [], plan.end_state)


def run_controls(plan, skel) -> Controls:
    style = plan.style
    carry = style.label == "carry"
    N = len(plan.times)
    x0, z0 = plan.path[0]
    c = neutral_controls(N, x0, z0, plan.heading[0], carry=carry)
    a = plan.amp
    v = plan.speed
    phi = plan.phi
    th = plan.heading
    sA = 1.0 if plan.first_side == 0 else -1.0
    g = np.clip(v / style.v_hub, 0.0, 1.5)
    # leaning into turns: centripetal acceleration v * omega, partly compensated
    lean = -np.arctan(0.6 * v * plan.turn_rate / 9.81)
    lean = gaussian(lean, 2.0)
    osc_sway = np.cos(np.pi * (phi - 1.6))
    sway = sA * 0.022 * a * osc_sway
    lateral = sway - 0.35 * np.sin(lean)             # pelvis shifts towards the inside of a turn
    c.heading[:] = th
    c.root_pos[:, 0] = plan.path[:, 0] + np.cos(th) * lateral
    c.root_pos[:, 2] = plan.path[:, 1] - np.sin(th) * lateral
    c.root_pos[:, 1] = H_STAND - a * (0.003 + 0.003 * v)
    yaw_osc = -sA * np.radians(1.5 + 2.0 * v) * a * np.cos(np.pi * (phi - 1.0))
    roll_osc = sA * np.radians(1.0 + 1.6 * v) * a * np.cos(np.pi * (phi - 1.45))
    acc = gaussian(plan.accel, 3.0)
    c.pelvis[:, 0] = yaw_osc
    c.pelvis[:, 1] += a * np.radians(1.0 + 2.0 * v) + 0.02 * acc
    c.pelvis[:, 2] = roll_osc + 0.5 * lean
    c.spine[:, 0] += a * np.radians(1.0 * v) + 0.015 * acc
    c.spine[:, 1] = 0.8 * roll_osc + 0.2 * lean      # keep the thorax nearly level
    c.spine[:, 2] = -1.6 * yaw_osc                   # thorax counter-rotation
    c.head[:, 0] += a * np.radians(3.0)
    c.head[:, 1] = np.clip(0.45 * plan.look, -0.6, 0.6) * a
    if not carry:
        amp_arm = np.radians(4.0 + 8.0 * v) * a
        for s in (0, 1):
            sgn = 1.0 if s == plan.first_side else -1.0
            sw = sgn * amp_arm * np.cos(np.pi * (phi - 0.1))
            c.arm[:, s, 0] = NEUTRAL["swing"] + a * np.radians(2.0) + sw
            c.arm[:, s, 2] = NEUTRAL["elbow"] + a * np.radians(5.0) + 0.45 * np.maximum(sw, 0.0)
            c.arm[:, s, 1] = NEUTRAL["abd"] + a * np.radians(2.0)
    ankle, fq, toe, swing, roll = foot_tracks(plan.prints, plan.times)
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    ext = (LEG_EXT + (LEG_EXT_WALK - LEG_EXT) * a)[:, None] * (1.0 - 0.02 * roll ** 2)
    ext = np.where(swing, 0.999 * body.leg_length(), ext)     # swing leg may straighten fully
    vault_height(skel, c, ext, plan.phi, gate=smoothstep(a / 0.1), max_bob=0.03 + 0.012 * v)
    return c


# ------------------------------------------------------------------------------------------
# keyframed activities
# ------------------------------------------------------------------------------------------
_CH = ("px", "py", "pz", "yaw", "pitch", "roll", "flex", "lat", "twist", "hpitch", "hyaw",
       "swingL", "swingR", "abdL", "abdR", "elbowL", "elbowR", "clavL", "clavR")


def _neutral_key(carry=False):
    k = {"px": 0.0, "py": H_STAND, "pz": 0.0, "yaw": 0.0, "pitch": NEUTRAL["pitch"], "roll": 0.0,
         "flex": NEUTRAL["flex"], "lat": 0.0, "twist": 0.0, "hpitch": NEUTRAL["hpitch"], "hyaw": 0.0,
         "swingL": NEUTRAL["swing"], "swingR": NEUTRAL["swing"], "abdL": NEUTRAL["abd"],
         "abdR": NEUTRAL["abd"], "elbowL": NEUTRAL["elbow"], "elbowR": NEUTRAL["elbow"],
         "clavL": 0.0, "clavR": 0.0}
    if carry:
        k.update(pitch=CARRY_NEUTRAL["pitch"], flex=CARRY_NEUTRAL["flex"],
                 hpitch=CARRY_NEUTRAL["hpitch"], clavL=CARRY_NEUTRAL["clav"], clavR=CARRY_NEUTRAL["clav"])
    return k


def _seated_key():
    k = _neutral_key()
    k.update(px=SEATED_ROOT[0], py=SEATED_ROOT[1], pz=SEATED_ROOT[2], pitch=-0.06, flex=0.10,
             hpitch=0.12, swingL=0.3, swingR=0.3, elbowL=0.9, elbowR=0.9)
    return k


def _keyed(keys, T, times):
    """keys: [(fraction of T, {channel: value})]; missing channels repeat the previous key."""
    ts = [f * T for f, _ in keys]
    rows = []
    cur = {}
    for _, d in keys:
        cur = {**cur, **d}
        rows.append([cur[ch] for ch in _CH])
    vals = keyframes(np.array(ts), np.array(rows), times)
    return {ch: vals[:, i] for i, ch in enumerate(_CH)}


def _apply_keys(c: Controls, k, x0, z0, th0):
    loc = np.stack([k["px"], k["py"], k["pz"]], axis=-1)
    c.root_pos[:] = body_to_world(loc, x0, z0, th0)
    c.heading[:] = th0
    c.pelvis[:] = np.stack([k["yaw"], k["pitch"], k["roll"]], axis=-1)
    c.spine[:] = np.stack([k["flex"], k["lat"], k["twist"]], axis=-1)
    c.head[:] = np.stack([k["hpitch"], k["hyaw"]], axis=-1)
    c.arm[:, 0] = np.stack([k["swingL"], k["abdL"], k["elbowL"]], axis=-1)
    c.arm[:, 1] = np.stack([k["swingR"], k["abdR"], k["elbowR"]], axis=-1)
    c.clav[:, 0, 0] = k["clavL"]
    c.clav[:, 1, 0] = k["clavR"]


def _frames(T, fps):
    n = max(int(round(T * fps)), 2)
    return n, np.arange(n + 1) / fps


def idle(skel, rng, state, fps, carry=False) -> Group:
    """Standing: one to three weight shifts with a look around, back to neutral."""
    x0, z0, th0 = state
    shifts = int(rng.integers(1, 4))
    keys = [(0.0, _neutral_key(carry))]
    t = 0.0
    plan = []
    side = float(rng.choice([-1.0, 1.0]))
    for i in range(shifts):
        t_in = rng.uniform(0.7, 1.1)
        hold = rng.uniform(0.4, 1.4)
        plan.append((t + t_in, t + t_in + hold, side))
        t += t_in + hold
        side = -side if rng.random() < 0.7 else side
    T = t + rng.uniform(0.8, 1.1)
    for (ta, tb, sd) in plan:
        sh = sd * rng.uniform(0.025, 0.04)
        roll = sd * rng.uniform(0.04, 0.07)
        d = {"px": sh, "py": H_STAND - rng.uniform(0.005, 0.012), "pz": rng.uniform(-0.01, 0.01),
             "roll": roll, "lat": 0.8 * roll, "yaw": sd * rng.uniform(-0.05, 0.08),
             "hyaw": rng.uniform(-0.5, 0.5), "hpitch": NEUTRAL["hpitch"] + rng.uniform(-0.05, 0.1),
             "twist": rng.uniform(-0.08, 0.08)}
        if not carry:
            d.update(swingL=NEUTRAL["swing"] + rng.uniform(-0.04, 0.06),
                     swingR=NEUTRAL["swing"] + rng.uniform(-0.04, 0.06),
                     elbowL=NEUTRAL["elbow"] + rng.uniform(0.0, 0.15),
                     elbowR=NEUTRAL["elbow"] + rng.uniform(0.0, 0.15))
        keys.append((ta / T, d))
        keys.append((tb / T, {}))
    keys.append((1.0, _neutral_key(carry)))
    N, times = _frames(T, fps)
    T = N / fps
    k = _keyed(keys, T, times)
    c = neutral_controls(N + 1, x0, z0, th0, carry)
    _apply_keys(c, k, x0, z0, th0)
    if carry:
        _set_carry(c)
    return Group(c, [(0, N, "idle")], [(0, "carry_stand" if carry else "stand")], [], state)


def turn_in_place(skel, rng, state, fps, prefer=0.0) -> Group:
    """Turning on the spot by 45-180 deg in small steps (lead foot opens, other foot closes).
    ``prefer`` (rad) biases the turn towards a wanted heading change."""
    x0, z0, th0 = state
    mag = rng.uniform(45.0, 180.0)
    sign = rng.choice([-1.0, 1.0])
    if abs(prefer) > np.radians(30.0):
        sign = np.sign(prefer)
        mag = float(np.clip(np.degrees(abs(prefer)) + rng.uniform(-20, 20), 45.0, 180.0))
    dth = float(np.radians(mag) * sign)
    pairs = int(np.ceil(abs(dth) / np.radians(65.0)))
    lead = 0 if dth > 0 else 1
    t_shift, swing, ds = 0.3, rng.uniform(0.36, 0.44), 0.12
    prints = standing_prints(x0, z0, th0)
    prints = [p for p in prints]
    t = t_shift
    lifts = []
    steps = []
    for i in range(pairs):
        th_i = th0 + dth * (i + 1) / pairs
        for side in (lead, 1 - lead):
            sg = 1.0 if side == 0 else -1.0
            p = body_to_world(np.array([sg * WALK.stand_width, 0.0, 0.0]), x0, z0, th_i)
            steps.append((side, t, t + swing, p, th_i + sg * WALK.toe_out))
            t += swing + ds
    T = t + 0.35
    N, times = _frames(T, fps)
    T = N / fps
    # footprint list with timing
    last = {0: prints[0], 1: prints[1]}
    allp = list(prints)
    for side, t_lift, t_land, p, yaw in steps:
        last[side].t_lift = t_lift
        last[side].t_heeloff = t_lift
        fp = Footprint(side, float(p[0]), float(p[2]), float(yaw), t_land, t_land, np.inf, np.inf,
                       clearance=0.05)
        allp.append(fp)
        last[side] = fp
    allp.sort(key=lambda q: (q.side, q.t_land))
    ankle, fq, toe, swing, roll = foot_tracks(allp, times)
    t_first, t_last = steps[0][1], steps[-1][2]
    head = th0 + dth * smootherstep((times - t_first + 0.1) / (t_last - t_first + 0.1))
    c = neutral_controls(N + 1, x0, z0, th0)
    c.heading[:] = head
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    # pelvis shifts over the stance foot while the other foot steps
    sway = np.zeros(N + 1)
    for side, t_lift, t_land, p, yaw in steps:
        stance_sg = -1.0 if side == 0 else 1.0
        m = smoothstep((times - t_lift + 0.18) / 0.2) * (1 - smoothstep((times - t_land + 0.05) / 0.2))
        sway += stance_sg * 0.025 * m
    c.root_pos[:, 0] = x0 + np.cos(head) * sway
    c.root_pos[:, 2] = z0 - np.sin(head) * sway
    c.pelvis[:, 2] = 0.8 * sway
    c.spine[:, 1] = 0.6 * sway
    look = np.interp(np.minimum(times + 0.35, T), times, head) - head
    c.head[:, 1] = 0.8 * look
    c.spine[:, 2] = 0.3 * look
    limit_reach(skel, c)
    return Group(c, [(0, N, "turn")], [(0, "stand")], [], (x0, z0, th0 + dth))


def _ramp(times, a, b):
    return smootherstep((times - a) / max(b - a, 1e-6))


def sit_cycle(skel, rng, state, fps) -> Group:
    """sit_down onto a chair behind, 1-2 seated idles, stand_up."""
    x0, z0, th0 = state
    parts = []
    # -- sit down
    T = rng.uniform(2.2, 2.8)
    N1, t1 = _frames(T, fps)
    T = N1 / fps
    lean = rng.uniform(0.85, 1.15)
    seated = _seated_key()
    keys = [(0.0, _neutral_key()),
            (0.22, {"pz": -0.03, "py": H_STAND - 0.03, "pitch": 0.15 * lean, "flex": 0.10,
                    "hpitch": 0.22, "swingL": 0.10, "swingR": 0.10}),
            (0.52, {"pz": -0.19, "py": 0.77, "pitch": 0.50 * lean, "flex": 0.22 * lean, "hpitch": 0.15,
                    "swingL": 0.35, "swingR": 0.35, "elbowL": 0.45, "elbowR": 0.45}),
            (0.80, {"pz": -0.38, "py": 0.615, "pitch": 0.30 * lean, "flex": 0.18, "hpitch": 0.12,
                    "swingL": 0.35, "swingR": 0.35, "elbowL": 0.7, "elbowR": 0.7}),
            (1.0, seated)]
    k = _keyed(keys, T, t1)
    c1 = neutral_controls(N1 + 1, x0, z0, th0)
    _apply_keys(c1, k, x0, z0, th0)
    w = _ramp(t1, 0.72 * T, T)
    c1.hand_w[:] = w[:, None]
    c1.hand_world[:] = body_to_world(THIGH_REST, x0, z0, th0)
    parts.append((c1, "sit_down", "stand"))
    # -- seated idles
    for _ in range(1 if rng.random() < 0.7 else 2):
        T = rng.uniform(2.5, 5.5)
        N2, t2 = _frames(T, fps)
        T = N2 / fps
        keys = [(0.0, seated)]
        n_k = int(rng.integers(1, 3))
        for i in range(n_k):
            f = (i + 0.5 + rng.uniform(-0.15, 0.15)) / n_k
            keys.append((f, {"flex": seated["flex"] + rng.uniform(-0.06, 0.12),
                             "twist": rng.uniform(-0.15, 0.15), "lat": rng.uniform(-0.05, 0.05),
                             "hyaw": rng.uniform(-0.6, 0.6), "hpitch": seated["hpitch"] + rng.uniform(-0.1, 0.15)}))
        keys.append((1.0, seated))
        k = _keyed(keys, T, t2)
        c2 = neutral_controls(N2 + 1, x0, z0, th0)
        _apply_keys(c2, k, x0, z0, th0)
        c2.hand_w[:] = 1.0
        c2.hand_world[:] = body_to_world(THIGH_REST, x0, z0, th0)
        parts.append((c2, "sit", "seated"))
    # -- stand up
    T = rng.uniform(2.0, 2.6)
    N3, t3 = _frames(T, fps)
    T = N3 / fps
    lean = rng.uniform(0.9, 1.15)
    keys = [(0.0, seated),
            (0.30, {"pz": -0.40, "py": 0.595, "pitch": 0.45 * lean, "flex": 0.22, "hpitch": 0.2}),
            (0.52, {"pz": -0.26, "py": 0.70, "pitch": 0.55 * lean, "flex": 0.22, "hpitch": 0.15,
                    "swingL": 0.3, "swingR": 0.3, "elbowL": 0.5, "elbowR": 0.5}),
            (0.78, {"pz": -0.06, "py": H_STAND - 0.04, "pitch": 0.18, "flex": 0.08, "hpitch": 0.1,
                    "swingL": 0.12, "swingR": 0.12, "elbowL": 0.3, "elbowR": 0.3}),
            (1.0, _neutral_key())]
    k = _keyed(keys, T, t3)
    c3 = neutral_controls(N3 + 1, x0, z0, th0)
    _apply_keys(c3, k, x0, z0, th0)
    w = 1.0 - _ramp(t3, 0.05 * T, 0.45 * T)
    c3.hand_w[:] = w[:, None]
    c3.hand_world[:] = body_to_world(THIGH_REST, x0, z0, th0)
    parts.append((c3, "stand_up", "seated"))
    group = _join(skel, parts, state)
    chair = body_to_world(np.array([0.0, 0.0, CHAIR_OFFSET]), x0, z0, th0)
    group.props.append({"kind": "chair", "start": 0, "end": group.num_frames + 1,
                        "x": float(chair[0]), "z": float(chair[2]), "heading": float(th0),
                        "seat_height": SEAT_HEIGHT, "size": [0.45, SEAT_HEIGHT, 0.42]})
    return group


def _join(skel, parts, state, end=None) -> Group:
    """Concatenate (controls, label, start hub) parts that share their boundary frames."""
    ctl = []
    segs = []
    hubs = []
    f = 0
    for i, (c, label, hub) in enumerate(parts):
        if isinstance(c, Group):
            g = c
            keep = g.controls if i == len(parts) - 1 else g.controls.slice(0, g.num_frames)
            ctl.append(keep)
            segs += [(a + f, b + f, lab) for a, b, lab in g.segments]
            hubs += [(h + f, n) for h, n in g.hubs]
            f += g.num_frames
            continue
        n = c.num_frames - 1
        keep = c if i == len(parts) - 1 else c.slice(0, n)
        limit_reach(skel, keep)
        ctl.append(keep)
        segs.append((f, f + n, label))
        hubs.append((f, hub))
        f += n
    return Group(Controls.concat(ctl), segs, hubs, [], end or state)


def _ride_box(skel, c: Controls, times, grip_t, lift, place):
    """Wrist targets for a box carried in the thorax frame. Picking up: at ``grip_t`` the
    wrists are on the box on the floor; expressed in the thorax frame of that instant they
    ride with the thorax and move to the carry pose over ``lift``. Putting down: the reverse
    (carry pose -> the floor grip as seen from the thorax at ``grip_t``), then the world
    target takes over. The switch between world and thorax targets happens at the instant
    where both are the same point, so the box never jumps."""
    rot, pos = chest_transforms(skel, c)
    fg = int(np.argmin(np.abs(times - grip_t)))
    inv = quat.inv(rot[fg])
    grip_local = quat.rotate(np.broadcast_to(inv, (2, 4)), c.hand_world[fg] - pos[fg])
    u = _ramp(times, lift[0], lift[1])[:, None, None]
    if place:
        c.hand_thorax[:] = (1 - u) * CARRY_WRIST + u * grip_local
        c.hand_attach[:] = (1.0 - _ramp(times, grip_t, grip_t + 0.15))[:, None]
    else:
        c.hand_thorax[:] = (1 - u) * grip_local + u * CARRY_WRIST
        c.hand_attach[:] = _ramp(times, grip_t, grip_t + 0.12)[:, None]


def box_cycle(skel, rng, state, fps, steer) -> Group:
    """pick_up a box in front, 1-2 carry runs (with turns and speed changes), put_down."""
    x0, z0, th0 = state
    parts = []
    box0 = body_to_world(np.array([0.0, BOX_SIZE[1] / 2, BOX_AHEAD]), x0, z0, th0)
    # -- pick up
    T = rng.uniform(2.6, 3.2)
    N1, t1 = _frames(T, fps)
    T = N1 / fps
    bottom = {"pz": -0.17, "py": 0.53, "pitch": 0.80, "flex": 0.50, "hpitch": 0.35,
              "swingL": 0.3, "swingR": 0.3}
    keys = [(0.0, _neutral_key()),
            (0.18, {"hpitch": 0.55, "flex": 0.08, "py": H_STAND - 0.01}),
            (0.45, bottom),
            (0.58, {"py": 0.535, "pitch": 0.78}),
            (0.82, {"pz": -0.05, "py": 0.88, "pitch": 0.22, "flex": 0.10, "hpitch": 0.25}),
            (1.0, _neutral_key(carry=True))]
    k = _keyed(keys, T, t1)
    c1 = neutral_controls(N1 + 1, x0, z0, th0)
    _apply_keys(c1, k, x0, z0, th0)
    reach = _ramp(t1, 0.22 * T, 0.46 * T)
    c1.hand_w[:] = reach[:, None]
    c1.hand_world[:] = body_to_world(BOX_GRIP, x0, z0, th0)
    # the box rides with the thorax from the grip on, moving to the carry pose
    _ride_box(skel, c1, t1, grip_t=0.46 * T, lift=(0.58 * T, 0.86 * T), place=False)
    c1.clav[:, :, 0] = CARRY_NEUTRAL["clav"] * c1.hand_attach[:, :1]
    parts.append((c1, "pick_up", "stand"))
    props = [{"kind": "box", "start": 0, "end": int(round(0.58 * T * fps)), "x": float(box0[0]),
              "z": float(box0[2]), "heading": float(th0), "size": list(BOX_SIZE)}]
    carried_from = int(round(0.58 * T * fps))
    # where the box sits relative to the wrists while carried (body frame: down, forward)
    hold = [float(BOX_SIZE[1] / 2 - BOX_GRIP[0, 1]), float(BOX_AHEAD - BOX_GRIP[0, 2])]
    # -- carry runs
    st = (x0, z0, th0)
    for r in range(1 if rng.random() < 0.9 else 2):
        if r > 0:
            g = idle(skel, rng, st, fps, carry=True)
            g.segments = [(a, b, "carry") for a, b, _ in g.segments]
            parts.append((g, None, None))
        g = run_group(skel, rng, st, fps, CARRY, int(rng.integers(1, 3)), steer)
        parts.append((g, None, None))
        st = g.end
    # -- put down
    x1, z1, th1 = st
    T = rng.uniform(2.6, 3.2)
    N3, t3 = _frames(T, fps)
    T = N3 / fps
    keys = [(0.0, _neutral_key(carry=True)),
            (0.20, {"hpitch": 0.45, "pz": -0.02, "py": H_STAND - 0.05, "pitch": 0.15, "flex": 0.05}),
            (0.45, {**bottom, "hpitch": 0.35}),
            (0.60, {"py": 0.535, "pitch": 0.78}),
            (0.86, {"pz": -0.05, "py": 0.88, "pitch": 0.22, "flex": 0.10, "hpitch": 0.2,
                    "swingL": 0.1, "swingR": 0.1}),
            (1.0, _neutral_key())]
    k = _keyed(keys, T, t3)
    c3 = neutral_controls(N3 + 1, x1, z1, th1)
    _apply_keys(c3, k, x1, z1, th1)
    c3.hand_world[:] = body_to_world(BOX_GRIP, x1, z1, th1)
    _ride_box(skel, c3, t3, grip_t=0.46 * T, lift=(0.12 * T, 0.46 * T), place=True)
    c3.hand_w[:] = (1.0 - _ramp(t3, 0.53 * T, 0.74 * T))[:, None]
    c3.clav[:, :, 0] = CARRY_NEUTRAL["clav"] * c3.hand_attach[:, :1]
    parts.append((c3, "put_down", "carry_stand"))
    group = _join(skel, parts, state, end=st)
    put_start = group.num_frames - N3
    box1 = body_to_world(np.array([0.0, BOX_SIZE[1] / 2, BOX_AHEAD]), x1, z1, th1)
    props.append({"kind": "box", "carried": True, "start": carried_from,
                  "end": put_start + int(round(0.46 * T * fps)), "size": list(BOX_SIZE),
                  "hold_offset": hold})
    props.append({"kind": "box", "start": put_start + int(round(0.46 * T * fps)),
                  "end": group.num_frames + 1, "x": float(box1[0]), "z": float(box1[2]),
                  "heading": float(th1), "size": list(BOX_SIZE)})
    group.props = props
    return group
