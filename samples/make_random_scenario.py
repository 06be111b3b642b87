"""Write a random but valid world and crowd scenario: ``DIR/world.usda`` + ``DIR/scenario.toml``.

    python samples/make_random_scenario.py --seed 3 --characters 60 [--kind mixed] --out /tmp/random60
    crowdweave bake /tmp/random60 --out /tmp/random60.usdc

The same as ``crowdweave generate scenario`` (:mod:`authoring.scenario_gen`): kinds crossing,
rooms, meeting, seats, boxes or mixed (one per district of characters); same seed and options,
same bytes.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:       # run as a script from anywhere
    sys.path.insert(0, str(ROOT))

from authoring.commands import CLIError  # noqa: E402
from authoring.commands.generate import configure_scenario, run_scenario  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    configure_scenario(ap)
    args = ap.parse_args(argv)
    try:
        return run_scenario(args)
    except CLIError as e:
        print(f"make_random_scenario: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
