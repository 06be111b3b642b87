import os
import subprocess
import sys

import msgpack
import numpy as np
import pytest

from runtime.assets import AssetError, load_pack, save_pack


def _arrays():
    rng = np.random.default_rng(0)
    return {"a": rng.normal(size=(5, 3)).astype(np.float32), "idx": np.arange(7, dtype=np.int64)}


def test_round_trip_exact(tmp_path):
    p = tmp_path / "x.cwpack"
    save_pack(p, "graph", 3, {"name": "lib", "n": 2}, _arrays())
    pk = load_pack(p, kind="graph", version=3)
    assert pk.kind == "graph" and pk.version == 3 and pk.meta == {"name": "lib", "n": 2}
    for k, v in _arrays().items():
        assert pk.arrays[k].dtype == v.dtype
        np.testing.assert_array_equal(pk.arrays[k], v)


def test_same_input_same_bytes(tmp_path):
    save_pack(tmp_path / "a.cwpack", "graph", 1, {"x": 1}, _arrays())
    save_pack(tmp_path / "b.cwpack", "graph", 1, {"x": 1}, _arrays())
    assert (tmp_path / "a.cwpack").read_bytes() == (tmp_path / "b.cwpack").read_bytes()


@pytest.mark.parametrize("damage, reason", [
    ("truncate", "truncated or corrupt"),
    ("flip", ""),
    ("empty", "empty"),
    ("missing", "not found"),
])
def test_damaged_files_raise_asset_error_naming_file(tmp_path, damage, reason):
    p = tmp_path / "lib.cwpack"
    save_pack(p, "graph", 1, {"x": 1}, _arrays())
    raw = p.read_bytes()
    if damage == "truncate":
        p.write_bytes(raw[: len(raw) // 2])
    elif damage == "flip":
        b = bytearray(raw)
        b[len(b) - 40] ^= 0x10  # inside array data: decodes fine, checksum catches it
        p.write_bytes(bytes(b))
    elif damage == "empty":
        p.write_bytes(b"")
    else:
        p.unlink()
    with pytest.raises(AssetError) as ei:
        load_pack(p)
    assert str(p) in str(ei.value) and reason in str(ei.value)
    if damage == "flip":
        assert "checksum" in str(ei.value) or "malformed" in str(ei.value) or "corrupt" in str(ei.value)


def test_every_single_bit_flip_is_detected(tmp_path):
    p = tmp_path / "lib.cwpack"
    save_pack(p, "graph", 1, {"x": 1}, {"a": np.arange(4, dtype=np.int32)})
    raw = p.read_bytes()
    rng = np.random.default_rng(1)
    for pos in rng.choice(len(raw), size=min(60, len(raw)), replace=False):
        b = bytearray(raw)
        b[pos] ^= 1 << int(rng.integers(0, 8))
        p.write_bytes(bytes(b))
        with pytest.raises(AssetError):
            load_pack(p)


def test_wrong_kind_and_version(tmp_path):
    p = tmp_path / "lib.cwpack"
    save_pack(p, "ddg", 2, {}, {})
    with pytest.raises(AssetError, match="wrong kind: expected 'graph'"):
        load_pack(p, kind="graph")
    with pytest.raises(AssetError, match="unsupported version 2"):
        load_pack(p, kind="ddg", version=3)
    p.write_bytes(msgpack.packb({"format": "other"}))
    with pytest.raises(AssetError, match="not a crowdweave pack"):
        load_pack(p)


def test_killed_write_leaves_previous_pack_intact(tmp_path):
    p = tmp_path / "lib.cwpack"
    save_pack(p, "graph", 1, {"gen": 1}, _arrays())
    before = p.read_bytes()
    # a child process starts writing a large pack and is killed midway (os._exit inside write)
    code = f"""
import os, numpy as np, runtime.assets as A
real = os.fsync
def die(fd):
    os._exit(9)   # killed after the temp file was written, before the rename
A.os.fsync = die
A.save_pack({str(p)!r}, "graph", 1, {{"gen": 2}}, {{"big": np.zeros(2_000_000)}})
"""
    r = subprocess.run([sys.executable, "-c", code], cwd=os.path.dirname(os.path.dirname(__file__)))
    assert r.returncode == 9
    assert p.read_bytes() == before
    assert load_pack(p).meta == {"gen": 1}
