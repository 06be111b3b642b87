"""The character pass: every figure in a handful of draw calls, none per character or per bone.

* Figures at least :data:`~runtime.viewer.figures.LOD_NEAR_PX` tall on screen: ONE
  non-instanced draw of ``6 * bones`` vertices; each bone is a capsule drawn as a ray-cast
  impostor. The vertex shader (``shaders/capsule.vert``) pulls the bone's endpoints and radius
  from buffer textures (``gl_VertexID / 6`` is the bone) and spans a camera-facing quad over
  the capsule's projection; the fragment shader intersects the view ray with the capsule,
  writes the true depth (limbs and characters intersect correctly) and shades the exact
  normal. Per frame the CPU uploads the bone endpoints with one ``glBufferSubData``.
* Smaller figures: ONE draw of one screen-space quad per figure; the CPU projects the figure's
  6 capsules (body, head, whole legs and arms) to pixels
  (:func:`runtime.viewer.figures.figure_vertices`) and the fragment shader
  (``shaders/figure.frag``) keeps the nearest capsule covering the pixel. Skeletons whose far
  set is not 6 capsules draw their far bones as impostors with the far variant of the capsule
  shaders (``#define FAR``: a 2D capsule in the quad's own coordinates, no depth write, so
  early depth testing stays on).

On llvmpipe the cost of small figures is per primitive and per 4 x 4 pixel block touched, not
per pixel, hence impostors, and one quad per distant figure; an instanced capsule mesh costs a
vertex-shading batch per instance (:class:`runtime.viewer.baseline.InstancedCapsules`).

Import only after :func:`runtime.viewer.headless.configure`.
"""
from __future__ import annotations

import numpy as np

from . import headless

headless.ensure()                       # pyglet's backend must be chosen before pyglet.gl loads
from pyglet import gl  # noqa: E402

from ..appearance import looks_for  # noqa: E402
from .figures import (FIGURE_CAPSULES, LOD_NEAR_PX, SHADOW_PX, FigureStyle, bone_arrays,  # noqa: E402
                      figure_sizes, figure_vertices, prop_arrays)
from .gl import Mesh, Program, TextureBuffer, vertex_array  # noqa: E402
from .lighting import LIGHT_DIR, SKY_HORIZON  # noqa: E402

__all__ = ["CharacterPass"]


class CharacterPass:
    """The GL objects of the character pass and what its last frame drew.

    Args:
        style: how the skeleton becomes capsules.

    Attributes:
        lod_counts: ``{"near": n, "far": m}`` figures of the last frame.
        num_bones: capsule impostors drawn (near and far bone by bone).
        near_bones: how many of them are near bones (they come first).
        num_figures: far figures drawn as one quad each.
        shadowed: indices of the figures big enough for a blob shadow.
    """

    def __init__(self, style: FigureStyle):
        self.style = style
        self.p_capsule = Program.from_files("capsule.vert", "capsule.frag", "capsule")
        self.p_capsule_far = Program.from_files("capsule.vert", "capsule_far.frag", "capsule (far)", defines=("FAR",))
        self.p_figure = Program.from_files("figure.vert", "figure.frag", "far figures")
        self.m_figures = Mesh([(loc, 4) for loc in range(13)])
        parts = [int(min(p, 2)) for p in style.far.part] + [0] * FIGURE_CAPSULES
        self.figure_parts = parts[:FIGURE_CAPSULES]       # 0 skin, 1 shirt, 2 trousers (shoes count as trousers)
        self.vao_empty = vertex_array()
        self.t_bones = TextureBuffer(gl.GL_RGB32F)
        self.t_style = TextureBuffer(gl.GL_RGBA32F)
        self.t_bones.upload(np.zeros((2, 3), np.float32))
        self.t_style.upload(np.zeros((1, 4), np.float32))
        self._palette_key = None
        self._pal = None
        self._looks = None
        self.names_source = None       # callable -> names of the first characters (e.g. World.names)
        self.look_seed = 0
        self._unnamed = None
        self.points = None
        self.near_bones = 0
        self.num_figures = 0
        self.lod_counts = {"near": 0, "far": 0}
        self.skip()

    def skip(self) -> None:
        """A frame without characters: no bones drawn, no shadows (``lod_counts`` and
        ``num_figures`` keep the last frame's)."""
        self.num_bones = 0
        self.shadowed = np.zeros(0, dtype=np.int64)

    def names(self, n: int) -> tuple:
        """Names of ``n`` characters: those ``names_source`` gives for the first rows, then
        ``#i`` for row ``i`` (rows without a name, e.g. tiled characters)."""
        given = self.names_source() if self.names_source is not None else None
        given = tuple(given or ())[:n]
        if self._unnamed is None or len(self._unnamed) < n:
            self._unnamed = tuple(f"#{i}" for i in range(max(n, 64)))
        return given + self._unnamed[len(given):n]

    def palette(self, n: int, selected) -> np.ndarray:
        """Colours (n, parts, 3) of ``n`` characters from their looks
        (:func:`runtime.appearance.looks_for` of their names and ``look_seed``), the
        ``selected`` one's shirt highlighted (kept until the names or the selection change)."""
        key = (self.names(n), self.look_seed, selected)
        if key != self._palette_key:
            self._looks = looks_for(key[0], self.look_seed)
            pal = self._looks.colours()                       # (N, parts, 3)
            if selected is not None and 0 <= selected < n:
                pal[selected, 1] = np.minimum(pal[selected, 1] * 0.3 + np.array([1.0, 0.85, 0.2]) * 0.8, 1.0)
            self._pal = pal
            self._palette_key = key
        return self._pal

    def bones(self, positions: np.ndarray, view: np.ndarray, proj: np.ndarray, height: int,
              selected=None, far_figures: bool | None = None):
        """Split the characters by level of detail and build their bone data.

        A character at least ``LOD_NEAR_PX`` pixels tall on screen is drawn bone by bone as
        ray-cast capsules (14 for the CMU skeleton); smaller ones as one screen-space quad per
        figure with 6 capsules (``far_figures``, default when the style's far set has 6
        capsules), or else bone by bone with the far shader. Characters at least ``SHADOW_PX``
        tall get a blob shadow (``self.shadowed``).

        Returns (bone endpoints (bones * 2, 3), bone styles (bones, 4) = radius, rgb, indices of
        the characters drawn as far figures or None). ``self.near_bones`` bones come first."""
        st = self.style
        P = st.points(positions)                                         # (N, J + V, 3)
        n = len(P)
        px, depth = figure_sizes(P, view, proj, height)
        near = (px >= LOD_NEAR_PX) & (depth > 0)
        visible = depth > 0
        pal = self.palette(n, selected)
        self.shadowed = np.flatnonzero((px >= SHADOW_PX) & (depth > 0))
        if far_figures is None:
            far_figures = len(st.far) == FIGURE_CAPSULES
        near_idx = np.flatnonzero(near)
        far_idx = np.flatnonzero(~near & visible)
        self.lod_counts = {"near": len(near_idx), "far": len(far_idx)}
        lk = self._looks
        ends, style = [], []
        if len(near_idx) and len(st.near):
            e, y = bone_arrays(P, near_idx, st.near, pal, lk.width)
            ends.append(e)
            style.append(y)
        e, y = prop_arrays(P, near_idx, st, lk.prop, lk.prop_colours())    # hats and bags, near figures
        ends.append(e)
        style.append(y)
        self.near_bones = sum(len(y) for y in style)
        if not far_figures and len(far_idx) and len(st.far):
            e, y = bone_arrays(P, far_idx, st.far, pal, lk.width)
            ends.append(e)
            style.append(y)
        self.points = P
        return np.concatenate(ends), np.concatenate(style), (far_idx if far_figures else None)

    def draw(self, view, proj, width: int, height: int, positions, selected=None, fog=(70.0, 220.0)) -> None:
        """The character pass (depth test on): near figures bone by bone, then the far ones.

        Args:
            view, proj: the camera's view and projection matrices.
            width, height: the framebuffer size in pixels.
            positions: joint positions (N, J, 3).
            selected: index of the selected character (its shirt is highlighted), or None.
            fog: fog start and end (metres from the eye).
        """
        ends, style, far_idx = self.bones(positions, view, proj, height, selected)
        self.num_bones = len(style)
        V3 = view[:3, :3]
        light, up = tuple(V3 @ LIGHT_DIR), tuple(V3 @ np.array([0.0, 1.0, 0.0]))
        if self.num_bones:
            self.t_bones.upload(ends)
            self.t_style.upload(style)
            self.t_bones.bind(0)
            self.t_style.bind(1)
            gl.glBindVertexArray(self.vao_empty)
            for prog, first, count in ((self.p_capsule, 0, self.near_bones),
                                       (self.p_capsule_far, self.near_bones, self.num_bones - self.near_bones)):
                if count <= 0:
                    continue
                p = prog.use()
                p.set(u_view=view, u_proj=proj, u_bones=0, u_style=1, u_first=int(first), u_light=light,
                      u_up=up, u_fog_color=SKY_HORIZON, u_fog=tuple(fog))
                gl.glDrawArrays(gl.GL_TRIANGLES, 0, 6 * int(count))
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, 0)
            gl.glActiveTexture(gl.GL_TEXTURE0)
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, 0)
        self.num_figures = 0 if far_idx is None else len(far_idx)
        if self.num_figures:
            pal = self.palette(len(self.points), selected)
            self.m_figures.upload(figure_vertices(self.points, far_idx, self.style.far, pal, view, proj, width,
                                                  height, fog, self._looks.width))
            p = self.p_figure.use()
            gl.glUniform1iv(p.loc("u_part"), FIGURE_CAPSULES, (gl.GLint * FIGURE_CAPSULES)(*self.figure_parts))
            p.set(u_light=light, u_up=up, u_fog_color=SKY_HORIZON)
            self.m_figures.draw()
        gl.glBindVertexArray(0)
