"""A motion library from capture files in one call: read the takes (labels from sidecars, or
derived from the motion), build the graph, account for every input second and say what the
library can do (``crowdweave author graph`` and the tests use it).

Real capture without labels gets the parameters measured on the CMU MotionBuilder-family
files (docs/decisions.md): hubs matched per pose kind, a wider hub threshold
(:data:`CAPTURE_THRESHOLD_CM`) and idle loops that stand still (:data:`STILL_EPS`).
"""
from __future__ import annotations

from dataclasses import replace

from runtime.motion.graph import MotionGraph

from .build import GraphBuildParams, build_graph
from .report import capabilities, format_report, source_report
from .sources import load_sources

__all__ = ["build_library", "capture_params", "CAPTURE_THRESHOLD_CM", "STILL_EPS"]

CAPTURE_THRESHOLD_CM = 14.0     # hub threshold for real capture with derived labels
STILL_EPS = (0.01, 1.0)         # m/s, deg/s: idle loops made in standing runs drift at most this


def capture_params(params: GraphBuildParams | None = None, derived: bool = True,
                   threshold_cm: float | None = None) -> GraphBuildParams:
    """Build parameters: ``params`` (default :class:`GraphBuildParams`), and for takes with
    derived labels hubs per pose kind, still idle loops and the capture threshold unless
    ``threshold_cm`` is given."""
    p = replace(params) if params is not None else GraphBuildParams()
    if derived:
        p.match_pose_kind = True
        p.still_eps = STILL_EPS
        p.threshold_cm = CAPTURE_THRESHOLD_CM
    if threshold_cm is not None:
        p.threshold_cm = float(threshold_cm)
    return p


def build_library(inputs, mirror: bool = False, labels=None, threshold_cm: float | None = None,
                  params: GraphBuildParams | None = None, fps: float = 30.0, scale=None, derive=None,
                  log=print, progress=None, read_progress=None, map_blocks=None) -> tuple[MotionGraph, list[str]]:
    """The motion graph of ``inputs`` (take directories and BVH files, :func:`.sources.load_sources`)
    with ``meta["build_report"]`` = {"sources": per file seconds kept of seconds given and
    why the rest was dropped, "capabilities": what the library can do and lacks}; and the
    report's lines for the terminal. ``params``: explicit build parameters (else
    :func:`capture_params`); ``map_blocks``: where the frame-distance blocks are computed (see
    :func:`.build.build_graph`)."""
    takes, files = load_sources(inputs, fps=fps, scale=scale, labels=labels, progress=read_progress,
                                mirror=mirror, derive=derive)
    if not takes:
        raise ValueError("no usable frames in the inputs: " + "; ".join(
            f"{f.path}: nothing but {', '.join(sorted(set(f.labels)))}" for f in files))
    frames = sum(t.clip.num_frames for t in takes)
    log(f"{len(takes)} takes{' (mirrored copies included)' if mirror else ''} from {len(files)} files, "
        f"{frames} frames ({frames / fps:.1f} s) at {fps:g} fps")
    if params is None:
        params = capture_params(None, any(f.derived for f in files), threshold_cm)
    elif threshold_cm is not None:
        params = replace(params, threshold_cm=float(threshold_cm))
    params = replace(params, fps=fps)
    g = build_graph(takes, params, progress=progress, log=log, map_blocks=map_blocks)
    sources = source_report(g, files)
    caps = capabilities(g, takes)
    g.meta["build_report"] = {"sources": sources, "capabilities": caps}
    return g, format_report(sources, caps)
