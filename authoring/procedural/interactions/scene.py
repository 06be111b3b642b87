"""A multi-person scene and its assembly: events, performers' timelines to clips, hand contact.

Each performer's timeline is a list of activity groups (:class:`~..group.Group`); at the end
every timeline is padded to the common length, solved by the rig, and the clips, label
segments and ground-truth events form a :class:`Scene`. Hands that meet (handshake, high
five) drive the arms' IK with world wrist targets; :func:`hand_fixup` measures the *hand
centre* (midway between the hand joint and the index end site, :func:`hand_centres`) after
a solve and corrects the wrist targets until the hand centres reach their goals.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from runtime.motion import Clip
from runtime.motion.fk import end_site_positions, forward_kinematics

from ..group import concat_groups
from ..rig import solve

__all__ = ["GENERATOR_VERSION", "SCENE_LABELS", "Event", "Scene", "hand_centres", "assemble_timeline",
           "finish_scene", "hand_fixup"]

GENERATOR_VERSION = "1.0"
SCENE_LABELS = ("handshake", "high_five", "bow", "bump", "stagger", "box_pass", "dash", "dodge",
                "wait", "walk", "start", "stop", "idle", "turn", "carry", "receive")


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
    """A generated multi-person take: one clip per performer on a shared clock, the
    per-performer label segments, the ground-truth :class:`Event` s and the props."""
    kind: str
    names: list
    clips: list                       # one Clip per performer, same frame count and fps
    segments: list                    # per performer [(start, end_exclusive, label)]
    events: list                      # [Event]
    props: list = field(default_factory=list)
    diagnostics: dict = field(default_factory=dict)


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


def assemble_timeline(person):
    """The controls and label segments of a performer's timeline (a
    :class:`~.choreography.Performer`): its groups joined, consecutive equal labels merged."""
    c, segs, _, _ = concat_groups(person.groups)
    merged = []
    for s in segs:                                   # merge consecutive equal labels
        if merged and merged[-1][2] == s[2] and merged[-1][1] == s[0]:
            merged[-1] = (merged[-1][0], s[1], s[2])
        elif s[1] > s[0]:
            merged.append(s)
    return c, merged


def finish_scene(skel, kind, people, fps, events, props=(), fixups=()) -> Scene:
    """Pad every timeline to the same length, solve, apply hand fix-ups, build clips.

    Args:
        skel: the performers' skeleton.
        kind: the scene kind (a key of ``SCENES``).
        people: the performers (:class:`~.choreography.Performer`), in the take's order.
        fps: frame rate.
        events: the ground-truth :class:`Event` s.
        props: prop dicts written to the take.
        fixups: functions called with the list of every performer's controls before the
            final solve (hand contact corrections, added twists).
    """
    F = max(p.frames for p in people)
    for p in people:
        p.wait_until(F, fps, label="wait")
    ctl, segs = zip(*[assemble_timeline(p) for p in people])
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


def hand_fixup(skel, pairs, iterations=3):
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
