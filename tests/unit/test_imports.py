"""The package's imports run one way: the graph of vpcontact.* imports read from the source
(module level and inside functions alike, since a lazy import is still a dependency) has no
cycle.  A cycle is reported as the modules that form it."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# the folders and the installed names they carry (pyproject.toml's package-dir mapping)
FOLDERS = {"app": "vpcontact", "forms": "vpcontact.forms", "meshes": "vpcontact.meshes"}


def _modules() -> dict[str, Path]:
    """Every module of the package, by its dotted name."""
    found = {}
    for folder, package in FOLDERS.items():
        for path in (ROOT / folder).rglob("*.py"):
            if "__pycache__" in path.parts:
                continue
            parts = list(path.relative_to(ROOT / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join([package, *parts])] = path
    return found


def _target(name: str, modules: dict[str, Path]) -> str | None:
    """The module an imported dotted name lives in (a name imported from a module is its module)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _imported(module: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules that one module imports, at any depth of its code."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            # `from pkg import sub` depends on the module sub, `from pkg.mod import f` on
            # pkg.mod; a package's __init__ (run first by any import of it) is not counted
            names += [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                      for a in node.names]
    targets = {_target(n, modules) for n in names if n.startswith("vpcontact")}
    return {t for t in targets if t and t != module}


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {m: _imported(m, p, modules) for m, p in modules.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _edges_within(graph, component) -> list[str]:
    members = set(component)
    return [f"{a} -> {b}" for a in component for b in sorted(graph[a] & members)]


def test_the_graph_is_read_from_the_source():
    graph = _graph()
    # known one-way edges, so that an empty graph cannot pass the test below
    assert "vpcontact.post.pictures" in graph
    assert "vpcontact.model.problem" in graph["vpcontact.simulation"]
    assert "vpcontact.forms.step" in set().union(*graph.values())


def test_cycle_finder_finds_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]


def test_no_import_cycle_between_modules():
    graph = _graph()
    cycles = _cycles(graph)
    report = "\n".join("cycle: " + ", ".join(c) + "\n  " + "\n  ".join(_edges_within(graph, c))
                       for c in cycles)
    assert not cycles, f"import cycles between the package's modules:\n{report}"
