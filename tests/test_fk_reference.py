"""Reference forward kinematics for every CMU file, independent of authoring.bvh and of the
quaternion code: a tiny BVH parser written here, and per-joint 4x4 homogeneous matrices
composed in each joint's channel order (world = parent world @ T(offset) @ R_c1 @ R_c2 @ R_c3;
root: T(position + offset) @ R). Batched over frames with matmul, one joint at a time.

Also: writing a clip and reading it back reproduces joint world positions to 1e-6 m.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from authoring.bvh import read_bvh, write_bvh
from runtime.motion.fk import end_site_positions

CMU = Path(__file__).resolve().parents[1].parent / "shared" / "mocap" / "cmu"
FILES = sorted(p.name for p in CMU.glob("*.bvh")) if CMU.is_dir() else []
pytestmark = pytest.mark.skipif(not FILES, reason=f"CMU developer set not found at {CMU}")

# metres per file unit, as ../shared/mocap/cmu/README.md describes each family
README_SCALE = {"cmu-mb": 0.05644, "cmu-3dsmax": 0.05644, "cmu-daz": 0.01}


def parse_plain(path):
    """(joints, end_sites, frames) with joints = [name, parent, offset(3), channels[list]]."""
    text = Path(path).read_text().replace("\r\n", "\n").replace("\r", "\n")
    head, motion = text.split("\nMOTION", 1)
    tok = head.split()
    joints, ends, stack, i = [], [], [], 0
    pending = None
    while i < len(tok):
        t = tok[i]
        if t in ("ROOT", "JOINT"):
            joints.append([tok[i + 1], stack[-1] if stack else -1, None, []])
            pending = len(joints) - 1
            i += 2
        elif t == "End":                 # "End Site"
            ends.append([stack[-1], None])
            pending = ("end", len(ends) - 1)
            i += 2
        elif t == "{":
            stack.append(pending)
            i += 1
        elif t == "}":
            stack.pop()
            i += 1
        elif t == "OFFSET":
            off = [float(x) for x in tok[i + 1:i + 4]]
            top = stack[-1]
            if isinstance(top, tuple):
                ends[top[1]][1] = off
            else:
                joints[top][2] = off
            i += 4
        elif t == "CHANNELS":
            n = int(tok[i + 1])
            joints[stack[-1]][3] = tok[i + 2:i + 2 + n]
            i += 2 + n
        else:
            i += 1                       # HIERARCHY
    lines = motion.strip().split("\n")
    ft = next(k for k, ln in enumerate(lines) if ln.startswith("Frame Time"))
    frames = np.array([[float(x) for x in ln.split()] for ln in lines[ft + 1:] if ln.strip()])
    return joints, ends, frames


def _rot4(axis, deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    m = np.zeros(a.shape + (4, 4))
    m[..., 3, 3] = 1.0
    i, j = {"X": (1, 2), "Y": (2, 0), "Z": (0, 1)}[axis]
    k = 3 - i - j
    m[..., k, k] = 1.0
    m[..., i, i] = c
    m[..., j, j] = c
    m[..., i, j] = -s
    m[..., j, i] = s
    return m


def _trans4(v):
    v = np.asarray(v, dtype=np.float64)
    m = np.zeros(v.shape[:-1] + (4, 4))
    m[..., 0, 0] = m[..., 1, 1] = m[..., 2, 2] = m[..., 3, 3] = 1.0
    m[..., :3, 3] = v
    return m


def reference_fk(path):
    """World joint positions (F, J, 3) and end-site positions (F, E, 3) in file units."""
    joints, ends, frames = parse_plain(path)
    F = len(frames)
    world = []
    col = 0
    for j, (name, parent, offset, chans) in enumerate(joints):
        pos = np.array(offset, dtype=np.float64) + np.zeros((F, 3))
        rot = np.broadcast_to(np.eye(4), (F, 4, 4))
        for c in chans:
            v = frames[:, col]
            col += 1
            if c.endswith("position"):
                if parent == -1:
                    pos[:, "XYZ".index(c[0])] += v
            else:
                rot = rot @ _rot4(c[0], v)
        local = _trans4(pos) @ rot
        world.append(local if parent == -1 else world[parent] @ local)
    assert col == frames.shape[1]
    P = np.stack([w[:, :3, 3] for w in world], axis=1)
    E = np.stack([(world[j] @ np.append(o, 1.0))[:, :3] for j, o in ends], axis=1)
    return P, E


@pytest.mark.parametrize("name", FILES)
def test_vectorized_fk_matches_reference(name):
    m = read_bvh(CMU / name)
    assert m.scale == README_SCALE[m.family]
    ref_p, ref_e = reference_fk(CMU / name)
    ref_p *= m.scale
    ref_e *= m.scale
    if m.dropped_first_frame:
        ref_p, ref_e = ref_p[1:], ref_e[1:]
    gr, gp = m.clip.fk()
    assert gp.shape == ref_p.shape
    err = np.abs(gp - ref_p).max()
    assert err < 1e-5, f"{name}: max joint position error {err:.3g} m"
    ep = end_site_positions(m.clip.skeleton, gr, gp)
    assert ep.shape == ref_e.shape
    assert np.abs(ep - ref_e).max() < 1e-5


@pytest.mark.parametrize("name", FILES)
def test_save_then_load_reproduces_world_positions(name, tmp_path):
    m = read_bvh(CMU / name)
    out = write_bvh(tmp_path / name, m.clip, channel_orders=m.channel_orders, scale=m.scale)
    back = read_bvh(out, drop_first_frame=False)
    assert back.scale == m.scale and back.family == m.family
    assert back.channel_orders == m.channel_orders
    assert back.clip.num_frames == m.clip.num_frames and back.clip.fps == m.clip.fps
    err = np.abs(back.clip.positions() - m.clip.positions()).max()
    assert err < 1e-6, f"{name}: round-trip error {err:.3g} m"
    # default orders (all ZYX) in metres also round-trip (8 decimals: 6 would quantise to 1e-6 m)
    out2 = write_bvh(tmp_path / ("m_" + name), m.clip, precision=8)
    back2 = read_bvh(out2, scale=1.0, drop_first_frame=False)
    assert np.abs(back2.clip.positions() - m.clip.positions()).max() < 1e-6
