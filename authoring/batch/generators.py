"""Scenario generators a sweep file can name instead of a base scenario.

A generator turns a few numbers into a scenario dict (the keys of ``scenario.toml``, see
:mod:`runtime.crowd.scenario`); everything random is drawn from ``numpy.random.default_rng(seed)``.
Characters start standing, facing their walk, on open ground (a sweep's ``world`` axis may add a
world stage; a start inside an obstacle then fails that variant with the scenario's error).

``grid``
    ``characters`` on a grid of rows ``spacing`` m apart, as square as the count allows, facing
    +X; each walks ``distance`` m along +X to its own cell of the grid moved there, the goal
    moved by up to ``jitter`` m in x and z. No time constraints.
``crossing``
    two groups face each other ``distance`` m apart and swap sides: ``characters`` split between
    a column at x = 0 facing +X and one at x = ``distance`` facing -X, each ``spacing`` m between
    neighbours, the second column offset by half a spacing, so every walker passes between two
    oncoming ones. Goals moved by up to ``jitter`` m. No time constraints.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Generator", "GENERATORS", "grid", "crossing"]


def _round(v) -> float:
    """Coordinates in the scenario text: millimetres (the text stays readable, and the same
    numbers come back when it is read)."""
    return round(float(v), 3) + 0.0


def _character(k: int, start, heading_deg: float, goal) -> dict:
    return {"name": f"c{k + 1:03d}",
            "start": {"position": [_round(start[0]), _round(start[1])], "heading": heading_deg, "pose": "stand"},
            "goal": [{"position": [_round(goal[0]), _round(goal[1])]}]}


def _scenario(name: str, description: str, duration: float, seed: int, chars: list) -> dict:
    return {"name": name, "description": description, "library": "default", "duration": float(duration),
            "seed": int(seed), "character": chars}


def grid(characters: int = 12, spacing: float = 2.5, distance: float = 8.0, jitter: float = 0.5,
         duration: float = 20.0, seed: int = 0) -> dict:
    """A grid walking ``distance`` m along +X (see the module docstring)."""
    rng = np.random.default_rng(seed)
    rows = max(1, int(math.ceil(math.sqrt(characters))))
    k = np.arange(characters)
    col, row = k // rows, k % rows
    start = np.stack([-col * spacing, (row - (rows - 1) / 2.0) * spacing], axis=1)
    goal = start + [distance, 0.0] + rng.uniform(-jitter, jitter, (characters, 2))
    chars = [_character(i, start[i], 90.0, goal[i]) for i in range(characters)]
    return _scenario(f"grid{characters}", f"{characters} characters on a {spacing:g} m grid walk {distance:g} m "
                     "along +X", duration, seed, chars)


def crossing(characters: int = 12, spacing: float = 2.0, distance: float = 10.0, jitter: float = 0.3,
             duration: float = 20.0, seed: int = 0) -> dict:
    """Two columns swapping sides (see the module docstring)."""
    rng = np.random.default_rng(seed)
    left = (characters + 1) // 2
    k = np.arange(characters)
    side = (k >= left).astype(float)                      # 0: starts at x = 0, 1: at x = distance
    slot = np.where(side == 0, k, k - left).astype(float)
    z = (slot + 0.5 * side) * spacing
    z -= z.mean() if characters else 0.0
    start = np.stack([side * distance, z], axis=1)
    goal = np.stack([(1.0 - side) * distance, z], axis=1) + rng.uniform(-jitter, jitter, (characters, 2))
    chars = [_character(i, start[i], 90.0 if side[i] == 0 else -90.0, goal[i]) for i in range(characters)]
    return _scenario(f"crossing{characters}", f"two columns of {characters} characters, {spacing:g} m apart, swap "
                     f"sides {distance:g} m away", duration, seed, chars)


@dataclass(frozen=True)
class Generator:
    """A named generator and its parameters with their types and defaults."""
    name: str
    make: object
    params: dict          # name -> (type, default)

    def __call__(self, **kw) -> dict:
        return self.make(**kw)


def _params(fn) -> dict:
    import inspect
    return {n: (type(p.default), p.default) for n, p in inspect.signature(fn).parameters.items()}


GENERATORS = {f.__name__: Generator(f.__name__, f, _params(f)) for f in (grid, crossing)}
