"""Per-character looks: clothing and skin colours, body width and an optional prop, drawn from
(seed, character name) alone, so the viewer and a bake give a character the same look whatever
else is in the scene and however it moves.

A look is independent of motion: the width factor scales the drawn or baked body's limbs across
their bones only (capsule radii in the viewer, a ``wide`` blend shape in a bake); joint
positions, root motion and the collision figures of the planners and checkers do not change.

Colours are indices into small palettes (:data:`SKIN`, :data:`SHIRTS`, :data:`TROUSERS`,
:data:`SHOES`, :data:`PROP_COLOURS`; sRGB, 0-1): skin tones span the ten tones of the Monk skin
tone scale, clothing is muted. A bake shares one material per palette entry between characters.

Each name is hashed once (BLAKE2b keyed by the seed); every draw after that is vectorized over
characters (a counter-based 64-bit mix of the name's hash and the draw's number). Same inputs,
same bytes.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

__all__ = ["Looks", "looks_for", "PARTS", "PROPS", "SKIN", "SHIRTS", "TROUSERS", "SHOES", "PROP_COLOURS",
           "WIDTH_RANGE", "HAT_SHARE", "BAG_SHARE", "srgb_to_linear"]

PARTS = ("skin", "shirt", "trousers", "shoes")
PROPS = ("none", "hat", "bag")
WIDTH_RANGE = (0.9, 1.12)        # body width factor (limb thickness), uniform in this range
HAT_SHARE = 0.2                  # share of characters with a hat
BAG_SHARE = 0.2                  # and with a bag in one hand


def _hex(*codes: str) -> np.ndarray:
    return np.array([[int(c[i:i + 2], 16) / 255.0 for i in (1, 3, 5)] for c in codes], dtype=np.float32)


# the Monk skin tone scale (Monk 2019), light to dark
SKIN = _hex("#f6ede4", "#f3e7db", "#f7ead0", "#eadaba", "#d7bd96", "#a07e56", "#825c43", "#604134", "#3a312a",
            "#292420")
SHIRTS = _hex("#3b4a6b", "#6b7b4a", "#7a3b3f", "#b08a3e", "#5d6d7e", "#2f6f6a", "#9a5b3c", "#8a8d91",
              "#d8d0bd", "#4a6c94", "#3f5a43", "#6d4a6e", "#a86f6f", "#c2b59b")
TROUSERS = _hex("#2e3138", "#2b3548", "#9c8a6a", "#5a4636", "#1f1f22", "#676b70", "#3f5577", "#56583f")
SHOES = _hex("#1c1a18", "#4a3325", "#d9d6cf", "#55504a")
PROP_COLOURS = _hex("#7b2d26", "#264653", "#c9a227", "#3d3d3d", "#8c5e3c", "#5b7553")

_PALETTES = (SKIN, SHIRTS, TROUSERS, SHOES)
_M64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser, elementwise on uint64."""
    with np.errstate(over="ignore"):
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return x ^ (x >> np.uint64(31))


def _name_keys(names, seed: int) -> np.ndarray:
    key = int(seed).to_bytes(8, "little", signed=True)
    return np.array([int.from_bytes(hashlib.blake2b(str(n).encode("utf-8"), digest_size=8, key=key).digest(),
                                    "little") for n in names], dtype=np.uint64)


def _uniform(keys: np.ndarray, draw: int) -> np.ndarray:
    """A uniform number in [0, 1) per key for draw number ``draw`` (float64, 53 bits)."""
    with np.errstate(over="ignore"):
        h = _mix(keys + np.uint64(draw + 1) * np.uint64(0x9E3779B97F4A7C15))
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB colours (0-1) to linear ones (for renderers that shade in linear space, e.g. USD)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


@dataclass(frozen=True)
class Looks:
    """The looks of characters ``names`` (row ``i`` is ``names[i]``).

    Attributes:
        part: (N, 4) int palette index per part of :data:`PARTS` (skin, shirt, trousers, shoes).
        width: (N,) float32 body width factor in :data:`WIDTH_RANGE`.
        prop: (N,) int8 index into :data:`PROPS` (0 none, 1 hat, 2 bag).
        prop_colour: (N,) int index into :data:`PROP_COLOURS`.
    """
    names: tuple
    seed: int
    part: np.ndarray
    width: np.ndarray
    prop: np.ndarray
    prop_colour: np.ndarray

    def __len__(self) -> int:
        return len(self.names)

    def colours(self) -> np.ndarray:
        """(N, 4, 3) float32 sRGB colours of the parts of :data:`PARTS`."""
        out = np.empty((len(self), len(PARTS), 3), dtype=np.float32)
        for k, pal in enumerate(_PALETTES):
            out[:, k] = pal[self.part[:, k]]
        return out

    def prop_colours(self) -> np.ndarray:
        """(N, 3) float32 sRGB colour of each character's prop (also given to those without one)."""
        return PROP_COLOURS[self.prop_colour]

    def look(self, i: int) -> dict:
        """Character ``i``'s look as plain values (for reports and tests)."""
        c = self.colours()[i]
        return {"name": self.names[i], **{p: [float(v) for v in c[k]] for k, p in enumerate(PARTS)},
                "width": float(self.width[i]), "prop": PROPS[int(self.prop[i])]}


def looks_for(names, seed: int = 0) -> Looks:
    """Looks of the characters ``names`` (strings), deterministic in (``seed``, name): a
    character's look does not depend on the other names or their order."""
    names = tuple(str(n) for n in names)
    keys = _name_keys(names, seed)
    part = np.empty((len(names), len(PARTS)), dtype=np.int64)
    for k, pal in enumerate(_PALETTES):
        part[:, k] = np.minimum((_uniform(keys, k) * len(pal)).astype(np.int64), len(pal) - 1)
    lo, hi = WIDTH_RANGE
    width = (lo + (hi - lo) * _uniform(keys, 4)).astype(np.float32)
    u = _uniform(keys, 5)
    prop = np.where(u < HAT_SHARE, 1, np.where(u < HAT_SHARE + BAG_SHARE, 2, 0)).astype(np.int8)
    pc = np.minimum((_uniform(keys, 6) * len(PROP_COLOURS)).astype(np.int64), len(PROP_COLOURS) - 1)
    return Looks(names, int(seed), part, width, prop, pc)
