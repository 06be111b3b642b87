"""Keyframed body poses: a few key poses in the body frame, interpolated per frame.

A key is a dict of :data:`CHANNELS` (pelvis offset ``px, py, pz`` in the standing body frame,
pelvis ``yaw, pitch, roll``, spine ``flex, lat, twist``, head ``hpitch, hyaw``, arm ``swing``,
``abd``, ``elbow`` and clavicle ``clav`` per side). :func:`keyed` interpolates a list of keys
with the monotone spline of :func:`.curves.keyframes` (no overshoot: a pelvis moving down
onto a seat never dips below it); :func:`apply_keys` writes the result into rig controls.
The feet are not keyed: they stay on their footprints and the leg IK follows the pelvis.
"""
from __future__ import annotations

import numpy as np

from .curves import keyframes
from .rig import Controls
from .stance import CARRY_NEUTRAL, H_STAND, NEUTRAL, body_to_world

__all__ = ["CHANNELS", "neutral_key", "keyed", "apply_keys", "frame_times"]

CHANNELS = ("px", "py", "pz", "yaw", "pitch", "roll", "flex", "lat", "twist", "hpitch", "hyaw",
            "swingL", "swingR", "abdL", "abdR", "elbowL", "elbowR", "clavL", "clavR")


def neutral_key(carry=False) -> dict:
    """The key of the standing hub pose (of standing with a box when ``carry``)."""
    k = {"px": 0.0, "py": H_STAND, "pz": 0.0, "yaw": 0.0, "pitch": NEUTRAL["pitch"], "roll": 0.0,
         "flex": NEUTRAL["flex"], "lat": 0.0, "twist": 0.0, "hpitch": NEUTRAL["hpitch"], "hyaw": 0.0,
         "swingL": NEUTRAL["swing"], "swingR": NEUTRAL["swing"], "abdL": NEUTRAL["abd"],
         "abdR": NEUTRAL["abd"], "elbowL": NEUTRAL["elbow"], "elbowR": NEUTRAL["elbow"],
         "clavL": 0.0, "clavR": 0.0}
    if carry:
        k.update(pitch=CARRY_NEUTRAL["pitch"], flex=CARRY_NEUTRAL["flex"],
                 hpitch=CARRY_NEUTRAL["hpitch"], clavL=CARRY_NEUTRAL["clav"], clavR=CARRY_NEUTRAL["clav"])
    return k


def keyed(keys, T, times) -> dict:
    """Per-frame channel values from keys.

    Args:
        keys: ``[(fraction of T, {channel: value})]``; a channel missing from a key repeats
            its value in the previous key (so the first key must set every channel).
        T: seconds the fractions refer to.
        times: seconds of the frames to evaluate.
    Returns:
        ``{channel: (len(times),) array}``.
    """
    ts = [f * T for f, _ in keys]
    rows = []
    cur = {}
    for _, d in keys:
        cur = {**cur, **d}
        rows.append([cur[ch] for ch in CHANNELS])
    vals = keyframes(np.array(ts), np.array(rows), times)
    return {ch: vals[:, i] for i, ch in enumerate(CHANNELS)}


def apply_keys(c: Controls, k, x0, z0, th0):
    """Write keyed channels ``k`` (from :func:`keyed`) into ``c`` for a performer standing
    at ``(x0, z0)`` with heading ``th0``: the pelvis offset goes through the body frame."""
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


def frame_times(T, fps):
    """``(N, times)`` for an action of about ``T`` seconds: ``N`` whole frames (at least 2)
    and the ``N + 1`` frame times ``0, 1/fps, ..., N/fps`` (both ends included)."""
    n = max(int(round(T * fps)), 2)
    return n, np.arange(n + 1) / fps
