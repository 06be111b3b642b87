"""The default motion library: procedural capture (seed 0) -> snap-together motion graph.

Built on first use and cached (``runtime.library.default_library_path``); the cache key holds
the generator version, so a new generator rebuilds it.
"""
from __future__ import annotations

import sys
from pathlib import Path

from runtime.assets import AssetError
from runtime.library import cache_dir, default_library_path, resolve_library
from runtime.motion.graph import MotionGraph

__all__ = ["DEFAULT_MINUTES", "DEFAULT_SEED", "ensure_library", "build_default_library", "default_capture_dir"]

DEFAULT_MINUTES = 6.0
DEFAULT_SEED = 0


def default_capture_dir() -> Path:
    from authoring.procedural import GENERATOR_VERSION
    return cache_dir() / f"capture-seed{DEFAULT_SEED}-{DEFAULT_MINUTES:g}min-v{GENERATOR_VERSION}"


def build_default_library(log=print, progress=True) -> Path:
    from tqdm import tqdm

    from authoring.motion_graph.build import BUILDER_VERSION, GraphBuildParams, build_graph
    from authoring.motion_graph.sources import load_takes
    from authoring.procedural import GENERATOR_VERSION, write_session
    cap = default_capture_dir()
    quiet = not progress or not sys.stderr.isatty()
    if not (cap / "session.json").exists():
        log(f"generating the default capture ({DEFAULT_MINUTES:g} min, seed {DEFAULT_SEED}) in {cap}")
        with tqdm(total=DEFAULT_MINUTES * 60, desc="capture", unit="s", disable=quiet) as bar:
            write_session(cap, DEFAULT_MINUTES, DEFAULT_SEED, progress=bar.update)
    takes = load_takes([cap])
    frames = sum(t.clip.num_frames for t in takes)
    log(f"building the default motion graph from {len(takes)} takes ({frames / 30:.0f} s)")
    with tqdm(total=frames, desc="frame distances", unit="frame", disable=quiet) as bar:
        g = build_graph(takes, GraphBuildParams(), progress=bar.update, log=log)
    g.meta["generator_version"] = GENERATOR_VERSION
    g.meta["builder_version"] = BUILDER_VERSION
    out = default_library_path()
    g.save(out)
    log(f"default library: {g.num_nodes} nodes, {g.num_edges} edges, {g.total_seconds:.0f} s -> {out}")
    return out


def ensure_library(name_or_path="default", base: Path | None = None, log=print, progress=True) -> Path:
    """Path of a usable library, building the default one if needed (or stale)."""
    p = resolve_library(name_or_path, base)
    if str(name_or_path) != "default":
        if not p.exists():
            raise AssetError(p, "motion library not found")
        return p
    from authoring.motion_graph.build import BUILDER_VERSION
    from authoring.procedural import GENERATOR_VERSION
    if p.exists():
        try:
            g = MotionGraph.load(p)
            if (g.meta.get("generator_version") == GENERATOR_VERSION
                    and g.meta.get("builder_version") == BUILDER_VERSION):
                return p
            log("default library was built by an older generator or builder; rebuilding")
        except AssetError as e:
            log(f"default library unusable ({e.reason}); rebuilding")
    return build_default_library(log=log, progress=progress)
