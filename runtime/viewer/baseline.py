"""Baselines for ``bench/viewer.py``.

:class:`InstancedCapsules` is the conventional way to draw capsule-limbed crowds: one
instanced draw of a real capsule mesh (:func:`runtime.viewer.meshes.capsule_mesh`, 8 sides),
one instance per bone of the full-detail bone set, per-instance endpoints, radius and colour
via ``glVertexAttribDivisor``, per-pixel lighting (``shaders/instanced_capsule.vert`` with
``shaders/lit.frag``). On a GPU this is fine; on llvmpipe every instance costs a
vertex-shading batch of its own, which is why :class:`runtime.viewer.render.Renderer` draws
ray-cast impostors pulled from buffer textures instead (:mod:`runtime.viewer.characters`).
:class:`LineFigures` is the line-figure renderer whose frame rates ``ENVIRONMENT.md`` records
for this kind of machine, a calibration of the machine's current speed.
Import only after :func:`runtime.viewer.headless.configure`.
"""
from __future__ import annotations

import numpy as np

from . import headless

headless.ensure()                       # pyglet's backend must be chosen before pyglet.gl loads
from pyglet import gl  # noqa: E402

from .figures import FigureStyle, character_palette  # noqa: E402
from .gl import Buffer, Program, float_attributes, shader_source, vertex_array  # noqa: E402
from .lighting import LIGHT_DIR, SKY_HORIZON  # noqa: E402
from .meshes import capsule_mesh  # noqa: E402

__all__ = ["InstancedCapsules", "LineFigures"]


class InstancedCapsules:
    """Capsule-limbed figures as one instanced draw of a capsule mesh (the benchmark's
    baseline); :meth:`draw_characters` takes the arguments of
    :meth:`runtime.viewer.render.Renderer.draw_characters`."""

    def __init__(self, skeleton, sides: int = 8, rings: int = 1):
        self.style = FigureStyle.for_skeleton(skeleton)
        self.prog = Program(shader_source("instanced_capsule.vert"), shader_source("lit.frag"), "instanced capsules")
        verts, idx = capsule_mesh(sides, rings)
        self.index_count = len(idx)
        self.vao = vertex_array()
        gl.glBindVertexArray(self.vao)
        self.mesh = Buffer(usage=gl.GL_STATIC_DRAW)
        self.mesh.upload(verts)
        float_attributes([(0, 4)], 4)
        self.index = Buffer(gl.GL_ELEMENT_ARRAY_BUFFER, gl.GL_STATIC_DRAW)
        self.index.upload(idx.astype(np.uint32).view(np.float32))   # raw bytes
        self.inst = Buffer()
        self.inst.upload(np.zeros((1, 10), np.float32))
        float_attributes([(1, 3), (2, 3), (3, 4)], 10)
        for loc in (1, 2, 3):
            gl.glVertexAttribDivisor(loc, 1)
        gl.glBindVertexArray(0)

    def draw_characters(self, view, proj, width, height, positions, selected=None, fog=(70.0, 220.0)) -> None:
        st = self.style
        bs = st.near
        P = st.points(positions)
        n = len(P)
        pal = character_palette(n)
        data = np.empty((n, len(bs), 10), dtype=np.float32)
        data[:, :, 0:3] = P[:, bs.a]
        data[:, :, 3:6] = P[:, bs.b]
        data[:, :, 6] = bs.radius
        data[:, :, 7:10] = pal[:, bs.part]
        p = self.prog.use()
        eye = -view[:3, :3].T @ view[:3, 3]
        p.set(u_vp=proj @ view, u_eye=tuple(eye), u_light=tuple(LIGHT_DIR), u_up=(0.0, 1.0, 0.0),
              u_fog_color=SKY_HORIZON, u_fog=tuple(fog))
        gl.glBindVertexArray(self.vao)
        self.inst.upload(data.reshape(-1, 10))
        gl.glEnable(gl.GL_CULL_FACE)
        gl.glDrawElementsInstanced(gl.GL_TRIANGLES, self.index_count, gl.GL_UNSIGNED_INT, None, n * len(bs))
        gl.glDisable(gl.GL_CULL_FACE)
        gl.glBindVertexArray(0)


class LineFigures:
    """The reference renderer of ``ENVIRONMENT.md`` ("20-bone line figures updated from numpy
    each frame, one VBO + glBufferSubData"): a calibration point for how fast this machine's
    llvmpipe is right now. ``draw_frame`` clears and draws every figure as 20 lines."""

    def __init__(self, skeleton, bones: int = 20):
        L = np.linalg.norm(skeleton.offsets, axis=1)
        js = np.flatnonzero(skeleton.parents >= 0)
        js = js[np.argsort(-L[js], kind="stable")][:bones]
        self.a, self.b = skeleton.parents[js], js
        self.prog = Program.from_files("line.vert", "line.frag", "line figures")
        self.vao = vertex_array()
        gl.glBindVertexArray(self.vao)
        self.buf = Buffer()
        self.buf.upload(np.zeros((2, 3), np.float32))
        float_attributes([(0, 3)], 3)
        gl.glBindVertexArray(0)

    def draw_frame(self, view, proj, width, height, positions) -> None:
        P = np.asarray(positions, dtype=np.float32)
        seg = np.empty((len(P), len(self.a), 2, 3), dtype=np.float32)
        seg[:, :, 0] = P[:, self.a]
        seg[:, :, 1] = P[:, self.b]
        gl.glViewport(0, 0, width, height)
        gl.glClearColor(0.8, 0.8, 0.8, 1.0)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT)
        p = self.prog.use()
        p.set(u_vp=proj @ view)
        gl.glBindVertexArray(self.vao)
        self.buf.upload(seg.reshape(-1, 3))
        gl.glDrawArrays(gl.GL_LINES, 0, seg.shape[0] * seg.shape[1] * 2)
        gl.glBindVertexArray(0)
