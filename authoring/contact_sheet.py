"""Contact sheets: grids of poses rendered with numpy into a PNG (no imaging dependency).

Each cell shows one frame of a take as capsule figures (orthographic side or three-quarter
view, the figure re-centred on its root and turned to a fixed heading), the floor, any prop
of that frame (chair, box), and a caption (label, frame, time). Rasterisation is a signed
distance test per capsule over its bounding box with one pixel of anti-aliasing, drawn far
to near; text uses a built-in 5x7 bitmap font; the PNG is written with zlib + struct.

``python -m authoring.contact_sheet TAKE_DIR OUT.png`` renders a sheet of a take directory
(one row per activity); ``--walk-cycle`` a close-up of one walk cycle; ``--docs`` both in
one image (the committed ``docs/capture_contact_sheet.png``).
"""
from __future__ import annotations

import argparse
import json
import struct
import zlib
from pathlib import Path

import numpy as np

from runtime.motion.fk import end_site_positions

__all__ = ["write_png", "Canvas", "render_cells", "take_sheet", "walk_cycle_sheet", "docs_sheet"]

# ------------------------------------------------------------------------------------------
# PNG
# ------------------------------------------------------------------------------------------


def write_png(path, rgb: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 image as an 8-bit RGB PNG (atomic)."""
    from runtime.assets import atomic_write_bytes

    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    h, w, _ = rgb.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rgb.reshape(h, w * 3)], axis=1).tobytes()

    def chunk(tag, data):
        c = struct.pack(">I", len(data)) + tag + data
        return c + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))
    atomic_write_bytes(Path(path), png)


# ------------------------------------------------------------------------------------------
# 5x7 font
# ------------------------------------------------------------------------------------------
_FONT_SRC = {
    "A": "01110 10001 10001 11111 10001 10001 10001", "B": "11110 10001 10001 11110 10001 10001 11110",
    "C": "01110 10001 10000 10000 10000 10001 01110", "D": "11110 10001 10001 10001 10001 10001 11110",
    "E": "11111 10000 10000 11110 10000 10000 11111", "F": "11111 10000 10000 11110 10000 10000 10000",
    "G": "01110 10001 10000 10111 10001 10001 01111", "H": "10001 10001 10001 11111 10001 10001 10001",
    "I": "01110 00100 00100 00100 00100 00100 01110", "J": "00111 00010 00010 00010 00010 10010 01100",
    "K": "10001 10010 10100 11000 10100 10010 10001", "L": "10000 10000 10000 10000 10000 10000 11111",
    "M": "10001 11011 10101 10101 10001 10001 10001", "N": "10001 10001 11001 10101 10011 10001 10001",
    "O": "01110 10001 10001 10001 10001 10001 01110", "P": "11110 10001 10001 11110 10000 10000 10000",
    "Q": "01110 10001 10001 10001 10101 10010 01101", "R": "11110 10001 10001 11110 10100 10010 10001",
    "S": "01111 10000 10000 01110 00001 00001 11110", "T": "11111 00100 00100 00100 00100 00100 00100",
    "U": "10001 10001 10001 10001 10001 10001 01110", "V": "10001 10001 10001 10001 10001 01010 00100",
    "W": "10001 10001 10001 10101 10101 10101 01010", "X": "10001 10001 01010 00100 01010 10001 10001",
    "Y": "10001 10001 01010 00100 00100 00100 00100", "Z": "11111 00001 00010 00100 01000 10000 11111",
    "0": "01110 10001 10011 10101 11001 10001 01110", "1": "00100 01100 00100 00100 00100 00100 01110",
    "2": "01110 10001 00001 00010 00100 01000 11111", "3": "11111 00010 00100 00010 00001 10001 01110",
    "4": "00010 00110 01010 10010 11111 00010 00010", "5": "11111 10000 11110 00001 00001 10001 01110",
    "6": "00110 01000 10000 11110 10001 10001 01110", "7": "11111 00001 00010 00100 01000 01000 01000",
    "8": "01110 10001 10001 01110 10001 10001 01110", "9": "01110 10001 10001 01111 00001 00010 01100",
    " ": "00000 00000 00000 00000 00000 00000 00000", "_": "00000 00000 00000 00000 00000 00000 11111",
    "-": "00000 00000 00000 11111 00000 00000 00000", ".": "00000 00000 00000 00000 00000 01100 01100",
    ":": "00000 01100 01100 00000 01100 01100 00000", "/": "00001 00010 00010 00100 01000 01000 10000",
    "(": "00010 00100 01000 01000 01000 00100 00010", ")": "01000 00100 00010 00010 00010 00100 01000",
    "=": "00000 00000 11111 00000 11111 00000 00000", "+": "00000 00100 00100 11111 00100 00100 00000",
    ",": "00000 00000 00000 00000 01100 00100 01000", "%": "11000 11001 00010 00100 01000 10011 00011",
    "?": "01110 10001 00001 00010 00100 00000 00100",
}
_FONT = {k: np.array([[c == "1" for c in row] for row in v.split()], dtype=bool) for k, v in _FONT_SRC.items()}


# ------------------------------------------------------------------------------------------
# canvas
# ------------------------------------------------------------------------------------------
class Canvas:
    def __init__(self, h, w, bg=(250, 249, 246)):
        self.img = np.empty((h, w, 3), dtype=np.float64)
        self.img[:] = bg

    @property
    def shape(self):
        return self.img.shape[:2]

    def _blend(self, y0, y1, x0, x1, cov, color):
        if y1 <= y0 or x1 <= x0:
            return
        a = np.clip(cov, 0.0, 1.0)[..., None]
        self.img[y0:y1, x0:x1] = self.img[y0:y1, x0:x1] * (1 - a) + np.asarray(color, float) * a

    def capsule(self, p, q, r, color):
        """Anti-aliased capsule from p to q (pixel coordinates x, y) with radius r."""
        h, w = self.shape
        x0 = int(max(np.floor(min(p[0], q[0]) - r - 1), 0))
        x1 = int(min(np.ceil(max(p[0], q[0]) + r + 2), w))
        y0 = int(max(np.floor(min(p[1], q[1]) - r - 1), 0))
        y1 = int(min(np.ceil(max(p[1], q[1]) + r + 2), h))
        if x1 <= x0 or y1 <= y0:
            return
        ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float64)
        d = np.array(q, float) - np.array(p, float)
        L2 = float(d @ d)
        if L2 < 1e-12:
            t = np.zeros_like(xs)
        else:
            t = np.clip(((xs - p[0]) * d[0] + (ys - p[1]) * d[1]) / L2, 0.0, 1.0)
        dist = np.hypot(xs - (p[0] + t * d[0]), ys - (p[1] + t * d[1]))
        self._blend(y0, y1, x0, x1, r + 0.5 - dist, color)

    def disc(self, c, r, color):
        self.capsule(c, c, r, color)

    def polygon(self, pts, color, alpha=1.0):
        """Filled convex polygon (pixel coordinates), anti-aliased edges."""
        pts = np.asarray(pts, float)
        h, w = self.shape
        x0 = int(max(np.floor(pts[:, 0].min()) - 1, 0))
        x1 = int(min(np.ceil(pts[:, 0].max()) + 2, w))
        y0 = int(max(np.floor(pts[:, 1].min()) - 1, 0))
        y1 = int(min(np.ceil(pts[:, 1].max()) + 2, h))
        if x1 <= x0 or y1 <= y0:
            return
        ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float64)
        area = np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
        sgn = 1.0 if area > 0 else -1.0
        cov = np.full(xs.shape, np.inf)
        for i in range(len(pts)):
            a, b = pts[i], pts[(i + 1) % len(pts)]
            e = b - a
            n = np.hypot(*e)
            if n < 1e-9:
                continue
            sd = sgn * ((xs - a[0]) * e[1] - (ys - a[1]) * e[0]) / n    # inside is negative
            cov = np.minimum(cov, 0.5 - sd)
        self._blend(y0, y1, x0, x1, np.clip(cov, 0, 1) * alpha, color)

    def text(self, x, y, s, color=(40, 40, 40), scale=1):
        cx = x
        for ch in s.upper():
            g = _FONT.get(ch, _FONT["?"])
            gy, gx = np.nonzero(g)
            for yy, xx in zip(gy, gx):
                ya, xa = y + yy * scale, cx + xx * scale
                if 0 <= ya and ya + scale <= self.shape[0] and 0 <= xa and xa + scale <= self.shape[1]:
                    self.img[ya:ya + scale, xa:xa + scale] = color
            cx += 6 * scale

    def line(self, p, q, color, width=1.0):
        self.capsule(p, q, width / 2.0, color)

    def to_uint8(self):
        return np.clip(np.round(self.img), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------------------------------
# figures
# ------------------------------------------------------------------------------------------
LEFT = np.array([52, 101, 164])
RIGHT = np.array([204, 76, 56])
MID = np.array([96, 96, 104])
PROP = np.array([176, 140, 96])
CHAIR = np.array([140, 150, 160])


def _side_of(name: str) -> int:
    if name.startswith(("Left", "LHip", "LThumb")):
        return 0
    if name.startswith(("Right", "RHip", "RThumb")):
        return 1
    return 2


def _view_matrix(view: str):
    """Rows: camera right, camera up, towards the viewer (world re-centred, facing +Z)."""
    if view == "side":       # camera on the performer's right, looking at +X: +Z goes right
        d = np.array([-1.0, 0.0, 0.0])
    elif view == "front":
        d = np.array([0.0, 0.0, 1.0])
    else:                    # three-quarter: front-right, slightly from above
        d = np.array([-0.75, 0.32, 0.9])
    d = d / np.linalg.norm(d)
    look = -d
    right = np.cross(look, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, look)
    return np.stack([right, up, d])


def _box_corners(center, size, heading):
    w, h, d = size
    xs = np.array([-w, w]) / 2
    ys = np.array([-h, h]) / 2
    zs = np.array([-d, d]) / 2
    c = np.array([[x, y, z] for x in xs for y in ys for z in zs])
    R = np.array([[np.cos(heading), 0, np.sin(heading)], [0, 1, 0], [-np.sin(heading), 0, np.cos(heading)]])
    return c @ R.T + center


_BOX_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def render_cells(clip, cells, cols, cell_w=150, cell_h=210, view="side", props=(), title=None,
                 metres_per_px=None, row_heading=True):
    """Render a grid. ``cells`` = [(frame, caption)]; ``props`` = label-sidecar props.
    Each figure is re-centred on its root; with ``row_heading`` the view turns with the
    heading of the first frame of the row (so turns show), else with each frame's own."""
    sk = clip.skeleton
    gr, gp = clip.fk()
    ends = end_site_positions(sk, gr, gp)
    names = sk.names
    parents = sk.parents
    heading = clip.world_heading()
    root = gp[:, 0]
    rows = int(np.ceil(len(cells) / cols))
    top = 26 if title else 4
    cv = Canvas(top + rows * cell_h + 4, cols * cell_w + 8)
    if title:
        cv.text(8, 8, title, (20, 20, 20), scale=2)
    mpp = metres_per_px or 1.95 / (cell_h - 30)
    M = _view_matrix(view)
    for ci, (f, caption) in enumerate(cells):
        r, cidx = divmod(ci, cols)
        ox = 4 + cidx * cell_w
        oy = top + r * cell_h
        cv.polygon([(ox + 2, oy + 2), (ox + cell_w - 2, oy + 2), (ox + cell_w - 2, oy + cell_h - 2),
                    (ox + 2, oy + cell_h - 2)], (255, 255, 255))
        th = heading[cells[r * cols][0]] if row_heading else heading[f]
        c0 = np.array([root[f, 0], 0.0, root[f, 2]])
        Rinv = np.array([[np.cos(-th), 0, np.sin(-th)], [0, 1, 0], [-np.sin(-th), 0, np.cos(-th)]])

        def cam(p):
            q = (np.asarray(p) - c0) @ Rinv.T
            return q @ M.T

        ground_y = oy + cell_h - 22
        cx = ox + cell_w / 2

        def px(q):
            return np.stack([cx + q[..., 0] / mpp, ground_y - q[..., 1] / mpp], axis=-1)

        cv.line((ox + 6, ground_y), (ox + cell_w - 6, ground_y), (200, 200, 196), 2.0)
        prims = []      # (depth, kind, data)
        # props
        for p in props:
            if not (p["start"] <= f < p["end"]):
                continue
            if p["kind"] == "chair":
                seat_h = p["seat_height"]
                w, _, d = p["size"]
                ctr = np.array([p["x"], seat_h - 0.02, p["z"]])
                corners = _box_corners(ctr, (w, 0.04, d), p["heading"])
                back_c = ctr + np.array([0, 0.25, 0]) + _rot(p["heading"]) @ np.array([0, 0, -d / 2])
                back = _box_corners(back_c, (w, 0.5, 0.03), p["heading"])
                for cs, col in ((corners, CHAIR), (back, CHAIR)):
                    q = cam(cs)
                    for face in _BOX_FACES:
                        prims.append((q[list(face), 2].mean(), "poly", (px(q[list(face)]), col)))
                for lx in (-1, 1):
                    for lz in (-1, 1):
                        top_ = ctr + _rot(p["heading"]) @ np.array([lx * (w / 2 - 0.03), 0, lz * (d / 2 - 0.03)])
                        bot = top_.copy()
                        bot[1] = 0.0
                        q = cam(np.stack([top_, bot]))
                        prims.append((q[:, 2].mean(), "cap", (px(q[0]), px(q[1]), 1.6, CHAIR * 0.8)))
            elif p["kind"] == "box":
                size = p["size"] if "size" in p else (0.4, 0.3, 0.3)
                if p.get("carried"):
                    lw = gp[f, names.index("LeftHand")]
                    rw = gp[f, names.index("RightHand")]
                    dy, dz = p.get("hold_offset", (-0.1, 0.02))
                    ctr = 0.5 * (lw + rw) + _rot(heading[f]) @ np.array([0.0, dy, dz])
                    hd = heading[f]
                else:
                    ctr = np.array([p["x"], size[1] / 2, p["z"]])
                    hd = p["heading"]
                q = cam(_box_corners(ctr, size, hd))
                for face in _BOX_FACES:
                    shade = 0.8 + 0.2 * (face[0] % 2)
                    prims.append((q[list(face), 2].mean(), "poly", (px(q[list(face)]), PROP * shade)))
        # bones
        P = cam(gp[f])
        E = cam(ends[f])
        for j in range(1, len(names)):
            a, b = P[parents[j]], P[j]
            if np.linalg.norm(gp[f, j] - gp[f, parents[j]]) < 1e-6:
                continue
            col = (LEFT, RIGHT, MID)[_side_of(names[j])]
            rad = 3.4 if names[j] in ("LeftLeg", "RightLeg", "LeftUpLeg", "RightUpLeg", "Spine", "Spine1",
                                      "LeftFoot", "RightFoot") else 2.6
            if names[j] in ("Spine", "Spine1", "Neck"):
                rad = 5.0
            prims.append(((a[2] + b[2]) / 2, "cap", (px(a), px(b), rad, col)))
        for (j, _), e in zip(sk.end_sites, E):
            col = (LEFT, RIGHT, MID)[_side_of(names[j])]
            if names[j] == "Head":
                hc = 0.5 * (P[j] + e)
                prims.append((hc[2], "disc", (px(hc), 0.105 / mpp, MID)))
            elif "Toe" in names[j]:
                prims.append((e[2], "cap", (px(P[j]), px(e), 2.6, col)))
        prims.sort(key=lambda t: t[0])
        shade_d = np.array([t[0] for t in prims])
        lo, hi = (shade_d.min(), shade_d.max()) if len(shade_d) else (0, 1)
        for d, kind, data in prims:
            k = 0.75 + 0.25 * (d - lo) / max(hi - lo, 1e-6)
            if kind == "cap":
                cv.capsule(data[0], data[1], data[2], np.asarray(data[3]) * k + 255 * (1 - k) * 0.3)
            elif kind == "disc":
                cv.disc(data[0], data[1], np.asarray(data[2]) * k + 255 * (1 - k) * 0.3)
            else:
                cv.polygon(data[0], data[1], alpha=0.9)
        cv.text(int(ox + 6), int(oy + 6), caption[:22], (30, 30, 30))
        cv.text(int(ox + 6), int(oy + cell_h - 14), f"F{f} {f / clip.fps:.2f}S", (120, 120, 120))
    return cv.to_uint8()


def _rot(h):
    return np.array([[np.cos(h), 0, np.sin(h)], [0, 1, 0], [-np.sin(h), 0, np.cos(h)]])


# ------------------------------------------------------------------------------------------
# sheets of takes
# ------------------------------------------------------------------------------------------
def _load(take_bvh):
    from authoring.bvh import read_bvh

    take_bvh = Path(take_bvh)
    clip = read_bvh(take_bvh, drop_first_frame=False).clip
    lab_path = take_bvh.with_name(take_bvh.name[:-4] + ".labels.json")
    labels = json.loads(lab_path.read_text()) if lab_path.exists() else {"segments": [], "props": []}
    return clip, labels


ACTIVITY_ORDER = ("start", "walk", "stop", "idle", "turn", "sit_down", "sit", "stand_up",
                  "pick_up", "carry", "put_down")


def _activity_cells(segs, order, per_row):
    """Cells of one row per label in ``order`` that occurs in ``segs``: ``per_row`` frames
    spread over the longest of its first four occurrences (the one that shows the most)."""
    cells = []
    for lab in order:
        occ = [s for s in segs if s[2] == lab]
        if not occ:
            continue
        a, b, _ = max(occ[:4], key=lambda s: s[1] - s[0])
        fr = np.linspace(a, b - 1, per_row).round().astype(int)
        cells += [(int(f), lab if i == 0 else "") for i, f in enumerate(fr)]
    return cells


def take_sheet(take_bvh, out_png, per_row=8, view="3q", order=None):
    """One row per activity (its first occurrence; sit_down -> stand_up and pick_up ->
    put_down shown in sequence), ``per_row`` frames spread over the segment."""
    clip, labels = _load(take_bvh)
    cells = _activity_cells(labels["segments"], order or ACTIVITY_ORDER, per_row)
    img = render_cells(clip, cells, per_row, view=view, props=labels.get("props", []),
                       title=f"crowdweave procedural capture - {Path(take_bvh).name} - {view} view")
    write_png(out_png, img)
    return out_png


def _walk_cycle_cells(clip, labels, n):
    """Frames of one gait cycle from a left heel-strike hub that starts a walk edge."""
    segs = labels["segments"]
    starts = {a: b for a, b, lab in segs if lab == "walk"}
    hubs = [f for f, h in labels.get("hubs", []) if h == "walk_l" and f in starts]
    cycle = int(round(2.0 / (1.0 + 0.65 * 1.3) * clip.fps))     # two steps at the hub speed
    good = [f for f in hubs if starts[f] - f >= cycle] or hubs
    if good:
        a = good[0]
    else:
        walks = [s for s in segs if s[2] == "walk"] or [[0, clip.num_frames, ""]]
        a = max(walks, key=lambda s: s[1] - s[0])[0]
    fr = np.linspace(a, min(a + cycle, clip.num_frames - 1), n).round().astype(int)
    return [(int(f), f"{100 * i // (n - 1)}%") for i, f in enumerate(fr)]


def walk_cycle_sheet(take_bvh, out_png, n=10, view="side"):
    """Close-up of one gait cycle (left heel strike to left heel strike)."""
    clip, labels = _load(take_bvh)
    img = render_cells(clip, _walk_cycle_cells(clip, labels, n), n, cell_w=130, cell_h=240, view=view,
                       title=f"one walk cycle (left heel strike to left heel strike) - {view} view")
    write_png(out_png, img)
    return out_png


def docs_sheet(take_bvh, out_png, per_row=8):
    """The committed contact sheet: one row per activity (three-quarter view) with a
    side-view close-up of one walk cycle underneath."""
    clip, labels = _load(take_bvh)
    cells = _activity_cells(labels["segments"], ACTIVITY_ORDER, per_row)
    top = render_cells(clip, cells, per_row, view="3q", props=labels.get("props", []),
                       title=f"crowdweave procedural capture - {Path(take_bvh).name} - 3/4 view")
    cyc = render_cells(clip, _walk_cycle_cells(clip, labels, 10), 10, cell_w=top.shape[1] // 10 - 1,
                       cell_h=250, view="side",
                       title="one walk cycle at 1.3 m/s, left heel strike to left heel strike - side view")
    w = max(top.shape[1], cyc.shape[1])
    pad = lambda im: np.concatenate([im, np.full((im.shape[0], w - im.shape[1], 3), 250, np.uint8)], axis=1)
    write_png(out_png, np.concatenate([pad(top), pad(cyc)], axis=0))
    return out_png


def main(argv=None):
    ap = argparse.ArgumentParser(description="render a contact sheet of a generated take")
    ap.add_argument("take", help="take directory (uses take_000.bvh) or a .bvh file")
    ap.add_argument("out", help="output PNG")
    ap.add_argument("--view", default="3q", choices=["side", "3q", "front"])
    ap.add_argument("--walk-cycle", action="store_true", help="close-up of one walk cycle only")
    ap.add_argument("--docs", action="store_true", help="activity rows (3/4 view) + walk cycle (side view)")
    args = ap.parse_args(argv)
    p = Path(args.take)
    if p.is_dir():
        p = p / "take_000.bvh"
    if args.docs:
        docs_sheet(p, args.out)
    elif args.walk_cycle:
        walk_cycle_sheet(p, args.out, view=args.view)
    else:
        take_sheet(p, args.out, view=args.view)
    print(args.out)


if __name__ == "__main__":
    main()
