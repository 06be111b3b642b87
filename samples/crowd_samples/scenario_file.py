"""Writing a sample folder: ``scenario.toml`` (the scenario format of
:mod:`runtime.crowd.scenario`; ``tomllib`` only reads), ``README.md`` and ``world.usda``.

README texts are ``samples/templates/<name>.md`` followed by ``samples/templates/bake.md``
(a :class:`string.Template` with ``${name}`` and ``${world}``).
"""
from __future__ import annotations

from pathlib import Path
from string import Template

import numpy as np

from runtime.assets import atomic_write_bytes

from .world_stage import WorldBuilder

__all__ = ["TEMPLATES", "toml_number", "toml_value", "scenario_toml", "readme_text", "write_sample"]

TEMPLATES = Path(__file__).resolve().parent.parent / "templates"


def toml_number(v) -> str:
    """A float as TOML text: rounded to 4 decimals, trailing zeros dropped, never ``-0.0``."""
    v = float(v)
    if v == 0:
        v = 0.0                     # no "-0.0"
    s = f"{round(v, 4):.4f}".rstrip("0")
    return s + "0" if s.endswith(".") else s


def toml_value(v) -> str:
    """A scenario value (bool, number, string, inline table, array) as TOML text."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return toml_number(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def scenario_toml(sc: dict) -> str:
    """TOML text of a scenario dict (keys as in ``runtime.crowd.scenario``)."""
    lines = []
    for k in ("name", "description", "world", "library", "duration", "seed"):
        if k in sc:
            lines.append(f"{k} = {toml_value(sc[k])}")
    if sc.get("synthesis"):
        lines += ["", "[synthesis]"] + [f"{k} = {toml_value(v)}" for k, v in sc["synthesis"].items()]
    for c in sc["character"]:
        lines += ["", "[[character]]", f"name = {toml_value(c['name'])}", f"start = {toml_value(c['start'])}"]
        for g in c.get("goal", []):
            lines.append("  [[character.goal]]")
            lines += [f"  {k} = {toml_value(v)}" for k, v in g.items()]
    return "\n".join(lines) + "\n"


def readme_text(name: str, world: bool = False) -> str:
    """The README of sample ``name``: its template and the regenerate-and-bake section
    (which also names ``world.usda`` when the sample has a world stage)."""
    head = (TEMPLATES / f"{name}.md").read_text(encoding="utf-8")
    bake = Template((TEMPLATES / "bake.md").read_text(encoding="utf-8"))
    return head + bake.substitute(name=name, world=" or `world.usda`" if world else "")


def write_sample(folder: Path, sc: dict, readme: str, world: WorldBuilder | None = None):
    """Write a sample folder (atomically per file): ``world.usda`` when ``world`` is
    given, ``scenario.toml`` from the scenario dict ``sc`` and ``README.md``."""
    folder.mkdir(parents=True, exist_ok=True)
    if world is not None:
        world.save(folder / "world.usda")
    atomic_write_bytes(folder / "scenario.toml", scenario_toml(sc).encode())
    atomic_write_bytes(folder / "README.md", readme.encode())
