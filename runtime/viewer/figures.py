"""Characters as capsules, on the CPU (numpy only, no GL): which capsules make a figure
(:class:`FigureStyle`, from the skeleton's joint names), their colours
(:func:`character_palette`), and the per-frame data of the two levels of detail the viewer
draws (:mod:`runtime.viewer.characters`).

Level of detail: a figure at least :data:`LOD_NEAR_PX` tall on screen is drawn bone by bone
(every limb segment, ``FigureStyle.near``); a smaller one as one screen-space quad holding its
:data:`FIGURE_CAPSULES` capsules (body, head, whole legs and arms; ``FigureStyle.far``)
projected to pixels by :func:`figure_vertices`. A figure at least :data:`SHADOW_PX` tall gets
a blob shadow.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FigureStyle", "BoneSet", "character_palette", "PARTS", "FIGURE_HEIGHT", "LOD_NEAR_PX", "SHADOW_PX",
           "FIGURE_CAPSULES", "PROP_CAPSULES", "figure_sizes", "bone_arrays", "prop_arrays", "figure_vertices"]

PARTS = ("skin", "shirt", "trousers", "shoes")
FIGURE_HEIGHT = 1.75       # metres, for the on-screen size of a figure
LOD_NEAR_PX = 70.0         # figures at least this tall on screen get every limb segment
SHADOW_PX = 28.0           # and at least this tall a blob shadow
FIGURE_CAPSULES = 6        # capsules of a far figure (its one quad carries them all)


@dataclass
class BoneSet:
    """Capsules of one level of detail: bone ``k`` runs from point ``a[k]`` to ``b[k]`` with
    ``radius[k]`` and colour ``part[k]`` (index into :data:`PARTS`)."""
    a: np.ndarray
    b: np.ndarray
    radius: np.ndarray
    part: np.ndarray

    def __len__(self):
        return len(self.a)


@dataclass
class FigureStyle:
    """How a skeleton becomes capsules, at two levels of detail: ``near`` (every limb segment,
    14 capsules for the CMU skeleton) and ``far`` (6 capsules: body, head, whole legs and arms;
    used when a figure is small on screen). Points are the skeleton's joints followed by
    virtual points ``virtual[v] = (joint, from_joint, length)`` placed at
    ``P[joint] + length * unit(P[joint] - P[from_joint])`` (the head top)."""
    near: BoneSet
    far: BoneSet
    virtual: tuple
    num_joints: int
    props: dict = field(default_factory=dict)   # prop kind -> (joint, joint it points away from)

    @classmethod
    def for_skeleton(cls, skeleton) -> "FigureStyle":
        names = skeleton.names
        cmu = ("Hips", "LeftUpLeg", "RightUpLeg", "LeftLeg", "LeftFoot", "Spine1", "Neck", "Head",
               "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightLeg", "RightFoot", "RightForeArm",
               "RightHand")
        if all(n in names for n in cmu):
            return cls._cmu(skeleton)
        return cls._generic(skeleton)

    @classmethod
    def _cmu(cls, sk) -> "FigureStyle":
        J = sk.num_joints
        ix = sk.index
        neck = "Neck1" if sk.has("Neck1") else "Neck"
        virtual = [(ix("Head"), ix(neck), 0.15)]
        HEAD_TOP = J

        def bones(spec):
            a, b, r, p = [], [], [], []
            for u, v, rad, part in spec:
                if (isinstance(u, str) and not sk.has(u)) or (isinstance(v, str) and not sk.has(v)):
                    continue
                a.append(u if isinstance(u, int) else ix(u))
                b.append(v if isinstance(v, int) else ix(v))
                r.append(rad)
                p.append(part)
            return BoneSet(np.array(a), np.array(b), np.array(r, dtype=np.float32), np.array(p))

        near = [("Hips", "Spine1", 0.115, 1), ("Spine1", "Neck", 0.125, 1), ("LeftArm", "RightArm", 0.062, 1),
                ("Head", HEAD_TOP, 0.095, 0)]
        far = [("Hips", "Neck", 0.135, 1), ("Head", HEAD_TOP, 0.1, 0)]
        for side in ("Left", "Right"):
            hand = next((f"{side}{h}" for h in ("HandIndex1", "FingerBase") if sk.has(f"{side}{h}")), f"{side}Hand")
            near += [(f"{side}UpLeg", f"{side}Leg", 0.07, 2), (f"{side}Leg", f"{side}Foot", 0.052, 2),
                     (f"{side}Foot", f"{side}ToeBase", 0.042, 3),
                     (f"{side}Arm", f"{side}ForeArm", 0.05, 1), (f"{side}ForeArm", hand, 0.04, 0)]
            far += [(f"{side}UpLeg", f"{side}Foot", 0.065, 2), (f"{side}Arm", f"{side}Hand", 0.048, 1)]
        props = {"hat": (ix("Head"), ix(neck))}
        if sk.has("RightHand") and sk.has("RightForeArm"):
            props["bag"] = (ix("RightHand"), ix("RightForeArm"))
        return cls(bones(near), bones(far), tuple(virtual), J, props)

    @classmethod
    def _generic(cls, sk) -> "FigureStyle":
        L = np.linalg.norm(sk.offsets, axis=1)
        js = np.flatnonzero((sk.parents >= 0) & (L > 0.03))
        r = np.clip(L[js] * 0.18, 0.025, 0.07).astype(np.float32)
        bs = BoneSet(sk.parents[js], js, r, np.ones(len(js), dtype=np.int64))
        return cls(bs, bs, (), sk.num_joints)

    def points(self, positions: np.ndarray) -> np.ndarray:
        """Joint positions (N, J, 3) followed by the virtual points: (N, J + V, 3) float32."""
        P = np.asarray(positions, dtype=np.float32)
        if not self.virtual:
            return np.ascontiguousarray(P)
        extra = []
        for j, f, length in self.virtual:
            d = P[:, j] - P[:, f]
            d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-6)
            extra.append(P[:, j] + length * d)
        return np.concatenate([P, np.stack(extra, axis=1)], axis=1)


_SHIRTS = np.array([[0.86, 0.26, 0.22], [0.20, 0.48, 0.80], [0.95, 0.68, 0.16], [0.22, 0.66, 0.42],
                    [0.62, 0.32, 0.72], [0.94, 0.94, 0.92], [0.16, 0.70, 0.76], [0.90, 0.44, 0.62],
                    [0.55, 0.78, 0.25], [0.98, 0.52, 0.18], [0.30, 0.34, 0.62], [0.80, 0.16, 0.40]])
_TROUSERS = np.array([[0.18, 0.22, 0.34], [0.26, 0.26, 0.28], [0.40, 0.32, 0.22], [0.14, 0.30, 0.46],
                      [0.34, 0.36, 0.30], [0.48, 0.44, 0.38]])
_SKIN = np.array([[0.96, 0.80, 0.66], [0.88, 0.68, 0.52], [0.72, 0.52, 0.38], [0.52, 0.36, 0.26],
                  [0.98, 0.86, 0.74]])
_SHOES = np.array([[0.12, 0.11, 0.10], [0.36, 0.24, 0.16], [0.82, 0.82, 0.80]])


def character_palette(n: int, seed: int = 7) -> np.ndarray:
    """Colours (n, len(PARTS), 3) float32; character ``i`` gets the same colours whatever ``n``
    (an integer hash of ``i`` and ``seed`` picks from each part's palette)."""
    i = np.arange(n, dtype=np.uint64)
    out = np.empty((n, len(PARTS), 3), dtype=np.float32)
    for k, pal in enumerate((_SKIN, _SHIRTS, _TROUSERS, _SHOES)):
        h = (i + np.uint64(seed * 7919 + k * 104729)) * np.uint64(2654435761)
        h ^= h >> np.uint64(13)
        h = (h * np.uint64(0x9E3779B1)) & np.uint64(0xFFFFFFFF)
        out[:, k] = pal[(h >> np.uint64(8)) % np.uint64(len(pal))]
    return out


# -- per frame: level of detail ----------------------------------------------------------------------

def figure_sizes(P: np.ndarray, view: np.ndarray, proj: np.ndarray, height: int):
    """On-screen height (pixels) and view depth (metres) of every figure, from the roots of
    the points ``P`` (N, J + V, 3)."""
    root = P[:, 0].astype(np.float64)
    depth = -(root @ view[2, :3] + view[2, 3])
    px = FIGURE_HEIGHT * proj[1, 1] * 0.5 * height / np.maximum(depth, 1e-3)
    return px, depth


# a prop's capsule: (start, end) distances past its joint along (joint - from joint), radius
PROP_CAPSULES = {"hat": (0.17, 0.24, 0.105), "bag": (0.08, 0.32, 0.08)}


def prop_arrays(P: np.ndarray, idx: np.ndarray, style: FigureStyle, prop: np.ndarray, colour: np.ndarray):
    """Capsules of the props (:data:`runtime.appearance.PROPS`: 1 a hat, 2 a bag in the right
    hand) of figures ``idx`` that have one, as :func:`bone_arrays` returns them. ``prop`` (N,)
    and ``colour`` (N, 3) are every figure's prop and prop colour."""
    ends, styles = [], []
    for code, kind in ((1, "hat"), (2, "bag")):
        if kind not in style.props:
            continue
        sel = idx[prop[idx] == code]
        if not len(sel):
            continue
        j, f = style.props[kind]
        d = P[sel, j] - P[sel, f]
        d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-6)
        a, b, r = PROP_CAPSULES[kind]
        e = np.empty((len(sel), 2, 3), dtype=np.float32)
        e[:, 0] = P[sel, j] + a * d
        e[:, 1] = P[sel, j] + b * d
        y = np.empty((len(sel), 4), dtype=np.float32)
        y[:, 0] = r
        y[:, 1:] = colour[sel]
        ends.append(e.reshape(-1, 3))
        styles.append(y)
    if not ends:
        return np.zeros((0, 3), np.float32), np.zeros((0, 4), np.float32)
    return np.concatenate(ends), np.concatenate(styles)


def bone_arrays(P: np.ndarray, idx: np.ndarray, bones: BoneSet, palette: np.ndarray, width: np.ndarray | None = None):
    """The capsules ``bones`` of figures ``idx`` of the points ``P`` (N, J + V, 3), for the
    capsule shaders' buffer textures: endpoints (len(idx) * len(bones) * 2, 3) float32 and
    styles (len(idx) * len(bones), 4) = radius, rgb, figure by figure. ``palette`` (N, parts, 3)
    holds the colours of all N figures (:meth:`runtime.appearance.Looks.colours`), ``width``
    (N,) their body width factors (radii are scaled by them)."""
    e = np.empty((len(idx), len(bones), 2, 3), dtype=np.float32)
    Q = P[idx]
    e[:, :, 0] = Q[:, bones.a]
    e[:, :, 1] = Q[:, bones.b]
    y = np.empty((len(idx), len(bones), 4), dtype=np.float32)
    y[:, :, 0] = bones.radius if width is None else bones.radius[None, :] * width[idx][:, None]
    y[:, :, 1:] = palette[idx][:, bones.part]
    return e.reshape(-1, 3), y.reshape(-1, 4)


def figure_vertices(P: np.ndarray, idx: np.ndarray, bones: BoneSet, palette: np.ndarray, view: np.ndarray,
                    proj: np.ndarray, width: int, height: int, fog, body_width: np.ndarray | None = None
                    ) -> np.ndarray:
    """Vertex data (6 per figure, 52 floats each) of the far figures ``idx`` of the points
    ``P`` (N, J + V, 3): a screen-space quad around the figure's projected capsules ``bones``
    (:data:`FIGURE_CAPSULES` of them), and the capsules themselves in window pixels (see
    ``shaders/figure.vert``).

    Args:
        palette: the colours (N, parts, 3) of all N figures.
        fog: fog start and end (metres from the eye).
        body_width: (N,) body width factors of all N figures (radii are scaled by them).
    """
    bs = bones
    m, k = len(idx), len(bs)
    ends = np.concatenate([bs.a, bs.b])                               # (2k,)
    Q = P[idx][:, ends].reshape(-1, 3).astype(np.float64)             # (M * 2k, 3)
    V = Q @ view[:3, :3].T + view[:3, 3]                              # 2-D matmul (BLAS)
    w = np.maximum(-V[:, 2], 1e-3)
    fy = proj[1, 1] * 0.5 * height
    px = ((V[:, 0] * proj[0, 0] + V[:, 2] * proj[0, 2]) / w + 1.0) * (0.5 * width)
    py = ((V[:, 1] * proj[1, 1] + V[:, 2] * proj[1, 2]) / w + 1.0) * (0.5 * height)
    px, py, w = px.reshape(m, 2 * k), py.reshape(m, 2 * k), w.reshape(m, 2 * k)
    wm = 0.5 * (w[:, :k] + w[:, k:])                                  # (M, k)
    rad = bs.radius[None, :] if body_width is None else bs.radius[None, :] * body_width[idx][:, None]
    r = np.maximum(rad * fy / wm, 0.6)                                # pixels
    x0 = np.minimum(px[:, :k], px[:, k:]) - r
    x1 = np.maximum(px[:, :k], px[:, k:]) + r
    y0 = np.minimum(py[:, :k], py[:, k:]) - r
    y1 = np.maximum(py[:, :k], py[:, k:]) + r
    lox, hix, loy, hiy = x0[:, 0], x1[:, 0], y0[:, 0], y1[:, 0]
    for c in range(1, k):                                             # (M,) pixel box
        lox, hix = np.minimum(lox, x0[:, c]), np.maximum(hix, x1[:, c])
        loy, hiy = np.minimum(loy, y0[:, c]), np.maximum(hiy, y1[:, c])
    root = P[idx, 0].astype(np.float64)
    Vr = root @ view[:3, :3].T + view[:3, 3]
    zr = (Vr @ proj[2, :3] + proj[2, 3]) / np.maximum(-Vr[:, 2], 1e-3)
    dist = np.sqrt(np.einsum("ij,ij->i", Vr, Vr))
    f = np.clip((dist - fog[0]) / (fog[1] - fog[0]), 0.0, 1.0) ** 2
    pal = palette[idx]                                                # (M, parts, 3)
    data = np.zeros((m, 52), dtype=np.float32)
    data[:, 2] = zr
    data[:, 3] = f
    seg = data[:, 4:28].reshape(m, k, 4)
    seg[:, :, 0], seg[:, :, 1] = px[:, :k], py[:, :k]
    seg[:, :, 2], seg[:, :, 3] = px[:, k:], py[:, k:]
    data[:, 28:34] = r
    data[:, 34:36] = wm[:, 0:2]
    data[:, 36:40] = wm[:, 2:6]
    data[:, 40:43] = pal[:, 0]
    data[:, 44:47] = pal[:, 1]
    data[:, 48:51] = pal[:, 2]
    out = np.repeat(data[:, None, :], 6, axis=1)                      # (M, 6, 52)
    sx, sy = 2.0 / width, 2.0 / height
    ax, bx = lox * sx - 1.0, hix * sx - 1.0
    ay, by = loy * sy - 1.0, hiy * sy - 1.0
    for v, (cx, cy) in enumerate(((ax, ay), (bx, ay), (bx, by), (ax, ay), (bx, by), (ax, by))):
        out[:, v, 0] = cx
        out[:, v, 1] = cy
    return out.reshape(-1, 52)
