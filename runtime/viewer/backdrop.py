"""The backdrop, painted last of the opaque things and at the far plane, so only on pixels
nothing else covers (everything else stands on or above the ground): a sky gradient above the
horizon line, the ground, the world's "plaza" (its bounds) in a lighter tone, and a line grid
(1 m over the plaza, 5 m around it) fading with distance. Its parts lie in one plane and are
layered in the order they are painted (all at the far plane's depth, which they do not write).

The ground is a static plane around the world's centre; lighting is per vertex (the normal is
constant, and the lighting is linear in the colour) and fog goes by view depth, which is linear
over a triangle and so interpolates exactly. So the ground and the plaza are a few large
triangles and every grid line a few long segments: llvmpipe's cost is per primitive and per
interpolated value, and no pixel is drawn twice. The ground and the plaza have one colour
each (``shaders/ground.*``, flat), so a pixel interpolates only its view depth; the grid lines
(``shaders/flat.*``) fade into the ground colour by eye distance per pixel.

Import only after :func:`runtime.viewer.headless.configure`.
"""
from __future__ import annotations

import math

import numpy as np

from . import headless

headless.ensure()                       # pyglet's backend must be chosen before pyglet.gl loads
from pyglet import gl  # noqa: E402

from .gl import Mesh, Program, vertex_array  # noqa: E402
from .lighting import GROUND, PLAZA, SKY_HORIZON, SKY_ZENITH  # noqa: E402
from .meshes import line_pieces, rect_minus  # noqa: E402

__all__ = ["Backdrop", "ground_mesh", "grid_lines", "horizontal_forward", "GROUND_EXTENT", "CUT_OVERLAP"]

GROUND_EXTENT = 600.0      # metres from the world's centre to the edge of the ground plane
CUT_OVERLAP = 0.5          # metres the plaza and a grid line left out under the floor still run under its edges


def ground_mesh(area, extent=GROUND_EXTENT, hidden=()):
    """Triangles (V, 7) = position, rgb, fade 0 of the ground plane around the area's centre,
    with a hole where the plaza (the area) lies, and of the plaza. The ground is the 3 x 3 grid
    with lines at the plaza's edges minus its middle cell, so every edge is shared whole (no
    T-junctions, no cracks).

    Args:
        area: (xmin, zmin, xmax, zmax) of the plaza.
        extent: metres from the plaza's centre to the ground's edge.
        hidden: rectangles (xmin, zmin, xmax, zmax) of opaque floor drawn over the plaza
            (:func:`runtime.viewer.meshes.floor_rects`): the plaza is left out under them.
    """
    x0, z0, x1, z1 = area
    cx, cz = (x0 + x1) / 2, (z0 + z1) / 2
    xs = (cx - extent, x0, x1, cx + extent)
    zs = (cz - extent, z0, z1, cz + extent)

    def quad(xa, za, xb, zb, col):
        P = np.array([[xa, 0.0, za], [xb, 0.0, za], [xb, 0.0, zb], [xa, 0.0, za], [xb, 0.0, zb], [xa, 0.0, zb]])
        return np.concatenate([P, np.broadcast_to(np.r_[col, 0.0], (6, 4))], axis=1)

    ground = np.concatenate([quad(xs[i], zs[j], xs[i + 1], zs[j + 1], GROUND)
                             for i in range(3) for j in range(3) if (i, j) != (1, 1)])
    inner = [(a + CUT_OVERLAP, b + CUT_OVERLAP, c - CUT_OVERLAP, d - CUT_OVERLAP) for a, b, c, d in hidden
             if c - a > 2 * CUT_OVERLAP and d - b > 2 * CUT_OVERLAP]
    cells = rect_minus(area, inner)               # overlapping the floor's edges: no cracks between them
    plaza = np.concatenate([quad(*c, PLAZA) for c in cells]) if cells else np.zeros((0, 7))
    return ground.astype(np.float32), plaza.astype(np.float32)


def grid_lines(area, extent=150.0, hidden=()):
    """Line segments (V, 7) = position, rgb, fade distance: 1 m lines over the plaza and 5 m
    lines out to ``extent`` (returned separately: they fade into different colours), in 25 m
    pieces (the fade is per pixel and the fog linear, so any pieces shade exactly; but llvmpipe
    drops lines that reach far outside the view, so they are not drawn whole). The x = 0 and
    z = 0 lines are tinted red and blue. What would be painted over is left out: the 5 m lines
    inside the plaza, and the 1 m lines under ``hidden`` rectangles (xmin, zmin, xmax, zmax) of
    opaque floor."""
    x0, z0, x1, z1 = area
    out = []

    def lines(lo_x, lo_z, hi_x, hi_z, spacing, colour, fade, seg, holes):
        xs = np.arange(math.ceil(lo_x / spacing), math.floor(hi_x / spacing) + 1) * spacing
        zs = np.arange(math.ceil(lo_z / spacing), math.floor(hi_z / spacing) + 1) * spacing
        for x in xs:
            if spacing < 5 and abs(x / 5 - round(x / 5)) < 1e-6:
                continue
            col = colour if abs(x) > 1e-6 else (0.64, 0.40, 0.36)
            for tz in line_pieces(lo_z, hi_z, seg, [(h[1], h[3]) for h in holes if h[0] < x < h[2]], CUT_OVERLAP):
                p = np.column_stack([np.full(len(tz), x), np.full(len(tz), 0.004), tz])
                out.append(_segments(p, col, fade))
        for z in zs:
            if spacing < 5 and abs(z / 5 - round(z / 5)) < 1e-6:
                continue
            col = colour if abs(z) > 1e-6 else (0.36, 0.46, 0.66)
            for tx in line_pieces(lo_x, hi_x, seg, [(h[0], h[2]) for h in holes if h[1] < z < h[3]], CUT_OVERLAP):
                p = np.column_stack([tx, np.full(len(tx), 0.004), np.full(len(tx), z)])
                out.append(_segments(p, col, fade))

    cx, cz = (x0 + x1) / 2, (z0 + z1) / 2
    lines(x0, z0, x1, z1, 1.0, np.array(PLAZA) * 0.90, 60.0, 25.0, list(hidden))
    minor = np.concatenate(out).astype(np.float32) if out else np.zeros((0, 7), np.float32)
    out.clear()
    lines(cx - extent, cz - extent, cx + extent, cz + extent, 5.0, np.array(GROUND) * 0.84, 90.0, 25.0, [tuple(area)])
    major = np.concatenate(out)
    # dissolve into the ground towards the edge of the grid
    rr = np.hypot(major[:, 0] - cx, major[:, 2] - cz) / extent
    k = np.clip((rr - 0.55) / 0.4, 0.0, 1.0)[:, None]
    major[:, 3:6] = major[:, 3:6] * (1 - k) + np.array(GROUND) * k
    return minor, major.astype(np.float32)


def _segments(p, col, fade):
    """Line-list vertices (2 (K - 1), 7) of the polyline ``p`` (K, 3), colour and fade."""
    a, b = p[:-1], p[1:]
    v = np.stack([a, b], axis=1).reshape(-1, 3)
    c = np.broadcast_to(np.r_[col, fade], (len(v), 4))
    return np.concatenate([v, c], axis=1)


def horizontal_forward(view: np.ndarray) -> np.ndarray:
    """The camera's forward direction projected on the ground plane, unit length (-Z when
    the camera looks straight down)."""
    f = -view[2, :3]                 # camera forward in world coordinates
    h = np.array([f[0], 0.0, f[2]])
    L = np.linalg.norm(h)
    return h / L if L > 1e-9 else np.array([0.0, 0.0, -1.0])


class Backdrop:
    """The GL objects of the backdrop; :meth:`set_area` places it, :meth:`draw` paints it."""

    def __init__(self):
        self.p_flat = Program.from_files("flat.vert", "flat.frag", "grid")
        self.p_ground = Program.from_files("ground.vert", "ground.frag", "ground")
        self.p_sky = Program.from_files("sky.vert", "sky.frag", "sky")
        self.vao_empty = vertex_array()
        flat = [(0, 3), (1, 4)]
        self.m_ground = Mesh(flat, usage=gl.GL_STATIC_DRAW)
        self.m_plaza = Mesh(flat, usage=gl.GL_STATIC_DRAW)
        self.m_lines = Mesh(flat, mode=gl.GL_LINES, usage=gl.GL_STATIC_DRAW)
        self.m_major = Mesh(flat, mode=gl.GL_LINES, usage=gl.GL_STATIC_DRAW)

    def set_area(self, area, hidden=()) -> None:
        """Rebuild the ground, plaza and grid around ``area`` (xmin, zmin, xmax, zmax), less
        what ``hidden`` rectangles of opaque floor cover (see :func:`ground_mesh`)."""
        g, p = ground_mesh(area, hidden=hidden)
        self.m_ground.upload(g)
        self.m_plaza.upload(p)
        minor, major = grid_lines(area, hidden=hidden)
        self.m_lines.upload(minor)
        self.m_major.upload(major)

    def draw(self, view: np.ndarray, vp: np.ndarray, eye: np.ndarray, dist: float, shade: dict) -> None:
        """Paint sky, ground, 5 m lines, plaza and 1 m lines in that order, at the far plane
        where nothing nearer was drawn (depth test on and left on, depth writes left on).

        Args:
            view, vp: the camera's view and view-projection matrices.
            eye: the eye position (3,).
            dist: the eye's distance from the world's centre (grid fade distances grow with it).
            shade: :func:`runtime.viewer.lighting.shade_uniforms`.
        """
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LEQUAL)
        gl.glDepthMask(gl.GL_FALSE)
        gl.glDepthRange(1.0, 1.0)                 # every fragment at the far plane: drawn where the depth is clear
        p = self.p_sky.use()
        horizon = eye + 1e4 * horizontal_forward(view)
        hc = vp @ np.r_[horizon, 1.0]
        hy = float(hc[1] / hc[3]) if hc[3] > 0 else -1.0
        if hy < 1.0:
            p.set(u_horizon_y=hy, u_horizon=SKY_HORIZON, u_zenith=SKY_ZENITH)
            gl.glBindVertexArray(self.vao_empty)
            gl.glDrawArrays(gl.GL_TRIANGLES, 0, 6)
        ground = dict(u_vp=vp, u_eye=tuple(eye), u_forward=tuple(-view[2, :3]), **shade)
        grid = dict(ground, u_fade_scale=float(max(1.0, dist / 40.0)))
        self.p_ground.use().set(**ground)
        self.m_ground.draw()
        self.p_flat.use().set(u_ground=GROUND, **grid)     # 5 m lines, hidden by the plaza
        self.m_major.draw()
        self.p_ground.use()
        self.m_plaza.draw()
        self.p_flat.use().set(u_ground=PLAZA, **grid)      # 1 m lines on the plaza
        self.m_lines.draw()
        gl.glDepthRange(0.0, 1.0)
        gl.glDepthMask(gl.GL_TRUE)
