"""Box hand-overs: one performer hands a carried box to another (and on to a third).

Giver and taker stand face to face. The giver pushes the box forward to the middle, the
taker's hands reach its sides, both hold it for a moment, then the taker brings it in to
its own carrying pose while the giver's hands drop. The box follows one track from the
giver's carrying position through the middle to the taker's; each holder's wrists are
world targets on that track until the taker's switch to the thorax-attached carry pose.
"""
from __future__ import annotations

import numpy as np

from runtime.motion import quat

from ..activities import BOX_SIZE
from ..curves import ramp
from ..gait import WALK
from ..group import Group
from ..keyframes import apply_keys, keyed, neutral_key
from ..rig import Controls, chest_transforms
from ..stance import CARRY_NEUTRAL, CARRY_WRIST, neutral_controls
from .choreography import Performer, heading_away, keyed_group, meet, run_to, start_state, turn_to, walk_off
from .scene import Event, Scene, finish_scene

__all__ = ["scene_box_pass", "scene_relay"]


_HOLD_DOWN = 0.10        # box centre below the wrists
_WRIST_ALONG = 0.09      # each holder's wrists this far from the box centre towards themselves


def _carry_wrists_world(skel, c: Controls):
    """(F, 2, 3) world positions of the carrying wrist targets (:data:`CARRY_WRIST` in the
    thorax frame of ``c``)."""
    rot, pos = chest_transforms(skel, c)
    F = c.num_frames
    out = np.empty((F, 2, 3))
    for s in (0, 1):
        out[:, s] = pos + quat.rotate(rot, np.broadcast_to(CARRY_WRIST[s], (F, 3)))
    return out


def _pass_pair(skel, rng, giver: Performer, taker: Performer, fps, f0, labels=("box_pass", "receive")):
    """The hand-over group for both (standing face to face, giver carrying). Returns the two
    groups, the contact interval (relative frames) and the box track (n, 3)."""
    T = float(rng.uniform(2.6, 3.1))
    t_out0, t_out1 = 0.05 * T, 0.38 * T          # giver pushes the box forward to the middle
    t_grab0, t_grab1 = 0.12 * T, 0.38 * T        # taker's hands reach the box sides
    t_hold1 = t_out1 + float(rng.uniform(0.3, 0.45))
    t_in1 = t_hold1 + 0.5                        # box to the taker's carry pose
    t_rel1 = t_hold1 + 0.4                       # giver's hands drop
    g_keys = [(0.0, neutral_key(carry=True)),
              (0.3, {"flex": 0.12, "pitch": 0.06, "hpitch": 0.35}),
              (t_hold1 / T, {}),
              (min((t_rel1 + 0.5) / T, 0.97), neutral_key()), (1.0, {})]
    r_keys = [(0.0, neutral_key()),
              (0.3, {"flex": 0.12, "pitch": 0.06, "hpitch": 0.35}),
              (t_hold1 / T, {}),
              (min((t_in1 + 0.3) / T, 0.97), neutral_key(carry=True)), (1.0, {})]
    cg, t = keyed_group(skel, giver.state, T, g_keys, fps, carry=True)
    cr, _ = keyed_group(skel, taker.state, T, r_keys, fps, carry=False)
    n = len(t)
    pg, pr = np.array(giver.state[:2]), np.array(taker.state[:2])
    d = (pr - pg) / np.linalg.norm(pr - pg)
    d3 = np.array([d[0], 0.0, d[1]])
    mid = 0.5 * (pg + pr)
    M = np.array([mid[0], float(rng.uniform(0.98, 1.05)), mid[1]])
    # box path: giver's carry position -> M -> taker's carry position
    wg = _carry_wrists_world(skel, cg)               # giver's carry wrists (trunk keyed)
    cr_carry = neutral_controls(n, taker.state[0], taker.state[1], taker.state[2], carry=True)
    apply_keys(cr_carry, keyed(r_keys, (n - 1) / fps, t), *taker.state)
    cr_carry.pelvis[:, 1] = cr.pelvis[:, 1]
    wr = _carry_wrists_world(skel, cr_carry)
    down = np.array([0.0, -_HOLD_DOWN, 0.0])
    box_g = wg.mean(axis=1) + down + _WRIST_ALONG * d3
    box_r = wr.mean(axis=1) + down - _WRIST_ALONG * d3
    u1 = ramp(t, t_out0, t_out1)[:, None]
    u2 = ramp(t, t_hold1, t_in1)[:, None]
    box = (1 - u1) * box_g + u1 * M
    box = (1 - u2) * box + u2 * box_r
    half_g = 0.5 * (wg[:, 0] - wg[:, 1])             # giver left minus right, half
    half_r = 0.5 * (wr[:, 0] - wr[:, 1])
    i_out = int(np.searchsorted(t, t_out0))
    i_in = min(int(np.searchsorted(t, t_in1)), n - 1)
    # giver: world targets follow the box from t_out0 (equal to the carry pose there)
    att_g = 1.0 - (t >= t_out0).astype(float)
    for s, sg in ((0, 1.0), (1, -1.0)):
        cg.hand_world[:, s] = box - down - _WRIST_ALONG * d3 + sg * half_g[i_out]
        cg.hand_attach[:, s] = att_g
    cg.hand_w[:, :] = (1.0 - ramp(t, t_hold1, t_rel1))[:, None]
    cg.clav[:, :, 0] = CARRY_NEUTRAL["clav"] * cg.hand_w[:, :1]
    # taker: reaches, holds, brings the box in; thorax-attached carry from t_in1 on
    att_r = (t >= t_in1).astype(float)
    for s, sg in ((0, 1.0), (1, -1.0)):
        cr.hand_world[:, s] = box - down + _WRIST_ALONG * d3 + sg * half_r[i_in]
        cr.hand_attach[:, s] = att_r
    cr.hand_thorax[:] = CARRY_WRIST
    cr.hand_w[:, :] = ramp(t, t_grab0, t_grab1)[:, None]
    cr.clav[:, :, 0] = CARRY_NEUTRAL["clav"] * ramp(t, t_in1 - 0.3, t_in1)[:, None]
    both = (t >= t_grab1) & (t <= t_hold1)
    idx = np.flatnonzero(both)
    contact = (int(idx[0]), int(idx[-1]))
    gg = Group(cg, [(0, n - 1, labels[0])], [(0, "carry_stand")], [], giver.state)
    gr = Group(cr, [(0, n - 1, labels[1])], [(0, "stand")], [], taker.state)
    return gg, gr, contact, box


def _hand_over(skel, rng, giver: Performer, taker: Performer, fps, f0, people):
    """The giver hands its box to the taker, both standing face to face from frame ``f0`` of
    the take: adds the hand-over groups to both timelines and returns the contact event and
    the box prop. ``people``: (giver, taker) indices in the take."""
    gg, gr, (c0, c1), box = _pass_pair(skel, rng, giver, taker, fps, f0)
    giver.add(gg)
    giver.carry = False
    taker.add(gr)
    taker.carry = True
    ev = Event("box_pass", "contact", people, f0 + c0, f0 + c1)
    prop = {"kind": "box", "size": list(BOX_SIZE), "pass_frames": [f0, f0 + len(box) - 1],
            "from": people[0], "to": people[1], "track": np.round(box, 4).tolist()}
    return ev, prop


def scene_box_pass(skel, rng, fps) -> Scene:
    """A walks up carrying a box and hands it to B; both walk off (B carrying)."""
    D = float(rng.uniform(0.8, 0.9))
    A, B, f0 = meet(skel, rng, fps, D, carry_a=True)
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    ev, prop = _hand_over(skel, rng, A, B, fps, f0, (0, 1))
    walk_off(skel, rng, fps, A, heading_away(rng, A, pb), carry=False)
    walk_off(skel, rng, fps, B, heading_away(rng, B, pa), carry=True)
    return finish_scene(skel, "box_pass", [A, B], fps, [ev], props=[prop])


def scene_relay(skel, rng, fps) -> Scene:
    """A hands a box to B; B turns to C (who has walked up) and hands it on."""
    D = float(rng.uniform(0.8, 0.9))
    A, B, f0 = meet(skel, rng, fps, D, carry_a=True)
    C = Performer("C", (0, 0, 0))
    pb = np.array(B.state[:2])
    ev1, prop1 = _hand_over(skel, rng, A, B, fps, f0, (0, 1))
    # B turns by +-90 deg (towards C's side)
    sgn = float(rng.choice([-1.0, 1.0]))
    new_h = B.state[2] + sgn * np.radians(rng.uniform(80, 100))
    g_turn = turn_to(skel, rng, B.state, new_h, fps, carry=True)
    end_b = np.array(g_turn.end[:2])
    fwd = np.array([np.sin(new_h), np.cos(new_h)])
    pc = end_b + fwd * float(rng.uniform(0.8, 0.9))
    gc = run_to(skel, rng, (pc[0], pc[1], new_h + np.pi), fps, WALK, 1)
    C.state = start_state(gc)
    walk_off(skel, rng, fps, A, heading_away(rng, A, pb, 20.0), carry=False)
    f_turn = B.frames
    B.add(g_turn)
    # B turning to C is a designed reaction, but C may still be out of proximity range then:
    # optional for recall (see Event.optional)
    ev_turn = Event("turn_to", "proximity", (1, 2), f_turn, B.frames - 1, optional=True)
    f2 = B.frames + int(rng.integers(3, 10))
    B.wait_until(f2, fps, look=pc)
    C.wait(max(f2 - gc.num_frames - int(rng.integers(5, 15)), 0), fps)
    C.add(gc)
    if C.frames > f2:                                  # C late: B waits longer
        f2 = C.frames
        B.wait_until(f2, fps, look=pc)
    C.wait_until(f2, fps, look=end_b)
    ev2, prop2 = _hand_over(skel, rng, B, C, fps, f2, (1, 2))
    walk_off(skel, rng, fps, B, heading_away(rng, B, pc, 20.0), carry=False)
    walk_off(skel, rng, fps, C, heading_away(rng, C, end_b, 20.0), carry=True)
    return finish_scene(skel, "relay", [A, B, C], fps, [ev1, ev_turn, ev2], props=[prop1, prop2])
