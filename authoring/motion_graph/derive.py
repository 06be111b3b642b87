"""Frame labels derived from the motion itself, for capture without label sidecars (BVH).

A graph built for goal-directed crowds needs to know, per frame, whether the character
stands, turns on the spot or walks (node labels "stand" and "walk", :mod:`.labels`), and
which frames are not flat-ground walking at all and must stay out of the graph. Everything
is measured from forward-kinematics joint positions at the graph's frame rate:

* **Root motion.** Planar root speed and heading rate, averaged over ``smooth`` seconds
  (a gait cycle's sway averages out); the direction of travel relative to the facing.
* **Foot contacts.** A foot is on the ground while its ankle or ball moves slower than
  ``contact_speed``, or stays within ``contact_height`` of its lowest height nearby without
  swinging; the ground level under a slow foot is the height of its lower joint.

Labels kept for the graph: ``idle`` (root slower than ``stand_speed``, turning slower than
``turn_rate``), ``turn`` (turning on the spot), ``walk``, and ``run`` (faster than
``run_speed`` with a flight phase). Labels left out, each with the reason the build report
gives (:data:`DROPPED`): ``jump`` (hops: both feet off the ground without running), ``low``
(the root less than ``low_ratio`` rest-pose leg lengths above the feet: crouching, sitting),
``backward`` and ``sideways`` (stepping with the root travelling more than ``backward_angle``
/ ``sideways_angle`` away from the facing), ``uneven`` (consecutive foot contacts more than
``level_step`` apart in height: stepping up or down).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runtime.motion import Clip, quat
from runtime.motion.fk import forward_kinematics

__all__ = ["DeriveParams", "derive_labels", "motion_features", "usable_runs", "runs", "DROPPED"]

# labels left out of the graph -> the reason the build report gives
DROPPED = {
    "jump": "not walking-like: hops or jumps (both feet off the ground)",
    "backward": "not walking-like: walks backward",
    "sideways": "not walking-like: steps sideways",
    "uneven": "uneven ground: steps up or down",
    "low": "not walking-like: crouching or sitting (root low over the feet)",
}


@dataclass
class DeriveParams:
    """Thresholds of :func:`derive_labels` (metres, seconds, degrees)."""
    smooth: float = 0.4               # s over which root speed and heading rate are averaged
    contact_speed: float = 0.4        # m/s: a foot joint slower than this is on the ground ...
    contact_height: float = 0.04      # m: ... and so is one this close to its lowest height within
    floor_window: float = 1.0         #    +-floor_window s moving slower than ``skim_speed``
    skim_speed: float = 1.2           #    (a heel strike slides a little in real capture)
    min_contact: float = 0.1          # s: shorter contacts do not give a ground height
    stand_speed: float = 0.25         # m/s: slower root is standing ...
    turn_rate: float = 25.0           # deg/s: ... unless it turns faster: a turn on the spot ...
    turn_speed: float = 0.6           # m/s: ... while the root moves slower than this (it sways)
    run_speed: float = 2.2            # m/s: faster with flight phases is running
    min_flight: float = 0.07          # s: shorter flights are contact noise
    jump_margin: float = 0.3          # s around a hop (crouch, landing) left out with it
    travel_speed: float = 0.3         # m/s: below this (or turning on the spot) the direction of
    #                                   travel is not judged
    sideways_angle: float = 55.0      # deg between travel and facing: sideways beyond this ...
    backward_angle: float = 115.0     # ... and backward beyond this
    direction_margin: float = 0.2     # s around backward / sideways travel left out with it
    level_step: float = 0.05          # m: consecutive contacts further apart in height are a step up/down
    low_ratio: float = 0.8            # root closer to the feet than this x the rest-pose leg is
    #                                   crouching or sitting


def _box(x: np.ndarray, half: int) -> np.ndarray:
    """Moving average over 2 * half + 1 frames (edges use the frames that exist)."""
    if half <= 0:
        return x.astype(np.float64)
    c = np.concatenate([[0.0], np.cumsum(x, dtype=np.float64)])
    n = len(x)
    lo = np.clip(np.arange(n) - half, 0, n)
    hi = np.clip(np.arange(n) + half + 1, 0, n)
    return (c[hi] - c[lo]) / (hi - lo)


def _dilate(mask: np.ndarray, r: int) -> np.ndarray:
    if r <= 0 or not mask.any():
        return mask.copy()
    return _box(mask.astype(np.float64), r) > 0


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, end exclusive) of every run of True."""
    m = np.concatenate([[0], mask.astype(np.int8), [0]])
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def _side(name: str) -> int | None:
    """0 for a left joint, 1 for a right one (``Left*``, ``L*``, ``l*`` + capital), else None."""
    low = name.lower()
    for k, word in enumerate(("left", "right")):
        if low.startswith(word) or (name[:1].lower() == word[0] and name[1:2].isupper()):
            return k
    return None


def _foot_joints(names) -> list[list[int]]:
    """Per side, the joints of the foot (ankle, ball, toe) by name."""
    out = [[], []]
    for j, n in enumerate(names):
        side = _side(n)
        if side is not None and any(w in n.lower() for w in ("foot", "toe", "ankle")):
            out[side].append(j)
    for side, js in zip(("left", "right"), out):
        if not js:
            raise ValueError(f"the skeleton has no {side} foot joint (a name with Foot, Toe or Ankle)")
    return out


def motion_features(clip: Clip, p: DeriveParams) -> dict:
    """Per frame (at least two): ``speed`` (m/s) and ``turn`` (deg/s) of the root, averaged; ``travel``
    (deg, direction of travel minus facing); ``contact`` (F, 2) per foot (slow, or low and
    not swinging); ``stance`` (F, 2) per foot (slow) and ``level`` (F, 2) the ground height
    under it (NaN off the ground); ``above_feet`` the root's height over the lowest foot
    joint in rest-pose leg lengths."""
    fps = clip.fps
    F = clip.num_frames
    pos, _ = clip.world_root()
    xz = pos[:, [0, 2]]
    v = np.gradient(xz, axis=0) * fps
    half = int(round(0.5 * p.smooth * fps))
    vs = np.stack([_box(v[:, 0], half), _box(v[:, 1], half)], axis=1)
    speed = np.hypot(vs[:, 0], vs[:, 1])
    h = clip.world_heading()
    turn = _box(np.degrees(np.gradient(h)) * fps, half)
    travel = (np.degrees(np.arctan2(vs[:, 0], vs[:, 1]) - h) + 180.0) % 360.0 - 180.0
    gp = clip.positions()
    r = max(int(round(p.floor_window * fps)), 1)
    contact = np.zeros((F, 2), dtype=bool)
    stance = np.zeros((F, 2), dtype=bool)
    level = np.full((F, 2), np.nan)
    legs = _foot_joints(list(clip.skeleton.names))
    for s, js in enumerate(legs):
        q = gp[:, js]                                            # (F, k, 3)
        sp = np.linalg.norm(np.gradient(q, axis=0), axis=-1) * fps
        y = q[..., 1]
        pad = np.concatenate([np.repeat(y[:1], r, axis=0), y, np.repeat(y[-1:], r, axis=0)], axis=0)
        floor = np.lib.stride_tricks.sliding_window_view(pad, 2 * r + 1, axis=0).min(axis=-1)
        slow = sp < p.contact_speed
        low = (y < floor + p.contact_height) & (sp < p.skim_speed)
        contact[:, s] = (slow | low).any(axis=1)
        stance[:, s] = slow.any(axis=1)
        level[:, s] = np.where(stance[:, s], np.where(slow, y, np.inf).min(axis=1), np.nan)
    feet = [j for js in legs for j in js]
    rest = forward_kinematics(clip.skeleton, np.zeros(3), np.tile(quat.identity(), (clip.skeleton.num_joints, 1)))[1]
    leg = float(-rest[feet, 1].min())
    above = pos[:, 1] - gp[:, feet, 1].min(axis=1)
    return {"speed": speed, "turn": turn, "travel": travel, "contact": contact, "stance": stance, "level": level,
            "above_feet": above / max(leg, 1e-6)}


def _level_steps(stance: np.ndarray, level: np.ndarray, step: float, min_frames: int) -> np.ndarray:
    """Frames from the start of a foot contact to the end of the next one (either foot)
    when their ground heights differ by more than ``step``."""
    F = len(stance)
    events = []                                                # (start, end, median level)
    for s in range(stance.shape[1]):
        for a, b in runs(stance[:, s]):
            if b - a >= min_frames:
                events.append((a, b, float(np.median(level[a:b, s]))))
    events.sort()
    bad = np.zeros(F, dtype=bool)
    for (a0, b0, l0), (a1, b1, l1) in zip(events, events[1:]):
        if abs(l1 - l0) > step:
            bad[a0:b1] = True
    return bad


def derive_labels(clip: Clip, params: DeriveParams | None = None) -> list[str]:
    """One label per frame of ``clip`` (see the module docstring); a clip of fewer than two
    frames does not move: ``idle``."""
    p = params or DeriveParams()
    fps = clip.fps
    F = clip.num_frames
    if F < 2:
        return ["idle"] * F
    f = motion_features(clip, p)
    speed, turn, travel = f["speed"], f["turn"], f["travel"]
    lab = np.full(F, "walk", dtype=object)
    spin = np.abs(turn) >= p.turn_rate
    lab[(speed < p.stand_speed) & ~spin] = "idle"
    on_spot = spin & (speed < p.turn_speed)
    lab[on_spot] = "turn"
    flight = ~f["contact"].any(axis=1)
    fl = np.zeros(F, dtype=bool)
    for a, b in runs(flight):
        if (b - a) / fps >= p.min_flight:
            fl[a:b] = True
    running = fl & (speed >= p.run_speed)
    hop = fl & ~running
    lab[_dilate(running, int(round(0.5 * fps)))] = "run"       # the strides around the flights
    # travel counts only while stepping (a foot off the ground nearby): bending over or sitting
    # down moves the root back with both feet planted
    lifted = ~f["stance"].all(axis=1)
    stepping = _dilate(lifted, int(round(p.direction_margin * fps)))
    moving = (speed >= p.travel_speed) & ~on_spot & stepping
    side = moving & (np.abs(travel) > p.sideways_angle)
    back = moving & (np.abs(travel) > p.backward_angle)
    r = int(round(p.direction_margin * fps))
    lab[_dilate(side, r)] = "sideways"
    lab[_dilate(back, r)] = "backward"
    lab[_dilate(hop, int(round(p.jump_margin * fps)))] = "jump"
    lab[f["above_feet"] < p.low_ratio] = "low"
    lab[_level_steps(f["stance"], f["level"], p.level_step, max(1, int(round(p.min_contact * fps))))] = "uneven"
    return lab.tolist()


def usable_runs(labels) -> list[tuple[int, int]]:
    """(start, end exclusive) of the runs of frames whose labels are kept for the graph."""
    keep = np.array([lab not in DROPPED for lab in labels], dtype=bool)
    return runs(keep)
