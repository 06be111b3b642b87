"""``crowdweave author KIND ...``: build a runtime asset pack.

Each asset kind has its own module ``authoring/commands/author_<kind>.py`` with
``configure(parser)`` and ``run(args)``.
"""
from __future__ import annotations

import importlib

KINDS = {
    "graph": ("authoring.commands.author_graph", "motion graph (snap-together hubs) from takes and BVH files"),
    "roadmap": ("authoring.commands.author_roadmap", "probabilistic roadmap of a world stage"),
    "flock": ("authoring.commands.author_flock", "record a boids flock and build its flock motion graph (DDG)"),
    "patches": ("authoring.commands.author_patches", "motion-patch library from multi-character takes"),
}


def configure(parser):
    sub = parser.add_subparsers(dest="kind", metavar="KIND", required=True)
    for name, (mod, help_) in KINDS.items():
        sp = sub.add_parser(name, help=help_, description=help_)
        try:
            m = importlib.import_module(mod)
        except ModuleNotFoundError as e:
            if e.name != mod:
                raise
            sp.set_defaults(_unavailable=True)
            continue
        m.configure(sp)
        sp.set_defaults(_module=m)


def run(args) -> int:
    from authoring.commands import CLIError
    if getattr(args, "_unavailable", False):
        raise CLIError(f"'author {args.kind}' is not available in this build yet")
    return args._module.run(args)
