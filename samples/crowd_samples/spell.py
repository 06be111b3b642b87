"""Experiment 2 (Sung, Kovar and Gleicher 2005, Figure 6): spell a word.

Block letters are polylines in letter units (width 4, height 6; v up). Every vertex is a
position; strokes after a letter's first share their end vertices with it.
"""
from __future__ import annotations

import math

import numpy as np

from .geometry import position
from .scenario_file import readme_text, write_sample

__all__ = ["LETTERS", "letter_points", "SPELL_STAGGER", "spell_scenario", "build"]

LETTERS = {
    "S": [[(4, 6), (0, 6), (0, 3), (4, 3), (4, 0), (0, 0)]],
    "C": [[(4, 6), (0, 6), (0, 0), (4, 0)]],
    "A": [[(0, 0), (0, 2.6), (0, 6), (4, 6), (4, 2.6), (4, 0)], [(0, 2.6), (4, 2.6)]],
    "O": [[(0, 0), (0, 6), (4, 6), (4, 0), (0, 0)]],
    "W": [[(0, 6), (0, 0), (2, 2), (4, 0), (4, 6)]],
    "D": [[(0, 0), (0, 6), (3, 6), (4, 5), (4, 1), (3, 0), (0, 0)]],
}


def _segments(word: str, scale: float, gap: float):
    segs = []                                   # (a, b) in metres, x right, v up
    x0 = 0.0
    for ch in word:
        for poly in LETTERS[ch]:
            poly = np.asarray(poly, float) * scale + [x0, 0.0]
            segs += list(zip(poly[:-1], poly[1:]))
        x0 += 4 * scale + gap
    return segs


def _points(segs, counts):
    pts = []
    for (a, b), n in zip(segs, counts):
        for k in range(n + 1):
            p = a + (b - a) * k / n
            if all(abs(p[0] - q[0]) + abs(p[1] - q[1]) > 1e-9 for q in pts):
                pts.append(p)
    return np.array(pts)


def letter_points(word: str, n: int, spacing: float, gap: float = 2.0) -> np.ndarray:
    """Exactly ``n`` positions (x, z) spelling ``word`` on the ground, consecutive points along
    a stroke at least ``spacing`` apart: x to the right, the letters' up direction is -Z (away
    from a camera on +Z), centred on x = 0 with the bottom of the letters on z = 0. The letter
    scale is the smallest whose strokes hold ``n`` points; segments are then split evenly,
    the most crowded ones losing a point until exactly ``n`` remain."""
    missing = sorted(set(word) - set(LETTERS))
    if missing:
        raise ValueError(f"no strokes for letters {missing} (known: {''.join(sorted(LETTERS))})")
    for scale in np.arange(0.5, 5.0, 0.01):
        segs = _segments(word, float(scale), gap)
        lens = np.array([np.hypot(*(b - a)) for a, b in segs])
        counts = np.maximum(1, np.floor(lens / spacing + 1e-9).astype(int))
        pts = _points(segs, counts)
        if len(pts) >= n:
            break
    else:
        raise ValueError(f"cannot place {n} points along {word!r}")
    while len(pts) > n:
        can = counts > 1
        if not can.any():
            raise ValueError(f"cannot place exactly {n} points along {word!r}")
        k = int(np.argmin(np.where(can, lens / counts, np.inf)))
        counts[k] -= 1
        pts = _points(segs, counts)
    if len(pts) != n:
        raise ValueError(f"cannot place exactly {n} points along {word!r}")
    pts = np.stack([pts[:, 0] - (pts[:, 0].min() + pts[:, 0].max()) / 2, -pts[:, 1]], axis=1)
    return pts - [0.0, pts[:, 1].max()]


SPELL_STAGGER = 3.0         # s between the front row's arrival window and the back row's


def spell_scenario(word: str = "SCA", n: int = 70, spacing: float = 1.6, seed: int = 0, gap: float = 2.0) -> dict:
    """``n`` characters start in a grid 5 m behind the word (spacing 2.0 x 2.2 m), walk to the
    letter points and arrive facing the camera (+Z), in a 1 s window that opens at 17 s for the
    front row of the word and ``SPELL_STAGGER`` s later for the back row (linear in depth). The letter scale is the
    smallest that gives exactly ``n`` points at least ``spacing`` apart along the strokes.
    Starts are assigned to points by minimum total squared distance (no crossing paths in
    depth: the back of the grid takes the far side of the letters)."""
    from scipy.optimize import linear_sum_assignment
    pts = letter_points(word, n, spacing, gap)
    cols = 14
    rows = int(math.ceil(n / cols))
    gx, gz = np.meshgrid((np.arange(cols) - (cols - 1) / 2) * 2.0, pts[:, 1].min() - 5.0 - np.arange(rows) * 2.2)
    starts = np.stack([gx.ravel(), gz.ravel()], axis=1)[:n]
    cost = ((starts[:, None, :] - pts[None, :, :]) ** 2).sum(-1)
    _, assign = linear_sum_assignment(cost)
    order = np.argsort(-pts[assign, 1], kind="stable")    # nearest the camera planned first
    zt = pts[:, 1]
    chars = []
    for k, i in enumerate(order):
        g = pts[assign[i]]
        # the word fills from the front: a point's window opens SPELL_STAGGER s later from the
        # front row to the back one, so a character filing into a stroke behind another
        # arrives after it has stopped rather than on its heels
        t0 = round(17.0 + SPELL_STAGGER * float((zt.max() - g[1]) / max(np.ptp(zt), 1e-9)), 2)
        chars.append({"name": f"c{k + 1:02d}",
                      "start": {"position": position(starts[i]), "heading": 0.0, "pose": "stand"},
                      "goal": [{"position": position(g), "heading": 0.0, "pose": "stand", "time": [t0, t0 + 1.0]}]})
    return {"name": "spell70", "description": f"Experiment 2 (Sung, Kovar and Gleicher 2005, Figure 6): {n} characters walk to "
            f"points spelling {word}, front row first, and face the camera (+Z)",
            "library": "default", "duration": 20.0 + SPELL_STAGGER, "seed": seed, "character": chars}

def build(folder):
    """Write the ``spell70`` sample into ``folder``."""
    write_sample(folder, spell_scenario(), readme_text("spell70"))
