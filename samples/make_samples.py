"""Generator of the sample scenarios that reproduce paper 000's experiments (section 4).

``python samples/make_samples.py [NAME ...]`` (re)writes, deterministically, each sample's
``world.usda`` (built with pxr), ``scenario.toml`` (built from code: grids, letter strokes,
theater rows) and ``README.md``:

=============  ===========================================================================
meet20         Experiment 1: 20 characters arrive in the same 0.5 s window in pairs,
               triangles and a square, partners facing each other
spell70        Experiment 2: 70 characters walk to points spelling "SCA", front row first,
               and face the camera (+Z)
rooms_box      Experiment 3: one character crosses six rooms with walls, doors and
               furniture, among 8 other characters (planned first), and picks up a box
theater40      Experiment 4: 40 characters walk from a lobby through two doors and take
               theater seats (back rows and inner seats first)
fetch_boxes20  Experiment 5: 20 seated characters each fetch a designated box from a
               second room, put it down at a designated spot and return to their seat
grid300/500    Experiment 6 (Figure 10): a uniform grid walks to a translated grid, each
               character to a randomly perturbed target cell
=============  ===========================================================================

Everything random is drawn from ``numpy.random.default_rng(seed)``; the files are written
atomically. The functions returning scenario dicts (:func:`grid_scenario`, ...) are also used
by ``bench/crowd_table.py`` for the Figure 11 spacing sweep.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(ROOT) not in sys.path:      # run as a script from anywhere
    sys.path.insert(0, str(ROOT))

from runtime.assets import atomic_path, atomic_write_bytes  # noqa: E402

SAMPLES = ("meet20", "spell70", "rooms_box", "theater40", "fetch_boxes20", "grid300", "grid500")

# Clearances the default library needs (bounding-cylinder radii, m): standing ~0.3, walking
# up to 0.63 (stride), carrying ~0.49, sitting 0.62, sitting down / standing up up to 0.72.
WALK_SPEED = 1.0        # m/s used to lay out time windows (the library walks at 0.6-1.6 m/s)


# ----------------------------------------------------------------------------------------------
# TOML writing (the scenario format of runtime.crowd.scenario; tomllib only reads)
def _num(v) -> str:
    v = float(v)
    if v == 0:
        v = 0.0                     # no "-0.0"
    s = f"{round(v, 4):.4f}".rstrip("0")
    return s + "0" if s.endswith(".") else s


def _val(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return _num(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_val(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_val(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def scenario_toml(sc: dict) -> str:
    """TOML text of a scenario dict (keys as in ``runtime.crowd.scenario``)."""
    lines = []
    for k in ("name", "description", "world", "library", "duration", "seed"):
        if k in sc:
            lines.append(f"{k} = {_val(sc[k])}")
    if sc.get("synthesis"):
        lines += ["", "[synthesis]"] + [f"{k} = {_val(v)}" for k, v in sc["synthesis"].items()]
    for c in sc["character"]:
        lines += ["", "[[character]]", f"name = {_val(c['name'])}", f"start = {_val(c['start'])}"]
        for g in c.get("goal", []):
            lines.append("  [[character.goal]]")
            lines += [f"  {k} = {_val(v)}" for k, v in g.items()]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------------------------
# World stages (pxr), following usd_io.world's conventions
class WorldBuilder:
    """A Y-up, metre world stage: obstacles under /World/Obstacles, seats under /World/Seats,
    boxes under /World/Boxes (markers face their local +Z; heading degrees about +Y)."""

    def __init__(self, doc: str):
        from pxr import Sdf, Usd, UsdGeom
        self.Sdf, self.Usd, self.UsdGeom = Sdf, Usd, UsdGeom
        self.stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(self.stage, 1.0)
        world = UsdGeom.Xform.Define(self.stage, "/World")
        self.stage.SetDefaultPrim(world.GetPrim())
        self.stage.GetRootLayer().documentation = doc
        for p in ("/World/Obstacles", "/World/Seats", "/World/Boxes"):
            UsdGeom.Scope.Define(self.stage, p)
        self._used = set()

    def _xform(self, prim, x, y, z, yaw=0.0, scale=None):
        api = self.UsdGeom.XformCommonAPI(prim)
        api.SetTranslate((float(x), float(y), float(z)))
        if yaw:
            api.SetRotate((0.0, float(yaw), 0.0))
        if scale is not None:
            api.SetScale(tuple(float(s) for s in scale))

    def _path(self, parent, name):
        p = f"{parent}/{name}"
        if p in self._used:
            raise ValueError(f"duplicate prim {p}")
        self._used.add(p)
        return p

    def block(self, name, x0, z0, x1, z1, height=2.5, yaw=0.0, parent="/World/Obstacles"):
        """An axis-aligned (before ``yaw``) box obstacle spanning [x0, x1] x [z0, z1]."""
        cube = self.UsdGeom.Cube.Define(self.stage, self._path(parent, name))
        cube.CreateSizeAttr(1.0)
        self._xform(cube.GetPrim(), (x0 + x1) / 2, height / 2, (z0 + z1) / 2, yaw,
                    (abs(x1 - x0), height, abs(z1 - z0)))
        return cube

    def pillar(self, name, x, z, radius, height=3.0):
        cyl = self.UsdGeom.Cylinder.Define(self.stage, self._path("/World/Obstacles", name))
        cyl.CreateAxisAttr("Y")
        cyl.CreateRadiusAttr(float(radius))
        cyl.CreateHeightAttr(float(height))
        self._xform(cyl.GetPrim(), x, height / 2, z)
        return cyl

    def wall(self, name, a, b, doors=(), thickness=0.2, height=2.5):
        """A straight axis-aligned wall from a=(x, z) to b with door gaps ``(centre, width)``
        measured along the wall from ``a``. Each solid piece is one Cube."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        length = float(np.hypot(*(b - a)))
        d = (b - a) / length
        cuts = sorted((c - w / 2, c + w / 2) for c, w in doors)
        pieces, s = [], 0.0
        for lo, hi in cuts:
            if lo > s:
                pieces.append((s, lo))
            s = max(s, hi)
        if s < length:
            pieces.append((s, length))
        n = np.array([-d[1], d[0]]) * thickness / 2
        for k, (s0, s1) in enumerate(pieces):
            p0, p1 = a + d * s0, a + d * s1
            lo = np.minimum(p0, p1) - np.abs(n)
            hi = np.maximum(p0, p1) + np.abs(n)
            self.block(f"{name}_{k}", lo[0], lo[1], hi[0], hi[1], height)

    def _marker(self, parent, name, role, x, z, heading_deg):
        xf = self.UsdGeom.Xform.Define(self.stage, self._path(parent, name))
        prim = xf.GetPrim()
        prim.CreateAttribute("crowdweave:role", self.Sdf.ValueTypeNames.String, custom=True).Set(role)
        self._xform(prim, x, 0.0, z, heading_deg)
        return prim.GetPath().pathString

    def seat(self, name, x, z, heading_deg):
        """A seat marker (root of a seated character, facing ``heading_deg``) with a chair
        under it (the marker's own geometry, not an obstacle)."""
        path = self._marker("/World/Seats", name, "seat", x, z, heading_deg)
        chair = self.UsdGeom.Cube.Define(self.stage, path + "/Chair")
        chair.CreateSizeAttr(1.0)
        self._xform(chair.GetPrim(), 0.0, 0.22, -0.05, scale=(0.5, 0.44, 0.5))
        back = self.UsdGeom.Cube.Define(self.stage, path + "/Back")
        back.CreateSizeAttr(1.0)
        self._xform(back.GetPrim(), 0.0, 0.65, -0.27, scale=(0.5, 0.9, 0.06))
        return path

    def box(self, name, x, z, heading_deg):
        """A box marker: the character picks it up standing in front of it (on its +Z side)."""
        path = self._marker("/World/Boxes", name, "box", x, z, heading_deg)
        crate = self.UsdGeom.Cube.Define(self.stage, path + "/Crate")
        crate.CreateSizeAttr(0.4)
        self._xform(crate.GetPrim(), 0.0, 0.2, 0.0)
        return path

    def save(self, path):
        with atomic_path(path) as tmp:
            self.stage.GetRootLayer().Export(str(tmp))


def _write(folder: Path, sc: dict, readme: str, world: WorldBuilder | None = None):
    folder.mkdir(parents=True, exist_ok=True)
    if world is not None:
        world.save(folder / "world.usda")
    atomic_write_bytes(folder / "scenario.toml", scenario_toml(sc).encode())
    atomic_write_bytes(folder / "README.md", readme.encode())


def _deg(v) -> float:
    return float(np.degrees(math.atan2(v[0], v[1])))


def _pos(p):
    return [round(float(p[0]), 4), round(float(p[1]), 4)]


def min_spacing(points) -> float:
    from scipy.spatial.distance import pdist
    p = np.asarray(points, float)
    return float(pdist(p).min()) if len(p) > 1 else math.inf


# ----------------------------------------------------------------------------------------------
# Experiment 1: meet in configurations at the same time
MEET_GROUPS = (2, 3, 2, 4, 2, 3, 2, 2)


def meet_scenario(groups=MEET_GROUPS, seed: int = 0, name: str | None = None) -> dict:
    """20 characters scattered over a 31 m square walk to 8 groups on a ring of radius 5 m --
    five facing pairs (1.2 m apart), two triangles and a square (circles of 0.8 and 0.85 m
    radius, members facing the group centre) -- and all arrive in [12, 12.5] s. ``groups``
    gives the group sizes (2, 3 or 4) around the ring.

    Start spots come from a jittered 2.6 m lattice (nothing within 2 m of a goal); each goal
    gets the spot that best gives a 7.5-10.5 m walk approaching the goal from behind (the final turn
    on the spot is at most about 60 degrees), by one assignment (Hungarian, scipy)."""
    from scipy.optimize import linear_sum_assignment
    rng = np.random.default_rng(seed)
    goals = []                              # (x, z, heading deg)
    for k, n in enumerate(groups):
        a = 2 * math.pi * k / len(groups)
        centre = 5.0 * np.array([math.sin(a), math.cos(a)])
        radius = {2: 0.6, 3: 0.8, 4: 0.85}[n]
        # pairs stand along the ring's tangent; larger groups are turned by a fixed offset
        base = a + math.pi / 2 if n == 2 else a + math.pi / n
        for m in range(n):
            b = base + 2 * math.pi * m / n
            p = centre + radius * np.array([math.sin(b), math.cos(b)])
            goals.append((p[0], p[1], _deg(centre - p)))
    goals = np.array(goals)
    u = np.arange(-6, 7) * 2.6
    cand = np.stack(np.meshgrid(u, u, indexing="ij"), -1).reshape(-1, 2) + rng.uniform(-0.5, 0.5, (len(u) ** 2, 2))
    dmin = np.hypot(cand[:, None, 0] - goals[None, :, 0], cand[:, None, 1] - goals[None, :, 1]).min(1)
    cand = cand[dmin > 2.0]
    d = goals[None, :, :2] - cand[:, None, :]
    dist = np.hypot(d[..., 0], d[..., 1])
    turn = np.abs((np.degrees(np.arctan2(d[..., 0], d[..., 1])) - goals[None, :, 2] + 180) % 360 - 180)
    cost = np.maximum(0, np.abs(dist - 9.0) - 1.5) + 0.1 * np.maximum(0, turn - 60)
    ci, gi = linear_sum_assignment(cost)
    order = np.argsort(gi)
    n = len(goals)
    chars = []
    for k, o in enumerate(order):
        s, g = cand[ci[o]], goals[gi[o]]
        chars.append({"name": f"c{k + 1:02d}",
                      "start": {"position": _pos(s), "heading": round(_deg(g[:2] - s), 3), "pose": "stand"},
                      "goal": [{"position": _pos(g[:2]), "heading": round(float(g[2]), 3), "pose": "stand",
                                "time": [12.0, 12.5]}]})
    return {"name": name or f"meet{n}", "description": f"Experiment 1 (paper 000, Figure 5): {n} characters "
            "arrive simultaneously in pairs, triangles and a square, facing each other",
            "library": "default", "duration": 16.0, "seed": seed, "character": chars}


# ----------------------------------------------------------------------------------------------
# Experiment 2: spell a word
# Block letters as polylines in letter units (width 4, height 6; v up). Every vertex is a
# position; strokes after a letter's first share their end vertices with it.
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
                      "start": {"position": _pos(starts[i]), "heading": 0.0, "pose": "stand"},
                      "goal": [{"position": _pos(g), "heading": 0.0, "pose": "stand", "time": [t0, t0 + 1.0]}]})
    return {"name": "spell70", "description": f"Experiment 2 (paper 000, Figure 6): {n} characters walk to "
            f"points spelling {word}, front row first, and face the camera (+Z)",
            "library": "default", "duration": 20.0 + SPELL_STAGGER, "seed": seed, "character": chars}


# ----------------------------------------------------------------------------------------------
# Experiment 3: cross the rooms and pick up a box
ROOMS_DOOR = 2.4            # door widths: the walking cylinder is up to 1.26 m wide


def rooms_world() -> WorldBuilder:
    """Six 8 x 8 m rooms (x 0..24, z -8..8; "up" in a top view is -Z) with 2.4 m doors placed so
    that the lower-right room reaches the upper-right one only through the four others, and
    furniture in every room (tables, shelves, pillars, crates)."""
    w = WorldBuilder("crowdweave sample rooms_box: six rooms with doors and furniture; box b01 in the "
                     "upper-right room (metres, Y up). Written by samples/make_samples.py.")
    D = ROOMS_DOOR
    w.wall("OuterNorth", (0, -8), (24, -8))
    w.wall("OuterEast", (24, -8), (24, 8))
    w.wall("OuterSouth", (0, 8), (24, 8))
    w.wall("OuterWest", (0, -8), (0, 8))
    w.wall("Middle", (0, 0), (24, 0), doors=[(3.0, D)])                  # lower-left <-> upper-left
    w.wall("West", (8, -8), (8, 8), doors=[(3.0, D), (13.5, D)])         # z = -5 and z = 5.5
    w.wall("East", (16, -8), (16, 8), doors=[(5.0, D), (12.0, D)])       # z = -3 and z = 4
    # furniture: every gap to a wall or another piece is either closed (< 0.6 m) or at least
    # 1.9 m wide: a walking character's cylinder (radius up to 0.63 m) plus clearance on both
    # sides, so that the roadmap (obstacles grown by 0.6 m) never routes one through a slot
    # its stride cannot follow
    # lower right (start room)
    w.block("LR_Table", 18.5, 0.1, 20.5, 1.0, 0.75)
    w.block("LR_Cabinet", 22.8, 6.4, 23.9, 7.9, 1.8)
    # lower middle
    w.block("LM_Sofa", 11.4, 3.2, 12.4, 6.0, 0.8)
    w.block("LM_Crates", 14.9, 6.6, 15.9, 7.9, 1.0)
    w.block("LM_Desk", 8.1, 0.1, 10.1, 1.2, 0.75)
    # lower left
    w.block("LL_Shelf", 0.6, 6.2, 2.2, 7.6, 2.0)
    w.block("LL_Table", 4.4, 2.0, 6.0, 3.0, 0.75)
    # upper left
    w.block("UL_Table", 0.1, -4.4, 2.5, -3.2, 0.75)
    w.pillar("UL_Pillar", 5.6, -2.6, 0.4)
    w.block("UL_Cabinet", 5.8, -7.6, 7.4, -6.6, 1.8)
    # upper middle
    w.block("UM_LongTable", 10.0, -4.6, 14.0, -3.4, 0.75)
    w.block("UM_Crates", 11.0, -1.1, 12.0, -0.1, 1.0)
    w.block("UM_Cabinet", 12.0, -7.9, 13.5, -7.2, 1.8)
    # upper right (the box)
    w.block("UR_Shelf", 22.6, -7.6, 23.6, -3.0, 2.2)
    w.block("UR_Crates", 18.0, -1.6, 19.2, -0.6, 1.0)
    w.pillar("UR_Pillar", 19.0, -5.6, 0.3)
    w.box("b01", 21.6, -5.0, -90.0)          # faces -X: picked up from its west side
    return w


# (room, points) the other characters walk between; each >= 1 m from furniture, >= 2 m from doors
ROOM_POINTS = {
    "LR": [(18.6, 6.4), (22.4, 1.2), (19.8, 4.2)],
    "LM_a": [(9.6, 3.0), (14.4, 2.0), (13.8, 5.0)],
    "LM_b": [(10.4, 6.8), (13.6, 1.2), (10.6, 2.4)],
    "LL": [(1.6, 2.2), (5.6, 6.8), (2.2, 4.6)],
    "UL": [(1.6, -6.4), (4.4, -5.6), (1.4, -1.8)],
    "UM_a": [(9.6, -1.4), (14.0, -1.2), (11.0, -6.4)],
    "UM_b": [(14.6, -6.2), (9.6, -6.6), (13.6, -2.2)],
    "UR": [(20.6, -1.8), (17.6, -6.8), (21.0, -3.4)],
}


def rooms_scenario(seed: int = 0, movers: bool = False) -> dict:
    """The character "main" starts in the lower-right room at (21.5, 6.5) and must pick up box
    /World/Boxes/b01 in the upper-right room, with no time constraint -- paper 000's
    Experiment 3 is this one character. With ``movers``, eight more characters first walk round
    triangles of points in the rooms (5 goals each, windows 2 s wide laid out at 1.1 m/s plus a
    2 s pause) and are moving obstacles to it (a harder variant, not the paper's)."""
    chars = []
    for k, (room, pts) in enumerate(ROOM_POINTS.items() if movers else ()):
        pts = [np.array(p, float) for p in pts]
        start = pts[-1]
        t = 3.0 + 1.5 * k
        goals = []
        prev = start
        for q in range(5):                      # round the triangle of points, starting at the last
            p = pts[q % 3]
            t += float(np.hypot(*(p - prev))) / 1.1 + 2.0
            goals.append({"position": _pos(p), "time": [round(t, 1), round(t + 2.0, 1)]})
            t += 2.0
            prev = p
        chars.append({"name": f"m{k + 1}_{room.split('_')[0].lower()}",
                      "start": {"position": _pos(start), "heading": round(_deg(pts[0] - start), 3), "pose": "stand"},
                      "goal": goals})
    chars.append({"name": "main", "start": {"position": [21.5, 6.5], "heading": -90.0, "pose": "stand"},
                  "goal": [{"box": "/World/Boxes/b01"}]})
    return {"name": "rooms_box", "description": "Experiment 3 (paper 000, Figure 7): one character crosses "
            "rooms full of obstacles and picks up a box",
            "world": "world.usda", "library": "default", "duration": 75.0, "seed": seed, "character": chars}


# ----------------------------------------------------------------------------------------------
# Experiment 4: theater
SEAT_X = -5.25 + 1.5 * np.arange(8)            # 8 seats a row, 1.5 m apart
ROW_PITCH = 3.2
ROW_Z = 7.5 - ROW_PITCH * np.arange(5)         # back row first
RAIL_HALF_WIDTH = 6.0                          # row partitions span the seat block, x -6..6
THEATER_DOORS = (-7.5, 7.5)
THEATER_GAP = 4.0                              # s between consecutive seats of a half theater


def theater_world() -> WorldBuilder:
    """A 20 x 22 m hall (x -10..10, z -10..12) with a stage at -Z and 5 rows of 8 seats facing
    it (1.5 m between seats, 3.2 m between rows, 4 m side aisles), and a lobby (z 12..24)
    joined to the hall by two 3 m doors at x = -7.5 and 7.5.

    Between consecutive rows (and behind the back row, in front of the front row) a 0.2 m row
    partition -- the seat backs of the row in front -- spans the seat block: a row is entered
    from the side aisles only, and its lane (the 2.1 m between its seats' front edge and the
    next partition) fits a walking character (radius up to 0.63 m) in front of its empty seats
    while a seated character (0.62-0.72 m) clears the partition behind it."""
    w = WorldBuilder("crowdweave sample theater40: lobby, two doors, hall with 5 rows of 8 seats facing a "
                     "stage (metres, Y up). Written by samples/make_samples.py.")
    w.wall("North", (-10, -10), (10, -10))
    w.wall("East", (10, -10), (10, 24))
    w.wall("South", (-10, 24), (10, 24))
    w.wall("West", (-10, -10), (-10, 24))
    w.wall("Foyer", (-10, 12), (10, 12), doors=[(d + 10, 3.0) for d in THEATER_DOORS])
    w.block("Stage", -7.0, -9.9, 7.0, -8.2, 1.0)
    w.pillar("LobbyPillar", 0.0, 17.5, 0.5)
    w.block("Counter", -1.5, 22.4, 1.5, 23.6, 1.1)
    for k, z in enumerate(list(ROW_Z + 1.0) + [ROW_Z[-1] - ROW_PITCH + 1.0]):
        w.block(f"RowPartition{k + 1}", -RAIL_HALF_WIDTH, z - 0.1, RAIL_HALF_WIDTH, z + 0.1, 0.9)
    for b, z in enumerate(ROW_Z):
        for j, x in enumerate(SEAT_X):
            w.seat(f"r{b + 1}_s{j + 1}", x, z, 180.0)
    return w


def theater_scenario(seed: int = 0) -> dict:
    """40 characters wait in the lobby in two 4 x 5 blocks (2 m spacing) beside the two doors
    and take seats row by row, back row first and inner seats first in each half row (so no
    one passes a seated character closely). Those nearest their door go first; seat k of a
    half-theater is reached in [18 + g k, 18 + g (k + 1)] s with g = ``THEATER_GAP`` (4 s: the
    one before has sat down by then, so the two are not walking the row's lane together)."""
    chars = []
    order = []
    for side, door_x in zip((-1, 1), THEATER_DOORS):
        xs = door_x + side * (np.arange(4) * 2.0 - 1.5) * -1        # towards the centre
        lobby = np.array([(x, z) for x in xs for z in 14.0 + 2.0 * np.arange(5)])
        dist = np.hypot(lobby[:, 0] - door_x, lobby[:, 1] - 12.0)
        lobby = lobby[np.lexsort((lobby[:, 0] * side, dist))]
        seats = []
        for b in range(len(ROW_Z)):
            for k in range(4):
                j = 3 - k if side < 0 else 4 + k
                seats.append((b, j))
        order.append(list(zip(lobby, seats)))
    n = 0
    for i in range(20):
        for side in range(2):
            (p, (b, j)) = order[side][i]
            n += 1
            t = 18.0 + THEATER_GAP * i
            chars.append({"name": f"c{n:02d}",
                          "start": {"position": _pos(p), "heading": 180.0, "pose": "stand"},
                          "goal": [{"seat": f"/World/Seats/r{b + 1}_s{j + 1}", "time": [t, t + THEATER_GAP]}]})
    return {"name": "theater40", "description": "Experiment 4 (paper 000, Figure 8): 40 characters walk from "
            "a lobby to theater seats", "world": "world.usda", "library": "default",
            "duration": 18.0 + THEATER_GAP * 20 + 4.0,
            "seed": seed, "character": chars}


# ----------------------------------------------------------------------------------------------
# Experiment 5: seated characters fetch boxes, put them down, return
FETCH_SEAT_X = 1.5 + 1.6 * np.arange(5)
FETCH_ROWS = ((1.2, 0.0), (6.8, 180.0), (9.2, 0.0), (14.8, 180.0))   # (z, heading): two corridors
FETCH_DOORS = (4.0, 12.0)            # z of the doors' centres (3 m wide), on the corridors' axes
FETCH_ROUND_SLACK = 4.0               # s between a corridor's near round back in its seats and its far round leaving
FETCH_GAP = 6.0                       # s between consecutive characters of a corridor
FETCH_LANES = np.concatenate([1.1 + 1.5 * np.arange(5), 14.9 - 1.5 * np.arange(5)[::-1]])   # z of room B's ten lanes, five per door
FETCH_PICK_X = (14.0, 20.0)           # x where a character stands to pick up the near and far box
FETCH_CARRY = 3.0                     # m carried straight on along the lane to the put-down spot
FETCH_ROOM_B = (10.0, 25.5)           # x extent of room B


def fetch_world() -> WorldBuilder:
    """Room A (x 0..10, z 0..16) with 20 seats in four rows of five facing two 4 m wide
    corridors; room B (x 10..25.5) with 20 boxes on ten lanes; two 3 m doors (z = 2.5, 13.5)."""
    w = WorldBuilder("crowdweave sample fetch_boxes20: a seating room and a store room with 20 boxes "
                     "(metres, Y up). Written by samples/make_samples.py.")
    xb = FETCH_ROOM_B[1]
    w.wall("North", (0, 0), (xb, 0))
    w.wall("East", (xb, 0), (xb, 16))
    w.wall("South", (0, 16), (xb, 16))
    w.wall("West", (0, 0), (0, 16))
    w.wall("Between", (10, 0), (10, 16), doors=[(z, 3.0) for z in FETCH_DOORS])
    w.block("Divider", 0.1, 7.9, 9.9, 8.1, 1.0)       # low divider between the back-to-back rows
    for r, (z, h) in enumerate(FETCH_ROWS):
        for j, x in enumerate(FETCH_SEAT_X):
            w.seat(f"s{r * 5 + j + 1:02d}", x, z, h)
    for k, (x, z, h) in enumerate(fetch_boxes()):
        w.box(f"b{k + 1:02d}", x, z, h)
    return w


def fetch_boxes():
    """(x, z, heading) of the 20 boxes: two on each of room B's ten lanes (z = ``FETCH_LANES``,
    1.5 m apart, 1 m from the walls), a near one and a far one, all facing -X (towards the doors). A character picks
    a box up facing away from the door, carries it ``FETCH_CARRY`` m straight on along its lane
    and puts it down there: the library's carrying clips turn only while walking on (about 1 m
    per 60 degrees), so no one has to turn round with a box. Numbered lane by lane, near box
    first."""
    from runtime.crowd.scenario import BOX_REACH
    return [(x + BOX_REACH, float(z), -90.0) for z in FETCH_LANES for x in FETCH_PICK_X]


def fetch_scenario(seed: int = 0) -> dict:
    """Each seated character stands up, walks through its corridor's door to its box in room B,
    picks it up, carries it ``FETCH_CARRY`` m on along the lane, puts it down there (pose
    "stand") and returns to its own seat. Each door serves the five lanes of its half, from
    their outer end; the near boxes go first, then the far ones (a far carrier walks through
    its lane's near spots after they are used), each time the lane nearest the door first,
    ``FETCH_GAP`` (6 s) apart, the characters seated nearest the door first; the far round
    leaves when the near round should be back in its seats. The pick-up and the
    put-down have 2.5 s windows laid out from the distances (walking 1 m/s, carrying 0.7 m/s,
    about 3.5 s per pose change); the return to the seat has none (the paper's Experiment 5
    times no goal): a character sits down when it gets there."""
    from runtime.crowd.scenario import BOX_REACH
    boxes = fetch_boxes()
    chars = []
    t_last = []
    for cor in range(2):
        seats = [(r + 2 * cor, j) for j in range(4, -1, -1) for r in range(2)]     # nearest the door first
        # lanes nearest the door first: everyone walks a straight line between the door and
        # its lane, so a character walking back crosses only lanes (on its side of the door)
        # whose users went before it and are ahead of it on the same way back, and one walking
        # out crosses none in use
        lanes = sorted(range(5 * cor, 5 * cor + 5), key=lambda i: abs(FETCH_LANES[i] - FETCH_DOORS[cor]))
        bidx = [2 * lane + far for far in (0, 1) for lane in lanes]
        door = np.array([10.0, FETCH_DOORS[cor]])
        t_prev = [-10.0, -10.0]
        back = []                   # when each character should be seated again
        for k, ((r, j), b) in enumerate(zip(seats, bidx)):
            z, h = FETCH_ROWS[r]
            seat = np.array([FETCH_SEAT_X[j], z])
            up = seat + 0.42 * np.array([math.sin(math.radians(h)), math.cos(math.radians(h))])
            pick = np.array(boxes[b][:2]) - [BOX_REACH, 0.0]
            place = pick + [FETCH_CARRY, 0.0]
            d1 = float(np.hypot(*(door - up)) + np.hypot(*(pick - door)))
            leave = 3.0 + d1 / WALK_SPEED + 4.0          # standing up, walking, picking up
            t1 = max(leave, t_prev[0] + FETCH_GAP)
            if k == 5:
                # the far round leaves once the near round is back in its seats: its first
                # carrier would otherwise meet them head-on in the corridor and the door
                t1 = max(t1, max(back) + FETCH_ROUND_SLACK + leave)
            t2 = max(t1 + 2.5 + FETCH_CARRY / 0.7 + 4.0, t_prev[1] + FETCH_GAP)
            t_prev = [t1, t2]
            d3 = float(np.hypot(*(door - place)) + np.hypot(*(up - door)))
            back.append(t2 + 2.5 + d3 / WALK_SPEED + 8.0)
            t_last.append(back[-1])
            sid = f"s{r * 5 + j + 1:02d}"
            chars.append({"name": f"c{len(chars) + 1:02d}", "start": {"seat": f"/World/Seats/{sid}"},
                          "goal": [{"box": f"/World/Boxes/b{b + 1:02d}", "time": [round(t1, 1), round(t1 + 2.5, 1)]},
                                   {"position": _pos(place), "pose": "stand", "time": [round(t2, 1), round(t2 + 2.5, 1)]},
                                   {"seat": f"/World/Seats/{sid}"}]})
    # interleave the corridors so that both start together in planning order
    chars = [c for pair in zip(chars[:10], chars[10:]) for c in pair]
    for i, c in enumerate(chars):
        c["name"] = f"c{i + 1:02d}"
    dur = max(t_last) + 10.0
    return {"name": "fetch_boxes20", "description": "Experiment 5 (paper 000, Figure 9): 20 seated characters "
            "fetch boxes, put them down at designated spots and return to their seats", "world": "world.usda",
            "library": "default", "duration": float(math.ceil(dur)), "seed": seed,
            # way points to a seat pass 2 m in front of it, in the corridor's middle: a returner
            # walks there, clear of the seated row, and comes in square between its seated
            # neighbours (1.6 m apart) instead of across their places
            "synthesis": {"approach_point": 2.0}, "character": chars}


# ----------------------------------------------------------------------------------------------
# Experiment 6: grid to translated grid (Figure 10)
def grid_scenario(cols: int, rows: int, spacing: float = 2.2, shift: float | None = None, seed: int = 0,
                  name: str | None = None, start_still: bool | None = None) -> dict:
    """``cols x rows`` characters on a uniform grid (``spacing`` m) facing +X walk to a copy of
    the grid translated by ``shift`` m along +X (default half the grid's width plus 10 m).
    Targets are perturbed as in the paper's Figure 10 while every path keeps about the same
    length: in each column, random pairs of neighbouring rows swap their targets (each pair
    with probability 1/2), so about two characters in three cross a neighbour's lane on the
    way. No time constraints; characters are planned front column first. ``start_still``: the
    scenario's ``[synthesis] start_still`` (None: not set)."""
    rng = np.random.default_rng(seed)
    if shift is None:
        shift = 0.5 * cols * spacing + 10.0
    i, j = np.meshgrid(np.arange(cols), np.arange(rows), indexing="ij")
    cells = np.stack([i.ravel(), j.ravel()], axis=1).astype(float)
    start = cells * spacing
    start[:, 1] -= (rows - 1) * spacing / 2
    start[:, 0] -= (cols - 1) * spacing
    assign = np.arange(cols * rows).reshape(cols, rows)
    for col in assign:
        r = 0
        while r < rows - 1:
            if rng.random() < 0.5:
                col[[r, r + 1]] = col[[r + 1, r]]
                r += 2
            else:
                r += 1
    assign = assign.ravel()
    target = start[assign] + [shift, 0.0]
    order = np.lexsort((start[:, 1], -start[:, 0]))       # front column first
    chars = []
    for k, c in enumerate(order):
        chars.append({"name": f"c{k + 1:03d}",
                      "start": {"position": _pos(start[c]), "heading": 90.0, "pose": "stand"},
                      "goal": [{"position": _pos(target[c])}]})
    n = cols * rows
    return {"name": name or f"grid{n}", "description": f"Experiment 6 (paper 000, Figure 10): {cols} x {rows} "
            f"grid, {spacing:g} m spacing, to the grid translated {shift:g} m along +X with perturbed targets",
            "library": "default", "duration": 60.0, "seed": seed,
            **({"synthesis": {"start_still": bool(start_still)}} if start_still is not None else {}),
            "character": chars}


def build_meet20(folder):
    sc = meet_scenario()
    _write(folder, sc, README["meet20"])


def build_spell70(folder):
    sc = spell_scenario()
    _write(folder, sc, README["spell70"])


def build_grid(n):
    def build(folder):
        cols, rows = {300: (20, 15), 500: (25, 20)}[n]
        sc = grid_scenario(cols, rows, spacing=3.0, seed=0, start_still=(n == 500))
        _write(folder, sc, README[f"grid{n}"])
    return build


_BAKE = """
Regenerate (deterministic) and bake:

```sh
.venv/bin/python samples/make_samples.py {name}
crowdweave bake samples/{name} --out /tmp/{name}.usdc --report /tmp/{name}.json
```

The bake prints the independent checker's summary (goal errors, arrival windows, poses,
per-frame adjustment against eps, overlaps). `bench/crowd_table.py --only {name}` prints this
sample's row of the paper's Table 1. Do not edit `scenario.toml`{world} by hand: change
`samples/make_samples.py` and rerun it (a test checks the files match the generator).
"""


def _readme(name, title, body, world=False):
    return (f"# {name}: {title}\n\n{body.strip()}\n"
            + _BAKE.format(name=name, world=" or `world.usda`" if world else ""))


README = {
    "meet20": _readme("meet20", "paper 000, Experiment 1 (Figure 5)", """
20 characters must arrive **simultaneously** (window [12, 12.5] s) in specified configurations:
five pairs facing each other 1.2 m apart, two triangles (0.8 m radius) and a square (0.85 m
radius) whose members face the group centre; the eight groups sit on a ring of radius 5 m on
open ground (no world stage). Each goal fixes position, heading and pose `stand`.

Starts come from a jittered 2.6 m lattice over a 31 m square (seeded), at least 2 m from every
goal; one assignment (scipy's Hungarian) gives every goal a start 7.5-10.5 m away that approaches
it roughly from behind (final turn on the spot up to about 60 degrees), so paths cross the ring
and each other and the characters must interact to arrive together.
"""),
    "spell70": _readme("spell70", "paper 000, Experiment 2 (Figure 6)", """
70 characters walk to points spelling **SCA** on open ground and stop there facing the camera
(+Z, heading 0). The word fills from the front: each point has a 1 s arrival window that opens
at 17 s for the front row (largest z) and 3 s later for the back row, linearly in depth, so a
character filing into a stroke behind another arrives after that one has stopped (with one
window for all, followers in a stroke walked on each other's heels). The block letters are polylines whose vertices are
points and whose segments are split evenly, at least 1.6 m apart (the smallest letter scale
that holds exactly 70 points, letters 2 m apart; the word is about 33 m wide and 14 m tall, read left to right
with the tops of the letters towards -Z). 1.6 m keeps two neighbours' bounding cylinders apart
in any pose of the library (radius at most 0.72 m; its standing idle loops reach 0.63 m): at
1.3 m, neighbours idling at their points overlapped whatever the planner did.

The characters start in a 14 x 5 grid (2.0 x 2.2 m) 5 m behind the word, facing +Z, and are
assigned to points by minimum total squared distance (the back of the grid takes the far side
of the letters, so paths do not cross in depth). Characters whose points are nearest the
camera are planned first.
"""),
    "rooms_box": _readme("rooms_box", "paper 000, Experiment 3 (Figure 7)", """
One character, `main`, starts in the lower-right room and must **pick up box
`/World/Boxes/b01`** in the upper-right room (goal `box = ...`: it stands 0.45 m in front of the
box, facing it, in pose `carry`). `world.usda` has six 8 x 8 m rooms (x 0..24, z -8..8; "up"
in a top view is -Z) with 2.4 m doors placed so the only route runs through the four other rooms
(about 45 m), and furniture in every room: tables, shelves, cabinets, crates and pillars.
Every gap between furniture and walls is either closed (< 0.6 m) or at least 1.9 m wide (a
walking character's cylinder is up to 1.26 m across).

As in the paper's Table 1 row, `main` is the only character. `make_samples.rooms_scenario(
movers=True)` adds eight characters walking round triangles of points in the rooms with 2 s
windows, planned first as moving obstacles: a harder variant that the planner does not yet
solve cleanly (see docs/status.md).
""", world=True),
    "theater40": _readme("theater40", "paper 000, Experiment 4 (Figure 8)", """
40 characters start in a **lobby** and take **theater seats** (goal `seat = "/World/Seats/rB_sJ"`:
position, heading and pose `sit` from the seat marker). `world.usda`: a hall (x -10..10,
z -10..12) with a stage at -Z and 5 rows of 8 seats facing it (1.5 m between seats, 3.2 m
between rows, 4 m side aisles), a lobby (z 12..24) with a pillar and a counter, and two 3 m
doors at x = -7.5 and 7.5 (the default library's walking cylinder is up to 1.26 m across, so
spacings are about twice a real theater's). Chairs are the seat markers' own geometry, not
obstacles; instead a 0.2 m row partition (the seat backs of the row in front) runs across the
seat block between consecutive rows, behind the back row and in front of the front row, so a
row is entered from the side aisles and its 2.1 m lane fits a walking character in front of
the row's empty seats with room to spare (at 2.6 m between rows the lane was 1.5 m, and the
search's perturbed motions grazed the partitions).

Each half of the lobby (4 x 5 characters, 2 m apart) fills one half of the seats through its
own door: back row first, and in each half row the innermost seat first, so nobody has to pass
close in front of a seated character (sitting characters are 0.62 m cylinders). Those nearest
the door go first; the k-th seat of each half is reached in [18 + 4 k, 22 + 4 k] s (4 s apart:
the one before has sat down by then, so two characters do not walk a row's lane together).
""", world=True),
    "fetch_boxes20": _readme("fetch_boxes20", "paper 000, Experiment 5 (Figure 9)", """
20 characters start **seated** (`start = { seat = ... }`); each must pick up a designated box in
the second room (`box = ...`), put it down at a designated spot (a `position` goal with pose
`stand` reached from the carrying state: the put-down) and **return to its own seat**.

`world.usda`: room A (x 0..10, z 0..16) with 20 seats in four rows of five (1.6 m apart) facing
two corridors (rows back to back in the middle, behind a low divider); room B (x 10..25.5) with
ten lanes 1.5 m apart (z = 1.1 .. 14.9), two boxes on each (a near and a far one, all facing the
doors); two 3 m doors on the corridors' axes (z = 4 and 12). Each door serves the five lanes of
its half.

The layout follows from the default library:

- The carrying clips turn only while walking on (about 1 m per 60 degrees), so no one turns
  round with a box: a character picks its box up facing away from the door and puts it down
  3 m straight on along its lane.
- Everyone walks a straight line between its corridor's door and its lane, and the lanes
  nearest the door go first. A character walking back then crosses only lanes whose users
  went before it, and those are ahead of it on the same way back.
- The near boxes go first and the far ones second. A far carrier walks through its lane's
  near spots after they have been used. The far round leaves once the near round should be
  back in its seats; otherwise its first carriers would meet them head-on in the corridor and
  the door.
- Within a round, characters leave 6 s apart, those seated nearest the door first. The
  pick-up and put-down windows (2.5 s wide) are laid out from the distances, at 1 m/s walking,
  0.7 m/s carrying and about 3.5 s per pose change.
- The return to the seat has no window: a character sits down when it gets there.

Two planner settings matter here:

- **`[synthesis] approach_point = 2.0`.** Way points to a seat pass 2 m in front of it, and way
  points from a seat leave through that point. Characters therefore walk down the middle of
  the corridor, clear of the seated rows, and come in square between their seated neighbours.
- **Seat holds.** A character who starts seated holds its seat, for the frames before it could
  leave, until it is planned (`runtime/crowd/scheduler.py`, `_seat_hold`). A neighbour sitting
  down next to it, planned earlier, then turns round clear of its place.
""", world=True),
    "grid300": _readme("grid300", "paper 000, Experiment 6a (Figure 10)", """
300 characters on a uniform 20 x 15 grid (3.0 m spacing, facing +X) walk to a copy of the grid
translated 40 m along +X. Targets are perturbed while every path stays about equally long (the
paper's Figure 10): in each column, random pairs of neighbouring rows swap targets (seeded), so
about two characters in three cross a neighbour's lane while the whole block walks. Goals fix
only the position (no heading, pose or time). Characters are planned front column first.

Why 3 m: the library's walking bounding cylinders reach 0.6-0.72 m radius (arm swing), so at
2.2 m neighbours walking abreast are 1 m apart and no character can change lanes without the
whole column behind it waiting; the Figure 11 sweep in `bench/crowd_table.py` plans this grid
at 1.6-3.0 m (made by the generator's `grid_scenario(cols, rows, spacing, ...)`) and prints the
checker's verdict for each spacing.
"""),
    "grid500": _readme("grid500", "paper 000, Experiment 6b (Figure 10)", """
500 characters on a uniform 25 x 20 grid (3.0 m spacing, facing +X) walk to a copy of the grid
translated 47.5 m along +X, with neighbouring rows' targets swapped as in `grid300` (same
construction, seeded). The issue's target for this sample: all 500 planned in <= 0.9 s on a
2-core machine (paper: 0.90 s).

Planned with `[synthesis] start_still = true`: characters start on a standing node where they
can wait (an idle clip) rather than the walking hub also labelled "stand"; a character whose
plan fails is planned again from the other. Measured (session 4): start_still first, all 500
clean in one pass; hub first, 19 characters still failed (after the retry) before the
first pass was stopped. grid300 is
the other way round (hub first: clean in one pass), so it keeps the default.
"""),
}
def build_rooms_box(folder):
    _write(folder, rooms_scenario(), README["rooms_box"], rooms_world())


def build_theater40(folder):
    _write(folder, theater_scenario(), README["theater40"], theater_world())


def build_fetch_boxes20(folder):
    _write(folder, fetch_scenario(), README["fetch_boxes20"], fetch_world())


BUILDERS = {"rooms_box": build_rooms_box, "theater40": build_theater40, "fetch_boxes20": build_fetch_boxes20,
            "meet20": build_meet20, "spell70": build_spell70, "grid300": build_grid(300), "grid500": build_grid(500)}


# ----------------------------------------------------------------------------------------------
def main(argv=None) -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", help=f"samples to write (default all: {', '.join(SAMPLES)})")
    args = ap.parse_args(argv)
    names = args.names or list(SAMPLES)
    for name in names:
        if name not in BUILDERS:
            ap.error(f"unknown sample {name!r} (known: {', '.join(SAMPLES)})")
        BUILDERS[name](HERE / name)
        print(f"wrote {HERE / name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
