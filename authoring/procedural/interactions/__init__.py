"""Procedural multi-character capture: two- and three-person takes on one shared clock.

Builds on the single-performer generator (:mod:`..activities`, :mod:`..gait`, :mod:`..rig`):
every performer is a sequence of activity :class:`~..group.Group` s (standing holds, walk
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

Modules: :mod:`.scene` (events, scenes, assembly, hand contact), :mod:`.choreography`
(timelines, walking to places, meeting, leaving), and one per family of scenes:
:mod:`.greetings`, :mod:`.reactions`, :mod:`.handover`, :mod:`.walkers`.
"""
from __future__ import annotations

import numpy as np

from .. import body
from .greetings import scene_bow, scene_bow3, scene_handshake, scene_high_five
from .handover import scene_box_pass, scene_relay
from .reactions import DASH, scene_bump, scene_dash_dodge
from .scene import GENERATOR_VERSION, SCENE_LABELS, Event, Scene, hand_centres
from .walkers import scene_handshake_bystander, scene_pair_apart, scene_walker

__all__ = ["GENERATOR_VERSION", "Scene", "Event", "SCENES", "SCENE_LABELS", "DASH", "make_scene", "hand_centres"]

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
