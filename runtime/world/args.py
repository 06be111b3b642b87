"""Argument checks of the World API: every public call checks its arguments before it changes
anything, so a call that raises leaves the World as it was.

A wrong type raises ``TypeError``; a value that is not finite, out of range, of the wrong shape
or an empty / reversed window raises ``ValueError``; every message names the argument.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["character_name", "point", "heading", "window", "alpha", "seconds", "marker_path", "names",
           "flock_starts", "MAX_COORDINATE", "MAX_TIME"]

MAX_COORDINATE = 1e6     # m from the origin: far beyond any world, and safe from overflow in squared distances
MAX_TIME = 1e7           # s of world time (about 115 days)
MAX_HEADING = 1e6        # rad: headings are angles; a huge one is a unit mistake


def _real(v, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise TypeError(f"{what} must be a number, not {type(v).__name__}")
    x = float(v)
    if not math.isfinite(x):
        raise ValueError(f"{what} must be finite, got {x}")
    return x


def character_name(name) -> str:
    """A character's name: a non-empty string."""
    if not isinstance(name, str):
        raise TypeError(f"a character name must be a string, not {type(name).__name__}")
    if not name:
        raise ValueError("a character name must not be empty")
    return name


def names(value) -> list[str]:
    """A non-empty list (or tuple) of distinct character names."""
    if isinstance(value, str) or not isinstance(value, (list, tuple)):
        raise TypeError(f"names must be a list of character names, not {type(value).__name__}")
    out = [character_name(n) for n in value]
    if not out:
        raise ValueError("names must name at least one character")
    if len(set(out)) != len(out):
        raise ValueError(f"names must be distinct, got {out}")
    return out


def point(p, what: str = "position") -> np.ndarray:
    """(x, z): two finite numbers within :data:`MAX_COORDINATE` of the origin, as float64 (2,)."""
    if isinstance(p, (str, bytes, dict)) or p is None or isinstance(p, numbers.Number):
        raise TypeError(f"{what} must be (x, z), not {type(p).__name__}")
    try:
        a = np.asarray(p)
    except (ValueError, TypeError):
        raise TypeError(f"{what} must be (x, z) numbers") from None
    if a.dtype == bool or not (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)):
        raise TypeError(f"{what} must be (x, z) numbers, got {a.dtype} values")
    if a.shape != (2,):
        raise ValueError(f"{what} must be (x, z): two numbers, got shape {a.shape}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite, got {a.tolist()}")
    if np.any(np.abs(a) > MAX_COORDINATE):
        raise ValueError(f"{what} {a.tolist()} is more than {MAX_COORDINATE:g} m from the origin")
    return a


def heading(h, optional: bool = False, what: str = "heading"):
    """A finite heading in radians (None allowed when ``optional``)."""
    if h is None and optional:
        return None
    x = _real(h, what)
    if abs(x) > MAX_HEADING:
        raise ValueError(f"{what} {x} is not an angle in radians")
    return x


def seconds(t, what: str = "time") -> float:
    """A finite, non-negative world time up to :data:`MAX_TIME`."""
    x = _real(t, what)
    if not 0.0 <= x <= MAX_TIME:
        raise ValueError(f"{what} must be from 0 to {MAX_TIME:g} s, got {x}")
    return x


def window(w, what: str = "arrive"):
    """None, or an arrival window (t0, t1) in seconds with 0 <= t0 <= t1."""
    if w is None:
        return None
    if isinstance(w, (str, bytes)) or not hasattr(w, "__len__"):
        raise TypeError(f"{what} must be (t0, t1) seconds, not {type(w).__name__}")
    if len(w) != 2:
        raise ValueError(f"{what} must be (t0, t1): two times, got {len(w)} values")
    t0, t1 = seconds(w[0], f"{what}[0]"), seconds(w[1], f"{what}[1]")
    if t1 < t0:
        raise ValueError(f"{what} ({t0}, {t1}) is reversed: it ends before it starts")
    return (t0, t1)


def alpha(a) -> float:
    """A render interpolation fraction: finite, clipped to [0, 1]."""
    return min(1.0, max(0.0, _real(a, "alpha")))


def marker_path(path, what: str) -> str:
    """A marker's prim path: a non-empty string."""
    if not isinstance(path, str):
        raise TypeError(f"{what} must be a prim path string, not {type(path).__name__}")
    if not path:
        raise ValueError(f"{what} must not be empty")
    return path


def flock_starts(positions, headings, regions, seed):
    """Flock centroids (k, 3), headings (k,) or None, regions (a list of k, or one region for
    all, or None), seed None or a non-negative integer: checked, as float64 arrays."""
    try:
        pos = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("positions must be (k, 3) numbers") from None
    if pos.ndim != 2 or pos.shape[1] != 3 or len(pos) == 0:
        raise ValueError(f"positions must be (k, 3) flock centroids, got shape {pos.shape}")
    if not np.all(np.isfinite(pos)) or np.any(np.abs(pos) > MAX_COORDINATE):
        raise ValueError(f"positions must be finite and within {MAX_COORDINATE:g} m of the origin")
    if headings is not None:
        try:
            headings = np.asarray(headings, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise TypeError("headings must be numbers") from None
        if len(headings) != len(pos) or not np.all(np.isfinite(headings)):
            raise ValueError(f"headings must be {len(pos)} finite numbers")
    if isinstance(regions, (list, tuple)) and len(regions) != len(pos):     # else one region for all
        raise ValueError(f"regions must have one entry per flock ({len(pos)}), got {len(regions)}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise ValueError(f"seed must be None or a non-negative integer, got {seed!r}")
    return pos, headings
