"""Pictures of the foot lock, before and after (docs/foot_lock_footprints.png, docs/foot_lock_filmstrip.png).

One character of the default library is planned from standing to a goal 8 m away, arriving in a
window 9 s later (a start, a slow walk, a stop); its joints are evaluated as the library plays them and as the
bake writes them (planted feet locked, runtime/motion/footlock.py).

* footprints: the toe joints from above, every frame a small dot, the frames a foot is planted
  (toe within 5 cm of its lowest point, vertical speed under 15 cm/s: runtime/footslide.py) large:
  before, planted feet smear into streaks; after, each footstep is one point;
* filmstrip: the skeleton from the side (distance along the walk against height) at every fourth
  frame of the start and of the stop, with the toes' path and their planted frames.

    CROWDWEAVE_CACHE=... python docs/make_foot_pictures.py [--out docs]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from runtime.crowd.scenario import parse_scenario  # noqa: E402
from runtime.crowd.scheduler import plan_scenario  # noqa: E402
from runtime.crowd.tracks import joint_positions  # noqa: E402
from runtime.footslide import planted_slide, slide_summary  # noqa: E402
from runtime.library import load_library  # noqa: E402
from runtime.motion.footlock import FootLockModel  # noqa: E402
from runtime.pose import locked_joint_positions  # noqa: E402

SCENARIO = {"name": "footprints", "duration": 10.0, "seed": 0, "character": [
    {"name": "walker", "start": {"position": [0.0, 0.0], "heading": 0.0, "pose": "stand"},
     "goal": [{"position": [4.0, 7.0], "heading": -60.0, "pose": "stand", "time": [9.0, 9.5]}]}]}


def plan(graph):
    res = plan_scenario(parse_scenario(SCENARIO, "footprints"), graph)
    return res.characters[0].track


def footprints(ax, toe, title):
    plant, v = planted_slide(toe, 30.0)
    s = slide_summary(v[plant])
    for side, color in ((0, "tab:blue"), (1, "tab:red")):
        p = toe[:, side]
        ax.plot(p[:, 0], p[:, 2], "-", color=color, lw=0.4, alpha=0.4)
        ax.plot(p[:, 0], p[:, 2], ".", color=color, ms=1.5, alpha=0.5)
        q = p[plant[:, side]]
        ax.plot(q[:, 0], q[:, 2], "o", color=color, ms=5, mfc="none", mew=0.9,
                label=f"{'left' if side == 0 else 'right'} toe, planted")
    ax.set_aspect("equal")
    ax.set_title(f"{title}\nplanted toes: mean {s['mean_cm_s']:.1f} cm/s, p95 {s['p95_cm_s']:.1f} cm/s, "
                 f"{s['sliding_share'] * 100:.0f}% > 10 cm/s", fontsize=9)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.grid(alpha=0.3)


def filmstrip(ax, jp, parents, frames, fwd, legs, plant, title):
    """Skeletons from the side (distance along ``fwd`` against height), legs drawn strong, and
    under them the toes' path over the whole stretch with the planted frames in black."""
    leg = set(np.concatenate([legs.hip, legs.knee, legs.ankle, legs.toe]).tolist())
    for k, f in enumerate(frames):
        d = jp[f] @ fwd
        y = jp[f, :, 1]
        c = plt.cm.viridis(k / max(len(frames) - 1, 1))
        for j, p in enumerate(parents):
            if p >= 0:
                strong = j in leg
                ax.plot([d[p], d[j]], [y[p], y[j]], "-", color=c, lw=1.2 if strong else 0.5,
                        alpha=1.0 if strong else 0.35)
    span = np.arange(frames[0], frames[-1] + 1)
    for s in range(2):
        t = jp[span, legs.toe[s]]
        ax.plot(t @ fwd, t[:, 1], "-", color="0.5", lw=0.6)
        q = t[plant[span, s]]
        ax.plot(q @ fwd, q[:, 1], "o", color="k", ms=2.5)
    ax.set_aspect("equal")
    ax.set_ylim(-0.05, 1.6)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("along the walk (m)")
    ax.set_ylabel("height (m)")
    ax.grid(alpha=0.3)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent))
    args = ap.parse_args(argv)
    out = Path(args.out)
    graph = load_library("default")
    legs = FootLockModel.for_library(graph).legs
    tr = plan(graph)
    before = joint_positions(graph, tr)
    after = locked_joint_positions(graph, tr)

    fig, axes = plt.subplots(1, 2, figsize=(11, 7.5), sharex=True, sharey=True)
    footprints(axes[0], before[:, legs.toe], "before: the library's poses on the planned path")
    footprints(axes[1], after[:, legs.toe], "after: planted feet locked")
    axes[1].legend(loc="lower right", fontsize=8)
    fig.suptitle("Footprints from above: one character from standing to a goal 8 m away, 9 s later", fontsize=11)
    fig.tight_layout()
    fig.savefig(out / "foot_lock_footprints.png", dpi=110)
    plt.close(fig)

    speed = np.linalg.norm(np.diff(tr.root[:, :2], axis=0), axis=1) * 30
    moving = np.flatnonzero(speed > 0.05)
    s0, s1 = int(moving[0]), int(moving[-1])
    start = list(range(max(s0 - 3, 0), min(s0 + 45, len(tr)), 4))
    stop = list(range(max(s1 - 45, 0), min(s1 + 6, len(tr)), 4))
    d = tr.root[s1, :2] - tr.root[s0, :2]
    fwd = np.array([d[0], 0.0, d[1]]) / max(np.linalg.norm(d), 1e-9)
    par = graph.skeleton.parents
    fig, axes = plt.subplots(2, 2, figsize=(14, 6.5), gridspec_kw={"width_ratios": [1, 1]})
    for row, (jp, label) in enumerate(((before, "before"), (after, "after"))):
        plant, _ = planted_slide(jp[:, legs.toe], 30.0)
        filmstrip(axes[row, 0], jp, par, start, fwd, legs, plant, f"{label}: the start (every 4th frame)")
        filmstrip(axes[row, 1], jp, par, stop, fwd, legs, plant, f"{label}: the stop (every 4th frame)")
    fig.suptitle("Side view: the toes' path (grey) with their planted frames (black): streaks before, points "
                 "after; later frames lighter", fontsize=11)
    fig.tight_layout()
    fig.savefig(out / "foot_lock_filmstrip.png", dpi=100)
    plt.close(fig)
    print(f"wrote {out / 'foot_lock_footprints.png'} and {out / 'foot_lock_filmstrip.png'}")


if __name__ == "__main__":
    main()
