"""Flocks as USD: one PointInstancer per flock.

Layout::

    /World/Flocks/<name>              PointInstancer
        prototypes -> /World/Flocks/<name>/Prototypes/Agent (a small cone pointing +Z)
        protoIndices, ids             int[]  (ids = agent identities, stable over the walk)
        positions, orientations       point3f[t], quath[t] per frame

Agents keep their row (identity) through DDG transitions, so ``ids`` never change and a DCC
tool's motion blur or trails follow the same animal. Arrays come from the runtime
(:meth:`runtime.flock.FlockSystem.positions` / ``orientations``); nothing is computed here.
"""
from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, UsdGeom, Vt

from runtime.crowd.scenario import prim_name

__all__ = ["write_flock_instancer", "FLOCKS"]

FLOCKS = "/World/Flocks"


def write_flock_instancer(stage, name: str, positions: np.ndarray, orientations: np.ndarray,
                          start: float = 0.0, size: float = 0.5):
    """Author one flock: positions (T, N, 3), orientations (T, N, 4) w-x-y-z, frame ``k`` at
    time code ``start + k``. Returns the PointInstancer."""
    positions = np.asarray(positions, dtype=np.float32)
    orientations = np.asarray(orientations, dtype=np.float64)
    T, N = positions.shape[:2]
    if orientations.shape != (T, N, 4):
        raise ValueError(f"orientations shape {orientations.shape} != ({T}, {N}, 4)")
    if not stage.GetPrimAtPath(FLOCKS):
        UsdGeom.Scope.Define(stage, FLOCKS)
    path = Sdf.Path(FLOCKS).AppendChild(prim_name(name))
    inst = UsdGeom.PointInstancer.Define(stage, path)
    proto_root = UsdGeom.Scope.Define(stage, path.AppendChild("Prototypes"))
    cone = UsdGeom.Cone.Define(stage, proto_root.GetPath().AppendChild("Agent"))
    cone.CreateAxisAttr("Z")
    cone.CreateRadiusAttr(0.3 * size)
    cone.CreateHeightAttr(size)
    cone.CreateExtentAttr([(-0.3 * size, -0.3 * size, -0.5 * size), (0.3 * size, 0.3 * size, 0.5 * size)])
    inst.CreatePrototypesRel().SetTargets([cone.GetPath()])
    inst.CreateProtoIndicesAttr(Vt.IntArray([0] * N))
    inst.CreateIdsAttr(Vt.Int64Array(list(range(N))))
    pos_attr = inst.CreatePositionsAttr()
    ori_attr = inst.CreateOrientationsAttr()
    layer = stage.GetEditTarget().GetLayer()
    q = np.ascontiguousarray(orientations[..., [1, 2, 3, 0]], dtype=np.float16)   # GfQuath memory: x, y, z, w
    with Sdf.ChangeBlock():
        for k in range(T):
            t = float(start + k)
            layer.SetTimeSample(pos_attr.GetPath(), t, Vt.Vec3fArray.FromNumpy(positions[k]))
            layer.SetTimeSample(ori_attr.GetPath(), t, Vt.QuathArray.FromNumpy(q[k]))
    lo = positions.reshape(-1, 3).min(axis=0) - size
    hi = positions.reshape(-1, 3).max(axis=0) + size
    inst.CreateExtentAttr([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())])
    return inst
