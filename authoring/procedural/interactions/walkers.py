"""Scenes without an interaction: a lone walker, two performers far apart, a bystander.

They give the episode detector takes where nothing should be found: walk runs, idles and
turns in place that keep each performer in its own area, far from the others.
"""
from __future__ import annotations

import numpy as np

from runtime.motion import Clip
from runtime.motion.planar import wrap_angle

from ..activities import idle
from ..gait import WALK
from ..rig import solve
from .choreography import Performer, run_from, turn_to
from .greetings import scene_handshake
from .scene import Scene, assemble_timeline, finish_scene

__all__ = ["scene_walker", "scene_pair_apart", "scene_handshake_bystander"]


def _walker_timeline(skel, rng, P: Performer, fps, seconds, radius=3.0):
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
                if abs(wrap_angle(want - th)) > np.radians(50):
                    P.add(turn_to(skel, rng, P.state, want + np.radians(rng.uniform(-30, 30)), fps))
            P.add(run_from(skel, rng, P.state, fps, WALK, int(rng.integers(1, 3)), max_turn_deg=45.0))
        elif r < 0.8:
            P.add(idle(skel, rng, P.state, fps))
        else:
            P.add(turn_to(skel, rng, P.state, P.state[2] + np.radians(rng.choice([-1, 1]) * rng.uniform(60, 170)), fps))


def scene_walker(skel, rng, fps) -> Scene:
    """One performer walking about alone for 14-18 s."""
    P = Performer("A", (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-np.pi, np.pi))))
    _walker_timeline(skel, rng, P, fps, float(rng.uniform(14.0, 18.0)))
    return finish_scene(skel, "walker", [P], fps, [])


def scene_pair_apart(skel, rng, fps) -> Scene:
    """Two performers walking about in areas 14 m apart: no interaction at all."""
    ang = float(rng.uniform(-np.pi, np.pi))
    d = np.array([np.sin(ang), np.cos(ang)]) * 7.0
    P = Performer("A", (float(d[0]), float(d[1]), float(rng.uniform(-np.pi, np.pi))))
    Q = Performer("B", (float(-d[0]), float(-d[1]), float(rng.uniform(-np.pi, np.pi))))
    secs = float(rng.uniform(12.0, 15.0))
    _walker_timeline(skel, rng, P, fps, secs, radius=1.5)
    _walker_timeline(skel, rng, Q, fps, secs, radius=1.5)
    return finish_scene(skel, "pair_apart", [P, Q], fps, [])


def scene_handshake_bystander(skel, rng, fps) -> Scene:
    """A handshake while a third performer walks about at least 4 m away."""
    sc = scene_handshake(skel, rng, fps)
    F = sc.clips[0].num_frames
    pos = [c.world_root()[0][:, [0, 2]] for c in sc.clips]
    centre = 0.5 * (pos[0].mean(axis=0) + pos[1].mean(axis=0))
    ang = float(rng.uniform(-np.pi, np.pi))
    far = centre + 11.0 * np.array([np.sin(ang), np.cos(ang)])
    C = Performer("C", (float(far[0]), float(far[1]), float(rng.uniform(-np.pi, np.pi))))
    _walker_timeline(skel, rng, C, fps, F / fps, radius=1.0)
    # trim/pad C to F frames
    c_ctl, c_segs = assemble_timeline(C)
    if c_ctl.num_frames < F:
        C.wait_until(F - 1, fps)
        c_ctl, c_segs = assemble_timeline(C)
    c_ctl = c_ctl.slice(0, F)
    c_segs = [(a, min(b, F), lab) for a, b, lab in c_segs if a < F]
    sol = solve(skel, c_ctl)
    clip = Clip.from_world(skel, fps, sol.root_pos, sol.local)
    sc.kind = "handshake_bystander"
    sc.names = sc.names + ["C"]
    sc.clips.append(clip)
    sc.segments.append(c_segs)
    return sc
