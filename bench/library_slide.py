"""Benchmark: foot slide of the motion library and of planned crowds, and what waiting plays.

* **Library** -- every edge of the motion graph by forward kinematics at its own origin; a
  contact point is planted on the frames its contact flag says (``MotionGraph.frame_contacts``);
  the figures are the horizontal speed of planted points between consecutive frames: mean and
  95th percentile (cm/s) and the share over 10 cm/s (``runtime.motion.contacts.slide_figures``);
  with the edges' own build-time figures (``meta["foot_slide"]``) when the library has them.
* **Samples** -- for each sample given (default ``meet20``, planned like ``crowdweave bake``), the
  same figures over every character's planned track (contacts of the library frames played), and
  the frames on which a character plays locomotion with its root held: the library frame moves
  its root faster than 0.3 m/s while the character's root moves less than a tenth of that
  ("held").

Figures only, no asserts; measured on the planned tracks (before any bake-time foot locking).

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/library_slide.py [--samples meet20,plaza] [--library PACK]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

HELD_CLIP_SPEED = 0.3     # m/s: a library frame moving its root at least this fast is locomotion


def library_speeds(graph) -> np.ndarray:
    """(T, 4) planted-point speeds of every library frame to the next within its edge (NaN
    where not planted on both, and at every edge's last frame)."""
    from runtime.motion import Clip
    from runtime.motion.contacts import contact_point_positions, leg_joints, planted_speeds
    clip = Clip(graph.skeleton, graph.fps, graph.frame_xz, graph.frame_heading, graph.frame_height,
                graph.frame_rotations)
    gr, gp = clip.fk(origin=np.zeros(3))
    v = planted_speeds(contact_point_positions(leg_joints(graph.skeleton), gr, gp), graph.frame_contacts, graph.fps)
    out = np.full((len(graph.frame_heading), 4), np.nan)
    out[:-1] = v
    out[graph.edge_start[1:] - 1] = np.nan
    return out


def track_figures(graph, tracks) -> tuple[np.ndarray, int, int]:
    """(planted-point speeds (N, 4), held frames, frames) over all ``tracks``."""
    from runtime.crowd.tracks import evaluate_poses, track_contacts
    from runtime.motion.contacts import contact_point_positions, leg_joints, planted_speeds
    from runtime.motion.fk import forward_kinematics
    legs = leg_joints(graph.skeleton)
    speeds, held, frames = [], 0, 0
    for tr in tracks:
        pos, rot = evaluate_poses(graph, tr.frames_a, tr.frames_b, tr.frames_t, tr.root)
        gr, gp = forward_kinematics(graph.skeleton, pos, rot)
        c = track_contacts(graph, tr.frames_a, tr.frames_b, tr.frames_t)
        speeds.append(planted_speeds(contact_point_positions(legs, gr, gp), c, graph.fps))
        a = tr.frames_a
        same_edge = np.searchsorted(graph.edge_start, a[:-1], "right") == np.searchsorted(graph.edge_start, a[1:], "right")
        step = (a[1:] - a[:-1] == 1) & same_edge
        clip_v = np.linalg.norm(graph.frame_xz[a[1:]] - graph.frame_xz[a[:-1]], axis=1) * graph.fps
        root_v = np.linalg.norm(np.diff(tr.root[:, :2], axis=0), axis=1) * graph.fps
        held += int((step & (clip_v > HELD_CLIP_SPEED) & (root_v < 0.1 * clip_v)).sum())
        frames += len(tr) - 1
    return np.concatenate(speeds) if speeds else np.zeros((0, 4)), held, frames


def row(name, fig, extra=""):
    print(f"{name:<28} {fig['mean_cm_s']:>8.2f} {fig['p95_cm_s']:>8.2f} {100 * fig['sliding']:>8.1f}%  {extra}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", default="meet20", help="comma-separated sample names ('' for none)")
    ap.add_argument("--library", default="default", help="motion-graph pack (default: the default library)")
    ap.add_argument("--worst", type=int, default=5, help="list this many edges with the most slide")
    a = ap.parse_args(argv)
    from authoring.default_library import ensure_library
    from runtime.motion.contacts import slide_figures
    from runtime.motion.graph import MotionGraph
    graph = MotionGraph.load(ensure_library(a.library, log=lambda *x: None, progress=False))
    print(f"{'':<28} {'mean':>8} {'p95':>8} {'>10cm/s':>9}   (planted-point horizontal speed, cm/s)")
    v = library_speeds(graph)
    row("library (FK of every edge)", slide_figures(v), f"{graph.num_edges} edges")
    per_edge = np.array([np.nanmax(np.r_[v[s:e].ravel(), 0.0]) for s, e in zip(graph.edge_start[:-1], graph.edge_start[1:])])
    for e in np.argsort(-per_edge)[:a.worst]:
        print(f"    edge {e:>4} {graph.edge_src[e]:>3}->{graph.edge_dst[e]:<3} {','.join(graph.edge_labels[e]):<22} "
              f"max {100 * per_edge[e]:6.1f} cm/s")
    for name in [s for s in a.samples.split(",") if s]:
        from authoring.commands.bake import load_sample
        from runtime.crowd.scheduler import plan_scenario
        sc, g, env, roadmap = load_sample(ROOT / "samples" / name, log=lambda *x: None, progress=False)
        res = plan_scenario(sc, g, env, roadmap)
        sp, held, frames = track_figures(g, [c.track for c in res.characters])
        row(f"{name} (planned tracks)", slide_figures(sp), f"held locomotion {held} of {frames} frames")


if __name__ == "__main__":
    main()
