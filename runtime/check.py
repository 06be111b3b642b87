"""The result every independent checker returns (crowds, tilings, flock walks).

A checker never trusts the synthesizer: it reads what was produced (a baked stage, the
deformed patch instances, the agents' world positions) and recomputes the figures. What it
found is a :class:`CheckReport`: ``passed``, a flat JSON-ready ``summary()`` of counts and
worst values (the same keys ``passed`` and ``kind`` in every system), ``details()`` with the
per-item rows, and a one-line ``str()`` for the CLI.
"""
from __future__ import annotations

__all__ = ["CheckReport", "format_summary"]


def format_summary(kind: str, summary: dict, keys=None) -> str:
    """``"<kind> check: PASSED | key value | ..."`` from a summary dict (``keys``: which, in
    order; default all but ``passed`` and ``kind``)."""
    keys = [k for k in summary if k not in ("passed", "kind")] if keys is None else keys
    verdict = "PASSED" if summary.get("passed") else "FAILED"
    parts = [f"{k.replace('_', ' ')} {summary[k]}" for k in keys]
    return f"{kind} check: {verdict}" + "".join(f" | {p}" for p in parts)


class CheckReport:
    """Base of the checkers' reports. Subclasses set ``kind`` and implement :attr:`passed`,
    :meth:`figures` (the summary without ``passed``/``kind``) and, if they have per-item
    rows, :meth:`details`."""

    kind: str = "check"

    @property
    def passed(self) -> bool:              # pragma: no cover - abstract
        raise NotImplementedError

    def figures(self) -> dict:             # pragma: no cover - abstract
        raise NotImplementedError

    def details(self) -> dict:
        return {}

    def summary(self) -> dict:
        return {"kind": self.kind, "passed": bool(self.passed), **self.figures()}

    def to_dict(self) -> dict:
        """``{"summary": ..., **details}``: what a bake writes into its JSON report."""
        return {**self.details(), "summary": self.summary()}

    def __str__(self) -> str:
        return format_summary(self.kind, self.summary())
