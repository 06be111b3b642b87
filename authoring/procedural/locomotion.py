"""Walk runs: the body over planned footsteps (standing -> start -> walk edges -> stop -> standing).

:func:`.gait.plan_run` lays out the footprints, the pelvis path, speed, heading and gait
phase of a run; :func:`run_controls` turns the plan into rig controls: pelvis sway, yaw and
roll oscillating with the gait phase, leaning into turns, trunk counter-rotation, arm swing
(or arms on the box when carrying), feet on their footprints, and the pelvis height from
:func:`vault_height` (the pelvis rises over the stance leg, lowest in double support).
:func:`run_group` draws a random run (turns and speed changes per edge) and returns it as a
:class:`~.group.Group`.
"""
from __future__ import annotations

import numpy as np

from . import body, gait
from .curves import gaussian, keyframes, lower_envelope, smoothstep
from .gait import foot_tracks, plan_run
from .group import Group
from .rig import Controls
from .stance import H_STAND, LEG_EXT, LEG_EXT_WALK, NEUTRAL, allowed_root_height, neutral_controls

__all__ = ["run_edges", "run_group", "run_controls", "vault_height"]


def vault_height(skel, c: Controls, ext, phi, gate=None, max_bob=None, sigma=1.0):
    """Walking pelvis height. The pelvis rises over the stance leg and is lowest in double
    support: ``h = cap - depth(phi) * w(phi)`` with ``w = ((1 + cos 2 pi (phi - k - 0.04)) / 2) ** 0.6``
    (1 just after heel strike, 0 half a step later), where each step's depth is
    the smallest that keeps both legs within reach ``ext`` over that step. Any remaining
    excess is removed by one-sided smoothing."""
    allow = allowed_root_height(skel, c, ext)
    cap = c.root_pos[:, 1].copy()
    need = cap - allow
    w = (0.5 + 0.5 * np.cos(2 * np.pi * (phi - 0.04))) ** 0.6
    k = np.floor(phi + 0.46).astype(int)              # step window [k - 0.46, k + 0.54)
    ks = np.arange(k.min(), k.max() + 1)
    depth = np.zeros(len(ks))
    sel = w > 0.2
    np.maximum.at(depth, k[sel] - ks[0], np.maximum(need[sel], 0.0) / w[sel])
    excess = np.zeros_like(depth)
    if max_bob is not None:      # deeper than a human bob: lower the whole step instead
        mb = np.interp(ks + 0.04, phi, max_bob)
        excess = np.maximum(depth - mb, 0.0)
        depth = depth - excess
    if len(ks) > 1:
        depth_f = keyframes(ks + 0.04, depth, phi)
        excess_f = keyframes(ks + 0.04, excess, phi)
    else:
        depth_f, excess_f = np.full_like(phi, depth[0]), np.full_like(phi, excess[0])
    g = 1.0 if gate is None else gate
    h = cap - (np.maximum(depth_f, 0.0) * w + np.maximum(excess_f, 0.0)) * g
    corr = np.minimum(allow - h, 0.0)
    c.root_pos[:, 1] = h + lower_envelope(corr, sigma)


def run_edges(rng, style, n_edges, steer):
    """Random edge list for a run: start, ``n_edges`` walk edges, stop.

    Args:
        rng: the ``numpy.random.Generator`` every choice is drawn from.
        style: the :class:`~.gait.GaitStyle` (hub speed and speed range).
        n_edges: number of walk edges between start and stop.
        steer: called once per walk edge; returns a heading change (rad) added to the
            edge's random turn (to steer back towards the capture volume's centre).
    """
    edges = [("start", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-25, 25))))]
    for _ in range(n_edges):
        n = int(rng.integers(2, 8))
        f_hub = float(gait.cadence(style.v_hub, style))
        width_s = (n - 2 * gait.HUB_MARGIN) / f_hub               # seconds of the turning window
        max_turn = np.radians(90.0) * width_s / 2.0               # peak rate 90 deg/s (sin^2 profile)
        max_turn = min(max_turn, np.radians(120.0))
        turn = rng.choice([-1.0, 1.0]) * np.sqrt(rng.uniform(0.0, 1.0)) * max_turn   # favour big turns
        turn = float(np.clip(turn + steer(), -max_turn, max_turn))
        # speed change: keep |dv/dt| <= ~1.3 m/s^2 for the sin^2 bump
        max_dv = 1.3 * width_s / np.pi
        lo = max(style.v_min - style.v_hub, -max_dv)
        hi = min(style.v_max - style.v_hub, max_dv)
        dv = float((lo if rng.random() < 0.5 else hi) * np.sqrt(rng.uniform(0.0, 1.0)))   # favour extremes
        if rng.random() < 0.15:
            dv = 0.0
        edges.append(("walk", n, turn, dv))
    edges.append(("stop", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-20, 20)))))
    return edges


def run_group(skel, rng, state, fps, style, n_edges, steer) -> Group:
    """A random walk run from standing at ``state`` = (x, z, heading) (see :func:`run_edges`)."""
    x0, z0, th0 = state
    edges = run_edges(rng, style, n_edges, steer)
    first = int(rng.integers(0, 2))
    plan = plan_run(style, edges, x0, z0, th0, first, fps)
    c = run_controls(plan, skel)
    return Group(c, plan.segments, plan.hubs, [], plan.end_state)


def run_controls(plan, skel) -> Controls:
    """Rig controls (``len(plan.times)`` frames) of a planned run (:class:`~.gait.RunPlan`)."""
    style = plan.style
    carry = style.label == "carry"
    N = len(plan.times)
    x0, z0 = plan.path[0]
    c = neutral_controls(N, x0, z0, plan.heading[0], carry=carry)
    a = plan.amp
    v = plan.speed
    phi = plan.phi
    th = plan.heading
    sA = 1.0 if plan.first_side == 0 else -1.0
    # leaning into turns: centripetal acceleration v * omega, partly compensated
    lean = -np.arctan(0.6 * v * plan.turn_rate / 9.81)
    lean = gaussian(lean, 2.0)
    osc_sway = np.cos(np.pi * (phi - 1.6))
    sway = sA * 0.022 * a * osc_sway
    lateral = sway - 0.35 * np.sin(lean)             # pelvis shifts towards the inside of a turn
    c.heading[:] = th
    c.root_pos[:, 0] = plan.path[:, 0] + np.cos(th) * lateral
    c.root_pos[:, 2] = plan.path[:, 1] - np.sin(th) * lateral
    c.root_pos[:, 1] = H_STAND - a * (0.003 + 0.003 * v)
    yaw_osc = -sA * np.radians(1.5 + 2.0 * v) * a * np.cos(np.pi * (phi - 1.0))
    roll_osc = sA * np.radians(1.0 + 1.6 * v) * a * np.cos(np.pi * (phi - 1.45))
    acc = gaussian(plan.accel, 3.0)
    c.pelvis[:, 0] = yaw_osc
    c.pelvis[:, 1] += a * np.radians(1.0 + 2.0 * v) + 0.02 * acc
    c.pelvis[:, 2] = roll_osc + 0.5 * lean
    c.spine[:, 0] += a * np.radians(1.0 * v) + 0.015 * acc
    c.spine[:, 1] = 0.8 * roll_osc + 0.2 * lean      # keep the thorax nearly level
    c.spine[:, 2] = -1.6 * yaw_osc                   # thorax counter-rotation
    c.head[:, 0] += a * np.radians(3.0)
    c.head[:, 1] = np.clip(0.45 * plan.look, -0.6, 0.6) * a
    if not carry:
        amp_arm = np.radians(4.0 + 8.0 * v) * a
        for s in (0, 1):
            sgn = 1.0 if s == plan.first_side else -1.0
            sw = sgn * amp_arm * np.cos(np.pi * (phi - 0.1))
            c.arm[:, s, 0] = NEUTRAL["swing"] + a * np.radians(2.0) + sw
            c.arm[:, s, 2] = NEUTRAL["elbow"] + a * np.radians(5.0) + 0.45 * np.maximum(sw, 0.0)
            c.arm[:, s, 1] = NEUTRAL["abd"] + a * np.radians(2.0)
    ankle, fq, toe, swing, roll = foot_tracks(plan.prints, plan.times)
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    ext = (LEG_EXT + (LEG_EXT_WALK - LEG_EXT) * a)[:, None] * (1.0 - 0.02 * roll ** 2)
    ext = np.where(swing, 0.999 * body.leg_length(), ext)     # swing leg may straighten fully
    vault_height(skel, c, ext, plan.phi, gate=smoothstep(a / 0.1), max_bob=0.03 + 0.012 * v)
    return c
