"""Property test: mutated BVH text either loads into a finite clip or raises BVHError whose
message names a line ("<name>:<line>: ..."); no other exception ever escapes read_bvh."""
from __future__ import annotations

import re

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from authoring.bvh import BVHError, read_bvh

BASE = """HIERARCHY
ROOT Hips
{
\tOFFSET 0.0 1.0 0.0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
\tJOINT Spine
\t{
\t\tOFFSET 0 0.3 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 0.2 0
\t\t}
\t}
\tJOINT Leg
\t{
\t\tOFFSET 0.1 -0.4 0
\t\tCHANNELS 3 Zrotation Yrotation Xrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 -0.4 .05
\t\t}
\t}
}
MOTION
Frames: 4
Frame Time: .0083333
0.0 0.95 0.0 0 0 0 0 0 0 0 0 0
0.01 0.95 0.01 1 -2 3 10 0 5 -20 0 0
0.02 0.96 0.02 2 -4 6 20 0 10 -25 1 0
0.03 0.97 0.03 3 -6 9 30 0 15 -30 2 0
"""
BASE_LINES = BASE.splitlines()
N_TOKENS = len(BASE.split())

SPECIAL = ["", "{", "}", "{ }", "nan", "inf", "-inf", "1e999", "1e308", "-", ".", "+", "e5", "1.2.3",
           "0x10", "1_0", "JOINT", "JOINT X", "ROOT", "End", "Site", "End Site", "MOTION", "Frames:",
           "Frames: 4", "Frame Time:", "Frame Time: 0", "CHANNELS", "CHANNELS 7", "OFFSET",
           "Xposition", "Qrotation", "HIERARCHY", "0", "-0", "-1", "99999999999", "3.5", "é", "\x00",
           "\t", "\r", "\n", "\r\n", "\u2028", "\ufeff", "Spine", "Hips"]

token_text = st.one_of(st.sampled_from(SPECIAL), st.text(max_size=6))
index = st.integers(min_value=0, max_value=10_000)

mutation = st.one_of(
    st.tuples(st.just("drop_line"), index),
    st.tuples(st.just("dup_line"), index),
    st.tuples(st.just("swap_lines"), index, index),
    st.tuples(st.just("insert_line"), index, token_text),
    st.tuples(st.just("drop_token"), index),
    st.tuples(st.just("dup_token"), index),
    st.tuples(st.just("corrupt_token"), index, token_text),
    st.tuples(st.just("truncate"), index),
    st.tuples(st.just("line_endings"), st.sampled_from(["\r\n", "\r", "mixed", "\n\n"])),
)
# a byte that is not UTF-8, inserted in about one example in ten (the rest test the text paths)
bad_byte = st.tuples(st.integers(min_value=0, max_value=9), index,
                     st.sampled_from([b"\xff", b"\xc3", b"\x80", b"\xed\xa0\x80"]))


def _replace_token(text, k, new):
    spans = [m.span() for m in re.finditer(r"\S+", text)]
    if not spans:
        return text
    a, b = spans[k % len(spans)]
    return text[:a] + new(text[a:b]) + text[b:]


def apply(mutations, raw=None) -> bytes:
    text = BASE
    for m in mutations:
        kind = m[0]
        lines = text.split("\n")
        if kind == "drop_line":
            del lines[m[1] % len(lines)]
            text = "\n".join(lines)
        elif kind == "dup_line":
            i = m[1] % len(lines)
            lines.insert(i, lines[i])
            text = "\n".join(lines)
        elif kind == "swap_lines":
            i, j = m[1] % len(lines), m[2] % len(lines)
            lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
        elif kind == "insert_line":
            lines.insert(m[1] % (len(lines) + 1), m[2])
            text = "\n".join(lines)
        elif kind == "drop_token":
            text = _replace_token(text, m[1], lambda t: "")
        elif kind == "dup_token":
            text = _replace_token(text, m[1], lambda t: t + " " + t)
        elif kind == "corrupt_token":
            text = _replace_token(text, m[1], lambda t, new=m[2]: new)
        elif kind == "truncate":
            text = text[: m[1] % (len(text) + 1)]
        elif kind == "line_endings":
            style = m[1]
            if style == "mixed":
                text = "".join(ln + ("\r\n" if i % 3 == 0 else "\n") for i, ln in enumerate(text.split("\n")))
            else:
                text = text.replace("\n", style)
    data = text.encode("utf-8", errors="surrogatepass")
    if raw is not None and raw[0] == 7:
        p = raw[1] % (len(data) + 1)
        data = data[:p] + raw[2] + data[p:]
    return data


def _n_lines(data: bytes) -> int:
    return max(1, len(data.replace(b"\r\n", b"\n").replace(b"\r", b"\n").rstrip(b"\n").split(b"\n")) + 1)


def test_base_text_loads():
    m = read_bvh(BASE)
    assert m.clip.num_frames == 4 and m.clip.skeleton.num_joints == 3
    assert m.channel_orders == ("ZYX", "ZXY", "ZYX")


@settings(max_examples=500, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(mutations=st.lists(mutation, min_size=1, max_size=4), raw=bad_byte,
       drop=st.sampled_from(["auto", True, False]),
       fps=st.sampled_from([None, 30.0]))
def test_mutated_bvh_raises_only_bvherror_naming_a_line(mutations, raw, drop, fps):
    data = apply(mutations, raw)
    try:
        m = read_bvh(data, drop_first_frame=drop, fps=fps, name="fuzz.bvh")
    except BVHError as e:
        msg = str(e)
        found = re.match(r"^fuzz\.bvh:(\d+): \S", msg)
        assert found, msg
        assert int(found.group(1)) == e.line and e.path == "fuzz.bvh"
        assert 1 <= e.line <= _n_lines(data), (e.line, msg)
        return
    c = m.clip
    assert c.num_frames >= 1
    assert np.isfinite(c.rotations).all()
    assert np.isfinite(c.positions()).all()
