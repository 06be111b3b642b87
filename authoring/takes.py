"""Multi-character takes: several performers captured on one shared clock.

A :class:`Take` holds one :class:`~runtime.motion.clip.Clip` per performer (same frame count
and rate; frame ``i`` of every clip is the same instant, and each clip keeps its world
placement in ``clip.origin``), the performers' names, per-performer label segments, the
ground-truth interaction events (for tests of the episode detector of Kim, Hwang, Hyun and
Lee 2012, section 4.1) and props (the box of a hand-over).

On disk a take is a directory::

    take.json              {"format": "crowdweave-take", "version": 1, "name", "fps", "frames",
                            "people": [{"name", "bvh", "labels"}], "events": [...],
                            "props": [...], "labels": [...], "source": {...}}
    <person>.bvh           one BVH per performer (world root placement, CMU units for the
                           CMU skeleton families, metres otherwise)
    <person>.labels.json   {"fps", "frames", "segments": [[start, end_exclusive, label], ...]}

so :func:`authoring.capture_quality.take_quality` checks a take directory as it is (foot
sliding per performer). A directory of takes has one sub-directory per take and a
``takes.json`` manifest.

Sources: :func:`generate_takes` (procedural scenes of :mod:`authoring.procedural.interactions`,
seeded, byte-identical for one seed) and :func:`import_cmu_duet` (two BVH files recorded on
one clock, e.g. the CMU salsa duet 60_10 + 61_10 at 60 fps, resampled to 30 Hz).
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from runtime.assets import atomic_write_bytes
from runtime.motion import ops

__all__ = ["TAKE_FORMAT", "TAKE_VERSION", "DEFAULT_KINDS", "TakeError", "Take", "take_from_scene",
           "generate_takes", "write_takes", "load_take", "load_takes", "find_take_dirs", "import_cmu_duet"]

TAKE_FORMAT = "crowdweave-take"
TAKE_VERSION = 1
DEFAULT_KINDS = ("handshake", "high_five", "bow", "bump", "box_pass", "dash_dodge", "relay", "bow3",
                 "handshake_bystander", "walker", "walker", "pair_apart")


class TakeError(ValueError):
    """A take directory that cannot be read. ``str(e)`` is ``"path: what is wrong"``."""

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{self.path}: {reason}")


@dataclass(eq=False)
class Take:
    """A multi-person take: one clip per performer on a shared clock (see the module
    docstring); checks on construction that the clips agree on frame count and rate."""
    name: str
    fps: float
    people: list                     # performer names
    clips: list                      # one Clip per performer
    segments: list = field(default_factory=list)   # per performer [(start, end_exclusive, label)]
    events: list = field(default_factory=list)     # [{"label", "kind", "people", "start", "end"}]
    props: list = field(default_factory=list)
    labels: tuple = ()
    source: dict = field(default_factory=dict)

    def __post_init__(self):
        if not self.clips:
            raise ValueError(f"take {self.name!r} has no performers")
        if len(self.people) != len(self.clips):
            raise ValueError(f"take {self.name!r}: {len(self.people)} names for {len(self.clips)} clips")
        F = self.clips[0].num_frames
        for n, c in zip(self.people, self.clips):
            if c.num_frames != F:
                raise ValueError(f"take {self.name!r}: performer {n!r} has {c.num_frames} frames, not {F}")
            if abs(c.fps - self.fps) > 1e-9:
                raise ValueError(f"take {self.name!r}: performer {n!r} at {c.fps} fps, take at {self.fps}")
        if len(set(self.people)) != len(self.people):
            raise ValueError(f"take {self.name!r}: performer names must be unique")
        if not self.segments:
            self.segments = [[(0, F, "unlabelled")] for _ in self.clips]
        self.labels = tuple(self.labels)

    @property
    def num_people(self) -> int:
        return len(self.clips)

    @property
    def num_frames(self) -> int:
        return self.clips[0].num_frames

    @property
    def duration(self) -> float:
        return (self.num_frames - 1) / self.fps

    def label_at(self, person: int, frame: int) -> str:
        for a, b, lab in self.segments[person]:
            if a <= frame < b:
                return lab
        return ""

    # -- files -----------------------------------------------------------------------------
    def manifest(self) -> dict:
        return {
            "format": TAKE_FORMAT, "version": TAKE_VERSION, "name": self.name, "fps": float(self.fps),
            "frames": int(self.num_frames),
            "people": [{"name": n, "bvh": f"{n}.bvh", "labels": f"{n}.labels.json"} for n in self.people],
            "events": [_event_json(e) for e in self.events],
            "props": self.props, "labels": list(self.labels), "source": self.source,
        }

    def save(self, directory) -> Path:
        """Write the take directory (BVH per performer, label sidecars, take.json); atomic per file."""
        from authoring.bvh import default_scale, write_bvh

        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        for n, c, segs in zip(self.people, self.clips, self.segments):
            write_bvh(d / f"{n}.bvh", c, channel_orders="ZYX", scale=default_scale(c.skeleton.family), precision=6)
            side = {"fps": float(self.fps), "frames": int(self.num_frames),
                    "segments": [[int(a), int(b), str(lab)] for a, b, lab in segs]}
            atomic_write_bytes(d / f"{n}.labels.json", _json_bytes(side))
        atomic_write_bytes(d / "take.json", _json_bytes(self.manifest()))
        return d


def _event_json(e) -> dict:
    if hasattr(e, "to_json"):
        return e.to_json()
    d = {"label": str(e["label"]), "kind": str(e["kind"]), "people": [int(p) for p in e["people"]],
         "start": int(e["start"]), "end": int(e["end"])}
    if e.get("optional"):
        d["optional"] = True
    return d


def _json_bytes(obj) -> bytes:
    return (json.dumps(obj, indent=1, sort_keys=True) + "\n").encode("utf-8")


# ------------------------------------------------------------------------------------------
# procedural takes
# ------------------------------------------------------------------------------------------
def take_from_scene(scene, name: str, source: dict | None = None) -> Take:
    """A :class:`Take` from an :class:`authoring.procedural.interactions.Scene`."""
    labels = sorted({e.label for e in scene.events}) or [scene.kind]
    return Take(name, scene.clips[0].fps, list(scene.names), list(scene.clips),
                [list(s) for s in scene.segments], [e.to_json() for e in scene.events], list(scene.props),
                tuple(labels), dict(source or {}, kind=scene.kind, diagnostics=scene.diagnostics))


def generate_takes(seed: int, kinds=DEFAULT_KINDS, repeat: int = 1, fps: float = 30.0, progress=None) -> list[Take]:
    """Generate ``repeat`` takes of every scene kind. Take ``i`` gets its own child seed of
    ``SeedSequence(seed)``, so a take does not depend on the ones generated before it."""
    from authoring.procedural.interactions import GENERATOR_VERSION, make_scene

    kinds = list(kinds)
    if repeat < 1:
        raise ValueError("repeat must be at least 1")
    if not kinds:
        raise ValueError("no take kinds given")
    jobs = [k for _ in range(repeat) for k in kinds]
    children = np.random.SeedSequence(int(seed)).spawn(len(jobs))
    out = []
    for i, (k, ss) in enumerate(zip(jobs, children)):
        sc = make_scene(k, ss, fps)
        out.append(take_from_scene(sc, f"{k}_{i:03d}",
                                   {"generator": "crowdweave.procedural.interactions", "version": GENERATOR_VERSION,
                                    "seed": int(seed), "index": i}))
        if progress is not None:
            progress(1)
    return out


def write_takes(out_dir, seed: int, kinds=DEFAULT_KINDS, repeat: int = 1, fps: float = 30.0, progress=None) -> dict:
    """Generate and write takes into ``out_dir/<name>/`` plus ``out_dir/takes.json``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    takes = generate_takes(seed, kinds, repeat, fps, progress)
    rows = []
    for tk in takes:
        d = tk.save(out / tk.name)
        files = sorted(p for p in d.iterdir() if p.is_file())
        rows.append({"name": tk.name, "kind": tk.source.get("kind"), "people": tk.people,
                     "frames": tk.num_frames, "seconds": round(tk.num_frames / fps, 4),
                     "events": [_event_json(e) for e in tk.events],
                     "files": [{"path": f"{tk.name}/{p.name}", "sha256": _sha256(p)} for p in files]})
    manifest = {"format": "crowdweave-takes", "version": TAKE_VERSION, "seed": int(seed), "fps": float(fps),
                "kinds": list(kinds), "repeat": int(repeat), "takes": rows}
    atomic_write_bytes(out / "takes.json", _json_bytes(manifest))
    return manifest


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# ------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------
def load_take(directory) -> Take:
    """Read a take directory written by :meth:`Take.save`. Raises :class:`TakeError`
    naming the file and the problem."""
    from authoring.bvh import BVHError, read_bvh

    d = Path(directory)
    mf = d / "take.json"
    if not mf.is_file():
        raise TakeError(d, "not a take directory (no take.json)")
    try:
        m = json.loads(mf.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise TakeError(mf, f"cannot read JSON ({e})") from None
    if not isinstance(m, dict) or m.get("format") != TAKE_FORMAT:
        raise TakeError(mf, f"not a crowdweave take manifest (format {m.get('format') if isinstance(m, dict) else None!r})")
    if m.get("version") != TAKE_VERSION:
        raise TakeError(mf, f"take version {m.get('version')!r}, this build reads {TAKE_VERSION}")
    try:
        fps = float(m["fps"])
        frames = int(m["frames"])
        people = m["people"]
        if not isinstance(people, list) or not people:
            raise TakeError(mf, "'people' must be a non-empty list")
    except (KeyError, TypeError, ValueError) as e:
        raise TakeError(mf, f"missing or bad field ({e})") from None
    clips, names, segs = [], [], []
    for i, p in enumerate(people):
        try:
            name, bvh = str(p["name"]), d / str(p["bvh"])
        except (KeyError, TypeError):
            raise TakeError(mf, f"people[{i}] needs 'name' and 'bvh'") from None
        if not bvh.is_file():
            raise TakeError(bvh, f"BVH file of performer {name!r} is missing")
        try:
            mo = read_bvh(bvh, drop_first_frame=False)
        except BVHError:
            raise
        c = mo.clip
        if c.num_frames != frames:
            raise TakeError(bvh, f"{c.num_frames} frames, take.json says {frames}")
        if abs(c.fps - fps) > 1e-6 * fps:
            raise TakeError(bvh, f"{c.fps:g} fps, take.json says {fps:g}")
        c = c.copy(fps=fps)
        seg = [(0, frames, "unlabelled")]
        lab = d / str(p.get("labels", f"{name}.labels.json"))
        if lab.is_file():
            try:
                seg = [(int(a), int(b), str(x)) for a, b, x in json.loads(lab.read_text(encoding="utf-8"))["segments"]]
            except (OSError, ValueError, KeyError, TypeError) as e:
                raise TakeError(lab, f"bad label sidecar ({e})") from None
        clips.append(c)
        names.append(name)
        segs.append(seg)
    events = m.get("events", [])
    for k, e in enumerate(events):
        try:
            ok = all(0 <= int(q) < len(clips) for q in e["people"]) and 0 <= int(e["start"]) <= int(e["end"]) < frames
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise TakeError(mf, f"events[{k}] is malformed or out of range")
    try:
        return Take(str(m.get("name", d.name)), fps, names, clips, segs, [_event_json(e) for e in events],
                    list(m.get("props", [])), tuple(m.get("labels", [])), dict(m.get("source", {})))
    except ValueError as e:
        raise TakeError(mf, str(e)) from None


def find_take_dirs(path) -> list[Path]:
    """Take directories under ``path``: itself if it holds take.json, else its immediate
    sub-directories that do (sorted by name)."""
    p = Path(path)
    if not p.exists():
        raise TakeError(p, "no such file or directory")
    if (p / "take.json").is_file():
        return [p]
    if p.is_dir():
        subs = sorted(q for q in p.iterdir() if q.is_dir() and (q / "take.json").is_file())
        if subs:
            return subs
    raise TakeError(p, "no take.json here or in its sub-directories (write takes with "
                       "`crowdweave capture --takes`)")


def load_takes(paths, progress=None) -> list[Take]:
    """Every take under ``paths`` (take directories or directories of them, see
    :func:`find_take_dirs`); ``progress(1)`` after each."""
    out = []
    for p in paths:
        for d in find_take_dirs(p):
            out.append(load_take(d))
            if progress is not None:
                progress(1)
    return out


# ------------------------------------------------------------------------------------------
# real two-person capture
# ------------------------------------------------------------------------------------------
def import_cmu_duet(path_a, path_b, fps: float = 30.0, name: str = "salsa", people=("A_male", "B_female"),
                    label: str = "salsa") -> Take:
    """Two BVH files recorded on one clock (CMU 60_10 + 61_10: 1197 frames at 60 fps each)
    as a two-person take resampled to ``fps``. Frame ``i`` of both files is the same instant;
    the files must agree on frame count and rate. Both keep their world placement."""
    from authoring.bvh import read_bvh

    ms = [read_bvh(p, drop_first_frame=False) for p in (path_a, path_b)]
    a, b = ms
    if a.source_frames != b.source_frames:
        raise TakeError(path_b, f"{b.source_frames} frames but {Path(path_a).name} has {a.source_frames}: "
                                "not one clock")
    if abs(a.source_fps - b.source_fps) > 1e-6:
        raise TakeError(path_b, f"{b.source_fps:g} fps but {Path(path_a).name} has {a.source_fps:g}")
    clips = [ops.resample(m.clip, fps=fps) for m in ms]
    F = clips[0].num_frames
    return Take(name, float(fps), list(people), clips, [[(0, F, label)] for _ in clips], [], [], (label,),
                {"import": "bvh duet", "files": [Path(p).name for p in (path_a, path_b)],
                 "source_fps": a.source_fps, "source_frames": a.source_frames})
