"""Killing a bake never loses the previous output: real ``crowdweave bake --clips-per`` processes
stopped at five points (planning; the stage built in memory; value-clip workers running; the
stage written to its temporary file; checked, before the rename) with ``kill -9``: the old
stage and its clip directory stay byte-identical, no worker survives 5 s, and the next bake
removes every temporary file and directory the killed one left. SIGTERM cleans up at once.

The bake stops at a named point when ``CROWDWEAVE_PAUSE_AT`` names it
(:func:`runtime.assets.pause_point`), so every kill lands where it is meant to."""
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc (Linux)")]

SCENARIO = '''name = "two"
duration = 8.0
seed = 0
[[character]]
name = "a"
start = {{ position = [-6.0, -6.0], pose = "stand" }}
  [[character.goal]]
  position = [{x}, -3.0]
[[character]]
name = "b"
start = {{ position = [6.0, 6.0], pose = "stand" }}
  [[character.goal]]
  position = [4.0, 3.5]
'''


def _bake(sample, out, pause=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("CROWDWEAVE_PAUSE_AT", None)
    if pause:
        env["CROWDWEAVE_PAUSE_AT"] = pause
    cmd = [sys.executable, "-m", "authoring.cli", "bake", str(sample), "--out", str(out), "--quiet",
           "--clips-per", "1", "--workers", "2"]
    return subprocess.Popen(cmd, env=env, cwd=str(ROOT), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)


def _finish(proc, timeout=300):
    out, err = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, err
    return out


def _wait_for_pause(proc, stage, timeout=300):
    """Read stderr until the bake says it stopped at ``stage``; keep reading in the background."""
    lines, seen = [], threading.Event()

    def read():
        for line in proc.stderr:
            lines.append(line)
            if f"paused at {stage}" in line:
                seen.set()
    threading.Thread(target=read, daemon=True).start()
    if not seen.wait(timeout):
        proc.kill()
        pytest.fail(f"the bake never reached {stage}: {''.join(lines)[-2000:]}")
    if stage == "clips":                   # both workers are at work (each says so)
        t0 = time.time()
        while sum(f"paused at {stage}" in ln for ln in lines) < 2 and time.time() - t0 < 60:
            time.sleep(0.05)


def _stat(pid):
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()
    return fields[0], int(fields[1])          # state, parent pid


def _descendants(pid):
    kids, todo = set(), [pid]
    while todo:
        p = todo.pop()
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                s = _stat(int(d.name))
                if s and s[1] == p and int(d.name) not in kids:
                    kids.add(int(d.name))
                    todo.append(int(d.name))
    return kids


def _alive(pids):
    return {p for p in pids if (_stat(p) or ("Z", 0))[0] not in ("Z", "X")}


def _files(d: Path):
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def _kept(d: Path, out: Path):
    """The stage and the clip directory it refers to (what must survive untouched)."""
    from pxr import Sdf
    used = Sdf.Layer.OpenAsAnonymous(str(out), metadataOnly=True).customLayerData["crowdweave:clipDirectory"]
    assert (d / used).is_dir()
    return {k: v for k, v in _files(d).items() if k == out.name or k.startswith(used + "/")}


def _clean(d: Path, out: Path):
    """Only the stage and its one clip directory: no temporary, no stale clip directory."""
    names = sorted(p.name for p in d.iterdir())
    assert not [n for n in names if n.startswith(".") or "tmp" in n], names
    assert len(names) == 2 and out.name in names, names


def test_kill_9_at_five_points_loses_nothing_and_leaves_nothing(tmp_path, default_graph):
    samples = []
    for k, x in enumerate((-4.0, -3.0)):
        d = tmp_path / f"s{k}"
        d.mkdir()
        (d / "scenario.toml").write_text(SCENARIO.format(x=x))
        samples.append(d)
    work = tmp_path / "out"
    work.mkdir()
    out = work / "two.usdc"
    _finish(_bake(samples[0], out))
    for k, stage in enumerate(("planning", "writing", "clips", "checking", "replacing")):
        before = _kept(work, out)
        other = samples[(k + 1) % 2]          # a different scenario: a different stage and clips
        proc = _bake(other, out, pause=stage)
        _wait_for_pause(proc, stage)
        kids = _descendants(proc.pid)
        if stage == "clips":
            assert len(kids) >= 2, "the clip workers run"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        t0 = time.time()
        while _alive(kids) and time.time() - t0 < 5.0:
            time.sleep(0.1)
        assert not _alive(kids), f"kill -9 at {stage}: children {_alive(kids)} survived 5 s"
        assert _kept(work, out) == before, f"kill -9 at {stage} changed the previous output"
        _finish(_bake(other, out))            # the next bake to the same path
        _clean(work, out)
        assert _kept(work, out) != before     # it did replace the stage


def test_sigterm_while_workers_run_cleans_up_at_once(tmp_path, default_graph):
    d = tmp_path / "s"
    d.mkdir()
    (d / "scenario.toml").write_text(SCENARIO.format(x=-4.0))
    work = tmp_path / "out"
    work.mkdir()
    out = work / "two.usdc"
    _finish(_bake(d, out))
    before = _kept(work, out)
    (d / "scenario.toml").write_text(SCENARIO.format(x=-3.0))
    proc = _bake(d, out, pause="clips")
    _wait_for_pause(proc, "clips")
    kids = _descendants(proc.pid)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    t0 = time.time()
    while _alive(kids) and time.time() - t0 < 5.0:
        time.sleep(0.1)
    assert not _alive(kids)
    assert _kept(work, out) == before
    _clean(work, out)                         # nothing left, without another bake
