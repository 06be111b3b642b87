"""Recording what the viewer shows as an animated GIF (Pillow, loaded only when recording).

:class:`GifRecorder` keeps frames at a fixed rate of wall-clock time (``fps``), each scaled down
to ``width`` pixels wide, up to ``max_frames`` (the clip's memory stays bounded: 150 frames of
640 x 360 are about 100 MB as RGB, less once quantized); :meth:`save` writes the GIF atomically.
The viewer hands it each frame it draws (:meth:`runtime.viewer.window.Viewer.run` ``record=``).
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..assets import atomic_write_bytes

__all__ = ["GifRecorder"]


class GifRecorder:
    """Frames for a GIF: ``fps`` per second of the viewer's wall-clock time, ``width`` pixels wide,
    ``max_frames`` at most (later frames are dropped)."""

    def __init__(self, path, fps: float = 10.0, width: int = 640, max_frames: int = 150):
        if not (0 < fps <= 50) or width < 16 or max_frames < 1:
            raise ValueError(f"GifRecorder: fps in (0, 50], width >= 16, max_frames >= 1 (got {fps}, {width}, "
                             f"{max_frames})")
        self.path = Path(path)
        self.fps, self.width, self.max_frames = float(fps), int(width), int(max_frames)
        self.frames: list = []
        self._next = 0.0

    def due(self, t: float) -> bool:
        """Whether the frame drawn at wall-clock second ``t`` of the run should be kept."""
        return len(self.frames) < self.max_frames and t >= self._next

    def add(self, rgb: np.ndarray, t: float) -> None:
        """Keep frame ``rgb`` (H, W, 3) uint8, top row first, drawn at second ``t``."""
        from PIL import Image
        img = Image.fromarray(np.ascontiguousarray(rgb))
        if img.width > self.width:
            img = img.resize((self.width, max(1, round(img.height * self.width / img.width))), Image.BILINEAR)
        self.frames.append(img.quantize(colors=255, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE))
        self._next = t + 1.0 / self.fps

    def save(self) -> str:
        """Write the GIF (looping, ``fps`` frames per second) atomically; returns its path."""
        if not self.frames:
            raise ValueError(f"{self.path}: no frames recorded")
        buf = io.BytesIO()
        self.frames[0].save(buf, format="GIF", save_all=True, append_images=self.frames[1:],
                            duration=round(1000.0 / self.fps), loop=0, optimize=False)
        atomic_write_bytes(self.path, buf.getvalue())
        return str(self.path)
