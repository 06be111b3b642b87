"""Motion-patch construction from multi-character takes (Kim, Hwang, Hyun and Lee 2012, section 4).

:mod:`.features` (pose vectors, Eq. 4 motion variation, body points, gaze),
:mod:`.episodes` (contact, proximity with reaction, synchronicity Eq. 5, merging),
:mod:`.boundaries` (pose clustering, subset search over the k largest pose groups),
:mod:`.build` (cutting fragments, constraints, pose classes, single-character patches).
The patch data model is :mod:`runtime.tiling.patch`.
"""
from .build import BuildResult, PatchBuildError, PatchBuildParams, build_patch_library
from .episodes import EpisodeParams, detect_episodes, detect_events, score_against_ground_truth

__all__ = ["PatchBuildParams", "BuildResult", "PatchBuildError", "build_patch_library", "EpisodeParams",
           "detect_episodes", "detect_events", "score_against_ground_truth"]
