"""BVH import/export (authoring.bvh): tiny synthetic files with exact asserts, error cases
with exact line numbers, and loading every file of the CMU developer set."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from authoring.bvh import BVHError, bvh_summary, bvh_text, read_bvh, write_bvh
from runtime.motion import quat
from runtime.motion.fk import end_site_positions

CMU = Path(__file__).resolve().parents[1].parent / "shared" / "mocap" / "cmu"
need_cmu = pytest.mark.skipif(not CMU.is_dir(), reason=f"CMU developer set not found at {CMU}")

# Line numbers are referenced by the error tests below: keep the layout.
TINY = """HIERARCHY
ROOT Hips
{
\tOFFSET 1.0 2.0 3.0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
\tJOINT Spine
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tJOINT Head
\t\t{
\t\t\tOFFSET 0 5 0
\t\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\t\tEnd Site
\t\t\t{
\t\t\t\tOFFSET 0 2 0
\t\t\t}
\t\t}
\t}
\tJOINT Leg
\t{
\t\tOFFSET 3 -10 0
\t\tCHANNELS 3 Yrotation Zrotation Xrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 -8 1
\t\t}
\t}
}
MOTION
Frames: 3
Frame Time: .0333333
10 20 30 0 0 0 0 0 0 0 0 0 0 0 0
11 20 30 0 0 0 90 0 0 0 0 0 0 0 0
12 20 30 90 0 0 0 0 0 0 0 0 0 0 0
"""
TINY_LINES = TINY.splitlines()
FRAMES_LINE = TINY_LINES.index("Frames: 3") + 1          # 31
FIRST_FRAME_LINE = FRAMES_LINE + 2                          # 33


def test_tiny_layout_matches_line_constants():
    assert FRAMES_LINE == 31 and FIRST_FRAME_LINE == 33 and len(TINY_LINES) == 35


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


_R = {"X": _rx, "Y": _ry, "Z": _rz}


def _matrix(order, degs):
    m = np.eye(3)
    for ax, d in zip(order, degs):
        m = m @ _R[ax](math.radians(d))
    return m


# ------------------------------------------------------------------------------------------
# structure, channel orders, end sites, numbers
# ------------------------------------------------------------------------------------------
def test_tiny_structure_and_channel_orders():
    m = read_bvh(TINY)
    sk = m.clip.skeleton
    assert sk.names == ("Hips", "Spine", "Head", "Leg")
    assert sk.parents.tolist() == [-1, 0, 1, 0]
    assert m.channel_orders == ("ZYX", "ZXY", "XYZ", "YZX")
    assert m.clip.num_frames == 3 and m.source_frames == 3
    assert m.scale == 1.0 and m.family.startswith("custom-")
    assert m.frame_time == 0.0333333 and m.source_fps == 30.0 and m.clip.fps == 30.0
    assert m.dropped_first_frame is False
    assert m.path == "<bvh text>" and m.notes == ()
    np.testing.assert_array_equal(sk.offsets, [[0, 0, 0], [0, 10, 0], [0, 5, 0], [3, -10, 0]])
    assert sk.end_sites == ((2, (0.0, 2.0, 0.0)), (3, (0.0, -8.0, 1.0)))


def test_tiny_root_offset_added_and_positions_exact():
    m = read_bvh(TINY)
    root, _ = m.clip.world_root()
    np.testing.assert_allclose(root, [[11, 22, 33], [12, 22, 33], [13, 22, 33]], atol=1e-12)
    _, pos = m.clip.fk()
    # frame 0: everything at rest
    np.testing.assert_allclose(pos[0], [[11, 22, 33], [11, 32, 33], [11, 37, 33], [14, 12, 33]], atol=1e-5)
    # frame 1: Spine Zrotation 90 turns the +Y bone to -X
    np.testing.assert_allclose(pos[1, 2], [12 - 5, 32, 33], atol=1e-5)
    # frame 2: root Zrotation 90: Spine offset (0,10,0) -> (-10,0,0), Leg (3,-10,0) -> (10,3,0)
    np.testing.assert_allclose(pos[2], [[13, 22, 33], [3, 22, 33], [-2, 22, 33], [23, 25, 33]], atol=1e-5)
    gr, gp = m.clip.fk()
    ends = end_site_positions(m.clip.skeleton, gr, gp)
    np.testing.assert_allclose(ends[0], [[11, 39, 33], [14, 4, 34]], atol=1e-5)


@pytest.mark.parametrize("order", ["ZYX", "ZXY", "XYZ", "YZX", "YXZ", "XZY"])
def test_channel_order_composes_left_to_right(order):
    names = {"X": "Xrotation", "Y": "Yrotation", "Z": "Zrotation"}
    angles = (30.0, -50.0, 70.0)
    text = TINY.replace("CHANNELS 3 Zrotation Xrotation Yrotation",
                        "CHANNELS 3 " + " ".join(names[a] for a in order))
    lines = text.splitlines()
    lines[FIRST_FRAME_LINE - 1] = "10 20 30 0 0 0 %g %g %g 0 0 0 0 0 0" % angles
    m = read_bvh("\n".join(lines) + "\n")
    assert m.channel_orders[1] == order
    got = quat.to_matrix(m.clip.rotations[0, 1].astype(np.float64))
    np.testing.assert_allclose(got, _matrix(order, angles), atol=1e-6)


def test_rotation_channels_on_each_joint_match_matrices():
    lines = TINY.splitlines()
    vals = [0, 0, 0, 10, -20, 30, 40, 50, -60, 170, -80, 250, -300, 15, 5]
    lines[FIRST_FRAME_LINE - 1] = " ".join(str(v) for v in vals)
    m = read_bvh("\n".join(lines) + "\n")
    _, rroot = m.clip.world_root()
    np.testing.assert_allclose(quat.to_matrix(rroot[0]), _matrix("ZYX", vals[3:6]), atol=1e-6)
    for j, order, a in ((1, "ZXY", vals[6:9]), (2, "XYZ", vals[9:12]), (3, "YZX", vals[12:15])):
        np.testing.assert_allclose(quat.to_matrix(m.clip.rotations[0, j].astype(np.float64)),
                                   _matrix(order, a), atol=1e-6)


def test_angles_beyond_180_equal_wrapped():
    a = TINY.replace("12 20 30 90 0 0", "12 20 30 -270 0 0")
    pa = read_bvh(a).clip.positions()
    pb = read_bvh(TINY).clip.positions()
    np.testing.assert_allclose(pa, pb, atol=1e-5)


@pytest.mark.parametrize("tokens,value", [
    (".5", 0.5), ("-.25", -0.25), ("5.", 5.0), ("1e1", 10.0), ("+2", 2.0), ("1E-1", 0.1),
    ("-0", 0.0), ("007", 7.0), ("2.5e+0", 2.5),
])
def test_number_formats(tokens, value):
    lines = TINY.splitlines()
    lines[FIRST_FRAME_LINE - 1] = f"{tokens} 20 30 0 0 0 0 0 0 0 0 0 0 0 0"
    m = read_bvh("\n".join(lines))
    assert m.clip.world_root()[0][0, 0] == pytest.approx(1.0 + value, abs=1e-12)


@pytest.mark.parametrize("line,fps", [
    ("Frame Time: .0333333", 30.0), ("Frame Time:\t0.0333333", 30.0), ("Frame Time:.0333333", 30.0),
    ("Frame  Time :  0.033333333", 30.0), ("frame time: 0.0083333", 120.0), ("Frame Time: 0.008333", 120.0),
    ("Frame Time: 0.0166667", 60.0), ("Frame Time: 0.0333667", 1 / 0.0333667),
])
def test_frame_time_variants(line, fps):
    text = TINY.replace("Frame Time: .0333333", line)
    m = read_bvh(text)
    assert m.source_fps == pytest.approx(fps, rel=1e-12)
    assert m.clip.fps == m.source_fps


def test_frames_line_variants():
    for v in ("Frames:3", "Frames:\t3", "Frames :  3  ", "FRAMES: 3"):
        assert read_bvh(TINY.replace("Frames: 3", v)).clip.num_frames == 3


def _same_motion(a, b):
    assert a.clip.skeleton.names == b.clip.skeleton.names
    assert a.channel_orders == b.channel_orders
    np.testing.assert_array_equal(a.clip.rotations, b.clip.rotations)
    np.testing.assert_array_equal(a.clip.world_root()[0], b.clip.world_root()[0])
    assert a.clip.skeleton.end_sites == b.clip.skeleton.end_sites


def test_line_endings_tabs_trailing_spaces_bom():
    ref = read_bvh(TINY)
    crlf = TINY.replace("\n", "\r\n")
    cr = TINY.replace("\n", "\r")
    mixed = "".join(ln + ("\r\n" if i % 2 else "\n") for i, ln in enumerate(TINY_LINES))
    spaced = "\n".join("  " + ln.replace("\t", " \t ") + " \t " for ln in TINY_LINES)
    bom = "\ufeff" + TINY
    for text in (crlf, cr, mixed, spaced, bom, crlf.encode("utf-8"), TINY.encode("utf-8")):
        _same_motion(ref, read_bvh(text))


def test_blank_lines_in_frame_block_are_ignored():
    lines = TINY_LINES[:]
    lines.insert(FIRST_FRAME_LINE, "   ")
    lines.append("")
    m = read_bvh("\n".join(lines) + "\n\n")
    _same_motion(read_bvh(TINY), m)


def test_brace_on_joint_line_and_name_with_space():
    text = TINY.replace("JOINT Spine\n\t{", "JOINT Spine {").replace("JOINT Leg", "JOINT Left Leg")
    m = read_bvh(text)
    assert m.clip.skeleton.names == ("Hips", "Spine", "Head", "Left Leg")
    np.testing.assert_allclose(m.clip.positions(), read_bvh(TINY).clip.positions())


def test_root_channels_in_any_order():
    text = TINY.replace("CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation",
                        "CHANNELS 6 Zrotation Zposition Xposition Yrotation Yposition Xrotation")
    lines = text.splitlines()
    # values for (Zrot, Zpos, Xpos, Yrot, Ypos, Xrot) = (90, 30, 12, 0, 20, 0)
    lines[FIRST_FRAME_LINE + 1] = "90 30 12 0 20 0 0 0 0 0 0 0 0 0 0"
    m = read_bvh("\n".join(lines))
    np.testing.assert_allclose(m.clip.positions()[2], read_bvh(TINY).clip.positions()[2], atol=1e-5)


def test_root_without_position_channels_uses_offset():
    text = TINY.replace("CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation",
                        "CHANNELS 3 Zrotation Yrotation Xrotation")
    lines = text.splitlines()
    for k in range(3):
        lines[FIRST_FRAME_LINE - 1 + k] = " ".join(lines[FIRST_FRAME_LINE - 1 + k].split()[3:])
    m = read_bvh("\n".join(lines))
    np.testing.assert_allclose(m.clip.world_root()[0], [[1, 2, 3]] * 3, atol=1e-12)


def test_fewer_rotation_channels_and_non_root_translation_note():
    text = TINY.replace("CHANNELS 3 Zrotation Xrotation Yrotation",
                        "CHANNELS 4 Xposition Yposition Zposition Zrotation")
    lines = text.splitlines()
    # Spine: translation (99, 99, 99) is ignored; Zrotation 90 on frame 1
    lines[FIRST_FRAME_LINE - 1] = "10 20 30 0 0 0 99 99 99 0 0 0 0 0 0 0"
    lines[FIRST_FRAME_LINE] = "11 20 30 0 0 0 99 99 99 90 0 0 0 0 0 0"
    lines[FIRST_FRAME_LINE + 1] = "12 20 30 90 0 0 99 99 99 0 0 0 0 0 0 0"
    m = read_bvh("\n".join(lines))
    assert m.channel_orders[1] == "Z"
    assert len(m.notes) == 1 and "Spine" in m.notes[0] and "ignored" in m.notes[0]
    np.testing.assert_allclose(m.clip.positions(), read_bvh(TINY).clip.positions(), atol=1e-5)


# ------------------------------------------------------------------------------------------
# scale, first frame, resampling
# ------------------------------------------------------------------------------------------
def test_scale_applies_to_offsets_end_sites_and_root():
    m = read_bvh(TINY, scale=0.01)
    assert m.scale == 0.01
    np.testing.assert_allclose(m.clip.skeleton.offsets[3], [0.03, -0.1, 0.0])
    assert m.clip.skeleton.end_sites[1] == (3, (0.0, -0.08, 0.01))
    np.testing.assert_allclose(m.clip.positions(), read_bvh(TINY).clip.positions() * 0.01, atol=1e-7)
    with pytest.raises(ValueError):
        read_bvh(TINY, scale=0.0)


def _smooth_take(n=60, fps=120, t_pose=False):
    """TINY's skeleton with n frames of smooth motion (and optionally a T-pose frame 0)."""
    t = np.arange(n) / fps
    rows = []
    for k, tt in enumerate(t):
        a = 20 * np.sin(2 * np.pi * tt)
        rows.append([10 + tt, 20, 30, 5 * np.sin(tt), 0, 0, a, 0.5 * a, 0, 0, a, 0, -a, 0, 0.3 * a])
    if t_pose:
        rows[0] = [rows[1][0], 20, 30] + [0.0] * 3 + [0, 0, 0, 0, 0, 0, 45, 0, 0]
    head = TINY[:TINY.index("MOTION")]
    body = "\n".join(" ".join(f"{v:.6f}" for v in r) for r in rows)
    return f"{head}MOTION\nFrames: {n}\nFrame Time: {1 / fps:.7f}\n{body}\n"


def test_drop_first_frame_auto_true_false():
    tp = _smooth_take(t_pose=True)
    smooth = _smooth_take()
    auto = read_bvh(tp)
    assert auto.dropped_first_frame is True and auto.clip.num_frames == 59 and auto.source_frames == 60
    keep = read_bvh(tp, drop_first_frame=False)
    assert keep.dropped_first_frame is False and keep.clip.num_frames == 60
    np.testing.assert_allclose(auto.clip.positions(), keep.clip.positions()[1:], atol=1e-9)
    s_auto = read_bvh(smooth)
    assert s_auto.dropped_first_frame is False and s_auto.clip.num_frames == 60
    forced = read_bvh(smooth, drop_first_frame=True)
    assert forced.dropped_first_frame is True and forced.clip.num_frames == 59
    with pytest.raises(ValueError):
        read_bvh(smooth, drop_first_frame="yes")


def test_resample_to_30_keeps_duration():
    m120 = read_bvh(_smooth_take(n=121), drop_first_frame=False)
    assert m120.clip.fps == 120.0 and m120.clip.duration == pytest.approx(1.0)
    m30 = read_bvh(_smooth_take(n=121), drop_first_frame=False, fps=30)
    assert m30.clip.fps == 30.0 and m30.clip.num_frames == 31
    assert m30.clip.duration == pytest.approx(m120.clip.duration)
    assert m30.source_fps == 120.0
    # 30 Hz frame k is 120 Hz frame 4k
    np.testing.assert_allclose(m30.clip.positions(), m120.clip.positions()[::4], atol=1e-6)


# ------------------------------------------------------------------------------------------
# errors: BVHError naming file and line
# ------------------------------------------------------------------------------------------
def _replace_line(n, new):
    lines = TINY_LINES[:]
    lines[n - 1] = new
    return "\n".join(lines) + "\n"


def _delete_line(n):
    lines = TINY_LINES[:]
    del lines[n - 1]
    return "\n".join(lines) + "\n"


ERROR_CASES = [
    ("empty", "", 1, "empty file"),
    ("blank", "  \n\t\n", 1, "empty file"),
    ("no HIERARCHY", "\n".join(TINY_LINES[1:]), 1, "expected HIERARCHY"),
    ("no ROOT", _replace_line(2, "JOINT Hips"), 2, "expected ROOT"),
    ("root without name", _replace_line(2, "ROOT"), 2, "no name"),
    ("missing brace", _delete_line(7), 7, "expected '{'"),
    ("unknown channel", _replace_line(9, "\t\tCHANNELS 3 Zrotation Qrotation Yrotation"), 9, "unknown channel name 'Qrotation'"),
    ("duplicate channel", _replace_line(9, "\t\tCHANNELS 3 Zrotation Zrotation Yrotation"), 9, "appears twice"),
    ("channel count", _replace_line(13, "\t\t\tCHANNELS x Xrotation Yrotation Zrotation"), 13, "channel count"),
    ("too few channel names", _replace_line(13, "\t\t\tCHANNELS 3 Xrotation Yrotation"), 14, "unknown channel name 'End'"),
    ("bad offset", _replace_line(12, "\t\t\tOFFSET 0 five 0"), 12, "'five' is not a number"),
    ("short offset", _replace_line(12, "\t\t\tOFFSET 0 5"), 13, "'CHANNELS' is not a number"),
    ("missing OFFSET", _delete_line(22), 22, "expected OFFSET"),
    ("End without Site", _replace_line(24, "\t\tEnd"), 25, "expected 'End Site'"),
    ("duplicate joint", TINY.replace("JOINT Leg", "JOINT Spine"), 20, "duplicate joint name 'Spine'"),
    ("stray token", _replace_line(19, "\t} oops"), 19, "'oops'"),
    ("second ROOT", _replace_line(20, "ROOT Leg"), 20, "only one root"),
    ("truncated hierarchy", "\n".join(TINY_LINES[:12]) + "\n", 12, "unexpected end of file"),
    ("extra closing brace", _replace_line(20, "}"), 21, "expected MOTION"),
    ("no MOTION", "\n".join(TINY_LINES[:29]) + "\n", 29, "expected MOTION"),
    ("no Frames line", _delete_line(31), 31, "expected 'Frames: N'"),
    ("Frames not integer", _replace_line(31, "Frames: 3.0"), 31, "not a whole number"),
    ("Frames zero", _replace_line(31, "Frames: 0"), 31, "at least 1"),
    ("no Frame Time", _replace_line(32, "Time: .0333333"), 32, "expected 'Frame Time"),
    ("zero Frame Time", _replace_line(32, "Frame Time: 0"), 32, "positive"),
    ("negative Frame Time", _replace_line(32, "Frame Time: -0.0333"), 32, "positive"),
    ("bad Frame Time", _replace_line(32, "Frame Time: fast"), 32, "not a number"),
    ("too few values", _replace_line(34, "11 20 30 0 0 0 90 0 0 0 0 0 0 0"), 34, "expected 15 values on a frame line, found 14"),
    ("too many values", _replace_line(33, "10 20 30 0 0 0 0 0 0 0 0 0 0 0 0 0"), 33, "found 16"),
    ("non-numeric value", _replace_line(35, "12 20 30 90 0 0 0 0 zero 0 0 0 0 0 0"), 35, "'zero' is not a number"),
    ("malformed number", _replace_line(35, "12 20 30 90 0 0 0 0 1.2.3 0 0 0 0 0 0"), 35, "'1.2.3' is not a number"),
    ("nan value", _replace_line(34, "11 20 30 nan 0 0 90 0 0 0 0 0 0 0 0"), 34, "'nan' is not a number"),
    ("overflow value", _replace_line(34, "11 20 30 1e999 0 0 90 0 0 0 0 0 0 0 0"), 34, "out of range"),
    ("fewer frames than declared", TINY.replace("Frames: 3", "Frames: 4"), 31, "declares 4 frames but the file has 3"),
    ("more frames than declared", TINY.replace("Frames: 3", "Frames: 2"), 35, "more frame lines than the 2 declared"),
    ("truncated last frame", TINY[:-12], 35, "found 9"),
    ("first bad line wins", _replace_line(35, "x").replace("Frames: 3", "Frames: 5"), 35, "found 1"),
]


@pytest.mark.parametrize("text,line,what", [c[1:] for c in ERROR_CASES], ids=[c[0] for c in ERROR_CASES])
def test_errors_name_the_line(text, line, what):
    with pytest.raises(BVHError) as ei:
        read_bvh(text.encode("utf-8"), name="take.bvh")
    e = ei.value
    assert isinstance(e, ValueError)
    assert (e.path, e.line) == ("take.bvh", line), str(e)
    assert str(e).startswith(f"take.bvh:{line}: ")
    assert what in str(e)


def test_error_line_numbers_with_crlf_and_cr():
    bad = _replace_line(34, "11 20 30 0 0 0 90 0 0 0 0 0 0 0")
    for text in (bad.replace("\n", "\r\n"), bad.replace("\n", "\r")):
        with pytest.raises(BVHError, match=r"^<bvh text>:34: "):
            read_bvh(text)


def test_non_utf8_names_line(tmp_path):
    data = TINY.encode("utf-8").replace(b"JOINT Head", b"JOINT H\xffad")
    p = tmp_path / "bad.bvh"
    p.write_bytes(data)
    with pytest.raises(BVHError) as ei:
        read_bvh(p)
    assert ei.value.line == 10 and str(ei.value).startswith(f"{p}:10: ")


def test_error_names_the_file_path(tmp_path):
    p = tmp_path / "take.bvh"
    p.write_text(_replace_line(9, "\t\tCHANNELS 3 Zrotation Wrotation Yrotation"))
    for arg in (p, str(p)):
        with pytest.raises(BVHError, match=re.escape(f"{p}:9: unknown channel name 'Wrotation'")):
            read_bvh(arg)
    with pytest.raises(OSError):
        read_bvh(tmp_path / "missing.bvh")


# ------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------
def test_write_read_roundtrip_and_determinism(tmp_path):
    m = read_bvh(_smooth_take(), drop_first_frame=False)
    a, b = tmp_path / "a.bvh", tmp_path / "b.bvh"
    write_bvh(a, m.clip, channel_orders=m.channel_orders)
    write_bvh(b, m.clip, channel_orders=m.channel_orders)
    assert a.read_bytes() == b.read_bytes()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.bvh", "b.bvh"]   # no temp files left
    back = read_bvh(a, drop_first_frame=False)
    assert back.channel_orders == m.channel_orders
    assert back.clip.skeleton.fingerprint == m.clip.skeleton.fingerprint
    assert back.clip.skeleton.end_sites == m.clip.skeleton.end_sites
    np.testing.assert_allclose(back.clip.positions(), m.clip.positions(), atol=1e-6)
    np.testing.assert_allclose(back.clip.origin, m.clip.origin, atol=1e-9)


def test_write_layout_orders_and_scale():
    m = read_bvh(TINY)
    text = bvh_text(m.clip, scale=0.5)
    lines = text.splitlines()
    assert lines[0] == "HIERARCHY" and lines[1] == "ROOT Hips"
    assert "\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" in lines
    assert lines.count("\t\tCHANNELS 3 Zrotation Yrotation Xrotation") == 2       # default ZYX
    assert "\t\tOFFSET 6.000000 -20.000000 0.000000" in lines                    # Leg offset / 0.5
    assert "\t\t\tOFFSET 0.000000 -16.000000 2.000000" in lines                  # Leg end site / 0.5
    assert lines[lines.index("MOTION") + 1] == "Frames: 3"
    assert lines[lines.index("MOTION") + 2].startswith("Frame Time: 0.03333333")
    first = lines[lines.index("MOTION") + 3].split()
    assert first[:3] == ["22.000000", "44.000000", "66.000000"]                   # (root + offset) / 0.5
    assert not any(v == "-0.000000" for v in " ".join(lines).split())
    orders = bvh_text(m.clip, channel_orders=m.channel_orders)
    assert "\t\tCHANNELS 3 Zrotation Xrotation Yrotation" in orders
    assert "\t\tCHANNELS 3 Yrotation Zrotation Xrotation" in orders
    assert "\t\t\tCHANNELS 3 Xrotation Yrotation Zrotation" in orders
    back = read_bvh(text, scale=0.5)
    np.testing.assert_allclose(back.clip.positions(), m.clip.positions(), atol=1e-5)
    with pytest.raises(ValueError):
        bvh_text(m.clip, channel_orders="ZZX")


def test_write_pads_short_orders():
    text = TINY.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 1 Zrotation")
    lines = text.splitlines()
    for k in range(3):
        vals = lines[FIRST_FRAME_LINE - 1 + k].split()
        lines[FIRST_FRAME_LINE - 1 + k] = " ".join(vals[:7] + vals[9:])
    m = read_bvh("\n".join(lines))
    assert m.channel_orders[1] == "Z"
    back = read_bvh(bvh_text(m.clip, channel_orders=m.channel_orders))
    assert back.channel_orders[1] == "ZYX"
    np.testing.assert_allclose(back.clip.positions(), m.clip.positions(), atol=1e-5)


def test_summary(tmp_path):
    p = tmp_path / "t.bvh"
    p.write_text(_smooth_take(t_pose=True))
    s = bvh_summary(p)
    assert s["frames"] == 59 and s["source_frames"] == 60
    assert s["fps"] == 120.0 and s["duration"] == pytest.approx(58 / 120)
    assert s["joints"] == 4 and s["end_sites"] == 2
    assert s["dropped_first_frame"] is True and s["scale"] == 1.0
    assert s["channel_orders"] == {"XYZ": 1, "YZX": 1, "ZXY": 1, "ZYX": 1}
    assert s["family"].startswith("custom-") and s["path"] == str(p)


# ------------------------------------------------------------------------------------------
# the CMU developer set
# ------------------------------------------------------------------------------------------
def _readme_table():
    """file -> dict(family letter, frames, fps, joints, end_sites, t0) from the README table."""
    rows = {}
    for line in (CMU / "README.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 13 and cells[0].endswith(".bvh"):
            fam = cells[4].split()[0]
            fps = float(re.search(r"\(\**(\d+)\**\)", cells[6]).group(1))
            rows[cells[0]] = dict(family=fam, frames=int(cells[5]), fps=fps, joints=int(cells[8]),
                                  end_sites=int(cells[10]), t0=cells[11].startswith("yes"))
        elif len(cells) == 6 and cells[0].endswith(".bvh"):
            # "Walking with turns": family A cgspeed files, 120 fps, T-pose frame 0 (stated
            # once above that table rather than per row)
            rows[cells[0]] = dict(family="A", frames=int(cells[4]), fps=120.0, joints=31,
                                  end_sites=7, t0=True)
    return rows


@need_cmu
def test_cmu_all_files_load_with_readme_properties():
    table = _readme_table()
    assert len(table) >= 15 and sorted(table) == sorted(p.name for p in CMU.glob("*.bvh"))
    fam_of_letter = {}
    for name, row in sorted(table.items()):
        m = read_bvh(CMU / name)
        sk = m.clip.skeleton
        assert m.dropped_first_frame is row["t0"], name
        assert m.source_frames == row["frames"], name
        assert m.clip.num_frames == row["frames"] - int(row["t0"]), name
        assert m.clip.fps == row["fps"] and m.source_fps == row["fps"], name
        assert sk.num_joints == row["joints"] and len(sk.end_sites) == row["end_sites"], name
        letter = row["family"].rstrip("′'")
        fam_of_letter.setdefault(letter, set()).add(m.family)
        assert np.isfinite(m.clip.rotations).all()
        # hips roughly a metre up: the family scale is right
        assert 0.7 < float(np.median(m.clip.root_height)) < 1.2, name
    assert {k: sorted(v) for k, v in fam_of_letter.items()} == {
        "A": ["cmu-mb"], "B": ["cmu-3dsmax"], "C": ["cmu-daz"]}


@need_cmu
def test_cmu_families_and_channel_orders():
    a = read_bvh(CMU / "cmu_02_01_walk.bvh")
    a2 = read_bvh(CMU / "cmu_16_11_walk_veer_left_retargeted.bvh")
    b = read_bvh(CMU / "cmu_131_02_start_walk_stop_maxfriendly.bvh")
    c = read_bvh(CMU / "cmu_16_15_walk_dazfriendly.bvh")
    assert a.fingerprint == a2.fingerprint and a.family == a2.family == "cmu-mb"
    assert len({a.fingerprint, b.fingerprint, c.fingerprint}) == 3
    assert (a.scale, b.scale, c.scale) == (0.05644, 0.05644, 0.01)
    assert set(a.channel_orders) == {"ZYX"}
    arms = {"LeftShoulder", "LeftElbow", "LeftWrist", "lhand", "LFingers", "LThumb",
            "RightShoulder", "RightElbow", "RightWrist", "rhand", "RFingers", "RThumb"}
    for n, o in zip(b.clip.skeleton.names, b.channel_orders):
        assert o == ("ZXY" if n in arms else "ZYX"), n
    assert c.channel_orders[0] == "ZYX" and set(c.channel_orders[1:]) == {"ZXY"}
    # the DAZ rest pose sits a frame before the motion; dropping keeps frame 1 as frame 0
    c_all = read_bvh(CMU / "cmu_16_15_walk_dazfriendly.bvh", drop_first_frame=False)
    np.testing.assert_allclose(c.clip.positions(), c_all.clip.positions()[1:], atol=1e-9)


@need_cmu
def test_cmu_resample_salsa_and_walk_to_30():
    for name, src in (("cmu_60_10_salsa_duet_A_male.bvh", 60.0), ("cmu_02_01_walk.bvh", 120.0)):
        full = read_bvh(CMU / name)
        m = read_bvh(CMU / name, fps=30)
        assert full.clip.fps == src and m.clip.fps == 30.0
        assert abs(m.clip.duration - full.clip.duration) < 1 / 30
        step = int(src // 30)
        n = m.clip.num_frames
        np.testing.assert_allclose(m.clip.positions(), full.clip.positions()[::step][:n], atol=1e-5)


@need_cmu
def test_cmu_summary_131():
    s = bvh_summary(CMU / "cmu_131_02_start_walk_stop_maxfriendly.bvh")
    assert (s["frames"], s["joints"], s["family"], s["fps"]) == (1247, 31, "cmu-3dsmax", 120.0)
    assert s["channel_orders"] == {"ZYX": 19, "ZXY": 12}
    assert s["dropped_first_frame"] is False and s["scale"] == 0.05644


def test_write_non_dfs_skeleton_reorders_columns_consistently():
    from runtime.motion.clip import Clip
    from runtime.motion.skeleton import Skeleton
    # breadth-first order: C is B's child... written depth-first as R, A, C, B, D
    sk = Skeleton(("R", "A", "B", "C", "D"), np.array([-1, 0, 0, 1, 2]),
                  np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0.5, 0], [0.5, 0, 0]]),
                  end_sites=((3, (0.0, 0.1, 0.0)),))
    rng = np.random.default_rng(3)
    F = 5
    rot = quat.from_euler(rng.uniform(-90, 90, size=(F, 5, 3)), "ZYX")
    root = np.column_stack([np.arange(F) * 0.1, np.full(F, 1.0), np.zeros(F)])
    clip = Clip.from_world(sk, 30.0, root, rot)
    back = read_bvh(bvh_text(clip, precision=9), drop_first_frame=False)
    assert back.clip.skeleton.names == ("R", "A", "C", "B", "D")
    idx = [back.clip.skeleton.index(n) for n in sk.names]
    np.testing.assert_allclose(back.clip.positions()[:, idx], clip.positions(), atol=1e-6)
    assert back.clip.skeleton.end_sites == ((2, (0.0, 0.1, 0.0)),)
