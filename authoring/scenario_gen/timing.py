"""Timing of a generated scenario: arrival windows, ``after`` constraints and the duration.

A goal's earliest arrival E is the latest the previous arrival may be (the end of its window,
or the earliest arrival of an untimed goal; 0 at the start) plus the goal's need: the walking
(carrying) distance round the obstacles at ``walk_speed`` (``carry_speed``), times ``1 +
slack_ratio``, plus the state change (sitting down, picking up, putting down) plus ``slack``.
A window opens no earlier than E and is ``window_width`` wide. An ``after`` goal follows a
goal of another character that has a window [w0, w1] and no ``after`` itself: within = [a, b]
with a >= E - w0 (so even when the other arrives at w0 there is time) and b - a a window
width. The scenario lasts until the latest window closes or, for untimed goals,
``untimed_factor`` times the needs after the previous arrival, plus ``margin``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Leg", "legs", "assign_timing", "resolved_window", "arrival_bounds"]


@dataclass
class Leg:
    """The walk to one goal: from ``origin`` to ``target`` (a seat: the point ``approach`` m in
    front of it), ``distance`` m round the obstacles (inf: unreachable; a seat's approach
    included), at ``speed`` m/s, then ``change`` s of state change."""
    origin: np.ndarray
    target: np.ndarray
    distance: float
    speed: float
    change: float

    def need(self, p) -> float:
        travel = self.distance / self.speed
        return travel * (1.0 + p.slack_ratio) + self.change + p.slack


def legs(sc, fs, p) -> list:
    """Per character of the parsed scenario ``sc``, the :class:`Leg` of each goal."""
    out = []
    for c in sc.characters:
        prev, carrying, row = np.asarray(c.position, float), False, []
        for g in c.goals:
            target, extra, change = np.asarray(g.position, float), 0.0, 0.0
            if g.kind == "seat":
                target = target + p.approach * np.array([math.sin(g.heading), math.cos(g.heading)])
                extra, change = p.approach, p.sit_time
            elif g.kind == "box":
                change = p.pick_time
            elif carrying and g.pose == "stand":
                change = p.put_time
            d = float(fs.geodesic(prev, target[None])[0]) + extra
            row.append(Leg(prev, target, d, p.carry_speed if carrying else p.walk_speed, change))
            carrying = g.kind == "box" or (carrying and g.pose == "carry")
            prev = np.asarray(g.position, float)
        out.append(row)
    return out


def _up(t: float) -> float:
    """Rounded up to 0.1 s."""
    return math.ceil(t * 10.0 - 1e-9) / 10.0


def _width(rng, p) -> float:
    return round(float(rng.uniform(*p.window_width)), 1)


def assign_timing(tasks, goal_dicts, leg_rows, rng, p) -> float:
    """Adds ``time`` and ``after`` to the goal dicts (``goal_dicts[i][k]`` of ``tasks[i]``) and
    returns the duration. Meetings get one window for all members, or a window for the first
    and ``after`` it for the others."""
    windows = {}                  # (name, goal) -> its own time window (candidates for after)
    has_after = set()
    hi = {t.name: 0.0 for t in tasks}
    late = {t.name: 0.0 for t in tasks}
    done = set()
    by_meeting = {}
    group = {t.name: t.group for t in tasks}
    for i, t in enumerate(tasks):
        if t.meeting is not None:
            by_meeting.setdefault(t.meeting, []).append(i)

    def timed(i, w1):
        hi[tasks[i].name] = late[tasks[i].name] = w1

    for i, t in enumerate(tasks):
        if i in done:
            continue
        if t.meeting is not None:
            members = by_meeting[t.meeting]
            E = [hi[tasks[j].name] + leg_rows[j][0].need(p) for j in members]
            t0 = _up(max(E) + float(rng.uniform(0.0, 2.0)))
            t1 = round(t0 + _width(rng, p), 1)
            lead = members[0]
            goal_dicts[lead][0]["time"] = [t0, t1]
            windows[(tasks[lead].name, 0)] = (t0, t1)
            timed(lead, t1)
            follow = len(members) > 1 and rng.random() < 0.5
            for j in members[1:]:
                if follow:
                    w2 = _width(rng, p)
                    goal_dicts[j][0]["after"] = {"character": tasks[lead].name, "goal": 0, "within": [0.0, w2]}
                    has_after.add(tasks[j].name)
                    timed(j, t1 + w2)
                else:
                    goal_dicts[j][0]["time"] = [t0, t1]
                    windows[(tasks[j].name, 0)] = (t0, t1)
                    timed(j, t1)
            done.update(members)
            continue
        for gi, leg in enumerate(leg_rows[i]):
            need = leg.need(p)
            E = hi[t.name] + need
            r = rng.random()
            targets = [(n, k) for (n, k) in windows if n != t.name and n not in has_after and group[n] == t.group]
            if r < p.window_share:
                t0 = _up(E + float(rng.uniform(0.0, 3.0)))
                t1 = round(t0 + _width(rng, p), 1)
                goal_dicts[i][gi]["time"] = [t0, t1]
                if t.name not in has_after:
                    windows[(t.name, gi)] = (t0, t1)
                timed(i, t1)
            elif r < p.window_share + p.after_share and targets and not any(n == t.name for n, _ in windows):
                n, k = targets[int(rng.integers(len(targets)))]
                w0, w1 = windows[(n, k)]
                a = _up(max(0.0, E - w0) + float(rng.uniform(0.0, 1.0)))
                b = round(a + _width(rng, p), 1)
                goal_dicts[i][gi]["after"] = {"character": n, "goal": k, "within": [a, b]}
                has_after.add(t.name)
                timed(i, w1 + b)
            else:
                hi[t.name] = E
                late[t.name] += need * p.untimed_factor
    return float(math.ceil(max(late.values(), default=0.0) + p.margin))


def resolved_window(sc, g):
    """The absolute window of goal spec ``g`` of the parsed scenario ``sc``: its ``time``,
    intersected with [w0 + a, w1 + b] for ``after`` a goal with window [w0, w1] (None: untimed;
    an ``after`` on an untimed goal has no bound known in advance: ValueError)."""
    w = g.time
    if g.after is not None:
        other = sc.character(g.after["character"]).goals[g.after["goal"]]
        if other.time is None:
            raise ValueError(f"after {g.after['character']!r} goal {g.after['goal']}, which has no window")
        a, b = g.after["within"]
        wa = (other.time[0] + a, other.time[1] + b)
        w = wa if w is None else (max(w[0], wa[0]), min(w[1], wa[1]))
    return w


def arrival_bounds(sc, leg_rows, p) -> list:
    """Per character, per goal: (earliest arrival E, window or None, latest reasonable arrival)."""
    out = []
    for c, row in zip(sc.characters, leg_rows):
        hi = late = 0.0
        res = []
        for g, leg in zip(c.goals, row):
            need = leg.need(p)
            E = hi + need
            w = resolved_window(sc, g)
            if w is None:
                hi, late = E, late + need * p.untimed_factor
            else:
                hi = late = w[1]
            res.append((E, w, late))
        out.append(res)
    return out
