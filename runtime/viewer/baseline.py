"""Baselines for ``bench/viewer.py``.

:class:`InstancedCapsules` is the conventional way to draw capsule-limbed crowds: one
instanced draw of a real capsule mesh (:func:`meshes.capsule_mesh`, 8 sides), one instance per
bone of the full-detail bone set, per-instance endpoints, radius and colour via
``glVertexAttribDivisor``, per-pixel lighting. On a GPU this is fine; on llvmpipe
every instance costs a vertex-shading batch of its own (about 17 us each measured here), which
is why :class:`runtime.viewer.render.Renderer` draws ray-cast impostors pulled from texture
buffers instead. :class:`LineFigures` is the line-figure renderer whose frame rates
``ENVIRONMENT.md`` records for this kind of machine, a calibration of the machine's current speed.
Import only after :func:`runtime.viewer.headless.configure`.
"""
from __future__ import annotations

import numpy as np

from . import headless as _headless

_headless.ensure()
from pyglet import gl  # noqa: E402

from .meshes import FigureStyle, capsule_mesh, character_palette  # noqa: E402
from .render import _LIT_FS, LIGHT_DIR, SKY_HORIZON, _attribs, _Buffer, _Program, _vao  # noqa: E402

__all__ = ["InstancedCapsules", "LineFigures"]

_VS = """#version 330 core
layout(location = 0) in vec4 a_vert;     // unit normal in the bone frame (u, v, w), end s
layout(location = 1) in vec3 i_p0;
layout(location = 2) in vec3 i_p1;
layout(location = 3) in vec4 i_style;    // radius, r, g, b
uniform mat4 u_vp;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_color;
void main() {
    vec3 axis = i_p1 - i_p0;
    float len = length(axis);
    vec3 W = len > 1e-6 ? axis / len : vec3(0.0, 1.0, 0.0);
    vec3 h = abs(W.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 U = normalize(cross(h, W));
    vec3 V = cross(W, U);
    vec3 n = a_vert.x * U + a_vert.y * V + a_vert.z * W;
    vec3 p = mix(i_p0, i_p1, a_vert.w) + i_style.x * n;
    v_pos = p;
    v_normal = n;
    v_color = i_style.yzw;
    gl_Position = u_vp * vec4(p, 1.0);
}
"""


class InstancedCapsules:
    def __init__(self, skeleton, sides: int = 8, rings: int = 1):
        self.style = FigureStyle.for_skeleton(skeleton)
        self.prog = _Program(_VS, _LIT_FS, "instanced capsules")
        verts, idx = capsule_mesh(sides, rings)
        self.index_count = len(idx)
        self.vao = _vao()
        gl.glBindVertexArray(self.vao)
        self.mesh = _Buffer(usage=gl.GL_STATIC_DRAW)
        self.mesh.upload(verts)
        _attribs([(0, 4)], 4)
        self.index = _Buffer(gl.GL_ELEMENT_ARRAY_BUFFER, gl.GL_STATIC_DRAW)
        self.index.upload(idx.astype(np.uint32).view(np.float32))   # raw bytes
        self.inst = _Buffer()
        self.inst.upload(np.zeros((1, 10), np.float32))
        _attribs([(1, 3), (2, 3), (3, 4)], 10)
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


_LINE_VS = """#version 330 core
layout(location = 0) in vec3 a_pos;
uniform mat4 u_vp;
void main() { gl_Position = u_vp * vec4(a_pos, 1.0); }
"""
_LINE_FS = """#version 330 core
out vec4 frag;
void main() { frag = vec4(0.1, 0.1, 0.1, 1.0); }
"""


class LineFigures:
    """The reference renderer of ``ENVIRONMENT.md`` ("20-bone line figures updated from numpy
    each frame, one VBO + glBufferSubData"): a calibration point for how fast this machine's
    llvmpipe is right now. ``draw_frame`` clears and draws every figure as 20 lines."""

    def __init__(self, skeleton, bones: int = 20):
        L = np.linalg.norm(skeleton.offsets, axis=1)
        js = np.flatnonzero(skeleton.parents >= 0)
        js = js[np.argsort(-L[js], kind="stable")][:bones]
        self.a, self.b = skeleton.parents[js], js
        self.prog = _Program(_LINE_VS, _LINE_FS, "line figures")
        self.vao = _vao()
        gl.glBindVertexArray(self.vao)
        self.buf = _Buffer()
        self.buf.upload(np.zeros((2, 3), np.float32))
        _attribs([(0, 3)], 3)
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
