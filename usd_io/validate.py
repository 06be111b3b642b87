"""Validation of USD stages: ``pxr.UsdValidation``'s registered validators plus crowdweave's own
checks for what those validators miss.

The stock validators (about 30 in usd-core 26.x) flag missing ``metersPerUnit``/``upAxis``/
``defaultPrim``, SkelBindingAPI problems, composition errors and so on, but none of them
looks inside a SkelAnimation. UsdSkel itself is silent about broken animation data: when
``translations``, ``rotations`` and ``scales`` do not all have one entry per joint at a time
sample, it drops the whole animation at that time and poses the rest pose instead. The
project checks here catch that and related binding mistakes:

- ``crowdweave:skelAnimationArrays``: every SkelAnimation lists unique joints and, at its
  default value and at every time sample, translations/rotations/scales hold exactly one
  finite entry per joint (all three present); rotations are unit quaternions (warning);
  blendShapeWeights match blendShapes; samples lie inside the stage's time range (warning).
- ``crowdweave:skeleton``: every Skeleton has unique joints with a valid topology and
  restTransforms/bindTransforms/jointNames of the joint count; it sits under a SkelRoot
  (warning otherwise).
- ``crowdweave:skelBinding``: ``skel:skeleton`` targets a Skeleton and
  ``skel:animationSource`` a SkelAnimation; every joint the bound animation lists exists in
  the Skeleton; joints the animation leaves out can fall back to a rest pose.

More checks register with :func:`register_check`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable

import numpy as np
from pxr import Sdf, Usd, UsdSkel, UsdValidation

from .stage import open_stage

__all__ = ["Issue", "validate_stage", "errors", "register_check", "PROJECT_CHECKS", "format_issues"]


@dataclass(frozen=True)
class Issue:
    severity: str   # "error" | "warning" | "info"
    check: str      # validator name, e.g. "usdGeomValidators:StageMetadataChecker" or "crowdweave:skeleton"
    path: str       # prim/property path, or a layer identifier; "" for the whole stage
    message: str

    def __str__(self) -> str:
        where = f" {self.path}" if self.path else ""
        return f"{self.severity}: [{self.check}]{where}: {self.message}"


def errors(issues: Iterable[Issue]) -> list[Issue]:
    return [i for i in issues if i.severity == "error"]


def format_issues(issues: Iterable[Issue]) -> str:
    return "\n".join(str(i) for i in issues)


# -- pxr.UsdValidation --------------------------------------------------------------------------
_SEVERITY = {
    UsdValidation.ValidationErrorType.Error: "error",
    UsdValidation.ValidationErrorType.Warn: "warning",
    UsdValidation.ValidationErrorType.Info: "info",
}
_CONTEXT = None


def _usd_context():
    global _CONTEXT
    if _CONTEXT is None:
        validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
        _CONTEXT = UsdValidation.ValidationContext(validators)
    return _CONTEXT


def _site_path(site) -> str:
    if site.IsProperty():
        return str(site.GetProperty().GetPath())
    if site.IsPrim():
        return str(site.GetPrim().GetPath())
    layer = site.GetLayer()
    return layer.identifier if layer else ""


def _usd_validation(stage: Usd.Stage) -> list[Issue]:
    out = []
    for e in _usd_context().Validate(stage):
        sev = _SEVERITY.get(e.GetType())
        if sev is None:
            continue
        validator = e.GetValidator()
        name = validator.GetMetadata().name if validator else "usdValidation"
        sites = [p for p in (_site_path(s) for s in e.GetSites()) if p]
        out.append(Issue(sev, f"{name}", ", ".join(sites), f"{e.GetName()}: {e.GetMessage()}"))
    return out


# -- project checks ---------------------------------------------------------------------------
PROJECT_CHECKS: dict[str, Callable[[Usd.Stage], Iterable[Issue]]] = {}


def register_check(name: str):
    """Decorator: register ``fn(stage) -> iterable of Issue`` as project check ``name``."""
    def deco(fn):
        PROJECT_CHECKS[name] = fn
        return fn
    return deco


def _prims(stage: Usd.Stage, schema) -> list[Usd.Prim]:
    rng = Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))
    return [p for p in rng if p.IsA(schema)]


def _more(n: int) -> str:
    return f" (and {n} more time sample{'' if n == 1 else 's'})" if n else ""


_ANIM_ATTRS = (("translations", 3), ("rotations", 4), ("scales", 3))


@register_check("crowdweave:skelAnimationArrays")
def _check_animation_arrays(stage: Usd.Stage) -> Iterable[Issue]:
    name = "crowdweave:skelAnimationArrays"
    ranged = stage.HasAuthoredTimeCodeRange()
    t0, t1 = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    for prim in _prims(stage, UsdSkel.Animation):
        anim = UsdSkel.Animation(prim)
        where = str(prim.GetPath())
        joints = list(anim.GetJointsAttr().Get() or [])
        n = len(joints)
        if len(set(joints)) != n:
            dup = sorted({j for j in joints if joints.count(j) > 1})
            yield Issue("error", name, where, f"joints lists duplicates: {dup[:5]}")
        authored = {}
        for attr_name, _ in _ANIM_ATTRS:
            attr = prim.GetAttribute(attr_name)
            has_default = bool(attr) and attr.Get(Usd.TimeCode.Default()) is not None
            times = list(attr.GetTimeSamples()) if attr else []
            if has_default or times:
                authored[attr_name] = (attr, has_default, times)
        if not authored:
            yield Issue("warning", name, where, "no translations, rotations or scales authored")
            continue
        if n == 0:
            yield Issue("error", name, where, "joint transforms are authored but joints is empty")
            continue
        missing = [a for a, _ in _ANIM_ATTRS if a not in authored]
        if missing:
            yield Issue("error", name, where,
                        f"{' and '.join(missing)} not authored: UsdSkel applies an animation only when "
                        f"translations, rotations and scales all have values, so this one is ignored")
        for attr_name, width in _ANIM_ATTRS:
            if attr_name not in authored:
                continue
            attr, has_default, times = authored[attr_name]
            where_attr = str(attr.GetPath())
            samples = ([Usd.TimeCode.Default()] if has_default else []) + [Usd.TimeCode(t) for t in times]
            bad_len, bad_val, bad_unit = [], [], []
            for tc in samples:
                v = attr.Get(tc)
                a = np.asarray(v, dtype=np.float64) if v is not None else np.zeros((0, width))
                label = "default" if tc.IsDefault() else f"{tc.GetValue():g}"
                if len(a) != n:
                    bad_len.append((label, len(a)))
                    continue
                if not np.isfinite(a).all():
                    bad_val.append(label)
                elif attr_name == "rotations" and n and np.abs(np.linalg.norm(a, axis=-1) - 1.0).max() > 1e-3:
                    bad_unit.append(label)
            if bad_len:
                (label, m), rest = bad_len[0], len(bad_len) - 1
                yield Issue("error", name, where_attr,
                            f"{attr_name} has {m} entries at time {label}{_more(rest)} but joints lists {n} joints")
            if bad_val:
                yield Issue("error", name, where_attr,
                            f"{attr_name} holds NaN or infinite values at time {bad_val[0]}{_more(len(bad_val) - 1)}")
            if bad_unit:
                yield Issue("warning", name, where_attr,
                            f"rotations are not unit quaternions at time {bad_unit[0]}{_more(len(bad_unit) - 1)}")
            if ranged and times and (times[0] < t0 - 1e-9 or times[-1] > t1 + 1e-9):
                yield Issue("warning", name, where_attr,
                            f"time samples span {times[0]:g}..{times[-1]:g}, outside the stage's "
                            f"start/end {t0:g}..{t1:g}")
        shapes = anim.GetBlendShapesAttr().Get()
        weights_attr = anim.GetBlendShapeWeightsAttr()
        if shapes is not None or weights_attr.HasAuthoredValue():
            ns = len(shapes or [])
            for tc in [Usd.TimeCode.Default()] + [Usd.TimeCode(t) for t in weights_attr.GetTimeSamples()]:
                w = weights_attr.Get(tc)
                if w is not None and len(w) != ns:
                    yield Issue("error", name, str(weights_attr.GetPath()),
                                f"blendShapeWeights has {len(w)} entries but blendShapes lists {ns}")
                    break


@register_check("crowdweave:skeleton")
def _check_skeletons(stage: Usd.Stage) -> Iterable[Issue]:
    name = "crowdweave:skeleton"
    for prim in _prims(stage, UsdSkel.Skeleton):
        skel = UsdSkel.Skeleton(prim)
        where = str(prim.GetPath())
        joints = list(skel.GetJointsAttr().Get() or [])
        n = len(joints)
        if n == 0:
            yield Issue("error", name, where, "skeleton has no joints")
            continue
        if len(set(joints)) != n:
            dup = sorted({j for j in joints if joints.count(j) > 1})
            yield Issue("error", name, where, f"joints lists duplicates: {dup[:5]}")
        else:
            ok, why = UsdSkel.Topology(skel.GetJointsAttr().Get()).Validate()
            if not ok:
                yield Issue("error", name, where, f"invalid joint topology: {why}")
        for attr in (skel.GetRestTransformsAttr(), skel.GetBindTransformsAttr(), skel.GetJointNamesAttr()):
            v = attr.Get()
            if v is not None and len(v) != n:
                yield Issue("error", name, str(attr.GetPath()),
                            f"{attr.GetName()} has {len(v)} entries but joints lists {n} joints")
        if not UsdSkel.Root.Find(prim):
            yield Issue("warning", name, where, "Skeleton is not under a SkelRoot; DCC tools will not pose it")


def _targets(prim: Usd.Prim, rel_name: str) -> list[Sdf.Path]:
    rel = prim.GetRelationship(rel_name)
    return list(rel.GetForwardedTargets()) if rel else []


@register_check("crowdweave:skelBinding")
def _check_bindings(stage: Usd.Stage) -> Iterable[Issue]:
    name = "crowdweave:skelBinding"
    rng = Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))
    for prim in rng:
        for rel_name, schema, kind in (("skel:skeleton", UsdSkel.Skeleton, "Skeleton"),
                                       ("skel:animationSource", UsdSkel.Animation, "SkelAnimation")):
            targets = _targets(prim, rel_name)
            if len(targets) > 1:
                yield Issue("error", name, f"{prim.GetPath()}.{rel_name}", f"has {len(targets)} targets; one expected")
            for t in targets[:1]:
                tp = stage.GetPrimAtPath(t)
                if not tp or not tp.IsA(schema):
                    yield Issue("error", name, f"{prim.GetPath()}.{rel_name}", f"target {t} is not a {kind}")
    for prim in _prims(stage, UsdSkel.Skeleton):
        skel = UsdSkel.Skeleton(prim)
        anim_prim = UsdSkel.BindingAPI(prim).GetInheritedAnimationSource()
        if not anim_prim or not anim_prim.IsA(UsdSkel.Animation):
            continue
        skel_joints = list(skel.GetJointsAttr().Get() or [])
        anim_joints = list(UsdSkel.Animation(anim_prim).GetJointsAttr().Get() or [])
        known = set(skel_joints)
        unknown = [j for j in anim_joints if j not in known]
        if unknown:
            yield Issue("error", name, str(anim_prim.GetPath()),
                        f"{len(unknown)} animated joint(s) do not exist in the bound Skeleton {prim.GetPath()}: "
                        f"{unknown[:3]}")
        unanimated = [j for j in skel_joints if j not in set(anim_joints)]
        rest = skel.GetRestTransformsAttr().Get()
        if unanimated and (rest is None or len(rest) != len(skel_joints)):
            yield Issue("error", name, str(prim.GetPath()),
                        f"{len(unanimated)} joint(s) are not animated by {anim_prim.GetPath()} and the Skeleton "
                        f"has no valid restTransforms to fall back on: {unanimated[:3]}")


# -- entry point --------------------------------------------------------------------------------
def validate_stage(stage_or_path, *, usd_validators: bool = True, project_checks: bool = True) -> list[Issue]:
    """All issues found on a stage (or a USD file): UsdValidation's registered validators, then
    the project's checks (:data:`PROJECT_CHECKS`). Empty ``errors(...)`` means valid."""
    stage = open_stage(stage_or_path)
    issues: list[Issue] = []
    if usd_validators:
        issues += _usd_validation(stage)
    if project_checks:
        for fn in PROJECT_CHECKS.values():
            issues += list(fn(stage))
    return issues
