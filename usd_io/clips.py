"""Value clips for very large baked crowds: the time samples of N characters per layer, written
by parallel worker processes.

A bake with ``clips_per=N`` writes, beside ``out.usdc``::

    out.usdc                            the stage: every prim, the frame arrays, clip metadata
    out.usdc.clips-<digest>/            the clip directory (assembled under a temporary name,
        chunk_0000.usdc                 then renamed: never half-written)
        chunk_0001.usdc                 root translate ops, joint rotations, crowdweave:root of
        ...                             characters N*k .. N*k+N-1, as time samples
        manifest.usda                   the attributes the clips carry (no values)

Each character's SkelRoot carries one clip set (``Usd.ClipsAPI``, set ``default``) with its
chunk layer as the only clip, ``primPath`` = its own path (so one layer serves N characters),
``active = [(start, 0)]`` and the identity ``times`` mapping over its frames; USD composes the
clip's samples as if they were authored in the stage (UsdSkel, ``Usd.Attribute.Get`` and
``GetTimeSamples`` all see them).

The directory name ends in a digest of its files, so the stage on disk always refers to a
complete directory of matching content: a new bake renames a new directory into place before
the stage is replaced, and :func:`remove_unused_clip_dirs` deletes the old one afterwards.
Chunk layers are written in a ``spawn`` process pool (each process authors its chunks through
Sdf and exports them), or, given a Dask scheduler address, on that cluster's workers: each worker
returns its layer as the bytes of a ``.usdc`` file and this process writes them into the
temporary directory, so the workers need no filesystem shared with the stage (only the tracks
and the library travel, and the layers come back once). Same input gives byte-identical files
either way.

The workers die with the process that started them: each asks the kernel for SIGKILL when its
parent exits (Linux ``PR_SET_PDEATHSIG``) and also watches its parent id, so a bake killed with
``kill -9`` leaves no worker behind; on an error or a signal the bake terminates them itself.
The directory is assembled under a temporary name carrying the bake's pid
(:func:`runtime.assets.temp_path`), which the next write to the same stage removes if that
process is gone.
"""
from __future__ import annotations

import hashlib
import multiprocessing
import os
import pickle
import re
import shutil
import signal
import sys
import tempfile
import threading
import time
import uuid
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from pxr import Gf, Sdf, Vt

from runtime.assets import pause_point, temp_path

from .stage import StageError
from .timesamples import SkelValues, author_tracks, define_animated_specs

__all__ = ["write_clip_layers", "ClipLayers", "remove_unused_clip_dirs", "clip_dir_pattern", "export_with_digest",
           "failed_stage_path", "chunk_layer_bytes", "MANIFEST"]

MANIFEST = "manifest.usda"
GRAPH_FILE = ".graph.pickle"     # the library, for the workers (removed before the rename)


def failed_stage_path(out_path) -> Path:
    """Where a bake keeps a stage that failed its check when asked to (``out.failed.usdc`` beside
    ``out.usdc``); it may refer to a clip directory named after ``out_path``."""
    p = Path(out_path)
    return p.with_name(f"{p.stem}.failed{p.suffix}")


def clip_dir_pattern(out_path) -> re.Pattern:
    """Names of the clip directories a bake to ``out_path`` writes (``<name>.clips-<16 hex>``)."""
    return re.compile(re.escape(Path(out_path).name) + r"\.clips-[0-9a-f]{16}")


def _default_mode(mode: int) -> int:
    um = os.umask(0)
    os.umask(um)
    return mode & ~um


def export_with_digest(layer: Sdf.Layer, path: Path) -> str:
    """Export ``layer`` to ``path``, fsync it, and return the file's sha256 (hex); StageError
    when the export fails."""
    if not layer.Export(str(path)):
        raise StageError(path, "USD export failed")
    h = hashlib.sha256()
    with open(path, "rb") as f:
        os.fsync(f.fileno())
        for block in iter(lambda: f.read(1 << 22), b""):
            h.update(block)
    return h.hexdigest()


def _chunk_layer(graph, sv, fps: float, items) -> Sdf.Layer:
    """A clip layer holding the time samples of ``items`` ((SkelRoot path, Track), ...)."""
    layer = Sdf.Layer.CreateAnonymous("chunk.usdc")
    layer.timeCodesPerSecond = float(fps)
    layer.framesPerSecond = float(fps)
    with Sdf.ChangeBlock():
        author_tracks(layer, items, graph, sv, lambda path, tr: define_animated_specs(layer, Sdf.Path(path)))
    return layer


def chunk_layer_bytes(graph, fps: float, name: str, items) -> tuple[str, bytes]:
    """``(name, bytes of the .usdc file)`` of the clip layer of ``items`` (what a Dask worker
    returns: the same bytes the process pool exports)."""
    with tempfile.TemporaryDirectory(prefix="crowdweave-chunk-") as d:
        path = Path(d) / name
        layer = _chunk_layer(graph, SkelValues.of(graph.skeleton), fps, items)
        if not layer.Export(str(path)):
            raise StageError(path, "USD export failed")
        return name, path.read_bytes()


def _write_fsync(path: Path, data: bytes) -> str:
    with open(path, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    return hashlib.sha256(data).hexdigest()


# -- worker processes -----------------------------------------------------------------------------
_W: dict = {}


def _die_with_parent(parent: int) -> None:
    """End this worker when ``parent`` exits, however it exits (``kill -9`` included)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)    # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch():
        while os.getppid() == parent:
            time.sleep(0.2)
        os._exit(1)
    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=watch, daemon=True, name="parent-watch").start()


def _init_worker(graph_file, fps, parent):
    _die_with_parent(parent)
    with open(graph_file, "rb") as f:
        graph = pickle.load(f)
    _W.update(graph=graph, fps=fps, sv=SkelValues.of(graph.skeleton))


def _write_chunk(args):
    directory, name, items = args
    pause_point("clips")
    layer = _chunk_layer(_W["graph"], _W["sv"], _W["fps"], items)
    return name, export_with_digest(layer, Path(directory) / name)


class ClipLayers:
    """Clip layers being written for one bake (see :func:`write_clip_layers`)."""

    def __init__(self, out_path, items, graph, fps: float, clips_per: int, workers: int | None,
                 scheduler: str | None = None):
        self.out = Path(out_path)
        self.scheduler = scheduler
        self.fps = float(fps)
        self.graph = graph
        chunks = [items[i:i + clips_per] for i in range(0, len(items), clips_per)]
        self.tasks = [(f"chunk_{k:04d}.usdc", [(str(p), tr) for p, tr in c]) for k, c in enumerate(chunks)]
        self.chunk_of = {str(p): name for name, c in self.tasks for p, _ in c}
        self.workers = max(1, min(int(workers or min(2, os.cpu_count() or 1)), len(self.tasks)))
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = temp_path(self.out, suffix="-clips", directory=True)
        self.dir_name: str | None = None
        self._pool = self._pending = self._client = None
        try:
            self._start(graph)
        except BaseException:
            self.close(failed=True)
            raise

    def _start(self, graph) -> None:
        if self.scheduler:
            self._start_dask(graph)
        elif self.workers > 1:
            # The library goes to the workers as a file: a large argument would block this process
            # until each worker has started up and read it. spawn, not fork: the parent has USD (and
            # its thread pool) loaded. A worker that dies raises BrokenProcessPool instead of hanging.
            graph_file = self.tmp / GRAPH_FILE
            with open(graph_file, "wb") as f:
                pickle.dump(graph, f, protocol=pickle.HIGHEST_PROTOCOL)
            self._pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=_init_worker,
                                             initargs=(str(graph_file), self.fps, os.getpid()))
            self._pending = [self._pool.submit(_write_chunk, (str(self.tmp), n, c)) for n, c in self.tasks]

    def _start_dask(self, graph) -> None:
        # A lost worker's chunks are computed again by the scheduler; this process writes each
        # layer exactly once, as its result arrives.
        from distributed import Client
        try:
            self._client = Client(self.scheduler, timeout=10, set_as_default=False)
        except (OSError, ValueError, TypeError) as e:
            raise ConnectionError(f"cannot reach the Dask scheduler at {self.scheduler}: {e}") from None
        graph_data = self._client.scatter(graph, broadcast=False, hash=False)
        run = uuid.uuid4().hex[:12]
        self._pending = [self._client.submit(chunk_layer_bytes, graph_data, self.fps, n, c, pure=False,
                                             key=f"crowdweave-clip-{n}-{run}")
                         for n, c in self.tasks]

    def _wait_dask(self) -> list:
        from distributed import as_completed
        digests = []
        for fut in as_completed(self._pending, loop=self._client.loop):
            name, data = fut.result()
            digests.append((name, _write_fsync(self.tmp / name, data)))
            fut.release()
        self._client.close()
        self._client = None
        return digests

    def wait(self) -> str:
        """Wait for the chunk layers, write the manifest, rename the directory into place; returns
        its name (relative to the stage's directory)."""
        if self._client is not None:
            digests = self._wait_dask()
        elif self._pool is not None:
            digests = [f.result() for f in self._pending]
            self._pool.shutdown()
            self._pool = None
            (self.tmp / GRAPH_FILE).unlink()
        else:
            sv = SkelValues.of(self.graph.skeleton)
            digests = [(n, export_with_digest(_chunk_layer(self.graph, sv, self.fps, c), self.tmp / n))
                       for n, c in self.tasks]
        manifest = Sdf.Layer.CreateAnonymous("manifest.usda")
        manifest.timeCodesPerSecond = self.fps
        manifest.framesPerSecond = self.fps
        with Sdf.ChangeBlock():
            for p in self.chunk_of:
                define_animated_specs(manifest, Sdf.Path(p))
        digests.append((MANIFEST, export_with_digest(manifest, self.tmp / MANIFEST)))
        h = hashlib.sha256("".join(f"{n}:{d}\n" for n, d in sorted(digests)).encode())
        self.dir_name = f"{self.out.name}.clips-{h.hexdigest()[:16]}"
        final = self.out.parent / self.dir_name
        os.chmod(self.tmp, _default_mode(0o777))
        if final.is_dir():          # the same content (the name is its digest): keep the one in place
            shutil.rmtree(self.tmp)
        else:
            os.rename(self.tmp, final)
        return self.dir_name

    def author_clip_set(self, prim_spec: Sdf.PrimSpec, path, track) -> None:
        """The clip set of one character on its SkelRoot spec (call after :meth:`wait`)."""
        assert self.dir_name is not None, "wait() first"
        start = float(track.start_frame)
        end = start + len(track) - 1
        times = [Gf.Vec2d(start, start)] + ([Gf.Vec2d(end, end)] if end > start else [])
        prim_spec.SetInfo("clips", {"default": {
            "assetPaths": Sdf.AssetPathArray([f"./{self.dir_name}/{self.chunk_of[str(path)]}"]),
            "manifestAssetPath": Sdf.AssetPath(f"./{self.dir_name}/{MANIFEST}"),
            "primPath": str(path),
            "active": Vt.Vec2dArray([Gf.Vec2d(start, 0.0)]),
            "times": Vt.Vec2dArray(times),
        }})

    def close(self, failed: bool) -> None:
        """Stop the workers (terminated at once after a failure or a signal: they may be in the
        middle of a chunk) and remove the temporary directory if it is still there."""
        if self._client is not None:
            self._client.cancel(self._pending)
            self._client.close()
            self._client = None
        if self._pool is not None:
            if failed:      # the executor offers no way to stop running tasks: end its processes
                for p in list((getattr(self._pool, "_processes", None) or {}).values()):
                    p.terminate()
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self.tmp.exists():
            shutil.rmtree(self.tmp, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(exc_type is not None)
        return False


def write_clip_layers(out_path, items, graph, fps: float, clips_per: int, workers: int | None = None,
                      scheduler: str | None = None) -> ClipLayers:
    """Start writing the clip layers of ``items`` ((SkelRoot path, Track), ...) for a stage that
    will be saved as ``out_path``: ``clips_per`` characters per layer, ``workers`` processes
    (default 2; 1 writes in this process), or the workers of the Dask cluster at ``scheduler``
    (ConnectionError, naming the address, when it cannot be reached). Use as a context manager;
    :meth:`ClipLayers.wait` finishes the directory (temporary name, then rename), :meth:`ClipLayers.author_clip_set` points a
    character at its layer. On an error the temporary directory is removed."""
    return ClipLayers(out_path, list(items), graph, fps, int(clips_per), workers, scheduler)


def _clip_dir_of(stage_path: Path) -> str:
    """The clip directory a saved stage names in its customLayerData (or "")."""
    if not stage_path.is_file():
        return ""
    try:
        layer = Sdf.Layer.OpenAsAnonymous(str(stage_path), metadataOnly=True)
    except Exception:     # an unreadable stage refers to nothing
        return ""
    return (layer.customLayerData.get("crowdweave:clipDirectory") if layer else None) or ""


def remove_unused_clip_dirs(out_path, keep: str | None = None) -> list[Path]:
    """Delete clip directories of earlier bakes to ``out_path`` other than ``keep`` (default: the
    one the saved stage names in its customLayerData ``crowdweave:clipDirectory``) and the one a
    kept failed stage (:func:`failed_stage_path`) names; returns them."""
    out = Path(out_path)
    if keep is None:
        keep = _clip_dir_of(out)
    keep = {keep, _clip_dir_of(failed_stage_path(out))}
    pat = clip_dir_pattern(out)
    removed = []
    if out.parent.is_dir():
        for d in sorted(out.parent.iterdir()):
            if d.is_dir() and pat.fullmatch(d.name) and d.name not in keep:
                shutil.rmtree(d, ignore_errors=True)
                removed.append(d)
    return removed
