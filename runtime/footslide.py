"""Planted-foot slide, measured from what was written: the joints of a baked USD stage.

The measure an animator applies to a crowd, independent of the synthesizer and of the foot
contacts it used (:mod:`runtime.motion.contacts` is not consulted): a foot is *planted* on a
frame when its toe joint is within :data:`PLANT_HEIGHT` of that foot's lowest point over the
bake and its vertical speed is under :data:`PLANT_VSPEED`; the figures are the horizontal
speeds of planted feet, pooled over every foot of every character: the mean, the 95th
percentile, and the share of planted frames sliding faster than :data:`SLIDE_SPEED`. The speed
of a frame is its displacement from the previous frame times the frame rate (the first frame of
a character has none and is not counted). Alongside: the lowest foot point (toe and ankle joints) and
the knee flexion range: the angle between thigh and shin, signed by the side the knee is on --
in front of the hip-ankle line (towards where the foot points) is flexion, behind it is
hyperextension and counts negative.

:func:`slide_passed` holds the figures to :data:`LIMITS`: the slide, no foot more than 1 cm
below the ground, no hyperextension, and, when the capture's knee range is known (a library
build keeps it in ``meta["knee_flexion_deg"]``), no knee outside it by more than
:data:`KNEE_TOLERANCE`.

Joint positions are read through ``pxr.UsdSkel`` (skeleton-space joint transforms of every
time sample, placed by the Skeleton prim's world transform at that time); the toe joint of each side is found
by name (``Left``/``Right`` or ``l``/``r`` with ``Toe``; the foot joint on skeletons without
toes), the knee and hip as its ancestors. ``pxr`` is imported only when a stage is read.
"""
from __future__ import annotations

import re

import numpy as np

__all__ = ["PLANT_HEIGHT", "PLANT_VSPEED", "SLIDE_SPEED", "LIMITS", "KNEE_TOLERANCE", "MIN_SHARE_FRAMES", "ENFORCED",
           "knee_range_of", "planted_slide", "slide_summary", "stage_feet", "signed_knee_flexion", "measure_stage",
           "feet_report", "slide_passed", "slide_line"]

PLANT_HEIGHT = 0.05      # m above the foot's lowest point
PLANT_VSPEED = 0.15      # m/s vertical
SLIDE_SPEED = 0.10       # m/s: a planted frame faster than this is sliding
LIMITS = {"mean_cm_s": 3.0, "p95_cm_s": 10.0, "sliding_share": 0.03,
          "lowest_foot_m": -0.01,      # no foot point lower than this
          "knee_min_deg": 0.0}         # signed knee flexion: below zero is hyperextension
KNEE_TOLERANCE = 1.0     # degrees a knee may leave the capture's range by (measurement, blending)
# The sliding share is judged over at least this many planted frames (about 15 s of one walking
# character): below, a handful of touch-down frames decide it (3% of 163 frames is 5 frames).
MIN_SHARE_FRAMES = 1000
# Whether a bake over the limits fails (``crowdweave bake`` exits non-zero and keeps the old stage).
ENFORCED = True


def knee_range_of(library) -> list | None:
    """The capture's knee flexion range a library build kept (``meta["knee_flexion_deg"]``, per
    leg), as [least, most] degrees over both legs; None when the library has none."""
    meta = getattr(library, "meta", None) or {}
    r = meta.get("knee_flexion_deg")
    if r is None:
        return None
    return [float(np.min(r[0])), float(np.max(r[1]))]


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
    # instanced characters keep their Skeleton in an instance: traverse the instance proxies
    proxies = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
    for prim in stage.Traverse():
        if not prim.IsA(UsdSkel.Root) or (keep is not None and str(prim.GetPath()) not in keep):
            continue
        cache.Populate(UsdSkel.Root(prim), proxies)
    for prim in Usd.PrimRange.Stage(stage, proxies):
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
        rows = np.empty((len(times), 2, 4, 4))          # the joints' translation rows (row vectors)
        world = np.empty((len(times), 4, 4))            # the Skeleton's local-to-world (it may move)
        for k, t in enumerate(times):
            rows[k] = np.asarray(q.ComputeJointSkelTransforms(Usd.TimeCode(t)))[chains, 3]
            xf.SetTime(Usd.TimeCode(t))
            world[k] = np.array(xf.GetLocalToWorldTransform(prim), dtype=np.float64)
        rows[..., 3] = 1.0
        pos = (rows @ world[:, None])[..., :3]
        out[str(prim.GetPath())] = (float(times[0]), pos[:, :, 0], pos[:, :, 1], signed_knee_flexion(pos))
    return out


def signed_knee_flexion(pos: np.ndarray) -> np.ndarray:
    """Knee flexion (radians, ``(F, 2)``) of one character's legs ``pos`` (F, 2, 4, 3) = per side
    (toe, ankle, knee, hip): the angle between thigh and shin, negative when the knee lies behind
    the hip-ankle line. Behind is against the pelvis's facing (horizontal, square to the line
    between the hips; of its two senses, the one the feet point along on most frames): the knee
    is behind when it lies more than 5 mm behind the line along that facing (a knee turned out
    sideways is not)."""
    toe, ankle, knee, hip = pos[..., 0, :], pos[..., 1, :], pos[..., 2, :], pos[..., 3, :]
    thigh, shin = knee - hip, ankle - knee
    c = np.sum(thigh * shin, -1) / np.maximum(np.linalg.norm(thigh, axis=-1) * np.linalg.norm(shin, axis=-1), 1e-12)
    flex = np.arccos(np.clip(c, -1.0, 1.0))
    line = ankle - hip
    u = line / np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), 1e-12)
    off = thigh - np.sum(thigh * u, -1, keepdims=True) * u          # the knee's offset from the line
    across = hip[:, 1] - hip[:, 0]
    face = np.stack([across[:, 2], np.zeros(len(across)), -across[:, 0]], axis=-1)   # up x across
    feet = toe - ankle
    if np.sum(np.sum(feet * face[:, None], -1)) < 0.0:
        face = -face
    face = face / np.maximum(np.linalg.norm(face, axis=-1, keepdims=True), 1e-12)
    behind = np.sum(off * face[:, None], -1) < -0.005
    return np.where(behind, -flex, flex)


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


def feet_report(path, roots=None, knee_range=None) -> dict:
    """:func:`measure_stage` plus ``within_limits`` (:func:`slide_passed`, against the capture's
    ``knee_range`` (degrees, [least, most]) when given), the ``limits`` and whether they decide
    a bake (``enforced``: :data:`ENFORCED`)."""
    f = measure_stage(path, roots)
    f.update({"within_limits": slide_passed(f, knee_range), "limits": dict(LIMITS), "enforced": ENFORCED,
              "capture_knee_deg": None if knee_range is None else [float(k) for k in knee_range]})
    return f


def slide_passed(figures: dict, knee_range=None) -> bool:
    """Whether the figures are within :data:`LIMITS` (figures a test leaves out are not
    judged; the sliding share only over :data:`MIN_SHARE_FRAMES` planted frames or more), and
    the knee range within the capture's ``knee_range`` [least, most] degrees (give or take
    :data:`KNEE_TOLERANCE`) when given."""
    share_judged = figures.get("planted_frames", MIN_SHARE_FRAMES) >= MIN_SHARE_FRAMES
    ok = (figures["mean_cm_s"] <= LIMITS["mean_cm_s"] and figures["p95_cm_s"] <= LIMITS["p95_cm_s"]
          and (figures["sliding_share"] <= LIMITS["sliding_share"] or not share_judged)
          and figures.get("lowest_foot_m", 0.0) >= LIMITS["lowest_foot_m"])
    knee = figures.get("knee_flexion_deg")
    if knee is not None:
        ok = ok and knee[0] >= LIMITS["knee_min_deg"]
        if knee_range is not None:
            ok = ok and knee[0] >= knee_range[0] - KNEE_TOLERANCE and knee[1] <= knee_range[1] + KNEE_TOLERANCE
    return bool(ok)


def slide_line(figures: dict) -> str:
    """One line for a bake's printout."""
    return (f"planted feet: mean {figures['mean_cm_s']:.1f} cm/s, p95 {figures['p95_cm_s']:.1f} cm/s, "
            f"{figures['sliding_share'] * 100:.1f}% sliding > {SLIDE_SPEED * 100:.0f} cm/s "
            f"({figures['planted_frames']} planted frames; limits {LIMITS['mean_cm_s']:.0f} / "
            f"{LIMITS['p95_cm_s']:.0f} cm/s, {LIMITS['sliding_share'] * 100:.0f}%); lowest foot "
            f"{figures['lowest_foot_m'] * 100:.1f} cm, knee flexion {figures['knee_flexion_deg'][0]:.1f}-"
            f"{figures['knee_flexion_deg'][1]:.1f} deg"
            + (f" (capture {figures['capture_knee_deg'][0]:.1f}-{figures['capture_knee_deg'][1]:.1f})"
               if figures.get("capture_knee_deg") else ""))
