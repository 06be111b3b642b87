"""Scenario TOML fuzzing (hypothesis): a valid scenario with random edits -- values replaced by
values of any TOML type (NaN, inf, huge numbers, lists, tables, strings), keys removed or added
at any depth, the text cut or garbled -- is either accepted with every value usable (finite
numbers, windows in order, distinct prim names) or rejected with a ScenarioError: one line
naming the file, and for a value the table and the key. Never another exception."""
import json
import math
import re

import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from authoring.batch.toml_text import inline_value
from authoring.batch.toml_text import key as toml_key
from runtime.crowd.environment import Environment, Marker
from runtime.crowd.scenario import ScenarioError, load_scenario, parse_scenario, prim_name
from runtime.limits import MAX_CHARACTER_SECONDS, MAX_DURATION

LABELS = {"stand", "walk", "sit", "carry"}
ENV = Environment(
    polygons=[[(4.0, 4.0), (6.0, 4.0), (6.0, 6.0), (4.0, 6.0)]],
    markers=[Marker("/World/Seats/s01", "seat", (8.0, 0.0), 0.0), Marker("/World/Boxes/b01", "box", (0.0, 8.0), 1.0),
             Marker("/World/Regions/r", "region", (20.0, 0.0), 0.0,
                    np.array([(15.0, -5.0), (25.0, -5.0), (25.0, 5.0), (15.0, 5.0)]))])

BASE = {
    "name": "fuzz", "description": "d", "library": "default", "duration": 20.0, "seed": 3,
    "synthesis": {"epsilon": [0.02, 2.0, 0.0667], "passes": 2, "start_still": False, "approach_point": 1.0,
                  "n_m": 100, "k_m": 20, "n_max": 500},
    "character": [
        {"name": "a", "start": {"position": [0.0, 0.0], "heading": 90.0, "pose": "stand"},
         "goal": [{"position": [3.0, 0.0], "heading": 0.0, "time": [5.0, 6.0], "pose": "stand"},
                  {"seat": "/World/Seats/s01", "after": {"character": "b", "goal": 0, "within": [0.0, 2.0]}}]},
        {"name": "b", "start": {"seat": "/World/Seats/s01"},
         "goal": [{"box": "/World/Boxes/b01", "time": 12.0}]},
    ],
    "flock": [{"name": "sheep", "ddg": {"dim": 2, "agents": 10, "seconds": 30.0, "seed": 1}, "count": 2,
               "region": "/World/Regions/r", "seed": 0}],
    "tiling": [{"name": "zone", "zone": "/World/Regions/r", "patches": "synthetic", "period": 8.0, "horizon": 1.5,
                "seed": 0, "team": [{"count": 2, "start": [18.0, 0.0], "heading": 90.0,
                                     "targets": [[22.0, 1.0], [18.0, 0.0]]}]}],
}

floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
scalar = st.one_of(floats, st.integers(-2 ** 70, 2 ** 70), st.booleans(), st.text(max_size=6),
                   st.sampled_from([0, -1, 1, 0.0, -0.0, 1e300, -1e300, 5e-324, 2 ** 63, 2 ** 64, "", "stand", "sit",
                                    "/World/Seats/s01", "/World/Boxes/b01", "/World/Regions/r", "a", "b", "x y",
                                    "1st", "Zoë"]))
value = st.recursive(scalar, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                     st.dictionaries(st.sampled_from(["x", "position", "time", "name",
                                                                                      "goal", "within", "count"]),
                                                                     inner, max_size=3)),
                     max_leaves=6)


def _paths(node, prefix=()):
    """Every (path, value) inside a nested dict/list."""
    yield prefix, node
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


def _copy(x):
    return json.loads(json.dumps(x))


def _apply(doc, edit):
    kind, path, v = edit
    if not path:
        return doc if kind != "replace" else v
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    last = path[-1]
    if kind == "replace":
        parent[last] = v
    elif kind == "delete":
        del parent[last]
    elif kind == "add" and isinstance(parent[last], dict):
        parent[last]["unknown_" + str(abs(hash(str(v))) % 97)] = v
    elif kind == "wrap":
        parent[last] = [parent[last]]
    return doc


@st.composite
def edited(draw):
    doc = _copy(BASE)
    for _ in range(draw(st.integers(1, 4))):
        paths = [p for p, _ in _paths(doc) if p]       # the document itself: see the file test
        path = draw(st.sampled_from(paths))
        kind = draw(st.sampled_from(["replace", "replace", "replace", "delete", "add", "wrap"]))
        doc = _apply(doc, (kind, path, draw(value)))
    return doc


def _check_accepted(sc):
    assert 0 < sc.duration <= MAX_DURATION and math.isfinite(sc.duration)
    assert isinstance(sc.seed, int) and sc.seed >= 0
    assert len(sc.characters) * sc.duration <= MAX_CHARACTER_SECONDS
    assert all(math.isfinite(e) and e > 0 for e in sc.epsilon)
    assert len({prim_name(c.name) for c in sc.characters}) == len(sc.characters)
    for c in sc.characters:
        assert isinstance(c.name, str) and c.name and np.all(np.isfinite(c.position)) and math.isfinite(c.heading)
        assert isinstance(c.pose, str)
        for g in c.goals:
            assert np.all(np.isfinite(g.position)) and g.position.shape == (2,)
            assert g.heading is None or math.isfinite(g.heading)
            if g.time is not None:
                assert 0 <= g.time[0] <= g.time[1] <= sc.duration
            if g.after is not None:
                assert g.after["within"][0] <= g.after["within"][1]
    for f in sc.flocks:
        assert 1 <= f.count and (isinstance(f.ddg, str) or isinstance(f.ddg, dict))
    for t in sc.tilings:
        assert t.period > 0 and t.horizon > 0 and all(tm["count"] >= 1 for tm in t.teams)


def _check_error(e: ScenarioError, path: str):
    msg = str(e)
    event("rejected: " + re.sub(r"'[^']*'|\[[^\]]*\]|-?\d[\d.e+-]*|got .*", "_", msg[len(path) + 2:])[:60])
    assert msg.startswith(path + ":"), msg
    assert "\n" not in msg, msg


@settings(max_examples=600, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(doc=edited())
def test_edited_scenarios_are_accepted_clean_or_rejected_naming_the_place(doc):
    try:
        sc = parse_scenario(doc, "fuzz.toml", env=ENV, node_labels=LABELS)
    except ScenarioError as e:
        _check_error(e, "fuzz.toml")
    else:
        event("accepted")
        _check_accepted(sc)


@settings(max_examples=500, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(doc=edited(), cut=st.one_of(st.none(), st.integers(0, 4000)), junk=st.sampled_from(["", "[", "= 1", "\x00",
                                                                                          "\ud800", "a = 1\na = 2"]))
def test_scenario_files_from_edited_text(tmp_path_factory, doc, cut, junk):
    """The same through the file: TOML written from the edited document, sometimes cut short or
    with junk appended (syntax errors, duplicate keys, bad UTF-8); errors name the file."""
    text = "\n".join(f"{toml_key(k)} = {inline_value(v)}" for k, v in doc.items()) + "\n"
    if cut is not None:
        text = text[:cut]
    p = tmp_path_factory.mktemp("s") / "scenario.toml"
    p.write_bytes((text + junk).encode("utf-8", errors="surrogatepass"))
    try:
        sc = load_scenario(p, env=ENV, node_labels=LABELS)
    except ScenarioError as e:
        _check_error(e, str(p))
    else:
        _check_accepted(sc)


def test_the_base_scenario_is_valid():
    """The fuzzer starts from a valid scenario (so its edits test the checks, not a broken base)."""
    sc = parse_scenario(_copy(BASE), "fuzz.toml", env=ENV, node_labels=LABELS)
    assert [c.name for c in sc.characters] == ["a", "b"] and len(sc.flocks) == 1 and len(sc.tilings) == 1
