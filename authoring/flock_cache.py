"""Flock motion graphs named by a recording recipe, recorded and built once and cached."""
from __future__ import annotations

import sys
from pathlib import Path

from runtime.assets import AssetError
from runtime.library import cache_dir

__all__ = ["ensure_ddg", "resolve_scenario_flocks"]


def ensure_ddg(recipe: dict, log=print, progress=True) -> Path:
    """Pack path of the DDG for ``{dim, agents, seconds, seed}`` (built on first use)."""
    from runtime.flock.ddg import load_ddg, save_ddg
    dim, agents = int(recipe.get("dim", 2)), int(recipe.get("agents", 20))
    seconds, seed = float(recipe.get("seconds", 120.0)), int(recipe.get("seed", 0))
    p = cache_dir() / "flocks" / f"ddg-{dim}d-{agents}a-{seconds:g}s-seed{seed}.cwpack"
    if p.exists():
        try:
            load_ddg(p)
            return p
        except AssetError as e:
            log(f"cached flock graph unusable ({e.reason}); rebuilding")
    from tqdm import tqdm

    from authoring.boids import BoidsParams, record_flock
    from authoring.ddg import DDGBuildParams, build_ddg
    quiet = not progress or not sys.stderr.isatty()
    log(f"recording a {dim}D flock of {agents} for {seconds:g} s (seed {seed}) and building its graph")
    rp = BoidsParams(n_agents=agents, dim=dim)
    with tqdm(total=int(round(seconds * rp.fps)), desc="recording boids", unit="step", disable=quiet) as bar:
        rec = record_flock(rp, seconds, seed=seed, progress=bar.update)
    ddg, _ = build_ddg(rec, DDGBuildParams(),
                       progress=lambda desc, total: tqdm(total=total, desc=desc, unit="pair", disable=quiet, leave=False))
    save_ddg(p, ddg)
    return p


def resolve_scenario_flocks(sc, base: Path, log=print, progress=True) -> None:
    """Load each ``[[flock]]``'s DDG into ``spec.loaded`` (building recipes as needed)."""
    from runtime.flock.ddg import load_ddg
    for spec in sc.flocks:
        if isinstance(spec.ddg, dict):
            spec.loaded = load_ddg(ensure_ddg(spec.ddg, log=log, progress=progress))
        else:
            p = Path(spec.ddg)
            spec.loaded = load_ddg(p if p.is_absolute() else base / p)
