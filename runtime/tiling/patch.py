"""Motion patches (Kim, Hwang, Hyun and Lee 2012, section 3): the data model and the ``motion_patches`` pack.

Contract (shared by the authoring side, the tiler and the checker)
------------------------------------------------------------------
* :class:`Fragment` -- one character's motion inside a patch, sampled at the patch's ``fps``
  (30 Hz): ``t0`` start time in the patch (s); ``root_xz`` (F, 2) float64 root path in the
  *patch frame*; ``heading`` (F,) float64 radians, 0 facing +Z, unwrapped; ``root_height`` (F,)
  float32; ``rotations`` (F, J, 4) float32 w-x-y-z local joint rotations whose entry 0 is the
  root rotation *with its heading removed* (as in :class:`runtime.motion.clip.Clip`).
  ``entry_class`` / ``exit_class``: pose class (int) of the first / last frame; ``-1`` means the
  port is *closed* (the fragment starts at a source or ends at a sink: it can never be
  stitched and is only allowed where the environment has a source/sink or at the region's
  boundary). ``entry_open`` / ``exit_open`` default to ``class >= 0``. ``contacts`` (F, 4) bool:
  foot contacts per frame in :data:`runtime.motion.contacts.CONTACT_POINTS` order (None:
  unknown; the pack stores detected ones, :func:`fragment_contacts`).
* :class:`Constraint` -- an interpersonal constraint between frame ``frame_a`` of fragment
  ``frag_a`` and frame ``frame_b`` of fragment ``frag_b``: ``rel_position`` (2,) is b's root
  minus a's root expressed in a's heading frame, ``rel_direction`` = heading_b - heading_a
  (rad, wrapped to [-pi, pi)), ``dt`` = time_b - time_a (s), ``label`` (e.g. "contact").
  :meth:`Constraint.measure` fills the numbers from the fragments.
* :class:`Patch` -- ``name``, ``labels`` (tuple of str), ``fragments``, ``constraints``, ``fps``,
  derived ``entries`` / ``exits`` (:class:`Port`: fragment, kind, position, direction, time,
  pose_class, open), ``duration`` (s, from the earliest entry at t=0 to the latest exit) and
  per-fragment per-frame bounding boxes ``boxes[i]`` (F, 6) float32 = (xmin, ymin, zmin, xmax,
  ymax, zmax) of all joints and end sites *relative to the root in its heading frame* (x
  lateral, z forward; y absolute height). Because the boxes are local, they follow any path
  deformation: the world box at frame f is ``root_xz[f] + rotate_xz(corner, heading[f])``.
  :meth:`Patch.from_fragments` computes boxes by forward kinematics and (by default) recentres
  the patch: time so the earliest entry is at 0, space so the centre of the root paths' bounds
  is the origin.
* :class:`PatchLibrary` -- ``skeleton``, ``fps``, ``patches``, and the pose classes
  (``pose_class_names``; optional representative ``pose_class_rotations`` (C, J, 4) and
  ``pose_class_height`` (C,)). ``save(path)`` / ``PatchLibrary.load(path)``: pack kind
  ``"motion_patches"``, version 1 (runtime.assets), with structural validation that raises
  :class:`~runtime.assets.AssetError` naming the file and the problem.
* :func:`single_character_patches` -- one-character walking/turning/idle patches cut from a
  runtime :class:`~runtime.motion.graph.MotionGraph`: every edge (or short chain of edges) is
  a fragment whose entry/exit pose classes are the graph's hub nodes (``node:<id>``), so the
  pose at a matching exit and entry is identical by construction (snap-together hubs).

Stitching (Eq. 1-3) matches an exit to an entry of the same pose class: the two frames are the
same frame of the character (the entry repeats the exit), so a character's track is the
concatenation of its fragments with each later fragment's first frame dropped.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..assets import AssetError, pack_fields, save_pack
from ..motion.clip import Clip
from ..motion.contacts import contacts_of
from ..motion.fk import end_site_positions, forward_kinematics
from ..motion.planar import rotate_xz, wrap_angle
from ..motion.skeleton import Skeleton, load_motion_pack

__all__ = ["Fragment", "Constraint", "Port", "Patch", "PatchLibrary", "single_character_patches",
           "fragment_boxes", "fragment_contacts", "PACK_KIND", "PACK_VERSION"]

PACK_KIND = "motion_patches"
PACK_VERSION = 2


# --------------------------------------------------------------------------------------------
@dataclass(eq=False)
class Fragment:
    t0: float
    root_xz: np.ndarray        # (F, 2) float64, patch frame
    heading: np.ndarray        # (F,) float64 rad
    root_height: np.ndarray    # (F,) float32
    rotations: np.ndarray      # (F, J, 4) float32, [:, 0] heading-free root rotation
    entry_class: int = -1
    exit_class: int = -1
    entry_open: bool | None = None
    exit_open: bool | None = None
    contacts: np.ndarray | None = None   # (F, 4) bool, CONTACT_POINTS order

    def __post_init__(self):
        self.t0 = float(self.t0)
        self.heading = np.asarray(self.heading, dtype=np.float64).reshape(-1)
        F = len(self.heading)
        if F < 2:
            raise ValueError(f"a fragment needs at least 2 frames, got {F}")
        self.root_xz = np.asarray(self.root_xz, dtype=np.float64).reshape(F, 2)
        self.root_height = np.asarray(self.root_height, dtype=np.float32).reshape(F)
        rot = np.asarray(self.rotations, dtype=np.float32)
        if rot.ndim != 3 or rot.shape[0] != F or rot.shape[2] != 4:
            raise ValueError(f"rotations shape {rot.shape} != ({F}, J, 4)")
        self.rotations = rot
        self.entry_class = int(self.entry_class)
        self.exit_class = int(self.exit_class)
        if self.entry_open is None:
            self.entry_open = self.entry_class >= 0
        if self.exit_open is None:
            self.exit_open = self.exit_class >= 0
        self.entry_open = bool(self.entry_open)
        self.exit_open = bool(self.exit_open)
        if not (np.all(np.isfinite(self.root_xz)) and np.all(np.isfinite(self.heading))):
            raise ValueError("fragment root path has non-finite values")
        if self.contacts is not None:
            self.contacts = np.asarray(self.contacts, dtype=bool)
            if self.contacts.shape != (F, 4):
                raise ValueError(f"contacts shape {self.contacts.shape} != ({F}, 4)")

    @property
    def num_frames(self) -> int:
        return len(self.heading)

    def times(self, fps: float) -> np.ndarray:
        return self.t0 + np.arange(self.num_frames) / fps

    def t1(self, fps: float) -> float:
        return self.t0 + (self.num_frames - 1) / fps


@dataclass(eq=False)
class Constraint:
    frag_a: int
    frame_a: int
    frag_b: int
    frame_b: int
    rel_position: np.ndarray   # (2,) b - a in a's heading frame
    rel_direction: float       # heading_b - heading_a, wrapped
    dt: float                  # time_b - time_a
    label: str = "contact"

    def __post_init__(self):
        self.frag_a, self.frame_a = int(self.frag_a), int(self.frame_a)
        self.frag_b, self.frame_b = int(self.frag_b), int(self.frame_b)
        self.rel_position = np.asarray(self.rel_position, dtype=np.float64).reshape(2)
        self.rel_direction = float(self.rel_direction)
        self.dt = float(self.dt)
        self.label = str(self.label)

    @classmethod
    def measure(cls, fragments, frag_a: int, frame_a: int, frag_b: int, frame_b: int,
                label: str = "contact", fps: float = 30.0) -> "Constraint":
        """The constraint that holds in ``fragments`` as they are."""
        a, b = fragments[frag_a], fragments[frag_b]
        rel = rotate_xz(b.root_xz[frame_b] - a.root_xz[frame_a], -a.heading[frame_a])
        ddir = float(wrap_angle(b.heading[frame_b] - a.heading[frame_a]))
        dt = (b.t0 + frame_b / fps) - (a.t0 + frame_a / fps)
        return cls(frag_a, frame_a, frag_b, frame_b, rel, ddir, dt, label)


@dataclass(frozen=True)
class Port:
    """An entry (first frame) or exit (last frame) of a fragment, in the patch frame."""
    fragment: int
    kind: str                  # "entry" | "exit"
    position: np.ndarray       # (2,)
    direction: float           # heading, rad
    time: float                # s, patch time
    pose_class: int
    open: bool


def fragment_contacts(skeleton: Skeleton, fps: float, f: Fragment) -> np.ndarray:
    """``f.contacts``, or when unknown the contacts detected on its motion (``(F, 4)`` bool)."""
    if f.contacts is not None:
        return f.contacts
    return contacts_of(Clip(skeleton, fps, f.root_xz, f.heading, f.root_height, f.rotations))


def fragment_boxes(skeleton: Skeleton, root_height, rotations) -> np.ndarray:
    """Per-frame boxes (F, 6) float32 (xmin, ymin, zmin, xmax, ymax, zmax) of all joints and
    end sites relative to the root in its heading frame (root at x = z = 0)."""
    rot = np.asarray(rotations, dtype=np.float64)
    F = rot.shape[0]
    pos = np.zeros((F, 3))
    pos[:, 1] = np.asarray(root_height, dtype=np.float64)
    gr, gp = forward_kinematics(skeleton, pos, rot)
    pts = np.concatenate([gp, end_site_positions(skeleton, gr, gp)], axis=1)
    return np.concatenate([pts.min(axis=1), pts.max(axis=1)], axis=1).astype(np.float32)


# --------------------------------------------------------------------------------------------
@dataclass(eq=False)
class Patch:
    name: str
    labels: tuple
    fragments: list
    constraints: list
    boxes: list                # per fragment (F, 6) float32, see module docstring
    fps: float = 30.0
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.labels = tuple(str(x) for x in self.labels)
        self.fragments = list(self.fragments)
        self.constraints = list(self.constraints)
        if not self.fragments:
            raise ValueError(f"patch {self.name!r} has no fragments")
        n = len(self.fragments)
        for c in self.constraints:
            for fr, fi in ((c.frag_a, c.frame_a), (c.frag_b, c.frame_b)):
                if not (0 <= fr < n) or not (0 <= fi < self.fragments[fr].num_frames):
                    raise ValueError(f"patch {self.name!r}: constraint refers to fragment {fr} frame {fi}, out of range")
        if len(self.boxes) != n or any(b.shape != (f.num_frames, 6) for b, f in zip(self.boxes, self.fragments)):
            raise ValueError(f"patch {self.name!r}: boxes do not match the fragments")
        fps = float(self.fps)
        self.entries = [Port(i, "entry", f.root_xz[0].copy(), float(f.heading[0]), f.t0, f.entry_class, f.entry_open)
                        for i, f in enumerate(self.fragments)]
        self.exits = [Port(i, "exit", f.root_xz[-1].copy(), float(f.heading[-1]), f.t1(fps), f.exit_class, f.exit_open)
                      for i, f in enumerate(self.fragments)]
        self.t_start = min(f.t0 for f in self.fragments)
        self.t_end = max(f.t1(fps) for f in self.fragments)
        self.duration = self.t_end - self.t_start
        allxz = np.concatenate([f.root_xz for f in self.fragments])
        self.extent = float(np.max(np.linalg.norm(allxz, axis=1)))  # radius of the root paths about the origin

    @property
    def num_characters(self) -> int:
        return len(self.fragments)

    @property
    def num_frames(self) -> int:
        return sum(f.num_frames for f in self.fragments)

    @classmethod
    def from_fragments(cls, name, labels, skeleton: Skeleton, fragments, constraints=(), fps: float = 30.0,
                       recenter: bool = True, meta: dict | None = None) -> "Patch":
        frags = list(fragments)
        if not frags:
            raise ValueError(f"patch {name!r} has no fragments")
        J = skeleton.num_joints
        for i, f in enumerate(frags):
            if f.rotations.shape[1] != J:
                raise ValueError(f"patch {name!r} fragment {i}: {f.rotations.shape[1]} joints, skeleton has {J}")
        if recenter:
            t_shift = min(f.t0 for f in frags)
            allxz = np.concatenate([f.root_xz for f in frags])
            c = 0.5 * (allxz.min(axis=0) + allxz.max(axis=0))
            frags = [Fragment(f.t0 - t_shift, f.root_xz - c, f.heading, f.root_height, f.rotations,
                              f.entry_class, f.exit_class, f.entry_open, f.exit_open, f.contacts) for f in frags]
        boxes = [fragment_boxes(skeleton, f.root_height, f.rotations) for f in frags]
        return cls(str(name), tuple(labels), frags, list(constraints), boxes, float(fps), dict(meta or {}))

    def constraint_error(self) -> float:
        """Largest violation (m / rad / s mixed, as in the splice cost) of the patch's own
        constraints in its stored (undeformed) form: 0 when built with Constraint.measure."""
        err = 0.0
        for c in self.constraints:
            m = Constraint.measure(self.fragments, c.frag_a, c.frame_a, c.frag_b, c.frame_b, c.label, self.fps)
            err = max(err, float(np.max(np.abs(m.rel_position - c.rel_position))),
                      abs(float(wrap_angle(m.rel_direction - c.rel_direction))), abs(m.dt - c.dt))
        return err


# --------------------------------------------------------------------------------------------
@dataclass(eq=False)
class PatchLibrary:
    skeleton: Skeleton
    patches: list
    pose_class_names: list = field(default_factory=list)
    pose_class_rotations: np.ndarray | None = None   # (C, J, 4) float32 representative poses
    pose_class_height: np.ndarray | None = None      # (C,) float32
    fps: float = 30.0
    meta: dict = field(default_factory=dict)
    path: str | None = None

    def __post_init__(self):
        self.patches = list(self.patches)
        ncls = max([len(self.pose_class_names)] + [max(f.entry_class, f.exit_class) + 1
                                                     for p in self.patches for f in p.fragments])
        if len(self.pose_class_names) < ncls:
            self.pose_class_names = list(self.pose_class_names) + [f"class{i}" for i in range(len(self.pose_class_names), ncls)]
        self._by_name = {p.name: i for i, p in enumerate(self.patches)}
        self._flat = None

    def __len__(self):
        return len(self.patches)

    @property
    def num_pose_classes(self) -> int:
        return len(self.pose_class_names)

    def index(self, name: str) -> int:
        if name not in self._by_name:
            raise KeyError(f"patch library has no patch named {name!r}")
        return self._by_name[name]

    def with_label(self, label: str) -> list[int]:
        return [i for i, p in enumerate(self.patches) if label in p.labels]

    def ports_by_class(self, kind: str) -> dict[int, list[tuple[int, int]]]:
        """{pose class: [(patch, fragment), ...]} for open entries (kind="entry") or exits."""
        out: dict[int, list] = {}
        for pi, p in enumerate(self.patches):
            for port in (p.entries if kind == "entry" else p.exits):
                if port.open:
                    out.setdefault(port.pose_class, []).append((pi, port.fragment))
        return out

    def merged(self, other: "PatchLibrary") -> "PatchLibrary":
        """Both libraries' patches; pose classes matched by name (other's renumbered)."""
        if not self.skeleton.same_family(other.skeleton):
            raise ValueError("cannot merge patch libraries of different skeleton families")
        names = list(self.pose_class_names)
        remap = {}
        for i, n in enumerate(other.pose_class_names):
            if n not in names:
                names.append(n)
            remap[i] = names.index(n)
        remap[-1] = -1
        pats = list(self.patches)
        for p in other.patches:
            frags = [Fragment(f.t0, f.root_xz, f.heading, f.root_height, f.rotations, remap[f.entry_class],
                              remap[f.exit_class], f.entry_open, f.exit_open, f.contacts) for f in p.fragments]
            pats.append(Patch(p.name, p.labels, frags, p.constraints, p.boxes, p.fps, p.meta))
        rot = hgt = None
        if self.pose_class_rotations is not None and other.pose_class_rotations is not None:
            J = self.skeleton.num_joints
            rot = np.zeros((len(names), J, 4), np.float32)
            rot[..., 0] = 1
            hgt = np.zeros(len(names), np.float32)
            rot[:len(self.pose_class_rotations)] = self.pose_class_rotations
            hgt[:len(self.pose_class_height)] = self.pose_class_height
            for i, j in remap.items():
                if i >= 0 and i < len(other.pose_class_rotations) and j >= len(self.pose_class_rotations):
                    rot[j] = other.pose_class_rotations[i]
                    hgt[j] = other.pose_class_height[i]
        return PatchLibrary(self.skeleton, pats, names, rot, hgt, self.fps, {**other.meta, **self.meta})

    # -- pack ------------------------------------------------------------------------------
    def save(self, path) -> None:
        P = len(self.patches)
        frags = [f for p in self.patches for f in p.fragments]
        boxes = [b for p in self.patches for b in p.boxes]
        cons = [(pi, c) for pi, p in enumerate(self.patches) for c in p.constraints]
        J = self.skeleton.num_joints
        arrays = {
            "patch_frag_start": np.concatenate([[0], np.cumsum([len(p.fragments) for p in self.patches])]).astype(np.int64),
            "frag_frame_start": np.concatenate([[0], np.cumsum([f.num_frames for f in frags])]).astype(np.int64),
            "frag_t0": np.array([f.t0 for f in frags], np.float64),
            "frag_class": np.array([[f.entry_class, f.exit_class] for f in frags], np.int64).reshape(-1, 2),
            "frag_open": np.array([[f.entry_open, f.exit_open] for f in frags], np.uint8).reshape(-1, 2),
            "frame_xz": np.concatenate([f.root_xz for f in frags]) if frags else np.zeros((0, 2)),
            "frame_heading": np.concatenate([f.heading for f in frags]) if frags else np.zeros(0),
            "frame_height": np.concatenate([f.root_height for f in frags]).astype(np.float32) if frags else np.zeros(0, np.float32),
            "frame_rotations": np.concatenate([f.rotations for f in frags]).astype(np.float32) if frags else np.zeros((0, J, 4), np.float32),
            "frame_box": np.concatenate(boxes).astype(np.float32) if boxes else np.zeros((0, 6), np.float32),
            "frame_contacts": (np.concatenate([fragment_contacts(self.skeleton, self.fps, f) for f in frags])
                               if frags else np.zeros((0, 4), bool)),
            "con_patch": np.array([pi for pi, _ in cons], np.int64),
            "con_frames": np.array([[c.frag_a, c.frame_a, c.frag_b, c.frame_b] for _, c in cons], np.int64).reshape(-1, 4),
            "con_values": np.array([[*c.rel_position, c.rel_direction, c.dt] for _, c in cons], np.float64).reshape(-1, 4),
        }
        if self.pose_class_rotations is not None:
            arrays["pose_class_rotations"] = np.asarray(self.pose_class_rotations, np.float32)
            arrays["pose_class_height"] = np.asarray(self.pose_class_height, np.float32)
        meta = dict(self.meta)
        meta.update({
            "skeleton": self.skeleton.to_dict(), "fps": float(self.fps), "num_patches": P,
            "patch_names": [p.name for p in self.patches], "patch_labels": [list(p.labels) for p in self.patches],
            "patch_meta": [p.meta for p in self.patches],
            "constraint_labels": [c.label for _, c in cons], "pose_class_names": list(self.pose_class_names),
        })
        save_pack(path, PACK_KIND, PACK_VERSION, meta, arrays)

    @classmethod
    def load(cls, path) -> "PatchLibrary":
        pk, meta, sk, fps = load_motion_pack(path, PACK_KIND, PACK_VERSION, "motion patch pack is missing a field")
        with pack_fields(path, "motion patch pack is missing a field"):
            P = int(meta.pop("num_patches"))
            names = meta.pop("patch_names")
            labels = meta.pop("patch_labels")
            pmeta = meta.pop("patch_meta")
            clabels = meta.pop("constraint_labels")
            cnames = meta.pop("pose_class_names")
            a = pk.arrays
            pfs, ffs = a["patch_frag_start"], a["frag_frame_start"]
        NF, T, J = len(a["frag_t0"]), len(a["frame_heading"]), sk.num_joints
        problems = []
        if not (len(names) == len(labels) == len(pmeta) == P) or len(pfs) != P + 1:
            problems.append("patch tables have inconsistent lengths")
        elif pfs[0] != 0 or pfs[-1] != NF or np.any(np.diff(pfs) < 1):
            problems.append("patch_frag_start offsets invalid")
        if len(ffs) != NF + 1 or ffs[0] != 0 or ffs[-1] != T or np.any(np.diff(ffs) < 2):
            problems.append("frag_frame_start offsets invalid")
        for k, shp in (("frag_class", (NF, 2)), ("frag_open", (NF, 2)), ("frame_xz", (T, 2)),
                       ("frame_height", (T,)), ("frame_rotations", (T, J, 4)), ("frame_box", (T, 6)),
                       ("frame_contacts", (T, 4))):
            if a[k].shape != shp:
                problems.append(f"{k} shape {a[k].shape} != {shp}")
        NC = len(a["con_patch"])
        if a["con_frames"].shape != (NC, 4) or a["con_values"].shape != (NC, 4) or len(clabels) != NC:
            problems.append("constraint tables have inconsistent lengths")
        if NC and (a["con_patch"].min() < 0 or a["con_patch"].max() >= P):
            problems.append("constraint patch index out of range")
        if NF and (a["frag_class"].min() < -1 or a["frag_class"].max() >= len(cnames)):
            problems.append("pose class index out of range")
        if "pose_class_rotations" in a and (a["pose_class_rotations"].shape != (len(cnames), J, 4)
                                           or a["pose_class_height"].shape != (len(cnames),)):
            problems.append("pose class tables have the wrong shape")
        if not (np.all(np.isfinite(a["frame_xz"])) and np.all(np.isfinite(a["frame_heading"]))):
            problems.append("non-finite root path values")
        if problems:
            raise AssetError(path, "motion patch pack is inconsistent: " + "; ".join(problems))
        patches = []
        try:
            for pi in range(P):
                frags, boxes = [], []
                for fi in range(pfs[pi], pfs[pi + 1]):
                    s, e = ffs[fi], ffs[fi + 1]
                    frags.append(Fragment(a["frag_t0"][fi], a["frame_xz"][s:e], a["frame_heading"][s:e],
                                          a["frame_height"][s:e], a["frame_rotations"][s:e],
                                          a["frag_class"][fi, 0], a["frag_class"][fi, 1],
                                          bool(a["frag_open"][fi, 0]), bool(a["frag_open"][fi, 1]),
                                          a["frame_contacts"][s:e]))
                    boxes.append(a["frame_box"][s:e])
                sel = np.flatnonzero(a["con_patch"] == pi)
                cons = [Constraint(*a["con_frames"][k], a["con_values"][k, :2], a["con_values"][k, 2],
                                   a["con_values"][k, 3], clabels[k]) for k in sel]
                patches.append(Patch(names[pi], tuple(labels[pi]), frags, cons, boxes, fps, dict(pmeta[pi])))
        except (ValueError, IndexError) as e:
            raise AssetError(path, f"motion patch pack is inconsistent: patch {pi}: {e}") from None
        return cls(sk, patches, list(cnames), a.get("pose_class_rotations"), a.get("pose_class_height"), fps,
                   meta, str(path))

    # -- flat pose tables (the MotionGraph layout, so runtime.crowd.tracks.evaluate_poses works) --
    def _flat_frames(self):
        if getattr(self, "_flat", None) is None:
            offs, rots, hts, cts = {}, [], [], []
            n = 0
            for pi, p in enumerate(self.patches):
                for k, f in enumerate(p.fragments):
                    offs[(pi, k)] = n
                    rots.append(f.rotations)
                    hts.append(f.root_height)
                    cts.append(fragment_contacts(self.skeleton, self.fps, f))
                    n += f.num_frames
            J = self.skeleton.num_joints
            self._flat = (np.concatenate(rots) if rots else np.zeros((0, J, 4), np.float32),
                          np.concatenate(hts).astype(np.float64) if hts else np.zeros(0), offs,
                          np.concatenate(cts) if cts else np.zeros((0, 4), bool))
        return self._flat

    @property
    def frame_rotations(self) -> np.ndarray:
        """(T, J, 4) float32: every fragment frame of every patch, flat."""
        return self._flat_frames()[0]

    @property
    def frame_height(self) -> np.ndarray:
        """(T,) float64 root heights, flat like :attr:`frame_rotations`."""
        return self._flat_frames()[1]

    @property
    def frame_contacts(self) -> np.ndarray:
        """(T, 4) bool foot contacts, flat like :attr:`frame_rotations`."""
        return self._flat_frames()[3]

    def fragment_offset(self, patch: int, fragment: int) -> int:
        """Row of (patch, fragment)'s first frame in the flat tables."""
        return self._flat_frames()[2][(patch, fragment)]

    def summary(self) -> dict:
        from collections import Counter
        chars = Counter(p.num_characters for p in self.patches)
        labs = Counter(l for p in self.patches for l in p.labels)
        return {"patches": len(self.patches), "characters_per_patch": dict(sorted(chars.items())),
                "labels": dict(sorted(labs.items())), "pose_classes": self.num_pose_classes,
                "constraints": sum(len(p.constraints) for p in self.patches),
                "seconds": round(sum(f.t1(self.fps) - f.t0 for p in self.patches for f in p.fragments), 2)}


# --------------------------------------------------------------------------------------------
DEFAULT_SINGLE_LABELS = ("walk", "turn", "idle", "start", "stop")


def single_character_patches(graph, labels=DEFAULT_SINGLE_LABELS, states=("walking",), max_per_pair: int = 10,
                             min_frames: int = 8, seed: int = 0, name_prefix: str = "single",
                             include_transitions: bool = False) -> PatchLibrary:
    """Single-character patches cut from a runtime MotionGraph.

    Every edge of the given ``states`` carrying one of ``labels`` becomes a one-fragment patch:
    entry class = the edge's source hub, exit class = its destination hub (pose classes are
    named ``node:<id>``; every graph node gets a class, so class ``i`` is node ``i`` and the
    representative pose is the hub pose). At most ``max_per_pair`` edges per (src, dst) pair
    are kept, chosen to spread the heading change (sorted by heading change, evenly picked;
    ties broken by ``seed``). Patch labels are the edge labels (plus "single").
    ``include_transitions`` also admits edges between states (pick up, put down, sit down).
    Runtime-side on purpose: it only reads the graph's frame arrays, so a shipped game can
    build a tiling library from its motion graph without the authoring tools.
    """
    rng = np.random.default_rng(seed)
    st = [graph.state_index(s) for s in states] + ([-1] if include_transitions else [])
    want = set(labels)
    cand = [e for e in range(graph.num_edges)
            if graph.edge_state[e] in st and want.intersection(graph.edge_labels[e]) and graph.edge_frames[e] >= min_frames]
    by_pair: dict = {}
    for e in cand:
        by_pair.setdefault((int(graph.edge_src[e]), int(graph.edge_dst[e])), []).append(e)
    keep = []
    for pair in sorted(by_pair):
        es = np.array(by_pair[pair])
        if len(es) > max_per_pair:
            order = np.lexsort((rng.random(len(es)), graph.edge_disp[es, 2]))
            es = es[order[np.round(np.linspace(0, len(es) - 1, max_per_pair)).astype(int)]]
        keep.extend(int(e) for e in es)
    keep.sort()
    patches = []
    for e in keep:
        a, b = graph.edge_start[e], graph.edge_start[e + 1]
        frag = Fragment(0.0, graph.frame_xz[a:b], graph.frame_heading[a:b], graph.frame_height[a:b],
                        graph.frame_rotations[a:b], int(graph.edge_src[e]), int(graph.edge_dst[e]),
                        contacts=graph.frame_contacts[a:b])
        patches.append(Patch.from_fragments(f"{name_prefix}_e{e}", tuple(graph.edge_labels[e]) + ("single",),
                                            graph.skeleton, [frag], (), graph.fps, meta={"edge": e}))
    return PatchLibrary(graph.skeleton, patches, [f"node:{i}" for i in range(graph.num_nodes)],
                        np.asarray(graph.node_rotations, np.float32), np.asarray(graph.node_height, np.float32),
                        graph.fps, {"source": "motion_graph", "graph": str(graph.path or ""),
                                    **{k: graph.meta[k] for k in ("knee_flexion_deg",) if k in graph.meta}})

