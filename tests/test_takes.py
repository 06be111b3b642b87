"""Multi-character takes (authoring.takes, authoring.procedural.interactions): the shared clock,
files and determinism, whether the performers really interact (measured from forward
kinematics of the written takes, not from the generator's own numbers), foot sliding by the
capture checker, the CMU salsa duet import and the CLI."""
from __future__ import annotations

import json

import numpy as np
import pytest

from authoring.capture_quality import take_quality
from authoring.takes import (DEFAULT_KINDS, Take, TakeError, generate_takes, import_cmu_duet, load_take,
                             load_takes, write_takes)
from runtime.motion.fk import end_site_positions

SALSA = ("cmu_60_10_salsa_duet_A_male.bvh", "cmu_61_10_salsa_duet_B_female.bvh")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """Every scene kind once (seed 0), written and read back from disk."""
    out = tmp_path_factory.mktemp("takes")
    manifest = write_takes(out, 0)
    by_kind = {}
    for t in load_takes([out]):
        by_kind.setdefault(t.name.rsplit("_", 1)[0], t)
    return out, manifest, by_kind


def _fk(clip):
    gr, gp = clip.fk()
    return gp, end_site_positions(clip.skeleton, gr, gp)


def _hand_centre(clip, side):
    """Midway between the hand joint and the index-finger end site (world, per frame)."""
    gp, es = _fk(clip)
    sk = clip.skeleton
    hand = sk.index("RightHand" if side else "LeftHand")
    idx = sk.index("RightHandIndex1" if side else "LeftHandIndex1")
    e = [j for j, _ in sk.end_sites].index(idx)
    return 0.5 * (gp[:, hand] + es[:, e])


def _root_xz(clip):
    return clip.world_root()[0][:, [0, 2]]


def _event(take, label):
    return next(e for e in take.events if e["label"] == label)


# -- structure, files, determinism -------------------------------------------------------------
def test_every_kind_is_written_on_one_clock(written):
    out, manifest, by_kind = written
    assert len(manifest["takes"]) == len(DEFAULT_KINDS)
    people = {"handshake": 2, "high_five": 2, "bow": 2, "bump": 2, "box_pass": 2, "dash_dodge": 2,
              "relay": 3, "bow3": 3, "handshake_bystander": 3, "walker": 1, "pair_apart": 2}
    for kind, n in people.items():
        tk = by_kind[kind]
        assert tk.num_people == n, kind
        F = tk.num_frames
        assert all(c.num_frames == F and c.fps == 30.0 for c in tk.clips)
        for segs in tk.segments:                       # labels tile every frame of every performer
            assert segs[0][0] == 0 and segs[-1][1] == F
            assert all(a[1] == b[0] for a, b in zip(segs[:-1], segs[1:]))
        for e in tk.events:
            assert 0 <= e["start"] <= e["end"] < F and len(e["people"]) >= 2
        # nobody teleports: root steps stay below a sprint
        for c in tk.clips:
            assert np.linalg.norm(np.diff(c.world_root()[0], axis=0), axis=1).max() < 0.1
    assert not by_kind["walker"].events and not by_kind["pair_apart"].events
    assert (out / "takes.json").is_file()


def test_same_seed_gives_byte_identical_takes(tmp_path):
    kinds = ("handshake", "bump")
    a = write_takes(tmp_path / "a", 7, kinds)
    b = write_takes(tmp_path / "b", 7, kinds)
    assert a == b
    files = sorted(p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file())
    assert len(files) == 1 + 2 * 5                  # takes.json + per take: take.json, 2 x (bvh + labels)
    for f in files:
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f
    c = write_takes(tmp_path / "c", 8, kinds)
    assert c["takes"][0]["files"] != a["takes"][0]["files"]


def test_take_round_trip(written, tmp_path):
    tk = generate_takes(5, kinds=("box_pass",))[0]
    d = tk.save(tmp_path / "t")
    back = load_take(d)
    assert back.people == tk.people and back.events == tk.events and back.num_frames == tk.num_frames
    assert back.segments == [list(s) for s in tk.segments]
    for c0, c1 in zip(tk.clips, back.clips):
        assert np.abs(c0.positions() - c1.positions()).max() < 1e-4
    assert back.props[0]["track"] == tk.props[0]["track"]


def test_bad_take_directories_are_named(written, tmp_path):
    out, _, by_kind = written
    src = out / by_kind["handshake"].name
    d = tmp_path / "broken"
    d.mkdir()
    for f in src.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    (d / "B.bvh").unlink()
    with pytest.raises(TakeError, match=r"B\.bvh.*missing"):
        load_take(d)
    m = json.loads((src / "take.json").read_text())
    m["frames"] += 1
    (d / "B.bvh").write_bytes((src / "B.bvh").read_bytes())
    (d / "take.json").write_text(json.dumps(m))
    with pytest.raises(TakeError, match=r"A\.bvh: \d+ frames, take.json says"):
        load_take(d)
    (d / "take.json").write_text("{not json")
    with pytest.raises(TakeError, match="take.json"):
        load_take(d)
    with pytest.raises(TakeError, match="no such file"):
        load_takes([tmp_path / "nothing_here"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(TakeError, match="no take.json"):
        load_takes([tmp_path / "empty"])
    with pytest.raises(ValueError, match="frames"):
        tk = by_kind["handshake"]
        Take("x", 30.0, ["a", "b"], [tk.clips[0], tk.clips[1].copy(root_heading=tk.clips[1].root_heading[:-1],
                                                                    root_xz=tk.clips[1].root_xz[:-1],
                                                                    root_height=tk.clips[1].root_height[:-1],
                                                                    rotations=tk.clips[1].rotations[:-1])])


# -- the interactions are real -------------------------------------------------------------------
def _facing_each_other(tk, f, a=0, b=1, tol_deg=20.0):
    xa, xb = _root_xz(tk.clips[a])[f], _root_xz(tk.clips[b])[f]
    for c, p, q in ((tk.clips[a], xa, xb), (tk.clips[b], xb, xa)):
        h = c.world_heading()[f]
        fwd = np.array([np.sin(h), np.cos(h)])
        d = (q - p) / np.linalg.norm(q - p)
        assert np.degrees(np.arccos(np.clip(fwd @ d, -1, 1))) < tol_deg


@pytest.mark.parametrize("kind,label,height", [("handshake", "handshake", (0.85, 1.2)),
                                               ("high_five", "high_five", (1.45, 1.9))])
def test_right_hands_meet(written, kind, label, height):
    tk = written[2][kind]
    e = _event(tk, label)
    ha, hb = _hand_centre(tk.clips[0], 1), _hand_centre(tk.clips[1], 1)
    d = np.linalg.norm(ha - hb, axis=1)
    sl = slice(e["start"], e["end"] + 1)
    assert d[sl].max() < 0.05                          # palm to palm: within a few cm all the contact
    assert d[max(e["start"] - 45, 0)] > 0.3            # apart 1.5 s before
    assert height[0] < ha[sl, 1].mean() < height[1]
    _facing_each_other(tk, e["start"])


def test_bow_faces_the_partner_and_bends(written):
    tk = written[2]["bow"]
    e = _event(tk, "bow")
    _facing_each_other(tk, e["start"])
    for c in tk.clips:
        gp, es = _fk(c)
        head = es[:, [j for j, _ in c.skeleton.end_sites].index(c.skeleton.index("Head")), 1]
        assert head[e["start"]:e["end"] + 1].min() < head[e["start"]] - 0.2   # the head goes down
        assert abs(head[e["end"]] - head[e["start"]]) < 0.03                 # and comes back up


def test_bumped_performer_staggers_after_the_contact(written):
    tk = written[2]["bump"]
    A, B = tk.clips
    gA, _ = _fk(A)
    gB, _ = _fk(B)
    sh = A.skeleton.index("RightArm")
    d = np.linalg.norm(gA[:, sh] - gB[:, sh], axis=1)
    contact = np.flatnonzero(d < 0.16)                 # shoulder joints closer than two shoulders' radii
    assert len(contact) >= 2
    c = int(contact[0])
    xb = _root_xz(B)
    still = np.linalg.norm(xb[c - 15:c + 1] - xb[c], axis=1).max()
    assert still < 0.01                                # B stands still until the contact
    moved = np.linalg.norm(xb - xb[c], axis=1)
    first = int(np.flatnonzero(moved[c:] > 0.02)[0]) + c
    assert c < first <= c + 12                         # reacts after the contact, within 0.4 s
    assert moved[c:c + 30].max() > 0.2                 # and is pushed back a good step
    hb = B.world_heading()
    assert np.degrees(abs(hb[c + 30] - hb[c])) > 10   # twisting


def test_box_passes_from_hand_to_hand(written):
    tk = written[2]["box_pass"]
    prop = tk.props[0]
    e = _event(tk, "box_pass")
    a0, a1 = prop["pass_frames"]
    track = np.array(prop["track"])
    hands = [np.stack([_hand_centre(c, s) for s in (0, 1)], axis=1) for c in tk.clips]   # (F, 2, 3)

    def dist(person, f):
        return np.linalg.norm(hands[person][f] - track[f - a0], axis=1).max()

    assert dist(0, a0) < 0.35 and dist(1, a0) > 0.35             # giver holds it, taker does not
    for f in range(e["start"], e["end"] + 1):                      # both hold it at the hand-over
        assert dist(0, f) < 0.35 and dist(1, f) < 0.35
    assert dist(1, a1) < 0.35 and dist(0, a1) > 0.35             # taker holds it, giver let go
    gap = np.linalg.norm(hands[0][e["start"]:e["end"] + 1, :, None] - hands[1][e["start"]:e["end"] + 1, None],
                         axis=-1).min(axis=(1, 2))
    assert gap.max() < 0.12                                        # hands side by side on the box
    _facing_each_other(tk, e["start"])


def test_dodger_reacts_after_the_dasher_approaches(written):
    tk = written[2]["dash_dodge"]
    A, B = tk.clips
    xa, xb = _root_xz(A), _root_xz(B)
    dist = np.linalg.norm(xa - xb, axis=1)
    e = _event(tk, "dodge")
    f = e["start"]
    moved = np.linalg.norm(xb - xb[f - 5], axis=1)
    start = int(np.flatnonzero(moved[f - 5:] > 0.03)[0]) + f - 5
    assert dist[start] < 3.5                                       # the dasher is close when B moves
    assert dist[start - 20] > dist[start] + 0.5                    # and has been approaching fast
    speed_a = np.linalg.norm(np.diff(xa, axis=0), axis=1) * 30
    assert speed_a[start - 10:start].mean() > 1.5
    assert moved[start:start + 30].max() > 0.45                    # a real side-step
    assert dist[start:start + 60].min() > 0.4                      # and the dasher misses


def test_three_person_takes(written):
    relay = written[2]["relay"]
    pairs = [tuple(e["people"]) for e in relay.events if e["kind"] == "contact"]
    assert pairs == [(0, 1), (1, 2)]
    bow3 = written[2]["bow3"]
    assert _event(bow3, "bow")["people"] == [0, 1, 2]
    by = written[2]["handshake_bystander"]
    xc = _root_xz(by.clips[2])
    for other in (0, 1):
        assert np.linalg.norm(xc - _root_xz(by.clips[other]), axis=1).min() > 4.0


def test_feet_do_not_skate(written):
    out, manifest, _ = written
    for row in manifest["takes"]:
        s = take_quality(out / row["name"])["summary"]
        assert s["foot_contact_mean_speed_m_s"] < 0.02, row["name"]
        assert s["foot_contact_p95_speed_m_s"] < 0.02, row["name"]
        assert s["hyperextended_frames"] == 0, row["name"]
        assert s["labels_tile_frames"], row["name"]


# -- CMU salsa duet ---------------------------------------------------------------------------------
def test_salsa_duet_import(cmu_dir, tmp_path):
    from authoring.bvh import read_bvh

    tk = import_cmu_duet(cmu_dir / SALSA[0], cmu_dir / SALSA[1])
    assert tk.num_people == 2 and tk.fps == 30.0 and tk.num_frames == 599      # 1197 frames at 60 Hz
    src = read_bvh(cmu_dir / SALSA[1], drop_first_frame=False).clip
    assert src.fps == 60.0
    # frame k at 30 Hz is frame 2k of the 60 Hz file (one clock, no offset)
    assert np.abs(tk.clips[1].positions()[[0, 100, 598]] - src.positions()[[0, 200, 1196]]).max() < 1e-4
    d = tk.save(tmp_path / "duet")
    back = load_take(d)
    assert back.num_frames == 599 and back.people == tk.people
    dist = np.linalg.norm(_root_xz(back.clips[0]) - _root_xz(back.clips[1]), axis=1)
    assert dist.min() < 1.0                  # the dancers come within arm's reach of each other


# -- CLI -----------------------------------------------------------------------------------------------
def test_capture_takes_cli(tmp_path, capsys):
    from authoring.cli import main

    rc = main(["capture", "--takes", "--kinds", "handshake,walker", "--seed", "2", "--out", str(tmp_path / "t"),
               "--quiet"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "handshake(0, 1)@" in out and "foot sliding" in out
    assert (tmp_path / "t" / "handshake_000" / "take.json").is_file()
    assert (tmp_path / "t" / "walker_001" / "A.bvh").is_file()
    rc = main(["capture", "--takes", "--kinds", "tango", "--out", str(tmp_path / "u"), "--quiet"])
    assert rc == 2
    assert "tango" in capsys.readouterr().err
