"""Reading a BVH file into a runtime :class:`~runtime.motion.clip.Clip`.

The clip holds the root position in metres and joint local rotations as unit quaternions,
with the world placement of frame 0 kept in ``clip.origin``.

* **Per-joint channel order.** A joint's rotation is ``R = R_c1 R_c2 R_c3`` for its rotation
  channels listed left to right (``Zrotation Xrotation Yrotation`` is ``Rz Rx Ry``, order
  string ``"ZXY"``), the convention of :func:`runtime.motion.quat.from_euler`. CMU files mix
  ZYX and ZXY (3dsMax-friendly: ZXY on the arms only; DAZ-friendly: ZXY everywhere but the
  root). Angles are degrees and may exceed +-180 (they become quaternions). A joint may
  declare fewer than three rotation channels; the missing axes are zero.
* **Root.** Up to 6 channels, positions and rotations in any order. The root ``OFFSET`` is
  added to the root position channels (and the skeleton's root offset is then zero).
  Non-root joints with position channels are accepted; their translation is ignored and a
  note is recorded in :attr:`BVHMotion.notes`.
* **End sites** are kept in ``Skeleton.end_sites`` (scaled to metres).
* **Scale, synthetic first frame, frame rate**: by skeleton family and release
  (:mod:`.families`). ``fps=`` resamples (slerp, :func:`runtime.motion.ops.resample`) after
  dropping frame 0.
* **Foot contacts** (``clip.contacts``) are detected at the file's own rate
  (:func:`runtime.motion.contacts.clip_contacts`) before resampling, for skeletons whose leg
  joints are known; otherwise ``clip.contacts`` is None.

Problems reading the file itself (missing, unreadable) raise the usual ``OSError``; a
malformed file raises :class:`~.parse.BVHError` (:mod:`.parse`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runtime.motion import ops, quat
from runtime.motion.clip import Clip
from runtime.motion.contacts import clip_contacts, contact_summary
from runtime.motion.skeleton import Skeleton

from .families import default_scale, detect_synthetic_first_frame, snap_fps
from .parse import BVHError, Tokens, as_text, parse_frames, parse_hierarchy, parse_motion_header, split_lines

__all__ = ["BVHMotion", "read_bvh", "bvh_summary"]


@dataclass(frozen=True, eq=False)
class BVHMotion:
    """Result of :func:`read_bvh`."""
    clip: Clip                       # root position in metres, world placement in clip.origin
    channel_orders: tuple            # per joint, the rotation channel order as read ("ZYX", "ZXY", ...)
    frame_time: float                # seconds, as written in the file
    source_fps: float                # 1 / frame_time (snapped to an integer when that close)
    scale: float                     # metres per file unit that was applied
    family: str                      # skeleton family (Skeleton.family)
    fingerprint: str                 # skeleton fingerprint (joint names + topology)
    dropped_first_frame: bool
    path: str                        # file path, or the ``name`` given for text input
    source_frames: int = 0           # frames in the file (before dropping / resampling)
    notes: tuple = ()                # things accepted but not represented (ignored channels)

    @property
    def skeleton(self) -> Skeleton:
        return self.clip.skeleton


def _channel_layout(joints, n_channels):
    """Where each joint's rotation and the root's position are in a frame line.

    Returns:
        ``(rot_idx, pos_idx, orders, full_orders, notes)``: (J, 3) frame columns of each
        joint's rotation channels in file order and the 3 columns of the root position
        (``n_channels`` stands for a missing channel, read as zero), each joint's rotation
        order as declared and completed to three axes, and notes on ignored channels.
    """
    J = len(joints)
    notes = []
    rot_idx = np.full((J, 3), n_channels, dtype=np.int64)     # n_channels -> a zero column
    orders, full_orders = [], []
    pos_idx = [n_channels] * 3
    moved = []
    col = 0
    for ji, j in enumerate(joints):
        order = ""
        for kind, what in j.channels:
            if kind == "r":
                rot_idx[ji, len(order)] = col
                order += what
            elif ji == 0:
                pos_idx[what] = col
            elif j.name not in moved:
                moved.append(j.name)
            col += 1
        orders.append(order)
        full = order + "".join(a for a in "ZYX" if a not in order)
        full_orders.append(full)
    if moved:
        notes.append(f"position channels of non-root joints ignored (translation not supported): "
                     f"{', '.join(moved)}")
    return rot_idx, pos_idx, orders, full_orders, notes


def read_bvh(path_or_text, scale=None, drop_first_frame="auto", fps=None, name=None) -> BVHMotion:
    """Read a BVH file into a :class:`BVHMotion`.

    Args:
        path_or_text: a path (``str``/``PathLike``), or BVH text (``bytes``, or a ``str``
            that contains a line break or starts with ``HIERARCHY``).
        scale: metres per file unit; ``None`` chooses by skeleton family (:mod:`.families`).
        drop_first_frame: ``True``, ``False`` or ``"auto"`` (detect a synthetic T-pose/rest
            frame).
        fps: resample to this rate (slerp) after dropping; ``None`` keeps the file's rate.
        name: the label used for the file in errors and in ``BVHMotion.path`` (default: the
            path, or ``"<bvh text>"`` for text input).
    """
    if drop_first_frame not in (True, False, "auto"):
        raise ValueError(f"drop_first_frame must be True, False or 'auto', not {drop_first_frame!r}")
    if scale is not None and not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive number of metres per file unit, not {scale!r}")
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, not {fps!r}")
    label, text = as_text(path_or_text, name)

    def fail(line, reason):
        raise BVHError(label, line, reason)

    lines = split_lines(text)
    if not text.strip(" \t\r\n\ufeff"):
        fail(1, "empty file")
    tk = Tokens(lines, fail)
    joints, end_sites = parse_hierarchy(tk, fail)

    n_frames, frames_line, frame_time, i = parse_motion_header(lines, tk.next_line, fail)

    J = len(joints)
    n_channels = sum(len(j.channels) for j in joints)
    if n_channels == 0:
        fail(joints[0].line, "the hierarchy declares no channels")
    data = parse_frames(lines, i, n_frames, n_channels, frames_line, fail)

    rot_idx, pos_idx, orders, full_orders, notes = _channel_layout(joints, n_channels)

    skel0 = Skeleton(tuple(j.name for j in joints), np.array([j.parent for j in joints]),
                     np.zeros((J, 3)))
    family = skel0.family
    if scale is None:
        scale = default_scale(family)
    scale = float(scale)

    ext = np.concatenate([data, np.zeros((n_frames, 1))], axis=1)
    angles = ext[:, rot_idx]                                 # (F, J, 3)
    rot = np.empty((n_frames, J, 4))
    for order in sorted(set(full_orders)):
        sel = np.array([o == order for o in full_orders])
        rot[:, sel] = quat.from_euler(angles[:, sel], order)
    root_pos = (ext[:, pos_idx] + np.asarray(joints[0].offset)) * scale

    if drop_first_frame == "auto":
        drop = detect_synthetic_first_frame(rot)
    else:
        drop = bool(drop_first_frame)
        if drop and n_frames < 2:
            fail(frames_line, "cannot drop the first frame of a file with 1 frame")
    if drop:
        rot = rot[1:]
        root_pos = root_pos[1:]

    offsets = np.array([j.offset for j in joints], dtype=np.float64) * scale
    offsets[0] = 0.0                       # the root OFFSET is in the root position
    skel = Skeleton(skel0.names, skel0.parents, offsets,
                    tuple((e, tuple(float(x) * scale for x in o)) for e, o in end_sites))
    src_fps = snap_fps(frame_time)
    clip = Clip.from_world(skel, src_fps, root_pos, rot, keep_origin=True)
    try:
        clip = clip.copy(contacts=clip_contacts(clip))
    except ValueError:                     # no known leg joints: contacts unknown
        pass
    if fps is not None:
        clip = ops.resample(clip, fps=float(fps))
    return BVHMotion(clip=clip, channel_orders=tuple(orders), frame_time=frame_time, source_fps=src_fps,
                     scale=scale, family=family, fingerprint=skel.fingerprint, dropped_first_frame=drop,
                     path=label, source_frames=n_frames, notes=tuple(notes))


def bvh_summary(path, **read_kwargs) -> dict:
    """A JSON-ready summary of a BVH file (frames after dropping a synthetic first frame)."""
    m = read_bvh(path, **read_kwargs)
    c = m.clip
    counts: dict[str, int] = {}
    for o in m.channel_orders:
        counts[o] = counts.get(o, 0) + 1
    return {
        "path": m.path,
        "frames": c.num_frames,
        "source_frames": m.source_frames,
        "fps": c.fps,
        "source_fps": m.source_fps,
        "frame_time": m.frame_time,
        "duration": c.duration,
        "joints": c.skeleton.num_joints,
        "end_sites": len(c.skeleton.end_sites),
        "family": m.family,
        "fingerprint": m.fingerprint,
        "scale": m.scale,
        "dropped_first_frame": m.dropped_first_frame,
        "channel_orders": dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))),
        "notes": list(m.notes),
        "contacts": contact_summary(c.contacts, "detected") if c.contacts is not None else "unknown (no known leg joints)",
    }
