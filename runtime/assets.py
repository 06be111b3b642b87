"""Versioned msgpack asset packs (``*.cwpack``), ARCHITECTURE.md "Assets".

On disk a pack is one msgpack map::

    {"format": "crowdweave", "kind": str, "version": int, "meta": {...},
     "arrays": {name: {"dtype": str, "shape": [..], "data": bytes}}, "sha256": hex}

``sha256`` covers the canonical msgpack encoding of everything else. Writes are atomic
(temporary file in the same folder, fsync, rename), so a write killed midway leaves the
previous pack intact. Loading checks format, kind, version and checksum and raises
:class:`AssetError` naming the file and the reason; it never returns a half-loaded pack.
"""
from __future__ import annotations

import hashlib
import os
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import msgpack
import numpy as np

__all__ = ["AssetError", "Pack", "save_pack", "load_pack", "pack_fields", "atomic_write_bytes", "atomic_path"]

FORMAT = "crowdweave"
# Largest pack accepted (guards against decoding garbage as a huge allocation).
MAX_PACK_BYTES = 8 << 30


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


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: temp file beside it, fsync, rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
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
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, self.tmp = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=".tmp" + self.suffix,
                                        dir=self.path.parent)
        os.close(fd)
        return self.tmp

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            with open(self.tmp, "rb+") as f:
                os.fsync(f.fileno())
            os.chmod(self.tmp, _default_mode())
            os.replace(self.tmp, self.path)
        else:
            try:
                os.unlink(self.tmp)
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
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise AssetError(path, "file not found") from None
    except OSError as e:
        raise AssetError(path, f"cannot read: {e}") from None
    if size > MAX_PACK_BYTES:
        raise AssetError(path, f"file is {size} bytes, larger than the {MAX_PACK_BYTES} byte limit")
    raw = path.read_bytes()
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
