"""Motion patch tiling (paper 003).

- :mod:`.patch`: patches, fragments, constraints, ports, the ``motion_patches`` pack, single-
  character patches cut from a motion graph (the data contract with the authoring side);
- :mod:`.deform`: Laplacian path deformation with limits (section 3), factored once per patch;
- :mod:`.boxindex`: space-time index of per-frame oriented boxes;
- :mod:`.tiler`: Algorithm 1 and 2 with control (section 5) -> :class:`.result.TilingResult`;
- :mod:`.result`: tiled instances, character identity chains, tracks for baking/drawing, pack;
- :mod:`.check`: the independent checker (danglings, interpenetration, limits, 3 x 3 seams);
- :mod:`.interactive`: incremental tiling per tick (section 5.3);
- :mod:`.synthetic`: multi-character stand-in patches composed from graph edges;
- :mod:`.scenario`: TOML configs for samples and benchmarks.
"""
from .patch import Constraint, Fragment, Patch, PatchLibrary, Port, single_character_patches

__all__ = ["Constraint", "Fragment", "Patch", "PatchLibrary", "Port", "single_character_patches"]
