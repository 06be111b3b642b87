"""Geometry the viewer draws, built with numpy (no GL here): the unit capsule of the
instanced baseline, the flock agents' arrowhead, boxes, the static environment mesh (obstacle
footprints extruded to prisms, seats, boxes, spawn points and regions), copies of a mesh posed
on the ground, and the decals (blob shadows and rings). Characters' capsules are in
:mod:`runtime.viewer.figures`.
"""
from __future__ import annotations

import math
import numpy as np

__all__ = ["capsule_mesh", "arrow_mesh", "box_mesh", "environment_mesh", "split_floor", "floor_rects", "rect_minus",
           "line_pieces", "triangulate", "posed_copies", "decal_vertices", "CARDBOARD", "FLOOR_MAX_Y"]


# -- capsule -----------------------------------------------------------------------------------------

def capsule_mesh(sides: int = 8, cap_rings: int = 2):
    """Unit capsule for instancing: vertices (V, 4) ``(u, v, w, s)`` -- the outward unit normal
    in the bone's frame (``w`` along the bone) and ``s`` in {0, 1}, the end it hangs from; the
    shader places ``p = mix(p0, p1, s) + radius * (u U + v V + w W)``. Indices (I,) uint32,
    triangles wound counter-clockwise seen from outside."""
    rings = []   # (w, s) per ring; the poles are single vertices
    for k in range(1, cap_rings + 1):          # bottom cap, from the pole upwards
        lat = -math.pi / 2 + k * (math.pi / 2) / (cap_rings + 1)
        rings.append((lat, 0.0))
    rings.append((0.0, 0.0))
    rings.append((0.0, 1.0))
    for k in range(1, cap_rings + 1):
        lat = k * (math.pi / 2) / (cap_rings + 1)
        rings.append((lat, 1.0))
    th = 2 * math.pi * np.arange(sides) / sides
    verts = [(0.0, 0.0, -1.0, 0.0)]
    for lat, s in rings:
        c = math.cos(lat)
        for a in th:
            verts.append((c * math.cos(a), c * math.sin(a), math.sin(lat), s))
    verts.append((0.0, 0.0, 1.0, 1.0))
    verts = np.array(verts, dtype=np.float32)
    top = len(verts) - 1
    tris = []
    for i in range(sides):  # bottom fan
        tris.append((0, 1 + (i + 1) % sides, 1 + i))
    for r in range(len(rings) - 1):
        b0, b1 = 1 + r * sides, 1 + (r + 1) * sides
        for i in range(sides):
            j = (i + 1) % sides
            tris.append((b0 + i, b0 + j, b1 + j))
            tris.append((b0 + i, b1 + j, b1 + i))
    last = 1 + (len(rings) - 1) * sides
    for i in range(sides):
        tris.append((last + i, last + (i + 1) % sides, top))
    tris = np.array(tris, dtype=np.uint32)
    # make every triangle counter-clockwise seen from outside (checked on a sample capsule)
    p = verts[:, :3] * 0.5 + np.c_[np.zeros((len(verts), 2)), verts[:, 3]]
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    n = np.cross(b - a, c - a)
    out = verts[tris].mean(axis=1)[:, :3]
    flip = np.sum(n * out, axis=1) < 0
    tris[flip] = tris[flip][:, ::-1]
    return verts, tris.reshape(-1)


def arrow_mesh(length: float = 0.55, width: float = 0.36, height: float = 0.22):
    """Flat-shaded arrowhead pointing +Z (heading 0), base on the ground: (V, 6) position+normal."""
    tip = (0.0, 0.05, length * 0.6)
    bl = (-width / 2, 0.05, -length * 0.4)
    br = (width / 2, 0.05, -length * 0.4)
    notch = (0.0, 0.05, -length * 0.15)
    apex = (0.0, height, -length * 0.05)
    faces = [(tip, apex, bl), (tip, br, apex), (bl, apex, notch), (notch, apex, br), (tip, bl, notch), (tip, notch, br)]
    out = []
    for f in faces:
        a, b, c = (np.array(v) for v in f)
        n = np.cross(b - a, c - a)
        n = n / (np.linalg.norm(n) + 1e-12)
        for v in (a, b, c):
            out.append(np.r_[v, n])
    return np.array(out, dtype=np.float32)


def box_mesh(size: float = 0.4):
    """A cube of side ``size`` standing on the origin: (36, 6) position+normal."""
    mb = _MeshBuilder()
    mb.box((0.0, 0.0, 0.0), (size, size, size), 0.0, np.ones(3))
    return mb.build()[:, :6]


# -- polygons --------------------------------------------------------------------------------------

def _area2(p):
    return float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def triangulate(poly) -> np.ndarray:
    """Ear clipping of a simple polygon (K, 2) in either orientation: (K - 2, 3) vertex indices."""
    p = np.asarray(poly, dtype=np.float64)
    idx = list(range(len(p)))
    if _area2(p) < 0:
        idx.reverse()
    tris = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    guard = 0
    while len(idx) > 3 and guard < 10000:
        guard += 1
        m = len(idx)
        for k in range(m):
            i0, i1, i2 = idx[(k - 1) % m], idx[k], idx[(k + 1) % m]
            a, b, c = p[i0], p[i1], p[i2]
            if cross(a, b, c) <= 1e-14:
                continue
            ok = True
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                q = p[j]
                if cross(a, b, q) >= 0 and cross(b, c, q) >= 0 and cross(c, a, q) >= 0:
                    ok = False
                    break
            if ok:
                tris.append((i0, i1, i2))
                idx.pop(k)
                break
        else:  # degenerate (collinear) remainder: fan it
            break
    for k in range(1, len(idx) - 1):
        tris.append((idx[0], idx[k], idx[k + 1]))
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


# -- environment -----------------------------------------------------------------------------------

_OBSTACLE_COLOURS = np.array([[0.74, 0.68, 0.60], [0.62, 0.66, 0.70], [0.72, 0.62, 0.52],
                              [0.60, 0.65, 0.58], [0.70, 0.70, 0.66]])
WOOD = np.array([0.58, 0.40, 0.24])
CARDBOARD = np.array([0.80, 0.60, 0.34])
SPAWN = np.array([0.36, 0.72, 0.46])
REGION = np.array([0.93, 0.80, 0.42])
REGION_FILL = np.array([0.76, 0.72, 0.60])


class _MeshBuilder:
    def __init__(self):
        self.parts = []

    def tris(self, pos, normal, colour):
        pos = np.asarray(pos, dtype=np.float64).reshape(-1, 3)
        nrm = np.broadcast_to(np.asarray(normal, dtype=np.float64), pos.shape)
        col = np.broadcast_to(np.asarray(colour, dtype=np.float64), pos.shape)
        self.parts.append(np.concatenate([pos, nrm, col], axis=1))

    def box(self, centre, size, heading, colour):
        """Axis-aligned box rotated by ``heading`` about +Y; ``centre`` of its bottom face."""
        cx, cy, cz = centre
        sx, sy, sz = (s / 2 for s in size)
        c, s = math.cos(heading), math.sin(heading)
        R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        faces = [((1, 0, 0), [(sx, -sy, -sz), (sx, sy, -sz), (sx, sy, sz), (sx, -sy, sz)]),
                 ((-1, 0, 0), [(-sx, -sy, sz), (-sx, sy, sz), (-sx, sy, -sz), (-sx, -sy, -sz)]),
                 ((0, 1, 0), [(-sx, sy, -sz), (-sx, sy, sz), (sx, sy, sz), (sx, sy, -sz)]),
                 ((0, -1, 0), [(-sx, -sy, sz), (-sx, -sy, -sz), (sx, -sy, -sz), (sx, -sy, sz)]),
                 ((0, 0, 1), [(sx, -sy, sz), (sx, sy, sz), (-sx, sy, sz), (-sx, -sy, sz)]),
                 ((0, 0, -1), [(-sx, -sy, -sz), (-sx, sy, -sz), (sx, sy, -sz), (sx, -sy, -sz)])]
        off = np.array([cx, cy + sy, cz])
        for n, q in faces:
            q = np.array(q) @ R.T + off
            shade = 1.0 if n[1] >= 0 else 0.7
            self.tris(q[[0, 1, 2, 0, 2, 3]], R @ np.array(n, dtype=np.float64), colour * shade)

    def prism(self, poly, y0, y1, colour, smooth=False):
        poly = np.asarray(poly, dtype=np.float64)
        if _area2(poly) < 0:
            poly = poly[::-1]
        t = triangulate(poly)
        top = np.column_stack([poly[:, 0], np.full(len(poly), y1), poly[:, 1]])
        self.tris(top[t[:, ::-1].reshape(-1)], (0, 1, 0), np.minimum(colour * 1.08, 1.0))
        nxt = np.roll(poly, -1, axis=0)
        d = nxt - poly
        en = np.column_stack([d[:, 1], np.zeros(len(d)), -d[:, 0]])
        en /= np.linalg.norm(en, axis=1, keepdims=True) + 1e-12
        if smooth:
            vn = en + np.roll(en, 1, axis=0)
            vn /= np.linalg.norm(vn, axis=1, keepdims=True) + 1e-12
            n0, n1 = vn, np.roll(vn, -1, axis=0)
        else:
            n0 = n1 = en
        for i in range(len(poly)):
            a, b = poly[i], nxt[i]
            q = np.array([[a[0], y0, a[1]], [b[0], y0, b[1]], [b[0], y1, b[1]], [a[0], y1, a[1]]])
            nq = np.array([n0[i], n1[i], n1[i], n0[i]])
            self.parts.append(np.concatenate([q[[0, 1, 2, 0, 2, 3]], nq[[0, 1, 2, 0, 2, 3]],
                                              np.broadcast_to(colour, (6, 3))], axis=1))

    def flat(self, poly, y, colour):
        poly = np.asarray(poly, dtype=np.float64)
        t = triangulate(poly)
        pts = np.column_stack([poly[:, 0], np.full(len(poly), y), poly[:, 1]])
        self.tris(pts[t.reshape(-1)], (0, 1, 0), colour)

    def outline(self, poly, y, width, colour):
        poly = np.asarray(poly, dtype=np.float64)
        nxt = np.roll(poly, -1, axis=0)
        for a, b in zip(poly, nxt):
            d = b - a
            L = np.hypot(*d)
            if L < 1e-9:
                continue
            nrm = np.array([-d[1], d[0]]) / L * width / 2
            q = np.array([a - nrm, b - nrm, b + nrm, a + nrm])
            q3 = np.column_stack([q[:, 0], np.full(4, y), q[:, 1]])
            self.tris(q3[[0, 1, 2, 0, 2, 3]], (0, 1, 0), colour)

    def build(self) -> np.ndarray:
        if not self.parts:
            return np.zeros((0, 9), dtype=np.float32)
        return np.concatenate(self.parts).astype(np.float32)


def _circle(cx, cz, r, n=32):
    a = 2 * math.pi * np.arange(n) / n
    return np.column_stack([cx + r * np.sin(a), cz + r * np.cos(a)])


def environment_mesh(env, heights=None, default_height: float = 1.0, draw_boxes: bool = True) -> np.ndarray:
    """Triangles (V, 9) = position, normal, colour of the environment's static geometry:
    obstacles (polygons then circles, in ``env.obstacle_paths`` order) extruded to
    ``heights[i]`` (default ``default_height``), seats (a chair facing the marker's heading),
    boxes (0.4 m crates), spawn points (a disc with a heading tick) and regions (a tinted
    footprint with an outline)."""
    mb = _MeshBuilder()
    n_poly = len(env.polygons)
    hs = list(heights) if heights is not None else []
    for i, poly in enumerate(env.polygons):
        h = float(hs[i]) if i < len(hs) and hs[i] else default_height
        mb.prism(poly, 0.0, h, _OBSTACLE_COLOURS[i % len(_OBSTACLE_COLOURS)], smooth=len(poly) > 12)
    for k, (cx, cz, r) in enumerate(env.circles):
        i = n_poly + k
        h = float(hs[i]) if i < len(hs) and hs[i] else default_height
        mb.prism(_circle(cx, cz, r), 0.0, h, _OBSTACLE_COLOURS[i % len(_OBSTACLE_COLOURS)], smooth=True)
    for m in env.markers.values():
        x, z = m.position
        h = m.heading
        fwd = np.array([math.sin(h), math.cos(h)])
        if m.role == "seat":
            mb.box((x, 0.0, z), (0.46, 0.42, 0.44), h, WOOD * 0.8)
            mb.box((x, 0.42, z), (0.50, 0.06, 0.50), h, WOOD)
            bx, bz = np.array([x, z]) - fwd * 0.22
            mb.box((bx, 0.48, bz), (0.50, 0.46, 0.06), h, WOOD)
        elif m.role == "box" and draw_boxes:
            mb.box((x, 0.0, z), (0.4, 0.4, 0.4), h, CARDBOARD)
        elif m.role == "spawn":
            mb.flat(_circle(x, z, 0.45, 24), 0.012, SPAWN)
            tip = np.array([x, z]) + fwd * 0.6
            side = np.array([fwd[1], -fwd[0]]) * 0.18
            base = np.array([x, z]) + fwd * 0.3
            mb.flat(np.array([base - side, tip, base + side]), 0.014, SPAWN * 0.7)
        elif m.role == "region" and m.polygon is not None:
            mb.flat(m.polygon, 0.006, REGION_FILL)
            mb.outline(m.polygon, 0.009, 0.08, REGION * 0.8)
    return mb.build()


FLOOR_MAX_Y = 0.05         # flat triangles at most this high are floor markings


def split_floor(mesh: np.ndarray):
    """Split triangles (V, 9) of :func:`environment_mesh` into the floor markings (flat,
    facing up, at most :data:`FLOOR_MAX_Y` high: spawn discs, region fills and outlines) and
    the rest. The floor comes highest first (stable within a height), so that where markings
    overlap the topmost one is drawn first: the renderer shades each floor pixel once.

    Returns (floor (F, 9), rest (V - F, 9))."""
    tri = np.asarray(mesh).reshape(-1, 3, mesh.shape[-1])
    flat = (tri[:, :, 1].max(axis=1) <= FLOOR_MAX_Y) & (tri[:, :, 4].min(axis=1) > 0.999)
    floor = tri[flat]
    floor = floor[np.argsort(-floor[:, 0, 1], kind="stable")]
    return floor.reshape(-1, mesh.shape[-1]), tri[~flat].reshape(-1, mesh.shape[-1])


def floor_rects(env) -> list[tuple[float, float, float, float]]:
    """The region fills of :func:`environment_mesh` that are axis-aligned rectangles, as
    (xmin, zmin, xmax, zmax): opaque floor that hides whatever of the ground lies under it."""
    out = []
    for m in env.markers.values():
        if m.role != "region" or m.polygon is None or len(m.polygon) != 4:
            continue
        p = m.polygon
        xs, zs = np.unique(p[:, 0]), np.unique(p[:, 1])
        d = np.abs(np.diff(np.vstack([p, p[:1]]), axis=0))
        if len(xs) == 2 and len(zs) == 2 and (np.minimum(d[:, 0], d[:, 1]) == 0).all():
            out.append((float(xs[0]), float(zs[0]), float(xs[1]), float(zs[1])))
    return out


def rect_minus(rect, holes) -> list[tuple[float, float, float, float]]:
    """The rectangle ``rect`` (xmin, zmin, xmax, zmax) less the rectangles ``holes``, as
    rectangles: the cells between all the edges, the uncovered ones merged along x. Empty
    when the holes cover it."""
    x0, z0, x1, z1 = rect
    holes = [h for h in holes if h[0] < x1 and h[2] > x0 and h[1] < z1 and h[3] > z0]
    xs = np.unique(np.clip([x0, x1, *(h[0] for h in holes), *(h[2] for h in holes)], x0, x1))
    zs = np.unique(np.clip([z0, z1, *(h[1] for h in holes), *(h[3] for h in holes)], z0, z1))
    out = []
    for za, zb in zip(zs[:-1], zs[1:]):
        run = None
        for xa, xb in zip(xs[:-1], xs[1:]):
            cx, cz = 0.5 * (xa + xb), 0.5 * (za + zb)
            if any(h[0] <= cx <= h[2] and h[1] <= cz <= h[3] for h in holes):
                if run is not None:
                    out.append(run)
                run = None
            else:
                run = (run[0], za, xb, zb) if run is not None else (xa, za, xb, zb)
        if run is not None:
            out.append(run)
    return [tuple(float(v) for v in r) for r in out]


def line_pieces(lo, hi, seg, cuts, overlap: float = 0.0):
    """A line from ``lo`` to ``hi`` in pieces of at most ``seg`` (evenly spaced), less what
    lies inside the intervals ``cuts`` [(a, b), ...] further than ``overlap`` from their ends:
    a list of arrays of the kept points, one per run of pieces (the uncut line's points, and
    the cuts' ends: where the line is kept it is drawn through the same points as uncut)."""
    cuts = [(a + overlap, b - overlap) for a, b in cuts if b - a > 2 * overlap]
    t = np.linspace(lo, hi, max(2, int((hi - lo) / seg) + 1))
    ends = [v for a, b in cuts for v in (a, b) if lo < v < hi]
    t = np.unique(np.concatenate([t, ends])) if ends else t
    mid = 0.5 * (t[:-1] + t[1:])
    keep = np.ones(len(mid), dtype=bool)
    for a, b in cuts:
        keep &= ~((mid > a) & (mid < b))
    runs, k = [], 0
    while k < len(mid):
        if keep[k]:
            j = k
            while j + 1 < len(mid) and keep[j + 1]:
                j += 1
            runs.append(t[k:j + 2])
            k = j + 1
        else:
            k += 1
    return runs


# -- per frame -------------------------------------------------------------------------------------

def posed_copies(mesh: np.ndarray, pos: np.ndarray, heading: np.ndarray, colour) -> np.ndarray:
    """Copies of ``mesh`` (K, 6) position+normal turned by ``heading`` (M,) about +Y and moved
    to ``pos`` (M, 3): lit vertices (M * K, 9) position, normal, ``colour``."""
    m = len(pos)
    A = mesh
    c, s = np.cos(heading), np.sin(heading)
    px, pz = A[:, 0], A[:, 2]
    nx, nz = A[:, 3], A[:, 5]
    v = np.empty((m, len(A), 9), dtype=np.float32)
    v[:, :, 0] = pos[:, 0:1] + c[:, None] * px + s[:, None] * pz
    v[:, :, 1] = pos[:, 1:2] + A[:, 1]
    v[:, :, 2] = pos[:, 2:3] - s[:, None] * px + c[:, None] * pz
    v[:, :, 3] = c[:, None] * nx + s[:, None] * nz
    v[:, :, 4] = A[:, 4]
    v[:, :, 5] = -s[:, None] * nx + c[:, None] * nz
    v[:, :, 6:9] = colour
    return v.reshape(-1, 9)


def decal_vertices(roots: np.ndarray, rings) -> np.ndarray:
    """Ground quads (V, 10) = position, corner u, v, kind, rgba: a blob shadow under each of
    ``roots`` (N, 3) and the ``rings`` [(x, z, radius, (r, g, b, a)), ...] (kind 1)."""
    n = len(roots)
    items = np.zeros((n + len(rings), 8), dtype=np.float32)     # x, z, radius, kind, rgba
    if n:
        items[:n, 0] = roots[:, 0]
        items[:n, 1] = roots[:, 2]
        items[:n, 2] = 0.42
        items[:n, 7] = 0.36
    for k, (x, z, r, col) in enumerate(rings):
        items[n + k] = (x, z, r, 1.0, *col)
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, -1], [1, 1], [-1, 1]], dtype=np.float32)
    m = len(items)
    v = np.empty((m, 6, 10), dtype=np.float32)
    v[:, :, 0] = items[:, None, 0] + corners[None, :, 0] * items[:, None, 2]
    v[:, :, 1] = 0.012
    v[:, :, 2] = items[:, None, 1] + corners[None, :, 1] * items[:, None, 2]
    v[:, :, 3:5] = corners[None]
    v[:, :, 5] = items[:, None, 3]
    v[:, :, 6:10] = items[:, None, 4:8]
    return v.reshape(-1, 10)
