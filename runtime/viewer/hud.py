"""Heads-up display: a translucent panel with frame and scene statistics (top left) and a key
help line (bottom). pyglet text in one batch; drawn after the 3D scene with depth testing off,
using pyglet's own window projection (the 3D renderer never touches it)."""
from __future__ import annotations

from . import headless

headless.ensure()
import pyglet  # noqa: E402
from pyglet import shapes  # noqa: E402

__all__ = ["Hud", "format_stats"]

HELP = ("LMB: select / orbit   MMB, Shift+LMB: pan   wheel: zoom   RMB: send selected there   "
        "P: plaza  T: tiled zone  B: birds  R: follow someone   Space: pause  .: step  +/-: speed  "
        "F: follow  H: HUD  Esc: quit")


def _fmt(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.2f}" if abs(v) < 100 else f"{v:.0f}"
    return str(v)


def format_stats(viewer_stats: dict, scene_stats: dict) -> list[str]:
    """Lines of the panel: the viewer's own figures first, then whatever the scene reports."""
    lines = ["  ".join(f"{k} {_fmt(v)}" for k, v in viewer_stats.items())]
    items = [f"{k} {_fmt(v)}" for k, v in scene_stats.items()]
    for i in range(0, len(items), 4):
        lines.append("  ".join(items[i:i + 4]))
    return lines


class Hud:
    def __init__(self, window, font_size: int = 11):
        self.window = window
        self.batch = pyglet.graphics.Batch()
        self.bg_group = pyglet.graphics.Group(order=0)
        self.fg_group = pyglet.graphics.Group(order=1)
        self.panel = shapes.Rectangle(8, 0, 10, 10, color=(18, 22, 30, 170), batch=self.batch, group=self.bg_group)
        self.label = pyglet.text.Label("", font_size=font_size, x=16, y=0, anchor_y="top", multiline=True,
                                       width=900, color=(240, 244, 250, 255), batch=self.batch,
                                       group=self.fg_group)
        self.help_bg = shapes.Rectangle(0, 0, 10, 22, color=(18, 22, 30, 140), batch=self.batch, group=self.bg_group)
        self.help = pyglet.text.Label(HELP, font_size=max(8, font_size - 2), x=10, y=6, color=(225, 230, 238, 255),
                                      batch=self.batch, group=self.fg_group)
        self.visible = True
        self._text = None

    def update(self, lines: list[str]) -> None:
        text = "\n".join(lines)
        w, h = self.window.get_size()
        if text != self._text:
            self.label.text = text
            self._text = text
        self.label.y = h - 12
        lw = min(self.label.content_width, w - 32)
        lh = self.label.content_height
        self.panel.x, self.panel.y = 8, h - 18 - lh
        self.panel.width, self.panel.height = lw + 16, lh + 12
        self.help_bg.width = w
        self.help.x = 10

    def rects(self) -> list[tuple[float, float, float, float]]:
        """Window rectangles (x, y, width, height) the HUD covers when visible."""
        if not self.visible:
            return []
        return [(self.panel.x, self.panel.y, self.panel.width, self.panel.height),
                (self.help_bg.x, self.help_bg.y, self.help_bg.width, self.help_bg.height)]

    def draw(self) -> None:
        if self.visible:
            self.batch.draw()
