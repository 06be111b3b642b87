"""Experiment 6 (Sung, Kovar and Gleicher 2005, Figure 10): a grid walks to a translated grid."""
from __future__ import annotations

import numpy as np

from .geometry import position
from .scenario_file import readme_text, write_sample

__all__ = ["grid_scenario", "build_grid"]

def grid_scenario(cols: int, rows: int, spacing: float = 2.2, shift: float | None = None, seed: int = 0,
                  name: str | None = None, start_still: bool | None = None) -> dict:
    """``cols x rows`` characters on a uniform grid (``spacing`` m) facing +X walk to a copy of
    the grid translated by ``shift`` m along +X (default half the grid's width plus 10 m).
    Targets are perturbed as in the paper's Figure 10 while every path keeps about the same
    length: in each column, random pairs of neighbouring rows swap their targets (each pair
    with probability 1/2), so about two characters in three cross a neighbour's lane on the
    way. No time constraints; characters are planned front column first. ``start_still``: the
    scenario's ``[synthesis] start_still`` (None: not set)."""
    rng = np.random.default_rng(seed)
    if shift is None:
        shift = 0.5 * cols * spacing + 10.0
    i, j = np.meshgrid(np.arange(cols), np.arange(rows), indexing="ij")
    cells = np.stack([i.ravel(), j.ravel()], axis=1).astype(float)
    start = cells * spacing
    start[:, 1] -= (rows - 1) * spacing / 2
    start[:, 0] -= (cols - 1) * spacing
    assign = np.arange(cols * rows).reshape(cols, rows)
    for col in assign:
        r = 0
        while r < rows - 1:
            if rng.random() < 0.5:
                col[[r, r + 1]] = col[[r + 1, r]]
                r += 2
            else:
                r += 1
    assign = assign.ravel()
    target = start[assign] + [shift, 0.0]
    order = np.lexsort((start[:, 1], -start[:, 0]))       # front column first
    chars = []
    for k, c in enumerate(order):
        chars.append({"name": f"c{k + 1:03d}",
                      "start": {"position": position(start[c]), "heading": 90.0, "pose": "stand"},
                      "goal": [{"position": position(target[c])}]})
    n = cols * rows
    return {"name": name or f"grid{n}", "description": f"Experiment 6 (Sung, Kovar and Gleicher 2005, Figure 10): {cols} x {rows} "
            f"grid, {spacing:g} m spacing, to the grid translated {shift:g} m along +X with perturbed targets",
            "library": "default", "duration": 60.0, "seed": seed,
            **({"synthesis": {"start_still": bool(start_still)}} if start_still is not None else {}),
            "character": chars}


def build_grid(n):
    """The builder of the ``grid{n}`` sample (n = 300: 20 x 15, n = 500: 25 x 20, 3 m apart)."""
    def build(folder):
        cols, rows = {300: (20, 15), 500: (25, 20)}[n]
        sc = grid_scenario(cols, rows, spacing=3.0, seed=0, start_still=(n == 500))
        write_sample(folder, sc, readme_text(f"grid{n}"))
    return build
