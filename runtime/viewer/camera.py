"""Orbit camera: view/projection matrices, projection of world points to window pixels, and
picking rays (numpy only, no GL, so tests and tools can use it without a display).

Conventions: world Y up, right-handed; matrices act on column vectors (``clip = VP @ [p, 1]``)
and are handed to GL column-major. Window pixels are pyglet's: x to the right, y up from the
bottom edge, pixel ``(i, j)`` covering ``[i, i + 1) x [j, j + 1)``; a mouse event at integer
``(i, j)`` is taken at the pixel centre ``(i + 0.5, j + 0.5)``.

The camera orbits ``target`` at ``distance``: ``yaw`` is the eye's bearing about +Y (0 puts the
eye on the +Z side of the target, looking towards -Z) and ``pitch`` its elevation above the
ground plane, both radians.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["OrbitCamera", "perspective", "look_at", "project", "look_at_landmark", "VIEWS"]

# The views the viewer's keys jump to, by landmark name: (distance m, pitch rad) or None (fitted to
# the landmark's radius). "plaza", the opening view, shows a person at least 30 px tall in the middle
# of a 720 px high view (45 degree field of view).
VIEWS = {"plaza": (18.0, 0.42), "follow": (9.0, 0.35), "tiled": None, "flocks": None}


def perspective(fov_y: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / math.tan(0.5 * fov_y)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def look_at(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    eye = np.asarray(eye, dtype=np.float64)
    f = np.asarray(target, dtype=np.float64) - eye
    f /= np.linalg.norm(f)
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


@dataclass
class OrbitCamera:
    target: np.ndarray = field(default_factory=lambda: np.zeros(3))
    distance: float = 20.0
    yaw: float = 0.6
    pitch: float = 0.75
    fov_y: float = math.radians(45.0)
    near: float = 0.2
    far: float = 600.0
    min_distance: float = 1.0
    max_distance: float = 400.0

    def __post_init__(self):
        self.target = np.asarray(self.target, dtype=np.float64).reshape(3).copy()

    # -- matrices ------------------------------------------------------------------------------
    @property
    def eye(self) -> np.ndarray:
        cp = math.cos(self.pitch)
        d = np.array([cp * math.sin(self.yaw), math.sin(self.pitch), cp * math.cos(self.yaw)])
        return self.target + self.distance * d

    def view(self) -> np.ndarray:
        return look_at(self.eye, self.target)

    def projection(self, width: int, height: int) -> np.ndarray:
        return perspective(self.fov_y, max(width, 1) / max(height, 1), self.near, self.far)

    def view_projection(self, width: int, height: int) -> np.ndarray:
        """4x4 world -> clip matrix (column vectors)."""
        return self.projection(width, height) @ self.view()

    # -- projection and picking ------------------------------------------------------------------
    def project(self, points, width: int, height: int):
        """Window pixel coordinates (..., 2) (x right, y up from the bottom) of world points
        (..., 3), and a mask (...,) of points in front of the camera."""
        return project(self.view_projection(width, height), points, width, height)

    def ray(self, x: float, y: float, width: int, height: int):
        """World ray (origin (3,), unit direction (3,)) through window pixel ``(x, y)`` (the
        pixel's centre)."""
        inv = np.linalg.inv(self.view_projection(width, height))
        nx = 2.0 * (x + 0.5) / width - 1.0
        ny = 2.0 * (y + 0.5) / height - 1.0
        a = inv @ np.array([nx, ny, -1.0, 1.0])
        b = inv @ np.array([nx, ny, 1.0, 1.0])
        a, b = a[:3] / a[3], b[:3] / b[3]
        d = b - a
        return a, d / np.linalg.norm(d)

    def ground_hit(self, x: float, y: float, width: int, height: int, ground_y: float = 0.0):
        """(x, z) where the ray through pixel ``(x, y)`` meets the plane ``y = ground_y``, or
        None when it does not (ray parallel to or pointing away from the plane)."""
        o, d = self.ray(x, y, width, height)
        if abs(d[1]) < 1e-9:
            return None
        s = (ground_y - o[1]) / d[1]
        if s <= 0:
            return None
        p = o + s * d
        return np.array([p[0], p[2]])

    # -- interaction -----------------------------------------------------------------------------
    def orbit(self, dx: float, dy: float, speed: float = 0.008) -> None:
        self.yaw -= dx * speed
        self.pitch = float(np.clip(self.pitch - dy * speed, math.radians(3.0), math.radians(89.0)))

    def pan(self, dx: float, dy: float, height: int) -> None:
        """Move the target in the ground plane so the point under the mouse follows it."""
        scale = 2.0 * self.distance * math.tan(0.5 * self.fov_y) / max(height, 1)
        right = np.array([math.cos(self.yaw), 0.0, -math.sin(self.yaw)])
        fwd = np.array([-math.sin(self.yaw), 0.0, -math.cos(self.yaw)])
        self.target -= right * dx * scale
        self.target -= fwd * dy * scale / max(math.sin(self.pitch), 0.2)

    def zoom(self, steps: float) -> None:
        self.distance = float(np.clip(self.distance * (0.88 ** steps), self.min_distance, self.max_distance))

    def frame(self, bounds, margin: float = 1.1) -> None:
        """Look at the centre of ``bounds`` = (xmin, zmin, xmax, zmax) from far enough to see it."""
        x0, z0, x1, z1 = bounds
        self.target = np.array([(x0 + x1) / 2, 0.0, (z0 + z1) / 2])
        r = 0.5 * math.hypot(x1 - x0, z1 - z0) * margin
        self.distance = float(np.clip(r / math.tan(0.5 * self.fov_y), self.min_distance, self.max_distance))


def look_at_landmark(cam: OrbitCamera, name: str, spot) -> None:
    """Point ``cam`` at landmark ``name`` = (x, y, z, radius) (see ``World.landmarks``): "plaza"
    and "follow" at a person's scale (:data:`VIEWS`, looking at chest height), "flocks" from
    far enough for the flock's spread, anything else (a tiling zone) fitted to its radius."""
    x, y, z, r = (float(v) for v in spot)
    fixed = VIEWS.get(name)
    if fixed is not None:
        cam.target = np.array([x, 0.9, z])
        cam.distance, cam.pitch = fixed
    elif name == "flocks":
        cam.target = np.array([x, y, z])
        cam.distance, cam.pitch = float(np.clip(2.2 * r + 12.0, 15.0, cam.max_distance)), 0.3
    else:
        cam.target = np.array([x, y, z])
        cam.distance = float(np.clip(1.2 * r / math.tan(0.5 * cam.fov_y), 8.0, cam.max_distance))
        cam.pitch = 0.6


def project(vp: np.ndarray, points, width: int, height: int):
    """Window pixels (..., 2) and in-front mask (...,) of world points (..., 3) under the
    view-projection ``vp``."""
    p = np.asarray(points, dtype=np.float64)
    h = p @ vp[:3, :3].T + vp[:3, 3]
    w = p @ vp[3, :3] + vp[3, 3]
    front = w > 1e-9
    ws = np.where(front, w, 1.0)
    nx, ny = h[..., 0] / ws, h[..., 1] / ws
    px = np.stack([(nx + 1.0) * 0.5 * width, (ny + 1.0) * 0.5 * height], axis=-1)
    return px, front
