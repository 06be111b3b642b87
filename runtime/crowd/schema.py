"""Checked reading of TOML tables: every key known, every value of the right type, finite and in
range, and every error naming the file, the table and the key.

A :class:`Table` wraps one table of a parsed document (``where`` says which, e.g.
``"[synthesis]"`` or ``"character 'c01' goal 2"``); its readers return plain Python values and
raise the given error class with a one-line message such as::

    scenario.toml: [synthesis]: passes: must be an integer from 1 to 20, got 'many'

TOML booleans are never numbers here (Python's ``True == 1`` is not a count of passes), and
``nan`` / ``inf`` (valid TOML floats) are rejected wherever a number is read.
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from ..assets import read_bounded

__all__ = ["Table", "show", "read_toml", "MISSING"]

MISSING = object()


def show(v) -> str:
    """A short description of a TOML value for an error message."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return repr(v if len(v) <= 40 else v[:37] + "...")
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        s = repr(v)
        return s if len(s) <= 40 else f"a list of {len(v)}"
    return repr(v)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _range(lo, hi, integer: bool) -> str:
    f = (lambda x: str(int(x))) if integer else (lambda x: f"{x:g}")
    if lo is not None and hi is not None:
        return f" from {f(lo)} to {f(hi)}"
    if lo is not None:
        return f" of at least {f(lo)}"
    if hi is not None:
        return f" of at most {f(hi)}"
    return ""


def read_toml(path, limit: int, error=ValueError) -> dict:
    """Parse a TOML file read with a hard size limit (whatever the file system reports about
    its size; only a regular file); errors name the file (a syntax error also its line and
    column)."""
    p = Path(path)
    raw = read_bounded(p, limit, lambda where, reason: error(f"{where}: {reason}"))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise error(f"{p}: not UTF-8 text (byte {e.start})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{p}: not valid TOML: {e}") from None


class Table:
    """One table of a TOML document, read with checks (see the module docstring).

    Args:
        path: the file, for messages.
        where: which table, for messages (``"[synthesis]"``, ``"character 'c01' start"``).
        data: the parsed table (anything else is an error).
        keys: the keys it may have (any other is an error listing the known ones).
        error: the exception class raised.
    """

    def __init__(self, path, where: str, data, keys, error=ValueError):
        self.path, self.where, self.error = str(path), where, error
        if not isinstance(data, dict):
            raise error(f"{self.path}: {where}: must be a table, got {show(data)}")
        unknown = sorted(set(data) - set(keys))
        if unknown:
            raise error(f"{self.path}: {where}: unknown key{'s' if len(unknown) > 1 else ''} "
                        f"{', '.join(map(repr, unknown))} (known: {', '.join(sorted(keys))})")
        self.data = data

    def fail(self, key: str, message: str):
        raise self.error(f"{self.path}: {self.where}: {key}: {message}")

    def __contains__(self, key) -> bool:
        return key in self.data

    def _get(self, key, default):
        if key in self.data:
            return self.data[key]
        if default is MISSING:
            self.fail(key, "missing")
        return default

    def number(self, key: str, default=MISSING, lo=None, hi=None, lo_open: bool = False, unit: str = "") -> float:
        """A finite number (int or float) in [lo, hi] (lo excluded with ``lo_open``)."""
        v = self._get(key, default)
        return self.check_number(key, v, lo, hi, lo_open, unit)

    def check_number(self, key, v, lo=None, hi=None, lo_open: bool = False, unit: str = "") -> float:
        what = "a positive number" if lo_open and lo == 0 and hi is None else "a number"
        u = f" ({unit})" if unit else ""
        if not _is_number(v):
            self.fail(key, f"must be {what}{u}, got {show(v)}")
        x = float(v)
        if not math.isfinite(x):
            self.fail(key, f"must be a finite number{u}, got {show(v)}")
        if (lo is not None and (x < lo or (lo_open and x == lo))) or (hi is not None and x > hi):
            rng = (f" greater than {lo:g}" + (f" and at most {hi:g}" if hi is not None else "")) if lo_open \
                else _range(lo, hi, False)
            self.fail(key, f"must be a number{rng}{u}, got {show(v)}")
        return x

    def integer(self, key: str, default=MISSING, lo=None, hi=None) -> int:
        """An integer in [lo, hi] (a float with an integral value is not an integer here)."""
        v = self._get(key, default)
        if not isinstance(v, int) or isinstance(v, bool) or (lo is not None and v < lo) or (hi is not None and v > hi):
            self.fail(key, f"must be an integer{_range(lo, hi, True)}, got {show(v)}")
        return int(v)

    def string(self, key: str, default=MISSING, nonempty: bool = False) -> str:
        v = self._get(key, default)
        if not isinstance(v, str):
            self.fail(key, f"must be a string, got {show(v)}")
        if nonempty and not v:
            self.fail(key, "must not be empty")
        return v

    def boolean(self, key: str, default=MISSING) -> bool:
        v = self._get(key, default)
        if not isinstance(v, bool):
            self.fail(key, f"must be true or false, got {show(v)}")
        return v

    def vector(self, key: str, n: int, default=MISSING, what: str = "") -> np.ndarray:
        """A list of ``n`` finite numbers, as float64."""
        v = self._get(key, default)
        return self.check_vector(key, v, n, what)

    def check_vector(self, key, v, n: int, what: str = "") -> np.ndarray:
        shape = what or "[" + ", ".join(["x", "z"] if n == 2 else ["x", "y", "z"] if n == 3 else ["_"] * n) + "]"
        if not isinstance(v, list) or len(v) != n or not all(_is_number(x) for x in v):
            self.fail(key, f"must be {shape} ({n} numbers), got {show(v)}")
        a = np.asarray(v, dtype=np.float64)
        if not np.all(np.isfinite(a)):
            self.fail(key, f"must be {n} finite numbers, got {show(v)}")
        return a

    def interval(self, key: str, default=MISSING, lo=None, hi=None, scalar: bool = False, unit: str = "s") -> tuple:
        """``[a, b]`` with a <= b (or a single number a = b with ``scalar``), finite, in [lo, hi]."""
        v = self._get(key, default)
        if scalar and _is_number(v):
            v = [v, v]
        if not isinstance(v, (list, tuple)) or len(v) != 2 or not all(_is_number(x) for x in v):
            self.fail(key, f"must be [a, b] ({unit}){' or a number' if scalar else ''}, got {show(v)}")
        a, b = float(v[0]), float(v[1])
        if not (math.isfinite(a) and math.isfinite(b)):
            self.fail(key, f"must be finite numbers, got {show(list(v))}")
        if b < a:
            self.fail(key, f"[{a:g}, {b:g}] is empty (the end comes before the start)")
        if (lo is not None and a < lo) or (hi is not None and b > hi):
            self.fail(key, f"[{a:g}, {b:g}] must lie within [{'-inf' if lo is None else f'{lo:g}'}, "
                           f"{'inf' if hi is None else f'{hi:g}'}] {unit}")
        return a, b

    def table(self, key: str, where: str, keys, default=MISSING) -> "Table":
        """A sub-table (an inline table or a [header] table)."""
        v = self._get(key, default)
        return Table(self.path, where, v, keys, self.error)

    def tables(self, key: str, limit: int | None = None) -> list:
        """An array of tables (``[[key]]``), possibly empty; each element must be a table."""
        v = self.data.get(key, [])
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            self.fail(key, f"must be an array of tables ([[{key}]]), got {show(v)}")
        if limit is not None and len(v) > limit:
            self.fail(key, f"{len(v)} entries: more than the limit of {limit}")
        return v
