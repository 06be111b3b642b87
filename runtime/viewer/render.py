"""OpenGL 3.3 core renderer for the viewer (pyglet's GL bindings; import only after
:func:`runtime.viewer.headless.configure`).

A frame is a handful of draw calls, none per character or per bone. Everything opaque is drawn
front to back in kind, depth tested, before the backdrop, so that llvmpipe (fill-rate bound)
shades each covered pixel about once:

* floor markings (spawn discs, region fills and outlines; :func:`runtime.viewer.meshes.split_floor`),
  topmost first, each pixel shaded by the first marking that covers it (the stencil buffer;
  without one they overdraw, to the same picture);
* static environment: obstacle footprints extruded to prisms, seats, boxes (one static vertex
  buffer, :func:`runtime.viewer.meshes.environment_mesh`, per-pixel lighting, ``shaders/lit.*``);
* flock agents: arrowheads expanded on the CPU into one vertex buffer; movable boxes the same;
* characters by level of detail (:mod:`runtime.viewer.characters`);
* the backdrop (:mod:`runtime.viewer.backdrop`): sky, ground, plaza and grid, painted in that
  order at the far plane, so only where nothing else was drawn;
* decals: blob shadows under characters big enough on screen, selection and go-to rings
  (blended, no depth writes, ``shaders/decal.*``).

Light and colours are in :mod:`runtime.viewer.lighting`.
"""
from __future__ import annotations

import numpy as np

from . import headless

headless.ensure()                       # pyglet's backend must be chosen before pyglet.gl loads
from pyglet import gl  # noqa: E402

from .backdrop import Backdrop  # noqa: E402
from .characters import CharacterPass  # noqa: E402
from .figures import FigureStyle  # noqa: E402
from .gl import Mesh, Program  # noqa: E402
from .lighting import GROUND, PLAZA, SKY_HORIZON, fog_range, shade_uniforms  # noqa: E402
from .meshes import (CARDBOARD, arrow_mesh, box_mesh, decal_vertices, environment_mesh, floor_rects,  # noqa: E402
                     posed_copies, split_floor)

__all__ = ["Renderer", "SKY_HORIZON", "GROUND", "PLAZA"]

FLOCK_COLOUR = (0.96, 0.56, 0.16)


class Renderer:
    """Owns the GL objects; :meth:`draw` renders one frame into the current framebuffer.

    Args:
        skeleton: the characters' skeleton (its joint names choose the figure style).

    Attributes:
        area: (xmin, zmin, xmax, zmax) of the plaza: the environment's bounds grown by 1.5 m.
        stats: ``{"bones": ..., "agents": ...}`` drawn in the last frame.
    """

    def __init__(self, skeleton):
        self.style = FigureStyle.for_skeleton(skeleton)
        self.backdrop = Backdrop()
        self.characters = CharacterPass(self.style)
        self.p_lit = Program.from_files("lit.vert", "lit.frag", "lit")
        self.p_floor = Program.from_files("floor.vert", "floor.frag", "floor")
        self.p_decal = Program.from_files("decal.vert", "decal.frag", "decal")
        lit = [(0, 3), (1, 3), (2, 3)]
        self.m_floor = Mesh(lit, usage=gl.GL_STATIC_DRAW)
        self.m_env = Mesh(lit, usage=gl.GL_STATIC_DRAW)
        self.m_agents = Mesh(lit)
        self.m_boxes = Mesh(lit)
        self.m_decals = Mesh([(0, 3), (1, 3), (2, 4)])
        self._arrow = arrow_mesh()
        self._box = box_mesh(0.4)
        self.area = (-15.0, -15.0, 15.0, 15.0)
        self.backdrop.set_area(self.area)

    @property
    def lod_counts(self) -> dict:
        """``{"near": n, "far": m}`` figures drawn in the last frame with characters."""
        return self.characters.lod_counts

    @property
    def num_bones(self) -> int:
        """Capsule impostors drawn in the last frame."""
        return self.characters.num_bones

    # -- static content -----------------------------------------------------------------------------
    def set_environment(self, env, heights=None, draw_boxes: bool = True) -> None:
        """Draw ``env`` (obstacles ``heights`` m tall, default 1 m; its box markers unless
        ``draw_boxes`` is False) and fit the plaza to its bounds."""
        floor, rest = split_floor(environment_mesh(env, heights, draw_boxes=draw_boxes))
        self.m_floor.upload(floor)
        self.m_env.upload(rest)
        if env.num_obstacles or env.markers:
            self.area = env.bounds(1.5)
        self.backdrop.set_area(self.area, floor_rects(env) if len(floor) else ())

    # -- per frame ----------------------------------------------------------------------------------------
    def draw_characters(self, view, proj, width: int, height: int, positions, selected=None,
                        fog=(70.0, 220.0)) -> None:
        """The character pass alone (depth test on): see :meth:`CharacterPass.draw`."""
        self.characters.draw(view, proj, width, height, positions, selected, fog)

    def _draw_lit(self, mesh: Mesh, vp, eye, shade: dict, vertices=None, program=None) -> None:
        p = (program or self.p_lit).use()
        p.set(u_vp=vp, u_eye=tuple(eye), **shade)
        if vertices is not None:
            mesh.upload(vertices)
        mesh.draw()

    def draw(self, view: np.ndarray, proj: np.ndarray, eye, width: int, height: int, positions=None,
             flock=None, selected=None, rings=(), boxes=None) -> None:
        """One frame.

        Args:
            view, proj: the camera's view and projection matrices (4 x 4, column vectors).
            eye: the eye position (3,).
            width, height: the framebuffer size in pixels.
            positions: joint positions (N, J, 3), or None.
            flock: (positions (M, 3), headings (M,)) of flock agents, or None.
            selected: index of the selected character, or None.
            rings: iterable of (x, z, radius, (r, g, b, a)).
            boxes: (K, 4) bottom centre x, y, z and heading of movable boxes, or None.
        """
        vp = proj @ view
        eye = np.asarray(eye, dtype=np.float64)
        gl.glViewport(0, 0, width, height)
        gl.glClearColor(*SKY_HORIZON, 1.0)
        gl.glClearStencil(0)
        gl.glStencilMask(0xFF)
        gl.glDepthMask(gl.GL_TRUE)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT | gl.GL_STENCIL_BUFFER_BIT)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LEQUAL)
        gl.glDisable(gl.GL_BLEND)
        gl.glDisable(gl.GL_CULL_FACE)
        centre = np.array([0.5 * (self.area[0] + self.area[2]), 0.0, 0.5 * (self.area[1] + self.area[3])])
        dist = float(np.linalg.norm(eye - centre))
        fog = fog_range(dist)
        shade = shade_uniforms(fog)
        n = 0 if positions is None else len(positions)
        if self.m_floor.count:                # the first (topmost) marking on a pixel is the one shaded
            gl.glEnable(gl.GL_STENCIL_TEST)
            gl.glStencilFunc(gl.GL_EQUAL, 0, 0xFF)
            gl.glStencilOp(gl.GL_KEEP, gl.GL_KEEP, gl.GL_INCR)
            self._draw_lit(self.m_floor, vp, eye, shade, program=self.p_floor)
            gl.glDisable(gl.GL_STENCIL_TEST)
        if self.m_env.count:
            self._draw_lit(self.m_env, vp, eye, shade)
        m = 0
        if flock is not None and len(flock[0]):
            fpos = np.asarray(flock[0], dtype=np.float64)
            m = len(fpos)
            heading = np.asarray(flock[1], dtype=np.float64)
            self._draw_lit(self.m_agents, vp, eye, shade, posed_copies(self._arrow, fpos, heading, FLOCK_COLOUR))
        if boxes is not None and len(boxes):          # movable boxes (carried or put down)
            b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
            self._draw_lit(self.m_boxes, vp, eye, shade, posed_copies(self._box, b[:, :3], b[:, 3], tuple(CARDBOARD)))
        if n:
            self.characters.draw(view, proj, width, height, positions, selected, fog)
        else:
            self.characters.skip()
        self.backdrop.draw(view, vp, eye, dist, shade)
        shadowed = self.characters.shadowed
        roots = np.zeros((0, 3)) if not n else np.asarray(positions[shadowed, 0])
        if len(roots) or rings:
            gl.glEnable(gl.GL_BLEND)
            gl.glBlendFunc(gl.GL_SRC_ALPHA, gl.GL_ONE_MINUS_SRC_ALPHA)
            gl.glDepthMask(gl.GL_FALSE)
            p = self.p_decal.use()
            p.set(u_vp=vp)
            self.m_decals.upload(decal_vertices(roots, list(rings)))
            self.m_decals.draw()
            gl.glDepthMask(gl.GL_TRUE)
            gl.glDisable(gl.GL_BLEND)
        gl.glBindVertexArray(0)
        gl.glUseProgram(0)
        gl.glDisable(gl.GL_DEPTH_TEST)
        self.stats = {"bones": self.num_bones, "agents": m}
