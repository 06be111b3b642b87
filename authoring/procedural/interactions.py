"""Procedural multi-character capture: two- and three-person takes on one shared clock.

Builds on the single-performer generator (:mod:`.activities`, :mod:`.gait`, :mod:`.rig`):
every performer is a sequence of activity :class:`~.activities.Group` s (standing holds, walk
runs, keyframed actions) whose controls are solved by the same rig, so planted feet come out
exact. What is new here is the *coordination* between performers:

* **Meeting.** A walk run is planned at the origin, then rotated and translated so that it
  ends exactly at a wanted standing place and heading (facing the partner); the performer
  who arrives first waits there, so the interaction starts on the same frame for everybody.
* **Hands that meet.** Handshake, high five and the box hand-over drive the arms' IK with
  world wrist targets; after a first solve, forward kinematics measures the *hand centre*
  (midway between the hand joint and the index end site) and the wrist targets are corrected
  so the two hand centres meet (about 3 cm apart: palm to palm) while in contact.
* **Reactions.** A shoulder bump is a walk run that passes the other performer's shoulder;
  the bumped performer staggers two steps back, twisting, a fixed reaction delay after the
  contact frame. A dash is a fast run past a standing performer who side-steps out of the way
  when the dasher is about 2.5 m away.
* **Ground truth.** Every scene returns its events (label, kind ``contact`` / ``proximity`` /
  ``sync``, performers, frame interval) for the episode detector's tests, and per-performer
  label segments that tile every frame.

Scenes (``SCENES``): handshake, high_five, bow, bump, box_pass, dash_dodge (two people);
relay (box A -> B -> C), bow3 (three in a circle), handshake_bystander (a third person walks
by far away); walker (one person) and pair_apart (two people who never meet). Each scene is a
function ``(skel, rng, fps) -> Scene``; all randomness comes from ``rng``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from runtime.motion import Clip, quat
from runtime.motion.clip import rotate_xz
from runtime.motion.fk import end_site_positions, forward_kinematics

from . import activities as act
from . import body
from .activities import (BOX_SIZE, CARRY_NEUTRAL, CARRY_WRIST, NEUTRAL, Group, body_to_world,
                         neutral_controls)
from .curves import smootherstep, smoothstep
from .gait import CARRY, WALK, Footprint, GaitStyle, foot_tracks, plan_run
from .rig import Controls, chest_transforms, solve

__all__ = ["GENERATOR_VERSION", "Scene", "Event", "SCENES", "SCENE_LABELS", "DASH", "make_scene", "hand_centres"]

GENERATOR_VERSION = "1.0"

DASH = GaitStyle("dash", 2.0, 1.2, 0.06, 0.10, np.radians(5.0), 0.6, 2.4,
                 np.radians(16.0), np.radians(62.0), 0.07, ("dash_l", "dash_r"), "dash")

SCENE_LABELS = ("handshake", "high_five", "bow", "bump", "stagger", "box_pass", "dash", "dodge",
                "wait", "walk", "start", "stop", "idle", "turn", "carry", "receive")
REACTION_DELAY = 0.12          # s from a bump contact to the bumped performer's first response
_PALM_GAP = 0.03               # m between the two hand centres while hands are together


@dataclass
class Event:
    """A ground-truth interaction: ``people`` (indices) do ``label`` over frames
    ``[start, end]`` (inclusive) of the take; ``kind`` is contact / proximity / sync.
    ``optional``: a designed reaction that a detector may or may not flag (it explains a
    detection but is not counted as missed)."""
    label: str
    kind: str
    people: tuple
    start: int
    end: int
    optional: bool = False

    def to_json(self) -> dict:
        d = {"label": self.label, "kind": self.kind, "people": [int(p) for p in self.people],
             "start": int(self.start), "end": int(self.end)}
        if self.optional:
            d["optional"] = True
        return d


@dataclass
class Scene:
    kind: str
    names: list
    clips: list                       # one Clip per performer, same frame count and fps
    segments: list                    # per performer [(start, end_exclusive, label)]
    events: list                      # [Event]
    props: list = field(default_factory=list)
    diagnostics: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------------------
# body helpers
# ------------------------------------------------------------------------------------------
def hand_centres(skel, clip_or_solved) -> np.ndarray:
    """(F, 2, 3) world hand centres (left, right): midway between the hand joint and the
    index-finger end site."""
    if isinstance(clip_or_solved, Clip):
        gr, gp = clip_or_solved.fk()
    else:
        gr, gp = forward_kinematics(skel, clip_or_solved.root_pos, clip_or_solved.local)
    es = end_site_positions(skel, gr, gp)
    ends = [j for j, _ in skel.end_sites]
    out = np.empty(gp.shape[:-2] + (2, 3))
    for s, (hand, idx) in enumerate((("LeftHand", "LeftHandIndex1"), ("RightHand", "RightHandIndex1"))):
        e = ends.index(skel.index(idx))
        out[..., s, :] = 0.5 * (gp[..., skel.index(hand), :] + es[..., e, :])
    return out


def _look_yaw(state, target):
    """Head yaw (relative to the body heading) that looks from ``state`` at ``target``."""
    x, z, th = state
    want = np.arctan2(target[0] - x, target[1] - z)
    return float(np.clip((want - th + np.pi) % (2 * np.pi) - np.pi, -1.1, 1.1))


def _heading_to(a, b):
    return float(np.arctan2(b[0] - a[0], b[1] - a[1]))


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _frames(T, fps):
    n = max(int(round(T * fps)), 2)
    return n, np.arange(n + 1) / fps


# ------------------------------------------------------------------------------------------
# groups
# ------------------------------------------------------------------------------------------
def hold(state, n, fps, carry=False, look=None, label="wait") -> Group:
    """Standing still in the hub pose for ``n`` frames (controls n + 1); when ``look`` is a
    point, the head turns towards it in the middle and back to neutral at both ends."""
    x0, z0, th0 = state
    c = neutral_controls(n + 1, x0, z0, th0, carry=carry)
    if look is not None and n >= 24:
        t = np.arange(n + 1) / fps
        T = n / fps
        w = smootherstep(t / 0.6) * smootherstep((T - t) / 0.6)
        c.head[:, 1] = _look_yaw(state, look) * w
    hub = "carry_stand" if carry else "stand"
    return Group(c, [(0, n, "carry" if carry and label == "wait" else label)], [(0, hub)], [], state)


def _edges(rng, n_walk, max_turn_deg, start_turn_deg=15.0):
    edges = [("start", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-start_turn_deg, start_turn_deg))))]
    for _ in range(n_walk):
        n = int(rng.integers(2, 5))
        edges.append(("walk", n, float(np.radians(rng.uniform(-max_turn_deg, max_turn_deg))),
                      float(rng.uniform(-0.2, 0.15))))
    edges.append(("stop", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-10.0, 10.0)))))
    return edges


def _fix_labels(plan, style):
    if style.label is None:
        return plan.segments
    return [(a, b, style.label) for a, b, _ in plan.segments]


def run_to(skel, rng, target, fps, style=WALK, n_walk=1, max_turn_deg=30.0) -> Group:
    """A walk run (start, walk edges, stop) that ends standing exactly at ``target`` =
    (x, z, heading): planned at the origin, then rotated and translated into place."""
    edges = _edges(rng, n_walk, max_turn_deg)
    first = int(rng.integers(0, 2))
    p0 = plan_run(style, edges, 0.0, 0.0, 0.0, first, fps)
    ex, ez, eth = p0.end_state
    th0 = target[2] - eth
    off = rotate_xz(np.array([ex, ez]), th0)
    plan = plan_run(style, edges, target[0] - off[0], target[1] - off[1], th0, first, fps)
    c = act.run_controls(plan, skel)
    return Group(c, _fix_labels(plan, style), plan.hubs, [], tuple(float(v) for v in plan.end_state))


def run_from(skel, rng, state, fps, style=WALK, n_walk=1, max_turn_deg=30.0) -> Group:
    """A walk run starting from standing at ``state``; returns the group (end in ``.end``)."""
    edges = _edges(rng, n_walk, max_turn_deg)
    plan = plan_run(style, edges, state[0], state[1], state[2], int(rng.integers(0, 2)), fps)
    c = act.run_controls(plan, skel)
    return Group(c, _fix_labels(plan, style), plan.hubs, [], tuple(float(v) for v in plan.end_state))


def straight_run(style, n_steps, first, fps, x0=0.0, z0=0.0, th0=0.0):
    """Plan of a straight run: start, walk edges (no turns, no speed change), stop."""
    n_start = 3
    n_stop = 3
    mids = []
    left = n_steps
    while left > 0:
        k = min(4, left)
        mids.append(("walk", k, 0.0, 0.0))
        left -= k
    edges = [("start", n_start, 0.0)] + mids + [("stop", n_stop, 0.0)]
    return plan_run(style, edges, x0, z0, th0, first, fps)


def turn_to(skel, rng, state, heading, fps, carry=False) -> Group:
    """Turning on the spot to ``heading`` (exactly) in small steps, like
    :func:`.activities.turn_in_place` but to a given heading and optionally carrying."""
    x0, z0, th0 = state
    dth = float(_wrap(heading - th0))
    pairs = max(1, int(np.ceil(abs(dth) / np.radians(65.0))))
    lead = 0 if dth > 0 else 1
    swing = float(rng.uniform(0.36, 0.44))
    prints = act.standing_prints(x0, z0, th0)
    t = 0.3
    steps = []
    for i in range(pairs):
        th_i = th0 + dth * (i + 1) / pairs
        for side in (lead, 1 - lead):
            sg = 1.0 if side == 0 else -1.0
            p = body_to_world(np.array([sg * WALK.stand_width, 0.0, 0.0]), x0, z0, th_i)
            steps.append((side, t, t + swing, p, th_i + sg * WALK.toe_out))
            t += swing + 0.12
    T = t + 0.35
    N, times = _frames(T, fps)
    last = {0: prints[0], 1: prints[1]}
    allp = list(prints)
    for side, t_lift, t_land, p, yaw in steps:
        last[side].t_lift = t_lift
        last[side].t_heeloff = t_lift
        fp = Footprint(side, float(p[0]), float(p[2]), float(yaw), t_land, t_land, np.inf, np.inf, clearance=0.05)
        allp.append(fp)
        last[side] = fp
    allp.sort(key=lambda q: (q.side, q.t_land))
    ankle, fq, toe, _, _ = foot_tracks(allp, times)
    t_first, t_last = steps[0][1], steps[-1][2]
    head = th0 + dth * smootherstep((times - t_first + 0.1) / (t_last - t_first + 0.1))
    c = neutral_controls(N + 1, x0, z0, th0, carry=carry)
    c.heading[:] = head
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    sway = np.zeros(N + 1)
    for side, t_lift, t_land, p, yaw in steps:
        stance_sg = -1.0 if side == 0 else 1.0
        m = smoothstep((times - t_lift + 0.18) / 0.2) * (1 - smoothstep((times - t_land + 0.05) / 0.2))
        sway += stance_sg * 0.025 * m
    c.root_pos[:, 0] = x0 + np.cos(head) * sway
    c.root_pos[:, 2] = z0 - np.sin(head) * sway
    c.pelvis[:, 2] = 0.8 * sway
    c.spine[:, 1] = 0.6 * sway
    look = np.interp(np.minimum(times + 0.35, times[-1]), times, head) - head
    c.head[:, 1] = 0.8 * look
    c.spine[:, 2] = 0.3 * look
    act.limit_reach(skel, c)
    hub = "carry_stand" if carry else "stand"
    return Group(c, [(0, N, "carry" if carry else "turn")], [(0, hub)], [], (x0, z0, float(th0 + dth)))


def _keyed_group(skel, state, T, keys, fps, carry=False):
    """Standing keyframed action (feet planted at the standing footprints of ``state``)."""
    x0, z0, th0 = state
    N, times = _frames(T, fps)
    k = act._keyed(keys, N / fps, times)
    c = neutral_controls(N + 1, x0, z0, th0, carry=carry)
    act._apply_keys(c, k, x0, z0, th0)
    return c, times


def _ramp(t, a, b):
    return smootherstep((t - a) / max(b - a, 1e-6))


# ------------------------------------------------------------------------------------------
# person timelines and assembly
# ------------------------------------------------------------------------------------------
class _Person:
    def __init__(self, name, state):
        self.name = name
        self.state = tuple(float(v) for v in state)
        self.groups: list[Group] = []
        self.carry = False

    @property
    def frames(self) -> int:
        return sum(g.num_frames for g in self.groups)

    def add(self, g: Group):
        self.groups.append(g)
        self.state = tuple(float(v) for v in g.end)
        return g

    def wait(self, n, fps, look=None, label="wait"):
        if n > 0:
            self.add(hold(self.state, n, fps, carry=self.carry, look=look, label=label))

    def wait_until(self, frame, fps, look=None, label="wait"):
        n = frame - self.frames
        if n < 0:
            raise AssertionError(f"{self.name}: timeline already at {self.frames} > {frame}")
        self.wait(n, fps, look, label)


def _assemble(skel, person: _Person, fps):
    parts, segs = [], []
    f = 0
    for i, g in enumerate(person.groups):
        last = i == len(person.groups) - 1
        parts.append(g.controls if last else g.controls.slice(0, g.num_frames))
        segs += [(a + f, b + f, lab) for a, b, lab in g.segments]
        f += g.num_frames
    c = Controls.concat(parts)
    a, b, lab = segs[-1]
    segs[-1] = (a, c.num_frames, lab)
    merged = []
    for s in segs:                                   # merge consecutive equal labels
        if merged and merged[-1][2] == s[2] and merged[-1][1] == s[0]:
            merged[-1] = (merged[-1][0], s[1], s[2])
        elif s[1] > s[0]:
            merged.append(s)
    return c, merged


def _finish(skel, kind, people, fps, events, props=(), fixups=()) -> Scene:
    """Pad every timeline to the same length, solve, apply hand fix-ups, build clips."""
    F = max(p.frames for p in people)
    for p in people:
        p.wait_until(F, fps, label="wait")
    ctl, segs = zip(*[_assemble(skel, p, fps) for p in people])
    ctl = list(ctl)
    for fix in fixups:
        fix(ctl)
    sols = [solve(skel, c) for c in ctl]
    clips = [Clip.from_world(skel, fps, s.root_pos, s.local) for s in sols]
    diag = {
        "max_leg_reach_error_m": float(max(s.leg_reach_error.max() for s in sols)),
        "max_arm_reach_error_m": float(max(s.arm_reach_error.max() for s in sols)),
    }
    return Scene(kind, [p.name for p in people], clips, list(segs), list(events), list(props), diag)


def _hand_fixup(skel, pairs, iterations=3):
    """A fix-up that corrects world wrist targets so hand centres reach their goals.

    ``pairs``: [(person, side, frames (slice), goals (n, 3))]. Frames where the hand's
    target weight is below 1 get the correction of the nearest full-weight frame scaled by
    the weight, so the hand still arrives smoothly."""
    def fix(ctl):
        for _ in range(iterations):
            sol_cache = {}
            for person, side, sl, goals in pairs:
                if person not in sol_cache:
                    sol_cache[person] = solve(skel, ctl[person])
                hc = hand_centres(skel, sol_cache[person])[sl, side]
                c = ctl[person]
                w = c.hand_w[sl, side]
                full = w > 0.999
                err = goals - hc
                if not np.any(full):
                    continue
                idx = np.flatnonzero(full)
                near = idx[np.clip(np.searchsorted(idx, np.arange(len(w))), 0, len(idx) - 1)]
                prev = idx[np.clip(np.searchsorted(idx, np.arange(len(w))) - 1, 0, len(idx) - 1)]
                pick = np.where(np.abs(near - np.arange(len(w))) <= np.abs(prev - np.arange(len(w))), near, prev)
                corr = np.where(full[:, None], err, err[pick] * w[:, None])
                c.hand_world[sl, side] += corr
    return fix


# ------------------------------------------------------------------------------------------
# two-person encounters that meet face to face
# ------------------------------------------------------------------------------------------
def _meet(skel, rng, fps, D, names=("A", "B"), carry_a=False):
    """Two performers walk up to each other and stop ``D`` apart, facing. Returns the two
    persons (timelines up to the common start frame) and the meeting frame."""
    centre = rng.uniform(-1.0, 1.0, size=2)
    axis = float(rng.uniform(-np.pi, np.pi))
    d = np.array([np.sin(axis), np.cos(axis)])
    pa = centre - d * D / 2
    pb = centre + d * D / 2
    A = _Person(names[0], (0, 0, 0))
    B = _Person(names[1], (0, 0, 0))
    A.carry = carry_a
    ga = run_to(skel, rng, (pa[0], pa[1], axis), fps, CARRY if carry_a else WALK, int(rng.integers(1, 3)))
    gb = run_to(skel, rng, (pb[0], pb[1], axis + np.pi), fps, WALK, int(rng.integers(1, 3)))
    A.state = tuple(float(v) for v in ga.controls.root_pos[0, [0, 2]]) + (float(ga.controls.heading[0]),)
    B.state = tuple(float(v) for v in gb.controls.root_pos[0, [0, 2]]) + (float(gb.controls.heading[0]),)
    pad = int(rng.integers(6, 20))
    wait = [int(rng.integers(6, 25)) for _ in range(2)]
    meet = pad + max(ga.num_frames + wait[0], gb.num_frames + wait[1])
    for P, g, wt in ((A, ga, wait[0]), (B, gb, wait[1])):
        P.wait(meet - g.num_frames - wt, fps)
        P.add(g)
        P.wait_until(meet, fps)
    return A, B, meet


def _leave(skel, rng, fps, P: _Person, away_heading, carry=False, n_walk=1):
    """Turn (if needed) towards ``away_heading`` and walk off."""
    if abs(_wrap(away_heading - P.state[2])) > np.radians(20.0):
        P.add(turn_to(skel, rng, P.state, away_heading, fps, carry=carry))
    P.add(run_from(skel, rng, P.state, fps, CARRY if carry else WALK, n_walk, max_turn_deg=20.0))


def _away(rng, P: _Person, other_xz, spread=35.0):
    """A heading pointing away from ``other_xz`` (with some spread)."""
    base = _heading_to(other_xz, P.state[:2])
    return float(base + np.radians(rng.uniform(-spread, spread)))


def _arm_shake_keys(lean, look_pitch):
    return {"flex": NEUTRAL["flex"] + lean, "pitch": NEUTRAL["pitch"] + 0.4 * lean, "hpitch": look_pitch}


def scene_handshake(skel, rng, fps) -> Scene:
    D = float(rng.uniform(0.82, 0.9))
    A, B, f0 = _meet(skel, rng, fps, D)
    T = float(rng.uniform(2.8, 3.4))
    ta, tb = 0.12 * T, 0.36 * T           # reach
    tr0, tr1 = 0.74 * T, 0.94 * T         # release
    cycles = int(rng.integers(2, 4))
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    mid = 0.5 * (pa + pb)
    axis = A.state[2]
    groups, goals = [], []
    for P in (A, B):
        lean = float(rng.uniform(0.05, 0.1))
        keys = [(0.0, act._neutral_key()), (0.3, _arm_shake_keys(lean, 0.25)), (0.5, {}),
                (0.78, _arm_shake_keys(lean * 0.6, 0.15)), (1.0, act._neutral_key())]
        c, t = _keyed_group(skel, P.state, T, keys, fps)
        w = _ramp(t, ta, tb) * (1.0 - _ramp(t, tr0, tr1))
        c.hand_w[:, 1] = w
        shake = 0.035 * np.sin(2 * np.pi * cycles * np.clip((t - tb) / (tr0 - tb), 0, 1)) * (t > tb) * (t < tr0)
        groups.append((P, c, t, shake))
    h = float(rng.uniform(0.98, 1.04))
    lat = np.array([np.cos(axis), -np.sin(axis)])        # A's left in the world
    n = len(groups[0][2])
    for i, (P, c, t, shake) in enumerate(groups):
        # hand centres side by side (palm to palm) across the line between the two
        goal_xz = mid + (1 if i == 0 else -1) * 0.5 * _PALM_GAP * lat
        goal = np.stack([np.full(n, goal_xz[0]), h + shake, np.full(n, goal_xz[1])], axis=-1)
        toward = (pb - pa) if i == 0 else (pa - pb)
        toward = toward / np.linalg.norm(toward)
        wrist = goal - 0.085 * np.array([toward[0], 0.0, toward[1]])
        c.hand_world[:, 1] = wrist
        c.wrist[:, 1] = 0.0
        goals.append(goal)
        P.add(Group(c, [(0, n - 1, "handshake")], [(0, "stand")], [], P.state))
    full = np.flatnonzero((groups[0][1].hand_w[:, 1] > 0.999))
    ev = Event("handshake", "contact", (0, 1), f0 + int(full[0]), f0 + int(full[-1]))
    sl = slice(f0, f0 + n)
    fix = _hand_fixup(skel, [(0, 1, sl, goals[0]), (1, 1, sl, goals[1])])
    for P, other in ((A, pb), (B, pa)):
        _leave(skel, rng, fps, P, _away(rng, P, other), n_walk=1)
    return _finish(skel, "handshake", [A, B], fps, [ev], fixups=[fix])


def scene_high_five(skel, rng, fps) -> Scene:
    D = float(rng.uniform(0.78, 0.86))
    A, B, f0 = _meet(skel, rng, fps, D)
    T = float(rng.uniform(1.8, 2.2))
    t_up0, t_hit = 0.12 * T, 0.45 * T
    hold_s = float(rng.uniform(0.1, 0.16))
    t_dn1 = 0.85 * T
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    mid = 0.5 * (pa + pb)
    toward = (pb - pa) / np.linalg.norm(pb - pa)
    h = float(rng.uniform(1.6, 1.68))
    goals, cs = [], []
    for i, P in enumerate((A, B)):
        keys = [(0.0, act._neutral_key()), (0.45, {"hpitch": -0.15, "pitch": NEUTRAL["pitch"] + 0.02,
                                                   "flex": NEUTRAL["flex"] + 0.04, "lat": -0.05}),
                (0.6, {}), (1.0, act._neutral_key())]
        c, t = _keyed_group(skel, P.state, T, keys, fps)
        up = _ramp(t, t_up0, t_hit)
        down = _ramp(t, t_hit + hold_s, t_dn1)
        c.hand_w[:, 1] = up * (1.0 - down)
        sgn = 1.0 if i == 0 else -1.0
        goal_xz = mid - sgn * 0.5 * _PALM_GAP * toward
        goal = np.tile([goal_xz[0], h, goal_xz[1]], (len(t), 1))
        # the wrist below and behind the hand centre (fingers up); the fix-up refines it
        back = np.array([toward[0], 0.0, toward[1]]) * sgn
        c.hand_world[:, 1] = goal - np.array([0.0, 0.07, 0.0]) - 0.03 * back
        c.wrist[:, 1] = -0.9 * up * (1.0 - down)
        c.clav[:, 1, 0] = 0.15 * up * (1.0 - down)
        goals.append(goal)
        cs.append((c, t))
        P.add(Group(c, [(0, len(t) - 1, "high_five")], [(0, "stand")], [], P.state))
    c0 = cs[0][0]
    full = np.flatnonzero(c0.hand_w[:, 1] > 0.999)
    ev = Event("high_five", "contact", (0, 1), f0 + int(full[0]), f0 + int(full[-1]))
    n = len(cs[0][1])
    sl = slice(f0, f0 + n)
    fix = _hand_fixup(skel, [(0, 1, sl, goals[0]), (1, 1, sl, goals[1])])
    for P, other in ((A, pb), (B, pa)):
        _leave(skel, rng, fps, P, _away(rng, P, other), n_walk=1)
    return _finish(skel, "high_five", [A, B], fps, [ev], fixups=[fix])


def _bow(skel, rng, P: _Person, fps, t_start, depth, T, look_at):
    """A bow starting ``t_start`` s into a group of length ``T``."""
    t_down, t_hold, t_up = t_start + 0.75, t_start + 0.75 + float(rng.uniform(0.4, 0.8)), None
    t_up = t_hold + 0.8
    f = lambda s: s / T  # noqa: E731
    bowed = {"pitch": NEUTRAL["pitch"] + 0.45 * depth, "flex": NEUTRAL["flex"] + 0.55 * depth,
             "hpitch": 0.55 + 0.5 * depth, "pz": -0.07 * depth, "py": act.H_STAND - 0.015,
             "swingL": 0.05, "swingR": 0.05, "elbowL": 0.15, "elbowR": 0.15}
    keys = [(0.0, act._neutral_key()), (f(t_start), {}), (f(t_down), bowed), (f(t_hold), {}),
            (f(t_up), act._neutral_key()), (1.0, {})]
    c, t = _keyed_group(skel, P.state, T, keys, fps)
    w = _ramp(t, 0.1, t_start) * (1.0 - _ramp(t, t_up, min(t_up + 0.5, T)))
    c.head[:, 1] = _look_yaw(P.state, look_at) * w
    act.limit_reach(skel, c)
    return c, t, (t_start, t_up)


def scene_bow(skel, rng, fps) -> Scene:
    D = float(rng.uniform(1.4, 1.7))
    A, B, f0 = _meet(skel, rng, fps, D)
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    lead = float(rng.uniform(0.3, 0.5))
    lag = float(rng.uniform(0.08, 0.3))
    T = lead + lag + 3.0
    spans = []
    for P, other, ts in ((A, pb, lead), (B, pa, lead + lag)):
        c, t, span = _bow(skel, rng, P, fps, ts, float(rng.uniform(0.8, 1.1)), T, other)
        spans.append(span)
        P.add(Group(c, [(0, len(t) - 1, "bow")], [(0, "stand")], [], P.state))
    s0 = f0 + int(round(min(s[0] for s in spans) * fps))
    s1 = f0 + int(round(max(s[1] for s in spans) * fps))
    ev = Event("bow", "sync", (0, 1), s0, s1)
    for P, other in ((A, pb), (B, pa)):
        _leave(skel, rng, fps, P, _away(rng, P, other), n_walk=1)
    return _finish(skel, "bow", [A, B], fps, [ev])


# ------------------------------------------------------------------------------------------
# shoulder bump with a stagger
# ------------------------------------------------------------------------------------------
def stagger(skel, rng, state, fps, push_dir, hit_side, delay) -> Group:
    """Pushed at one shoulder: the body twists, two quick steps back along ``push_dir``
    (world unit vector) catch the fall, arms go out, then the performer settles standing.
    ``hit_side`` 0 = left shoulder, 1 = right; ``delay`` s of standing before the reaction."""
    x0, z0, th0 = state
    T = delay + float(rng.uniform(1.9, 2.3))
    N, t = _frames(T, fps)
    dist = float(rng.uniform(0.28, 0.4))
    sg = 1.0 if hit_side == 0 else -1.0
    dth = sg * float(np.radians(rng.uniform(18.0, 30.0)))      # hit shoulder goes back
    th1 = th0 + dth
    p1 = np.array([x0, z0]) + dist * np.asarray(push_dir)
    # root: quick shove (overshoot) then settle
    s = _ramp(t, delay, delay + 0.55)
    over = 0.07 * np.sin(np.pi * np.clip((t - delay) / 0.9, 0, 1)) ** 2
    xz = np.array([x0, z0]) + (s * dist + over)[:, None] * np.asarray(push_dir)
    head = th0 + dth * _ramp(t, delay, delay + 0.6)
    # steps: hit-side foot first (it is unloaded by the push), then the other
    prints = act.standing_prints(x0, z0, th0)
    finals = act.standing_prints(p1[0], p1[1], th1)
    first = hit_side
    t1a, t1b = delay + 0.08, delay + 0.36
    t2a, t2b = delay + 0.3, delay + 0.62
    for side, ta, tb in ((first, t1a, t1b), (1 - first, t2a, t2b)):
        prints[side].t_lift = ta
        prints[side].t_heeloff = ta
        fp = finals[side]
        fp.t_land, fp.t_flat = tb, tb
        fp.clearance = 0.045
        prints.append(fp)
    prints.sort(key=lambda q: (q.side, q.t_land))
    ankle, fq, toe, _, _ = foot_tracks(prints, t)
    keys = [(0.0, act._neutral_key()), (delay / T, {}),
            ((delay + 0.22) / T, {"pitch": NEUTRAL["pitch"] - 0.12, "flex": NEUTRAL["flex"] - 0.08,
                                  "twist": 0.25 * sg, "lat": 0.08 * sg, "roll": 0.05 * sg, "hpitch": 0.0,
                                  "hyaw": 0.35 * sg, "abdL": 0.55, "abdR": 0.55, "elbowL": 0.6, "elbowR": 0.6,
                                  "swingL": 0.2, "swingR": 0.2}),
            ((delay + 0.6) / T, {"pitch": NEUTRAL["pitch"] + 0.08, "flex": NEUTRAL["flex"] + 0.06,
                                 "twist": 0.1 * sg, "lat": 0.0, "roll": 0.0, "hpitch": 0.2, "hyaw": 0.5 * sg,
                                 "abdL": 0.35, "abdR": 0.35}),
            ((delay + 1.2) / T, {**act._neutral_key(), "hyaw": 0.4 * sg}),
            (1.0, act._neutral_key())]
    k = act._keyed(keys, N / fps, t)
    c = neutral_controls(N + 1, x0, z0, th0)
    act._apply_keys(c, k, x0, z0, th0)
    # re-place the keyed pelvis offsets along the moving root
    loc = np.stack([k["px"], k["py"], k["pz"]], axis=-1)
    for i in range(N + 1):
        c.root_pos[i] = body_to_world(loc[i], xz[i, 0], xz[i, 1], head[i])
    c.heading[:] = head
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    act.limit_reach(skel, c)
    return Group(c, [(0, int(round(delay * fps)), "wait"), (int(round(delay * fps)), N, "stagger")],
                 [(0, "stand")], [], (float(p1[0]), float(p1[1]), float(th1)))


def scene_bump(skel, rng, fps) -> Scene:
    centre = rng.uniform(-1.0, 1.0, size=2)
    axis = float(rng.uniform(-np.pi, np.pi))            # direction the bumper walks
    fwd = np.array([np.sin(axis), np.cos(axis)])
    left = np.array([np.cos(axis), -np.sin(axis)])      # the bumper's left in the world
    # B stands at the centre facing the bumper (heading axis + pi), so B's right is the bumper's
    # left; the bumper's line is offset to its left, so the two right shoulders meet.
    B = _Person("B", (0, 0, 0))
    A = _Person("A", (0, 0, 0))
    gb = run_to(skel, rng, (centre[0], centre[1], axis + np.pi + np.radians(rng.uniform(-10, 10))), fps,
                WALK, int(rng.integers(1, 3)))
    B.state = tuple(float(v) for v in gb.controls.root_pos[0, [0, 2]]) + (float(gb.controls.heading[0]),)
    lateral = float(rng.uniform(0.36, 0.42))
    n_steps = int(rng.integers(7, 10))
    first = int(rng.integers(0, 2))
    p0 = straight_run(WALK, n_steps, first, fps)
    # distance along the path where A's root is level with B (contact): about the middle
    s_path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p0.path, axis=0), axis=1))])
    L = s_path[-1]
    s_contact = L * float(rng.uniform(0.5, 0.62))
    start_xz = centre + left * lateral - fwd * s_contact
    plan = straight_run(WALK, n_steps, first, fps, start_xz[0], start_xz[1], axis)
    ga = Group(act.run_controls(plan, skel), plan.segments, plan.hubs, [], plan.end_state)
    # contact frame: A's right shoulder level with B's right shoulder
    rel = np.sum((plan.path - centre) * fwd, axis=1)
    f_pass = int(np.argmin(np.abs(rel)))
    # timelines: B arrives and waits; A starts so that it passes B after B has stood a while
    pad_b = int(rng.integers(6, 20))
    B.wait(pad_b, fps)
    B.add(gb)
    t_b_ready = B.frames + int(rng.integers(20, 45))
    start_a = max(t_b_ready - f_pass, int(rng.integers(6, 20)))
    A.state = (float(start_xz[0]), float(start_xz[1]), axis)
    A.wait(start_a, fps)
    A.add(ga)
    f_contact = start_a + f_pass
    B.wait_until(f_contact - 1, fps)                 # B does not see it coming
    delay = 1.0 / fps + REACTION_DELAY
    push = fwd * 0.8 + left * 0.35                      # pushed along A's walk, a little aside
    push = push / np.linalg.norm(push)
    g = stagger(skel, rng, B.state, fps, push, 1, delay)
    B.add(g)
    stag0 = f_contact - 1 + int(round(delay * fps))
    ev_contact = Event("bump", "contact", (0, 1), f_contact - 2, f_contact + 2)
    ev_react = Event("stagger", "proximity", (0, 1), stag0, stag0 + int(round(0.7 * fps)))
    # A twists as it bumps; added on its controls around the contact frame
    def twist(ctl):
        c = ctl[0]
        t = (np.arange(c.num_frames) - f_contact) / fps
        bumpw = np.exp(-0.5 * ((t - 0.12) / 0.12) ** 2)
        c.spine[:, 2] -= 0.22 * bumpw                  # right shoulder driven back
        c.pelvis[:, 0] -= 0.08 * bumpw
        c.head[:, 1] += -0.3 * np.exp(-0.5 * ((t - 0.5) / 0.35) ** 2)
    _leave(skel, rng, fps, B, _away(rng, B, plan.path[-1], 40.0), n_walk=1)
    return _finish(skel, "bump", [A, B], fps, [ev_contact, ev_react], fixups=[twist])


# ------------------------------------------------------------------------------------------
# dash and dodge
# ------------------------------------------------------------------------------------------
def sidestep(skel, rng, state, fps, side, delay, look_at) -> Group:
    """Quick side-step to ``side`` (0 left, 1 right) by about half a metre, leaning away."""
    x0, z0, th0 = state
    T = delay + float(rng.uniform(1.5, 1.8))
    N, t = _frames(T, fps)
    L = float(rng.uniform(0.6, 0.75))
    sg = 1.0 if side == 0 else -1.0
    dth = float(np.radians(rng.uniform(-12, 12)))
    th1 = th0 + dth
    shift = body_to_world(np.array([sg * L, 0.0, float(rng.uniform(-0.1, 0.05))]), x0, z0, th0)
    p1 = np.array([shift[0], shift[2]])
    prints = act.standing_prints(x0, z0, th0)
    finals = act.standing_prints(p1[0], p1[1], th1)
    lead = side
    for s_, ta, tb in ((lead, delay + 0.06, delay + 0.34), (1 - lead, delay + 0.3, delay + 0.58)):
        prints[s_].t_lift = ta
        prints[s_].t_heeloff = ta
        fp = finals[s_]
        fp.t_land, fp.t_flat = tb, tb
        fp.clearance = 0.05
        prints.append(fp)
    prints.sort(key=lambda q: (q.side, q.t_land))
    ankle, fq, toe, _, _ = foot_tracks(prints, t)
    s = _ramp(t, delay, delay + 0.5)
    xz = np.array([x0, z0]) + s[:, None] * (p1 - np.array([x0, z0]))
    head = th0 + dth * _ramp(t, delay + 0.2, delay + 0.9)
    keys = [(0.0, act._neutral_key()), (delay / T, {}),
            ((delay + 0.25) / T, {"roll": -0.1 * sg, "lat": -0.12 * sg, "pitch": NEUTRAL["pitch"] + 0.08,
                                  "flex": NEUTRAL["flex"] + 0.1, "abdL": 0.35, "abdR": 0.35,
                                  "elbowL": 0.7, "elbowR": 0.7, "swingL": 0.25, "swingR": 0.25,
                                  "py": act.H_STAND - 0.05}),
            ((delay + 0.7) / T, {"roll": 0.0, "lat": 0.0, "py": act.H_STAND - 0.02}),
            (1.0, act._neutral_key())]
    k = act._keyed(keys, N / fps, t)
    c = neutral_controls(N + 1, x0, z0, th0)
    act._apply_keys(c, k, x0, z0, th0)
    loc = np.stack([k["px"], k["py"], k["pz"]], axis=-1)
    for i in range(N + 1):
        c.root_pos[i] = body_to_world(loc[i], xz[i, 0], xz[i, 1], head[i])
    c.heading[:] = head
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    # the head follows the dasher (look_at: (N+1, 2) positions over the group)
    yaw = np.array([_look_yaw((xz[i, 0], xz[i, 1], head[i]), look_at[i]) for i in range(N + 1)])
    c.head[:, 1] = yaw * smootherstep(t / 0.3) * (1 - _ramp(t, T - 0.5, T))
    act.limit_reach(skel, c)
    return Group(c, [(0, int(round(delay * fps)), "wait"), (int(round(delay * fps)), N, "dodge")],
                 [(0, "stand")], [], (float(p1[0]), float(p1[1]), float(th1)))


def scene_dash_dodge(skel, rng, fps) -> Scene:
    centre = rng.uniform(-1.0, 1.0, size=2)
    axis = float(rng.uniform(-np.pi, np.pi))
    fwd = np.array([np.sin(axis), np.cos(axis)])
    leftA = np.array([np.cos(axis), -np.sin(axis)])
    A = _Person("A", (0, 0, 0))
    B = _Person("B", (0, 0, 0))
    # B walks in and stands at the centre, facing roughly towards the dasher
    gb = run_to(skel, rng, (centre[0], centre[1], axis + np.pi + np.radians(rng.uniform(-25, 25))), fps,
                WALK, int(rng.integers(1, 3)))
    B.state = tuple(float(v) for v in gb.controls.root_pos[0, [0, 2]]) + (float(gb.controls.heading[0]),)
    n_steps = int(rng.integers(9, 12))
    first = int(rng.integers(0, 2))
    p0 = straight_run(DASH, n_steps, first, fps)
    s_path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p0.path, axis=0), axis=1))])
    s_pass = s_path[-1] * float(rng.uniform(0.55, 0.65))
    offset = float(rng.uniform(-0.1, 0.1))
    start_xz = centre + leftA * offset - fwd * s_pass
    plan = straight_run(DASH, n_steps, first, fps, start_xz[0], start_xz[1], axis)
    ga = Group(act.run_controls(plan, skel), [(a, b, "dash") for a, b, _ in plan.segments],
               plan.hubs, [], plan.end_state)
    rel = np.sum((plan.path - centre) * fwd, axis=1)
    f_pass = int(np.argmin(np.abs(rel)))
    f_react_rel = int(np.argmin(np.abs(rel + float(rng.uniform(2.3, 2.8)))))   # dasher ~2.5 m away
    B.wait(int(rng.integers(6, 20)), fps)
    B.add(gb)
    ready = B.frames + int(rng.integers(15, 40))
    start_a = max(ready - f_react_rel, int(rng.integers(6, 20)))
    A.state = (float(start_xz[0]), float(start_xz[1]), axis)
    A.wait(start_a, fps)
    A.add(ga)
    f_react = start_a + f_react_rel
    B.wait_until(f_react, fps, look=plan.path[max(f_react_rel - 10, 0)])
    # dodge away from the dasher's line: to the side B is on relative to it
    side_world = leftA if offset < 0 else -leftA                    # away from A's line
    bl = np.array([np.cos(B.state[2]), -np.sin(B.state[2])])       # B's left
    side = 0 if np.dot(side_world, bl) > 0 else 1
    delay = 0.15
    look = []
    n_g = int(round((delay + 1.9) * fps)) + 2          # frames of the side-step group (upper bound)
    for i in range(n_g):
        fa = min(f_react_rel + i, len(plan.path) - 1)
        look.append(plan.path[fa])
    g = sidestep(skel, rng, B.state, fps, side, delay, np.array(look))
    B.add(g)
    d0 = f_react + int(round(delay * fps))
    ev = Event("dodge", "proximity", (0, 1), d0, d0 + int(round(0.6 * fps)))
    _leave(skel, rng, fps, B, _away(rng, B, plan.path[-1], 40.0), n_walk=1)
    return _finish(skel, "dash_dodge", [A, B], fps, [ev])


# ------------------------------------------------------------------------------------------
# box hand-over
# ------------------------------------------------------------------------------------------
_HOLD_DOWN = 0.10        # box centre below the wrists
_WRIST_ALONG = 0.09      # each holder's wrists this far from the box centre towards themselves


def _carry_wrists_world(skel, c: Controls):
    rot, pos = chest_transforms(skel, c)
    F = c.num_frames
    out = np.empty((F, 2, 3))
    for s in (0, 1):
        out[:, s] = pos + quat.rotate(rot, np.broadcast_to(CARRY_WRIST[s], (F, 3)))
    return out


def _pass_pair(skel, rng, giver: _Person, taker: _Person, fps, f0, labels=("box_pass", "receive")):
    """The hand-over group for both (standing face to face, giver carrying). Returns the two
    groups, the contact interval (relative frames) and the box track (n, 3)."""
    T = float(rng.uniform(2.6, 3.1))
    t_out0, t_out1 = 0.05 * T, 0.38 * T          # giver pushes the box forward to the middle
    t_grab0, t_grab1 = 0.12 * T, 0.38 * T        # taker's hands reach the box sides
    t_hold1 = t_out1 + float(rng.uniform(0.3, 0.45))
    t_in1 = t_hold1 + 0.5                        # box to the taker's carry pose
    t_rel1 = t_hold1 + 0.4                       # giver's hands drop
    g_keys = [(0.0, act._neutral_key(carry=True)),
              (0.3, {"flex": 0.12, "pitch": 0.06, "hpitch": 0.35}),
              (t_hold1 / T, {}),
              (min((t_rel1 + 0.5) / T, 0.97), act._neutral_key()), (1.0, {})]
    r_keys = [(0.0, act._neutral_key()),
              (0.3, {"flex": 0.12, "pitch": 0.06, "hpitch": 0.35}),
              (t_hold1 / T, {}),
              (min((t_in1 + 0.3) / T, 0.97), act._neutral_key(carry=True)), (1.0, {})]
    cg, t = _keyed_group(skel, giver.state, T, g_keys, fps, carry=True)
    cr, _ = _keyed_group(skel, taker.state, T, r_keys, fps, carry=False)
    n = len(t)
    pg, pr = np.array(giver.state[:2]), np.array(taker.state[:2])
    d = (pr - pg) / np.linalg.norm(pr - pg)
    d3 = np.array([d[0], 0.0, d[1]])
    mid = 0.5 * (pg + pr)
    M = np.array([mid[0], float(rng.uniform(0.98, 1.05)), mid[1]])
    # box path: giver's carry position -> M -> taker's carry position
    wg = _carry_wrists_world(skel, cg)               # giver's carry wrists (trunk keyed)
    cr_carry = neutral_controls(n, taker.state[0], taker.state[1], taker.state[2], carry=True)
    act._apply_keys(cr_carry, act._keyed(r_keys, (n - 1) / fps, t), *taker.state)
    cr_carry.pelvis[:, 1] = cr.pelvis[:, 1]
    wr = _carry_wrists_world(skel, cr_carry)
    down = np.array([0.0, -_HOLD_DOWN, 0.0])
    box_g = wg.mean(axis=1) + down + _WRIST_ALONG * d3
    box_r = wr.mean(axis=1) + down - _WRIST_ALONG * d3
    u1 = _ramp(t, t_out0, t_out1)[:, None]
    u2 = _ramp(t, t_hold1, t_in1)[:, None]
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
    cg.hand_w[:, :] = (1.0 - _ramp(t, t_hold1, t_rel1))[:, None]
    cg.clav[:, :, 0] = CARRY_NEUTRAL["clav"] * cg.hand_w[:, :1]
    # taker: reaches, holds, brings the box in; thorax-attached carry from t_in1 on
    att_r = (t >= t_in1).astype(float)
    for s, sg in ((0, 1.0), (1, -1.0)):
        cr.hand_world[:, s] = box - down + _WRIST_ALONG * d3 + sg * half_r[i_in]
        cr.hand_attach[:, s] = att_r
    cr.hand_thorax[:] = CARRY_WRIST
    cr.hand_w[:, :] = _ramp(t, t_grab0, t_grab1)[:, None]
    cr.clav[:, :, 0] = CARRY_NEUTRAL["clav"] * _ramp(t, t_in1 - 0.3, t_in1)[:, None]
    both = (t >= t_grab1) & (t <= t_hold1)
    idx = np.flatnonzero(both)
    contact = (int(idx[0]), int(idx[-1]))
    gg = Group(cg, [(0, n - 1, labels[0])], [(0, "carry_stand")], [], giver.state)
    gr = Group(cr, [(0, n - 1, labels[1])], [(0, "stand")], [], taker.state)
    holder = np.where(t < 0.5 * (t_grab1 + t_hold1), 0, 1)
    return gg, gr, contact, box, holder


def scene_box_pass(skel, rng, fps) -> Scene:
    D = float(rng.uniform(0.8, 0.9))
    A, B, f0 = _meet(skel, rng, fps, D, carry_a=True)
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    gg, gr, (c0, c1), box, holder = _pass_pair(skel, rng, A, B, fps, f0)
    A.add(gg)
    A.carry = False
    B.add(gr)
    B.carry = True
    ev = Event("box_pass", "contact", (0, 1), f0 + c0, f0 + c1)
    _leave(skel, rng, fps, A, _away(rng, A, pb), carry=False)
    _leave(skel, rng, fps, B, _away(rng, B, pa), carry=True)
    prop = {"kind": "box", "size": list(BOX_SIZE), "pass_frames": [f0, f0 + len(box) - 1],
            "from": 0, "to": 1, "track": np.round(box, 4).tolist()}
    return _finish(skel, "box_pass", [A, B], fps, [ev], props=[prop])


def scene_relay(skel, rng, fps) -> Scene:
    """A hands a box to B; B turns to C (who has walked up) and hands it on."""
    D = float(rng.uniform(0.8, 0.9))
    A, B, f0 = _meet(skel, rng, fps, D, carry_a=True)
    C = _Person("C", (0, 0, 0))
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    gg, gr, (c0, c1), box, _ = _pass_pair(skel, rng, A, B, fps, f0)
    A.add(gg)
    A.carry = False
    B.add(gr)
    B.carry = True
    ev1 = Event("box_pass", "contact", (0, 1), f0 + c0, f0 + c1)
    # B turns by +-90 deg (towards C's side)
    sgn = float(rng.choice([-1.0, 1.0]))
    new_h = B.state[2] + sgn * np.radians(rng.uniform(80, 100))
    g_turn = turn_to(skel, rng, B.state, new_h, fps, carry=True)
    end_b = np.array(g_turn.end[:2])
    fwd = np.array([np.sin(new_h), np.cos(new_h)])
    pc = end_b + fwd * float(rng.uniform(0.8, 0.9))
    gc = run_to(skel, rng, (pc[0], pc[1], new_h + np.pi), fps, WALK, 1)
    C.state = tuple(float(v) for v in gc.controls.root_pos[0, [0, 2]]) + (float(gc.controls.heading[0]),)
    _leave(skel, rng, fps, A, _away(rng, A, pb, 20.0), carry=False)
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
    gg2, gr2, (d0, d1), box2, _ = _pass_pair(skel, rng, B, C, fps, f2)
    B.add(gg2)
    B.carry = False
    C.add(gr2)
    C.carry = True
    ev2 = Event("box_pass", "contact", (1, 2), f2 + d0, f2 + d1)
    _leave(skel, rng, fps, B, _away(rng, B, pc, 20.0), carry=False)
    _leave(skel, rng, fps, C, _away(rng, C, end_b, 20.0), carry=True)
    props = [{"kind": "box", "size": list(BOX_SIZE), "pass_frames": [f0, f0 + len(box) - 1], "from": 0, "to": 1,
              "track": np.round(box, 4).tolist()},
             {"kind": "box", "size": list(BOX_SIZE), "pass_frames": [f2, f2 + len(box2) - 1], "from": 1, "to": 2,
              "track": np.round(box2, 4).tolist()}]
    return _finish(skel, "relay", [A, B, C], fps, [ev1, ev_turn, ev2], props=props)


# ------------------------------------------------------------------------------------------
# three people bowing; a handshake with a bystander; walkers
# ------------------------------------------------------------------------------------------
def scene_bow3(skel, rng, fps) -> Scene:
    centre = rng.uniform(-1.0, 1.0, size=2)
    R = float(rng.uniform(0.85, 1.0))
    base = float(rng.uniform(-np.pi, np.pi))
    people, spots = [], []
    groups = []
    for i, name in enumerate(("A", "B", "C")):
        ang = base + i * 2 * np.pi / 3 + np.radians(rng.uniform(-8, 8))
        spot = centre + R * np.array([np.sin(ang), np.cos(ang)])
        face = _heading_to(spot, centre)
        g = run_to(skel, rng, (spot[0], spot[1], face), fps, WALK, int(rng.integers(1, 3)))
        P = _Person(name, tuple(float(v) for v in g.controls.root_pos[0, [0, 2]]) + (float(g.controls.heading[0]),))
        people.append(P)
        spots.append(spot)
        groups.append(g)
    pad = int(rng.integers(6, 20))
    meet = pad + max(g.num_frames for g in groups) + int(rng.integers(8, 20))
    for P, g in zip(people, groups):
        P.wait(meet - g.num_frames - int(rng.integers(3, 8)), fps)
        P.add(g)
        P.wait_until(meet, fps)
    leads = [0.3 + float(rng.uniform(0.0, 0.35)) for _ in people]
    T = max(leads) + 3.0
    spans = []
    for i, P in enumerate(people):
        look = spots[(i + 1) % 3] if rng.random() < 0.5 else spots[(i + 2) % 3]
        c, t, span = _bow(skel, rng, P, fps, leads[i], float(rng.uniform(0.8, 1.1)), T, look)
        spans.append(span)
        P.add(Group(c, [(0, len(t) - 1, "bow")], [(0, "stand")], [], P.state))
    s0 = meet + int(round(min(s[0] for s in spans) * fps))
    s1 = meet + int(round(max(s[1] for s in spans) * fps))
    ev = Event("bow", "sync", (0, 1, 2), s0, s1)
    for P in people:
        _leave(skel, rng, fps, P, _away(rng, P, centre, 25.0), n_walk=1)
    return _finish(skel, "bow3", people, fps, [ev])


def _walker_timeline(skel, rng, P: _Person, fps, seconds, radius=3.0):
    """Walk runs, idles and turns in place until ``seconds`` of motion; runs steer back
    towards the performer's own area (centre = first position)."""
    home = np.array(P.state[:2])
    while P.frames < seconds * fps:
        r = rng.random()
        if r < 0.55 or not P.groups:
            x, z, th = P.state
            d = home - np.array([x, z])
            if np.linalg.norm(d) > radius * 0.5:
                want = np.arctan2(d[0], d[1])
                if abs(_wrap(want - th)) > np.radians(50):
                    P.add(turn_to(skel, rng, P.state, want + np.radians(rng.uniform(-30, 30)), fps))
            P.add(run_from(skel, rng, P.state, fps, WALK, int(rng.integers(1, 3)), max_turn_deg=45.0))
        elif r < 0.8:
            P.add(act.idle(skel, rng, P.state, fps))
        else:
            P.add(turn_to(skel, rng, P.state, P.state[2] + np.radians(rng.choice([-1, 1]) * rng.uniform(60, 170)), fps))


def scene_walker(skel, rng, fps) -> Scene:
    P = _Person("A", (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-np.pi, np.pi))))
    _walker_timeline(skel, rng, P, fps, float(rng.uniform(14.0, 18.0)))
    return _finish(skel, "walker", [P], fps, [])


def scene_pair_apart(skel, rng, fps) -> Scene:
    """Two performers walking about in areas 14 m apart: no interaction at all."""
    ang = float(rng.uniform(-np.pi, np.pi))
    d = np.array([np.sin(ang), np.cos(ang)]) * 7.0
    P = _Person("A", (float(d[0]), float(d[1]), float(rng.uniform(-np.pi, np.pi))))
    Q = _Person("B", (float(-d[0]), float(-d[1]), float(rng.uniform(-np.pi, np.pi))))
    secs = float(rng.uniform(12.0, 15.0))
    _walker_timeline(skel, rng, P, fps, secs, radius=1.5)
    _walker_timeline(skel, rng, Q, fps, secs, radius=1.5)
    return _finish(skel, "pair_apart", [P, Q], fps, [])


def scene_handshake_bystander(skel, rng, fps) -> Scene:
    """A handshake while a third performer walks about at least 4 m away."""
    sc = scene_handshake(skel, rng, fps)
    F = sc.clips[0].num_frames
    pos = [c.world_root()[0][:, [0, 2]] for c in sc.clips]
    centre = 0.5 * (pos[0].mean(axis=0) + pos[1].mean(axis=0))
    ang = float(rng.uniform(-np.pi, np.pi))
    far = centre + 11.0 * np.array([np.sin(ang), np.cos(ang)])
    C = _Person("C", (float(far[0]), float(far[1]), float(rng.uniform(-np.pi, np.pi))))
    _walker_timeline(skel, rng, C, fps, F / fps, radius=1.0)
    # trim/pad C to F frames
    c_ctl, c_segs = _assemble(skel, C, fps)
    if c_ctl.num_frames < F:
        C.wait_until(F - 1, fps)
        c_ctl, c_segs = _assemble(skel, C, fps)
    c_ctl = c_ctl.slice(0, F)
    c_segs = [(a, min(b, F), lab) for a, b, lab in c_segs if a < F]
    sol = solve(skel, c_ctl)
    clip = Clip.from_world(skel, fps, sol.root_pos, sol.local)
    sc.kind = "handshake_bystander"
    sc.names = sc.names + ["C"]
    sc.clips.append(clip)
    sc.segments.append(c_segs)
    return sc


SCENES = {
    "handshake": scene_handshake,
    "high_five": scene_high_five,
    "bow": scene_bow,
    "bump": scene_bump,
    "box_pass": scene_box_pass,
    "dash_dodge": scene_dash_dodge,
    "relay": scene_relay,
    "bow3": scene_bow3,
    "handshake_bystander": scene_handshake_bystander,
    "walker": scene_walker,
    "pair_apart": scene_pair_apart,
}


def make_scene(kind: str, seed, fps: float = 30.0) -> Scene:
    """Generate one scene of ``kind`` from ``seed`` (an int or a numpy SeedSequence)."""
    if kind not in SCENES:
        raise ValueError(f"unknown scene kind {kind!r}; known: {', '.join(SCENES)}")
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(int(seed))
    rng = np.random.default_rng(ss)
    return SCENES[kind](body.make_skeleton(), rng, fps)
