"""Shared helpers of the viewer tests: a private Xvfb server and screenshot checks (pixels at
projected world positions against a bare frame of the same view)."""
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest


def xvfb_display():
    """Generator for a fixture: starts a private Xvfb (1280x720x24), yields its DISPLAY string,
    stops it afterwards. Skips when Xvfb is not installed."""
    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.skip("Xvfb is not installed (apt-get install -y xvfb)")
    r, wfd = os.pipe()
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen([exe, "-displayfd", str(wfd), "-screen", "0", "1280x720x24", "-nolisten", "tcp"],
                            pass_fds=(wfd,), stdout=subprocess.DEVNULL, stderr=log)
    os.close(wfd)
    try:
        buf, end = b"", time.monotonic() + 20.0      # the display number, up to its newline
        while not buf.endswith(b"\n"):
            ready, _, _ = select.select([r], [], [], max(0.0, end - time.monotonic()))
            chunk = os.read(r, 64) if ready else b""
            if not chunk:
                break
            buf += chunk
        line = buf.decode().strip()
        if not line:
            proc.kill()
            log.seek(0)
            pytest.fail(f"Xvfb did not report a display: {log.read().decode(errors='replace')[-2000:]}")
        yield f":{line}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        os.close(r)
        log.close()


def read_png(path):
    from pyglet.extlibs import png   # pure Python decoder: no GL, no display
    w, h, rows, _ = png.Reader(filename=str(path)).asRGBA8()
    return np.array([np.frombuffer(bytes(row), np.uint8) for row in rows]).reshape(h, w, 4)[..., :3].astype(int)


class Screenshot:
    """``shot.png``, ``bare.png`` (the same view without the scene) and ``frame.npz`` (viewport
    ``vp``, ``size``, ``joints``, optional ``hud`` rectangles) written by a viewer run."""

    def __init__(self, out: Path):
        self.shot, self.bare = read_png(out / "shot.png"), read_png(out / "bare.png")
        self.frame = np.load(out / "frame.npz")
        self.w, self.h = (int(v) for v in self.frame["size"])
        assert self.shot.shape == self.bare.shape == (self.h, self.w, 3)
        self.vp = self.frame["vp"]
        self.joints = self.frame["joints"]
        self.hud = self.frame["hud"] if "hud" in self.frame.files else np.zeros((0, 4))

    def project(self, pts):
        from runtime.viewer.camera import project
        return project(self.vp, np.asarray(pts, dtype=float), self.w, self.h)

    def usable(self, px, front, margin=3):
        """On screen (``margin`` pixels in) and outside the HUD's rectangles."""
        w, h = self.w, self.h
        ok = front & (px[:, 0] >= margin) & (px[:, 0] < w - margin) & (px[:, 1] >= margin) & (px[:, 1] < h - margin)
        for x, y, rw, rh in self.hud:
            ok &= ~((px[:, 0] >= x - 2) & (px[:, 0] <= x + rw + 2) & (px[:, 1] >= y - 2) & (px[:, 1] <= y + rh + 2))
        return ok

    def diff(self, px):
        """Largest colour difference (sum over RGB) in the 3x3 block around each pixel."""
        out = []
        for x, y in px:
            c, r = int(x), self.h - 1 - int(y)            # PNG rows run top to bottom
            a = self.shot[r - 1:r + 2, c - 1:c + 2]
            b = self.bare[r - 1:r + 2, c - 1:c + 2]
            out.append(int(np.abs(a - b).sum(axis=-1).max()))
        return np.array(out)

    def drawn_at(self, pts, what: str, min_visible: int) -> int:
        """Every visible one of ``pts`` (world, (n, 3)) differs from the bare frame; at least
        ``min_visible`` are on screen. Returns how many were."""
        px, front = self.project(pts)
        vis = self.usable(px, front)
        assert vis.sum() >= min_visible, f"only {vis.sum()} of {len(pts)} {what} on screen"
        d = self.diff(px[vis])
        assert (d > 40).all(), f"{what} not drawn at {px[vis][d <= 40].round(1).tolist()} (diffs {d[d <= 40]})"
        return int(vis.sum())

    def obstacles_drawn(self, env) -> None:
        """The middle of each obstacle footprint at half height (extruded 1 m by default)."""
        centres = [p.mean(axis=0) for p in env.polygons] + [c[:2] for c in env.circles]
        self.drawn_at(np.array([[c[0], 0.5, c[1]] for c in centres]), "obstacles", len(centres) - 1)

    def empty_ground_is_bare(self, env) -> None:
        """Control: ground far from characters, obstacles and markers looks like the bare frame."""
        rng = np.random.default_rng(0)
        x0, z0, x1, z1 = env.bounds(1.0)
        g = np.column_stack([rng.uniform(x0, x1, 600), rng.uniform(z0, z1, 600)])
        far = env.distance(g) > 1.0
        roots = self.joints[:, 0][:, [0, 2]]
        far &= np.min(np.hypot(*(g[:, None, :] - roots[None]).transpose(2, 0, 1)), axis=1) > 2.5
        mk = np.array([m.position for m in env.markers.values()])
        far &= np.min(np.hypot(*(g[:, None, :] - mk[None]).transpose(2, 0, 1)), axis=1) > 2.0
        for m in env.markers.values():
            if m.polygon is not None:
                lo, hi = m.polygon.min(axis=0) - 0.5, m.polygon.max(axis=0) + 0.5
                far &= ~np.all((g >= lo) & (g <= hi), axis=1)
        gp, gf = self.project(np.column_stack([g[:, 0], np.zeros(len(g)), g[:, 1]]))
        ok = far & self.usable(gp, gf)
        assert ok.sum() >= 20
        same = self.diff(gp[ok]) <= 24
        assert same.mean() >= 0.8, f"empty ground differs from the bare frame at {(~same).sum()} of {ok.sum()} points"
