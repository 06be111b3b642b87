"""The take scheduler: a capture session of several takes, written as BVH + label sidecars.

A session is a sequence of activity groups (:mod:`.activities`), each starting and ending
in the standing hub pose. A bag of the non-locomotion activities (idle, turn in place, sit
cycle, box cycle) is shuffled and drawn in turn, with walk runs between them, so every
activity recurs at a steady rate; the bag persists across takes. The performer stays inside
a capture volume: walk edges and turns in place are biased towards its centre when far
from it. Every random choice comes from one ``numpy.random.Generator`` seeded from the
session seed; the same seed gives byte-identical files.

Files: ``take_NNN.bvh`` (31-joint CMU MotionBuilder-family hierarchy, ZYX channels, CMU
units), ``take_NNN.labels.json`` (``{"fps", "frames", "segments": [[start, end_exclusive,
label], ...], "hubs": [[frame, hub], ...], "props": [...], "contacts": {point: [[start,
end_exclusive], ...]}}``; the segments cover every frame; ``contacts`` lists, per contact point
of :data:`runtime.motion.contacts.CONTACT_POINTS`, the runs of frames it is on the ground, from
the generator's foot targets, :mod:`.contacts`) and ``session.json`` (generator version, seed, minutes, fps, files with sha256).
"""
from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from runtime.assets import atomic_write_bytes
from runtime.limits import MAX_CAPTURE_MINUTES, MAX_SEED, MAX_TAKE_MINUTES
from runtime.motion import Clip
from runtime.motion.contacts import CONTACT_POINTS
from runtime.motion.planar import wrap_angle

from . import activities as act
from . import body
from .contacts import contact_labels
from .gait import WALK
from .group import concat_groups
from .locomotion import run_group
from .rig import solve

__all__ = ["GENERATOR_VERSION", "LABELS", "GeneratedTake", "generate_session", "write_session", "contact_runs"]

GENERATOR_VERSION = "1.1"
LABELS = ("walk", "start", "stop", "idle", "turn", "sit_down", "sit", "stand_up",
          "pick_up", "carry", "put_down")
VOLUME_RADIUS = 4.0        # metres; walks bend back towards the centre beyond this


@dataclass
class GeneratedTake:
    """One generated single-performer take: the clip, its label segments and hub frames,
    the props (chair, box) and the rig solver's diagnostics."""
    clip: Clip
    segments: list
    hubs: list
    props: list
    diagnostics: dict

    def labels_json(self) -> dict:
        return {
            "fps": self.clip.fps,
            "frames": self.clip.num_frames,
            "segments": [[int(a), int(b), lab] for a, b, lab in self.segments],
            "hubs": [[int(f), h] for f, h in self.hubs],
            "props": self.props,
            "contacts": {name: contact_runs(self.clip.contacts[:, k]) for k, name in enumerate(CONTACT_POINTS)},
            "generator": f"crowdweave.procedural {GENERATOR_VERSION}",
        }


def contact_runs(flags: np.ndarray) -> list:
    """[[start, end_exclusive], ...] of the runs of True in ``flags``."""
    d = np.diff(np.concatenate([[0], np.asarray(flags, dtype=np.int8), [0]]))
    return [[int(a), int(b)] for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]


def _steer_bias(state):
    """Heading change (rad) that points the performer back towards the volume centre."""
    x, z, th = state
    dist = float(np.hypot(x, z))
    if dist < 1e-6:
        return 0.0
    want = np.arctan2(-x, -z)
    d = wrap_angle(want - th)
    gain = np.clip((dist - 0.5 * VOLUME_RADIUS) / VOLUME_RADIUS, 0.0, 1.0)
    return float(d * gain)


class _Scheduler:
    """Walk runs alternate with one or two activities drawn from a shuffled bag of
    (idle, turn, sit, box); near the end of a take only short groups are scheduled and the
    drawn activities wait for the next take."""

    def __init__(self, rng, skel, fps):
        self.rng = rng
        self.skel = skel
        self.fps = fps
        self.bag = []
        self.queue = []
        self.need_run = True

    def _draw(self):
        if not self.bag:
            self.bag = ["idle", "turn", "sit", "box"]
            self.rng.shuffle(self.bag)
        return self.bag.pop()

    def _run(self, state, n_edges=None, style=WALK):
        n_edges = int(self.rng.integers(2, 5)) if n_edges is None else n_edges
        bias = _steer_bias(state) / (n_edges + 1)
        return run_group(self.skel, self.rng, state, self.fps, style, n_edges, lambda: bias)

    def next(self, state, remaining):
        """The next group from ``state`` given the seconds left in the take."""
        if remaining < 12.0:
            short = [k for k in self.queue if k in ("idle", "turn")]
            if not short and not self.queue and self.bag:
                short = [k for k in self.bag if k in ("idle", "turn")]
                if short:                                 # take it from the bag now
                    self.bag.remove(short[0])
                    self.queue.append(short[0])
            if short:
                kind = short[0]
                self.queue.remove(kind)
            elif remaining > 8.0:
                return self._run(state, n_edges=1)
            else:
                return act.idle(self.skel, self.rng, state, self.fps)
        elif self.need_run or not self.queue:
            self.need_run = False
            if not self.queue:
                self.queue = [self._draw() for _ in range(1 if self.rng.random() < 0.4 else 2)]
            return self._run(state)
        else:
            kind = self.queue.pop(0)
        if not self.queue:
            self.need_run = True
        if kind == "idle":
            return act.idle(self.skel, self.rng, state, self.fps)
        if kind == "turn":
            return act.turn_in_place(self.skel, self.rng, state, self.fps, prefer=_steer_bias(state))
        if kind == "sit":
            return act.sit_cycle(self.skel, self.rng, state, self.fps)
        bias = _steer_bias(state) * 0.3
        return act.box_cycle(self.skel, self.rng, state, self.fps, lambda: bias)


def _assemble(skel, groups, fps) -> GeneratedTake:
    c, segs, hubs, starts = concat_groups(groups)
    props = []
    for i, (g, f) in enumerate(zip(groups, starts)):
        last = i == len(groups) - 1
        for p in g.props:
            q = dict(p)
            q["start"] = int(p["start"]) + f
            q["end"] = int(min(p["end"] + f, f + g.num_frames + (1 if last else 0)))
            props.append(q)
    F = c.num_frames
    hubs.append((F - 1, "stand"))             # the final frame is the end hub
    sol = solve(skel, c)
    clip = Clip.from_world(skel, fps, sol.root_pos, sol.local).copy(contacts=contact_labels(c, fps))
    diag = {
        "max_leg_reach_error_m": float(sol.leg_reach_error.max()),
        "max_arm_reach_error_m": float(sol.arm_reach_error.max()),
        "max_knee_flexion_deg": float(np.degrees(sol.knee_flexion.max())),
    }
    return GeneratedTake(clip, segs, hubs, props, diag)


def _check_session(minutes: float, seed: int, fps: float, take_minutes: float) -> None:
    if not (0 < minutes <= MAX_CAPTURE_MINUTES):
        raise ValueError(f"minutes must be positive and at most {MAX_CAPTURE_MINUTES:g}, got {minutes}")
    if not (0 < take_minutes <= MAX_TAKE_MINUTES):
        raise ValueError(f"take minutes must be positive and at most {MAX_TAKE_MINUTES:g}, got {take_minutes}")
    if not (0 < fps <= 1000):
        raise ValueError(f"fps must be positive and at most 1000, got {fps}")
    if not (0 <= int(seed) <= MAX_SEED):
        raise ValueError(f"seed must be from 0 to {MAX_SEED}, got {seed}")


def generate_session(minutes: float, seed: int, fps: float = 30.0, take_minutes: float = 2.0,
                     progress=None) -> list[GeneratedTake]:
    """Generate the takes of a session in memory. ``progress(seconds)`` is called as
    motion is produced."""
    _check_session(minutes, seed, fps, take_minutes)
    return list(_iter_session(minutes, seed, fps, take_minutes, progress))


def _iter_session(minutes, seed, fps, take_minutes, progress):
    """The takes of a session one after another (only one is held at a time)."""
    rng = np.random.default_rng(np.random.SeedSequence(int(seed)))
    skel = body.make_skeleton()
    total = minutes * 60.0
    n_takes = max(1, int(np.ceil(total / (take_minutes * 60.0) - 1e-9)))
    lengths = [min(take_minutes * 60.0, total - i * take_minutes * 60.0) for i in range(n_takes)]
    if n_takes > 1 and lengths[-1] < min(20.0, 0.5 * take_minutes * 60.0):   # fold a short remainder
        lengths[-2] += lengths[-1]
        lengths.pop()
    sched = _Scheduler(rng, skel, fps)
    for target in lengths:
        state = (0.0, 0.0, float(rng.uniform(-np.pi, np.pi)))
        sched.need_run = True
        groups = []
        t = 0.0
        while t < target - 2.0:
            g = sched.next(state, target - t)
            groups.append(g)
            state = g.end
            t += g.num_frames / fps
            if progress is not None:
                progress(g.num_frames / fps)
        yield _assemble(skel, groups, fps)


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


_TAKE_FILE = re.compile(r"take_\d{3,}\.(bvh|labels\.json)")


def _earlier_take_files(out: Path) -> set:
    """Take files an earlier session left in ``out``: those its session.json lists and any
    ``take_NNN.bvh`` / ``take_NNN.labels.json`` (a session killed before its manifest)."""
    names = {p.name for p in out.iterdir() if p.is_file() and _TAKE_FILE.fullmatch(p.name)}
    try:
        old = json.loads((out / "session.json").read_text(encoding="utf-8"))
        names |= {f["path"] for f in old.get("files", []) if isinstance(f, dict) and isinstance(f.get("path"), str)
                  and _TAKE_FILE.fullmatch(f["path"])}
    except (OSError, ValueError, AttributeError):
        pass
    return names


def write_session(out_dir, minutes: float, seed: int, fps: float = 30.0, take_minutes: float = 2.0,
                  progress=None) -> dict:
    """Generate and write a session, take by take (memory holds one take); returns the manifest
    (also written as session.json, last). Writing into the directory of an earlier session
    replaces it: its session.json goes first (a directory without one is incomplete) and its
    take files that the new session does not write are removed, so no stale take is read later.
    """
    from authoring.bvh import write_bvh

    _check_session(minutes, seed, fps, take_minutes)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    earlier = _earlier_take_files(out)
    (out / "session.json").unlink(missing_ok=True)
    files = []
    take_rows = []
    for i, tk in enumerate(_iter_session(minutes, seed, fps, take_minutes, progress)):
        bvh = out / f"take_{i:03d}.bvh"
        lab = out / f"take_{i:03d}.labels.json"
        write_bvh(bvh, tk.clip, channel_orders="ZYX", scale=body.CMU_UNIT, precision=6)
        atomic_write_bytes(lab, (json.dumps(tk.labels_json(), indent=1) + "\n").encode("utf-8"))
        counts = {}
        for a, b, l in tk.segments:
            counts[l] = counts.get(l, 0) + 1
        take_rows.append({"bvh": bvh.name, "labels": lab.name, "frames": tk.clip.num_frames,
                          "seconds": round(tk.clip.num_frames / fps, 4), "segments": counts,
                          "diagnostics": {k: round(v, 6) for k, v in tk.diagnostics.items()}})
        files += [bvh, lab]
    for name in sorted(earlier - {p.name for p in files}):
        (out / name).unlink(missing_ok=True)
    manifest = {
        "generator": "crowdweave.procedural",
        "version": GENERATOR_VERSION,
        "seed": int(seed),
        "minutes": float(minutes),
        "take_minutes": float(take_minutes),
        "fps": float(fps),
        "skeleton_family": "cmu-mb",
        "bvh_scale_m_per_unit": body.CMU_UNIT,
        "labels": list(LABELS),
        "takes": take_rows,
        "files": [{"path": p.name, "bytes": p.stat().st_size, "sha256": _sha256(p)} for p in files],
    }
    atomic_write_bytes(out / "session.json", (json.dumps(manifest, indent=1) + "\n").encode("utf-8"))
    return manifest
