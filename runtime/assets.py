"""Versioned msgpack asset packs (``*.cwpack``), ARCHITECTURE.md "Assets".

On disk a pack is one msgpack map::

    {"format": "crowdweave", "kind": str, "version": int, "meta": {...},
     "arrays": {name: {"dtype": str, "shape": [..], "data": bytes}}, "sha256": hex}

``sha256`` covers the canonical msgpack encoding of everything else. Writes are atomic
(temporary file in the same folder, fsync, rename), so a write killed midway leaves the
previous pack intact. Loading checks format, kind, version and checksum and raises
:class:`AssetError` naming the file and the reason; it never returns a half-loaded pack.

Reads are bounded whatever the file system reports: only regular files are read (not a
device such as ``/dev/zero``, even through a symbolic link), in blocks, up to
:data:`MAX_PACK_BYTES`, and a file that does not start like a pack is rejected at its first
byte. Temporary files are named ``.<name>.tmp-<pid>-<random>`` beside their target, so a
temporary left by a process that was killed (``kill -9`` cannot be caught) is recognised and
removed by the next write to the same path (:func:`sweep_stale_temps`).
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import stat
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import msgpack
import numpy as np

__all__ = ["AssetError", "Pack", "save_pack", "load_pack", "pack_fields", "atomic_write_bytes", "atomic_path",
           "temp_path", "commit_temp", "sweep_stale_temps", "read_bounded", "pause_point", "PAUSE_ENV"]

FORMAT = "crowdweave"
# Largest pack accepted: the read stops here whatever the file claims (a pack's arrays are
# copied once more when decoded, so this is about a third of a workstation's memory).
MAX_PACK_BYTES = 4 << 30
_READ_BLOCK = 1 << 24


class AssetError(Exception):
    """A pack could not be read: names the file and what is wrong."""

    def __init__(self, path, reason: str):
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{path}: {reason}")


@dataclass
class Pack:
    kind: str
    version: int
    meta: dict = field(default_factory=dict)
    arrays: dict = field(default_factory=dict)
    path: str | None = None


def _encode_arrays(arrays: dict) -> dict:
    out = {}
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        if a.dtype == object:
            raise TypeError(f"array {name!r} has dtype object; packs hold numeric arrays only")
        out[name] = {"dtype": a.dtype.str, "shape": list(a.shape), "data": a.tobytes()}
    return out


def _body_bytes(body: dict) -> bytes:
    return msgpack.packb(body, use_bin_type=True)


def _default_mode() -> int:
    """0666 minus the umask: what ``open()`` would give a new file (mkstemp uses 0600)."""
    um = os.umask(0)
    os.umask(um)
    return 0o666 & ~um


def _temp_prefix(path: Path, pid: int | None = None) -> str:
    return f".{path.name}.tmp-{os.getpid() if pid is None else pid}-"


def temp_path(path, suffix: str = "", directory: bool = False) -> Path:
    """A new, empty temporary file (or directory) beside ``path``, named
    ``.<name>.tmp-<pid>-<random><suffix>`` (the parent is created if needed). The caller
    renames or removes it; one left by a killed process is removed by :func:`sweep_stale_temps`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if directory:
        return Path(tempfile.mkdtemp(prefix=_temp_prefix(path), suffix=suffix, dir=path.parent))
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=suffix, dir=path.parent)
    os.close(fd)
    return Path(tmp)


PAUSE_ENV = "CROWDWEAVE_PAUSE_AT"


def pause_point(name: str) -> None:
    """A test hook at a named point of a long write: when the environment variable
    ``CROWDWEAVE_PAUSE_AT`` equals ``name``, say so on stderr and wait (tests kill the process
    there, e.g. ``tests/test_hardening_kill.py``). Does nothing otherwise."""
    if os.environ.get(PAUSE_ENV) == name:
        import sys
        import time
        print(f"crowdweave: paused at {name} (pid {os.getpid()})", file=sys.stderr, flush=True)
        while True:
            time.sleep(60)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def sweep_stale_temps(path) -> list[Path]:
    """Remove the temporary files and directories of writes to ``path`` (see :func:`temp_path`)
    whose process no longer runs; returns them. Temporaries of running processes are left."""
    path = Path(path)
    pat = re.compile(re.escape(f".{path.name}.tmp-") + r"(\d+)-")
    removed = []
    try:
        entries = list(path.parent.iterdir())
    except OSError:
        return removed
    for e in entries:
        m = pat.match(e.name)
        if m is None or int(m.group(1)) == os.getpid() or _alive(int(m.group(1))):
            continue
        try:
            shutil.rmtree(e) if e.is_dir() and not e.is_symlink() else e.unlink()
            removed.append(e)
        except FileNotFoundError:
            pass
    return removed


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: temp file beside it, fsync, rename (temporaries
    that killed writers left beside ``path`` are removed first)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sweep_stale_temps(path)
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, _default_mode())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def commit_temp(tmp, path) -> Path:
    """Make a finished temporary file ``path``: fsync it, give it the permissions a plain
    ``open()`` would (0666 less the umask; mkstemp uses 0600) and rename it onto ``path``."""
    with open(tmp, "rb+") as f:
        os.fsync(f.fileno())
    os.chmod(tmp, _default_mode())
    os.replace(tmp, path)
    return Path(path)


class atomic_path:
    """Context manager giving a temporary path beside ``path``; renamed onto ``path`` only if
    the block succeeds (for writers such as USD that want a file name, not bytes)::

        with atomic_path("out.usdc") as tmp:
            stage.GetRootLayer().Export(tmp)
    """

    def __init__(self, path, suffix: str | None = None):
        self.path = Path(path)
        self.suffix = suffix if suffix is not None else self.path.suffix

    def __enter__(self) -> str:
        sweep_stale_temps(self.path)
        self.tmp = str(temp_path(self.path, suffix=".tmp" + self.suffix))
        return self.tmp

    def __exit__(self, exc_type, exc, tb):
        try:
            if exc_type is None:
                commit_temp(self.tmp, self.path)
        finally:
            try:
                os.unlink(self.tmp)     # still there if the block or the rename failed
            except OSError:
                pass
        return False


def save_pack(path, kind: str, version: int, meta: dict | None = None, arrays: dict | None = None) -> Path:
    body = {
        "format": FORMAT,
        "kind": str(kind),
        "version": int(version),
        "meta": meta or {},
        "arrays": _encode_arrays(arrays or {}),
    }
    raw = _body_bytes(body)
    body["sha256"] = hashlib.sha256(raw).hexdigest()
    atomic_write_bytes(path, _body_bytes(body))
    return Path(path)


def load_pack(path, kind: str | None = None, version: int | None = None,
              min_version: int | None = None) -> Pack:
    """Load and verify a pack. ``kind``/``version`` (exact) or ``min_version`` check what the
    caller can read."""
    path = Path(path)
    raw = read_bounded(path, MAX_PACK_BYTES, AssetError, first=_looks_like_a_pack)
    if not raw:
        raise AssetError(path, "file is empty")
    try:
        body = msgpack.unpackb(raw, raw=False, strict_map_key=True)
    except Exception as e:  # msgpack raises several types for truncated/garbled input
        raise AssetError(path, f"not a valid msgpack pack (truncated or corrupt): {type(e).__name__}: {e}") from None
    if not isinstance(body, dict):
        raise AssetError(path, "not a crowdweave pack (top level is not a map)")
    if body.get("format") != FORMAT:
        raise AssetError(path, f"not a crowdweave pack (format={body.get('format')!r})")
    for key, typ in (("kind", str), ("version", int), ("meta", dict), ("arrays", dict), ("sha256", str)):
        if not isinstance(body.get(key), typ):
            raise AssetError(path, f"field {key!r} missing or of the wrong type")
    digest = body.pop("sha256")
    if hashlib.sha256(_body_bytes(body)).hexdigest() != digest:
        raise AssetError(path, "checksum mismatch (file is corrupt or was modified)")
    if kind is not None and body["kind"] != kind:
        raise AssetError(path, f"wrong kind: expected {kind!r}, file holds {body['kind']!r}")
    if version is not None and body["version"] < version:
        raise AssetError(path, f"unsupported version {body['version']} (this build reads version {version}): the pack "
                               f"was written by an older crowdweave; rebuild it from its sources")
    if version is not None and body["version"] != version:
        raise AssetError(path, f"unsupported version {body['version']} (this build reads version {version})")
    if min_version is not None and body["version"] < min_version:
        raise AssetError(path, f"version {body['version']} is older than the oldest supported ({min_version})")
    arrays = {}
    for name, spec in body["arrays"].items():
        try:
            dt = np.dtype(spec["dtype"])
            shape = tuple(int(s) for s in spec["shape"])
            a = np.frombuffer(spec["data"], dtype=dt)
            arrays[name] = a.reshape(shape).copy()
        except Exception as e:
            raise AssetError(path, f"array {name!r} is malformed: {e}") from None
    return Pack(body["kind"], body["version"], body["meta"], arrays, str(path))


def _looks_like_a_pack(head: bytes) -> str | None:
    """Why ``head`` (a file's first bytes) cannot start a pack (a msgpack map), or None."""
    if head and not (0x80 <= head[0] <= 0x8F or head[0] in (0xDE, 0xDF)):
        return f"not a crowdweave pack (starts with byte 0x{head[0]:02x}, not a msgpack map)"
    return None


def read_bounded(path, limit: int, error=AssetError, first=None) -> bytes:
    """The bytes of the regular file ``path``, read in blocks and never more than ``limit``
    (whatever ``stat`` reports). ``error(path, reason)`` is raised for a missing file, a
    directory, a device or pipe, an unreadable file, or one over the limit; ``first(head)`` may
    return a reason to reject the file from its first block."""
    path = Path(path)
    try:
        # O_NONBLOCK: opening a named pipe must not wait for a writer (no effect on files)
        with os.fdopen(os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)), "rb") as f:
            mode = os.fstat(f.fileno()).st_mode
            if not stat.S_ISREG(mode):
                kind = "a directory" if stat.S_ISDIR(mode) else "a device or pipe"
                raise error(path, f"not a regular file ({kind})")
            chunks, total = [], 0
            while True:
                block = f.read(min(_READ_BLOCK, limit + 1 - total))
                if not block:
                    break
                if not chunks and first is not None:
                    why = first(block)
                    if why:
                        raise error(path, why)
                chunks.append(block)
                total += len(block)
                if total > limit:
                    raise error(path, f"larger than the {limit / (1 << 20):g} MB limit")
    except FileNotFoundError:
        raise error(path, "file not found") from None
    except IsADirectoryError:
        raise error(path, "not a regular file (a directory)") from None
    except OSError as e:
        raise error(path, f"cannot read: {e.strerror or e}") from None
    return b"".join(chunks)


@contextmanager
def pack_fields(path, what: str):
    """Read a loaded pack's meta and arrays inside this block: any error but an
    :class:`AssetError` becomes one naming ``path`` as ``"<what>: <Type>: <message>"`` (a
    missing key, a wrong type, an inconsistent shape), so a bad pack never half-loads.

    Args:
        path: the pack's file, for the message.
        what: what is wrong, e.g. ``"motion graph pack is inconsistent"``.
    """
    try:
        yield
    except AssetError:
        raise
    except Exception as e:
        raise AssetError(path, f"{what}: {type(e).__name__}: {e}") from None
