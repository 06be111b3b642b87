"""The crowd samples that reproduce the experiments of Sung, Kovar and Gleicher 2005 (section 4).

One module per experiment builds its scenario dict (and its world stage, where it has one):
:mod:`.meet` (Experiment 1), :mod:`.spell` (2), :mod:`.rooms` (3), :mod:`.theater` (4),
:mod:`.fetch` (5), :mod:`.grid` (6). :mod:`.scenario_file` writes a sample folder
(``scenario.toml`` text, ``README.md`` from ``samples/templates``, ``world.usda``),
:class:`usd_io.world_writer.WorldBuilder` builds the USD stages, :mod:`.geometry` holds small
layout functions.

Clearances the default library needs (bounding-cylinder radii, m): standing ~0.3, walking
up to 0.63 (stride), carrying ~0.49, sitting 0.62, sitting down / standing up up to 0.72.
"""

