"""Scaling out on Dask, with real worker processes (a LocalCluster of 2): a sweep's stages and
reports are those of ``crowdweave bake``; a worker killed mid-sweep loses nothing and writes
nothing twice; a failing variant is reported and the rest go on; an unreachable scheduler is a
one-line error; value-clip layers written on workers and motion graphs whose distance blocks are
computed on workers are byte-identical to the single-process ones; and the same code runs
against ``dask scheduler`` / ``dask worker`` processes started by hand."""
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from authoring.batch import load_sweep, local_cluster, run_batch  # noqa: E402
from authoring.cli import main  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p])}

# four small variants (3 characters walking 5 m, 10 s baked): two seeds x two spacings
SWEEP = """[sweep]
name = "small"
generator = "grid"
[generator]
characters = 3
distance = 5.0
duration = 10.0
[axes]
seed = [0, 1]
spacing = [2.0, 3.0]
"""

BLOCK_WORLD = """#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Y"
)

def Xform "World"
{
    def Xform "Obstacles"
    {
        def Cube "Block"
        {
            double size = 1
            double3 xformOp:translate = (-1, 0.5, 0)
            float3 xformOp:scale = (8, 1, 8)
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
        }
    }
}
"""


def _files(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _without_timing(report: bytes) -> dict:
    r = json.loads(report)
    assert set(r.pop("timing")) == {"plan_seconds", "write_seconds", "per_character"}
    return r


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    (d / "sweep.toml").write_text(SWEEP)
    return d / "sweep.toml"


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of 2 single-threaded worker processes for the module."""
    with local_cluster(2) as c, distributed.Client(c, set_as_default=False) as client:
        client.wait_for_workers(2)
        yield c, client


@pytest.fixture(scope="module")
def reference(sweep_file, tmp_path_factory):
    """The sweep through ``crowdweave batch`` (its own LocalCluster) and every variant through
    ``crowdweave bake`` in a subprocess (two at a time)."""
    base = tmp_path_factory.mktemp("reference")
    out, ref = base / "out", base / "ref"
    assert main(["batch", str(sweep_file), "--out", str(out), "--workers", "2", "--quiet"]) == 0
    ids = sorted(p.name for p in out.iterdir() if p.is_dir())
    procs = []
    for vid in ids:
        cmd = [sys.executable, "-m", "authoring.cli", "bake", str(out / vid / "scenario.toml"),
               "--out", str(ref / vid / "stage.usdc"), "--report", str(ref / vid / "report.json"), "--quiet"]
        procs.append(subprocess.Popen(cmd, env=ENV, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE))
        if len(procs) % 2 == 0:
            procs[-2].wait()
    for p in procs:
        assert p.wait() == 0, p.stderr.read().decode()
    return out, ref, ids


def test_sweep_outputs_are_those_of_crowdweave_bake(reference):
    """4 variants on a LocalCluster of 2 workers: every stage is byte-identical to the one
    ``crowdweave bake`` writes for the same variant, and every report too apart from its
    wall-clock timings; the summary lists them all."""
    out, ref, ids = reference
    assert len(ids) == 4
    for vid in ids:
        mine, theirs = _files(out / vid), _files(ref / vid)
        assert set(mine) == {"scenario.toml", "stage.usdc", "report.json", "bake.log", "variant.json"}
        assert mine["stage.usdc"] == theirs["stage.usdc"], vid
        assert _without_timing(mine["report.json"]) == _without_timing(theirs["report.json"]), vid
        rec = json.loads(mine["variant.json"])
        assert rec["status"] == "passed" and rec["characters"] == 3 and rec["error"] == ""
    rows = (out / "summary.csv").read_text().splitlines()
    assert len(rows) == 5 and all(",passed," in r and ",1," in r for r in rows[1:])
    assert (out / "summary.md").is_file() and (out / "sweep.png").stat().st_size > 1000
    assert sorted(p.name for p in out.iterdir()) == sorted(ids + ["summary.csv", "summary.md", "sweep.png"])
    # the variants ran on both workers
    assert len({json.loads((out / v / "variant.json").read_text())["worker"] for v in ids}) == 2


def test_a_worker_killed_mid_sweep_loses_nothing(reference, sweep_file, cluster, tmp_path):
    """Kill (SIGKILL) the worker process running the first variant while it bakes: the scheduler
    runs that variant again, every output is written once, byte-identical to the undisturbed
    sweep, and no temporary directory is left."""
    out_ref, _, ids = reference
    _, client = cluster
    out = tmp_path / "out"
    killed = []

    def kill_first_attempt():
        attempts = out / ".batch" / "attempts"
        deadline = time.time() + 120
        while time.time() < deadline:
            found = sorted(attempts.glob("*@*")) if attempts.is_dir() else []
            if found:
                host, pid, _ = found[0].read_text().split()
                time.sleep(1.0)                        # well inside its bake (seconds long)
                os.kill(int(pid), signal.SIGKILL)
                killed.append((found[0].name.split("@")[0], int(pid)))
                return
            time.sleep(0.05)

    watcher = threading.Thread(target=kill_first_attempt)
    watcher.start()
    result = run_batch(load_sweep(sweep_file), out, client=client)
    watcher.join()
    assert killed, "no variant started"
    vid, pid = killed[0]
    assert result.counts == {"passed": 4, "failed": 0, "error": 0, "lost": 0}
    assert result.attempts[vid] >= 2                   # it really was running when its worker died
    assert json.loads((out / vid / "variant.json").read_text())["worker"] != f"{socket.gethostname()}:{pid}"
    assert sorted(p.name for p in out.iterdir()) == sorted(ids + ["summary.csv", "summary.md", "sweep.png"])
    for v in ids:
        mine, before = _files(out / v), _files(out_ref / v)
        assert set(mine) == set(before)
        assert mine["stage.usdc"] == before["stage.usdc"] and mine["scenario.toml"] == before["scenario.toml"]
        assert _without_timing(mine["report.json"]) == _without_timing(before["report.json"])
    rows = {r.split(",")[0]: r for r in (out / "summary.csv").read_text().splitlines()[1:]}
    assert len(rows) == 4
    client.wait_for_workers(2, timeout=60)             # the nanny restarted it


def test_resume_bakes_only_the_missing_variants(reference, sweep_file, cluster, tmp_path, capsys):
    """Into a directory that holds the batch: without --resume a one-line error naming the
    variant's folder; with it, only the variant that was removed is baked again."""
    import shutil
    out_ref, _, ids = reference
    out = tmp_path / "out"
    shutil.copytree(out_ref, out)
    shutil.rmtree(out / ids[2])
    address = cluster[0].scheduler_address
    base = ["batch", str(sweep_file), "--out", str(out), "--scheduler", address, "--quiet"]
    assert main(base) == 2
    assert capsys.readouterr().err.strip() == (f"crowdweave batch: error: {out / ids[0]}: already baked; "
                                               "give --resume to keep the variants already baked")
    assert main(base + ["--resume"]) == 0
    assert "(3 kept from an earlier run)" in capsys.readouterr().out
    attempts = {r.split(",")[0]: r.split(",")[-3] for r in (out / "summary.csv").read_text().splitlines()[1:]}
    assert attempts == {v: ("1" if v == ids[2] else "0") for v in ids}
    assert (out / ids[2] / "stage.usdc").read_bytes() == (out_ref / ids[2] / "stage.usdc").read_bytes()


def test_a_failing_variant_is_reported_and_the_batch_goes_on(cluster, tmp_path, capsys):
    """A variant whose characters start inside an obstacle fails with the scenario's error
    (naming the variant's own file); the other is baked; the command exits 1."""
    address = cluster[0].scheduler_address
    (tmp_path / "block.usda").write_text(BLOCK_WORLD)
    (tmp_path / "sweep.toml").write_text(SWEEP.replace("seed = [0, 1]\nspacing = [2.0, 3.0]\n",
                                                       'world = ["block.usda", ""]\n').replace("characters = 3", "characters = 2"))
    out = tmp_path / "out"
    rc = main(["batch", str(tmp_path / "sweep.toml"), "--out", str(out), "--scheduler", address, "--quiet"])
    assert rc == 1
    printed = capsys.readouterr().out
    assert "1 passed, 0 failed the checker, 1 errors, 0 lost of 2 variants" in printed
    bad = json.loads((out / "000-worldblock" / "variant.json").read_text())
    assert bad["status"] == "error"
    assert bad["error"] == (f"{out / '000-worldblock' / 'scenario.toml'}: character 'c001' start position "
                            "[0.0, -1.25] is inside an obstacle")
    assert json.loads((out / "001-worldopen" / "variant.json").read_text())["status"] == "passed"
    md = (out / "summary.md").read_text()
    assert "| 000-worldblock | block.usda | error |" in md and "is inside an obstacle" in md
    assert "1 passed, 0 failed, 1 error, 0 lost of 2 variants" in md


def test_an_unreachable_scheduler_is_a_one_line_error(sweep_file, tmp_path):
    address = f"tcp://127.0.0.1:{_free_port()}"
    for cmd in (["batch", str(sweep_file), "--out", str(tmp_path / "o"), "--scheduler", address, "--timeout", "1"],
                ["bake", str(ROOT / "samples" / "meet20"), "--out", str(tmp_path / "b.usdc"), "--clips-per", "5",
                 "--scheduler", address]):
        r = subprocess.run([sys.executable, "-m", "authoring.cli", *cmd], env=ENV, cwd=ROOT,
                           capture_output=True, text=True, timeout=120)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1, r.stderr
        assert lines[0].startswith(f"crowdweave {cmd[0]}: error: cannot reach the Dask scheduler at {address}")
    assert not (tmp_path / "o").exists() and not (tmp_path / "b.usdc").exists()


def test_value_clip_layers_written_on_workers_are_the_same_bytes(cluster, default_graph, tmp_path):
    """``build_crowd_stage(..., scheduler=ADDRESS)``: the layers come back from the workers and
    the stage and clip directory are byte-identical to the in-process writer's."""
    from runtime.crowd.tracks import Track
    from usd_io.crowd import build_crowd_stage, save_crowd_stage
    rng = np.random.default_rng(0)
    T = len(default_graph.frame_heading)
    tracks = {}
    for i in range(7):
        n = int(rng.integers(40, 90))
        a = int(rng.integers(0, T - n - 1))
        f = np.arange(a, a + n)
        root = np.column_stack([rng.uniform(-9, 9) + np.cumsum(rng.normal(0, 0.02, n)),
                                rng.uniform(-9, 9) + np.cumsum(rng.normal(0, 0.02, n)), rng.uniform(-3, 3, n)])
        tracks[f"c{i}"] = Track(f, f + 1, np.full(n, 0.25, np.float32), root, int(rng.integers(0, 5)))
    for sub, kw in (("local", {"workers": 1}), ("dask", {"scheduler": cluster[0].scheduler_address})):
        out = tmp_path / sub / "crowd.usdc"
        save_crowd_stage(build_crowd_stage(tracks, default_graph, 30.0, out_path=out, clips_per=3, **kw), out)
    local, dask = _files(tmp_path / "local"), _files(tmp_path / "dask")
    assert local == dask and len(local) == 5            # stage, 3 chunks, manifest


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """Two minutes of generated capture (two takes)."""
    from authoring.procedural import write_session
    d = tmp_path_factory.mktemp("capture")
    write_session(d, 2.0, 3, take_minutes=1.0)
    return d


def test_graph_distance_blocks_on_workers_give_the_same_pack(capture, cluster, tmp_path):
    """``crowdweave author graph ... --scheduler ADDRESS``: the pack is byte-identical to the
    single-process build's."""
    address = cluster[0].scheduler_address
    one, dist = tmp_path / "one.cwpack", tmp_path / "dist.cwpack"
    assert main(["author", "graph", str(capture), "--out", str(one), "--no-usd", "--quiet", "--workers", "1"]) == 0
    assert main(["author", "graph", str(capture), "--out", str(dist), "--no-usd", "--quiet",
                 "--scheduler", address]) == 0
    assert one.read_bytes() == dist.read_bytes()


def test_many_blocks_on_workers_equal_the_serial_candidates(capture, cluster):
    """Many small blocks (60 frames each) computed on the workers, results in block order: the
    transition candidates equal the serial computation's exactly."""
    from authoring.batch.cluster import block_mapper
    from authoring.motion_graph.distance import frame_features
    from authoring.motion_graph.hubs import find_candidates
    from authoring.motion_graph.sources import load_takes
    takes = load_takes([str(capture)], fps=30.0)[:1]
    sk = takes[0].clip.skeleton
    feats = frame_features([t.clip.positions(origin=np.zeros(3)) for t in takes], np.ones(len(sk.names)))
    N = len(feats.sq)
    rng = np.random.default_rng(0)
    cls = rng.integers(0, 2, N)
    args = (0.003, cls, np.array([[True, False], [False, True]]), feats.valid, feats.valid, 20)
    chunk = 60 * 8 * 4 * N
    serial = find_candidates(feats, *args, chunk_bytes=chunk)
    dist = find_candidates(feats, *args, chunk_bytes=chunk, map_blocks=block_mapper(cluster[1]))
    assert len(serial.cols) > 1000 and len(serial.indptr) - 1 > 20 * 60
    for a, b in ((serial.indptr, dist.indptr), (serial.cols, dist.cols), (serial.dist, dist.dist)):
        assert a.dtype == b.dtype and np.array_equal(a, b)


@pytest.mark.slow
def test_hand_started_scheduler_and_workers(sweep_file, reference, tmp_path):
    """``dask scheduler`` and ``dask worker`` started as separate processes: the sweep runs on
    them through ``--scheduler`` and gives the same stages."""
    out_ref, _, ids = reference
    info = tmp_path / "scheduler.json"
    port = _free_port()
    dask_cmd = [sys.executable, "-m", "dask"]
    procs = [subprocess.Popen(dask_cmd + ["scheduler", "--host", "127.0.0.1", "--port", str(port),
                                          "--no-dashboard", "--scheduler-file", str(info)],
                              env=ENV, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.time() + 60
        while not info.is_file() and time.time() < deadline:
            time.sleep(0.1)
        cfg = tmp_path / "dask-config"          # the README's setting for worker hosts
        cfg.mkdir()
        (cfg / "crowdweave.yaml").write_text(
            "distributed:\n  nanny:\n    pre-spawn-environ:\n      MALLOC_TRIM_THRESHOLD_: null\n")
        procs.append(subprocess.Popen(dask_cmd + ["worker", f"tcp://127.0.0.1:{port}", "--nworkers", "2",
                                                  "--nthreads", "1", "--no-dashboard"],
                                      env={**ENV, "DASK_CONFIG": str(cfg)}, cwd=tmp_path,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = f"tcp://127.0.0.1:{port}"
        with distributed.Client(address, timeout=30, set_as_default=False) as c:
            c.wait_for_workers(2, timeout=60)
            trim = c.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_"))
            assert len(trim) == 2 and set(trim.values()) == {None}
        out = tmp_path / "out"
        r = subprocess.run([sys.executable, "-m", "authoring.cli", "batch", str(sweep_file), "--out", str(out),
                            "--scheduler", address, "--quiet"], env=ENV, cwd=ROOT, capture_output=True, text=True,
                           timeout=600)
        assert r.returncode == 0, r.stderr
        assert f"4 variants on {address} (2 workers)" in r.stdout
        for v in ids:
            assert (out / v / "stage.usdc").read_bytes() == (out_ref / v / "stage.usdc").read_bytes()
    finally:
        for p in reversed(procs):
            p.send_signal(signal.SIGINT)
        for p in reversed(procs):
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
