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
IK keeps them exactly on their footprints, :mod:`.keyframes`); locomotion comes from
:mod:`.locomotion`, turning in place from :mod:`.turning`, the shared hub pose from
:mod:`.stance`.
"""
from __future__ import annotations

import numpy as np

from runtime.motion import quat

from .curves import ramp
from .gait import CARRY
from .group import Group
from .keyframes import apply_keys, frame_times, keyed, neutral_key
from .locomotion import run_group
from .rig import Controls, chest_transforms
from .stance import (CARRY_NEUTRAL, CARRY_WRIST, H_STAND, NEUTRAL, body_to_world, limit_reach,
                     neutral_controls, set_carry)
from .turning import turn_on_spot

__all__ = ["idle", "turn_in_place", "sit_cycle", "box_cycle", "BOX_SIZE", "SEAT_HEIGHT", "CHAIR_OFFSET"]

SEAT_HEIGHT = 0.45                  # chair seat surface (m)
SEATED_ROOT = (0.0, 0.585, -0.42)   # pelvis in the standing body frame when seated
CHAIR_OFFSET = -0.40                # chair seat centre behind the standing pelvis (m)
BOX_SIZE = (0.40, 0.30, 0.30)       # width (x), height (y), depth (z), metres
BOX_AHEAD = 0.40                    # box centre ahead of the standing pelvis (m)
# wrist targets at the box sides on the ground, in the standing body frame
BOX_GRIP = np.array([[0.225, 0.25, BOX_AHEAD - 0.02], [-0.225, 0.25, BOX_AHEAD - 0.02]])
# wrists resting on the thighs when seated, standing body frame
THIGH_REST = np.array([[0.115, 0.60, -0.17], [-0.115, 0.60, -0.17]])


def _seated_key():
    k = neutral_key()
    k.update(px=SEATED_ROOT[0], py=SEATED_ROOT[1], pz=SEATED_ROOT[2], pitch=-0.06, flex=0.10,
             hpitch=0.12, swingL=0.3, swingR=0.3, elbowL=0.9, elbowR=0.9)
    return k


def idle(skel, rng, state, fps, carry=False) -> Group:
    """Standing: one to three weight shifts with a look around, back to neutral."""
    x0, z0, th0 = state
    shifts = int(rng.integers(1, 4))
    keys = [(0.0, neutral_key(carry))]
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
    keys.append((1.0, neutral_key(carry)))
    N, times = frame_times(T, fps)
    T = N / fps
    k = keyed(keys, T, times)
    c = neutral_controls(N + 1, x0, z0, th0, carry)
    apply_keys(c, k, x0, z0, th0)
    if carry:
        set_carry(c)
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
    c, N = turn_on_spot(skel, state, dth, rng.uniform(0.36, 0.44), fps)
    return Group(c, [(0, N, "turn")], [(0, "stand")], [], (x0, z0, th0 + dth))


def sit_cycle(skel, rng, state, fps) -> Group:
    """sit_down onto a chair behind, 1-2 seated idles, stand_up."""
    x0, z0, th0 = state
    parts = []
    # -- sit down
    T = rng.uniform(2.2, 2.8)
    N1, t1 = frame_times(T, fps)
    T = N1 / fps
    lean = rng.uniform(0.85, 1.15)
    seated = _seated_key()
    keys = [(0.0, neutral_key()),
            (0.22, {"pz": -0.03, "py": H_STAND - 0.03, "pitch": 0.15 * lean, "flex": 0.10,
                    "hpitch": 0.22, "swingL": 0.10, "swingR": 0.10}),
            (0.52, {"pz": -0.19, "py": 0.77, "pitch": 0.50 * lean, "flex": 0.22 * lean, "hpitch": 0.15,
                    "swingL": 0.35, "swingR": 0.35, "elbowL": 0.45, "elbowR": 0.45}),
            (0.80, {"pz": -0.38, "py": 0.615, "pitch": 0.30 * lean, "flex": 0.18, "hpitch": 0.12,
                    "swingL": 0.35, "swingR": 0.35, "elbowL": 0.7, "elbowR": 0.7}),
            (1.0, seated)]
    k = keyed(keys, T, t1)
    c1 = neutral_controls(N1 + 1, x0, z0, th0)
    apply_keys(c1, k, x0, z0, th0)
    w = ramp(t1, 0.72 * T, T)
    c1.hand_w[:] = w[:, None]
    c1.hand_world[:] = body_to_world(THIGH_REST, x0, z0, th0)
    parts.append((c1, "sit_down", "stand"))
    # -- seated idles
    for _ in range(1 if rng.random() < 0.7 else 2):
        T = rng.uniform(2.5, 5.5)
        N2, t2 = frame_times(T, fps)
        T = N2 / fps
        keys = [(0.0, seated)]
        n_k = int(rng.integers(1, 3))
        for i in range(n_k):
            f = (i + 0.5 + rng.uniform(-0.15, 0.15)) / n_k
            keys.append((f, {"flex": seated["flex"] + rng.uniform(-0.06, 0.12),
                             "twist": rng.uniform(-0.15, 0.15), "lat": rng.uniform(-0.05, 0.05),
                             "hyaw": rng.uniform(-0.6, 0.6), "hpitch": seated["hpitch"] + rng.uniform(-0.1, 0.15)}))
        keys.append((1.0, seated))
        k = keyed(keys, T, t2)
        c2 = neutral_controls(N2 + 1, x0, z0, th0)
        apply_keys(c2, k, x0, z0, th0)
        c2.hand_w[:] = 1.0
        c2.hand_world[:] = body_to_world(THIGH_REST, x0, z0, th0)
        parts.append((c2, "sit", "seated"))
    # -- stand up
    T = rng.uniform(2.0, 2.6)
    N3, t3 = frame_times(T, fps)
    T = N3 / fps
    lean = rng.uniform(0.9, 1.15)
    keys = [(0.0, seated),
            (0.30, {"pz": -0.40, "py": 0.595, "pitch": 0.45 * lean, "flex": 0.22, "hpitch": 0.2}),
            (0.52, {"pz": -0.26, "py": 0.70, "pitch": 0.55 * lean, "flex": 0.22, "hpitch": 0.15,
                    "swingL": 0.3, "swingR": 0.3, "elbowL": 0.5, "elbowR": 0.5}),
            (0.78, {"pz": -0.06, "py": H_STAND - 0.04, "pitch": 0.18, "flex": 0.08, "hpitch": 0.1,
                    "swingL": 0.12, "swingR": 0.12, "elbowL": 0.3, "elbowR": 0.3}),
            (1.0, neutral_key())]
    k = keyed(keys, T, t3)
    c3 = neutral_controls(N3 + 1, x0, z0, th0)
    apply_keys(c3, k, x0, z0, th0)
    w = 1.0 - ramp(t3, 0.05 * T, 0.45 * T)
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
    u = ramp(times, lift[0], lift[1])[:, None, None]
    if place:
        c.hand_thorax[:] = (1 - u) * CARRY_WRIST + u * grip_local
        c.hand_attach[:] = (1.0 - ramp(times, grip_t, grip_t + 0.15))[:, None]
    else:
        c.hand_thorax[:] = (1 - u) * grip_local + u * CARRY_WRIST
        c.hand_attach[:] = ramp(times, grip_t, grip_t + 0.12)[:, None]


def box_cycle(skel, rng, state, fps, steer) -> Group:
    """pick_up a box in front, 1-2 carry runs (with turns and speed changes), put_down."""
    x0, z0, th0 = state
    parts = []
    box0 = body_to_world(np.array([0.0, BOX_SIZE[1] / 2, BOX_AHEAD]), x0, z0, th0)
    # -- pick up
    T = rng.uniform(2.6, 3.2)
    N1, t1 = frame_times(T, fps)
    T = N1 / fps
    bottom = {"pz": -0.17, "py": 0.53, "pitch": 0.80, "flex": 0.50, "hpitch": 0.35,
              "swingL": 0.3, "swingR": 0.3}
    keys = [(0.0, neutral_key()),
            (0.18, {"hpitch": 0.55, "flex": 0.08, "py": H_STAND - 0.01}),
            (0.45, bottom),
            (0.58, {"py": 0.535, "pitch": 0.78}),
            (0.82, {"pz": -0.05, "py": 0.88, "pitch": 0.22, "flex": 0.10, "hpitch": 0.25}),
            (1.0, neutral_key(carry=True))]
    k = keyed(keys, T, t1)
    c1 = neutral_controls(N1 + 1, x0, z0, th0)
    apply_keys(c1, k, x0, z0, th0)
    reach = ramp(t1, 0.22 * T, 0.46 * T)
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
    N3, t3 = frame_times(T, fps)
    T = N3 / fps
    keys = [(0.0, neutral_key(carry=True)),
            (0.20, {"hpitch": 0.45, "pz": -0.02, "py": H_STAND - 0.05, "pitch": 0.15, "flex": 0.05}),
            (0.45, {**bottom, "hpitch": 0.35}),
            (0.60, {"py": 0.535, "pitch": 0.78}),
            (0.86, {"pz": -0.05, "py": 0.88, "pitch": 0.22, "flex": 0.10, "hpitch": 0.2,
                    "swingL": 0.1, "swingR": 0.1}),
            (1.0, neutral_key())]
    k = keyed(keys, T, t3)
    c3 = neutral_controls(N3 + 1, x1, z1, th1)
    apply_keys(c3, k, x1, z1, th1)
    c3.hand_world[:] = body_to_world(BOX_GRIP, x1, z1, th1)
    _ride_box(skel, c3, t3, grip_t=0.46 * T, lift=(0.12 * T, 0.46 * T), place=True)
    c3.hand_w[:] = (1.0 - ramp(t3, 0.53 * T, 0.74 * T))[:, None]
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
