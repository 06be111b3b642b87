"""Foot contact detection on synthetic trajectories and on the procedural skeleton."""
import numpy as np
import pytest

from runtime.motion.contacts import detect_contacts, planted, CONTACT_POINTS


def _step_track(F=60, fps=30.0):
    """One point: on the ground frames 0-19, lifted and moving 20-39, on the ground 40-59."""
    p = np.zeros((F, 1, 3))
    t = np.arange(20, 40)
    p[t, 0, 1] = 0.15 * np.sin(np.pi * (t - 19) / 21)
    p[t, 0, 2] = np.linspace(0, 0.7, 20)
    p[40:, 0, 2] = 0.7
    return p, fps


def test_stance_and_swing_are_told_apart():
    p, fps = _step_track()
    c = detect_contacts(p, fps)[:, 0]
    assert c[:18].all() and c[43:].all()
    assert not c[23:37].any()


def test_hysteresis_keeps_a_contact_through_a_small_bump():
    p, fps = _step_track()
    p[5:16, 0, 1] = 0.06 - 0.012 * np.abs(np.arange(5, 16) - 10)   # peaks above enter, below exit height
    assert detect_contacts(p, fps)[:18, 0].all()
    assert not detect_contacts(p, fps, exit_height=0.055)[10, 0]


def test_short_contacts_are_dropped():
    p = np.zeros((30, 1, 3))
    p[:, 0, 1] = 0.3
    p[10:12, 0, 1] = 0.0
    assert not detect_contacts(p, 30.0, floor_percentile=0.0, min_frames=3).any()


def test_planted_is_heel_or_toe():
    c = np.array([[1, 0, 0, 0], [0, 1, 0, 1], [0, 0, 0, 0]], dtype=bool)
    assert planted(c).tolist() == [[True, False], [True, True], [False, False]]
    assert len(CONTACT_POINTS) == 4


def test_leg_joints_of_the_procedural_skeleton():
    from authoring.procedural.body import make_skeleton
    from runtime.motion.contacts import leg_joints
    legs = leg_joints(make_skeleton())
    assert (legs.toe >= 0).all() and legs.hip[0] != legs.hip[1]
