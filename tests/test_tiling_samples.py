"""The tiling samples (Figure 7) check independently of the tiler: no dangling entry/exit inside
the region, no interpenetration, every frame's deformation inside the limits; the repeating
tile laid out 3 x 3 is seamless."""
from pathlib import Path

import pytest

from runtime.tiling.check import check_repeating, check_tiling
from runtime.tiling.result import TilingResult
from runtime.tiling.scenario import TilingConfigError, build_library, load_config
from test_tiling_util import graph  # noqa: F401  (fixture)

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
NAMES = sorted(p.name for p in SAMPLES.glob("tiling_*") if (p / "tiling.toml").exists())


def _load(name, graph):
    cfg = load_config(SAMPLES / name / "tiling.toml")
    return cfg, TilingResult.load(SAMPLES / name / "tiling.cwpack", build_library(cfg, graph))


def test_samples_exist():
    assert {"tiling_static_15", "tiling_static_30", "tiling_static_45", "tiling_dynamic", "tiling_rows",
            "tiling_repeat", "tiling_boxes", "tiling_teams"} <= set(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_sample_checks(name, graph):
    cfg, res = _load(name, graph)
    rep = check_tiling(res)
    assert rep.ok, f"{name}: {rep}"
    assert rep.constraint_error < 1e-3
    s = res.summary()
    if cfg.get("mode") == "static":
        assert s["patches"] > 50 and s["characters"] > 5
    if name == "tiling_rows":
        assert s["keyframes"] == 2
    if name == "tiling_dynamic":
        assert len(res.obstacles) == 2 and len(res.portals) == 2


@pytest.mark.slow
def test_repeating_sample_is_seamless_3x3(graph):
    _, res = _load("tiling_repeat", graph)
    rep = check_repeating(res)
    assert rep.ok, str(rep)


def test_config_errors_name_the_file(tmp_path):
    bad = tmp_path / "t.toml"
    bad.write_text('mode = "sideways"\n')
    with pytest.raises(TilingConfigError, match="t.toml.*mode"):
        load_config(bad)
    bad.write_text('mode = "static"\n')
    with pytest.raises(TilingConfigError, match="region"):
        load_config(bad)
    bad.write_text("mode = [\n")
    with pytest.raises(TilingConfigError, match="TOML"):
        load_config(bad)


def test_tiled_characters_bake_one_skelroot_each(graph):
    """The tracks plug into the crowd bake as they are (library flat pose tables)."""
    pytest.importorskip("pxr")
    from usd_io.crowd import build_crowd_stage, read_tracks
    _, res = _load("tiling_teams", graph)
    tracks = {f"tiled{i:03d}": t.to_track() for i, t in enumerate(res.tracks())}
    stage = build_crowd_stage(tracks, res.library, res.fps, body=False)
    back = read_tracks(stage)
    assert sorted(back) == sorted(tracks)
    for k, tr in tracks.items():
        assert back[k].root.shape == tr.root.shape
