"""The viewer's light and colours (numpy only, no GL): a warm key light from above, sky and
ground colours, and the fog that fades everything into the horizon colour.

The shaders light with a key light (``LIGHT_DIR``), a sky/ground hemisphere ambient, a little
specular and rim light (``shaders/shade.glsl``), and fog towards ``SKY_HORIZON`` between two
distances from the eye that grow with the camera's distance from the world's centre
(:func:`fog_range`).
"""
from __future__ import annotations

import numpy as np

__all__ = ["SKY_HORIZON", "SKY_ZENITH", "GROUND", "PLAZA", "LIGHT_DIR", "fog_range", "shade_uniforms"]

SKY_HORIZON = (0.80, 0.85, 0.90)
SKY_ZENITH = (0.42, 0.60, 0.86)
GROUND = (0.50, 0.52, 0.49)
PLAZA = (0.68, 0.66, 0.62)
LIGHT_DIR = np.array([0.45, 0.80, 0.35]) / np.linalg.norm([0.45, 0.80, 0.35])


def fog_range(dist: float) -> tuple[float, float]:
    """Fog start and end (metres from the eye) for an eye ``dist`` metres from the world's
    centre: at least 70 and 220 m, and 2.5 and 7 times ``dist``."""
    return (max(70.0, dist * 2.5), max(220.0, dist * 7.0))


def shade_uniforms(fog) -> dict:
    """The uniforms of ``shade.glsl`` in world space: light, up, fog colour and range."""
    return dict(u_light=tuple(LIGHT_DIR), u_up=(0.0, 1.0, 0.0), u_fog_color=SKY_HORIZON, u_fog=fog)
