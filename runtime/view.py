"""What a viewer reads from a scene: the typed protocol between the simulation and the screen.

:class:`runtime.world.World` implements it; :class:`runtime.viewer.TrackScene` is a light
stand-in for benchmarks. The viewer (``runtime.viewer``) reads nothing else, so any object with
these members can be shown. Required members are in :class:`SceneView`; the optional ones are
in :class:`InteractiveSceneView` and are looked up with ``getattr`` (a scene may leave any of
them out).
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["SceneView", "InteractiveSceneView"]


@runtime_checkable
class SceneView(Protocol):
    """The members a viewer needs.

    Attributes:
        environment: a :class:`runtime.crowd.environment.Environment`; obstacles are drawn as
            their footprints extruded, seats / boxes / spawn points / regions from its markers.
            Read when the viewer starts and again whenever it refers to another object.
        skeleton: the :class:`runtime.motion.skeleton.Skeleton` shared by all characters.
    """

    environment: object
    skeleton: object

    def joint_positions(self) -> np.ndarray:
        """Every character's joint world positions (N, J, 3) at the current render time
        (interpolated between ticks); row ``i`` is character ``i``, joint 0 the root."""

    def step(self, dt: float) -> object:
        """Advance by ``dt`` seconds of simulated time (the scene keeps its own fixed-step
        clock, :class:`runtime.clock.FixedStep`)."""


class InteractiveSceneView(SceneView, Protocol):
    """Optional members; the viewer uses each one a scene has.

    Attributes:
        dt: tick length in seconds (default 1/30), for single-stepping.
        obstacle_heights: heights (m) per obstacle in environment order (polygons, then
            circles); default 1 m.
    """

    dt: float
    obstacle_heights: object

    def flock_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Flock agents: positions (M, 3) and headings (M,) (radians about +Y, 0 facing +Z)."""

    def box_positions(self) -> np.ndarray:
        """(K, 4) bottom-centre x, y, z and heading of every box, carried ones included."""

    def hud_stats(self) -> dict:
        """Name -> value shown in the heads-up display, in order."""

    def select(self, i: int | None) -> None:
        """Character ``i`` (or None) was selected by a click."""

    def command_go_to(self, i: int, xz: np.ndarray) -> None:
        """Right-click on the ground with character ``i`` selected; ``xz`` float64 (2,)."""

    def landmarks(self) -> dict:
        """Named places the viewer's view keys jump to: name -> (x, y, z, radius) ("plaza":
        the opening view, "tiled", "flocks")."""
