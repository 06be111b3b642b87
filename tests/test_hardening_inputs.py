"""Bad inputs are one-line errors naming the place, before any work: scenario keys and types,
limits, USD names, bounded reads of packs / BVH / TOML, temporary files of killed writers."""
import os
import re

import numpy as np
import pytest

from runtime.assets import AssetError, atomic_path, atomic_write_bytes, load_pack, save_pack, sweep_stale_temps
from runtime.crowd.scenario import ScenarioError, load_scenario, parse_scenario, prim_name, read_scenario_toml
from runtime.limits import MAX_CHARACTER_SECONDS, MAX_DURATION

LABELS = {"stand", "walk", "sit", "carry"}


def _doc(**top):
    d = {"name": "t", "duration": 10.0, "seed": 0,
         "character": [{"name": "a", "start": {"position": [0.0, 0.0], "heading": 0.0, "pose": "stand"},
                        "goal": [{"position": [3.0, 0.0]}, {"position": [3.0, 3.0], "time": [8.0, 9.0]}]},
                       {"name": "b", "start": {"position": [5.0, 0.0]},
                        "goal": [{"position": [5.0, 3.0], "after": {"character": "a", "goal": 0}}]}]}
    d.update(top)
    return d


def _set(doc, path, value):
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return doc


# (what the issue lists, where, value, words the message must hold: file, table, key, reason)
TYPE_CASES = [
    ("heading given as a list", ("character", 0, "start", "heading"), [90.0],
     ["character 'a' start", "heading", "must be a number"]),
    ("goal heading NaN", ("character", 0, "goal", 0, "heading"), float("nan"),
     ["character 'a' goal 0", "heading", "finite"]),
    ("passes = 'many'", ("synthesis",), {"passes": "many"}, ["[synthesis]", "passes", "integer"]),
    ("synthesis = 5", ("synthesis",), 5, ["synthesis", "must be a table"]),
    ("typo in [synthesis]", ("synthesis",), {"pases": 2}, ["[synthesis]", "unknown key 'pases'", "passes"]),
    ("after.within = 3", ("character", 1, "goal", 0, "after", "within"), 3,
     ["character 'b' goal 0 after", "within", "[a, b]"]),
    ("reversed after.within", ("character", 1, "goal", 0, "after", "within"), [2.0, 1.0],
     ["character 'b' goal 0 after", "within", "empty"]),
    ("inf duration", ("duration",), float("inf"), ["top level", "duration", "finite"]),
    ("duration 1e7", ("duration",), 1e7, ["top level", "duration", f"at most {MAX_DURATION:g}"]),
    ("negative seed", ("seed",), -1, ["top level", "seed", "integer from 0"]),
    ("library = 5", ("library",), 5, ["top level", "library", "must be a string"]),
    ("position of three numbers", ("character", 0, "goal", 1, "position"), [1.0, 2.0, 3.0],
     ["character 'a' goal 1", "position", "[x, z]"]),
    ("time window reversed", ("character", 0, "goal", 1, "time"), [9.0, 8.0],
     ["character 'a' goal 1", "time", "empty"]),
    ("time given as text", ("character", 0, "goal", 1, "time"), "soon", ["character 'a' goal 1", "time"]),
    ("a boolean as a number", ("character", 0, "start", "heading"), True, ["character 'a' start", "heading"]),
    ("name not a string", ("character", 0, "name"), 7, ["character 0", "name", "must be a string"]),
    ("empty name", ("character", 0, "name"), "", ["character 0", "name", "must not be empty"]),
    ("unknown goal key", ("character", 0, "goal", 0, "speed"), 2.0, ["character 'a' goal 0", "unknown key 'speed'"]),
    ("epsilon with a zero", ("synthesis",), {"epsilon": [0.02, 0.0, 0.1]}, ["[synthesis]", "epsilon"]),
    ("flock recipe too large", ("flock",), [{"ddg": {"agents": 100000}}], ["flock 'flock0' ddg", "agents"]),
    ("flock count a float", ("flock",), [{"ddg": "x.cwpack", "count": 2.5}], ["flock 'flock0'", "count", "integer"]),
]


@pytest.mark.parametrize("what,path,value,words", TYPE_CASES, ids=[c[0] for c in TYPE_CASES])
def test_scenario_type_errors_name_file_table_and_key(what, path, value, words):
    with pytest.raises(ScenarioError) as e:
        parse_scenario(_set(_doc(), path, value), "dir/scenario.toml", node_labels=LABELS)
    msg = str(e.value)
    assert msg.startswith("dir/scenario.toml: ") and "\n" not in msg, msg
    for w in words:
        assert w in msg, (w, msg)


def test_the_unedited_scenario_is_valid():
    sc = parse_scenario(_doc(), "dir/scenario.toml", node_labels=LABELS)
    assert [c.name for c in sc.characters] == ["a", "b"] and sc.characters[0].goals[1].time == (8.0, 9.0)


def test_characters_times_duration_has_a_limit():
    chars = [{"name": f"c{i}", "start": {"position": [float(i), 0.0]}} for i in range(100)]
    d = _doc(character=chars, duration=MAX_CHARACTER_SECONDS / 100 + 1)
    with pytest.raises(ScenarioError, match=r"100 characters x 601 s is more than the limit of 60000"):
        parse_scenario(d, "s.toml")
    d["duration"] = MAX_CHARACTER_SECONDS / 100
    assert len(parse_scenario(d, "s.toml").characters) == 100


def test_toml_syntax_errors_and_size_name_the_file(tmp_path):
    p = tmp_path / "scenario.toml"
    p.write_text('name = "x"\nduration = = 3\n')
    with pytest.raises(ScenarioError, match=re.escape(f"{p}: not valid TOML: ") + r".*line 2"):
        load_scenario(tmp_path)
    p.write_bytes(b"# " + b"x" * (17 << 20))
    with pytest.raises(ScenarioError, match=re.escape(f"{p}: larger than the 16 MB limit")):
        load_scenario(p)
    p.write_bytes(b'name = "\xff"\n')
    with pytest.raises(ScenarioError, match="not UTF-8"):
        load_scenario(p)
    d = tmp_path / "sample"
    d.mkdir()
    with pytest.raises(ScenarioError, match=re.escape(f"{d / 'scenario.toml'}: file not found")):
        load_scenario(d)
    (d / "scenario.toml").mkdir()
    with pytest.raises(ScenarioError, match=re.escape(f"{d / 'scenario.toml'}: not a regular file (a directory)")):
        read_scenario_toml(d / "scenario.toml")
    with pytest.raises(ScenarioError, match="/dev/zero: not a regular file"):
        read_scenario_toml("/dev/zero")


# -- names ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name,usd", [("bob smith", "bob_smith"), ("a/b", "a_b"), ("1st", "_1st"), ("Zoë", "Zo_"),
                                      ("c01", "c01"), ("_x", "_x"), ("a.b-c", "a_b_c")])
def test_prim_names(name, usd):
    assert prim_name(name) == usd
    assert re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", prim_name(name))


def test_names_that_become_one_prim_are_an_error_before_planning():
    d = _doc()
    d["character"][0]["name"], d["character"][1]["name"] = "x y", "x_y"
    d["character"][1]["goal"][0].pop("after")
    with pytest.raises(ScenarioError) as e:
        parse_scenario(d, "s.toml")
    assert "character 'x y' and character 'x_y' both become the USD character prim 'x_y'" in str(e.value)
    d["character"][1]["name"] = "x z"
    assert [c.name for c in parse_scenario(d, "s.toml").characters] == ["x y", "x z"]


# -- bounded reads ---------------------------------------------------------------------------------
def test_packs_are_read_with_a_hard_limit(tmp_path):
    link = tmp_path / "lib.cwpack"
    link.symlink_to("/dev/zero")
    for p in (link, "/dev/zero"):
        with pytest.raises(AssetError, match="not a regular file"):
            load_pack(p)
    os.mkfifo(tmp_path / "pipe.cwpack")
    with pytest.raises(AssetError, match="not a regular file"):
        load_pack(tmp_path / "pipe.cwpack")           # does not wait for a writer
    (tmp_path / "text.cwpack").write_bytes(b"hello" * 1000)
    with pytest.raises(AssetError, match="starts with byte 0x68, not a msgpack map"):
        load_pack(tmp_path / "text.cwpack")
    with pytest.raises(AssetError, match="file not found"):
        load_pack(tmp_path / "none.cwpack")


def test_pack_size_limit_holds_whatever_stat_says(tmp_path, monkeypatch):
    import runtime.assets as assets
    p = save_pack(tmp_path / "a.cwpack", "k", 1, {}, {"x": np.zeros(1000)})
    monkeypatch.setattr(assets, "MAX_PACK_BYTES", 4000)
    with pytest.raises(AssetError, match="larger than the"):
        load_pack(p)
    monkeypatch.setattr(assets, "MAX_PACK_BYTES", 1 << 20)
    assert load_pack(p).arrays["x"].shape == (1000,)


def test_bvh_is_read_with_a_hard_limit(tmp_path):
    from authoring.bvh import BVHError, read_bvh
    link = tmp_path / "walk.bvh"
    link.symlink_to("/dev/zero")
    with pytest.raises(BVHError, match="not a regular file"):
        read_bvh(link)
    with pytest.raises(OSError):
        read_bvh(tmp_path / "missing.bvh")


def test_library_dev_zero_is_a_clean_error(tmp_path):
    from runtime.library import load_library
    with pytest.raises(AssetError, match="/dev/zero: not a regular file"):
        load_library("/dev/zero")


# -- temporary files ---------------------------------------------------------------------------------
def test_temporaries_of_dead_writers_are_swept_and_a_failed_rename_leaks_nothing(tmp_path):
    target = tmp_path / "x.cwpack"
    dead = tmp_path / ".x.cwpack.tmp-999999999-abc.tmp"        # no such process
    dead.write_bytes(b"half")
    dead_dir = tmp_path / ".x.cwpack.tmp-999999999-def-clips"
    dead_dir.mkdir()
    mine = tmp_path / f".x.cwpack.tmp-{os.getpid()}-ghi.tmp"    # a running writer's: kept
    mine.write_bytes(b"busy")
    other = tmp_path / ".y.cwpack.tmp-999999999-abc.tmp"        # another file's: kept
    other.write_bytes(b"y")
    atomic_write_bytes(target, b"data")
    assert target.read_bytes() == b"data"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([target.name, mine.name, other.name])
    assert sweep_stale_temps(target) == []
    # a rename that fails (the target is a directory) leaves no temporary behind
    d = tmp_path / "adir"
    d.mkdir()
    (d / "f").write_bytes(b"")
    with pytest.raises(OSError):
        with atomic_path(d) as tmp:
            open(tmp, "wb").write(b"x")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".adir")]
    with pytest.raises(OSError):
        atomic_write_bytes(d, b"x")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".adir")]
