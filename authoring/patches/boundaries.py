"""Boundary determination (Kim, Hwang, Hyun and Lee 2012, section 4.2): pose clustering and the
choice of pose groups at which the patches are cut.

1. **Candidate frames.** For every performer of every episode, the frames before the episode
   (entry side) and after it (exit side) that are *eventless*: at least ``margin_s`` away
   from any episode of that performer, at most ``max_pad_s`` from this one.
2. **Pose clustering.** Agglomerative hierarchical clustering with *complete* linkage
   (``scipy.cluster.hierarchy``) of the candidates' boundary features
   (:func:`.features.boundary_features`: pose + velocity, RMS metres), cut at ``threshold``, so
   the dissimilarity between any two poses of a group is below the threshold.
3. **Subset search.** Let ``G_1..G_k`` be the ``k`` largest groups. For every non-empty subset
   ``S`` of them (``2^k - 1`` subsets; all cardinalities, as in the paper) each fragment side
   is cut at the nearest frame (to its episode) whose group is in ``S``, and

       cost(S) = weight * |S| + sum over sides of the frames added to the patch (padding)

   with ``infeasible_cost`` per episode that cannot be closed by ``S``. The subset of least
   cost is chosen: ``weight`` (frames per pose class) trades the diversity of boundary poses
   against the size of the patches. A side whose window reaches the start or end of the take
   may instead be *closed* there (a source/sink port, pose class -1) at ``closed_cost`` extra.

Evaluated for all subsets at once with numpy; deterministic for the same input.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

__all__ = ["BoundaryParams", "Side", "cluster_poses", "group_order", "side_candidates", "select_subset"]


@dataclass
class BoundaryParams:
    threshold: float = 0.06          # RMS metres (pose + velocity) inside a group
    k: int = 10                      # largest groups considered
    weight: float = 60.0             # frames per pose class in the cost
    max_pad_s: float = 5.0           # a boundary at most this far from its episode
    margin_s: float = 0.2            # ... and at least this far from any event of the performer
    max_candidates: int = 3500       # clustering sample size (stride grows beyond it)
    infeasible_cost: float = 1.0e6
    closed_cost: float = 150.0       # frames: price of a closed (source/sink) port


@dataclass
class Side:
    """One end of one fragment: frames ``[lo, hi]`` of performer ``person`` in take ``take``
    may hold the cut; ``near`` is the frame next to the episode."""
    episode: int
    take: int
    person: int
    kind: str                        # "entry" | "exit"
    lo: int
    hi: int
    anchor: int                      # the episode's first (entry) / last (exit) frame
    can_close: bool                  # window touches the start/end of the take
    close_frame: int                 # where a closed port would be


def cluster_poses(X: np.ndarray, threshold: float) -> np.ndarray:
    """Complete-linkage agglomerative clustering of the rows of ``X`` (already scaled so the
    Euclidean distance is the dissimilarity); returns group ids 0..G-1 (by first occurrence)."""
    from scipy.cluster.hierarchy import fcluster, linkage

    n = len(X)
    if n == 0:
        return np.zeros(0, np.int64)
    if n == 1:
        return np.zeros(1, np.int64)
    Z = linkage(X, method="complete", metric="euclidean")
    raw = fcluster(Z, t=threshold, criterion="distance")
    _, first = np.unique(raw, return_index=True)
    order = np.argsort(first)
    remap = np.empty(raw.max() + 1, np.int64)
    remap[np.unique(raw)[order]] = np.arange(len(order))
    return remap[raw]


def group_order(labels: np.ndarray) -> np.ndarray:
    """Group ids sorted by size (descending), ties by id."""
    ids, counts = np.unique(labels, return_counts=True)
    return ids[np.lexsort((ids, -counts))]


def side_candidates(side: Side, frames: np.ndarray, labels: np.ndarray, groups: np.ndarray):
    """For one side: per group in ``groups`` the sampled member frame nearest to the episode
    (or -1), from the sampled ``frames`` (take frame numbers of this performer, sorted) and
    their group ``labels``."""
    out = np.full(len(groups), -1, np.int64)
    sel = (frames >= side.lo) & (frames <= side.hi)
    f, lab = frames[sel], labels[sel]
    for gi, g in enumerate(groups):
        m = f[lab == g]
        if len(m):
            out[gi] = m.max() if side.kind == "entry" else m.min()
    return out


def select_subset(pads: np.ndarray, close: np.ndarray, side_episode: np.ndarray, n_episodes: int,
                  p: BoundaryParams):
    """Choose the subset of groups (columns of ``pads``) of least cost.

    pads: (n_sides, k) frames added by cutting side s at group g (inf: no candidate);
    close: (n_sides,) frames + closed_cost to close the side at the take boundary (inf: not allowed).
    Returns (mask (k,) bool, cost, table [(subset tuple, cost, feasible episodes)] sorted by cost)."""
    k = pads.shape[1]
    subsets = [c for r in range(1, k + 1) for c in combinations(range(k), r)]
    M = np.zeros((len(subsets), k), bool)
    for i, c in enumerate(subsets):
        M[i, list(c)] = True
    big = np.where(M[:, None, :], pads[None, :, :], np.inf).min(axis=2)      # (n_subsets, n_sides)
    side_cost = np.minimum(big, close[None, :])
    ep_cost = np.zeros((len(subsets), n_episodes))
    np.add.at(ep_cost.T, side_episode, side_cost.T)
    feasible = np.isfinite(ep_cost)
    total = np.where(feasible, ep_cost, p.infeasible_cost).sum(axis=1) + p.weight * M.sum(axis=1)
    order = np.lexsort((M.sum(axis=1), total))                             # ties: fewer groups
    best = int(order[0])
    table = [(subsets[i], float(total[i]), int(feasible[i].sum())) for i in order[:20]]
    return M[best], float(total[best]), table
