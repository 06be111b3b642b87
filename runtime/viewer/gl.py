"""Thin wrappers over raw OpenGL 3.3 core (pyglet's bindings) for the viewer's renderers:
shader sources, linked programs with their uniforms, vertex buffers, buffer textures and
vertex arrays of interleaved floats.

Raw GL rather than pyglet's ``ShaderProgram``, which does not know ``samplerBuffer`` uniforms.
Import only after :func:`runtime.viewer.headless.configure` (pyglet's backend is chosen when
``pyglet.gl`` loads).

Shaders are package data, ``runtime/viewer/shaders/*.{vert,frag,glsl}``. GLSL has no include:
:func:`shader_source` replaces a line ``#include "name.glsl"`` with that file's text and can add
``#define`` lines after the ``#version`` line (one file, two variants).
"""
from __future__ import annotations

import ctypes
from functools import cache
from importlib import resources

import numpy as np

from . import headless

headless.ensure()                       # pyglet's backend must be chosen before pyglet.gl loads
from pyglet import gl  # noqa: E402

__all__ = ["shader_source", "Program", "Buffer", "TextureBuffer", "Mesh", "vertex_array", "float_attributes"]

_INCLUDE = "#include "


@cache
def _shader_file(name: str) -> str:
    return resources.files(__package__).joinpath("shaders", name).read_text(encoding="utf-8")


def shader_source(name: str, defines: tuple[str, ...] = ()) -> str:
    """The GLSL source of ``shaders/<name>``, includes expanded, ``#define D`` for each of
    ``defines`` inserted after the first (``#version``) line."""
    out = []
    for line in _shader_file(name).splitlines(keepends=True):
        if line.startswith(_INCLUDE):
            out.append(_shader_file(line[len(_INCLUDE):].strip().strip('"')))
        else:
            out.append(line)
    if defines:
        out[1:1] = [f"#define {d}\n" for d in defines]
    return "".join(out)


class Program:
    """A linked GL program with cached uniform locations.

    Args:
        vs, fs: vertex and fragment shader sources (see :func:`shader_source`).
        name: for error messages; a failed compile or link raises RuntimeError with GL's log.
    """

    def __init__(self, vs: str, fs: str, name: str):
        self.name = name
        self.id = gl.glCreateProgram()
        shaders = []
        for src, kind in ((vs, gl.GL_VERTEX_SHADER), (fs, gl.GL_FRAGMENT_SHADER)):
            sh = gl.glCreateShader(kind)
            b = src.encode()
            buf = ctypes.create_string_buffer(b)
            ptr = ctypes.cast(ctypes.pointer(ctypes.pointer(buf)), ctypes.POINTER(ctypes.POINTER(gl.GLchar)))
            gl.glShaderSource(sh, 1, ptr, None)
            gl.glCompileShader(sh)
            ok = gl.GLint()
            gl.glGetShaderiv(sh, gl.GL_COMPILE_STATUS, ctypes.byref(ok))
            if not ok.value:
                raise RuntimeError(f"{name}: shader compile failed: {self._log(sh, True)}")
            gl.glAttachShader(self.id, sh)
            shaders.append(sh)
        gl.glLinkProgram(self.id)
        ok = gl.GLint()
        gl.glGetProgramiv(self.id, gl.GL_LINK_STATUS, ctypes.byref(ok))
        if not ok.value:
            raise RuntimeError(f"{name}: program link failed: {self._log(self.id, False)}")
        for sh in shaders:
            gl.glDetachShader(self.id, sh)
            gl.glDeleteShader(sh)
        self._loc = {}

    @classmethod
    def from_files(cls, vs: str, fs: str, name: str, defines: tuple[str, ...] = ()) -> "Program":
        """A program from two shader files (``defines`` go to the vertex shader)."""
        return cls(shader_source(vs, defines), shader_source(fs), name)

    @staticmethod
    def _log(obj, shader: bool) -> str:
        n = gl.GLint()
        (gl.glGetShaderiv if shader else gl.glGetProgramiv)(obj, gl.GL_INFO_LOG_LENGTH, ctypes.byref(n))
        buf = ctypes.create_string_buffer(max(n.value, 1))
        (gl.glGetShaderInfoLog if shader else gl.glGetProgramInfoLog)(obj, max(n.value, 1), None, buf)
        return buf.value.decode(errors="replace")

    def loc(self, name: str) -> int:
        """The location of uniform ``name`` (-1 when the compiler optimised it away)."""
        if name not in self._loc:
            self._loc[name] = gl.glGetUniformLocation(self.id, name.encode())
        return self._loc[name]

    def use(self) -> "Program":
        gl.glUseProgram(self.id)
        return self

    def set(self, **values) -> None:
        """Set uniforms of the program in use: floats, vec2/3/4 tuples, 4x4 numpy matrices,
        ints (samplers)."""
        for k, v in values.items():
            loc = self.loc(k)
            if loc < 0:
                continue   # optimised away
            if isinstance(v, np.ndarray) and v.shape == (4, 4):
                arr = (gl.GLfloat * 16)(*np.asarray(v, dtype=np.float64).T.reshape(-1))
                gl.glUniformMatrix4fv(loc, 1, gl.GL_FALSE, arr)
            elif isinstance(v, int):
                gl.glUniform1i(loc, v)
            elif isinstance(v, float):
                gl.glUniform1f(loc, v)
            else:
                v = [float(x) for x in v]
                getattr(gl, f"glUniform{len(v)}f")(loc, *v)


class Buffer:
    """A GL buffer that grows by reallocation (by half again, at least) and is otherwise
    updated with ``glBufferSubData``.

    Args:
        target: the binding point, e.g. ``GL_ARRAY_BUFFER``, ``GL_ELEMENT_ARRAY_BUFFER``.
        usage: the usage hint given to ``glBufferData``.
    """

    def __init__(self, target=gl.GL_ARRAY_BUFFER, usage=gl.GL_DYNAMIC_DRAW):
        self.id = gl.GLuint()
        gl.glGenBuffers(1, ctypes.byref(self.id))
        self.target = target
        self.usage = usage
        self.capacity = 0

    def upload(self, data: np.ndarray) -> None:
        """Bind the buffer and copy ``data`` (converted to float32) to its start."""
        data = np.ascontiguousarray(data, dtype=np.float32)
        gl.glBindBuffer(self.target, self.id)
        n = data.nbytes
        if n > self.capacity or self.capacity == 0:
            cap = max(n, int(self.capacity * 1.5), 64)
            gl.glBufferData(self.target, cap, None, self.usage)
            self.capacity = cap
        if n:
            gl.glBufferSubData(self.target, 0, n, data.ctypes.data_as(ctypes.c_void_p))


class TextureBuffer:
    """A buffer texture (``samplerBuffer``) over a :class:`Buffer`.

    Args:
        fmt: the texel format, e.g. ``GL_RGB32F``.
    """

    def __init__(self, fmt):
        self.buffer = Buffer(gl.GL_TEXTURE_BUFFER)
        self.tex = gl.GLuint()
        gl.glGenTextures(1, ctypes.byref(self.tex))
        self.fmt = fmt
        self._bound_cap = -1

    def upload(self, data: np.ndarray) -> None:
        self.buffer.upload(data)
        if self.buffer.capacity != self._bound_cap:   # (re)attach after reallocation
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, self.tex)
            gl.glTexBuffer(gl.GL_TEXTURE_BUFFER, self.fmt, self.buffer.id)
            gl.glBindTexture(gl.GL_TEXTURE_BUFFER, 0)
            self._bound_cap = self.buffer.capacity

    def bind(self, unit: int) -> None:
        """Bind the texture to texture unit ``unit`` (and leave that unit active)."""
        gl.glActiveTexture(gl.GL_TEXTURE0 + unit)
        gl.glBindTexture(gl.GL_TEXTURE_BUFFER, self.tex)


def vertex_array():
    """A new vertex array object (its GLuint name)."""
    v = gl.GLuint()
    gl.glGenVertexArrays(1, ctypes.byref(v))
    return v


def float_attributes(layout, stride_floats: int) -> None:
    """Point the bound vertex array's attributes at the bound array buffer: float attributes
    ``[(location, size), ...]`` packed in that order, ``stride_floats`` floats per vertex."""
    off = 0
    for loc, size in layout:
        gl.glEnableVertexAttribArray(loc)
        gl.glVertexAttribPointer(loc, size, gl.GL_FLOAT, gl.GL_FALSE, stride_floats * 4, ctypes.c_void_p(off * 4))
        off += size


class Mesh:
    """A vertex array + vertex buffer of interleaved floats drawn as ``GL_TRIANGLES`` or
    ``GL_LINES``.

    Args:
        layout: ``[(location, size), ...]`` of the float attributes of one vertex.
        mode: the primitive drawn.
        usage: the buffer's usage hint.
    """

    def __init__(self, layout, mode=gl.GL_TRIANGLES, usage=gl.GL_DYNAMIC_DRAW):
        self.vao = vertex_array()
        self.stride = sum(s for _, s in layout)
        gl.glBindVertexArray(self.vao)
        self.buf = Buffer(usage=usage)
        self.buf.upload(np.zeros((1, self.stride), np.float32))
        float_attributes(layout, self.stride)
        gl.glBindVertexArray(0)
        self.mode = mode
        self.count = 0

    def upload(self, data: np.ndarray) -> None:
        """Replace the vertices by ``data`` (V, stride)."""
        data = np.asarray(data, dtype=np.float32).reshape(-1, self.stride)
        self.buf.upload(data if len(data) else np.zeros((1, self.stride), np.float32))
        self.count = len(data)

    def draw(self) -> None:
        if self.count:
            gl.glBindVertexArray(self.vao)
            gl.glDrawArrays(self.mode, 0, self.count)
