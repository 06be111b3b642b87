"""samples/flock_region_2d and _3d bake end to end: flocks stay in their region prim's outline,
no agent jumps, the stage validates."""
import json
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from authoring.cli import main
from usd_io.validate import errors, validate_stage

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.parametrize("name, flocks", [("flock_region_2d", 4), ("flock_region_3d", 3)])
def test_flock_sample_bakes_and_checks(name, flocks, tmp_path, default_graph, capsys):
    out = tmp_path / f"{name}.usdc"
    rep = tmp_path / "report.json"
    assert main(["bake", str(ROOT / "samples" / name), "--out", str(out), "--report", str(rep), "--quiet"]) == 0
    r = json.loads(rep.read_text())
    assert r["flocks"]["flocks"] == flocks and r["flocks"]["frames_outside"] == 0
    assert r["flocks"]["worst_step_ratio"] <= 1.1
    assert not errors(validate_stage(out))
    st = Usd.Stage.Open(str(out))
    inst = [p for p in st.Traverse() if p.IsA(UsdGeom.PointInstancer)]
    assert len(inst) == flocks
    pos = np.array(UsdGeom.PointInstancer(inst[0]).GetPositionsAttr().Get(100))
    assert pos.shape == (20, 3)
    if name.endswith("3d"):
        assert np.all((pos[:, 1] > 0.0))               # birds fly
