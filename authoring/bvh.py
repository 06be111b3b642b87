"""BVH (Biovision Hierarchy) motion capture import and export.

Reading turns a ``.bvh`` file into a runtime :class:`~runtime.motion.clip.Clip` (root
position in metres, joint local rotations as unit quaternions, world placement of frame 0
kept in ``clip.origin``); writing does the reverse. No paper equation is implemented here;
the format follows the Biovision description as written by the CMU/cgspeed releases
(../shared/mocap/cmu/README.md lists their quirks, all handled here):

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
* **Text.** CRLF, LF, CR and mixed line endings; tabs; trailing spaces; a UTF-8 BOM; numbers
  such as ``.0083333``, ``-5.``, ``1e-3``; ``Frames:``/``Frame Time:`` with any spacing.
  Blank lines in the frame block are ignored. Any number whose magnitude exceeds
  ``MAX_ABS_VALUE`` (1e9 degrees, file units or seconds) is rejected as corrupt.
* **Scale** (metres per file unit). ``scale=None`` picks it from the skeleton family
  (:attr:`Skeleton.family`, joint names + topology):

  ============  ==========  =====================================================
  family        scale       why
  ============  ==========  =====================================================
  cmu-mb        0.05644     CMU units, "inches x 0.45" (1 / 0.45 in = 0.05644 m)
  cmu-3dsmax    0.05644     CMU units
  cmu-daz       0.01        DAZ/Poser figure, roughly centimetres
  anything else 1.0         file assumed to be in metres (crowdweave's own exports)
  ============  ==========  =====================================================

* **Synthetic first frame.** cgspeed MotionBuilder-friendly and DAZ-friendly files start
  with a hand-made T-pose / rest pose. ``drop_first_frame="auto"`` drops frame 0 when its
  largest joint-rotation change to frame 1 is more than 5 degrees *and* more than 3 times
  the 99th percentile of the same quantity (largest per-joint change) over all later frame
  pairs. ``True``/``False`` force it. Measured on the 11 CMU files (ratio of frame 0's jump
  to that percentile): the four files with a synthetic frame give 12.4, 16.2 (T-poses) and
  6.6, 5.6 (DAZ rest poses), the seven others at most 1.6, so 3 sits about 2x from both
  sides. (A ratio of 8 would miss the DAZ files: their rest pose blends into the motion
  over frames 1-4, whose 35-40 degree steps raise the percentile.)
* **Frame rate.** ``source_fps = 1 / Frame Time``, snapped to the nearest integer when
  within 0.01 % (``.0083333`` -> 120, ``0.0166667`` -> 60; 29.97 stays 29.97). ``fps=``
  resamples (slerp, :func:`runtime.motion.ops.resample`) after dropping frame 0.

Errors in the file raise :class:`BVHError` whose message reads ``"path:LINE: what is
wrong"``. When several things are wrong the first one in the hierarchy is reported; in the
frame block the first bad frame line, and a frame count that falls short of ``Frames:`` is
reported (at the ``Frames:`` line) only when every present frame line is well formed.
Problems reading the file itself (missing, unreadable) raise the usual ``OSError``.

The frame block is parsed in one go with numpy (one ``str.split`` per line, one vectorized
float conversion); a 2 MB file loads in about 0.2 s.

Writing (:func:`write_bvh`, :func:`bvh_text`) emits root channels ``Xposition Yposition
Zposition`` followed by the rotation channels in each joint's order (default ``"ZYX"``),
end sites, positions divided by ``scale``, joints in depth-first order (the order they were
read in, for skeletons that came from a BVH file); the output is byte-for-byte
deterministic and written atomically.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from itertools import chain
from pathlib import Path

import numpy as np

from runtime.assets import atomic_write_bytes
from runtime.motion import ops, quat
from runtime.motion.clip import Clip
from runtime.motion.skeleton import Skeleton

__all__ = ["BVHError", "BVHMotion", "read_bvh", "write_bvh", "bvh_text", "bvh_summary",
           "FAMILY_SCALES", "default_scale"]

#: metres per file unit for the known skeleton families (see the module docstring).
FAMILY_SCALES: dict[str, float] = {"cmu-mb": 0.05644, "cmu-3dsmax": 0.05644, "cmu-daz": 0.01}

# Synthetic-first-frame detector thresholds (module docstring).
T0_MIN_DEGREES = 5.0
T0_RATIO = 3.0
# Snap 1 / frame_time to an integer rate when the relative difference is below this.
_FPS_SNAP_REL = 1e-4
# Largest magnitude accepted for any number in a file (degrees, file units, seconds): values
# beyond it are corrupt data, and refusing them keeps every later computation finite.
MAX_ABS_VALUE = 1e9

_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[0-9]+")
_NOT_NUMERIC_CHAR = re.compile(r"[^0-9eE.+\-\s]")
_FRAMES_LINE = re.compile(r"frames\s*:\s*(\S*)", re.IGNORECASE)
_FRAME_TIME_LINE = re.compile(r"frame\s*time\s*:\s*(\S*)", re.IGNORECASE)
_CHANNELS = {
    "xposition": ("p", 0), "yposition": ("p", 1), "zposition": ("p", 2),
    "xrotation": ("r", "X"), "yrotation": ("r", "Y"), "zrotation": ("r", "Z"),
}


def default_scale(family: str) -> float:
    """Metres per file unit for a skeleton family (1.0 for families not listed)."""
    return FAMILY_SCALES.get(family, 1.0)


class BVHError(ValueError):
    """A malformed BVH file. ``str(e)`` is ``"path:LINE: what is wrong"``."""

    def __init__(self, path, line: int, reason: str):
        self.path = str(path)
        self.line = int(line)
        self.reason = reason
        super().__init__(f"{self.path}:{self.line}: {reason}")


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


# --------------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------------
class _Tokens:
    """Whitespace tokens of a list of lines, produced lazily (the hierarchy is small; the
    frame block is never tokenised here)."""

    def __init__(self, lines, fail):
        self.lines = lines
        self.fail = fail
        self.next_line = 0          # index of the next line to read
        self.toks: list[str] = []
        self.k = 0
        self.lineno = 0             # 1-based line of the tokens in self.toks

    def _fill(self) -> bool:
        while self.k >= len(self.toks):
            if self.next_line >= len(self.lines):
                return False
            self.toks = self.lines[self.next_line].split()
            self.k = 0
            self.next_line += 1
            self.lineno = self.next_line
        return True

    def eof_line(self) -> int:
        return max(1, len(self.lines))

    def next(self, what: str):
        if not self._fill():
            self.fail(self.eof_line(), f"unexpected end of file in the hierarchy (expected {what})")
        t = self.toks[self.k]
        self.k += 1
        return t, self.lineno

    def rest_of_line(self) -> list[str]:
        rest = self.toks[self.k:]
        self.k = len(self.toks)
        return rest


def _as_text(path_or_text, name):
    """(label, text) from a path, a str holding BVH text, or bytes holding BVH text."""
    if isinstance(path_or_text, (bytes, bytearray, memoryview)):
        return (name or "<bvh text>"), _decode(bytes(path_or_text), name or "<bvh text>")
    if isinstance(path_or_text, str):
        head = path_or_text.lstrip("\ufeff \t\r\n")
        if "\n" in path_or_text or "\r" in path_or_text or not head or head[:9].upper() == "HIERARCHY":
            return (name or "<bvh text>"), path_or_text
    p = Path(os.fspath(path_or_text))
    label = name or str(p)
    return label, _decode(p.read_bytes(), label)


def _decode(data: bytes, label: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        head = data[:e.start].replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        line = head.count(b"\n") + 1
        raise BVHError(label, line, f"not UTF-8 text (byte 0x{data[e.start]:02x})") from None


def _split_lines(text: str) -> list[str]:
    if text.startswith("\ufeff"):
        text = text[1:]
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return lines


class _Joint:
    __slots__ = ("name", "parent", "offset", "channels", "line")

    def __init__(self, name, parent, line):
        self.name = name
        self.parent = parent
        self.offset = (0.0, 0.0, 0.0)
        self.channels: list[tuple[str, object]] = []
        self.line = line


def _parse_number(tok: str, line: int, what: str, fail) -> float:
    if not _NUMBER.fullmatch(tok):
        fail(line, f"{what}: {tok!r} is not a number")
    v = float(tok)
    if not abs(v) <= MAX_ABS_VALUE:
        fail(line, f"{what}: {tok!r} is out of range (|value| > {MAX_ABS_VALUE:g})")
    return v


def _parse_hierarchy(tk: _Tokens, fail):
    """Returns (joints, end_sites) and leaves ``tk`` after the root's closing brace."""
    tok, line = tk.next("HIERARCHY")
    if tok.upper() != "HIERARCHY":
        fail(line, f"expected HIERARCHY, found {tok!r}")
    tok, line = tk.next("ROOT")
    if tok.upper() != "ROOT":
        fail(line, f"expected ROOT, found {tok!r}")
    joints: list[_Joint] = []
    end_sites: list[tuple[int, tuple[float, float, float]]] = []
    names: dict[str, int] = {}

    def offset(what):
        tok, line = tk.next("OFFSET")
        if tok.upper() != "OFFSET":
            fail(line, f"expected OFFSET in {what}, found {tok!r}")
        vals = []
        for _ in range(3):
            t, ln = tk.next("an OFFSET value")
            vals.append(_parse_number(t, ln, f"OFFSET of {what}", fail))
        return tuple(vals)

    def open_joint(keyword_line, parent):
        rest = tk.rest_of_line()
        brace = bool(rest) and rest[-1] == "{"
        if brace:
            rest = rest[:-1]
        if not rest:
            fail(keyword_line, "joint has no name")
        name = " ".join(rest)
        if name in names:
            fail(keyword_line, f"duplicate joint name {name!r} (first at line {joints[names[name]].line})")
        if not brace:
            t, ln = tk.next("'{'")
            if t != "{":
                fail(ln, f"expected '{{' after joint {name!r}, found {t!r}")
        j = _Joint(name, parent, keyword_line)
        j.offset = offset(f"joint {name!r}")
        t, ln = tk.next("CHANNELS")
        if t.upper() != "CHANNELS":
            fail(ln, f"expected CHANNELS in joint {name!r}, found {t!r}")
        t, ln = tk.next("the channel count")
        if not _INTEGER.fullmatch(t) or int(t) > 6:
            fail(ln, f"channel count of joint {name!r} must be an integer 0..6, found {t!r}")
        seen = {}
        for _ in range(int(t)):
            c, ln = tk.next("a channel name")
            kind = _CHANNELS.get(c.lower())
            if kind is None:
                fail(ln, f"unknown channel name {c!r} in joint {name!r}")
            if kind in seen:
                fail(ln, f"channel {c!r} appears twice in joint {name!r}")
            seen[kind] = ln
            j.channels.append(kind)
        names[name] = len(joints)
        joints.append(j)
        return len(joints) - 1

    stack = [open_joint(line, -1)]
    while stack:
        tok, line = tk.next("JOINT, End Site or '}'")
        up = tok.upper()
        if up == "JOINT":
            stack.append(open_joint(line, stack[-1]))
        elif up == "END":
            t, ln = tk.next("Site")
            if t.upper() != "SITE":
                fail(ln, f"expected 'End Site', found 'End {t}'")
            t, ln = tk.next("'{'")
            if t != "{":
                fail(ln, f"expected '{{' after End Site, found {t!r}")
            off = offset(f"End Site of {joints[stack[-1]].name!r}")
            t, ln = tk.next("'}'")
            if t != "}":
                fail(ln, f"expected '}}' to close End Site, found {t!r}")
            end_sites.append((stack[-1], off))
        elif tok == "}":
            stack.pop()
        elif up == "ROOT":
            fail(line, "ROOT inside the hierarchy (only one root is supported)")
        else:
            fail(line, f"expected JOINT, End Site or '}}', found {tok!r}")
    extra = tk.rest_of_line()
    if extra:
        fail(tk.lineno, f"unexpected {extra[0]!r} after the end of the hierarchy")
    return joints, end_sites


def _parse_frames(lines, start, n_frames, n_channels, frames_line, fail) -> np.ndarray:
    """The frame block ``lines[start:]`` as an (n_frames, n_channels) float64 array."""
    rest = lines[start:]
    toks = [ln.split() for ln in rest]
    counts = np.fromiter(map(len, toks), dtype=np.int64, count=len(toks))
    data_idx = np.flatnonzero(counts)              # blank lines are ignored
    problems: list[tuple[int, str]] = []
    if len(data_idx) > n_frames:
        problems.append((start + 1 + int(data_idx[n_frames]), 2,
                         f"more frame lines than the {n_frames} declared by Frames: (line {frames_line})"))
    used = data_idx[:n_frames]
    bad_count = used[counts[used] != n_channels]
    if len(bad_count):
        i = int(bad_count[0])
        problems.append((start + 1 + i, 0, f"expected {n_channels} values on a frame line, found {int(counts[i])}"))
    block = "\n".join(rest)
    m = _NOT_NUMERIC_CHAR.search(block)
    if m:
        i = block.count("\n", 0, m.start())
        tok = next(t for t in toks[i] if _NOT_NUMERIC_CHAR.search(t))
        problems.append((start + 1 + i, 1, f"{tok!r} is not a number"))
    if problems:                                     # the first bad line; on it, a wrong count first
        line, _, reason = min(problems)
        fail(line, reason)
    if len(data_idx) < n_frames:
        fail(frames_line, f"Frames: declares {n_frames} frames but the file has {len(data_idx)} frame lines")
    flat = list(chain.from_iterable(toks[i] for i in used)) if len(used) != len(toks) \
        else list(chain.from_iterable(toks))
    try:
        values = np.array(flat, dtype=np.float64)
    except ValueError:
        for i in used:
            for t in toks[i]:
                if not _NUMBER.fullmatch(t):
                    fail(start + 1 + int(i), f"{t!r} is not a number")
        raise  # pragma: no cover - unreachable: every token matched the number grammar
    values = values.reshape(n_frames, n_channels)
    ok = np.abs(values) <= MAX_ABS_VALUE          # also False for inf (nan cannot be spelled)
    if not ok.all():
        r = int(np.argmax(~ok.all(axis=1)))
        c = int(np.argmax(~ok[r]))
        fail(start + 1 + int(used[r]), f"{toks[int(used[r])][c]!r} is out of range (|value| > {MAX_ABS_VALUE:g})")
    return values


def _snap_fps(frame_time: float) -> float:
    fps = 1.0 / frame_time
    r = round(fps)
    if r >= 1 and abs(fps - r) <= _FPS_SNAP_REL * r:
        return float(r)
    return fps


def _detect_synthetic_first_frame(rot: np.ndarray) -> bool:
    """Frame 0 is synthetic if its largest joint-rotation change to frame 1 is far above the
    typical frame-to-frame change (thresholds T0_MIN_DEGREES, T0_RATIO)."""
    if len(rot) < 3:
        return False
    step = np.degrees(quat.angle(rot[:-1], rot[1:])).max(axis=1)   # (F-1,) largest per-joint change
    first = step[0]
    typical = np.percentile(step[1:], 99)
    return bool(first > T0_MIN_DEGREES and first > T0_RATIO * typical)


def read_bvh(path_or_text, scale=None, drop_first_frame="auto", fps=None, name=None) -> BVHMotion:
    """Read a BVH file into a :class:`BVHMotion`.

    path_or_text: a path (``str``/``PathLike``), or BVH text (``bytes``, or a ``str`` that
        contains a line break or starts with ``HIERARCHY``).
    scale: metres per file unit; ``None`` chooses by skeleton family (module docstring).
    drop_first_frame: ``True``, ``False`` or ``"auto"`` (detect a synthetic T-pose/rest frame).
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
    label, text = _as_text(path_or_text, name)

    def fail(line, reason):
        raise BVHError(label, line, reason)

    lines = _split_lines(text)
    if not text.strip(" \t\r\n\ufeff"):
        fail(1, "empty file")
    tk = _Tokens(lines, fail)
    joints, end_sites = _parse_hierarchy(tk, fail)

    # -- MOTION header (line based) --------------------------------------------------------
    i = tk.next_line

    def header_line(what):
        nonlocal i
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            fail(max(1, len(lines)), f"unexpected end of file (expected {what})")
        i += 1
        return lines[i - 1].strip(), i

    s, ln = header_line("MOTION")
    if s.upper() != "MOTION":
        fail(ln, f"expected MOTION after the hierarchy, found {s.split()[0]!r}")
    s, frames_line = header_line("'Frames: N'")
    m = _FRAMES_LINE.fullmatch(s)
    if not m:
        fail(frames_line, f"expected 'Frames: N', found {s!r}")
    if not _INTEGER.fullmatch(m.group(1)):
        fail(frames_line, f"Frames: {m.group(1)!r} is not a whole number")
    n_frames = int(m.group(1))
    if n_frames < 1:
        fail(frames_line, "Frames: must be at least 1")
    s, ft_line = header_line("'Frame Time: seconds'")
    m = _FRAME_TIME_LINE.fullmatch(s)
    if not m:
        fail(ft_line, f"expected 'Frame Time: seconds', found {s!r}")
    frame_time = _parse_number(m.group(1), ft_line, "Frame Time", fail)
    if frame_time <= 0 or not np.isfinite(1.0 / frame_time):
        fail(ft_line, f"Frame Time must be a positive number of seconds, found {m.group(1)!r}")

    # -- channel layout ----------------------------------------------------------------------
    J = len(joints)
    n_channels = sum(len(j.channels) for j in joints)
    if n_channels == 0:
        fail(joints[0].line, "the hierarchy declares no channels")
    data = _parse_frames(lines, i, n_frames, n_channels, frames_line, fail)

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
        drop = _detect_synthetic_first_frame(rot)
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
    src_fps = _snap_fps(frame_time)
    clip = Clip.from_world(skel, src_fps, root_pos, rot, keep_origin=True)
    if fps is not None:
        clip = ops.resample(clip, fps=float(fps))
    return BVHMotion(clip=clip, channel_orders=tuple(orders), frame_time=frame_time, source_fps=src_fps,
                     scale=scale, family=family, fingerprint=skel.fingerprint, dropped_first_frame=drop,
                     path=label, source_frames=n_frames, notes=tuple(notes))


# --------------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------------
def _dfs_order(parents: np.ndarray) -> list[int]:
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


# --------------------------------------------------------------------------------------------
# summary (for `crowdweave info`)
# --------------------------------------------------------------------------------------------
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
    }
