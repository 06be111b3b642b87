"""Skeleton: joint names, parents, rest offsets (metres), end sites.

Joints are stored in topological order (every parent precedes its children), which is
what BVH gives and what the level-by-level forward kinematics relies on.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from ..assets import load_pack, pack_fields

__all__ = ["Skeleton", "SkeletonMismatchError", "KNOWN_FAMILIES", "pop_skeleton_and_fps", "load_motion_pack"]


class SkeletonMismatchError(ValueError):
    """Two motion sources use skeletons of different families."""


# Fingerprints (joint names + topology) of the skeleton families in the CMU developer set,
# see ../shared/mocap/cmu/README.md. The procedural generator uses family "cmu-mb".
KNOWN_FAMILIES: dict[str, str] = {}


@dataclass(frozen=True, eq=False)
class Skeleton:
    names: tuple[str, ...]
    parents: np.ndarray            # (J,) int, -1 for the root
    offsets: np.ndarray            # (J, 3) float64, metres, rest offset from the parent
    end_sites: tuple[tuple[int, tuple[float, float, float]], ...] = ()  # (joint, offset in metres)
    _index: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        parents = np.asarray(self.parents, dtype=np.int64)
        offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "names", tuple(self.names))
        if not (len(self.names) == len(parents) == len(offsets)):
            raise ValueError("names, parents and offsets must have the same length")
        if len(parents) == 0 or parents[0] != -1:
            raise ValueError("joint 0 must be the root (parent -1)")
        if np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, len(parents))):
            raise ValueError("joints must be in topological order (parent index < child index)")
        if len(set(self.names)) != len(self.names):
            raise ValueError("joint names must be unique")
        self._index.update({n: i for i, n in enumerate(self.names)})
        # depth levels for level-by-level FK
        depth = np.zeros(len(parents), dtype=np.int64)
        for j in range(1, len(parents)):
            depth[j] = depth[parents[j]] + 1
        object.__setattr__(self, "depth", depth)
        object.__setattr__(self, "levels", tuple(np.flatnonzero(depth == d) for d in range(1, depth.max() + 1)))

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"skeleton has no joint named {name!r}") from None

    def indices(self, names) -> np.ndarray:
        return np.array([self.index(n) for n in names], dtype=np.int64)

    def has(self, name: str) -> bool:
        return name in self._index

    def children(self, j: int) -> np.ndarray:
        return np.flatnonzero(self.parents == j)

    @property
    def fingerprint(self) -> str:
        """Hash of joint names and topology (not bone lengths): equal within a family."""
        h = hashlib.sha1()
        for n, p in zip(self.names, self.parents):
            h.update(f"{n}:{int(p)};".encode())
        return h.hexdigest()[:16]

    @property
    def family(self) -> str:
        return KNOWN_FAMILIES.get(self.fingerprint, f"custom-{self.fingerprint[:8]}")

    def same_family(self, other: "Skeleton") -> bool:
        return self.fingerprint == other.fingerprint

    def scaled(self, s: float) -> "Skeleton":
        return Skeleton(self.names, self.parents.copy(), self.offsets * s,
                        tuple((j, tuple(float(x) * s for x in o)) for j, o in self.end_sites))

    def mirror_map(self) -> np.ndarray:
        """Index of each joint's left/right counterpart (itself for centre joints)."""
        out = np.arange(self.num_joints)
        pairs = (("Left", "Right"), ("left", "right"), ("L", "R"), ("l", "r"))
        for i, n in enumerate(self.names):
            for a, b in pairs:
                for x, y in ((a, b), (b, a)):
                    if n.startswith(x) and self.has(y + n[len(x):]):
                        out[i] = self.index(y + n[len(x):])
                        break
                    if x in ("Left", "Right") and x in n and self.has(n.replace(x, y)):
                        out[i] = self.index(n.replace(x, y))
                        break
                if out[i] != i:
                    break
        return out

    # -- serialisation (packs) -------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "names": list(self.names),
            "parents": [int(p) for p in self.parents],
            "offsets": self.offsets.tolist(),
            "end_sites": [[int(j), list(o)] for j, o in self.end_sites],
        }

    @classmethod
    def from_dict(cls, d: dict) -> "Skeleton":
        return cls(tuple(d["names"]), np.array(d["parents"]), np.array(d["offsets"], dtype=np.float64),
                   tuple((int(j), tuple(o)) for j, o in d.get("end_sites", [])))


def pop_skeleton_and_fps(meta: dict) -> tuple:
    """(Skeleton, fps) taken out of a pack's ``meta`` (the ``skeleton`` and ``fps`` keys every
    pack of posed motion carries)."""
    return Skeleton.from_dict(meta.pop("skeleton")), float(meta.pop("fps"))


def load_motion_pack(path, kind: str, version: int, what: str) -> tuple:
    """A pack of posed motion: (the loaded pack, its meta without the skeleton and fps,
    Skeleton, fps); a bad skeleton or fps is an AssetError naming ``path`` and ``what``."""
    pk = load_pack(path, kind=kind, version=version)
    with pack_fields(path, what):
        meta = dict(pk.meta)
        sk, fps = pop_skeleton_and_fps(meta)
    return pk, meta, sk, fps


def _register(name: str, names, parents):
    sk = Skeleton(tuple(names), np.array(parents), np.zeros((len(names), 3)))
    KNOWN_FAMILIES[sk.fingerprint] = name


# Family A: CMU / cgspeed MotionBuilder-friendly, 31 joints (legs, spine and head, arms).
CMU_MB_NAMES = tuple("""Hips LHipJoint LeftUpLeg LeftLeg LeftFoot LeftToeBase RHipJoint RightUpLeg RightLeg RightFoot
    RightToeBase LowerBack Spine Spine1 Neck Neck1 Head LeftShoulder LeftArm LeftForeArm LeftHand LeftFingerBase
    LeftHandIndex1 LThumb RightShoulder RightArm RightForeArm RightHand RightFingerBase RightHandIndex1 RThumb""".split())
CMU_MB_PARENTS = (-1, 0, 1, 2, 3, 4, 0, 6, 7, 8, 9, 0, 11, 12, 13, 14, 15,
                  13, 17, 18, 19, 20, 21, 20, 13, 24, 25, 26, 27, 28, 27)
_register("cmu-mb", CMU_MB_NAMES, CMU_MB_PARENTS)

# Family B: cgspeed 3dsMax-friendly, 31 joints (the same tree as family A).
CMU_MAX_NAMES = tuple("""Hips LHipJoint LeftHip LeftKnee LeftAnkle LeftToe RHipJoint RightHip RightKnee RightAnkle
    RightToe lowerback Chest Chest2 lowerneck Neck Head LeftCollar LeftShoulder LeftElbow LeftWrist lhand LFingers
    LThumb RightCollar RightShoulder RightElbow RightWrist rhand RFingers RThumb""".split())
_register("cmu-3dsmax", CMU_MAX_NAMES, CMU_MB_PARENTS)

# Family C: cgspeed DAZ-friendly, 43 joints.
_DAZ = [
    ("hip", -1), ("abdomen", "hip"), ("chest", "abdomen"), ("neck", "chest"), ("head", "neck"),
    ("leftEye", "head"), ("rightEye", "head"),
    ("rCollar", "chest"), ("rShldr", "rCollar"), ("rForeArm", "rShldr"), ("rHand", "rForeArm"),
    ("rThumb1", "rHand"), ("rThumb2", "rThumb1"), ("rIndex1", "rHand"), ("rIndex2", "rIndex1"),
    ("rMid1", "rHand"), ("rMid2", "rMid1"), ("rRing1", "rHand"), ("rRing2", "rRing1"),
    ("rPinky1", "rHand"), ("rPinky2", "rPinky1"),
    ("lCollar", "chest"), ("lShldr", "lCollar"), ("lForeArm", "lShldr"), ("lHand", "lForeArm"),
    ("lThumb1", "lHand"), ("lThumb2", "lThumb1"), ("lIndex1", "lHand"), ("lIndex2", "lIndex1"),
    ("lMid1", "lHand"), ("lMid2", "lMid1"), ("lRing1", "lHand"), ("lRing2", "lRing1"),
    ("lPinky1", "lHand"), ("lPinky2", "lPinky1"),
    ("rButtock", "hip"), ("rThigh", "rButtock"), ("rShin", "rThigh"), ("rFoot", "rShin"),
    ("lButtock", "hip"), ("lThigh", "lButtock"), ("lShin", "lThigh"), ("lFoot", "lShin"),
]
_daz_names = [n for n, _ in _DAZ]
_register("cmu-daz", _daz_names, [-1 if p == -1 else _daz_names.index(p) for _, p in _DAZ])
