"""Sweep files, variants and the batch summary, without a cluster: every error names the file
and the key, variants apply their axes to the base scenario or the generator, scenario text
reads back as the same scenario, the summary tables and plot are written."""
import csv
import tomllib
from pathlib import Path

import pytest

from authoring.batch import SweepError, load_sweep, make_variants, scenario_text
from authoring.batch.generators import GENERATORS
from authoring.batch.summary import plot_sweep, write_summary
from authoring.batch.toml_text import dumps

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"


def _sweep(tmp_path, text, name="sweep.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


GEN = '[sweep]\ngenerator = "grid"\n[generator]\ncharacters = 3\n'


@pytest.mark.parametrize("text, where", [
    ("[sweep\n", "not valid TOML"),
    ("[axes]\nseed = [0]\n", "[sweep]: missing"),
    ('[sweep]\ngenerator = "grid"\nscenario = "x"\n', "exactly one of"),
    ('[sweep]\ngenerator = "nope"\n', "[sweep] generator: unknown generator 'nope'"),
    ('[sweep]\nscenario = "missing"\n', "[sweep] scenario: 'missing': no scenario file"),
    ('[sweep]\ngenerator = "grid"\nspeed = 2\n', "[sweep]: unknown keys ['speed']"),
    (GEN + "spacing = -1.0\n", "[generator] spacing: must be positive"),
    (GEN + "legs = 2\n", "[generator] legs: not a parameter of 'grid'"),
    (GEN + "[axes]\nseed = []\n", "[axes] seed: must be a non-empty array"),
    (GEN + "[axes]\nseed = [0, 0]\n", "[axes] seed: a value is repeated"),
    (GEN + "[axes]\nseed = [0.5]\n", "[axes] seed: must be a whole number"),
    (GEN + "[axes]\ncharacters = [2]\n", "[axes] characters: also set in [generator]"),
    (GEN + "[axes]\neps = [[0.02, 2.0]]\n", "[axes] eps: each value is a positive factor"),
    (GEN + '[axes]\nworld = ["nowhere.usda"]\n', "[axes] world: 'nowhere.usda': no such file"),
    (GEN + "[axes]\ncolour = [1]\n", "[axes] colour: not an axis"),
    ('[sweep]\nscenario = "../samples/meet20"\n[axes]\nspacing = [2.0]\n', "spacing needs a generator"),
    ('[sweep]\nscenario = "../samples/meet20"\n[generator]\ncharacters = 2\n', "[generator]: only with generator"),
    ('[sweep]\nscenario = "../samples/meet20"\n[axes]\ncharacters = [0]\n', "[axes] characters: must be a whole number >= 1"),
    ("[sweep]\ngenerator = \"grid\"\n[extra]\n", "unknown tables ['extra']"),
])
def test_sweep_errors_name_the_file_and_the_key(tmp_path, text, where):
    d = tmp_path / "s"
    d.mkdir()
    (tmp_path / "samples").symlink_to(SAMPLES)
    p = _sweep(d, text)
    with pytest.raises(SweepError) as e:
        make_variants(load_sweep(p))
    msg = str(e.value)
    assert msg.startswith(str(p) + ":") and where in msg and "\n" not in msg


def test_a_missing_sweep_file_is_named(tmp_path):
    with pytest.raises(SweepError, match="nope.toml: sweep file not found"):
        load_sweep(tmp_path / "nope.toml")


def test_base_scenario_subsets_too_large_or_cut_dependencies_are_errors(tmp_path):
    base = tmp_path / "base.toml"
    base.write_text('name = "b"\n[[character]]\nname = "a"\nstart = { position = [0.0, 0.0] }\n'
                    '  [[character.goal]]\n  position = [3.0, 0.0]\n'
                    '[[character]]\nname = "b"\nstart = { position = [2.0, 0.0] }\n'
                    '  [[character.goal]]\n  position = [5.0, 0.0]\n'
                    '  after = { character = "c" }\n'
                    '[[character]]\nname = "c"\nstart = { position = [4.0, 0.0] }\n'
                    '  [[character.goal]]\n  position = [7.0, 0.0]\n')
    p = _sweep(tmp_path, '[sweep]\nscenario = "base.toml"\n[axes]\ncharacters = [1, 4]\n')
    with pytest.raises(SweepError, match=r"characters: 4 is more than the 3 characters"):
        make_variants(load_sweep(p))
    p = _sweep(tmp_path, '[sweep]\nscenario = "base.toml"\n[axes]\ncharacters = [2]\n')
    with pytest.raises(SweepError, match=r"keeps 'b', whose goal waits for 'c', who is left out"):
        make_variants(load_sweep(p))


def test_variants_apply_the_axes_to_a_base_scenario(tmp_path):
    (tmp_path / "w").mkdir()
    world = tmp_path / "w" / "hall.usda"
    world.write_text("#usda 1.0\n")
    p = _sweep(tmp_path, f'[sweep]\nname = "m"\nscenario = "{SAMPLES / "meet20"}"\n'
               '[axes]\nseed = [3, 4]\ncharacters = [2, 5]\neps = [0.5, [0.01, 1.0, 0.05]]\n'
               'world = ["", "w/hall.usda"]\n')
    variants = make_variants(load_sweep(p))
    assert len(variants) == 16 and len({v.id for v in variants}) == 16
    assert [v.index for v in variants] == list(range(16))
    v = variants[0]
    assert v.id == "000-seed3-characters2-eps0.5-worldopen" and v.params == {
        "seed": 3, "characters": 2, "eps": 0.5, "world": ""}
    base = tomllib.loads((SAMPLES / "meet20" / "scenario.toml").read_text())
    assert v.scenario["seed"] == 3 and v.scenario["character"] == base["character"][:2]
    assert v.scenario["synthesis"]["epsilon"] == [0.01, 1.0, 0.5 / 15.0]
    assert "world" not in v.scenario and v.scenario["name"] == "m-" + v.id
    last = variants[-1]
    assert last.id == "015-seed4-characters5-eps0.01_1_0.05-worldhall"
    assert last.scenario["synthesis"]["epsilon"] == [0.01, 1.0, 0.05] and last.characters == 5
    # written in OUT/<variant>/, the world is named relative to that folder
    folder = tmp_path / "out" / last.id
    data = tomllib.loads(scenario_text(last, folder))
    assert data["world"] == "../../w/hall.usda"
    assert (folder / data["world"]).resolve() == world.resolve()
    assert data["character"] == base["character"][:5] and data["duration"] == base["duration"]


def test_generator_variants(tmp_path):
    p = _sweep(tmp_path, '[sweep]\ngenerator = "crossing"\n[generator]\ndistance = 6.0\n'
               '[axes]\ncharacters = [2, 5]\nspacing = [1.5, 3.0]\nseed = [0, 1]\n')
    variants = make_variants(load_sweep(p))
    assert len(variants) == 8
    for v in variants:
        expected = GENERATORS["crossing"](distance=6.0, **v.params)
        assert v.scenario == {**expected, "name": "sweep-" + v.id}
        assert v.characters == v.params["characters"]
    a, b = variants[0].scenario, variants[1].scenario          # seeds 0 and 1: other jitter
    assert a["character"][0]["start"] == b["character"][0]["start"]
    assert a["character"][0]["goal"] != b["character"][0]["goal"]


@pytest.mark.parametrize("gen", sorted(GENERATORS))
def test_generated_scenarios_are_valid_and_spaced(gen):
    import numpy as np

    from runtime.crowd.scenario import parse_scenario
    for n in (1, 2, 7):
        sc = parse_scenario(GENERATORS[gen](characters=n, spacing=1.7, seed=2))
        assert len(sc.characters) == n
        starts = np.array([c.position for c in sc.characters])
        if n > 1:
            d = np.hypot(*(starts[:, None] - starts[None]).transpose(2, 0, 1))
            assert d[~np.eye(n, dtype=bool)].min() >= 1.7 - 1e-3


def test_scenario_text_round_trips_every_sample():
    """The TOML writer keeps every value of every sample scenario (floats exactly)."""
    files = sorted(SAMPLES.glob("*/scenario.toml"))
    assert len(files) >= 10
    for f in files:
        data = tomllib.loads(f.read_text())
        assert tomllib.loads(dumps(data)) == data, f


def test_summary_files(tmp_path):
    p = _sweep(tmp_path, GEN + "[axes]\nseed = [0, 1]\nspacing = [2.0, 3.0]\n")
    sweep = load_sweep(p)
    variants = make_variants(sweep)
    records = {}
    for k, v in enumerate(variants[:3]):
        records[v.id] = {"id": v.id, "status": ["passed", "failed", "error"][k], "characters": 3,
                         "characters_within_eps": 3 - k, "character_overlap_pairs": k, "goals": 3,
                         "goals_in_window": 3, "plan_seconds": 1.5 + k, "write_seconds": 0.1, "seconds": 2.0,
                         "worker": "h:1", "error": "bad, \"quoted\" | piped" if k == 2 else ""}
    counts = write_summary(tmp_path, sweep, variants, records, {variants[0].id: 2})
    assert counts == {"passed": 1, "failed": 1, "error": 1, "lost": 1}
    rows = list(csv.DictReader((tmp_path / "summary.csv").open()))
    assert [r["variant"] for r in rows] == [v.id for v in variants]
    assert [r["status"] for r in rows] == ["passed", "failed", "error", "lost"]
    assert rows[0]["attempts"] == "2" and rows[1]["attempts"] == "0" and rows[0]["plan_s"] == "1.5"
    assert rows[2]["error"] == 'bad, "quoted" | piped' and rows[3]["error"] == "no result"
    md = (tmp_path / "summary.md").read_text()
    assert "1 passed, 1 failed, 1 error, 1 lost of 4 variants" in md and "bad, \"quoted\" \\| piped" in md
    assert md.count("\n| 00") == 4
    assert (tmp_path / "sweep.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob(".*tmp*"))


def test_plot_without_numeric_axes(tmp_path):
    rows = [{"variant": "000-worldopen", "world": "", "status": "passed", "characters": 2, "within_eps": 2,
             "plan_s": 1.0}]
    assert plot_sweep({"world": [""]}, rows, "w")[:4] == b"\x89PNG"


def test_bake_sample_rejects_unknown_options():
    from authoring.commands.bake import bake_sample
    with pytest.raises(TypeError, match="unknown option 'colour'"):
        bake_sample("x", "y.usdc", colour=1)


def test_batch_list_and_bad_sweep_from_the_command_line(tmp_path, capsys):
    from authoring.cli import main
    p = _sweep(tmp_path, GEN + "[axes]\nseed = [0, 1]\n")
    assert main(["batch", str(p), "--out", str(tmp_path / "o"), "--list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == ["000-seed0: 3 characters, 20 s", "001-seed1: 3 characters, 20 s"]
    bad = _sweep(tmp_path, GEN + "[axes]\nseed = 3\n", "bad.toml")
    assert main(["batch", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"crowdweave batch: error: {bad}: [axes] seed: must be a non-empty array of values"]
    assert not (tmp_path / "o").exists()
