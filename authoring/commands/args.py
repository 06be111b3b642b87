"""Checked command-line values: numbers that must be finite and in range (argparse types whose
limits also go into ``--help``), and output paths that must be writable before any work starts."""
from __future__ import annotations

import argparse
import math
import os
import tempfile
from pathlib import Path

from authoring.commands import CLIError

__all__ = ["number", "integer", "limits", "check_output", "check_output_dir"]


def limits(lo=None, hi=None, unit: str = "", lo_open: bool = False, prose: bool = False) -> str:
    """The range of a value: ``"1-64"``, ``"> 0, at most 3600 s"`` for its ``--help``, or with
    ``prose`` ``"from 1 to 64"``, ``"greater than 0 and at most 3600 s"`` for a message."""
    if lo_open and lo is not None:
        text = (f"greater than {lo:g}" if prose else f"> {lo:g}") + (
            "" if hi is None else (" and at most " if prose else ", at most ") + f"{hi:g}")
    elif lo is not None and hi is not None:
        text = f"from {lo:g} to {hi:g}" if prose else f"{lo:g}-{hi:g}"
    elif lo is not None or hi is not None:
        text = (("of at least " if prose else ">= ") + f"{lo:g}") if hi is None \
            else (("of at most " if prose else "<= ") + f"{hi:g}")
    else:
        return "" if prose else "any finite number"
    return text + (f" {unit}" if unit else "")


def _must(what: str, in_range: str, text: str) -> str:
    return f"must be {what}{' ' + in_range if in_range else ''}, got {text!r}"


def number(lo=None, hi=None, lo_open: bool = False, unit: str = ""):
    """An argparse ``type``: a finite float in [lo, hi] (lo excluded with ``lo_open``)."""
    def parse(text: str) -> float:
        try:
            x = float(text)
        except ValueError:
            x = None
        if x is None or not math.isfinite(x) or (lo is not None and (x < lo or (lo_open and x == lo))) \
                or (hi is not None and x > hi):
            raise argparse.ArgumentTypeError(_must("a finite number", limits(lo, hi, unit, lo_open, True), text))
        return x
    parse.__name__ = "number"
    return parse


def integer(lo=None, hi=None):
    """An argparse ``type``: an integer in [lo, hi]."""
    def parse(text: str) -> int:
        try:
            x = int(text, 10)
        except ValueError:
            x = None
        if x is None or (lo is not None and x < lo) or (hi is not None and x > hi):
            raise argparse.ArgumentTypeError(_must("an integer", limits(lo, hi, prose=True), text))
        return x
    parse.__name__ = "integer"
    return parse


def _writable_dir(d: Path, what: str) -> None:
    """``d`` (or, if it does not exist yet, its nearest existing ancestor, where it will be
    created) accepts a new file: tried by creating and removing one, which also works where
    permission bits say nothing (running as root, /proc, read-only mounts)."""
    probe = d
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise CLIError(f"{what}: {probe} is not a directory")
    try:
        fd, name = tempfile.mkstemp(prefix=".crowdweave-probe-", dir=probe)
        os.close(fd)
        os.unlink(name)
    except OSError as e:
        raise CLIError(f"{what}: cannot write in {probe}: {e.strerror or e}") from None


def check_output(path, suffixes=None, option: str = "--out") -> Path:
    """``path`` as a Path if a file can be written there: not a directory, an allowed suffix,
    its directory writable (or creatable). CLIError naming the option and the path otherwise."""
    p = Path(path)
    what = f"{option} {p}"
    if p.is_dir():
        raise CLIError(f"{what}: is a directory (give a file name)")
    if suffixes and p.suffix.lower() not in suffixes:
        raise CLIError(f"{what}: must end in {', '.join(suffixes)}")
    if p.name in ("", ".", ".."):
        raise CLIError(f"{what}: not a file name")
    _writable_dir(p.parent, what)
    return p


def check_output_dir(path, option: str = "--out") -> Path:
    """``path`` as a Path if it is (or can be created as) a writable directory."""
    p = Path(path)
    what = f"{option} {p}"
    if p.exists() and not p.is_dir():
        raise CLIError(f"{what}: exists and is not a directory")
    _writable_dir(p, what)
    return p
