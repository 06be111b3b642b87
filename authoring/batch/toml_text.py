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

__all__ = ["dumps"]

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def _key(k: str) -> str:
    return k if _BARE_KEY.fullmatch(k) else _string(k)


def _string(s: str) -> str:
    out = s.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n").replace("\t", "\\t")
    return f'"{out}"'


def _scalar(v) -> str:
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
        return "{ " + ", ".join(f"{_key(k)} = {_scalar(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_scalar(x) for x in v) + "]"
    if hasattr(v, "tolist"):            # numpy scalars and arrays
        return _scalar(v.tolist())
    raise TypeError(f"cannot write a {type(v).__name__} as TOML")


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _block(table: dict, prefix: str, indent: str, lines: list) -> None:
    """Plain keys first, then sub-tables, then arrays of tables (TOML needs that order)."""
    plain = [(k, v) for k, v in table.items() if not isinstance(v, dict) and not _is_table_array(v)]
    tables = [(k, v) for k, v in table.items() if isinstance(v, dict) and prefix == ""]
    inline = [(k, v) for k, v in table.items() if isinstance(v, dict) and prefix != ""]
    arrays = [(k, v) for k, v in table.items() if _is_table_array(v)]
    for k, v in plain + inline:
        lines.append(f"{indent}{_key(k)} = {_scalar(v)}")
    for k, v in tables:
        lines += ["", f"[{_key(k)}]"]
        _block(v, k, "", lines)
    for k, v in arrays:
        name = f"{prefix}.{_key(k)}" if prefix else _key(k)
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
