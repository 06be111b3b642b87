"""Interactive tiling zones in the World (Kim, Hwang, Hyun and Lee 2012, section 5.3) as one
system of the tick: each zone extends its time horizon with new patch instances; its characters
are drawn with the crowd."""
from __future__ import annotations

from ..pose import PoseBatch

__all__ = ["TilingHost"]


class TilingHost:
    """The world's :class:`~runtime.tiling.zone.TilingZone`s. A zone that raises is stopped
    with a ``warning`` event; it never stops the loop."""

    name = "tiling"

    def __init__(self):
        self.zones: list = []
        self._batches: dict = {}      # zone name -> (PoseBatch, frame pushed)

    def add(self, zone):
        if any(z.name == zone.name for z in self.zones):
            raise ValueError(f"a tiling zone named {zone.name!r} is already in the world")
        self.zones.append(zone)
        return zone

    def tick(self, world) -> None:
        t = (world.frame + 1) * world.dt
        ms = 0.0
        for z in list(self.zones):
            try:
                z.step(t)
                ms += z.step_ms
            except Exception as e:      # a failing zone stops, with an event
                self.zones.remove(z)
                self._batches.pop(z.name, None)
                world.emit("warning", z.name, message=f"tiling zone stopped: {type(e).__name__}: {e}")
        world.stats["tiling_ms"] = ms

    def after_tick(self, world) -> None:
        pass

    def __len__(self) -> int:
        """Tiled characters in all zones."""
        return sum(len(z) for z in self.zones)

    def zone_positions(self, zone, time: float, alpha: float):
        """Joint world positions of a zone's characters at the render time (their own
        PoseBatch over the patch library's pose tables, pushed once per tick)."""
        f = zone.frame_at(time)
        batch, at = self._batches.get(zone.name, (None, None))
        if batch is None or len(batch) != len(zone):
            batch, at = PoseBatch(zone.library), None
        if at != f:
            if at != f - 1:
                batch.reset()
                batch.push(zone.pose_state(f - 1 if f > 0 else f))
            batch.push(zone.pose_state(f))
        self._batches[zone.name] = (batch, f)
        return batch.positions(alpha)

    def steer(self, k: int, xz) -> bool:
        """Steer the team of tiled character ``k`` (counted over all zones) towards ``xz``
        (its zone clamps the spot inside the zone). False when there is no such character."""
        for z in self.zones:
            if k < len(z):
                z.set_target(z.team_of(k), xz)
                return True
            k -= len(z)
        return False
