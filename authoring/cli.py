"""The ``crowdweave`` command line.

Each sub-command lives in its own module under ``authoring/commands/`` exposing
``configure(parser)`` and ``run(args) -> int``; modules are imported only when their command
runs, so ``crowdweave --help`` stays fast and a command's heavy dependencies (USD, pyglet)
load only when needed.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from authoring.commands import CLIError

# name -> (module, one-line help). Order is the order shown by --help.
COMMANDS = {
    "demo": ("authoring.commands.demo", "the main job: generate the default capture and summarise it"),
    "run": ("authoring.commands.run", "open a sample world in the viewer, its crowd planned live"),
    "capture": ("authoring.commands.capture", "generate procedural motion-capture takes (BVH + labels)"),
    "info": ("authoring.commands.info", "summarise a BVH file, a take directory or a .cwpack"),
    "convert": ("authoring.commands.convert", "convert a BVH file to USD (UsdSkel)"),
    "author": ("authoring.commands.author", "build runtime assets: motion graphs, roadmaps, flock graphs, patches"),
    "world": ("authoring.commands.world", "check a world stage: obstacles, markers, unusable prims"),
    "bake": ("authoring.commands.bake", "plan a sample scenario and write the baked crowd to USD"),
    "generate": ("authoring.commands.generate", "write a random valid world and crowd scenario (tests, benchmarks)"),
}


def _build_parser(argv) -> tuple[argparse.ArgumentParser, dict]:
    p = argparse.ArgumentParser(prog="crowdweave", description="Data-driven crowd animation with USD interchange.")
    p.add_argument("--version", action="version", version="crowdweave 0.1.0")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    modules = {}
    wanted = next((a for a in argv if not a.startswith("-")), None)
    for name, (mod, help_) in COMMANDS.items():
        sp = sub.add_parser(name, help=help_, description=help_)
        if name == wanted:  # only import the module of the command being run
            m = importlib.import_module(mod)
            m.configure(sp)
            modules[name] = m
    return p, modules


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser, modules = _build_parser(argv)
    args = parser.parse_args(argv)
    if not args.command:
        parser.print_help()
        return 0
    mod = modules.get(args.command) or importlib.import_module(COMMANDS[args.command][0])
    try:
        return int(mod.run(args) or 0)
    except CLIError as e:
        print(f"crowdweave {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
