"""Writing a sample folder: ``scenario.toml`` (the scenario format of
:mod:`runtime.crowd.scenario`, written by :mod:`authoring.scenario_file`), ``README.md`` and
``world.usda`` (:class:`usd_io.world_writer.WorldBuilder`).

README texts are ``samples/templates/<name>.md`` followed by ``samples/templates/bake.md``
(a :class:`string.Template` with ``${name}`` and ``${world}``).
"""
from __future__ import annotations

from pathlib import Path
from string import Template

from authoring.scenario_file import scenario_toml
from runtime.assets import atomic_write_bytes
from usd_io.world_writer import WorldBuilder

__all__ = ["TEMPLATES", "scenario_toml", "readme_text", "write_sample"]

TEMPLATES = Path(__file__).resolve().parent.parent / "templates"


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
