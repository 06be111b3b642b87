"""USD stages as crowdweave writes them: metadata conventions, opening, atomic saving.

Every stage crowdweave writes says ``metersPerUnit = 1``, ``upAxis = "Y"`` and, when it
holds animation, ``timeCodesPerSecond`` (= ``framesPerSecond``) with start/end time codes
(ARCHITECTURE.md, "Conventions"). Frame ``i`` of a clip is time code ``start + i``.

Stages are built in memory and written with :func:`save_stage`, which exports the root
layer to a temporary file beside the target and renames it into place
(:class:`runtime.assets.atomic_path`), so a failed or interrupted write never leaves a
half-written file. The file format follows the extension: ``.usda`` text, ``.usdc``
binary crate, ``.usd`` crate (USD's default).
"""
from __future__ import annotations

import re
from pathlib import Path

from pxr import Sdf, Tf, Usd, UsdGeom

from runtime.assets import AssetError, atomic_path

__all__ = [
    "USD_EXTENSIONS", "StageError", "check_usd_path", "new_stage", "set_time_range",
    "set_default_prim", "open_stage", "save_stage", "save_layer", "export_layer", "valid_prim_name",
]

USD_EXTENSIONS = (".usda", ".usdc", ".usd")


class StageError(AssetError):
    """A USD file could not be written or read: names the file and what is wrong."""


def check_usd_path(path) -> Path:
    """``path`` as a Path if its extension is one USD writes (.usda/.usdc/.usd), else StageError."""
    p = Path(path)
    if p.suffix.lower() not in USD_EXTENSIONS:
        raise StageError(p, f"unsupported extension {p.suffix!r}; use one of {', '.join(USD_EXTENSIONS)}")
    return p


def valid_prim_name(name: str, fallback: str = "Prim") -> str:
    """A valid USD prim name (identifier) made from ``name`` (invalid characters become '_')."""
    s = Tf.MakeValidIdentifier(str(name)) if name else ""
    return s or fallback


def new_stage(fps: float | None = None, start: float | None = None, end: float | None = None, *,
              meters_per_unit: float = 1.0, up_axis: str = "Y") -> Usd.Stage:
    """An in-memory stage carrying crowdweave's metadata (metres, Y up, optional time range).

    Save it with :func:`save_stage`; the format is chosen by the target path's extension.
    """
    stage = Usd.Stage.CreateInMemory("crowdweave.usda")
    UsdGeom.SetStageMetersPerUnit(stage, float(meters_per_unit))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis.upper() == "Y" else UsdGeom.Tokens.z)
    if fps is not None:
        set_time_range(stage, fps, start if start is not None else 0.0, end)
    return stage


def set_time_range(stage: Usd.Stage, fps: float, start: float = 0.0, end: float | None = None) -> None:
    """Author ``timeCodesPerSecond`` and ``framesPerSecond`` (both ``fps``, so one time code is
    one frame) and the start/end time codes (``end`` defaults to ``start``)."""
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    stage.SetTimeCodesPerSecond(float(fps))
    stage.SetFramesPerSecond(float(fps))
    stage.SetStartTimeCode(float(start))
    stage.SetEndTimeCode(float(start if end is None else end))


def set_default_prim(stage: Usd.Stage, prim) -> None:
    """Make a root prim (Usd.Prim or path) the stage's defaultPrim."""
    if not isinstance(prim, Usd.Prim):
        prim = stage.GetPrimAtPath(Sdf.Path(str(prim)))
    if not prim or prim.GetPath().GetParentPath() != Sdf.Path.absoluteRootPath:
        raise ValueError(f"defaultPrim must be an existing root prim, got {prim}")
    stage.SetDefaultPrim(prim)


def usd_error_text(e) -> str:
    """The first message of a USD error, without the C++ context around it, on one line
    (``line 3, column 3: Expected } ...`` for a syntax error)."""
    msgs = [m.split(" : '", 1)[1].strip().rstrip("'").strip() for m in str(e).split("Error in ")[1:] if " : '" in m]
    first = msgs[0] if msgs else str(e)
    first = re.sub(r"^\S*?:(\d+):(\d+): ", r"line \1, column \2: ", first)
    return " ".join(first.split())[:300]


def open_usd_file(p: Path, error=StageError, unreadable: str = "cannot open as a USD stage") -> Usd.Stage:
    """Open the USD file ``p``; a file USD cannot read raises ``error(p, reason)`` with
    ``unreadable`` and USD's first message."""
    try:
        stage = Usd.Stage.Open(str(p))
    except Tf.ErrorException as e:
        raise error(p, f"{unreadable}: {usd_error_text(e)}") from None
    if stage is None:
        raise error(p, unreadable)
    return stage


def open_stage(stage_or_path) -> Usd.Stage:
    """Return ``stage_or_path`` if it is a stage, else open the file (StageError if that fails)."""
    if isinstance(stage_or_path, Usd.Stage):
        return stage_or_path
    p = Path(stage_or_path)
    if not p.is_file():
        raise StageError(p, "file not found")
    return open_usd_file(p)


def export_layer(layer: Sdf.Layer, path: str) -> None:
    """Write ``layer`` to ``path`` (format from the extension), not atomically: StageError on
    failure. :func:`save_layer` calls it on a temporary file (tests replace it to fail midway)."""
    try:
        ok = layer.Export(path)
    except Tf.ErrorException as e:
        raise StageError(path, f"USD export failed: {str(e).strip()}") from None
    if not ok:
        raise StageError(path, "USD export failed")


def save_layer(layer: Sdf.Layer, path) -> Path:
    """Export ``layer`` to ``path`` atomically (temporary file beside it, then rename).

    ``atomic_path`` gives the file the permissions a plain ``open()`` would (0666 less the umask).
    """
    p = check_usd_path(path)
    with atomic_path(p) as tmp:
        export_layer(layer, tmp)
    return p


def save_stage(stage: Usd.Stage, path) -> Path:
    """Write the stage's root layer to ``path`` atomically; ``.usda`` text, ``.usdc``/``.usd`` crate.

    A stage that pulls in other layers (sublayers, references, value clips) needs those saved
    too, each with :func:`save_layer`; only the root layer is written here.
    """
    return save_layer(stage.GetRootLayer(), path)
