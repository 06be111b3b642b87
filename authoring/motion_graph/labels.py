"""Frame labels, locomotion states and node labels (Sung, Kovar and Gleicher 2005, sections
3.2 and 4).

A *state* is a locomotion subgraph of Sung et al. 2005 ("a character who has just picked up a box
would be required to use one of the carry edges"): ``walking``, ``carrying``, ``sitting``.
Every frame label maps either to a state or to a *transition* between two states. Pose
constraints name *node labels* ("stand", "sit", "carry", "walk").
"""
from __future__ import annotations

import numpy as np

STATES = ("walking", "carrying", "sitting")

# frame label -> state, for labels inside one state
LABEL_STATE = {
    "walk": "walking", "start": "walking", "stop": "walking", "idle": "walking", "turn": "walking",
    "run": "walking", "jump": "walking", "dance": "walking", "stand": "walking",
    "carry": "carrying", "carry_start": "carrying", "carry_stop": "carrying", "carry_idle": "carrying",
    "carry_turn": "carrying",
    "sit": "sitting",
}
# frame label -> (state before, state after), for labels that change state
TRANSITIONS = {
    "sit_down": ("walking", "sitting"),
    "stand_up": ("sitting", "walking"),
    "pick_up": ("walking", "carrying"),
    "put_down": ("carrying", "walking"),
}
# frame label at a hub occurrence -> node label used by pose constraints
NODE_LABEL = {
    "idle": "stand", "stand": "stand", "stop": "stand", "start": "stand",
    "walk": "walk", "turn": "stand", "run": "walk", "jump": "walk", "dance": "walk",
    "sit": "sit",
    "carry": "carry", "carry_idle": "carry", "carry_start": "carry", "carry_stop": "carry", "carry_turn": "carry",
}


def state_classes(labels: list[str]):
    """Class per frame: 0..S-1 for states, S + k for transition label k (and unknown labels
    default to walking). Returns (classes (N,), names list, compatible (C, C) bool)."""
    trans = sorted(TRANSITIONS)
    names = list(STATES) + trans
    idx = {n: i for i, n in enumerate(names)}
    S = len(STATES)
    cls = np.empty(len(labels), dtype=np.int64)
    for i, lab in enumerate(labels):
        if lab in TRANSITIONS:
            cls[i] = idx[lab]
        else:
            cls[i] = idx[LABEL_STATE.get(lab, "walking")]
    C = len(names)
    comp = np.zeros((C, C), dtype=bool)
    comp[np.arange(S), np.arange(S)] = True
    for k, t in enumerate(trans):
        a, b = TRANSITIONS[t]
        for st in (a, b):
            comp[idx[st], S + k] = comp[S + k, idx[st]] = True
    return cls, names, comp


def state_of_label(label: str) -> str | None:
    """The state a label lies in, or None for a transition label."""
    if label in TRANSITIONS:
        return None
    return LABEL_STATE.get(label, "walking")


def pose_classes(labels: list[str], cls: np.ndarray, compatible: np.ndarray):
    """State classes (:func:`state_classes`) split further by node label, so that frames
    match only frames of the same pose kind ("stand" with "stand", "walk" with "walk"): a
    hub is then a standing or a walking pose, never both, and the data's own stops and
    starts are the only ways between them. Returns (classes (N,), compatible (C', C') bool)."""
    kinds = sorted({NODE_LABEL.get(lab, lab) for lab in labels})
    kind = np.array([kinds.index(NODE_LABEL.get(lab, lab)) for lab in labels], dtype=np.int64)
    K = len(kinds)
    return cls * K + kind, np.kron(compatible, np.eye(K, dtype=bool))
