"""Scenario dicts (the keys of :mod:`runtime.crowd.scenario`) as ``scenario.toml`` text:
``tomllib`` only reads TOML. Numbers are rounded to 4 decimals, so the same dict always gives
the same bytes."""
from __future__ import annotations

import numpy as np

__all__ = ["toml_number", "toml_value", "scenario_toml"]


def toml_number(v) -> str:
    """A float as TOML text: rounded to 4 decimals, trailing zeros dropped, never ``-0.0``."""
    v = float(v)
    if v == 0:
        v = 0.0                     # no "-0.0"
    s = f"{round(v, 4):.4f}".rstrip("0")
    return s + "0" if s.endswith(".") else s


def toml_value(v) -> str:
    """A scenario value (bool, number, string, inline table, array) as TOML text."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return toml_number(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def scenario_toml(sc: dict) -> str:
    """TOML text of a scenario dict (keys as in ``runtime.crowd.scenario``)."""
    lines = []
    for k in ("name", "description", "world", "library", "duration", "seed"):
        if k in sc:
            lines.append(f"{k} = {toml_value(sc[k])}")
    if sc.get("synthesis"):
        lines += ["", "[synthesis]"] + [f"{k} = {toml_value(v)}" for k, v in sc["synthesis"].items()]
    for c in sc["character"]:
        lines += ["", "[[character]]", f"name = {toml_value(c['name'])}", f"start = {toml_value(c['start'])}"]
        for g in c.get("goal", []):
            lines.append("  [[character.goal]]")
            lines += [f"  {k} = {toml_value(v)}" for k, v in g.items()]
    return "\n".join(lines) + "\n"
