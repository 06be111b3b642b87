"""Clip: a motion sampled at a fixed rate, stored root-relative.

Layout (ARCHITECTURE.md, "Conventions"):

- ``root_xz`` (F, 2): planar root position relative to frame 0, expressed in frame 0's
  heading frame (so ``root_xz[0] == (0, 0)`` and walking straight ahead is +Z);
- ``root_heading`` (F,): heading (rotation about +Y, radians, unwrapped) relative to
  frame 0 (``root_heading[0] == 0``);
- ``root_height`` (F,): root height above the ground, metres;
- ``rotations`` (F, J, 4) float32, w-x-y-z: joint local rotations; entry 0 is the root's
  rotation *with its heading removed* (the tilt/roll the character carries), so the root's
  world rotation is ``from_yaw(origin_heading + root_heading) * rotations[:, 0]``;
- ``origin`` (3,): (x, z, heading) of frame 0 in the world. Graph edges keep it at zero;
  imported takes keep where the capture put them;
- ``contacts`` (F, 4) bool or None: per frame, which contact points are on the ground, columns
  in :data:`runtime.motion.contacts.CONTACT_POINTS` order (left heel, left toe, right heel,
  right toe). None when unknown (:func:`runtime.motion.contacts.clip_contacts` detects them).

Heading is read from the root's lateral (+X) axis, see :func:`quat.yaw`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import quat
from .fk import forward_kinematics
from .planar import rotate_xz
from .skeleton import Skeleton

__all__ = ["Clip"]


@dataclass(frozen=True, eq=False)
class Clip:
    skeleton: Skeleton
    fps: float
    root_xz: np.ndarray
    root_heading: np.ndarray
    root_height: np.ndarray
    rotations: np.ndarray
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    contacts: np.ndarray | None = None

    def __post_init__(self):
        F = len(self.root_heading)
        object.__setattr__(self, "root_xz", np.asarray(self.root_xz, dtype=np.float64).reshape(F, 2))
        object.__setattr__(self, "root_heading", np.asarray(self.root_heading, dtype=np.float64))
        object.__setattr__(self, "root_height", np.asarray(self.root_height, dtype=np.float64).reshape(F))
        rot = np.asarray(self.rotations, dtype=np.float32)
        if rot.shape != (F, self.skeleton.num_joints, 4):
            raise ValueError(f"rotations shape {rot.shape} != ({F}, {self.skeleton.num_joints}, 4)")
        object.__setattr__(self, "rotations", rot)
        object.__setattr__(self, "origin", np.asarray(self.origin, dtype=np.float64).reshape(3))
        if self.fps <= 0:
            raise ValueError("fps must be positive")
        if self.contacts is not None:
            c = np.asarray(self.contacts, dtype=bool)
            if c.shape != (F, 4):
                raise ValueError(f"contacts shape {c.shape} != ({F}, 4): 4 flags for each of the {F} frames")
            object.__setattr__(self, "contacts", c)

    # -- basic properties ------------------------------------------------------------------
    @property
    def num_frames(self) -> int:
        return len(self.root_heading)

    def __len__(self) -> int:
        return self.num_frames

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return (self.num_frames - 1) / self.fps

    # -- construction from / conversion to world-space root --------------------------------
    @classmethod
    def from_world(cls, skeleton: Skeleton, fps: float, root_position: np.ndarray,
                   rotations: np.ndarray, keep_origin: bool = True) -> "Clip":
        """Build from a world root position (F, 3) and local rotations (F, J, 4) whose entry
        0 is the root's world rotation."""
        rot = quat.unroll(quat.normalize(np.asarray(rotations, dtype=np.float64)), axis=0)
        pos = np.asarray(root_position, dtype=np.float64)
        th, rest = quat.remove_yaw(rot[:, 0])
        th = np.unwrap(th)
        rot = rot.copy()
        rot[:, 0] = quat.unroll(quat.canonical(rest), axis=0)
        h0 = th[0]
        xz = pos[:, [0, 2]]
        rel = rotate_xz(xz - xz[0], -h0)
        origin = np.array([xz[0, 0], xz[0, 1], h0]) if keep_origin else np.zeros(3)
        return cls(skeleton, float(fps), rel, th - h0, pos[:, 1], rot.astype(np.float32), origin)

    def world_root(self, origin=None):
        """World root positions (F, 3) and root world rotations (F, 4) (float64)."""
        o = self.origin if origin is None else np.asarray(origin, dtype=np.float64)
        xz = rotate_xz(self.root_xz, o[2]) + o[:2]
        pos = np.stack([xz[:, 0], self.root_height, xz[:, 1]], axis=-1)
        heading = self.root_heading + o[2]
        rot = quat.mul(quat.from_yaw(heading), self.rotations[:, 0].astype(np.float64))
        return pos, rot

    def world_heading(self) -> np.ndarray:
        return self.root_heading + self.origin[2]

    def local_rotations_world_root(self, origin=None) -> np.ndarray:
        """(F, J, 4) float64 rotations with entry 0 replaced by the root's world rotation."""
        _, rroot = self.world_root(origin)
        rot = self.rotations.astype(np.float64)
        rot[:, 0] = rroot
        return rot

    def fk(self, origin=None):
        """World joint rotations (F, J, 4) and positions (F, J, 3)."""
        pos, _ = self.world_root(origin)
        return forward_kinematics(self.skeleton, pos, self.local_rotations_world_root(origin))

    def positions(self, origin=None) -> np.ndarray:
        return self.fk(origin)[1]

    # -- convenience -----------------------------------------------------------------------
    def with_origin(self, origin) -> "Clip":
        return replace(self, origin=np.asarray(origin, dtype=np.float64))

    def displacement(self):
        """(dx, dz, dheading) from the first to the last frame, in frame 0's heading frame."""
        return float(self.root_xz[-1, 0]), float(self.root_xz[-1, 1]), float(self.root_heading[-1])

    def copy(self, **changes) -> "Clip":
        return replace(self, **changes)
