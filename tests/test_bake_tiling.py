"""`crowdweave bake` of a tiling sample (tiling.toml): its characters written to USD like a crowd."""
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdSkel

from authoring.commands import CLIError
from authoring.commands.bake import bake_sample
from usd_io.crowd import read_tracks

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def test_a_static_tiling_bakes_to_skelroots_and_is_checked(tmp_path, capsys):
    out = tmp_path / "tiling.usdc"
    assert bake_sample(SAMPLES / "tiling_static_15", out, report=str(tmp_path / "r.json")) == 0
    text = capsys.readouterr().out
    assert "tiling check: OK" in text and "feet (tiled, " in text and "checker: PASSED" in text
    st = Usd.Stage.Open(str(out))
    roots = [p for p in st.Traverse() if p.IsA(UsdSkel.Root)]
    tracks = read_tracks(out)
    assert len(roots) == len(tracks) > 5
    starts = [t.start_frame for t in tracks.values()]
    assert min(starts) == 0 and max(starts) > 0          # characters enter through the region's edges
    import json
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["kind"] == "tiling" and rep["summary"]["passed"]
    f = rep["feet"]["tiled"]
    assert f["characters"] == len(tracks) and f["planted_frames"] > 1000 and np.isfinite(f["mean_cm_s"])


def test_a_tiling_bake_takes_no_seed(tmp_path):
    with pytest.raises(CLIError, match="seed"):
        bake_sample(SAMPLES / "tiling_static_15", tmp_path / "t.usdc", seed=3)


def test_slide_limits_fail_a_bake_once_enforced(tmp_path, capsys, monkeypatch):
    import runtime.footslide as fs
    monkeypatch.setattr(fs, "ENFORCED", True)
    monkeypatch.setitem(fs.LIMITS, "sliding_share", 0.0)      # no planted frame may slide at all
    out = tmp_path / "t.usdc"
    assert bake_sample(SAMPLES / "tiling_static_15", out) == 1
    text = capsys.readouterr().out
    assert "OVER LIMITS" in text and "checker: FAILED" in text and not out.exists()
