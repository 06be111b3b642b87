"""Episode detection (Kim, Hwang, Hyun and Lee 2012, section 4.1): contact, proximity with reaction,
synchronicity; nearby events merged into episodes.

For every pair of performers of a take, on the shared clock:

* **Contact.** Body points with radii (:data:`.features.BODY_POINTS`: hand centres, elbows,
  shoulders, head, chest, pelvis, knees, ankles) of the two performers overlap:
  ``|x_a - x_b| < r_a + r_b``. Runs of contact frames (gaps of up to ``close_gap`` frames
  closed) of at least ``min_frames`` frames are events.
* **Proximity with reaction.** The two roots are within ``proximity_m`` and either performer
  *acts*. The motion variation ``V_i`` of Eq. 4 (:func:`.features.motion_variation`) is what
  measures acting, but steady locomotion has a large ``V`` (the legs swing through the
  window) without being a reaction to anybody, so the action signal used here is the
  variation in excess of the performer's own recent level::

      A_i = max(0, V_i - baseline_factor * mean(V over [i - baseline_s, i - baseline_gap_s]))

  (zero while the performer walks forwards faster than ``locomotion_speed``: locomotion is
  not a reaction) and a performer reacts where ``A_i > reaction_threshold`` (m^2 per joint). The reaction is
  to an *approach*: the pair must have come at least ``approach_m`` closer within the last
  ``approach_s`` seconds (so walking off after an encounter is not a new event). An action
  event starts at the onset of the action (where V starts to rise).
* **Synchronicity** (Eq. 5)::

      S_ij = A_i^A * A_j^B * exp(-g(A, B)) * exp(-g(B, A))

  with ``i = j`` on the shared clock, ``g(A, B)`` the angle between A's gaze (head forward)
  and the vector from A's face to B's upper body (thorax joint); events where
  ``S > sync_threshold`` and the two are within ``sync_range_m``.
* **Merging.** Events that overlap in time (after widening by ``merge_gap_s``) and either
  share a performer or lie within ``merge_dist_m`` of each other are merged (transitively)
  into one episode, which may then involve more than two performers.
* **Whole actions.** An episode lasts until its performers are back in the pose they had at
  its start (within ``rest_m``), or have held still for a second (a new rest pose, e.g.
  holding the box just received), at most ``max_extend_s`` after its last event: a bow is
  one episode from bending down to standing up, not just its onset.

All thresholds are in :class:`EpisodeParams`; they were chosen, as in the paper, by trial and
error -- here against the ground truth of the procedural takes (see tests).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .features import PersonFeatures, person_features

__all__ = ["EpisodeParams", "DetectedEvent", "Episode", "action_signal", "forward_speed", "pair_signals", "detect_events",
           "merge_events", "extend_episodes", "detect_episodes", "score_against_ground_truth"]


@dataclass
class EpisodeParams:
    window: int = 5                   # w of Eq. 4 (frames at 30 Hz; scaled with fps)
    close_gap: int = 3                # frames
    min_frames: int = 2
    proximity_m: float = 2.0
    approach_m: float = 0.3           # ... after coming this much closer
    approach_s: float = 3.0           # ... within this many seconds
    reaction_threshold: float = 0.06  # m^2 per joint
    baseline_factor: float = 2.0
    baseline_s: float = 1.5
    baseline_gap_s: float = 0.4
    locomotion_speed: float = 0.5     # m/s forward: walking, not reacting
    sync_threshold: float = 0.01
    sync_range_m: float = 4.0
    merge_gap_s: float = 1.0
    rest_m: float = 0.04              # an action lasts until the pose is back within this (RMS m)
    max_extend_s: float = 2.5         # ... or at most this long after the trigger ends
    merge_dist_m: float = 2.5


@dataclass
class DetectedEvent:
    kind: str                         # contact | proximity | sync
    people: tuple                     # (a, b)
    start: int                        # first frame
    end: int                          # last frame (inclusive)
    peak: int                         # frame of the strongest evidence
    strength: float
    where: np.ndarray                 # (2,) ground position (midpoint of the two roots at peak)
    contact_frames: tuple = ()        # for contact: every frame in contact


@dataclass
class Episode:
    people: tuple                     # sorted performer indices
    start: int
    end: int
    events: list = field(default_factory=list)

    @property
    def kinds(self) -> tuple:
        return tuple(sorted({e.kind for e in self.events}))


def _runs(mask, close_gap=0, min_len=1):
    m = np.asarray(mask, dtype=bool).copy()
    if close_gap > 0 and m.any():
        idx = np.flatnonzero(m)
        gaps = np.diff(idx)
        for i in np.flatnonzero((gaps > 1) & (gaps <= close_gap + 1)):
            m[idx[i]:idx[i + 1]] = True
    d = np.diff(np.concatenate([[0], m.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    keep = (ends - starts + 1) >= min_len
    return list(zip(starts[keep].tolist(), ends[keep].tolist()))


def forward_speed(feat: PersonFeatures) -> np.ndarray:
    """Root speed along the facing direction (m/s), per frame."""
    vel = np.gradient(feat.root_xz, axis=0) * feat.fps
    fwd = np.stack([np.sin(feat.heading), np.cos(feat.heading)], axis=-1)
    return np.sum(vel * fwd, axis=1)


def action_signal(v: np.ndarray, fps: float, p: EpisodeParams, fwd_speed=None) -> np.ndarray:
    """``A_i``: Eq. 4's variation in excess of the performer's level over the preceding
    ``baseline_s`` seconds (ending ``baseline_gap_s`` before the frame); zero while the
    performer walks forward faster than ``locomotion_speed``."""
    F = len(v)
    nb = max(int(round(p.baseline_s * fps)), 1)
    ng = max(int(round(p.baseline_gap_s * fps)), 0)
    c = np.concatenate([[0.0], np.cumsum(v)])
    i = np.arange(F)
    b = np.clip(i - ng, 0, F)
    a = np.clip(b - nb, 0, F)
    n = b - a
    base = np.where(n > 0, (c[b] - c[a]) / np.maximum(n, 1), 0.0)
    out = np.maximum(v - p.baseline_factor * base, 0.0)
    if fwd_speed is not None:
        out = np.where(fwd_speed > p.locomotion_speed, 0.0, out)
    return out


def _onset(runs, feats, acts, p: EpisodeParams):
    """Move the start of action runs back to the onset of the action: while the acting
    performers' V keeps falling going back and is above 1/10 of the threshold (at most 0.5 s)."""
    out = []
    back_n = int(round(0.5 * feats[0].fps))
    for s, e in runs:
        who = [i for i in range(len(feats)) if acts[i][s:e + 1].max() > p.reaction_threshold] or [0, 1]
        s2 = s
        lim = max(s - back_n, 0)
        while s2 > lim and any(p.reaction_threshold * 0.1 < feats[i].variation[s2 - 1] < feats[i].variation[s2]
                               for i in who):
            s2 -= 1
        out.append((s2, e))
    return out


def extend_episodes(episodes, feats, fps: float, p: EpisodeParams):
    """Let every episode last until the whole action is over: until each of its performers is
    back within ``rest_m`` (RMS) of its pose at the episode's start, or has held still (V below
    1/10 of the reaction threshold) for a second, at most ``max_extend_s`` after the last
    event; episodes that then overlap and share a performer are merged."""
    ext = int(round(p.max_extend_s * fps))
    still_n = int(round(1.0 * fps))
    quiet = 0.1 * p.reaction_threshold
    for ep in episodes:
        F = len(feats[0].variation)
        J = feats[0].pose.shape[1]
        end = ep.end
        lim = min(ep.end + ext, F - 1)
        done = set()
        while end < lim and len(done) < len(ep.people):
            for q in ep.people:
                if q in done:
                    continue
                back = np.linalg.norm(feats[q].pose[end] - feats[q].pose[ep.start]) / np.sqrt(J) < p.rest_m
                still = end - still_n >= ep.end and np.all(feats[q].variation[end - still_n:end + 1] < quiet)
                if back or still:
                    done.add(q)
            if len(done) < len(ep.people):
                end += 1
        ep.end = int(end)
    merged = []
    for ep in sorted(episodes, key=lambda e: (e.start, e.people)):
        hit = next((m for m in merged if m.start <= ep.end and ep.start <= m.end and set(m.people) & set(ep.people)),
                   None)
        if hit is None:
            merged.append(ep)
        else:
            hit.people = tuple(sorted(set(hit.people) | set(ep.people)))
            hit.start, hit.end = min(hit.start, ep.start), max(hit.end, ep.end)
            hit.events = sorted(hit.events + ep.events, key=lambda e: (e.start, e.kind))
    return merged


def _approached(dist, fps, p: EpisodeParams):
    """Frames at which the pair has come at least ``approach_m`` closer within the last
    ``approach_s`` seconds (the reaction is to an approach, not to leaving)."""
    n = max(int(round(p.approach_s * fps)), 1)
    pad = np.concatenate([np.full(n, dist[0]), dist])
    recent_max = np.lib.stride_tricks.sliding_window_view(pad, n + 1)[:len(dist)].max(axis=1)
    return recent_max - dist > p.approach_m


def _angle(u, v):
    nu = np.linalg.norm(u, axis=-1)
    nv = np.linalg.norm(v, axis=-1)
    cos = np.sum(u * v, axis=-1) / np.maximum(nu * nv, 1e-12)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def pair_signals(fa: PersonFeatures, fb: PersonFeatures, act_a, act_b):
    """Per-frame contact mask, root distance and synchronicity S (Eq. 5) of one pair."""
    d = np.linalg.norm(fa.points[:, :, None, :] - fb.points[:, None, :, :], axis=-1)
    gap = d - (fa.radii[:, None] + fb.radii[None, :])
    contact = (gap < 0).any(axis=(1, 2))
    depth = np.maximum(-gap, 0).max(axis=(1, 2))
    dist = np.linalg.norm(fa.root_xz - fb.root_xz, axis=1)
    g_ab = _angle(fa.gaze, fb.chest - fa.face)
    g_ba = _angle(fb.gaze, fa.chest - fb.face)
    S = act_a * act_b * np.exp(-g_ab) * np.exp(-g_ba)
    return contact, depth, dist, S


def detect_events(take, params: EpisodeParams | None = None, features=None) -> list[DetectedEvent]:
    """All contact, proximity and synchronicity events of every pair of a take."""
    p = params or EpisodeParams()
    fps = take.fps
    w = max(int(round(p.window * fps / 30.0)), 1)
    feats = features or [person_features(c, w) for c in take.clips]
    acts = [action_signal(f.variation, fps, p, forward_speed(f)) for f in feats]
    out = []
    n = len(feats)
    for a in range(n):
        for b in range(a + 1, n):
            contact, depth, dist, S = pair_signals(feats[a], feats[b], acts[a], acts[b])
            mid = 0.5 * (feats[a].root_xz + feats[b].root_xz)

            def add(kind, runs, score):
                for s, e in runs:
                    pk = s + int(np.argmax(score[s:e + 1]))
                    extra = tuple(int(f) for f in np.flatnonzero(contact[s:e + 1]) + s) if kind == "contact" else ()
                    out.append(DetectedEvent(kind, (a, b), int(s), int(e), int(pk), float(score[pk]),
                                             mid[pk].copy(), extra))
            add("contact", _runs(contact, p.close_gap, p.min_frames), depth)
            react = np.maximum(acts[a], acts[b])
            prox = (dist < p.proximity_m) & (react > p.reaction_threshold) & _approached(dist, fps, p)
            add("proximity", _onset(_runs(prox, p.close_gap, max(p.min_frames, 3)),
                                    [feats[a], feats[b]], [acts[a], acts[b]], p), react)
            sync = (S > p.sync_threshold) & (dist < p.sync_range_m)
            add("sync", _onset(_runs(sync, p.close_gap, max(p.min_frames, 3)),
                               [feats[a], feats[b]], [acts[a], acts[b]], p), S)
    out.sort(key=lambda e: (e.start, e.people, e.kind))
    return out


def merge_events(events, fps: float, params: EpisodeParams | None = None) -> list[Episode]:
    """Merge events that are close in time and share a performer or are close in space."""
    p = params or EpisodeParams()
    gap = int(round(p.merge_gap_s * fps))
    n = len(events)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            ei, ej = events[i], events[j]
            if ei.start > ej.end + gap or ej.start > ei.end + gap:
                continue
            if set(ei.people) & set(ej.people) or np.linalg.norm(ei.where - ej.where) < p.merge_dist_m:
                parent[find(i)] = find(j)
    groups: dict = {}
    for i in range(n):
        groups.setdefault(find(i), []).append(events[i])
    eps = []
    for evs in groups.values():
        people = tuple(sorted({q for e in evs for q in e.people}))
        eps.append(Episode(people, min(e.start for e in evs), max(e.end for e in evs),
                           sorted(evs, key=lambda e: (e.start, e.kind))))
    eps.sort(key=lambda e: (e.start, e.people))
    return eps


def detect_episodes(take, params: EpisodeParams | None = None, features=None) -> list[Episode]:
    """Events of a take merged into episodes, each extended to the end of its action."""
    p = params or EpisodeParams()
    fps = take.fps
    feats = features or [person_features(c, max(int(round(p.window * fps / 30.0)), 1)) for c in take.clips]
    return extend_episodes(merge_events(detect_events(take, p, feats), fps, p), feats, fps, p)


def score_against_ground_truth(episodes, gt_events, fps: float, tolerance_s: float = 0.5) -> dict:
    """Precision / recall of detected episodes against a take's ground-truth events.

    A ground-truth event is *found* when an episode overlaps its frame interval (both widened
    by ``tolerance_s``) and involves all of its performers. An episode is *correct* when it is
    such a match for at least one ground-truth event. Events marked ``optional`` justify an
    episode but are not counted in recall."""
    tol = int(round(tolerance_s * fps))
    found = [False] * len(gt_events)
    required = [not g.get("optional", False) for g in gt_events]
    correct = [False] * len(episodes)
    for gi, g in enumerate(gt_events):
        gp = set(int(q) for q in g["people"])
        for ei, e in enumerate(episodes):
            if e.start - tol <= int(g["end"]) and int(g["start"]) <= e.end + tol and gp <= set(e.people):
                found[gi] = True
                correct[ei] = True
    return {"gt_events": int(sum(required)), "found": int(sum(f for f, r in zip(found, required) if r)),
            "episodes": len(episodes), "correct": int(sum(correct)),
            "missed": [g for g, f, r in zip(gt_events, found, required) if r and not f],
            "spurious": [(e.people, e.start, e.end, e.kinds) for e, c in zip(episodes, correct) if not c]}
