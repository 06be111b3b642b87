"""Loading takes for the graph builder: take directories (procedural capture) and BVH files.

A take directory holds ``*.bvh`` files with ``<stem>.labels.json`` sidecars
(``{"fps": .., "frames": .., "segments": [[start, end_exclusive, label], ...]}``, frames at
the BVH's own rate; an optional ``"contacts": {point: [[start, end_exclusive], ...]}`` gives the
foot contacts, else they are the ones detected when the BVH was read). A BVH file gets its labels from ``labels`` (a sidecar path, or a single
label for every frame), else from a sidecar beside it, else they are derived from the motion
(:mod:`.derive`; ``labels="derive"`` asks for that even beside a sidecar). Derived labels
also say which frames are not flat-ground walking: the file is cut into the runs of usable
frames, one take each, named ``<stem>[a:b]`` (frames ``a`` to ``b`` exclusive at the graph
rate). ``mirror=True`` adds every take mirrored left to right (``<name> mirrored``): a left
turn becomes a right turn. :func:`load_sources` also returns, per file, what it gave and
which takes came from it, for the build report (:mod:`.report`).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from runtime.motion import SkeletonMismatchError, ops
from runtime.motion.contacts import CONTACT_POINTS

from ..bvh import read_bvh
from .build import SourceClip
from .derive import DeriveParams, derive_labels, usable_runs

__all__ = ["load_takes", "load_sources", "read_labels", "read_contacts", "LabelError", "SourceFile", "DERIVE"]

DERIVE = "derive"     # the ``labels`` value that derives labels from the motion


@dataclass
class SourceFile:
    """One input file: its frames at the graph rate, their labels, and the takes cut from it
    (take name -> first frame in the file, mirrored copies included)."""
    path: str
    fps: float
    labels: list[str]
    derived: bool
    takes: dict = field(default_factory=dict)
    mirrored: set = field(default_factory=set)

    @property
    def frames(self) -> int:
        return len(self.labels)


class LabelError(ValueError):
    pass


def read_labels(path, n_frames_src: int) -> list[str]:
    """Per-frame labels (at the source rate) from a sidecar JSON."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
        segs = d["segments"]
    except FileNotFoundError:
        raise LabelError(f"{path}: label file not found") from None
    except (ValueError, KeyError, TypeError) as e:
        raise LabelError(f"{path}: not a label sidecar ({type(e).__name__}: {e})") from None
    out = [None] * n_frames_src
    for k, seg in enumerate(segs):
        try:
            s, e, lab = int(seg[0]), int(seg[1]), str(seg[2])
        except (ValueError, TypeError, IndexError):
            raise LabelError(f"{path}: segment {k} is not [start, end, label]") from None
        if not (0 <= s < e <= n_frames_src):
            raise LabelError(f"{path}: segment {k} [{s}, {e}) outside 0..{n_frames_src}")
        out[s:e] = [lab] * (e - s)
    missing = [i for i, x in enumerate(out) if x is None]
    if missing:
        raise LabelError(f"{path}: frames {missing[0]}..{missing[-1]} have no label ({len(missing)} frames)")
    return out


def read_contacts(path, n_frames_src: int) -> np.ndarray | None:
    """Contacts ``(n_frames_src, 4)`` bool from a sidecar's ``"contacts"`` runs (source rate),
    or None when it has none."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise LabelError(f"{path}: not a label sidecar ({type(e).__name__}: {e})") from None
    runs_ = d.get("contacts") if isinstance(d, dict) else None
    if runs_ is None:
        return None
    if not isinstance(runs_, dict) or set(runs_) != set(CONTACT_POINTS):
        raise LabelError(f"{path}: contacts must map each of {', '.join(CONTACT_POINTS)} to [[start, end], ...]")
    out = np.zeros((n_frames_src, len(CONTACT_POINTS)), dtype=bool)
    for k, name in enumerate(CONTACT_POINTS):
        for j, run in enumerate(runs_[name]):
            try:
                s, e = int(run[0]), int(run[1])
            except (ValueError, TypeError, IndexError):
                raise LabelError(f"{path}: contacts {name} run {j} is not [start, end]") from None
            if not (0 <= s < e <= n_frames_src):
                raise LabelError(f"{path}: contacts {name} run {j} [{s}, {e}) outside 0..{n_frames_src}")
            out[s:e, k] = True
    return out


def _resample_labels(labels: list[str], src_fps: float, n_out: int, dst_fps: float, offset: int) -> list[str]:
    idx = np.clip(np.round(np.arange(n_out) * src_fps / dst_fps).astype(np.int64) + offset, 0, len(labels) - 1)
    return [labels[i] for i in idx]


def _file_takes(m, path: Path, fps: float, labels_arg, sidecar: Path | None, derive: DeriveParams | None):
    """(takes, SourceFile) of one BVH file read into ``m``."""
    n = m.clip.num_frames
    offset = 1 if m.dropped_first_frame else 0
    src = None
    if labels_arg is not None and labels_arg != DERIVE and Path(labels_arg).suffix == ".json":
        src = read_labels(labels_arg, m.source_frames)
    elif labels_arg is not None and labels_arg != DERIVE:
        src = [str(labels_arg)] * m.source_frames
    elif labels_arg is None and sidecar is not None and sidecar.exists():
        src = read_labels(sidecar, m.source_frames)
        contacts = read_contacts(sidecar, m.source_frames)
        if contacts is not None:
            idx = np.clip(np.round(np.arange(n) * m.source_fps / fps).astype(np.int64) + offset, 0, len(contacts) - 1)
            m = replace(m, clip=m.clip.copy(contacts=contacts[idx]))
    if src is not None:
        labs = _resample_labels(src, m.source_fps, n, fps, offset)
        info = SourceFile(str(path), fps, labs, derived=False, takes={path.stem: 0})
        return [SourceClip(path.stem, m.clip, labs, str(path))], info
    try:
        labs = derive_labels(m.clip, derive)
    except ValueError as e:
        raise LabelError(f"{path}: cannot derive labels from the motion ({e}); give --labels") from None
    info = SourceFile(str(path), fps, labs, derived=True)
    takes = []
    for a, b in usable_runs(labs):
        if b - a < 2:
            continue
        name = f"{path.stem}[{a}:{b}]"
        info.takes[name] = a
        takes.append(SourceClip(name, ops.cut(m.clip, a, b), labs[a:b], str(path)))
    return takes, info


def load_takes(inputs, fps: float = 30.0, scale=None, labels=None, progress=None, mirror: bool = False,
               derive: DeriveParams | None = None) -> list[SourceClip]:
    """Takes from directories and BVH files, all resampled to ``fps`` (see the module
    docstring). Raises SkeletonMismatchError naming both files when families differ."""
    return load_sources(inputs, fps, scale, labels, progress, mirror, derive)[0]


def load_sources(inputs, fps: float = 30.0, scale=None, labels=None, progress=None, mirror: bool = False,
                 derive: DeriveParams | None = None) -> tuple[list[SourceClip], list[SourceFile]]:
    """(takes, files): :func:`load_takes` and, per input file, a :class:`SourceFile`."""
    files: list[Path] = []
    for inp in inputs:
        p = Path(inp)
        if p.is_dir():
            found = sorted(p.glob("*.bvh"))
            if not found:
                raise FileNotFoundError(f"{p}: no .bvh files in this directory")
            files.extend(found)
        elif p.exists():
            files.append(p)
        else:
            raise FileNotFoundError(f"{p}: no such file or directory")
    takes, infos = [], []
    first = None
    for f in files:
        m = read_bvh(f, scale=scale, fps=fps)
        if first is None:
            first = (f, m.clip.skeleton)
        elif not m.clip.skeleton.same_family(first[1]):
            raise SkeletonMismatchError(
                f"skeleton family mismatch: {f} has family {m.clip.skeleton.family!r} but "
                f"{first[0]} has {first[1].family!r}; retarget before mixing")
        ts, info = _file_takes(m, f, fps, labels, f.with_suffix(".labels.json"), derive)
        takes.extend(ts)
        if mirror:
            for t in ts:
                name = f"{t.name} mirrored"
                info.takes[name] = info.takes[t.name]
                info.mirrored.add(name)
                takes.append(SourceClip(name, ops.mirror(t.clip), list(t.labels), t.path))
        infos.append(info)
        if progress:
            progress(1)
    return takes, infos
