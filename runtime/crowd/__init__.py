"""Goal-directed crowds (paper 000): environment, roadmap, seed planning, search and splicing."""
