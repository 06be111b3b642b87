"""Pure functions on clips: cut, sample, resample, append (root-aligned), mirror, reverse.

Each returns a new :class:`Clip`; inputs are never modified. Contact flags (``Clip.contacts``)
travel with their frames: cut and reversed with them, resampled to the nearest source frame,
concatenated, and swapped left for right by :func:`mirror`; a clip without contacts gives a
clip without contacts (:func:`append` of a clip with and one without drops them).
"""
from __future__ import annotations

import numpy as np

from . import quat
from .clip import Clip
from .planar import rotate_xz

__all__ = ["cut", "sample", "sample_contacts", "resample", "append", "mirror", "reverse", "MIRROR_CONTACTS"]

MIRROR_CONTACTS = np.array([2, 3, 0, 1])   # CONTACT_POINTS columns after a left-right mirror


def cut(clip: Clip, start: int, stop: int | None = None) -> Clip:
    """Frames ``[start, stop)``, re-based so the new first frame is the local origin.
    World placement is preserved through ``origin``."""
    n = clip.num_frames
    stop = n if stop is None else stop
    start = start + n if start < 0 else start
    stop = stop + n if stop < 0 else stop
    if not (0 <= start < stop <= n):
        raise IndexError(f"cut [{start}, {stop}) outside a clip of {n} frames")
    sub = clip.copy(root_xz=clip.root_xz[start:stop], root_heading=clip.root_heading[start:stop],
                    root_height=clip.root_height[start:stop], rotations=clip.rotations[start:stop],
                    contacts=None if clip.contacts is None else clip.contacts[start:stop])
    # sub's frame 0 is at clip's local (xz, heading)[start]: fold that into the origin
    xz0 = clip.root_xz[start]
    h0 = clip.root_heading[start]
    o = clip.origin
    new_xz = rotate_xz(xz0[None], o[2])[0] + o[:2]
    return sub.copy(root_xz=rotate_xz(sub.root_xz - xz0, -h0), root_heading=sub.root_heading - h0,
                    origin=np.array([new_xz[0], new_xz[1], o[2] + h0]))


def sample(clip: Clip, frames: np.ndarray):
    """Evaluate the clip at fractional frame positions (clamped to the clip).

    Returns (root_xz (N, 2), root_heading (N,), root_height (N,), rotations (N, J, 4) float64).
    Root channels interpolate linearly (heading is unwrapped), rotations by slerp.
    """
    f = np.clip(np.asarray(frames, dtype=np.float64), 0.0, clip.num_frames - 1)
    i0 = np.floor(f).astype(np.int64)
    i1 = np.minimum(i0 + 1, clip.num_frames - 1)
    t = f - i0
    xz = clip.root_xz[i0] * (1 - t)[:, None] + clip.root_xz[i1] * t[:, None]
    h = clip.root_heading[i0] * (1 - t) + clip.root_heading[i1] * t
    y = clip.root_height[i0] * (1 - t) + clip.root_height[i1] * t
    r0 = clip.rotations[i0].astype(np.float64)
    r1 = clip.rotations[i1].astype(np.float64)
    rot = quat.slerp(r0, r1, np.broadcast_to(t[:, None], r0.shape[:-1]))
    return xz, h, y, rot


def resample(clip: Clip, fps: float | None = None, num_frames: int | None = None) -> Clip:
    """Resample to a new rate (keeping the duration) or to an exact frame count (stretching
    time so the first and last frames are kept)."""
    if num_frames is None:
        if fps is None:
            raise ValueError("give fps or num_frames")
        if abs(fps - clip.fps) < 1e-9:
            return clip
        num_frames = int(np.floor(clip.duration * fps + 1e-6)) + 1
        src = np.arange(num_frames) * (clip.fps / fps)
        new_fps = fps
    else:
        if num_frames < 2:
            raise ValueError("num_frames must be >= 2")
        src = np.linspace(0.0, clip.num_frames - 1, num_frames)
        new_fps = clip.fps if fps is None else fps
    xz, h, y, rot = sample(clip, src)
    rot = quat.unroll(rot, axis=0)
    return clip.copy(fps=float(new_fps), root_xz=xz, root_heading=h, root_height=y,
                     rotations=rot.astype(np.float32), contacts=sample_contacts(clip.contacts, src))


def sample_contacts(contacts: np.ndarray | None, frames: np.ndarray) -> np.ndarray | None:
    """Contact flags at fractional frame positions: those of the nearest frame (None stays
    None)."""
    if contacts is None:
        return None
    idx = np.clip(np.rint(np.asarray(frames, dtype=np.float64)).astype(np.int64), 0, len(contacts) - 1)
    return contacts[idx]


def append(a: Clip, b: Clip, shared_frame: bool = True) -> Clip:
    """Concatenate ``b`` after ``a`` with root alignment.

    ``b``'s first frame is placed at ``a``'s last frame position and heading (the join
    frame). With ``shared_frame`` (snap-together clips that both contain the join pose) the
    duplicate is dropped; otherwise ``b`` starts one frame later, continuing ``a``'s last
    root velocity.
    """
    if not a.skeleton.same_family(b.skeleton):
        raise ValueError("cannot append clips of different skeleton families")
    if abs(a.fps - b.fps) > 1e-9:
        raise ValueError(f"fps differ ({a.fps} vs {b.fps}); resample first")
    end_xz = a.root_xz[-1]
    end_h = a.root_heading[-1]
    if not shared_frame:
        step = a.root_xz[-1] - a.root_xz[-2] if a.num_frames > 1 else np.zeros(2)
        dh = a.root_heading[-1] - a.root_heading[-2] if a.num_frames > 1 else 0.0
        end_xz = end_xz + step
        end_h = end_h + dh
    bxz = rotate_xz(b.root_xz, end_h) + end_xz
    bh = b.root_heading + end_h
    s = 1 if shared_frame else 0
    contacts = None
    if a.contacts is not None and b.contacts is not None:
        contacts = np.concatenate([a.contacts, b.contacts[s:]])
    return a.copy(contacts=contacts,
        root_xz=np.concatenate([a.root_xz, bxz[s:]]),
        root_heading=np.concatenate([a.root_heading, bh[s:]]),
        root_height=np.concatenate([a.root_height, b.root_height[s:]]),
        rotations=np.concatenate([a.rotations, b.rotations[s:]]),
    )


def mirror(clip: Clip) -> Clip:
    """Mirror left/right across the character's sagittal plane (x -> -x).

    Joint rotations are reflected, ``(w, x, y, z) -> (w, x, -y, -z)``, and swapped with their
    left/right counterpart; the root path mirrors (x -> -x, heading -> -heading); contact
    columns swap left for right. Assumes a left/right symmetric rest skeleton.
    """
    m = clip.skeleton.mirror_map()
    rot = clip.rotations[:, m].copy()
    rot[..., 2] *= -1
    rot[..., 3] *= -1
    xz = clip.root_xz.copy()
    xz[:, 0] *= -1
    o = clip.origin.copy()
    o[2] = -o[2]
    o[0] = -o[0]
    contacts = None if clip.contacts is None else clip.contacts[:, MIRROR_CONTACTS]
    return clip.copy(root_xz=xz, root_heading=-clip.root_heading, rotations=rot, origin=o, contacts=contacts)


def reverse(clip: Clip) -> Clip:
    """Play backwards (the backward seed planner's time reversal). The reversed clip's first
    frame is the original's last, at the same world placement."""
    rev = clip.copy(root_xz=clip.root_xz[::-1], root_heading=clip.root_heading[::-1],
                    root_height=clip.root_height[::-1], rotations=clip.rotations[::-1],
                     contacts=None if clip.contacts is None else clip.contacts[::-1])
    return cut(rev, 0)
