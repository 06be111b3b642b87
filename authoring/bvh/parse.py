"""BVH text to numbers: the hierarchy (joints, offsets, channels, end sites), the MOTION
header and the frame block, with errors that name the file and line.

* **Text.** CRLF, LF, CR and mixed line endings; tabs; trailing spaces; a UTF-8 BOM; numbers
  such as ``.0083333``, ``-5.``, ``1e-3``; ``Frames:``/``Frame Time:`` with any spacing.
  Blank lines in the frame block are ignored. Any number whose magnitude exceeds
  ``MAX_ABS_VALUE`` (1e9 degrees, file units or seconds) is rejected as corrupt.
* **Channels.** A joint declares 0-6 channels (``Xposition`` ... ``Zrotation``, any order,
  each at most once); the root's ``OFFSET`` and all offsets are kept as written.
* **Errors** raise :class:`BVHError` whose message reads ``"path:LINE: what is wrong"``.
  When several things are wrong the first one in the hierarchy is reported; in the frame
  block the first bad frame line, and a frame count that falls short of ``Frames:`` is
  reported (at the ``Frames:`` line) only when every present frame line is well formed.

The frame block is parsed in one go with numpy (one ``str.split`` per line, one vectorized
float conversion) rather than token by token.
"""
from __future__ import annotations

import errno
import os
import re
from itertools import chain
from pathlib import Path

import numpy as np

from runtime.assets import read_bounded
from runtime.limits import MAX_BVH_BYTES

__all__ = ["BVHError", "MAX_ABS_VALUE", "Tokens", "Joint", "as_text", "eof_line", "split_lines", "parse_number",
           "parse_hierarchy", "parse_motion_header", "parse_frames"]

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


class BVHError(ValueError):
    """A malformed BVH file. ``str(e)`` is ``"path:LINE: what is wrong"``."""

    def __init__(self, path, line: int, reason: str):
        self.path = str(path)
        self.line = int(line)
        self.reason = reason
        super().__init__(f"{self.path}:{self.line}: {reason}")


class Tokens:
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
        return eof_line(self.lines)

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


def as_text(path_or_text, name):
    """(label, text) from a path, a str holding BVH text, or bytes holding BVH text."""
    if isinstance(path_or_text, (bytes, bytearray, memoryview)):
        return (name or "<bvh text>"), _decode(bytes(path_or_text), name or "<bvh text>")
    if isinstance(path_or_text, str):
        head = path_or_text.lstrip("\ufeff \t\r\n")
        if "\n" in path_or_text or "\r" in path_or_text or not head or head[:9].upper() == "HIERARCHY":
            return (name or "<bvh text>"), path_or_text
    p = Path(os.fspath(path_or_text))
    label = name or str(p)
    if not p.exists():
        raise FileNotFoundError(errno.ENOENT, "No such file or directory", str(p))
    # a hard size limit whatever the file system reports (a device, /proc, a growing file)
    data = read_bounded(p, MAX_BVH_BYTES, lambda path, reason: BVHError(label, 1, reason))
    return label, _decode(data, label)


def _decode(data: bytes, label: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        head = data[:e.start].replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        line = head.count(b"\n") + 1
        raise BVHError(label, line, f"not UTF-8 text (byte 0x{data[e.start]:02x})") from None


def eof_line(lines: list[str]) -> int:
    """The line an "unexpected end of file" names: the one after the last line with text
    (blank lines at the end of a file are not where it stopped), within the file."""
    last = len(lines)
    while last > 0 and not lines[last - 1].strip():
        last -= 1
    return max(1, min(len(lines), last + 1))


def split_lines(text: str) -> list[str]:
    """Lines of BVH text without a BOM, with CRLF, LF and CR all ending a line."""
    if text.startswith("\ufeff"):
        text = text[1:]
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return lines


class Joint:
    """A joint as declared: name, parent index (-1 for the root), OFFSET, channels as
    ``(kind, what)`` (``("p", axis index)`` or ``("r", "X"|"Y"|"Z")``) and its line."""

    __slots__ = ("name", "parent", "offset", "channels", "line")

    def __init__(self, name, parent, line):
        self.name = name
        self.parent = parent
        self.offset = (0.0, 0.0, 0.0)
        self.channels: list[tuple[str, object]] = []
        self.line = line


def parse_number(tok: str, line: int, what: str, fail) -> float:
    """``tok`` as a float, failing (at ``line``, naming ``what``) unless it is a plain
    decimal number of magnitude at most :data:`MAX_ABS_VALUE`."""
    if not _NUMBER.fullmatch(tok):
        fail(line, f"{what}: {tok!r} is not a number")
    v = float(tok)
    if not abs(v) <= MAX_ABS_VALUE:
        fail(line, f"{what}: {tok!r} is out of range (|value| > {MAX_ABS_VALUE:g})")
    return v


def parse_hierarchy(tk: Tokens, fail):
    """Returns (joints, end_sites) and leaves ``tk`` after the root's closing brace."""
    tok, line = tk.next("HIERARCHY")
    if tok.upper() != "HIERARCHY":
        fail(line, f"expected HIERARCHY, found {tok!r}")
    tok, line = tk.next("ROOT")
    if tok.upper() != "ROOT":
        fail(line, f"expected ROOT, found {tok!r}")
    joints: list[Joint] = []
    end_sites: list[tuple[int, tuple[float, float, float]]] = []
    names: dict[str, int] = {}

    def offset(what):
        tok, line = tk.next("OFFSET")
        if tok.upper() != "OFFSET":
            fail(line, f"expected OFFSET in {what}, found {tok!r}")
        vals = []
        for _ in range(3):
            t, ln = tk.next("an OFFSET value")
            vals.append(parse_number(t, ln, f"OFFSET of {what}", fail))
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
        j = Joint(name, parent, keyword_line)
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


def parse_motion_header(lines, start, fail):
    """The ``MOTION`` / ``Frames: N`` / ``Frame Time: s`` lines after the hierarchy (blank
    lines between them are skipped).

    Args:
        lines: the file's lines (:func:`split_lines`).
        start: index of the first line after the hierarchy.
        fail: ``fail(line, reason)`` raises the caller's :class:`BVHError`.
    Returns:
        ``(n_frames, frames_line, frame_time, next_index)``: the declared frame count, the
        1-based line of ``Frames:``, the frame time (s) and the index of the first frame line.
    """
    i = start

    def header_line(what):
        nonlocal i
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            fail(eof_line(lines), f"unexpected end of file (expected {what})")
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
    frame_time = parse_number(m.group(1), ft_line, "Frame Time", fail)
    if frame_time <= 0 or not np.isfinite(1.0 / frame_time):
        fail(ft_line, f"Frame Time must be a positive number of seconds, found {m.group(1)!r}")
    return n_frames, frames_line, frame_time, i


def parse_frames(lines, start, n_frames, n_channels, frames_line, fail) -> np.ndarray:
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
