"""Events the World emits, and their listeners."""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Event", "EVENT_KINDS", "EventBus"]

EVENT_KINDS = ("arrived", "sat", "stood", "picked_up", "put_down", "late", "warning")


@dataclass
class Event:
    """Something that happened on a tick.

    Attributes:
        kind: one of :data:`EVENT_KINDS`.
        character: the character's (or tiling zone's) name.
        time: world time in seconds when it was emitted.
        data: kind-specific details (arrivals: ``frame``, ``position``, ``heading``,
            ``marker``, ``start_frame``; warnings: ``message``).
    """

    kind: str
    character: str
    time: float
    data: dict = field(default_factory=dict)


class EventBus:
    """Listeners by event kind ("*" for all); every emitted event is also kept in
    :attr:`events`. A listener's error never stops the loop."""

    def __init__(self):
        self.events: list[Event] = []
        self._listeners: dict = {}

    def on(self, kind: str, callback) -> None:
        """Call ``callback(event)`` for events of ``kind`` ("*" for all)."""
        self._listeners.setdefault(kind, []).append(callback)

    def emit(self, kind: str, name: str, time: float, **data) -> Event:
        ev = Event(kind, name, time, data)
        self.events.append(ev)
        for cb in self._listeners.get(kind, []) + self._listeners.get("*", []):
            try:
                cb(ev)
            except Exception:      # a listener's error never stops the loop
                pass
        return ev
