"""Foot contact detection on synthetic trajectories and on the procedural skeleton."""
import numpy as np
import pytest

from runtime.motion.contacts import detect_contacts, planted, CONTACT_POINTS


def _step_track(F=60, fps=30.0):
    """One point: on the ground frames 0-19, lifted and moving 20-39, on the ground 40-59."""
    p = np.zeros((F, 1, 3))
    t = np.arange(20, 40)
    p[t, 0, 1] = 0.15 * np.sin(np.pi * (t - 19) / 21)
    p[t, 0, 2] = np.linspace(0, 0.7, 20)
    p[40:, 0, 2] = 0.7
    return p, fps


def test_stance_and_swing_are_told_apart():
    p, fps = _step_track()
    c = detect_contacts(p, fps)[:, 0]
    assert c[:18].all() and c[43:].all()
    assert not c[23:37].any()


def test_hysteresis_keeps_a_contact_through_a_small_bump():
    p, fps = _step_track()
    p[5:16, 0, 1] = 0.06 - 0.012 * np.abs(np.arange(5, 16) - 10)   # peaks above enter, below exit height
    assert detect_contacts(p, fps)[:18, 0].all()
    assert not detect_contacts(p, fps, exit_height=0.055)[10, 0]


def test_short_contacts_are_dropped():
    p = np.zeros((30, 1, 3))
    p[:, 0, 1] = 0.3
    p[10:12, 0, 1] = 0.0
    assert not detect_contacts(p, 30.0, floor_percentile=0.0, min_frames=3).any()


def test_planted_is_heel_or_toe():
    c = np.array([[1, 0, 0, 0], [0, 1, 0, 1], [0, 0, 0, 0]], dtype=bool)
    assert planted(c).tolist() == [[True, False], [True, True], [False, False]]
    assert len(CONTACT_POINTS) == 4


def test_leg_joints_of_the_procedural_skeleton():
    from authoring.procedural.body import make_skeleton
    from runtime.motion.contacts import leg_joints
    legs = leg_joints(make_skeleton())
    assert (legs.toe >= 0).all() and legs.hip[0] != legs.hip[1]


# -- contacts as clip data ----------------------------------------------------------------------
def _clip_with_contacts(rng, frames=40):
    from conftest import random_clip
    c = random_clip(rng, frames)
    flags = rng.random((frames, 4)) < 0.5
    return c.copy(contacts=flags), flags


def test_clip_ops_carry_contacts_and_mirror_swaps_sides():
    from runtime.motion import ops
    rng = np.random.default_rng(3)
    c, flags = _clip_with_contacts(rng)
    np.testing.assert_array_equal(ops.cut(c, 5, 20).contacts, flags[5:20])
    np.testing.assert_array_equal(ops.reverse(c).contacts, flags[::-1])
    m = ops.mirror(c).contacts
    np.testing.assert_array_equal(m[:, [0, 1]], flags[:, [2, 3]])      # left columns hold the right foot
    np.testing.assert_array_equal(m[:, [2, 3]], flags[:, [0, 1]])
    j = ops.append(c, c)
    assert j.contacts.shape == (2 * len(flags) - 1, 4)
    np.testing.assert_array_equal(j.contacts[len(flags):], flags[1:])
    assert ops.append(c, c.copy(contacts=None)).contacts is None
    r = ops.resample(c, num_frames=79)                       # twice the rate: every frame twice
    np.testing.assert_array_equal(r.contacts[::2], flags)
    assert ops.cut(c.copy(contacts=None), 3).contacts is None
    with pytest.raises(ValueError, match="contacts shape"):
        c.copy(contacts=flags[:-1])


def test_generated_contacts_hold_planted_points_still():
    """The generator's labels: planted points do not move, and the detector agrees with them
    on most frames."""
    from authoring.procedural import generate_session
    from runtime.motion.contacts import clip_contacts, contact_point_positions, leg_joints
    tk = generate_session(0.5, 0)[0]
    c = tk.clip.contacts
    assert c.shape == (tk.clip.num_frames, 4) and 0.5 < c.mean() < 0.95
    gr, gp = tk.clip.fk()
    p = contact_point_positions(leg_joints(tk.clip.skeleton), gr, gp)
    v = np.linalg.norm(np.diff(p[..., [0, 2]], axis=0), axis=-1) * tk.clip.fps
    both = c[1:] & c[:-1]
    assert np.percentile(v[both], 99) < 0.02                  # m/s
    assert (clip_contacts(tk.clip) == c).mean() > 0.85


def test_take_sidecar_contacts_reach_the_graph_and_the_pack(tmp_path):
    import json
    from authoring.motion_graph.sources import LabelError, load_takes
    from authoring.procedural import write_session
    write_session(tmp_path, 0.5, 1)
    side = json.loads((tmp_path / "take_000.labels.json").read_text())
    assert set(side["contacts"]) == set(CONTACT_POINTS)
    t = load_takes([tmp_path])[0]
    assert t.clip.contacts is not None
    runs = side["contacts"]["left_heel"]
    a, b = runs[1]
    assert t.clip.contacts[a:b, 0].all() and not t.clip.contacts[b, 0]
    side["contacts"]["left_toe"] = [[5, 2]]
    (tmp_path / "take_000.labels.json").write_text(json.dumps(side))
    with pytest.raises(LabelError, match=r"take_000.labels.json: contacts left_toe run 0"):
        load_takes([tmp_path])


def test_graph_pack_carries_contacts_and_refuses_an_old_pack(default_graph, tmp_path):
    from runtime.assets import AssetError, load_pack, save_pack
    from runtime.motion.graph import PACK_KIND, PACK_VERSION, MotionGraph
    g = default_graph
    assert g.frame_contacts.shape == (len(g.frame_heading), 4) and g.frame_contacts.any()
    e = int(np.argmax(g.edge_frames))
    np.testing.assert_array_equal(g.edge_clip(e).contacts,
                                  g.frame_contacts[g.edge_start[e]:g.edge_start[e + 1]])
    p = tmp_path / "lib.cwpack"
    g.save(p)
    np.testing.assert_array_equal(MotionGraph.load(p).frame_contacts, g.frame_contacts)
    pk = load_pack(p)
    arrays = {k: v for k, v in pk.arrays.items() if k != "frame_contacts"}
    save_pack(p, PACK_KIND, PACK_VERSION - 1, pk.meta, arrays)
    with pytest.raises(AssetError, match="older crowdweave; rebuild it"):
        MotionGraph.load(p)


def test_bvh_import_detects_contacts(cmu_dir):
    from authoring.bvh import bvh_summary, read_bvh
    m = read_bvh(cmu_dir / "cmu_02_01_walk.bvh", fps=30.0)
    c = m.clip.contacts
    assert c is not None and c.shape == (m.clip.num_frames, 4)
    feet = planted(c)
    assert feet.any(axis=1).mean() > 0.9 and (feet.sum(axis=1) == 1).mean() > 0.3   # walking: mostly one foot
    s = bvh_summary(cmu_dir / "cmu_02_01_walk.bvh")
    assert s["contacts"]["source"] == "detected"


def test_patch_pack_carries_contacts(default_graph, tmp_path):
    from runtime.tiling.patch import PatchLibrary, single_character_patches
    lib = single_character_patches(default_graph, max_per_pair=1)
    f = lib.patches[0].fragments[0]
    e = lib.patches[0].meta["edge"]
    np.testing.assert_array_equal(f.contacts, default_graph.frame_contacts[default_graph.edge_start[e]:
                                                                           default_graph.edge_start[e + 1]])
    p = tmp_path / "patches.cwpack"
    lib.save(p)
    back = PatchLibrary.load(p)
    np.testing.assert_array_equal(back.frame_contacts, lib.frame_contacts)
    assert back.frame_contacts.shape == (len(back.frame_height), 4) and back.frame_contacts.any()
