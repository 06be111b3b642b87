"""Planted-foot slide, measured from what was written: the joints of a baked USD stage.

The measure an animator applies to a crowd, independent of the synthesizer and of the foot
contacts it used (:mod:`runtime.motion.contacts` is not consulted): a foot is *planted* on a
frame when its toe joint is within :data:`PLANT_HEIGHT` of that foot's lowest point over the
bake and its vertical speed is under :data:`PLANT_VSPEED`; the figures are the horizontal
speeds of planted feet, pooled over every foot of every character: the mean, the 95th
percentile, and the share of planted frames sliding faster than :data:`SLIDE_SPEED`. The speed
of a frame is its displacement from the previous frame times the frame rate (the first frame of
a character has none and is not counted). Alongside: the lowest foot point (toe and ankle joints) and
the knee flexion range (angle between thigh and shin; below zero would be hyperextension, which
the angle cannot show, so the straightest and the most bent are reported).

Joint positions are read through ``pxr.UsdSkel`` (skeleton-space joint transforms of every
time sample, placed by the Skeleton prim's world transform); the toe joint of each side is found
by name (``Left``/``Right`` or ``l``/``r`` with ``Toe``; the foot joint on skeletons without
toes), the knee and hip as its ancestors. ``pxr`` is imported only when a stage is read.
"""
from __future__ import annotations

import re

import numpy as np

__all__ = ["PLANT_HEIGHT", "PLANT_VSPEED", "SLIDE_SPEED", "LIMITS", "ENFORCED", "planted_slide", "slide_summary",
           "stage_feet", "measure_stage", "feet_report", "slide_passed", "slide_line"]

PLANT_HEIGHT = 0.05      # m above the foot's lowest point
PLANT_VSPEED = 0.15      # m/s vertical
SLIDE_SPEED = 0.10       # m/s: a planted frame faster than this is sliding
LIMITS = {"mean_cm_s": 3.0, "p95_cm_s": 10.0, "sliding_share": 0.03}
# Whether a bake over the limits fails. Off while characters waiting between goals play their
# walking loop in place (their feet cannot be planted); the figures are printed either way.
ENFORCED = False


def planted_slide(toe: np.ndarray, fps: float):
    """Planted flags and horizontal speeds (both (F, P); frame 0 never planted) of toe
    trajectories ``toe`` (F, P, 3)."""
    p = np.asarray(toe, dtype=np.float64)
    v = np.zeros_like(p)
    if p.shape[0] < 2:
        return np.zeros(p.shape[:2], bool), np.zeros(p.shape[:2])
    v[1:] = np.diff(p, axis=0) * fps
    low = p[..., 1].min(axis=0)
    plant = (p[..., 1] - low < PLANT_HEIGHT) & (np.abs(v[..., 1]) < PLANT_VSPEED)
    plant[0] = False
    return plant, np.hypot(v[..., 0], v[..., 2])


def slide_summary(speeds: np.ndarray) -> dict:
    """Figures of the horizontal speeds of planted frames (m/s, any shape)."""
    s = np.asarray(speeds, dtype=np.float64).reshape(-1)
    if not len(s):
        return {"planted_frames": 0, "mean_cm_s": 0.0, "p95_cm_s": 0.0, "sliding_share": 0.0}
    return {"planted_frames": int(len(s)), "mean_cm_s": float(s.mean() * 100),
            "p95_cm_s": float(np.percentile(s, 95) * 100), "sliding_share": float(np.mean(s > SLIDE_SPEED))}


def _side_joints(names):
    """(toe, ankle, knee, hip) indices of the left and right legs from joint names and paths."""
    base = [n.rsplit("/", 1)[-1] for n in names]
    parent = []
    index = {n: i for i, n in enumerate(names)}
    for n in names:
        parent.append(index.get(n.rsplit("/", 1)[0], -1) if "/" in n else -1)
    out = []
    for side in ("l", "r"):
        pat = re.compile(rf"^({'left' if side == 'l' else 'right'}|{side})_?", re.I)
        cands = [i for i, b in enumerate(base) if pat.match(b) and "toe" in b.lower()]
        if not cands:
            cands = [i for i, b in enumerate(base) if pat.match(b) and ("foot" in b.lower() or "ankle" in b.lower())]
        if not cands:
            return None
        toe = min(cands)
        chain = [toe]
        for _ in range(3):
            chain.append(parent[chain[-1]] if chain[-1] >= 0 else -1)
        if min(chain) < 0:
            return None
        out.append(chain)
    return np.array(out)     # (2, 4): toe, ankle, knee, hip


def stage_feet(path, roots=None) -> dict:
    """Per skeleton prim of a stage (only those under the SkelRoot paths ``roots`` when given):
    ``{prim path: (first time code, toe (F, 2, 3), ankle (F, 2, 3), knee flexion (F, 2)
    radians)}`` over its joint-transform time samples."""
    from pxr import Usd, UsdGeom, UsdSkel
    stage = Usd.Stage.Open(str(path))
    cache = UsdSkel.Cache()
    xf = UsdGeom.XformCache()
    out = {}
    keep = None if roots is None else {str(r) for r in roots}
    for prim in stage.Traverse():
        if not prim.IsA(UsdSkel.Root) or (keep is not None and str(prim.GetPath()) not in keep):
            continue
        cache.Populate(UsdSkel.Root(prim), Usd.PrimDefaultPredicate)
    for prim in stage.Traverse():
        if not prim.IsA(UsdSkel.Skeleton):
            continue
        if keep is not None and not any(str(a) in keep for a in prim.GetPath().GetAncestorsRange()):
            continue
        q = cache.GetSkelQuery(UsdSkel.Skeleton(prim))
        if not q:
            continue
        chains = _side_joints([str(j) for j in q.GetJointOrder()])
        anim = q.GetAnimQuery()
        if chains is None or not anim:
            continue
        times = anim.GetJointTransformTimeSamples()
        if not times:
            continue
        world = np.array(xf.GetLocalToWorldTransform(prim), dtype=np.float64)
        rows = np.empty((len(times), 2, 4, 4))          # the joints' translation rows (row vectors)
        for k, t in enumerate(times):
            rows[k] = np.asarray(q.ComputeJointSkelTransforms(Usd.TimeCode(t)))[chains, 3]
        rows[..., 3] = 1.0
        pos = (rows @ world)[..., :3]
        thigh = pos[:, :, 2] - pos[:, :, 3]
        shin = pos[:, :, 1] - pos[:, :, 2]
        c = np.sum(thigh * shin, -1) / np.maximum(np.linalg.norm(thigh, axis=-1) * np.linalg.norm(shin, axis=-1), 1e-12)
        out[str(prim.GetPath())] = (float(times[0]), pos[:, :, 0], pos[:, :, 1], np.arccos(np.clip(c, -1, 1)))
    return out


def measure_stage(path, roots=None, fps: float | None = None) -> dict:
    """The planted-foot figures of every skeleton in a stage (only those under the SkelRoot
    paths ``roots`` when given): :func:`slide_summary` pooled over all feet, the lowest foot
    point (m), the knee flexion range (degrees) and the worst character by mean slide."""
    if fps is None:
        from pxr import Usd
        fps = float(Usd.Stage.Open(str(path)).GetTimeCodesPerSecond())
    feet = stage_feet(path, roots)
    speeds, lowest, flex, worst = [], np.inf, [], (None, 0.0)
    for name, (_, toe, ankle, knee) in feet.items():
        plant, v = planted_slide(toe, fps)
        speeds.append(v[plant])
        lowest = min(lowest, float(toe[..., 1].min()), float(ankle[..., 1].min()))
        flex.append(knee.reshape(-1))
        if plant.any() and v[plant].mean() * 100 > worst[1]:
            worst = (name, float(v[plant].mean() * 100))
    out = slide_summary(np.concatenate(speeds) if speeds else np.zeros(0))
    f = np.degrees(np.concatenate(flex)) if flex else np.zeros(0)
    out.update({"characters": len(speeds), "lowest_foot_m": float(lowest) if speeds else 0.0,
                "knee_flexion_deg": [float(f.min()), float(f.max())] if len(f) else [0.0, 0.0],
                "worst_character": worst[0], "worst_mean_cm_s": worst[1]})
    return out


def feet_report(path, roots=None) -> dict:
    """:func:`measure_stage` plus ``within_limits`` (:func:`slide_passed`), the ``limits`` and
    whether they decide a bake (``enforced``: :data:`ENFORCED`)."""
    f = measure_stage(path, roots)
    f.update({"within_limits": slide_passed(f), "limits": dict(LIMITS), "enforced": ENFORCED})
    return f


def slide_passed(figures: dict) -> bool:
    """Whether the figures are within :data:`LIMITS`."""
    return (figures["mean_cm_s"] <= LIMITS["mean_cm_s"] and figures["p95_cm_s"] <= LIMITS["p95_cm_s"]
            and figures["sliding_share"] <= LIMITS["sliding_share"])


def slide_line(figures: dict) -> str:
    """One line for a bake's printout."""
    return (f"planted feet: mean {figures['mean_cm_s']:.1f} cm/s, p95 {figures['p95_cm_s']:.1f} cm/s, "
            f"{figures['sliding_share'] * 100:.1f}% sliding > {SLIDE_SPEED * 100:.0f} cm/s "
            f"({figures['planted_frames']} planted frames; limits {LIMITS['mean_cm_s']:.0f} / "
            f"{LIMITS['p95_cm_s']:.0f} cm/s, {LIMITS['sliding_share'] * 100:.0f}%); lowest foot "
            f"{figures['lowest_foot_m'] * 100:.1f} cm, knee flexion {figures['knee_flexion_deg'][0]:.1f}-"
            f"{figures['knee_flexion_deg'][1]:.1f} deg")
