"""Motion patch data model and the motion_patches pack (Kim, Hwang, Hyun and Lee 2012, section 3)."""
import numpy as np
import pytest

from runtime.assets import AssetError, load_pack, save_pack
from runtime.motion.planar import rotate_xz
from runtime.motion.fk import end_site_positions, forward_kinematics
from runtime.motion import quat
from runtime.tiling.patch import (Constraint, Fragment, Patch, PatchLibrary, single_character_patches,
                                  PACK_KIND, PACK_VERSION)


def _edge_fragment(graph, e, origin=(0.0, 0.0, 0.0), t0=0.0, classes=None):
    a, b = graph.edge_start[e], graph.edge_start[e + 1]
    ox, oz, oh = origin
    xz = rotate_xz(graph.frame_xz[a:b], oh) + [ox, oz]
    ent, ext = classes if classes is not None else (graph.edge_src[e], graph.edge_dst[e])
    return Fragment(t0, xz, graph.frame_heading[a:b] + oh, graph.frame_height[a:b], graph.frame_rotations[a:b], ent, ext)


def _two_person(graph):
    walk = [e for e in range(graph.num_edges) if graph.edge_src[e] == 1 and graph.edge_dst[e] == 1]
    fa = _edge_fragment(graph, walk[0], (0.0, 0.0, 0.0))
    fb = _edge_fragment(graph, walk[1], (0.3, 2.5, np.pi), t0=0.2, classes=(1, -1))
    con = Constraint.measure([fa, fb], 0, 10, 1, 4, "contact")
    return Patch.from_fragments("meet", ("handshake", "friendly"), graph.skeleton, [fa, fb], [con])


def test_fragment_and_ports(default_graph):
    p = _two_person(default_graph)
    assert p.num_characters == 2 and len(p.entries) == 2 and len(p.exits) == 2
    # recentred: earliest entry at t=0, root path bounds centred on the origin
    assert min(port.time for port in p.entries) == 0.0
    allxz = np.concatenate([f.root_xz for f in p.fragments])
    assert np.allclose(allxz.min(0) + allxz.max(0), 0.0)
    assert p.entries[1].time == pytest.approx(0.0) or p.entries[0].time == pytest.approx(0.0)
    assert p.exits[1].pose_class == -1 and not p.exits[1].open and p.entries[1].open
    assert p.duration == pytest.approx(max(f.t1(30.0) for f in p.fragments))
    # the measured constraint is unchanged by recentring
    assert p.constraint_error() < 1e-9
    c = p.constraints[0]
    fa, fb = p.fragments
    rel = rotate_xz(fb.root_xz[4] - fa.root_xz[10], -fa.heading[10])
    assert np.allclose(rel, c.rel_position) and c.dt == pytest.approx(0.2 + 4 / 30 - 10 / 30)


def test_boxes_follow_the_root(default_graph):
    """A box is stored relative to the root in its heading frame; placed anywhere, the
    character's FK joints lie inside the box moved with the root."""
    g = default_graph
    p = _two_person(g)
    f, box = p.fragments[0], p.boxes[0]
    h = f.heading + 0.7
    xz = rotate_xz(f.root_xz, 0.7) + [3.0, -2.0]
    pos = np.stack([xz[:, 0], f.root_height, xz[:, 1]], -1)
    rot = f.rotations.astype(np.float64).copy()
    rot[:, 0] = quat.mul(quat.from_yaw(h), rot[:, 0])
    gr, gp = forward_kinematics(g.skeleton, pos, rot)
    pts = np.concatenate([gp, end_site_positions(g.skeleton, gr, gp)], 1)
    local = rotate_xz(pts[..., [0, 2]] - xz[:, None], -h[:, None])
    eps = 1e-4
    assert np.all(local[..., 0] >= box[:, None, 0] - eps) and np.all(local[..., 0] <= box[:, None, 3] + eps)
    assert np.all(local[..., 1] >= box[:, None, 2] - eps) and np.all(local[..., 1] <= box[:, None, 5] + eps)
    assert np.all(pts[..., 1] <= box[:, None, 4] + eps)
    # and the box is tight: some joint touches each side on every frame
    assert np.allclose(local[..., 0].min(1), box[:, 0], atol=1e-4)


def test_pack_round_trip(default_graph, tmp_path):
    g = default_graph
    lib = single_character_patches(g)
    assert len(lib) > 20 and lib.num_pose_classes == g.num_nodes
    assert {"walk", "idle", "turn"} <= set(lib.summary()["labels"])
    lib2 = PatchLibrary(g.skeleton, lib.patches + [_two_person(g)], lib.pose_class_names,
                        lib.pose_class_rotations, lib.pose_class_height, meta={"note": "test"})
    path = tmp_path / "p.cwpack"
    lib2.save(path)
    back = PatchLibrary.load(path)
    assert len(back) == len(lib2) and back.pose_class_names == lib2.pose_class_names
    assert back.meta["note"] == "test" and back.skeleton.fingerprint == g.skeleton.fingerprint
    for p, q in zip(lib2.patches, back.patches):
        assert p.name == q.name and p.labels == q.labels and p.meta == q.meta
        for f, h in zip(p.fragments, q.fragments):
            assert f.t0 == h.t0 and (f.entry_class, f.exit_class, f.entry_open, f.exit_open) == \
                (h.entry_class, h.exit_class, h.entry_open, h.exit_open)
            assert np.array_equal(f.root_xz, h.root_xz) and np.array_equal(f.heading, h.heading)
            assert np.array_equal(f.rotations, h.rotations) and np.array_equal(f.root_height, h.root_height)
        for b1, b2 in zip(p.boxes, q.boxes):
            assert np.array_equal(b1, b2)
        assert len(p.constraints) == len(q.constraints)
        for c, d in zip(p.constraints, q.constraints):
            assert (c.frag_a, c.frame_a, c.frag_b, c.frame_b, c.label) == (d.frag_a, d.frame_a, d.frag_b, d.frame_b, d.label)
            assert np.array_equal(c.rel_position, d.rel_position) and c.dt == d.dt and c.rel_direction == d.rel_direction
    assert np.array_equal(back.pose_class_rotations, lib2.pose_class_rotations)
    # the index of ports by pose class agrees with the patches
    ent = back.ports_by_class("entry")
    assert all(back.patches[p].fragments[f].entry_class == c for c, lst in ent.items() for p, f in lst)


def test_pack_errors(default_graph, tmp_path):
    g = default_graph
    lib = PatchLibrary(g.skeleton, [_two_person(g)])
    path = tmp_path / "p.cwpack"
    lib.save(path)
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    bad = tmp_path / "bad.cwpack"
    bad.write_bytes(bytes(raw))
    with pytest.raises(AssetError, match="bad.cwpack"):
        PatchLibrary.load(bad)
    other = tmp_path / "other.cwpack"
    save_pack(other, "motion_graph", 1, {}, {})
    with pytest.raises(AssetError, match="wrong kind"):
        PatchLibrary.load(other)
    newer = tmp_path / "newer.cwpack"
    pk = load_pack(path)
    save_pack(newer, PACK_KIND, PACK_VERSION + 1, pk.meta, pk.arrays)
    with pytest.raises(AssetError, match="version"):
        PatchLibrary.load(newer)
    # structurally inconsistent: offsets that run past the frames
    arrays = dict(pk.arrays)
    arrays["frag_frame_start"] = arrays["frag_frame_start"] + np.array([0, 0, 5])
    broken = tmp_path / "broken.cwpack"
    save_pack(broken, PACK_KIND, PACK_VERSION, pk.meta, arrays)
    with pytest.raises(AssetError, match="inconsistent"):
        PatchLibrary.load(broken)
    meta = dict(pk.meta)
    del meta["patch_names"]
    missing = tmp_path / "missing.cwpack"
    save_pack(missing, PACK_KIND, PACK_VERSION, meta, pk.arrays)
    with pytest.raises(AssetError, match="missing"):
        PatchLibrary.load(missing)


def test_constraint_out_of_range_is_rejected(default_graph):
    g = default_graph
    f = _edge_fragment(g, 0)
    with pytest.raises(ValueError, match="out of range"):
        Patch.from_fragments("x", (), g.skeleton, [f], [Constraint(0, 0, 1, 0, (0, 1), 0.0, 0.0)])


def test_matching_classes_share_the_pose(default_graph):
    """Single-character patches end and start on graph hubs: an exit and an entry of the same
    pose class hold the same pose, so stitching them is seamless."""
    lib = single_character_patches(default_graph)
    ent = lib.ports_by_class("entry")
    checked = 0
    for p in lib.patches[:20]:
        f = p.fragments[0]
        for q, k in ent.get(f.exit_class, [])[:3]:
            g = lib.patches[q].fragments[k]
            assert np.abs(f.rotations[-1] - g.rotations[0]).max() < 1e-3 or \
                np.abs(np.abs(np.sum(f.rotations[-1] * g.rotations[0], -1)) - 1).max() < 1e-5
            assert abs(f.root_height[-1] - g.root_height[0]) < 1e-3
            checked += 1
    assert checked > 20


def test_merged_libraries_renumber_pose_classes(default_graph):
    g = default_graph
    a = single_character_patches(g, labels=("walk",))
    b = PatchLibrary(g.skeleton, [_two_person(g)], ["x", "y", "node:1"])
    # the two-person patch uses classes 1 (entries) and -1: in b, class 1 is "y"
    m = a.merged(b)
    assert len(m) == len(a) + 1 and m.pose_class_names[:len(a.pose_class_names)] == a.pose_class_names
    last = m.patches[-1]
    assert m.pose_class_names[last.fragments[0].entry_class] == "y"
    assert last.fragments[1].exit_class == -1
    assert m.frame_rotations.shape[0] == sum(p.num_frames for p in m.patches)
    assert m.fragment_offset(len(m) - 1, 1) == m.frame_rotations.shape[0] - last.fragments[1].num_frames
