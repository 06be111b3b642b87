"""What every ``crowdweave bake`` does after writing its stage: measure the planted feet of the
written characters, move a checked stage into place (or keep a failed one aside), print the feet."""
from __future__ import annotations

import json

__all__ = ["bake_feet", "keep_result", "print_feet"]


def keep_result(tmp, out, report_path, report, passed: bool, keep_failed: bool) -> str:
    """Move a checked stage into place: a stage that passed replaces ``out`` (and the report is
    written); one that failed is kept as ``OUT.failed.usdc`` with ``keep_failed``, else dropped.
    Returns what happened, for the printout."""
    from runtime.assets import atomic_write_bytes, commit_temp, pause_point
    from usd_io.clips import failed_stage_path
    if passed:
        pause_point("replacing")
        commit_temp(tmp, out)
        if report_path is not None:
            atomic_write_bytes(report_path, json.dumps(report, indent=1, default=float).encode())
        return f"wrote {out}"
    if keep_failed:
        failed = failed_stage_path(out)
        commit_temp(tmp, failed)
        note = f"{out} not replaced: the failed stage is {failed}"
        if report_path is not None:
            rp = report_path.with_name(f"{report_path.stem}.failed{report_path.suffix}")
            atomic_write_bytes(rp, json.dumps(report, indent=1, default=float).encode())
            note += f", its report {rp}"
        return note
    return f"{out} not replaced (the checker failed; --keep-failed keeps the new stage beside it)"


def bake_feet(stage_path, tracks, zones, knee_range=None) -> dict:
    """Planted-foot slide of the written stage, measured by the crowd checker (crowd characters)
    and the tiling checker (each zone's characters); empty groups are left out. ``knee_range``:
    the capture's knee flexion range (:func:`runtime.footslide.knee_range_of`)."""
    from runtime.crowd.checker import check_crowd_feet
    from runtime.tiling.check import check_tiling_feet
    from usd_io.crowd import character_path
    out = {}
    if tracks:
        out["crowd"] = check_crowd_feet(stage_path, [character_path(n) for n in tracks], knee_range)
    tiled = [character_path(n) for z in zones for n in z.tracks()]
    if tiled:
        out["tiled"] = check_tiling_feet(stage_path, tiled, knee_range)
    return out


def print_feet(feet: dict) -> None:
    from runtime.footslide import slide_line
    for group, f in feet.items():
        verdict = "within limits" if f["within_limits"] else ("OVER LIMITS" if f["enforced"] else "over limits")
        print(f"feet ({group}, {f['characters']} characters): {slide_line(f)}: {verdict}")
