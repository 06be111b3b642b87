"""Where motion libraries live, and loading them by name.

``"default"`` is the library built from the procedural capture (seed 0); the authoring tools
build it on first use and cache it in :func:`cache_dir` (``$CROWDWEAVE_CACHE``, else
``~/.cache/crowdweave``). The runtime only loads packs: if the default library has not been
built yet, loading it raises :class:`~runtime.assets.AssetError` saying how to build it.
"""
from __future__ import annotations

import os
from pathlib import Path

from .assets import AssetError
from .motion.graph import MotionGraph

__all__ = ["cache_dir", "default_library_path", "resolve_library", "load_library"]

DEFAULT_LIBRARY_NAME = "default-v3.cwpack"   # the motion_graph pack version: packs of both can share a cache


def cache_dir() -> Path:
    d = os.environ.get("CROWDWEAVE_CACHE")
    return Path(d) if d else Path.home() / ".cache" / "crowdweave"


def default_library_path() -> Path:
    return cache_dir() / DEFAULT_LIBRARY_NAME


def resolve_library(name_or_path, base: Path | None = None) -> Path:
    """``"default"`` -> the cached default library; otherwise a path (relative to ``base``)."""
    if str(name_or_path) == "default":
        return default_library_path()
    p = Path(name_or_path)
    if not p.is_absolute() and base is not None:
        p = base / p
    return p


_loaded: dict = {}


def load_library(name_or_path="default", base: Path | None = None) -> MotionGraph:
    """Load (and memoise by path and modification time) a motion-graph pack."""
    p = resolve_library(name_or_path, base)
    if not p.exists():
        if str(name_or_path) == "default":
            raise AssetError(p, "the default motion library has not been built yet: "
                                "run `crowdweave demo --no-window` once to build it")
        raise AssetError(p, "file not found")
    key = (str(p.resolve()), p.stat().st_mtime_ns)
    if key not in _loaded:
        _loaded[key] = MotionGraph.load(p)
    return _loaded[key]
