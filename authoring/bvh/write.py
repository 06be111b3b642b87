"""Writing a :class:`~runtime.motion.clip.Clip` as BVH text.

The root carries channels ``Xposition Yposition Zposition`` followed by its rotation
channels, every other joint its three rotation channels, each in the joint's order (default
``"ZYX"``); end sites are written; positions are divided by ``scale`` (metres per file
unit); joints are in depth-first order (the order they were read in, for skeletons that came from a BVH
file). The output is byte-for-byte deterministic and written atomically.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from runtime.assets import atomic_write_bytes
from runtime.motion import quat
from runtime.motion.clip import Clip

__all__ = ["bvh_text", "write_bvh"]


def _dfs_order(parents: np.ndarray) -> list[int]:
    """Joint indices in depth-first order from the root (children in index order)."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        children.setdefault(int(p), []).append(j)
    out, stack = [], [0]
    while stack:
        j = stack.pop()
        out.append(j)
        stack.extend(reversed(children.get(j, [])))
    return out


def _full_order(o: str) -> str:
    """A rotation order completed to three axes (``"ZX"`` -> ``"ZXY"``); raises ValueError
    on anything but distinct letters X, Y, Z."""
    o = o.upper()
    if len(set(o)) != len(o) or any(c not in "XYZ" for c in o):
        raise ValueError(f"bad channel order {o!r} (a permutation of X, Y, Z expected)")
    return o + "".join(a for a in "ZYX" if a not in o)


def bvh_text(clip: Clip, channel_orders=None, scale: float = 1.0, precision: int = 6) -> str:
    """The BVH text of ``clip`` (see :func:`write_bvh`)."""
    sk = clip.skeleton
    J = sk.num_joints
    if channel_orders is None or isinstance(channel_orders, str):
        orders = [_full_order(channel_orders or "ZYX")] * J
    else:
        orders = [_full_order(o) for o in channel_orders]
        if len(orders) != J:
            raise ValueError(f"{len(orders)} channel orders for {J} joints")
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be positive, not {scale!r}")
    precision = int(precision)
    fmt = f"%.{precision}f"
    tiny = 0.5 * 10.0 ** -precision

    def num(v):
        v = float(v)
        return fmt % (0.0 if abs(v) < tiny else v)

    order = _dfs_order(sk.parents)
    children: dict[int, list[int]] = {}
    for j in order[1:]:
        children.setdefault(int(sk.parents[j]), []).append(j)
    ends: dict[int, list] = {}
    for j, o in sk.end_sites:
        ends.setdefault(int(j), []).append(o)
    axis_name = {"X": "Xrotation", "Y": "Yrotation", "Z": "Zrotation"}
    out = ["HIERARCHY"]

    def emit(j, depth):
        ind = "\t" * depth
        out.append(f"{ind}{'ROOT' if j == 0 else 'JOINT'} {sk.names[j]}")
        out.append(f"{ind}{{")
        off = np.zeros(3) if j == 0 else sk.offsets[j] / scale
        out.append(f"{ind}\tOFFSET {num(off[0])} {num(off[1])} {num(off[2])}")
        rch = " ".join(axis_name[a] for a in orders[j])
        if j == 0:
            out.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition {rch}")
        else:
            out.append(f"{ind}\tCHANNELS 3 {rch}")
        for c in children.get(j, []):
            emit(c, depth + 1)
        for o in ends.get(j, []):
            o = np.asarray(o, dtype=np.float64) / scale
            out.append(f"{ind}\tEnd Site")
            out.append(f"{ind}\t{{")
            out.append(f"{ind}\t\tOFFSET {num(o[0])} {num(o[1])} {num(o[2])}")
            out.append(f"{ind}\t}}")
        out.append(f"{ind}}}")

    emit(0, 0)

    F = clip.num_frames
    pos, rroot = clip.world_root()
    rot = clip.rotations.astype(np.float64)
    rot[:, 0] = rroot
    rot = quat.normalize(rot)
    euler = np.empty((F, J, 3))
    for o in sorted(set(orders)):
        sel = np.array([x == o for x in orders])
        euler[:, sel] = quat.to_euler(rot[:, sel], o)
    cols = [pos / scale] + [euler[:, j] for j in order]
    values = np.concatenate(cols, axis=1)
    values = np.where(np.abs(values) < tiny, 0.0, values)
    row = " ".join([fmt] * values.shape[1])
    out.append("MOTION")
    out.append(f"Frames: {F}")
    out.append(f"Frame Time: {1.0 / clip.fps:.10f}")
    out.extend(row % tuple(r) for r in values.tolist())
    return "\n".join(out) + "\n"


def write_bvh(path, clip: Clip, channel_orders=None, scale: float = 1.0, precision: int = 6) -> Path:
    """Write ``clip`` as BVH, atomically.

    The root carries the clip's world placement (``clip.origin``) in channels ``Xposition
    Yposition Zposition``, followed by rotation channels in each joint's order
    (``channel_orders``: one order string for all joints, or one per joint in skeleton
    order; default ``"ZYX"``; orders shorter than 3 letters are completed with the missing
    axes). Positions and offsets are divided by ``scale`` (metres per file unit), values
    are written with ``precision`` decimals; the output is deterministic byte for byte.
    """
    path = Path(path)
    atomic_write_bytes(path, bvh_text(clip, channel_orders, scale, precision).encode("utf-8"))
    return path
