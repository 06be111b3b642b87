"""A finished tiling: the deformed patch instances, who is who, and tracks for baking/drawing.

:class:`TilingResult` holds, per instance, the library patch, its rigid placement, whether it is
a keyframe, and its *deformed* fragments in the world (root xz, heading and time per source
frame, flat over the patch's fragments). ``links`` (L, 4) lists the stitches as
``(exit instance, exit fragment, entry instance, entry fragment)``.

Characters (identity continuous across stitched patches): :meth:`TilingResult.characters` follows
the links from every fragment whose entry is not stitched; each character is the list of
``(instance, fragment)`` it plays. :meth:`TilingResult.tracks` resamples every character on the
clock (``fps``) into a :class:`CharacterTrack` -- the :class:`runtime.crowd.tracks.Track` layout
(``frames_a``/``frames_b``/``frames_t`` index the library's flat pose tables
``PatchLibrary.frame_rotations`` / ``frame_height``; ``root`` = x, z, heading continuous), so
``runtime.crowd.tracks.evaluate_poses(result.library, ...)`` gives root positions and local
rotations for a bake (one SkelRoot per character) or the viewer.

Pack: kind ``"motion_tiling"``, version 1: placements, links, and the deformed paths (float32 root
positions and headings, float64 times) of
the instances that are not exactly their rigid placement (``inst_rigid`` marks those; they are
placed again from the library on load). The library is not embedded: pass it to
:meth:`TilingResult.load`, which checks that patch names and frame counts agree.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..assets import AssetError, load_pack, pack_fields, save_pack
from ..crowd.tracks import Track, evaluate_poses
from ..motion.planar import rotate_xz_scalar
from .region import Obstacle, Portal, Region

__all__ = ["TilingResult", "CharacterTrack", "continue_heading", "PACK_KIND", "PACK_VERSION"]

PACK_KIND = "motion_tiling"
PACK_VERSION = 1


def continue_heading(h, last):
    """Headings ``h`` of a fragment shifted by whole turns so that they continue a track whose
    previous heading is ``last`` (a character's heading stays continuous across stitches)."""
    return h + 2 * np.pi * np.round((last - h[0]) / (2 * np.pi))


@dataclass
class CharacterTrack(Track):
    """A tiled character on the clock: Track fields plus the (instance, fragment) segments it
    plays, each with the clock frame where it starts."""
    segments: list = field(default_factory=list)   # [(instance, fragment, first clock frame)]

    def to_track(self) -> Track:
        return Track(self.frames_a, self.frames_b, self.frames_t, self.root, self.start_frame)


@dataclass
class TilingResult:
    library: object                    # PatchLibrary
    region: Region
    patch: list
    place: list
    fixed: list
    xz: list
    heading: list
    time: list
    links: np.ndarray
    obstacles: list = field(default_factory=list)
    portals: list = field(default_factory=list)
    fps: float = 30.0
    info: dict = field(default_factory=dict)

    @property
    def num_instances(self) -> int:
        return len(self.patch)

    def frag_slices(self, i: int):
        p = self.library.patches[self.patch[i]]
        n = np.concatenate([[0], np.cumsum([f.num_frames for f in p.fragments])])
        return [slice(int(n[k]), int(n[k + 1])) for k in range(len(p.fragments))]

    # -- identity ------------------------------------------------------------------------------
    def characters(self) -> list:
        nxt = {(int(a), int(b)): (int(c), int(d)) for a, b, c, d in self.links}
        has_prev = set(nxt.values())
        chars = []
        for i in range(self.num_instances):
            for k in range(self.library.patches[self.patch[i]].num_characters):
                if (i, k) in has_prev:
                    continue
                chain = [(i, k)]
                seen = {(i, k)}
                while chain[-1] in nxt:
                    n = nxt[chain[-1]]
                    if n in seen:           # a loop (wrapped time): cut it
                        break
                    chain.append(n)
                    seen.add(n)
                chars.append(chain)
        # characters on closed loops (time wrap) have no head: start anywhere on the loop
        covered = {s for c in chars for s in c}
        for i in range(self.num_instances):
            for k in range(self.library.patches[self.patch[i]].num_characters):
                if (i, k) not in covered:
                    chain = [(i, k)]
                    covered.add((i, k))
                    while chain[-1] in nxt and nxt[chain[-1]] not in covered:
                        chain.append(nxt[chain[-1]])
                        covered.add(chain[-1])
                    chars.append(chain)
        return chars

    @property
    def num_characters(self) -> int:
        return len(self.characters())

    # -- tracks ----------------------------------------------------------------------------------
    def tracks(self, crop: bool = True) -> list[CharacterTrack]:
        """One :class:`CharacterTrack` per character (clock frames; cropped to the region's time
        interval unless ``crop=False``; characters entirely outside are dropped)."""
        fps = self.fps
        F0 = int(round(self.region.t0 * fps))
        F1 = int(round(self.region.t1 * fps))
        out = []
        for chain in self.characters():
            fa, fb, ft, roots, segs = [], [], [], [], []
            last_h = None
            q_next = None
            for n, (i, k) in enumerate(chain):
                sl = self.frag_slices(i)[k]
                tau = self.time[i][sl]
                # a stitched fragment starts exactly where the previous one stopped (no frame
                # twice or missing, whatever the rounding of the shared port time)
                q0 = math.ceil(tau[0] * fps - 1e-6) if q_next is None else q_next
                q1 = (math.floor(tau[-1] * fps + 1e-6) + 1) if n == len(chain) - 1 else math.ceil(tau[-1] * fps - 1e-6)
                q_next = max(q1, q0)
                if crop:
                    q0, q1 = max(q0, F0), min(q1, F1 + 1)
                if q1 <= q0:
                    continue
                q = np.arange(q0, q1)
                s = np.interp(q / fps, tau, np.arange(len(tau), dtype=np.float64))
                i0 = np.floor(s).astype(np.int64)
                i1 = np.minimum(i0 + 1, len(tau) - 1)
                w = s - i0
                xz = self.xz[i][sl]
                hd = self.heading[i][sl]
                x = xz[i0, 0] * (1 - w) + xz[i1, 0] * w
                z = xz[i0, 1] * (1 - w) + xz[i1, 1] * w
                h = hd[i0] * (1 - w) + hd[i1] * w
                if last_h is not None:
                    h = continue_heading(h, last_h)
                last_h = h[-1]
                off = self.library.fragment_offset(self.patch[i], k)
                fa.append(off + i0)
                fb.append(off + i1)
                ft.append(w.astype(np.float32))
                roots.append(np.stack([x, z, h], 1))
                segs.append((i, k, int(q0)))
            if not fa:
                continue
            out.append(CharacterTrack(np.concatenate(fa), np.concatenate(fb), np.concatenate(ft),
                                      np.concatenate(roots), segs[0][2], segments=segs))
        return out

    def poses(self, track: Track):
        """Root positions (F, 3) and local rotations (F, J, 4) (entry 0 = root world rotation)."""
        return evaluate_poses(self.library, track.frames_a, track.frames_b, track.frames_t, track.root)

    def summary(self) -> dict:
        chars = self.characters()
        return {"patches": self.num_instances, "characters": len(chars),
                "size": [round(self.region.x1 - self.region.x0, 3), round(self.region.z1 - self.region.z0, 3)],
                "seconds": round(self.region.t1 - self.region.t0, 3), "keyframes": int(np.sum(self.fixed)),
                "multi_character_instances": int(sum(self.library.patches[p].num_characters > 1 for p in self.patch))}

    # -- pack ------------------------------------------------------------------------------------
    def save(self, path, meta: dict | None = None) -> None:
        # instances that are exactly their rigid placement (most of them) store no arrays
        rigid = np.array([self._is_rigid(i) for i in range(self.num_instances)], bool)
        keep = np.flatnonzero(~rigid)
        n = np.concatenate([[0], np.cumsum([len(self.time[i]) for i in keep])]).astype(np.int64)
        obst = []
        arrays = {
            "inst_patch": np.array(self.patch, np.int64), "inst_place": np.array(self.place, np.float64).reshape(-1, 4),
            "inst_fixed": np.array(self.fixed, np.uint8), "inst_rigid": rigid.astype(np.uint8), "inst_frame_start": n,
            "xz": (np.concatenate([self.xz[i] for i in keep]) if len(keep) else np.zeros((0, 2))).astype(np.float32),
            "heading": (np.concatenate([self.heading[i] for i in keep]) if len(keep) else np.zeros(0)).astype(np.float32),
            "time": (np.concatenate([self.time[i] for i in keep]) if len(keep) else np.zeros(0)).astype(np.float64),
            "links": np.asarray(self.links, np.int64).reshape(-1, 4),
        }
        for k, ob in enumerate(self.obstacles):
            arrays[f"obstacle{k}_center"] = np.asarray(ob.center, np.float64)
            arrays[f"obstacle{k}_heading"] = np.asarray(ob.heading, np.float64)
            obst.append({"half": list(ob.half), "height": ob.height, "name": ob.name})
        r = self.region
        m = dict(meta or {})
        m.update({"region": [r.x0, r.z0, r.x1, r.z1, r.t0, r.t1], "wrap_space": bool(r.wrap_space),
                  "wrap_time": bool(r.wrap_time), "fps": self.fps, "obstacles": obst,
                  "portals": [[p.x, p.z, p.radius, p.kind] for p in self.portals],
                  "patch_names": [p.name for p in self.library.patches],
                  "patch_frames": [p.num_frames for p in self.library.patches], "info": _plain(self.info)})
        save_pack(path, PACK_KIND, PACK_VERSION, m, arrays)

    def rigid_arrays(self, i: int):
        """(xz, heading, time) of instance ``i``'s patch placed rigidly (no deformation)."""
        p = self.library.patches[self.patch[i]]
        x, z, th, t = self.place[i]
        rest = np.concatenate([f.root_xz for f in p.fragments])
        xz = rotate_xz_scalar(rest, th) + (x, z)
        hd = np.concatenate([f.heading for f in p.fragments]) + th
        tm = np.concatenate([f.t0 + np.arange(f.num_frames) / p.fps for f in p.fragments]) + t
        return xz, hd, tm

    def _is_rigid(self, i: int, tol: float = 1e-7) -> bool:
        xz, hd, tm = self.rigid_arrays(i)
        return (np.abs(xz - self.xz[i]).max() < tol and np.abs(hd - self.heading[i]).max() < tol
                and np.abs(tm - self.time[i]).max() < tol)

    @classmethod
    def load(cls, path, library) -> "TilingResult":
        pk = load_pack(path, kind=PACK_KIND, version=PACK_VERSION)
        with pack_fields(path, "tiling pack is missing a field"):
            m, a = pk.meta, pk.arrays
            names = m["patch_names"]
            frames = m["patch_frames"]
            x0, z0, x1, z1, t0, t1 = m["region"]
            region = Region(x0, z0, x1, z1, t0, t1, m["wrap_space"], m["wrap_time"])
            obst = [Obstacle(a[f"obstacle{k}_center"], o["half"], a[f"obstacle{k}_heading"], o["height"], o["name"])
                    for k, o in enumerate(m["obstacles"])]
            portals = [Portal(*p) for p in m["portals"]]
            fps = float(m["fps"])
            ip, pl, fx, st = a["inst_patch"], a["inst_place"], a["inst_fixed"], a["inst_frame_start"]
        lib_names = [p.name for p in library.patches]
        lib_frames = [p.num_frames for p in library.patches]
        for i, nm in enumerate(names):
            if i >= len(lib_names) or lib_names[i] != nm or lib_frames[i] != frames[i]:
                raise AssetError(path, f"tiling was made with another patch library (patch {i} {nm!r} differs)")
        n = len(ip)
        rigid = a.get("inst_rigid", np.zeros(n, np.uint8)).astype(bool)
        keep = np.flatnonzero(~rigid)
        if len(rigid) != n or len(st) != len(keep) + 1 or st[0] != 0 or st[-1] != len(a["time"]) \
                or (n and (ip.min() < 0 or ip.max() >= len(names))):
            raise AssetError(path, "tiling pack is inconsistent: instance tables")
        for k, i in enumerate(keep):
            if st[k + 1] - st[k] != frames[ip[i]]:
                raise AssetError(path, f"tiling pack is inconsistent: instance {i} has {st[k + 1] - st[k]} frames, "
                                       f"patch {names[ip[i]]!r} has {frames[ip[i]]}")
        links = a["links"]
        if len(links) and (links.min() < 0 or links[:, [0, 2]].max() >= n):
            raise AssetError(path, "tiling pack is inconsistent: links out of range")
        xz = a["xz"].astype(np.float64)
        hd = a["heading"].astype(np.float64)
        tm = a["time"].astype(np.float64)
        res = cls(library, region, [int(p) for p in ip], [tuple(map(float, r)) for r in pl], [bool(f) for f in fx],
                  [None] * n, [None] * n, [None] * n, links, obst, portals, fps, dict(m.get("info", {})))
        for k, i in enumerate(keep):
            s = slice(int(st[k]), int(st[k + 1]))
            res.xz[i], res.heading[i], res.time[i] = xz[s], hd[s], tm[s]
        for i in np.flatnonzero(rigid):
            res.xz[i], res.heading[i], res.time[i] = res.rigid_arrays(int(i))
        return res


def _plain(x):
    """msgpack-friendly copy (numpy scalars to Python)."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x
