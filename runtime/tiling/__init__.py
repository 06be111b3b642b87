"""Motion patch tiling (Kim, Hwang, Hyun and Lee 2012, "Tiling Motion Patches").

- :mod:`.patch`: patches, fragments, constraints, ports, the ``motion_patches`` pack, single-
  character patches cut from a motion graph (the data contract with the authoring side);
- :mod:`.deform`: Laplacian path deformation with limits (section 3), factored once per patch;
- :mod:`.prepared`: a library prepared for tiling (deformers, port and rest tables);
- :mod:`.region`: the space-time region, obstacles and portals;
- :mod:`.boxindex`: space-time index of per-frame oriented boxes;
- :mod:`.occupancy`: clock samples of instances and the collision queries of ``IsValid``;
- :mod:`.instances`: candidates, committed instances, the dangling-port table;
- :mod:`.state`: the tiling under construction (stitching, energy Eq. 6) -> :class:`.result.TilingResult`;
- :mod:`.preference`: the preference function Eq. 7; :mod:`.config`: the tiler's settings;
- :mod:`.sampling`, :mod:`.search`: Algorithm 1 and Algorithm 2 (section 5.1, 5.2);
- :mod:`.tiler`: the static tiler (keyframes, Algorithm 1, Algorithm 2);
- :mod:`.result`: tiled instances, character identity chains, tracks for baking/drawing, pack;
- :mod:`.check`: the independent checker (danglings, interpenetration, limits, 3 x 3 seams);
- :mod:`.interactive`: incremental tiling per tick (section 5.3), with its parts :mod:`.tick`,
  :mod:`.entries`, :mod:`.roster`, :mod:`.playback`, :mod:`.cornering`, :mod:`.extension`;
- :mod:`.zone`: an interactive tiling as a system of the runtime World;
- :mod:`.synthetic`: multi-character stand-in patches composed from graph edges;
- :mod:`.scenario`: TOML configs for samples and benchmarks.
"""
from .patch import Constraint, Fragment, Patch, PatchLibrary, Port, single_character_patches

__all__ = ["Constraint", "Fragment", "Patch", "PatchLibrary", "Port", "single_character_patches"]
