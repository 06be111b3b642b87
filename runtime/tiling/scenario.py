"""Tiling scenarios: a small TOML config -> a patch library recipe and a tiling run.

Used by ``samples/make_tiling_samples.py`` (each ``samples/tiling_*/tiling.toml``), the tests and
the benchmarks. A config::

    name = "tiling_static_30"
    description = "..."
    mode = "static"                    # or "interactive"
    seed = 1

    [library]                          # single-character patches of the motion graph, plus
    graph = "default"                  #   synthetic multi-character patches (runtime.tiling.synthetic)
    meets = 4
    passes = 0
    rows = 0
    carry = false                      # carrying / pick-up / put-down single patches too
    patches = ""                       # optional motion_patches pack (authoring), merged in

    [region]
    origin = [0.0, 0.0]
    size = [12.0, 12.0]
    seconds = 20.0
    wrap_space = false

    [tiler]                            # TilerConfig fields (seeds, alpha, i_max, ...) and
    seeds = 30                         # size_power / label_cost for the preference (Eq. 7)

    [[keyframe]]                       # fixed patch instances
    patch = "rows0"; x = 6.0; z = 6.0; heading = 0.0; t = 1.5

    [[obstacle]]                       # static: center; moving: path (back and forth) + period
    half = [0.4, 0.4]; height = 2.0; center = [3.0, 6.0]
    # path = [[2.0, 2.0], [10.0, 2.0]]; period = 8.0; spin = 45.0 (deg/s)

    [[portal]]
    x = 0.0; z = 6.0; radius = 1.5; kind = "source"

    [interactive]                      # mode = "interactive"
    seconds = 20.0
    horizon = 1.5
    interaction_labels = ["meet"]
    [[interactive.team]]
    count = 4; start = [-4.0, 0.0]; heading = 90.0; spacing = 1.5
    targets = [[0.0, 4.0, 0.0], [8.0, -3.0, 0.0]]   # (time s, x, z): the team's target from then on

Errors name the file and the key (:class:`TilingConfigError`).
"""
from __future__ import annotations

import math
import time as _time
import tomllib
from pathlib import Path

import numpy as np

from .config import TilerConfig
from .interactive import InteractiveTiling
from .patch import PatchLibrary, single_character_patches
from .preference import Preference
from .prepared import PreparedLibrary
from .region import Obstacle, Portal, Region
from .synthetic import synthetic_library
from .tiler import Tiler

__all__ = ["TilingConfigError", "load_config", "build_library", "make_obstacles", "run_config"]


class TilingConfigError(ValueError):
    def __init__(self, path, reason):
        self.path = str(path)
        super().__init__(f"{path}: {reason}")


def load_config(path) -> dict:
    path = Path(path)
    try:
        cfg = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise TilingConfigError(path, "file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise TilingConfigError(path, f"not valid TOML: {e}") from None
    cfg["_path"] = str(path)
    mode = cfg.get("mode", "static")
    if mode not in ("static", "interactive"):
        raise TilingConfigError(path, f"mode must be 'static' or 'interactive', not {mode!r}")
    for key in ("region",) if mode == "static" else ("interactive",):
        if key not in cfg:
            raise TilingConfigError(path, f"missing [{key}] table")
    return cfg


def _get(cfg, table, key, default, typ=None):
    v = cfg.get(table, {}).get(key, default)
    if typ is not None and v is not None:
        try:
            v = typ(v)
        except (TypeError, ValueError):
            raise TilingConfigError(cfg.get("_path", "<config>"), f"[{table}] {key} = {v!r} is not a {typ.__name__}") from None
    return v


def build_library(cfg: dict, graph) -> PatchLibrary:
    lib_cfg = cfg.get("library", {})
    known = {"graph", "meets", "passes", "rows", "carry", "patches", "max_per_pair"}
    extra = set(lib_cfg) - known
    if extra:
        raise TilingConfigError(cfg.get("_path", "<config>"), f"[library] unknown keys {sorted(extra)}")
    carry = bool(lib_cfg.get("carry", False))
    singles = single_character_patches(
        graph, labels=("walk", "turn", "idle", "start", "stop") + (("carry", "pick_up", "put_down") if carry else ()),
        states=("walking", "carrying") if carry else ("walking",), include_transitions=carry,
        max_per_pair=int(lib_cfg.get("max_per_pair", 10)))
    lib = synthetic_library(graph, meets=int(lib_cfg.get("meets", 0)), passes=int(lib_cfg.get("passes", 0)),
                            rows=int(lib_cfg.get("rows", 0)), singles=singles)
    pk = lib_cfg.get("patches", "")
    if pk:
        p = Path(pk)
        if not p.is_absolute():
            p = Path(cfg.get("_path", ".")).parent / p
        lib = lib.merged(PatchLibrary.load(p))
    return lib


def make_obstacles(cfg: dict, fps: float, frames: int) -> list:
    out = []
    for k, o in enumerate(cfg.get("obstacle", [])):
        try:
            half = tuple(float(h) for h in o["half"])
            height = float(o.get("height", 2.0))
            heading = math.radians(float(o.get("heading", 0.0)))
            if "path" in o:
                path = np.asarray(o["path"], np.float64).reshape(-1, 2)
                period = float(o.get("period", 8.0))
                t = np.arange(frames + 1) / fps
                u = (t % period) / period
                u = np.where(u < 0.5, 2 * u, 2 - 2 * u)           # back and forth
                seg = np.linspace(0, 1, len(path))
                center = np.stack([np.interp(u, seg, path[:, 0]), np.interp(u, seg, path[:, 1])], 1)
                hd = heading + math.radians(float(o.get("spin", 0.0))) * t
                out.append(Obstacle(center, half, hd, height, o.get("name", f"obstacle{k}")))
            else:
                out.append(Obstacle(np.asarray(o["center"], np.float64), half, heading, height, o.get("name", f"obstacle{k}")))
        except (KeyError, TypeError, ValueError) as e:
            raise TilingConfigError(cfg.get("_path", "<config>"), f"[[obstacle]] #{k}: {type(e).__name__}: {e}") from None
    return out


def _tiler_config(cfg):
    tc = dict(cfg.get("tiler", {}))
    pref = Preference(size_power=float(tc.pop("size_power", 1.0)), label_cost=dict(tc.pop("label_cost", {})))
    for k in ("max_seconds1", "max_seconds2"):
        tc.pop(k, None)
    fields = TilerConfig.__dataclass_fields__
    bad = [k for k in tc if k not in fields]
    if bad:
        raise TilingConfigError(cfg.get("_path", "<config>"), f"[tiler] unknown keys {bad}")
    for k in ("jitter_min", "jitter_max"):
        if k in tc:
            tc[k] = tuple(tc[k])
    return TilerConfig(**tc), pref


def run_static(cfg: dict, graph=None, library=None, prepared=None):
    """Keyframes, Algorithm 1, Algorithm 2. Returns (TilingResult, Tiler)."""
    lib = library or build_library(cfg, graph)
    prep = prepared or PreparedLibrary(lib)
    r = cfg["region"]
    ox, oz = r.get("origin", [0.0, 0.0])
    w, h = r.get("size", [12.0, 12.0])
    secs = float(r.get("seconds", 20.0))
    region = Region(ox, oz, ox + w, oz + h, 0.0, secs, bool(r.get("wrap_space", False)))
    tcfg, pref = _tiler_config(cfg)
    obst = make_obstacles(cfg, tcfg.fps, int(round(secs * tcfg.fps)))
    portals = [Portal(float(p["x"]), float(p["z"]), float(p["radius"]), p.get("kind", "both")) for p in cfg.get("portal", [])]
    til = Tiler(prep, region, obst, portals, tcfg, seed=int(cfg.get("seed", 0)), preference=pref)
    for k in cfg.get("keyframe", []):
        til.add_keyframe(k["patch"], float(k["x"]), float(k["z"]), math.radians(float(k.get("heading", 0.0))), float(k["t"]))
    t = cfg.get("tiler", {})
    s1 = til.phase1(t.get("max_seconds1"))
    s2 = til.phase2(t.get("max_seconds2"))
    res = til.result(phase1=s1, phase2=s2, stats=dict(til.stats), name=cfg.get("name", ""))
    return res, til


def run_interactive(cfg: dict, graph=None, library=None, prepared=None, tick_times: list | None = None):
    """Teams with scheduled targets, stepped on the clock. Returns (TilingResult, InteractiveTiling)."""
    lib = library or build_library(cfg, graph)
    prep = prepared or PreparedLibrary(lib)
    ic = cfg["interactive"]
    secs = float(ic.get("seconds", 20.0))
    it = InteractiveTiling(prep, horizon=float(ic.get("horizon", 1.5)), seed=int(cfg.get("seed", 0)),
                           interaction_labels=tuple(ic.get("interaction_labels", ())),
                           partner_radius=float(ic.get("partner_radius", 1.2)),
                           partner_time=float(ic.get("partner_time", 0.6)),
                           partner_dir=float(ic.get("partner_dir", 35.0)),
                           obstacles=make_obstacles(cfg, 30.0, int(round(secs * 30))))
    schedule = []
    for ti, team in enumerate(ic.get("team", [])):
        n = int(team["count"])
        sp = float(team.get("spacing", 1.5))
        side = int(math.ceil(math.sqrt(n)))
        hd = math.radians(float(team.get("heading", 0.0)))
        sx, sz = team["start"]
        for k in range(n):
            r, c = divmod(k, side)
            it.add_character((sx + sp * (c - 0.5 * (side - 1)), sz + sp * (r - 0.5 * (math.ceil(n / side) - 1))), hd, ti)
        for tt, x, z in team.get("targets", []):
            schedule.append((float(tt), ti, (float(x), float(z))))
    schedule.sort()
    nf = int(round(secs * it.fps))
    si = 0
    for f in range(1, nf + 1):
        while si < len(schedule) and schedule[si][0] * it.fps <= f:
            it.set_target(schedule[si][1], schedule[si][2])
            si += 1
        t0 = _time.perf_counter()
        it.step(f / it.fps)
        if tick_times is not None:
            tick_times.append(_time.perf_counter() - t0)
    return it.result(), it


def run_config(cfg: dict, graph=None, library=None):
    if cfg.get("mode", "static") == "interactive":
        return run_interactive(cfg, graph, library)[0]
    return run_static(cfg, graph, library)[0]
