"""The command line with careless input: a failed check never replaces a good bake, unwritable
outputs and bad numbers are one-line errors before any work, odd names and odd worlds bake,
re-capturing into an old directory leaves no stale take."""
import json
import os
from pathlib import Path

import numpy as np
import pytest

from authoring.cli import main

ONE = '''name = "one"
duration = 6.0
seed = 0
{extra}
[[character]]
name = "{name}"
start = {{ position = [-6.0, -6.0], pose = "stand" }}
  [[character.goal]]
  position = [-4.5, -4.0]
'''


def _sample(d: Path, name="a", extra="", second=None) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    text = ONE.format(name=name, extra=extra)
    if second:
        text += (f'[[character]]\nname = "{second}"\nstart = {{ position = [6.0, 6.0], pose = "stand" }}\n'
                 '  [[character.goal]]\n  position = [4.5, 4.5]\n')
    (d / "scenario.toml").write_text(text)
    return d


def _listing(d: Path):
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def _fail_the_checker(monkeypatch):
    import runtime.crowd.checker as checker
    real = checker.check_crowd

    class Failed:
        def __init__(self, r):
            self.r = r

        def to_dict(self):
            d = self.r.to_dict()
            d["summary"]["passed"] = False
            return d
    monkeypatch.setattr(checker, "check_crowd", lambda *a, **k: Failed(real(*a, **k)))


@pytest.mark.parametrize("clips", [False, True])
def test_a_failed_check_never_replaces_the_good_bake(tmp_path, monkeypatch, capsys, default_graph, clips):
    s = _sample(tmp_path / "s")
    out_dir = tmp_path / "out"
    out, rep = out_dir / "one.usdc", out_dir / "one.json"
    extra = ["--clips-per", "1", "--workers", "1"] if clips else []
    assert main(["bake", str(s), "--out", str(out), "--report", str(rep), "--quiet", *extra]) == 0
    good = _listing(out_dir)
    _fail_the_checker(monkeypatch)
    assert main(["bake", str(s), "--out", str(out), "--report", str(rep), "--quiet", "--seed", "5", *extra]) == 1
    o = capsys.readouterr().out
    assert "checker: FAILED" in o and f"{out} not replaced" in o
    assert _listing(out_dir) == good                       # stage, report, clips: untouched; no temporary
    # --keep-failed: the failed stage and report beside the good ones
    assert main(["bake", str(s), "--out", str(out), "--report", str(rep), "--quiet", "--seed", "5", "--keep-failed",
                 *extra]) == 1
    now = _listing(out_dir)
    assert {k: v for k, v in now.items() if k in good} == good
    assert "one.failed.usdc" in now and "one.failed.json" in now
    assert json.loads(now["one.failed.json"])["summary"]["passed"] is False
    from usd_io.crowd import read_tracks
    assert set(read_tracks(out_dir / "one.failed.usdc")) == {"a"}     # readable, clips and all
    monkeypatch.undo()
    # a later good bake keeps the failed stage's clip directory (it still refers to it)
    assert main(["bake", str(s), "--out", str(out), "--quiet", "--seed", "7", *extra]) == 0
    assert set(read_tracks(out_dir / "one.failed.usdc")) == {"a"} and set(read_tracks(out)) == {"a"}
    assert not [p for p in out_dir.iterdir() if p.name.startswith(".")]


def test_odd_character_names_bake_and_check(tmp_path, capsys, default_graph):
    """Names that are not USD identifiers: valid unique prim names, the original kept, the checker
    reads the bake back by the original names."""
    from pxr import Usd
    s = _sample(tmp_path / "s", name="bob smith", second="Zoë/1st")
    out = tmp_path / "o.usda"
    assert main(["bake", str(s), "--out", str(out), "--quiet"]) == 0, capsys.readouterr()
    st = Usd.Stage.Open(str(out))
    kids = {p.GetName(): p.GetAttribute("crowdweave:name").Get()
            for p in st.GetPrimAtPath("/World/Characters").GetChildren()}
    assert kids == {"bob_smith": "bob smith", "Zo__1st": "Zoë/1st"}
    assert "checker: PASSED" in capsys.readouterr().out


def test_names_that_collide_fail_before_planning(tmp_path, capsys, monkeypatch):
    import runtime.crowd.scheduler as scheduler
    monkeypatch.setattr(scheduler, "plan_scenario", lambda *a, **k: pytest.fail("planned"))
    s = _sample(tmp_path / "s", name="x y", second="x_y")
    assert main(["bake", str(s), "--out", str(tmp_path / "o.usdc"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "character 'x y' and character 'x_y' both become the USD character prim 'x_y'" in err
    assert sorted(os.listdir(tmp_path)) == ["s"]


@pytest.mark.parametrize("out,words", [("{tmp}/adir", "is a directory"), ("/proc/x.usdc", "cannot write in /proc"),
                                       ("{tmp}/afile/x.usdc", "is not a directory"),
                                       ("{tmp}/x.txt", "must end in .usda, .usdc, .usd")])
def test_unwritable_outputs_fail_before_planning(tmp_path, capsys, monkeypatch, out, words):
    import runtime.crowd.scheduler as scheduler
    monkeypatch.setattr(scheduler, "plan_scenario", lambda *a, **k: pytest.fail("planned"))
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("")
    s = _sample(tmp_path / "s")
    assert main(["bake", str(s), "--out", out.format(tmp=tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err
    assert main(["bake", str(s), "--out", str(tmp_path / "o.usdc"), "--report", str(tmp_path / "adir"), "--quiet"]) == 2
    assert "--report" in capsys.readouterr().err


def test_a_missing_parent_is_created(tmp_path, default_graph):
    s = _sample(tmp_path / "s")
    out = tmp_path / "new" / "deeper" / "o.usdc"
    assert main(["bake", str(s), "--out", str(out), "--quiet"]) == 0 and out.is_file()


@pytest.mark.parametrize("argv,words", [
    (["bake", "S", "--out", "o.usdc", "--seed", "-1"], "argument --seed: must be an integer from 0 to"),
    (["bake", "S", "--out", "o.usdc", "--workers", "1000"], "argument --workers: must be an integer from 1 to 64"),
    (["capture", "--minutes", "1e6", "--out", "c"], "argument --minutes: must be a finite number greater than 0"),
    (["capture", "--minutes", "nan", "--out", "c"], "argument --minutes"),
    (["capture", "--fps", "inf", "--out", "c"], "argument --fps"),
    (["author", "flock", "--agents", "100000", "--out", "f.cwpack"],
     "argument --agents: must be an integer from 2 to 500"),
    (["author", "flock", "--seconds", "-5", "--out", "f.cwpack"], "argument --seconds"),
    (["author", "roadmap", "w.usda", "--out", "r.cwpack", "--connect", "nan"], "argument --connect"),
    (["author", "roadmap", "w.usda", "--out", "r.cwpack", "--samples", "1e9"], "argument --samples"),
    (["author", "graph", "x", "--out", "g.cwpack", "--fps", "0"], "argument --fps"),
    (["convert", "a.bvh", "b.usda", "--scale", "-1"], "argument --scale"),
    (["run", "--seconds", "inf"], "argument --seconds"),
])
def test_every_number_is_checked_with_its_limits(capsys, argv, words):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err, err


def test_help_states_the_limits(capsys):
    assert main(["bake", "--help"]) == 0
    assert "1-5000" in capsys.readouterr().out
    assert main(["author", "flock", "--help"]) == 0
    h = capsys.readouterr().out
    assert "2-500" in h and "200000" in h
    assert main(["capture", "--help"]) == 0
    assert "at most 600" in capsys.readouterr().out


def test_flock_agent_seconds_limit(capsys, tmp_path):
    assert main(["author", "flock", "--agents", "500", "--seconds", "3000", "--out", str(tmp_path / "f.cwpack")]) == 2
    assert "more than the limit of 200000 agent-seconds" in capsys.readouterr().err


def test_bad_scenario_files_through_bake(tmp_path, capsys, default_graph):
    s = tmp_path / "s"
    s.mkdir()
    (s / "scenario.toml").write_text('name = "x"\nduration = 3\n[[character]\n')
    assert main(["bake", str(s), "--out", str(tmp_path / "o.usdc"), "--quiet"]) == 2
    assert f"{s / 'scenario.toml'}: not valid TOML" in capsys.readouterr().err
    for extra, words in (('library = "/dev/zero"', "/dev/zero: not a regular file"),
                         ("duration = 1e7", "duration: must be a number greater than 0 and at most 3600"),
                         ("library = 5", "top level: library: must be a string")):
        _sample(s, extra=extra)
        (s / "scenario.toml").write_text((s / "scenario.toml").read_text().replace("duration = 6.0\n", "")
                                         if "duration" in extra else (s / "scenario.toml").read_text())
        assert main(["bake", str(s), "--out", str(tmp_path / "o.usdc"), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert words in err, err
    assert not (tmp_path / "o.usdc").exists()


# -- worlds ----------------------------------------------------------------------------------------
WORLD = '''#usda 1.0
(
    {meta}
)
def Xform "{root}"
{{
    def Scope "Obstacles"
    {{
        def Cube "B"
        {{
            double size = {size}
            double3 xformOp:translate = {at}
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }}
    }}
}}
'''


def test_a_z_up_centimetre_world_is_referenced_in_metres_y_up(tmp_path, default_graph):
    from pxr import Usd, UsdGeom

    from usd_io.world import read_world
    s = _sample(tmp_path / "s", extra='world = "world.usda"')
    (s / "world.usda").write_text(WORLD.format(meta='defaultPrim = "World"\n    metersPerUnit = 0.01\n    upAxis = "Z"',
                                               root="World", size=100, at="(300, 400, 50)"))
    env = read_world(s / "world.usda")
    np.testing.assert_allclose(env.polygons[0].mean(axis=0), [3.0, -4.0], atol=1e-9)   # metres, Y up
    out = tmp_path / "o.usda"
    assert main(["bake", str(s), "--out", str(out), "--quiet"]) == 0
    st = Usd.Stage.Open(str(out))
    cube = st.GetPrimAtPath("/World/Environment/Stage/Obstacles/B")
    assert cube, [str(p.GetPath()) for p in st.Traverse()]
    box = UsdGeom.BBoxCache(Usd.TimeCode.Default(), ["default"]).ComputeWorldBound(cube).ComputeAlignedRange()
    np.testing.assert_allclose(np.array(box.GetMin()), [2.5, 0.0, -4.5], atol=1e-6)
    np.testing.assert_allclose(np.array(box.GetMax()), [3.5, 1.0, -3.5], atol=1e-6)


def test_worlds_without_a_default_prim_or_without_prims(tmp_path, default_graph):
    from pxr import Usd

    from usd_io.validate import errors, validate_stage
    s = _sample(tmp_path / "s", extra='world = "world.usda"')
    (s / "world.usda").write_text(WORLD.format(meta='metersPerUnit = 1\n    upAxis = "Y"', root="Root", size=1,
                                               at="(3, 0.5, -4)"))
    out = tmp_path / "o.usda"
    assert main(["bake", str(s), "--out", str(out), "--quiet"]) == 0
    assert Usd.Stage.Open(str(out)).GetPrimAtPath("/World/Environment/Obstacles/B")
    (s / "world.usda").write_text("#usda 1.0\n")
    assert main(["bake", str(s), "--out", str(out), "--quiet"]) == 0
    st = Usd.Stage.Open(str(out))
    assert not st.GetPrimAtPath("/World/Environment") and errors(validate_stage(out)) == []


def test_meters_per_unit_zero_is_an_error_naming_the_file(tmp_path, capsys):
    w = tmp_path / "world.usda"
    w.write_text(WORLD.format(meta='defaultPrim = "World"\n    metersPerUnit = 0', root="World", size=1,
                              at="(0, 0, 0)"))
    assert main(["world", "check", str(w)]) == 2
    assert f"{w}: stage metadata: metersPerUnit must be positive" in capsys.readouterr().out
    assert main(["author", "roadmap", str(w), "--out", str(tmp_path / "r.cwpack")]) == 2
    assert f"{w}: stage metadata" in capsys.readouterr().err


# -- capture ------------------------------------------------------------------------------------------
def test_recapturing_into_an_old_directory_leaves_no_stale_take(tmp_path, capsys):
    from authoring.motion_graph.sources import load_takes
    d = tmp_path / "cap"
    assert main(["capture", "--minutes", "0.6", "--take-minutes", "0.2", "--out", str(d), "--no-check", "--quiet"]) == 0
    assert sorted(p.name for p in d.glob("*.bvh")) == ["take_000.bvh", "take_001.bvh", "take_002.bvh"]
    (d / "notes.txt").write_text("mine")
    assert main(["capture", "--minutes", "0.2", "--take-minutes", "0.2", "--out", str(d), "--no-check", "--quiet"]) == 0
    assert sorted(p.name for p in d.iterdir()) == ["notes.txt", "session.json", "take_000.bvh", "take_000.labels.json"]
    assert len(load_takes([d])) == 1
    t = tmp_path / "takes"
    assert main(["capture", "--takes", "--kinds", "handshake", "--repeat", "2", "--out", str(t), "--no-check",
                 "--quiet"]) == 0
    assert main(["capture", "--takes", "--kinds", "bow", "--out", str(t), "--no-check", "--quiet"]) == 0
    assert sorted(p.name for p in t.iterdir()) == ["bow_000", "takes.json"]
    capsys.readouterr()


def test_a_broken_world_file_is_one_line_naming_line_and_column(tmp_path, capsys):
    w = tmp_path / "world.usda"
    w.write_text('#usda 1.0\ndef Xform "World" {\n  double x = \n}\n')
    assert main(["world", "check", str(w)]) == 2
    out = capsys.readouterr().out.strip()
    assert out == (f"crowdweave world: error: {w}: not a readable USD file: line 3, column 3: "
                   "Expected } at 'double x = ' in </World>")
