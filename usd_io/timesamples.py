"""Baked characters' animation authored at the Sdf level: prim and attribute specs, and one
``SetTimeSample`` per animated attribute per frame.

The animated attributes of a baked character (:data:`ANIMATED`) are the SkelRoot's
``xformOp:translate`` (the root joint's world position), the SkelAnimation's joint ``rotations``
and the SkelRoot's ``crowdweave:root``. The joint ``translations`` do not change over time (the
root joint's is zero, the others are the skeleton's offsets), so they are authored once
(:attr:`SkelValues.translations`): a time-sampled array of every joint's translation per frame
was 40% of a bake's bytes. Their values come
from the runtime (:func:`runtime.pose.skel_arrays`) for many characters at once, in batches of
about :data:`POSE_BATCH_FRAMES` frames, and are converted from numpy arrays to Vt arrays; the
per-call cost of ``SetTimeSample`` from Python is then what is left. Both the stage of a bake
(:mod:`usd_io.crowd`) and its value-clip layers (:mod:`usd_io.clips`) are written through
:func:`author_tracks`.

Call the authoring functions inside one ``Sdf.ChangeBlock``.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Vt

from runtime.crowd.tracks import Track

from .skel import joint_paths, rest_and_bind_transforms

__all__ = ["SkelValues", "ANIMATED", "ROOT_XFORM_ORDER", "POSE_BATCH_FRAMES", "prim_spec", "attribute_spec", "relationship_spec",
           "define_animated_specs", "pose_arrays", "author_samples", "track_times", "batches", "author_tracks"]

POSE_BATCH_FRAMES = 3000       # frames of poses evaluated per vectorized pass (small batches stay in cache)

_T = Sdf.ValueTypeNames
_SKEL_API = Sdf.TokenListOp.Create(prependedItems=["SkelBindingAPI"])

# the time-sampled attributes of a character: (prim path relative to the SkelRoot, attribute, type, custom)
ANIMATED = (("", "xformOp:translate", _T.Float3, False),
            ("Skel/Anim", "rotations", _T.QuatfArray, False),
            ("", "crowdweave:root", _T.Double3, True))
ROOT_XFORM_ORDER = Vt.TokenArray(["xformOp:translate"])   # the SkelRoot's xformOpOrder


@dataclass(frozen=True)
class SkelValues:
    """The Vt values every character of one skeleton shares (computed once per bake)."""
    joints: Vt.TokenArray
    names: Vt.TokenArray
    rest: Vt.Matrix4dArray
    bind: Vt.Matrix4dArray
    scales: Vt.Vec3hArray
    offsets: np.ndarray      # (J, 3) rest offsets: every non-root joint translation
    translations: Vt.Vec3fArray  # the SkelAnimation's constant translations: root 0, the others' offsets

    @classmethod
    def of(cls, skeleton) -> "SkelValues":
        rest, bind = rest_and_bind_transforms(skeleton)
        offsets = np.asarray(skeleton.offsets, dtype=np.float64)
        still = offsets.astype(np.float32)
        still[0] = 0.0
        return cls(Vt.TokenArray(joint_paths(skeleton)), Vt.TokenArray(list(skeleton.names)), rest, bind,
                   Vt.Vec3hArray.FromNumpy(np.ones((skeleton.num_joints, 3), np.float16)), offsets,
                   Vt.Vec3fArray.FromNumpy(still))


# -- specs --------------------------------------------------------------------------------------
def prim_spec(layer: Sdf.Layer, path: Sdf.Path, type_name: str | None, specifier=Sdf.SpecifierDef,
              api: bool = False) -> Sdf.PrimSpec:
    """A prim spec at ``path`` in ``layer`` (created with its ancestors as ``over``s).

    Args:
        type_name: schema type ("SkelRoot", ...), or None for a typeless prim.
        specifier: ``def`` (default), ``over`` or ``class``.
        api: prepend ``SkelBindingAPI`` to the prim's ``apiSchemas``.
    """
    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = specifier
    if type_name:
        spec.typeName = type_name
    if api:
        spec.SetInfo("apiSchemas", _SKEL_API)
    return spec


def attribute_spec(prim: Sdf.PrimSpec, name: str, type_name, value=None, *, uniform: bool = False,
                   custom: bool = False) -> Sdf.AttributeSpec:
    """An attribute spec on ``prim``, with ``value`` as its default when given.

    Args:
        uniform: variability uniform (not animatable) instead of varying.
        custom: declared custom (a crowdweave attribute, not a schema's).
    """
    a = Sdf.AttributeSpec(prim, name, type_name, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying,
                          custom)
    if value is not None:
        a.default = value
    return a


def relationship_spec(prim: Sdf.PrimSpec, name: str, target: Sdf.Path) -> None:
    """A relationship ``name`` on ``prim`` with the one explicit ``target``."""
    r = Sdf.RelationshipSpec(prim, name, False)
    r.targetPathList.explicitItems = [target]


def define_animated_specs(layer: Sdf.Layer, root_path: Sdf.Path, specifier=Sdf.SpecifierOver) -> list:
    """Only the attribute specs that carry time samples (the root's translate op, rotations,
    crowdweave:root), on prims of ``specifier`` (``over`` for a value-clip layer or a manifest)."""
    out = []
    for rel, name, type_name, custom in ANIMATED:
        prim_path = root_path.AppendPath(Sdf.Path(rel)) if rel else root_path
        spec = layer.GetPrimAtPath(prim_path) or prim_spec(layer, prim_path, None, specifier)
        out.append(attribute_spec(spec, name, type_name, custom=custom))
    return out


# -- values -------------------------------------------------------------------------------------
def pose_arrays(graph, tracks: list[Track], sv: SkelValues, foot_lock: bool = True):
    """SkelAnimation arrays of several tracks at once, concatenated over their frames:
    translations (M, J, 3) float32 (root: world position), rotations (M, J, 4) float32 in the
    x, y, z, w memory order of GfQuatf, and crowdweave:root (M, 3) float64 (x, z, heading deg).
    Planted feet are locked per track (the runtime's foot lock) unless ``foot_lock`` is False."""
    from runtime.pose import skel_arrays
    lens = [len(t) for t in tracks]
    starts = np.zeros(sum(lens), dtype=bool)
    first = np.cumsum([0] + lens[:-1])
    starts[first[first < len(starts)]] = True
    return skel_arrays(graph, np.concatenate([t.frames_a for t in tracks]), np.concatenate([t.frames_b for t in tracks]),
                       np.concatenate([t.frames_t for t in tracks]), np.concatenate([t.root for t in tracks]),
                       lock_segments=starts if foot_lock else None)


def author_samples(specs: list, times: list[float], trans, quats, rootv) -> None:
    """One ``SetTimeSample`` per attribute spec (the root's translate op from ``trans[:, 0]``,
    rotations, crowdweave:root) per frame; call inside an ``Sdf.ChangeBlock``."""
    st, sr, sc = specs
    # map() drives the calls from C: no Python loop body per sample
    deque(map(st.SetTimeSample, times, Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(trans[:, 0], np.float32))), 0)
    deque(map(sr.SetTimeSample, times, map(Vt.QuatfArray.FromNumpy, quats)), 0)
    deque(map(sc.SetTimeSample, times, Vt.Vec3dArray.FromNumpy(np.ascontiguousarray(rootv))), 0)


def track_times(track: Track) -> list[float]:
    """Time codes of a track's frames: ``start_frame``, ``start_frame + 1``, ..."""
    return (float(track.start_frame) + np.arange(len(track), dtype=np.float64)).tolist()


def batches(items, frames: int):
    """Consecutive groups of ``items`` ((path, Track), ...) with about ``frames`` frames each."""
    batch, n = [], 0
    for it in items:
        batch.append(it)
        n += len(it[1])
        if n >= frames:
            yield batch
            batch, n = [], 0
    if batch:
        yield batch


def author_tracks(layer: Sdf.Layer, items, graph, sv: SkelValues, define_specs, foot_lock: bool = True) -> None:
    """Author the time samples of ``items`` ((spec path, Track), ...) into ``layer``, poses
    evaluated in batches of :data:`POSE_BATCH_FRAMES` frames; call inside an ``Sdf.ChangeBlock``.

    Args:
        define_specs: ``f(path, track)`` -> the animated attribute specs of that character
            (the root's translate op, rotations, crowdweave:root), e.g. :func:`define_animated_specs`.
        foot_lock: lock planted feet (:func:`pose_arrays`).
    """
    for batch in batches(items, POSE_BATCH_FRAMES):
        trans, quats, rootv = pose_arrays(graph, [tr for _, tr in batch], sv, foot_lock)
        k = 0
        for path, tr in batch:
            specs = define_specs(path, tr)
            f = len(tr)
            author_samples(specs, track_times(tr), trans[k:k + f], quats[k:k + f], rootv[k:k + f])
            k += f
