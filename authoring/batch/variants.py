"""The variants of a sweep: every combination of its axes' values, each a scenario.

A variant's scenario is the base scenario (or the generator's) with the axes applied; it is
written as ``<variant>/scenario.toml`` in the batch's output directory, with the paths it holds
(world, library pack, flock and patch packs) made relative to that directory, so
``crowdweave bake OUT/<variant>/scenario.toml`` bakes the same variant.
"""
from __future__ import annotations

import itertools
import os
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from .generators import GENERATORS
from .sweep import DEFAULT_EPS, Sweep, SweepError
from .toml_text import dumps

__all__ = ["Variant", "make_variants", "scenario_text"]


@dataclass
class Variant:
    """One combination of axis values and its scenario (paths absolute until written)."""
    index: int
    id: str                   # the name of its output directory
    params: dict              # axis -> value
    scenario: dict

    @property
    def characters(self) -> int:
        return len(self.scenario.get("character", []))

    @property
    def cost(self) -> float:
        """A rough relative cost (characters x seconds) to start long variants first."""
        return max(1, self.characters) * float(self.scenario.get("duration", 20.0))


def _label(key: str, v) -> str:
    if key == "world":
        text = Path(v).stem if v else "open"
    elif isinstance(v, list):
        text = "_".join(f"{x:g}" for x in v)
    elif isinstance(v, float):
        text = f"{v:g}"
    else:
        text = str(v)
    return re.sub(r"[^A-Za-z0-9._]+", "_", f"{key}{text}")


def _map_paths(data: dict, fn) -> dict:
    """Apply ``fn`` to every file reference of a scenario dict (world, library pack, flock DDG
    packs, patch packs); names such as ``"default"`` and ``"synthetic"`` are not files."""
    if data.get("world"):
        data["world"] = fn(data["world"])
    if data.get("library", "default") != "default":
        data["library"] = fn(data["library"])
    for fl in data.get("flock", []):
        if isinstance(fl.get("ddg"), str):
            fl["ddg"] = fn(fl["ddg"])
    for tl in data.get("tiling", []):
        if tl.get("patches", "synthetic") != "synthetic":
            tl["patches"] = fn(tl["patches"])
    return data


def _absolute_paths(data: dict, base: Path) -> dict:
    """The scenario's file references made absolute (they were relative to ``base``)."""
    root = os.path.abspath(base)
    return _map_paths(data, lambda p: p if os.path.isabs(p) else os.path.normpath(os.path.join(root, p)))


def _relative_paths(data: dict, folder: Path) -> dict:
    root = os.path.abspath(folder)
    return _map_paths(data, lambda p: os.path.relpath(p, root).replace(os.sep, "/"))


def _base_scenario(sweep: Sweep) -> dict:
    try:
        data = tomllib.loads(sweep.scenario.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise SweepError(f"{sweep.path}: [sweep] scenario: cannot read {sweep.scenario}: {e}") from None
    return _absolute_paths(data, sweep.scenario.parent)


def _keep_characters(data: dict, n: int, sweep: Sweep) -> None:
    chars = data.get("character", [])
    if n > len(chars):
        raise SweepError(f"{sweep.path}: [axes] characters: {n} is more than the {len(chars)} characters "
                         f"of {sweep.scenario}")
    kept = chars[:n]
    names = {c.get("name") for c in kept}
    for c in kept:
        for g in c.get("goal", []):
            other = g.get("after", {}).get("character")
            if other is not None and other not in names:
                raise SweepError(f"{sweep.path}: [axes] characters: {n} keeps {c.get('name')!r}, whose goal "
                                 f"waits for {other!r}, who is left out")
    data["character"] = kept


def _apply(data: dict, key: str, v, sweep: Sweep) -> None:
    if key == "seed":
        data["seed"] = int(v)
    elif key == "duration":
        data["duration"] = float(v)
    elif key == "eps":
        eps = [float(x) for x in v] if isinstance(v, list) else [float(v) * e for e in DEFAULT_EPS]
        data.setdefault("synthesis", {})["epsilon"] = eps
    elif key == "world":
        data.pop("world", None)
        if v:
            data["world"] = os.path.normpath(os.path.abspath(sweep.base_dir / v))
    elif key == "characters":
        _keep_characters(data, int(v), sweep)


def make_variants(sweep: Sweep) -> list[Variant]:
    """Every combination of the sweep's axis values (the first axis varies slowest)."""
    keys = list(sweep.axes)
    combos = list(itertools.product(*(sweep.axes[k] for k in keys))) if keys else [()]
    gen = GENERATORS.get(sweep.generator) if sweep.generator else None
    base = _base_scenario(sweep) if gen is None else None
    out = []
    for i, values in enumerate(combos):
        params = dict(zip(keys, values))
        vid = "-".join([f"{i:03d}"] + [_label(k, v) for k, v in params.items()])
        if gen is not None:
            kw = dict(sweep.generator_params)
            kw.update({k: v for k, v in params.items() if k in gen.params})
            data = gen(**kw)
            rest = {k: v for k, v in params.items() if k not in gen.params}
        else:
            data = tomllib.loads(dumps(base))          # a deep copy
            rest = params
        for k, v in rest.items():
            _apply(data, k, v, sweep)
        data["name"] = f"{sweep.name}-{vid}"
        out.append(Variant(i, vid, params, data))
    return out


def scenario_text(variant: Variant, folder) -> str:
    """The variant's ``scenario.toml`` text for a scenario file in ``folder``."""
    data = tomllib.loads(dumps(variant.scenario))
    return dumps(_relative_paths(data, Path(folder)))
