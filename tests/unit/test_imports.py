"""The package's imports run one way: the graph of vpcontact.* imports read from the source
(module level and inside functions alike, since a lazy import is still a dependency) has no
cycle, and every import follows the layers of docs/architecture.md (section 2): a package
imports only the packages below it (``ALLOWED``), with the exceptions the page names
(``EXCEPTIONS``).  A cycle is reported as the modules that form it, a wrong import as its
edge."""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# the folders and the installed names they carry (pyproject.toml's package-dir mapping)
FOLDERS = {"app": "vpcontact", "forms": "vpcontact.forms", "meshes": "vpcontact.meshes"}

# The layers of docs/architecture.md, from the top of its map down (a row: one layer).  The
# process utilities at the bottom (and the package's face, app/__init__.py, whose API names
# are imported on first use) import nothing of the package; every package may import them.
PROCESS = ("vpcontact.native", "vpcontact.threads", "vpcontact.cachepaths", "vpcontact.startup")
LAYERS = (
    ("vpcontact.__main__",),
    ("vpcontact.cli",),
    ("vpcontact.studies",),
    ("vpcontact.simulation", "vpcontact.observers", "vpcontact.records"),
    ("vpcontact.post",),
    ("vpcontact.solvers",),
    ("vpcontact.model",),
    ("vpcontact.case",),
    ("vpcontact.kernels",),
    ("vpcontact.io",),
    ("vpcontact.forms", "vpcontact.meshes"),
    ("vpcontact", *PROCESS),
)
# within a layer: the time loop reads the observers and the records, the observers the records
SAME_LAYER = {"vpcontact.simulation": {"vpcontact.observers", "vpcontact.records"},
              "vpcontact.observers": {"vpcontact.records"}}
# the bottom of the map imports less than everything below it (section 2's list)
NARROW = {"vpcontact.case": {"vpcontact.io", "vpcontact.meshes"},
          "vpcontact.kernels": {"vpcontact.io"},
          "vpcontact.io": {"vpcontact.meshes"},
          "vpcontact.forms": set(),
          "vpcontact.meshes": set()}


def _allowed_packages() -> dict[str, set[str]]:
    """package -> the packages its modules may import (besides its own)."""
    allowed = {}
    for i, layer in enumerate(LAYERS):
        below = {p for lower in LAYERS[i + 1:] for p in lower}
        for package in layer:
            allowed[package] = NARROW.get(package, below) | SAME_LAYER.get(package, set())
            if package not in LAYERS[-1]:
                allowed[package] |= {"vpcontact", *PROCESS}
    return allowed


ALLOWED = _allowed_packages()
# the exceptions of docs/architecture.md: importer (a package or a module) -> the modules of
# a higher layer it may import
EXCEPTIONS = {
    # the light modules of the solvers that the case layer asks (eligibility, PETSc defaults,
    # the options' checks), and the registry of the built-in viscoplastic laws (their keys,
    # rules and titles, each declared in the law's module) and of the built-in contact laws
    "vpcontact.case": {"vpcontact.solvers.choice", "vpcontact.solvers.options",
                       "vpcontact.solvers.optioncheck", "vpcontact.solvers.optionpolicy",
                       "vpcontact.model.lawregistry", "vpcontact.model.contactregistry",
                       "vpcontact.model.contactspec"},
    # Observers of app/post/: BlowUpMonitor, RateWatch, ErrorEstimate
    "vpcontact.post.divergence": {"vpcontact.observers", "vpcontact.records"},
    "vpcontact.post.ratewatch": {"vpcontact.observers"},
    "vpcontact.post.estimators": {"vpcontact.observers"},
}


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


def _package(module: str) -> str:
    """The package of a module as the layers name it (vpcontact.<first part>)."""
    return ".".join(module.split(".")[:2])


def _allowed(importer: str, imported: str) -> bool:
    """Whether the layers allow the module ``importer`` to import the module ``imported``."""
    a, b = _package(importer), _package(imported)
    if a == b or b in ALLOWED[a]:
        return True
    return any(imported in targets for who, targets in EXCEPTIONS.items()
               if importer == who or importer.startswith(who + "."))


def _violations(graph: dict[str, set[str]]) -> list[str]:
    """The imports the layers do not allow, as 'importer -> imported'."""
    return [f"{a} -> {b}" for a in sorted(graph) for b in sorted(graph[a])
            if not _allowed(a, b)]


def _doc_map() -> list[str]:
    """The packages of the map in docs/architecture.md, from the top down (the lines of its
    first code block that start with a package's name)."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = text.split("```")[1]
    lines = [line for line in block.splitlines() if line.startswith("  vpcontact.")]
    return [name for line in lines for name in re.findall(r"vpcontact\.\w+", line)]


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


def test_the_layers_are_the_documented_map():
    """The table's layers are the map of docs/architecture.md, in its order (the entry point
    and the package's face are not drawn there)."""
    table = [p for layer in LAYERS for p in layer if p not in ("vpcontact.__main__", "vpcontact")]
    assert _doc_map() == table


def test_every_module_has_a_layer():
    """A new package or top-level module is placed in the layers before it is used."""
    unplaced = sorted({_package(m) for m in _graph()} - set(ALLOWED))
    assert not unplaced, f"modules of no layer (add them to LAYERS and the doc's map): {unplaced}"


def test_layer_check_finds_a_wrong_import():
    """An import upwards is reported, a documented exception and an import downwards are not."""
    graph = {"vpcontact.model.coulomb": {"vpcontact.solvers.snesvi", "vpcontact.case.model",
                                         "vpcontact.threads"},
             "vpcontact.case.validation": {"vpcontact.solvers.choice", "vpcontact.solvers.amg"},
             "vpcontact.meshes.meshcache": {"vpcontact.io.cachedirs", "vpcontact.cachepaths"},
             "vpcontact.threads": {"vpcontact.io.errors"}}
    assert _violations(graph) == [
        "vpcontact.case.validation -> vpcontact.solvers.amg",
        "vpcontact.meshes.meshcache -> vpcontact.io.cachedirs",
        "vpcontact.model.coulomb -> vpcontact.solvers.snesvi",
        "vpcontact.threads -> vpcontact.io.errors"]


def test_imports_follow_the_layers():
    """Every import of every module (at module level and inside functions) goes down the
    layers of docs/architecture.md or is one of its named exceptions."""
    wrong = _violations(_graph())
    assert not wrong, "imports against the layers of docs/architecture.md:\n  " + \
        "\n  ".join(wrong)
