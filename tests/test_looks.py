"""Per-character looks (runtime.appearance) and the instanced bake that carries them: looks are
deterministic in (seed, name) and vary between characters; the instanced stage shares one
prototype per prop kind, validates, reads back the same tracks, binds every part to the material
of its look and each prop to its joint."""
import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdShade, UsdSkel, Vt

from runtime.appearance import PROPS, SHIRTS, SKIN, WIDTH_RANGE, looks_for, srgb_to_linear
from runtime.crowd.tracks import Track
from usd_io.crowd import build_crowd_stage, read_tracks
from usd_io.stage import save_stage
from usd_io.validate import errors, format_issues, validate_stage

NAMES = [f"c{i:03d}" for i in range(300)]


def test_looks_are_deterministic_and_independent_of_the_other_names():
    a = looks_for(NAMES, seed=4)
    b = looks_for(NAMES, seed=4)
    for f in ("part", "width", "prop", "prop_colour"):
        assert getattr(a, f).tobytes() == getattr(b, f).tobytes()
    # a character's look depends on its name and the seed only, not on who else is there
    sub = looks_for(NAMES[::-7], seed=4)
    idx = [NAMES.index(n) for n in NAMES[::-7]]
    np.testing.assert_array_equal(sub.part, a.part[idx])
    np.testing.assert_array_equal(sub.width, a.width[idx])
    np.testing.assert_array_equal(sub.prop, a.prop[idx])
    other = looks_for(NAMES, seed=5)
    assert (other.part != a.part).any(axis=1).mean() > 0.9


def test_looks_vary_between_characters_within_their_ranges():
    lk = looks_for(NAMES)
    col = lk.colours()
    assert col.shape == (300, 4, 3) and col.dtype == np.float32
    assert len(np.unique(lk.part[:, 1])) == len(SHIRTS)        # every shirt colour is worn
    assert len(np.unique(lk.part[:, 0])) == len(SKIN)          # and every skin tone
    assert len({tuple(r) for r in lk.part}) > 250              # few characters dress alike
    lo, hi = WIDTH_RANGE
    assert lo <= lk.width.min() and lk.width.max() <= hi and lk.width.std() > 0.04
    counts = np.bincount(lk.prop, minlength=len(PROPS))
    assert all(c > 30 for c in counts), counts                  # no prop, hats and bags all occur


def _tracks(graph, names, frames=30):
    rng = np.random.default_rng(2)
    out = {}
    for k, name in enumerate(names):
        a = int(rng.integers(0, len(graph.frame_heading) - frames - 1))
        fa = np.arange(a, a + frames)
        root = np.column_stack([np.full(frames, 2.0 * k), np.linspace(0, 1, frames), np.zeros(frames)])
        out[name] = Track(fa, fa + 1, np.zeros(frames, np.float32), root, 0)
    return out


@pytest.fixture(scope="module")
def instanced_bake(default_graph, tmp_path_factory):
    names = NAMES[:12]
    tracks = _tracks(default_graph, names)
    out = tmp_path_factory.mktemp("looks") / "crowd.usdc"
    save_stage(build_crowd_stage(tracks, default_graph, 30.0, out_path=out, instancing=True), out)
    return out, tracks


def test_instanced_bake_shares_a_prototype_per_prop_kind(instanced_bake, default_graph):
    out, tracks = instanced_bake
    issues = validate_stage(out)
    assert errors(issues) == [], format_issues(issues)
    st = Usd.Stage.Open(str(out))
    lk = looks_for(list(tracks))
    rigs = [st.GetPrimAtPath(f"/World/Characters/{n}/Rig") for n in tracks]
    assert all(r.IsInstance() for r in rigs)
    protos = {r.GetPrototype().GetPath() for r in rigs}
    assert len(protos) == len(set(lk.prop.tolist())) == len(st.GetPrototypes())
    for r, prop in zip(rigs, lk.prop):
        kids = {c.GetName() for c in r.GetPrototype().GetChildren()}
        assert {"Skel", "Skin", "Shirt", "Trousers", "Shoes"} <= kids
        assert ("Hat" in kids, "Bag" in kids) == (PROPS[prop] == "hat", PROPS[prop] == "bag")
    # the animation is outside the instance, one per character, bound through the instance root
    cache = UsdSkel.Cache()
    for n in tracks:
        root = st.GetPrimAtPath(f"/World/Characters/{n}")
        cache.Populate(UsdSkel.Root(root), Usd.TraverseInstanceProxies())
        skel = UsdSkel.Skeleton(st.GetPrimAtPath(f"/World/Characters/{n}/Rig/Skel"))
        anim = cache.GetSkelQuery(skel).GetAnimQuery().GetPrim()
        assert anim.GetPath() == root.GetPath().AppendChild("Anim") and not anim.IsInstanceProxy()
    # the checker's reader gets the same tracks back
    back = read_tracks(out)
    assert sorted(back) == sorted(tracks)
    for n, tr in tracks.items():
        np.testing.assert_array_equal(back[n].frames_a, tr.frames_a)
        np.testing.assert_allclose(back[n].root, tr.root, atol=1e-12)


def test_every_part_has_the_material_of_its_look(instanced_bake):
    out, tracks = instanced_bake
    st = Usd.Stage.Open(str(out))
    lk = looks_for(list(tracks))
    col = lk.colours()
    seen = set()
    for i, n in enumerate(tracks):
        for k, part in enumerate(("Skin", "Shirt", "Trousers", "Shoes")):
            prim = st.GetPrimAtPath(f"/World/Characters/{n}/Rig/{part}")
            mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
            assert mat, prim.GetPath()
            shader = UsdShade.Shader(st.GetPrimAtPath(mat.GetPath().AppendChild("Surface")))
            c = np.array(shader.GetInput("diffuseColor").Get())
            np.testing.assert_allclose(c, srgb_to_linear(col[i, k]), atol=1e-6)
            if part == "Shirt":
                seen.add(tuple(c))
    assert len(seen) > 4


@pytest.mark.parametrize("instancing", [True, False])
def test_props_are_bound_to_their_joints(default_graph, tmp_path, instancing):
    names = [n for n, p in zip(NAMES, looks_for(NAMES).prop) if p > 0][:6]
    tracks = _tracks(default_graph, names)
    out = tmp_path / "props.usda"
    save_stage(build_crowd_stage(tracks, default_graph, 30.0, out_path=out, instancing=instancing), out)
    st = Usd.Stage.Open(str(out))
    sk = default_graph.skeleton
    want = {"hat": sk.index("Head"), "bag": sk.index("RightHand")}
    lk = looks_for(names)
    kinds = set()
    for i, n in enumerate(names):
        kind = PROPS[int(lk.prop[i])]
        kinds.add(kind)
        base = f"/World/Characters/{n}/Rig" if instancing else f"/World/Characters/{n}"
        prim = st.GetPrimAtPath(f"{base}/{kind.capitalize()}")
        assert prim and prim.IsA(UsdGeom.Mesh), prim.GetPath()
        cache = UsdSkel.Cache()
        cache.Populate(UsdSkel.Root(st.GetPrimAtPath(f"/World/Characters/{n}")), Usd.TraverseInstanceProxies())
        sq = cache.GetSkinningQuery(prim)
        ji = np.array(sq.GetJointIndicesPrimvar().Get())
        assert set(ji.tolist()) == {want[kind]}, (n, kind)
        # and it moves with that joint: its centre keeps its distance from the joint over time
        skel = UsdSkel.Skeleton(st.GetPrimAtPath(f"{base}/Skel"))
        skq = cache.GetSkelQuery(skel)
        d = []
        for t in (0.0, 15.0, 29.0):
            pts = np.array(UsdGeom.Mesh(prim).GetPointsAttr().Get(t))
            v = Vt.Vec3fArray.FromNumpy(pts.astype(np.float32))
            assert sq.ComputeSkinnedPoints(skq.ComputeSkinningTransforms(t), v, t)
            jw = np.array(skq.ComputeJointSkelTransforms(t))[want[kind], 3, :3]     # skeleton space, as skinned
            d.append(np.linalg.norm(np.array(v).mean(axis=0) - jw))
        assert max(d) - min(d) < 1e-4 and max(d) < 0.4
    assert kinds == {"hat", "bag"}


def test_viewer_draws_the_look_width_and_props(default_graph):
    """The viewer's capsules take each figure's colours and width from its look, and hats and
    bags sit on the head and in the right hand (numpy side of the character pass)."""
    from runtime.viewer.figures import PROP_CAPSULES, FigureStyle, bone_arrays, prop_arrays
    sk = default_graph.skeleton
    style = FigureStyle.for_skeleton(sk)
    names = NAMES[:40]
    lk = looks_for(names)
    P = style.points(_rest_positions(sk, len(names)))
    idx = np.arange(len(names))
    pal = lk.colours()
    e, y = bone_arrays(P, idx, style.near, pal, lk.width)
    y = y.reshape(len(names), len(style.near), 4)
    np.testing.assert_allclose(y[:, :, 0], style.near.radius[None] * lk.width[:, None], rtol=1e-6)
    np.testing.assert_array_equal(y[:, :, 1:], pal[:, style.near.part])
    e, y = prop_arrays(P, idx, style, lk.prop, lk.prop_colours())
    hats, bags = np.flatnonzero(lk.prop == 1), np.flatnonzero(lk.prop == 2)
    assert len(y) == len(hats) + len(bags) and len(hats) and len(bags)
    e = e.reshape(-1, 2, 3)
    head, hand = sk.index("Head"), sk.index("RightHand")
    np.testing.assert_allclose(np.linalg.norm(e[:len(hats), 0] - P[hats, head], axis=1), PROP_CAPSULES["hat"][0],
                               rtol=1e-4)
    np.testing.assert_allclose(np.linalg.norm(e[len(hats):, 0] - P[bags, hand], axis=1), PROP_CAPSULES["bag"][0],
                               rtol=1e-4)
    np.testing.assert_array_equal(y[:len(hats), 1:], lk.prop_colours()[hats])


def _rest_positions(sk, n):
    from runtime.motion import quat
    from runtime.motion.fk import forward_kinematics
    _, gp = forward_kinematics(sk, sk.offsets[0], quat.identity((sk.num_joints,)))
    return np.repeat(gp[None], n, axis=0) + np.arange(n)[:, None, None] * np.array([1.0, 0.0, 0.0])


def test_two_sets_of_characters_share_the_prototypes(default_graph, tmp_path):
    """A tiled zone's characters are baked into the crowd's stage by a second call: the
    prototypes and materials are made once, every character is an instance of them."""
    tracks = _tracks(default_graph, NAMES[:8])
    first = dict(list(tracks.items())[:5])
    second = dict(list(tracks.items())[5:])
    stage = build_crowd_stage(first, default_graph, 30.0, instancing=True)
    build_crowd_stage(second, default_graph, 30.0, stage=stage, instancing=True)
    out = tmp_path / "two.usdc"
    save_stage(stage, out)
    assert errors(validate_stage(out)) == []
    st = Usd.Stage.Open(str(out))
    assert all(st.GetPrimAtPath(f"/World/Characters/{n}/Rig").IsInstance() for n in tracks)
    assert len(st.GetPrototypes()) == len(set(looks_for(list(tracks)).prop.tolist()))
    assert sorted(read_tracks(out)) == sorted(tracks)


def test_instancing_with_value_clips_is_refused_before_planning(tmp_path):
    from pathlib import Path

    from authoring.commands import CLIError
    from authoring.commands.bake import bake_sample
    sample = Path(__file__).resolve().parents[1] / "samples" / "meet20"
    with pytest.raises(CLIError, match="--instancing and --clips-per"):
        bake_sample(sample, tmp_path / "out.usdc", instancing=True, clips_per=4)
    assert not any(tmp_path.iterdir())
