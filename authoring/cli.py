"""The ``crowdweave`` command line.

Each sub-command lives in its own module under ``authoring/commands/`` exposing
``configure(parser)`` and ``run(args) -> int``; modules are imported only when their command
runs, so ``crowdweave --help`` stays fast and a command's heavy dependencies (USD, pyglet)
load only when needed.
"""
from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading

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
    "batch": ("authoring.commands.batch", "bake every variant of a sweep on a Dask cluster, with a summary"),
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


def _exit_on_signal(signum, frame):
    """SIGTERM / SIGHUP end the command like Ctrl-C does: as an exception, so every ``finally``
    (temporary files, worker processes) runs on the way out."""
    raise SystemExit(128 + signum)


class _signals_exit:
    """Within the block, SIGTERM and SIGHUP raise SystemExit (main thread only); restored after."""

    def __enter__(self):
        self.old = {}
        if threading.current_thread() is threading.main_thread():
            for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None)):
                if s is not None:
                    self.old[s] = signal.signal(s, _exit_on_signal)
        return self

    def __exit__(self, *exc):
        for s, h in self.old.items():
            signal.signal(s, h)
        return False


def main(argv=None) -> int:
    """Run one command; returns its exit code (0 ok, 1 a check failed, 2 a usage or input error,
    130 interrupted; a command ended by SIGTERM/SIGHUP exits with 128 + the signal)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser, modules = _build_parser(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:        # --help, or a bad argument (argparse printed the one-line error)
        return e.code if isinstance(e.code, int) else 2
    if not args.command:
        parser.print_help()
        return 0
    mod = modules.get(args.command) or importlib.import_module(COMMANDS[args.command][0])
    with _signals_exit():
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
