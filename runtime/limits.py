"""Hard limits on input sizes, in one place: what crowdweave accepts before it starts work.

Each limit keeps one run within the memory of a workstation (a bake holds about 4.5 KB per
character and frame while it writes: grid300, 540,000 character-frames, peaks at 2.8 GB) or
keeps a read from trusting a file's reported size. Inputs over a limit are rejected before any
work with a message naming the limit; the README's "Limits and errors" section lists them for
users.
"""
from __future__ import annotations

__all__ = ["MAX_DURATION", "MAX_CHARACTERS", "MAX_CHARACTER_SECONDS", "MAX_GOALS", "MAX_FLOCKS",
           "MAX_FLOCK_AGENTS", "MAX_FLOCK_SECONDS", "MAX_FLOCK_AGENT_SECONDS", "MAX_TEAM",
           "MAX_CAPTURE_MINUTES", "MAX_TAKE_MINUTES", "MAX_TOML_BYTES", "MAX_BVH_BYTES", "MAX_SEED",
           "MAX_REPEAT", "MAX_ROADMAP_NODES"]

# scenarios and bakes
MAX_DURATION = 3600.0             # s: one hour of scenario (108,000 frames at 30 Hz)
MAX_CHARACTERS = 5000             # crowd and tiled characters of one scenario
MAX_CHARACTER_SECONDS = 60_000.0   # characters x duration (grid500 is 30,000): about 8 GB while baking
MAX_GOALS = 1000                  # goals of one character
MAX_FLOCKS = 1000                 # flocks of one [[flock]] entry
MAX_TEAM = 64                     # characters of one tiling team

# flock recordings (crowdweave author flock, scenario recipes)
MAX_FLOCK_AGENTS = 500            # boids per flock: the simulation holds agents^2 pair arrays per step
MAX_FLOCK_SECONDS = 3600.0        # s recorded
MAX_FLOCK_AGENT_SECONDS = 200_000.0  # agents x seconds recorded (positions and velocities kept)

# procedural capture
MAX_CAPTURE_MINUTES = 600.0       # a session (written take by take)
MAX_TAKE_MINUTES = 30.0           # one take (held in memory while it is generated)
MAX_REPEAT = 100                  # multi-person takes per kind

# files read whole (the limit holds whatever the file system reports)
MAX_TOML_BYTES = 16 << 20         # scenario files
MAX_BVH_BYTES = 512 << 20         # BVH files (the CMU files are 1-3 MB)

MAX_SEED = 2 ** 63 - 1            # seeds are 0 .. MAX_SEED
MAX_ROADMAP_NODES = 2_000_000     # roadmap samples (about 30 M candidate edges)
