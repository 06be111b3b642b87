"""The World a game embeds: a fixed-timestep loop of systems (goal-directed crowd, flocks,
tiling zones), commands, events and poses.

Modules: :mod:`.world` (the World and its tick), :mod:`.crowd` (characters, commands, staged
synthesis), :mod:`.planning` (the budgeted planning queue), :mod:`.playback` (buffered futures,
structure of arrays), :mod:`.occupancy` (collision questions over them), :mod:`.events`,
:mod:`.flocks`, :mod:`.tiling` (the other systems) and :mod:`.scenario` (a scenario's flocks
and tiling zones, shared with the offline bake).
"""
from .crowd import CharacterState, CrowdSystem
from .events import Event, EventBus
from .occupancy import IdleStretches
from .planning import StepCosts
from .playback import MAX_BUFFER, Playback
from .scenario import spread_in_region
from .world import World

__all__ = ["World", "CharacterState", "CrowdSystem", "Event", "EventBus", "StepCosts", "IdleStretches",
           "Playback", "MAX_BUFFER", "spread_in_region"]
