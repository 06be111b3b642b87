"""Acceptance figures of the default library (procedural capture, seed 0)."""
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from runtime.motion import ops, quat
from runtime.motion.graph import STATES, TRANSITION
from test_motion_graph import seam_report


def test_size_and_hubs(default_graph):
    g = default_graph
    assert g.total_seconds >= 60.0
    assert 6 <= g.num_nodes <= 40
    assert {"stand", "walk", "sit", "carry"} <= set(g.node_labels_all())


def test_degree_within_state_subgraph(default_graph):
    g = default_graph
    for n in range(g.num_nodes):
        s = g.node_state[n]
        assert np.sum((g.edge_src == n) & (g.edge_state == s)) >= 2, (n, g.node_labels[n])
        assert np.sum((g.edge_dst == n) & (g.edge_state == s)) >= 2, (n, g.node_labels[n])


def test_walking_parallel_edges_and_heading_span(default_graph):
    g = default_graph
    w = np.flatnonzero(g.edge_state == STATES.index("walking"))
    key = g.edge_src[w] * g.num_nodes + g.edge_dst[w]
    pairs, counts = np.unique(key, return_counts=True)
    assert np.median(counts) >= 3
    spans = []
    for k in pairs:
        h = np.degrees(g.edge_disp[w[key == k], 2])
        spans.append((h.min(), h.max()))
    assert any(lo <= -45 and hi >= 45 for lo, hi in spans)


def test_every_join_is_seamless(default_graph):
    root, excess = seam_report(default_graph)
    assert root < 1e-9
    assert excess <= 1.0


def _path(g, allowed, a, targets):
    """Fewest-edge path (edge ids) from node a to any node in targets over allowed edges."""
    m = np.flatnonzero(allowed)
    A = csr_matrix((np.ones(len(m)), (g.edge_src[m], g.edge_dst[m])), shape=(g.num_nodes,) * 2)
    dist, pred = shortest_path(A, unweighted=True, indices=a, return_predecessors=True)
    t = min(targets, key=lambda n: dist[n])
    if not np.isfinite(dist[t]):
        return None
    nodes = [t]
    while nodes[-1] != a:
        nodes.append(pred[nodes[-1]])
    nodes = nodes[::-1]
    return [int(m[(g.edge_src[m] == u) & (g.edge_dst[m] == v)][0]) for u, v in zip(nodes[:-1], nodes[1:])]


# the state change each stage label makes
STAGE_STATES = {"sit_down": ("walking", "sitting"), "sit": ("sitting", "sitting"), "stand_up": ("sitting", "walking"),
                "pick_up": ("walking", "carrying"), "carry": ("carrying", "carrying"),
                "put_down": ("carrying", "walking")}


def _walk_cycle(g, stages):
    """Chain edges through the labelled stages; returns the edge list or fails."""
    walking = STATES.index("walking")
    start = int(np.flatnonzero(g.node_state == walking)[0])
    node, edges = start, []
    for label in stages:
        a, b = (STATES.index(x) for x in STAGE_STATES[label])
        cand = [e for e in range(g.num_edges) if label in g.edge_labels[e]
                and g.node_state[g.edge_src[e]] == a and g.node_state[g.edge_dst[e]] == b]
        assert cand, f"no edge labelled {label}"
        # get to the source of some edge with that label, inside the current state
        state_edges = g.edge_state == g.node_state[node]
        best = None
        for e in cand:
            p = [] if g.edge_src[e] == node else _path(g, state_edges, node, [int(g.edge_src[e])])
            if p is not None and (best is None or len(p) < len(best[0])):
                best = (p, e)
        assert best is not None, f"cannot reach a {label} edge from node {node}"
        edges += best[0] + [best[1]]
        node = int(g.edge_dst[best[1]])
    back = _path(g, g.edge_state == g.node_state[node], node, [start])
    assert back is not None, "cannot walk back to the start node"
    return edges + back


def _check_chain(g, edges, stages):
    clip = g.edge_clip(edges[0])
    for a, b in zip(edges[:-1], edges[1:]):
        assert g.edge_dst[a] == g.edge_src[b]
        clip = ops.append(clip, g.edge_clip(b))
    # the stages happen in order: first edge doing each stage's state change
    def first(label):
        a, b = (STATES.index(x) for x in STAGE_STATES[label])
        return next(k for k, e in enumerate(edges) if label in g.edge_labels[e]
                    and g.node_state[g.edge_src[e]] == a and g.node_state[g.edge_dst[e]] == b)
    pos = [first(s) for s in stages]
    assert pos == sorted(pos), [g.edge_labels[e] for e in edges]
    assert g.node_state[g.edge_dst[edges[-1]]] == STATES.index("walking")
    # the chained motion has no rotation pop: every frame step is no larger than the largest
    # step inside the source clips
    steps = quat.angle(clip.rotations[1:].astype(float), clip.rotations[:-1].astype(float)).max(axis=1)
    inside = max(quat.angle(g.edge_clip(e).rotations[1:].astype(float),
                            g.edge_clip(e).rotations[:-1].astype(float)).max() for e in edges)
    assert steps.max() <= inside + 1e-6


def test_walk_sit_walk(default_graph):
    stages = ["sit_down", "sit", "stand_up"]
    _check_chain(default_graph, _walk_cycle(default_graph, stages), stages)


def test_walk_pickup_carry_putdown_walk(default_graph):
    stages = ["pick_up", "carry", "put_down"]
    _check_chain(default_graph, _walk_cycle(default_graph, stages), stages)


def test_transition_edges_connect_states(default_graph):
    g = default_graph
    t = np.flatnonzero(g.edge_state == TRANSITION)
    pairs = {(STATES[g.node_state[g.edge_src[e]]], STATES[g.node_state[g.edge_dst[e]]]) for e in t}
    assert {("walking", "sitting"), ("sitting", "walking"), ("walking", "carrying"), ("carrying", "walking")} <= pairs
