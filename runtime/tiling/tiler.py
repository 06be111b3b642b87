"""Tiling motion patches in a space-time region (Kim, Hwang, Hyun and Lee 2012, section 5).

:class:`Tiler` is the static tiler: keyframes, then Algorithm 1 (stochastic sampling,
:mod:`.sampling`), then Algorithm 2 (deterministic search with jitter, :mod:`.search`), on a
:class:`~runtime.tiling.state.TilingState` (instances, stitches, dangling ports, the energy
Eq. 6; its collision queries in :mod:`.occupancy`).

Control (section 5.3): :class:`~runtime.tiling.preference.Preference` (Eq. 7: target location,
orientation, time, labels), keyframes (:meth:`Tiler.add_keyframe`: fixed instances, never
removed), repeating tiles (``Region(wrap_space=True)``: the index and the port matching use the
minimum image), static and moving :class:`~runtime.tiling.region.Obstacle` s, and
:class:`~runtime.tiling.region.Portal` sources/sinks.

Everything random draws from one ``numpy.random.Generator(seed)``; the same library, settings
and seed give the same tiling (unless a wall-clock budget cuts a phase short).

The scene and settings types are importable from here too (``from runtime.tiling.tiler import
Region, Tiler, TilerConfig``).
"""
from __future__ import annotations

import numpy as np

from .config import TilerConfig
from .preference import Preference
from .prepared import PreparedLibrary
from .region import Obstacle, Portal, Region
from .result import TilingResult
from .sampling import sample_tiling
from .search import close_danglings
from .state import TilingState, tiling_energy

__all__ = ["Region", "Obstacle", "Portal", "Preference", "TilerConfig", "PreparedLibrary", "TilingState",
           "Tiler", "TilingResult", "tiling_energy"]


class Tiler(TilingState):
    """Static tiling: keyframes, then :meth:`phase1` (Algorithm 1), then :meth:`phase2`
    (Algorithm 2). :meth:`run` does all and returns a :class:`TilingResult`.

    Args: as :class:`~runtime.tiling.state.TilingState`; ``library`` may be a
    :class:`~runtime.tiling.patch.PatchLibrary` or an already prepared one.
    """

    def __init__(self, library, region: Region, obstacles=(), portals=(), config: TilerConfig | None = None,
                 seed: int = 0, preference: Preference | None = None):
        prepared = library if isinstance(library, PreparedLibrary) else PreparedLibrary(library)
        super().__init__(prepared, region, obstacles, portals, config, seed, preference)
        # Algorithm 1 draws patches by size and label weight (Eq. 7 with the size bias), and
        # anchored ones by label weight alone
        self.weights = np.array([pp.size ** self.pref.size_power * self.pref.label_factor(pp.patch.labels)
                                 for pp in prepared.patches])
        self.anchor_weights = np.array([self.pref.label_factor(pp.patch.labels) for pp in prepared.patches])
        self.timing = {"phase1": 0.0, "phase2": 0.0}
        self.free_placements = 0
        self._name_index = {p.name: i for i, p in enumerate(prepared.library.patches)}

    def add_keyframe(self, patch, x: float, z: float, heading: float, t: float, check: bool = True) -> int:
        """Place a patch instance the user chose (fixed; never deformed or removed). ``patch`` is
        a library index or name; ``(x, z, heading)`` place the patch frame's origin; ``t`` is the
        time of the patch's t=0."""
        p = self._name_index[patch] if isinstance(patch, str) else int(patch)
        cand = self.evaluate(p, (x, z, heading, t), match_others=True)
        if check and self.occupancy.collides(cand):
            raise ValueError(f"keyframe {self.lib.patches[p].patch.name!r} at ({x}, {z}, t={t}) collides with the tiling")
        return self.commit(cand, fixed=True)

    def phase1(self, max_seconds: float | None = None, max_patches: int | None = None) -> dict:
        """Algorithm 1 (:func:`~runtime.tiling.sampling.sample_tiling`)."""
        return sample_tiling(self, max_seconds, max_patches)

    def phase2(self, max_seconds: float | None = None, max_passes: int = 50, max_steps: int = 200000) -> dict:
        """Algorithm 2 (:func:`~runtime.tiling.search.close_danglings`)."""
        return close_danglings(self, max_seconds, max_passes, max_steps)

    def run(self, max_seconds1: float | None = None, max_seconds2: float | None = None) -> TilingResult:
        s1 = self.phase1(max_seconds1)
        s2 = self.phase2(max_seconds2)
        return self.result(phase1=s1, phase2=s2, stats=dict(self.stats))
