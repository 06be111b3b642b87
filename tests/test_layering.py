"""The layering of the packages, read from the source with ``ast`` (imports inside functions
included): the runtime a game ships imports neither the authoring tools nor usd_io; usd_io never
imports authoring; no module imports another's private (underscore) names; and no two modules
import each other, directly or through others."""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("runtime", "authoring", "usd_io")


def _modules():
    """{dotted name: path} of every module of the packages."""
    mods = {}
    for pkg in PACKAGES:
        for p in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(p.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = p
    return mods


MODULES = _modules()


def _resolve(mod: str, path: Path, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = mod.split(".")
    if path.name != "__init__.py":
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(mod: str, path: Path):
    """(target module, imported names, private attribute uses) of one module: targets are
    modules of the packages (``from pkg import submodule`` targets the submodule)."""
    tree = ast.parse(path.read_text(), str(path))
    targets, names, aliases = set(), [], {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name in MODULES:
                    targets.add(a.name)
                    aliases[a.asname or a.name] = a.name
        elif isinstance(node, ast.ImportFrom):
            src = _resolve(mod, path, node)
            for a in node.names:
                full = f"{src}.{a.name}"
                if full in MODULES:
                    targets.add(full)
                    aliases[a.asname or a.name] = full
                elif src in MODULES:
                    targets.add(src)
                    names.append((src, a.name))
    private_attrs = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases \
                and node.attr.startswith("_") and not node.attr.startswith("__"):
            private_attrs.append((aliases[node.value.id], node.attr))
    return targets, names, private_attrs


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


@pytest.mark.parametrize("layer, forbidden", [("runtime", ("authoring", "usd_io")), ("usd_io", ("authoring",))])
def test_lower_layers_never_import_higher_ones(layer, forbidden):
    bad = [(m, t) for m, (targets, _, _) in GRAPH.items() if m.split(".")[0] == layer
           for t in targets if t.split(".")[0] in forbidden]
    assert not bad, bad


def test_no_private_name_is_imported_from_another_module():
    bad = [(m, src, n) for m, (_, names, _) in GRAPH.items() for src, n in names
           if n.startswith("_") and not n.startswith("__") and src != m]
    bad += [(m, src, n) for m, (_, _, attrs) in GRAPH.items() for src, n in attrs if src != m]
    assert not bad, bad


def test_no_import_cycles():
    """Tarjan's strongly connected components over the module graph: every component is one
    module."""
    index, low, stack, on, comps = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(GRAPH[v][0]):
            if w == v:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            comps.append(comp)

    import sys
    sys.setrecursionlimit(10000)
    for v in sorted(GRAPH):
        if v not in index:
            visit(v)
    cycles = [sorted(c) for c in comps if len(c) > 1]
    assert not cycles, cycles


def test_the_checks_see_the_tree():
    """The scan is not vacuous: it finds the packages' modules and their imports."""
    assert len(MODULES) > 100
    assert "runtime.crowd.planner.segment" in GRAPH["runtime.crowd.scheduler"][0] or \
        "runtime.crowd.planner" in GRAPH["runtime.crowd.scheduler"][0]
    assert sum(len(t) for t, _, _ in GRAPH.values()) > 300
