"""Sweep files: a base scenario (or a generator with parameters) and the axes to vary.

```toml
[sweep]
name = "grid-density"            # optional; default: the file's name without .toml
scenario = "../samples/meet20"   # a sample directory or a scenario .toml (relative to this file)
# generator = "grid"             # ... or a generated scenario (authoring.batch.generators)

[generator]                      # the generator's parameters, the same for every variant
characters = 6
distance = 8.0

[axes]                           # every combination of the values is one variant
seed = [0, 1, 2, 3]              # the scenario's (and the generator's) seed
characters = [4, 8]              # generator: how many; base scenario: its first N characters
spacing = [2.0, 3.0]             # generator only: metres between neighbours
eps = [1.0, 0.5]                 # a factor of the paper's eps, or [m/s, deg/s, s/s]
world = ["", "hall.usda"]        # a world stage (relative to this file); "" is open ground
duration = [12.0, 20.0]          # seconds to bake
```

Any other parameter of the generator may be an axis too. Every error names the file and the
key (:class:`SweepError`, one line).
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .generators import GENERATORS

__all__ = ["SweepError", "Sweep", "load_sweep", "parse_sweep", "SCENARIO_AXES", "DEFAULT_EPS"]

DEFAULT_EPS = (0.02, 2.0, 1.0 / 15.0)     # the paper's per-frame adjustment tolerance (runtime.crowd.scenario)
SCENARIO_AXES = ("seed", "characters", "spacing", "eps", "world", "duration")
_TOP = {"sweep", "generator", "axes"}
_SWEEP = {"name", "scenario", "generator"}


class SweepError(ValueError):
    """A sweep file that cannot be run; the message names the file and the key."""


@dataclass
class Sweep:
    """A parsed sweep file (see the module docstring)."""
    path: Path
    name: str
    scenario: Path | None = None           # the base scenario file, or None with a generator
    generator: str | None = None
    generator_params: dict = field(default_factory=dict)
    axes: dict = field(default_factory=dict)   # key -> list of values, in the file's order

    @property
    def base_dir(self) -> Path:
        return self.path.parent


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_eps(v) -> str | None:
    if _is_number(v):
        return None if v > 0 else "a factor must be positive"
    if isinstance(v, list) and len(v) == 3 and all(_is_number(x) and x > 0 for x in v):
        return None
    return "each value is a positive factor of the paper's eps or [m/s, deg/s, s/s] (three positive numbers)"


def _check_generator_value(gen, key, v) -> str | None:
    kind, _ = gen.params[key]
    if kind is int and not (isinstance(v, int) and not isinstance(v, bool)):
        return f"must be a whole number, got {v!r}"
    if kind is float and not _is_number(v):
        return f"must be a number, got {v!r}"
    if key == "seed":
        return None
    if key == "jitter":
        return None if v >= 0 else f"must be at least 0, got {v!r}"
    return None if v > 0 else f"must be positive, got {v!r}"


def _check_axis_value(sweep: Sweep, key: str, v) -> str | None:
    gen = GENERATORS.get(sweep.generator) if sweep.generator else None
    if key == "eps":
        return _check_eps(v)
    if key == "world":
        if not isinstance(v, str):
            return f"each value is a path to a world stage or \"\" for open ground, got {v!r}"
        if v and not (sweep.base_dir / v).is_file():
            return f"{v!r}: no such file ({sweep.base_dir / v})"
        return None
    if key == "duration":
        return None if _is_number(v) and v > 0 else f"must be a positive number of seconds, got {v!r}"
    if gen is not None:
        return _check_generator_value(gen, key, v)
    if key == "seed":
        return None if isinstance(v, int) and not isinstance(v, bool) else f"must be a whole number, got {v!r}"
    if key == "characters":
        return None if isinstance(v, int) and not isinstance(v, bool) and v >= 1 \
            else f"must be a whole number >= 1, got {v!r}"
    return None


def parse_sweep(data: dict, path) -> Sweep:
    """Validate a sweep read from ``path`` (relative paths in it are relative to its folder)."""
    path = Path(path)
    where = str(path)
    bad = set(data) - _TOP
    if bad:
        raise SweepError(f"{where}: unknown tables {sorted(bad)} (known: [sweep], [generator], [axes])")
    head = data.get("sweep")
    if not isinstance(head, dict):
        raise SweepError(f"{where}: [sweep]: missing (it names the base scenario or the generator)")
    bad = set(head) - _SWEEP
    if bad:
        raise SweepError(f"{where}: [sweep]: unknown keys {sorted(bad)} (known: {sorted(_SWEEP)})")
    name = head.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise SweepError(f"{where}: [sweep] name: must be a non-empty string")
    sweep = Sweep(path, name)
    if ("scenario" in head) == ("generator" in head):
        raise SweepError(f"{where}: [sweep]: give exactly one of scenario = \"PATH\" and generator = \"NAME\"")
    params = data.get("generator", {})
    if not isinstance(params, dict):
        raise SweepError(f"{where}: [generator]: must be a table of the generator's parameters")
    if "scenario" in head:
        sc = head["scenario"]
        if not isinstance(sc, str):
            raise SweepError(f"{where}: [sweep] scenario: must be a path, got {sc!r}")
        p = sweep.base_dir / sc
        p = p / "scenario.toml" if p.is_dir() else p
        if not p.is_file():
            raise SweepError(f"{where}: [sweep] scenario: {sc!r}: no scenario file ({p})")
        if params:
            raise SweepError(f"{where}: [generator]: only with generator = \"NAME\" in [sweep]")
        sweep.scenario = p
    else:
        gname = head["generator"]
        gen = GENERATORS.get(gname) if isinstance(gname, str) else None
        if gen is None:
            raise SweepError(f"{where}: [sweep] generator: unknown generator {gname!r} (known: {', '.join(GENERATORS)})")
        sweep.generator = gname
        for k, v in params.items():
            if k not in gen.params:
                raise SweepError(f"{where}: [generator] {k}: not a parameter of {gname!r} "
                                 f"(known: {', '.join(gen.params)})")
            err = _check_generator_value(gen, k, v)
            if err:
                raise SweepError(f"{where}: [generator] {k}: {err}")
        sweep.generator_params = dict(params)
    axes = data.get("axes", {})
    if not isinstance(axes, dict):
        raise SweepError(f"{where}: [axes]: must be a table of key = [values]")
    gen = GENERATORS.get(sweep.generator) if sweep.generator else None
    known = list(SCENARIO_AXES) + ([k for k in gen.params if k not in SCENARIO_AXES] if gen else [])
    for k, values in axes.items():
        if k not in known or (gen is None and k == "spacing"):
            why = " (spacing needs a generator: a base scenario's positions are fixed)" if k == "spacing" else ""
            raise SweepError(f"{where}: [axes] {k}: not an axis{why} (known: {', '.join(x for x in known if gen or x != 'spacing')})")
        if gen is not None and k in sweep.generator_params:
            raise SweepError(f"{where}: [axes] {k}: also set in [generator]; give it in one place")
        if not isinstance(values, list) or not values:
            raise SweepError(f"{where}: [axes] {k}: must be a non-empty array of values")
        for v in values:
            err = _check_axis_value(sweep, k, v)
            if err:
                raise SweepError(f"{where}: [axes] {k}: {err}")
        if len({repr(v) for v in values}) != len(values):
            raise SweepError(f"{where}: [axes] {k}: a value is repeated")
        sweep.axes[k] = list(values)
    return sweep


def load_sweep(path) -> Sweep:
    """Read and validate a sweep file; :class:`SweepError` naming the file and the key."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SweepError(f"{path}: sweep file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise SweepError(f"{path}: cannot read the sweep file: {e}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SweepError(f"{path}: not valid TOML: {e}") from None
    return parse_sweep(data, path)
