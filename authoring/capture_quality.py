"""Independent quality check of captured takes (generated or real): reads the BVH files and
label sidecars back and measures them from forward-kinematics joint positions only. It does
not import the generator and uses none of its internal numbers (no footprints, no foot
geometry, no planned timing); thresholds are stated here.

Measures, per take and pooled over a take directory:

* **Foot sliding.** A foot joint (ankle ``*Foot``, ball ``*ToeBase``) is *low* when its
  height is within ``CONTACT_HEIGHT`` (2 cm) of its own floor level (its lowest height
  within +-1 s, which follows a floor that is not quite level in real capture) and its horizontal speed is under ``CONTACT_SPEED`` (1 m/s, only to
  exclude swinging feet skimming the floor). A foot is in contact when either joint is low;
  its sliding speed is that of its slowest low joint (a foot rolling over the heel or the
  ball pivots about the point on the floor, which must not slide). Reported: mean and 95th
  percentile over contact frames, and the same per joint for reference.
* **Cadence vs speed.** Heel strikes = contact onsets; a step is
  two consecutive strikes of opposite feet (contacts shorter than 0.12 s are ignored and
  gaps under 0.1 s inside a contact closed, for noisy real data). Step time, step length (distance between the
  two contact positions along the direction of travel) and speed (root displacement / step
  time) are binned by speed and compared with the human reference cadence
  ``1.0 + 0.65 v`` steps/s (step length ``v / (1.0 + 0.65 v)``).
* **Knee angles.** Flexion = angle between thigh (hip->knee) and shank (knee->ankle);
  hyperextension = a knee bent backwards, i.e. behind the hip-ankle line with respect to
  the pelvis' forward direction (perpendicular to the hip-to-hip axis, horizontal).
* **Pops.** Largest frame-to-frame change of any joint's local rotation (root: world
  rotation), with its frame, joint and label; largest root displacement per frame.
* **Labels.** Segments must tile ``[0, frames)`` in order; occurrences per label (both raw
  segments and merged runs of one label).
* **Hubs.** When the sidecar lists hub frames, the spread of the root-relative pose over
  all occurrences of each hub (largest joint distance from the hub's mean pose).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from runtime.motion import quat

__all__ = ["take_quality", "bvh_take_quality", "CONTACT_HEIGHT", "CONTACT_SPEED", "reference_cadence",
           "format_quality"]

CONTACT_HEIGHT = 0.02      # metres above the joint's floor level
CONTACT_SPEED = 1.0        # m/s; faster joints are swinging, not in contact
FLOOR_WINDOW_SECONDS = 1.0 # a joint's floor level = its lowest height within +-1 s
MIN_CONTACT_SECONDS = 0.12   # a contact (for step detection) lasts at least this long
MIN_STEP_SECONDS = 0.25
MAX_GAP_SECONDS = 0.1        # gaps this short inside a contact are closed (noisy real data)
SPEED_BINS = (0.45, 0.75, 1.05, 1.35, 1.65, 1.95)
HYPEREXT_TOL_DEG = 1.0


def reference_cadence(v):
    return 1.0 + 0.65 * np.asarray(v, dtype=np.float64)


def _foot_joints(names):
    out = []
    for side in ("Left", "Right"):
        need = [f"{side}UpLeg", f"{side}Leg", f"{side}Foot", f"{side}ToeBase"]
        if not all(n in names for n in need):
            raise ValueError(f"skeleton has no {side} leg chain named {need}")
        out.append([names.index(n) for n in need])
    return out


def _runs(mask):
    """Start/end (exclusive) of runs of True."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _label_array(segments, F):
    lab = np.array([""] * F, dtype=object)
    for a, b, l in segments:
        lab[max(a, 0):min(b, F)] = l
    return lab


def _contacts(pos, fps):
    """Per joint: low (F-1,) bool and horizontal speed (F-1,) over frame pairs."""
    h = pos[..., 1]
    r = max(int(round(FLOOR_WINDOW_SECONDS * fps)), 1)
    pad = np.concatenate([np.repeat(h[:1], r, axis=0), h, np.repeat(h[-1:], r, axis=0)], axis=0)
    floor = np.lib.stride_tricks.sliding_window_view(pad, 2 * r + 1, axis=0).min(axis=-1)
    low_h = h < floor + CONTACT_HEIGHT
    sp = np.linalg.norm(np.diff(pos[..., [0, 2]], axis=0), axis=-1) * fps
    low = low_h[:-1] & low_h[1:] & (sp < CONTACT_SPEED)
    return low, sp


def bvh_take_quality(bvh_path, labels_path=None) -> dict:
    from authoring.bvh import read_bvh

    m = read_bvh(bvh_path, drop_first_frame="auto")
    clip = m.clip
    fps = clip.fps
    F = clip.num_frames
    names = list(clip.skeleton.names)
    labels = {}
    if labels_path is not None and Path(labels_path).exists():
        labels = json.loads(Path(labels_path).read_text())
    segments = [tuple(s) for s in labels.get("segments", [])]
    lab = _label_array(segments, F)
    gr, gp = clip.fk()
    out = {"file": Path(bvh_path).name, "frames": F, "fps": fps, "seconds": F / fps,
           "family": m.family, "joints": clip.skeleton.num_joints}

    # ---- foot sliding ---------------------------------------------------------------------
    legs = _foot_joints(names)
    foot_speeds = []
    per_joint = {"ankle": [], "ball": []}
    contact = np.zeros((F - 1, 2), dtype=bool)
    for s, (jh, jk, ja, jt) in enumerate(legs):
        low, sp = _contacts(gp[:, [ja, jt]], fps)
        any_low = low.any(axis=1)
        slide = np.where(low, sp, np.inf).min(axis=1)
        foot_speeds.append(slide[any_low])
        per_joint["ankle"].append(sp[low[:, 0], 0])
        per_joint["ball"].append(sp[low[:, 1], 1])
        contact[:, s] = any_low
    fs = np.concatenate(foot_speeds)
    out["foot_contact"] = {
        "mean_speed_m_s": float(fs.mean()) if len(fs) else 0.0,
        "p95_speed_m_s": float(np.percentile(fs, 95)) if len(fs) else 0.0,
        "contact_fraction": float(contact.mean()),
        "mean_ankle_speed_m_s": float(np.concatenate(per_joint["ankle"]).mean()),
        "mean_ball_speed_m_s": float(np.concatenate(per_joint["ball"]).mean()),
        "frames": int(len(fs)),
    }

    # ---- steps: cadence and step length vs speed --------------------------------------------
    strikes = []      # (frame, side, contact position xz)
    for s, (jh, jk, ja, jt) in enumerate(legs):
        c = contact[:, s].copy()
        starts, ends = _runs(~c)
        for a, b in zip(starts, ends):          # close short gaps
            if a > 0 and b < len(c) and (b - a) <= MAX_GAP_SECONDS * fps:
                c[a:b] = True
        starts, ends = _runs(c)
        for a, b in zip(starts, ends):
            if (b - a) < MIN_CONTACT_SECONDS * fps:
                continue
            mid = gp[a:b, [ja, jt]][..., [0, 2]].mean(axis=(0, 1))
            strikes.append((int(a), s, mid))
    strikes.sort(key=lambda t: t[0])
    steps = []
    root = gp[:, 0]
    for (f0, s0, p0), (f1, s1, p1) in zip(strikes[:-1], strikes[1:]):
        if s0 == s1 or f1 <= f0:
            continue
        dt = (f1 - f0) / fps
        if dt < MIN_STEP_SECONDS:             # faster than 4 steps/s is not a walking step
            continue
        disp = root[f1, [0, 2]] - root[f0, [0, 2]]
        dist = float(np.linalg.norm(disp))
        if dist < 1e-3:
            continue
        v = dist / dt
        length = float(np.dot(p1 - p0, disp / dist))
        steps.append((f0, f1, v, 1.0 / dt, length, str(lab[f0]), str(lab[min(f1, F - 1)])))
    out["steps"] = _step_table(steps)

    # ---- knees ----------------------------------------------------------------------------
    flex_all, hyper_all = [], []
    across = gp[:, legs[0][0]] - gp[:, legs[1][0]]          # right hip -> left hip
    pelvis_fwd = np.cross(across, np.array([0.0, 1.0, 0.0]))
    pelvis_fwd /= np.maximum(np.linalg.norm(pelvis_fwd, axis=-1, keepdims=True), 1e-9)
    for (jh, jk, ja, jt) in legs:
        thigh = gp[:, jk] - gp[:, jh]
        shank = gp[:, ja] - gp[:, jk]
        cosang = np.sum(thigh * shank, -1) / (np.linalg.norm(thigh, axis=-1) * np.linalg.norm(shank, axis=-1))
        flex = np.degrees(np.arccos(np.clip(cosang, -1, 1)))
        line = gp[:, ja] - gp[:, jh]
        t = np.sum((gp[:, jk] - gp[:, jh]) * line, -1) / np.maximum(np.sum(line * line, -1), 1e-12)
        off = gp[:, jk] - (gp[:, jh] + t[:, None] * line)
        backwards = np.sum(off * pelvis_fwd, -1) < 0
        flex_all.append(flex)
        hyper_all.append(np.where(backwards, flex, 0.0))
    flex = np.stack(flex_all, 1)
    hyper = np.stack(hyper_all, 1)
    out["knees"] = {
        "max_flexion_deg": float(flex.max()),
        "max_flexion_label": str(lab[int(np.argmax(flex.max(1)))]),
        "max_hyperextension_deg": float(hyper.max()),
        "hyperextended_frames": int((hyper > HYPEREXT_TOL_DEG).any(axis=1).sum()),
    }

    # ---- pops -----------------------------------------------------------------------------
    rot = clip.local_rotations_world_root()
    ang = np.degrees(quat.angle(rot[:-1], rot[1:]))        # (F-1, J)
    f_, j_ = np.unravel_index(int(np.argmax(ang)), ang.shape)
    rp = np.linalg.norm(np.diff(gp[:, 0], axis=0), axis=-1)
    out["pops"] = {
        "max_rotation_step_deg": float(ang.max()),
        "at_frame": int(f_), "joint": names[j_], "label": str(lab[f_]),
        "p999_rotation_step_deg": float(np.percentile(ang.max(axis=1), 99.9)),
        "max_root_step_m": float(rp.max()),
    }

    # ---- labels ---------------------------------------------------------------------------
    ok = bool(segments) and segments[0][0] == 0 and segments[-1][1] == F and all(
        a[1] == b[0] for a, b in zip(segments[:-1], segments[1:])) and all(a < b for a, b, _ in segments)
    if labels and labels.get("frames") not in (None, F):
        ok = False
    seg_counts, runs = {}, {}
    prev = None
    for a, b, l in segments:
        seg_counts[l] = seg_counts.get(l, 0) + 1
        if l != prev:
            runs[l] = runs.get(l, 0) + 1
        prev = l
    out["labels"] = {"tiles_all_frames": ok, "segments": seg_counts, "occurrences": runs}

    # ---- hubs -----------------------------------------------------------------------------
    hubs = labels.get("hubs", [])
    if hubs:
        heading = clip.world_heading()
        spread = {}
        for name in sorted({h for _, h in hubs}):
            fr = np.array([f for f, h in hubs if h == name and 0 <= f < F])
            if len(fr) < 2:
                continue
            poses = []
            for f in fr:
                c, s = np.cos(-heading[f]), np.sin(-heading[f])
                R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
                p = (gp[f] - np.array([gp[f, 0, 0], 0.0, gp[f, 0, 2]])) @ R.T
                poses.append(p)
            poses = np.stack(poses)
            dev = np.linalg.norm(poses - poses.mean(0), axis=-1).max(axis=1)
            spread[name] = {"count": int(len(fr)), "max_joint_deviation_m": float(dev.max()),
                            "median_joint_deviation_m": float(np.median(dev))}
        out["hubs"] = spread
    return out


def _step_table(steps):
    rows = []
    for kind, allowed in (("walk", ("walk",)), ("carry", ("carry",)), ("all", None)):
        sel = [s for s in steps if allowed is None or (s[5] in allowed and s[6] in allowed)]
        table = []
        for lo, hi in zip(SPEED_BINS[:-1], SPEED_BINS[1:]):
            b = [s for s in sel if lo <= s[2] < hi]
            if not b:
                continue
            v = float(np.mean([s[2] for s in b]))
            cad = float(np.mean([s[3] for s in b]))
            length = float(np.mean([s[4] for s in b]))
            ref = float(reference_cadence(v))
            table.append({"speed_bin": [lo, hi], "steps": len(b), "speed_m_s": v, "cadence_steps_s": cad,
                          "reference_cadence": ref, "cadence_ratio": cad / ref, "step_length_m": length,
                          "reference_step_length_m": v / ref})
        rows.append((kind, {"steps": len(sel), "bins": table}))
    return dict(rows)


def take_quality(take_dir) -> dict:
    """Quality metrics of every ``*.bvh`` in a take directory (with ``*.labels.json``
    sidecars when present), per take and pooled."""
    d = Path(take_dir)
    files = sorted(d.glob("*.bvh"))
    if not files:
        raise FileNotFoundError(f"{d}: no .bvh files")
    takes = [bvh_take_quality(f, f.with_name(f.name[:-4] + ".labels.json")) for f in files]
    frames = np.array([t["frames"] for t in takes])
    cf = np.array([t["foot_contact"]["frames"] for t in takes])
    occ, segs = {}, {}
    for t in takes:
        for k, v in t["labels"]["occurrences"].items():
            occ[k] = occ.get(k, 0) + v
        for k, v in t["labels"]["segments"].items():
            segs[k] = segs.get(k, 0) + v
    # pool steps by re-binning the per-take bins (weighted by steps)
    pooled = {}
    for kind in ("walk", "carry", "all"):
        acc = {}
        for t in takes:
            for b in t["steps"][kind]["bins"]:
                key = tuple(b["speed_bin"])
                acc.setdefault(key, []).append(b)
        bins = []
        for key in sorted(acc):
            bs = acc[key]
            n = sum(b["steps"] for b in bs)

            def wmean(field):
                return float(sum(b[field] * b["steps"] for b in bs) / n)
            v = wmean("speed_m_s")
            ref = float(reference_cadence(v))
            cad = wmean("cadence_steps_s")
            bins.append({"speed_bin": list(key), "steps": n, "speed_m_s": v, "cadence_steps_s": cad,
                         "reference_cadence": ref, "cadence_ratio": cad / ref,
                         "step_length_m": wmean("step_length_m"), "reference_step_length_m": v / ref})
        pooled[kind] = {"steps": sum(t["steps"][kind]["steps"] for t in takes), "bins": bins}
    hubs = {}
    for t in takes:
        for k, v in t.get("hubs", {}).items():
            h = hubs.setdefault(k, {"count": 0, "max_joint_deviation_m": 0.0})
            h["count"] += v["count"]
            h["max_joint_deviation_m"] = max(h["max_joint_deviation_m"], v["max_joint_deviation_m"])
    walk_bins = [b for b in pooled["walk"]["bins"] if b["steps"] >= 5]
    summary = {
        "takes": len(takes),
        "frames": int(frames.sum()),
        "seconds": float(sum(t["seconds"] for t in takes)),
        "foot_contact_mean_speed_m_s": float(sum(t["foot_contact"]["mean_speed_m_s"] * n
                                                 for t, n in zip(takes, cf)) / max(cf.sum(), 1)),
        "foot_contact_p95_speed_m_s": float(max(t["foot_contact"]["p95_speed_m_s"] for t in takes)),
        "max_knee_flexion_deg": float(max(t["knees"]["max_flexion_deg"] for t in takes)),
        "max_knee_hyperextension_deg": float(max(t["knees"]["max_hyperextension_deg"] for t in takes)),
        "hyperextended_frames": int(sum(t["knees"]["hyperextended_frames"] for t in takes)),
        "max_rotation_step_deg": float(max(t["pops"]["max_rotation_step_deg"] for t in takes)),
        "labels_tile_frames": all(t["labels"]["tiles_all_frames"] for t in takes),
        "label_occurrences": dict(sorted(occ.items())),
        "label_segments": dict(sorted(segs.items())),
        "cadence": pooled,
        "hubs": hubs,
        "cadence_within_15pct": bool(walk_bins) and all(0.85 <= b["cadence_ratio"] <= 1.15 for b in walk_bins),
    }
    return {"summary": summary, "takes": takes}


def format_quality(q: dict) -> str:
    """Human-readable summary lines of :func:`take_quality`'s result."""
    s = q["summary"]
    lines = [
        f"takes {s['takes']}, {s['frames']} frames, {s['seconds']:.1f} s",
        f"foot sliding in contact: mean {100 * s['foot_contact_mean_speed_m_s']:.2f} cm/s, "
        f"p95 {100 * s['foot_contact_p95_speed_m_s']:.2f} cm/s",
        f"knees: max flexion {s['max_knee_flexion_deg']:.1f} deg, max hyperextension "
        f"{s['max_knee_hyperextension_deg']:.2f} deg ({s['hyperextended_frames']} frames)",
        f"largest frame-to-frame joint rotation {s['max_rotation_step_deg']:.2f} deg",
        "label occurrences: " + ", ".join(f"{k} {v}" for k, v in s["label_occurrences"].items()),
        "cadence vs speed (walk steps):",
        "  speed bin   steps  speed  cadence  ref(1+0.65v)  ratio  step len  ref len",
    ]
    for b in s["cadence"]["walk"]["bins"]:
        lines.append(f"  {b['speed_bin'][0]:.2f}-{b['speed_bin'][1]:.2f}  {b['steps']:5d}  {b['speed_m_s']:5.2f}  "
                     f"{b['cadence_steps_s']:7.2f}  {b['reference_cadence']:12.2f}  {b['cadence_ratio']:5.2f}  "
                     f"{b['step_length_m']:8.2f}  {b['reference_step_length_m']:7.2f}")
    if s["cadence"]["carry"]["bins"]:
        lines.append("cadence vs speed (carry steps):")
        for b in s["cadence"]["carry"]["bins"]:
            lines.append(f"  {b['speed_bin'][0]:.2f}-{b['speed_bin'][1]:.2f}  {b['steps']:5d}  {b['speed_m_s']:5.2f}  "
                         f"{b['cadence_steps_s']:7.2f}  {b['reference_cadence']:12.2f}  {b['cadence_ratio']:5.2f}  "
                         f"{b['step_length_m']:8.2f}  {b['reference_step_length_m']:7.2f}")
    if s["hubs"]:
        lines.append("hub pose spread: " + ", ".join(
            f"{k} x{v['count']} {100 * v['max_joint_deviation_m']:.1f} cm" for k, v in s["hubs"].items()))
    return "\n".join(lines)
