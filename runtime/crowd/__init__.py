"""Goal-directed crowds (Sung, Kovar and Gleicher 2005): environment, roadmap, seed planning, search and splicing."""
