"""TOML text of a scenario dict (``tomllib`` only reads).

Floats are written with ``repr`` (the shortest text that reads back as the same float), so a
scenario read with ``tomllib``, changed and written again keeps every other number exactly.
Nested tables and arrays of tables (``[[character]]`` with ``[[character.goal]]``) are written
in block form; tables inside arrays of plain values and small tables such as ``start`` are
written inline.
"""
from __future__ import annotations

import math
import re

__all__ = ["dumps", "inline_value", "key"]

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r", "\b": "\\b", "\f": "\\f"}


def key(k: str) -> str:
    """A table key: bare when it can be, else a quoted string."""
    return k if _BARE_KEY.fullmatch(k) else _string(k)


def _string(s: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = "".join(_ESCAPES.get(ch) or (f"\\u{ord(ch):04x}" if ord(ch) < 0x20 or ord(ch) == 0x7F else ch) for ch in s)
    return f'"{out}"'


def inline_value(v) -> str:
    """A value as inline TOML text: scalars, inline tables and arrays (numpy values too)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{key(k)} = {inline_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(inline_value(x) for x in v) + "]"
    if hasattr(v, "tolist"):            # numpy scalars and arrays
        return inline_value(v.tolist())
    raise TypeError(f"cannot write a {type(v).__name__} as TOML")


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _block(table: dict, prefix: str, indent: str, lines: list) -> None:
    """Plain keys first, then sub-tables, then arrays of tables (TOML needs that order)."""
    plain = [(k, v) for k, v in table.items() if not isinstance(v, dict) and not _is_table_array(v)]
    tables = [(k, v) for k, v in table.items() if isinstance(v, dict) and prefix == ""]
    small = [(k, v) for k, v in table.items() if isinstance(v, dict) and prefix != ""]
    arrays = [(k, v) for k, v in table.items() if _is_table_array(v)]
    for k, v in plain + small:
        lines.append(f"{indent}{key(k)} = {inline_value(v)}")
    for k, v in tables:
        lines += ["", f"[{key(k)}]"]
        _block(v, k, "", lines)
    for k, v in arrays:
        name = f"{prefix}.{key(k)}" if prefix else key(k)
        inner = indent + "  " if prefix else ""
        for item in v:
            if not prefix:
                lines.append("")
            lines.append(f"{inner}[[{name}]]")
            _block(item, name, inner, lines)


def dumps(data: dict) -> str:
    """TOML text of ``data`` (a dict of scalars, lists, tables and arrays of tables)."""
    lines: list[str] = []
    _block(data, "", "", lines)
    return "\n".join(lines).lstrip("\n") + "\n"
