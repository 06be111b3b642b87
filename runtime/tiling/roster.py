"""The characters of an interactive tiling: team, *tail* (the dangling exit of the last patch
instance each one plays), the patches banned at its tail, the index owner of its reservation,
and the teams' targets laid out as formations."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["Roster"]


class Roster:
    """Per-character arrays and lists (index = character id) and the team targets.

    Args:
        formation_spacing: default spacing (m) of a team's target grid.
    """

    def __init__(self, formation_spacing: float):
        self.formation_spacing = formation_spacing
        self.n = 0
        self.team = np.zeros(0, np.int64)
        self.tail: list = []                      # dangling exit key per character
        self.tail_time = np.zeros(0)
        self.ban: list = []                       # per character: patches not to retry at the current tail
        self.res_owner: list = []                 # per character: index owner of its reservation boxes
        self.targets: dict = {}

    def add(self, team: int, tail, tail_time: float, res_owner: int) -> int:
        """A new character; returns its id."""
        cid = self.n
        self.n += 1
        self.team = np.append(self.team, int(team))
        self.tail.append(tail)
        self.tail_time = np.append(self.tail_time, tail_time)
        self.ban.append(set())
        self.res_owner.append(res_owner)
        return cid

    def by_tail(self) -> dict:
        """Tail key -> character."""
        return {k: i for i, k in enumerate(self.tail)}

    def set_target(self, team: int, position, spacing: float | None = None) -> None:
        """Steer a team: its spots form a square grid of ``spacing`` metres (default
        ``formation_spacing``) centred on ``position``, in the order the members were added."""
        self.targets[int(team)] = (np.asarray(position, np.float64).reshape(2),
                                   self.formation_spacing if spacing is None else float(spacing))

    def target_of(self, cid: int):
        """Character ``cid``'s spot in its team's formation, or None without a target."""
        tg = self.targets.get(int(self.team[cid]))
        if tg is None:
            return None
        pos, sp = tg
        members = np.flatnonzero(self.team == self.team[cid])
        n = len(members)
        k = int(np.searchsorted(members, cid))
        side = int(math.ceil(math.sqrt(n)))
        r, c = divmod(k, side)
        return pos + sp * np.array([c - 0.5 * (side - 1), r - 0.5 * (math.ceil(n / side) - 1)])
