"""Generator of the sample scenarios that reproduce the experiments of Sung, Kovar and Gleicher
2005 (section 4).

``python samples/make_samples.py [NAME ...]`` (re)writes, deterministically, each sample's
``world.usda`` (built with pxr), ``scenario.toml`` (built from code: grids, letter strokes,
theater rows) and ``README.md``:

=============  ===========================================================================
meet20         Experiment 1: 20 characters arrive in the same 0.5 s window in pairs,
               triangles and a square, partners facing each other
spell70        Experiment 2: 70 characters walk to points spelling "SCA", front row first,
               and face the camera (+Z)
rooms_box      Experiment 3: one character crosses six rooms with walls, doors and
               furniture, among 8 other characters (planned first), and picks up a box
theater40      Experiment 4: 40 characters walk from a lobby through two doors and take
               theater seats (back rows and inner seats first)
fetch_boxes20  Experiment 5: 20 seated characters each fetch a designated box from a
               second room, put it down at a designated spot and return to their seat
grid300/500    Experiment 6 (Figure 10): a uniform grid walks to a translated grid, each
               character to a randomly perturbed target cell
=============  ===========================================================================

Everything random is drawn from ``numpy.random.default_rng(seed)``; the files are written
atomically. The code is in ``samples/crowd_samples`` (one module per experiment) and the
README texts in ``samples/templates``; this script names them. The functions returning
scenario dicts (:func:`grid_scenario`, ...) are also used by ``bench/crowd_table.py`` for
the Figure 11 spacing sweep.
"""
from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for _p in (ROOT, HERE):             # run as a script from anywhere; import as a module
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

from crowd_samples import fetch, meet, rooms, spell, theater  # noqa: E402
from crowd_samples.fetch import FETCH_CARRY, fetch_boxes, fetch_scenario, fetch_world  # noqa: E402
from crowd_samples.geometry import min_spacing  # noqa: E402
from crowd_samples.grid import build_grid, grid_scenario  # noqa: E402
from crowd_samples.meet import MEET_GROUPS, meet_scenario  # noqa: E402
from crowd_samples.rooms import rooms_scenario, rooms_world  # noqa: E402
from crowd_samples.scenario_file import scenario_toml  # noqa: E402
from crowd_samples.spell import SPELL_STAGGER, letter_points, spell_scenario  # noqa: E402
from crowd_samples.theater import theater_scenario, theater_world  # noqa: E402
from usd_io.world_writer import WorldBuilder  # noqa: E402

__all__ = ["SAMPLES", "BUILDERS", "main", "scenario_toml", "WorldBuilder", "min_spacing", "MEET_GROUPS",
           "meet_scenario", "letter_points", "SPELL_STAGGER", "spell_scenario", "rooms_world", "rooms_scenario",
           "theater_world", "theater_scenario", "FETCH_CARRY", "fetch_world", "fetch_boxes", "fetch_scenario",
           "grid_scenario"]

SAMPLES = ("meet20", "spell70", "rooms_box", "theater40", "fetch_boxes20", "grid300", "grid500")

BUILDERS = {"rooms_box": rooms.build, "theater40": theater.build, "fetch_boxes20": fetch.build,
            "meet20": meet.build, "spell70": spell.build, "grid300": build_grid(300), "grid500": build_grid(500)}


def main(argv=None) -> int:
    """Write the samples named in ``argv`` (default: all) into their folders beside this file."""
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", help=f"samples to write (default all: {', '.join(SAMPLES)})")
    args = ap.parse_args(argv)
    names = args.names or list(SAMPLES)
    for name in names:
        if name not in BUILDERS:
            ap.error(f"unknown sample {name!r} (known: {', '.join(SAMPLES)})")
        BUILDERS[name](HERE / name)
        print(f"wrote {HERE / name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
