"""Loading takes for the graph builder: take directories (procedural capture) and BVH files.

A take directory holds ``*.bvh`` files with ``<stem>.labels.json`` sidecars
(``{"fps": .., "frames": .., "segments": [[start, end_exclusive, label], ...]}``, frames at
the BVH's own rate). A BVH file gets its labels from ``--labels`` (a sidecar path or a
single label for every frame), else from a sidecar beside it, else ``"walk"``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from runtime.motion import SkeletonMismatchError

from ..bvh import read_bvh
from .build import SourceClip

__all__ = ["load_takes", "read_labels", "LabelError"]


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


def _resample_labels(labels: list[str], src_fps: float, n_out: int, dst_fps: float, offset: int) -> list[str]:
    idx = np.clip(np.round(np.arange(n_out) * src_fps / dst_fps).astype(np.int64) + offset, 0, len(labels) - 1)
    return [labels[i] for i in idx]


def _take_from_bvh(path: Path, fps: float, scale, labels_arg, sidecar: Path | None) -> SourceClip:
    m = read_bvh(path, scale=scale, fps=fps)
    n = m.clip.num_frames
    offset = 1 if m.dropped_first_frame else 0
    if labels_arg is not None and Path(labels_arg).suffix == ".json":
        src = read_labels(labels_arg, m.source_frames)
    elif labels_arg is not None:
        src = [str(labels_arg)] * m.source_frames
    elif sidecar is not None and sidecar.exists():
        src = read_labels(sidecar, m.source_frames)
    else:
        src = ["walk"] * m.source_frames
    return SourceClip(path.stem, m.clip, _resample_labels(src, m.source_fps, n, fps, offset), str(path))


def load_takes(inputs, fps: float = 30.0, scale=None, labels=None, progress=None) -> list[SourceClip]:
    """Takes from directories and BVH files, all resampled to ``fps``. Raises
    SkeletonMismatchError naming both files when families differ."""
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
    takes = []
    for f in files:
        t = _take_from_bvh(f, fps, scale, labels, f.with_suffix(".labels.json"))
        if takes and not t.clip.skeleton.same_family(takes[0].clip.skeleton):
            raise SkeletonMismatchError(
                f"skeleton family mismatch: {f} has family {t.clip.skeleton.family!r} but "
                f"{takes[0].path} has {takes[0].clip.skeleton.family!r}; retarget before mixing")
        takes.append(t)
        if progress:
            progress(1)
    return takes
