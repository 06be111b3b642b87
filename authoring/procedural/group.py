"""Activity groups: stretches of motion that start and end in a hub pose, and their joining.

A :class:`Group` owns ``N`` frames; its controls hold ``N + 1`` (the last one is the end hub,
which is also the first frame of the next group), so consecutive groups join without a
seam: :func:`concat_groups` keeps every group's first ``N`` frames and the last group's end.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .rig import Controls

__all__ = ["Group", "concat_groups"]


@dataclass
class Group:
    controls: Controls          # N + 1 frames: frame 0 = start hub, frame N = end hub
    segments: list              # [(start, end_exclusive, label)] covering [0, N)
    hubs: list                  # [(frame, hub)] including frame 0, excluding frame N
    props: list = field(default_factory=list)
    end: tuple = (0.0, 0.0, 0.0)

    @property
    def num_frames(self) -> int:      # frames owned by this group (without the end hub)
        return self.controls.num_frames - 1


def concat_groups(groups):
    """Join consecutive groups into one stretch of controls.

    Args:
        groups: a non-empty list of :class:`Group`, each starting where the previous ends.
    Returns:
        ``(controls, segments, hubs, starts)``: the joined controls (``sum(num_frames) + 1``
        frames), the label segments and hubs shifted to the joined frames (the last segment
        also covers the final frame), and each group's first frame.
    """
    parts, segs, hubs, starts = [], [], [], []
    f = 0
    for i, g in enumerate(groups):
        last = i == len(groups) - 1
        parts.append(g.controls if last else g.controls.slice(0, g.num_frames))
        segs += [(a + f, b + f, lab) for a, b, lab in g.segments]
        hubs += [(h + f, n) for h, n in g.hubs]
        starts.append(f)
        f += g.num_frames
    c = Controls.concat(parts)
    a, b, lab = segs[-1]
    segs[-1] = (a, c.num_frames, lab)
    return c, segs, hubs, starts
