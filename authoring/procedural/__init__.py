"""Procedural motion capture: the product's default motion data.

Generates long BVH takes of one performer on the 31-joint CMU MotionBuilder-family skeleton
(walking with turns and speed changes, starts and stops, idling, turning in place, sitting
on a chair, picking up / carrying / putting down a box) together with per-frame labels, as
a capture session would. Footsteps are planned first and the legs are solved with analytic
IK to them (:mod:`.gait`, :mod:`.rig`); activities start and end in shared hub poses so a
snap-together motion graph can be built from the takes (:mod:`.activities`,
:mod:`.session`). Two- and three-person takes on one clock come from :mod:`.interactions`.
"""
from .body import make_skeleton
from .session import GENERATOR_VERSION, LABELS, GeneratedTake, generate_session, write_session

__all__ = ["make_skeleton", "GENERATOR_VERSION", "LABELS", "GeneratedTake", "generate_session", "write_session"]
