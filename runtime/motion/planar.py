"""Planar rigid maths on the ground plane: configurations (x, z, heading) and 2D vectors (x, z).

Conventions (metres, Y up): a heading ``h`` is the rotation about +Y, 0 facing +Z, so a local
vector ``(x, z)`` seen from a frame with heading ``h`` is, in the world,
``Ry(h) (x, z) = (cos h x + sin h z, -sin h x + cos h z)``.

Array functions broadcast over leading axes (``...``) and use numpy's ``cos``/``sin``; the
``*1`` / ``*_scalar`` variants do the same arithmetic on one configuration or one heading with
:mod:`math` (a numpy call costs microseconds; chained single compositions are common in the
planners). The two can differ in the last bit, so a caller keeps to one of them for a quantity
it compares or caches.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["TWO_PI", "wrap_angle", "compose", "compose1", "compose_inverse", "relative",
           "rotate_xz", "rotate_xz_scalar"]

TWO_PI = 2.0 * np.pi


def wrap_angle(a):
    """Wrap radians to [-pi, pi). Python numbers give a Python float, anything else an array
    of the input's floating type (float32 stays float32)."""
    if isinstance(a, (int, float)) and not isinstance(a, np.generic):
        return (a + math.pi) % TWO_PI - math.pi
    return (np.asarray(a) + np.pi) % TWO_PI - np.pi


def compose(c, d):
    """Planar rigid composition ``c o d`` of (..., 3) = (x, z, heading) arrays: ``d`` is
    expressed in ``c``'s frame."""
    h = c[..., 2]
    ch, sh = np.cos(h), np.sin(h)
    x = c[..., 0] + ch * d[..., 0] + sh * d[..., 1]
    out = np.empty(x.shape + (3,), dtype=np.result_type(x, h, d))
    out[..., 0] = x
    out[..., 1] = c[..., 1] - sh * d[..., 0] + ch * d[..., 1]
    out[..., 2] = h + d[..., 2]
    return out


def compose1(c, d):
    """:func:`compose` of one configuration and one displacement, each (3,), in scalar math."""
    h = float(c[2])
    ch, sh = math.cos(h), math.sin(h)
    d0, d1 = float(d[0]), float(d[1])
    return np.array((c[0] + ch * d0 + sh * d1, c[1] - sh * d0 + ch * d1, h + d[2]))


def compose_inverse(c_end, d):
    """The configuration before a displacement ``d`` that ends at ``c_end``: the ``c`` with
    ``compose(c, d) == c_end``."""
    h = c_end[..., 2] - d[..., 2]
    ch, sh = np.cos(h), np.sin(h)
    x = c_end[..., 0] - (ch * d[..., 0] + sh * d[..., 1])
    z = c_end[..., 1] - (-sh * d[..., 0] + ch * d[..., 1])
    return np.stack([x, z, h], axis=-1)


def relative(c0, c1):
    """The displacement ``d`` with ``compose(c0, d) == c1`` (headings not wrapped)."""
    dx, dz = c1[..., 0] - c0[..., 0], c1[..., 1] - c0[..., 1]
    ch, sh = np.cos(c0[..., 2]), np.sin(c0[..., 2])
    return np.stack([ch * dx - sh * dz, sh * dx + ch * dz, c1[..., 2] - c0[..., 2]], axis=-1)


def rotate_xz(xz: np.ndarray, heading) -> np.ndarray:
    """Rotate planar vectors (..., 2) = (x, z) by headings about +Y (radians, broadcast)."""
    c = np.cos(heading)
    s = np.sin(heading)
    x = xz[..., 0]
    z = xz[..., 1]
    return np.stack([c * x + s * z, -s * x + c * z], axis=-1)


def rotate_xz_scalar(xz, heading: float) -> np.ndarray:
    """:func:`rotate_xz` by one heading, with :mod:`math` (float64 result)."""
    c, s = math.cos(heading), math.sin(heading)
    out = np.empty_like(xz, dtype=np.float64)
    out[..., 0] = c * xz[..., 0] + s * xz[..., 1]
    out[..., 1] = c * xz[..., 1] - s * xz[..., 0]
    return out
