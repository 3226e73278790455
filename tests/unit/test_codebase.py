"""The code's own rules, checked on the source: functions fit on a screen, public functions
say what their arguments and results are, no file cites what the repository does not hold,
and ruff (pyproject.toml) is clean.  (No C in Python strings: tests/unit/test_kernels.py.)"""
from __future__ import annotations

import ast
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ("app", "forms", "meshes", "demos")
MAX_LINES = 80


def _python_files(*roots: str) -> list[Path]:
    return sorted(p for r in roots for p in (ROOT / r).rglob("*.py")
                  if "__pycache__" not in p.parts)


def _functions(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def test_no_function_is_longer_than_a_screen():
    long = [f"{p.relative_to(ROOT)}:{f.lineno} {f.name} ({f.end_lineno - f.lineno + 1} lines)"
            for p in _python_files(*SOURCES) for f in _functions(p)
            if f.end_lineno - f.lineno + 1 > MAX_LINES]
    assert not long, f"functions over {MAX_LINES} lines: {long}"


def _returns_value(fn) -> bool:
    """A ``return x`` of fn itself (not of a function or class nested in it)."""
    todo = list(fn.body)
    while todo:
        node = todo.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(node, ast.Return) and node.value is not None and not (
                isinstance(node.value, ast.Constant) and node.value.value is None):
            return True
        todo.extend(ast.iter_child_nodes(node))
    return False


def _arguments(fn) -> list[str]:
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    return [n for n in names if n not in ("self", "cls")]


def _public_callables(tree: ast.Module):
    """Module-level functions and the methods of public classes, without a leading _."""
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            yield node
            yield from (m for m in node.body
                        if isinstance(m, (ast.FunctionDef, ast.AsyncFunctionDef)))


def _undocumented(node) -> str | None:
    doc = ast.get_docstring(node) or ""
    if isinstance(node, ast.ClassDef):
        return None if doc else "no docstring"
    if node.name.startswith("_") or any(
            getattr(d, "id", getattr(d, "attr", "")) in ("property", "cached_property", "setter")
            for d in node.decorator_list):
        return None
    if not doc:
        return "no docstring"
    missing = [s for s, needed in (("Args:", bool(_arguments(node))),
                                   ("Returns:", _returns_value(node)))
               if needed and s not in doc and not (s == "Returns:" and "Yields:" in doc)]
    return f"no {' '.join(missing)}" if missing else None


@pytest.mark.parametrize("root", ["app", "forms", "meshes"])
def test_public_functions_document_arguments_and_results(root):
    found = []
    for path in _python_files(root):
        for node in _public_callables(ast.parse(path.read_text())):
            why = _undocumented(node)
            if why:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: {why}")
    assert not found, "\n".join(found)


def _tracked_files() -> list[Path]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        pytest.skip("not a git checkout")
    return [ROOT / f for f in out.stdout.split()
            if Path(f).suffix in (".py", ".md", ".yaml", ".toml", ".c", ".h", "")]


# files that exist only outside this repository, and references to the tracker's numbers
FOREIGN = re.compile(r"MODEL\.md|STYLE\.md|\.\./shared|\(issue \d+|\bissue \d+\)")


def test_no_file_cites_what_the_repository_does_not_hold():
    this = Path(__file__).resolve()
    found = []
    for path in _tracked_files():
        if path.resolve() == this or not path.is_file():
            continue
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        found += [f"{path.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}: "
                  f"{m.group(0)}" for m in FOREIGN.finditer(text)]
    assert not found, found


@pytest.mark.skipif(importlib.util.find_spec("ruff") is None,
                    reason="ruff is not installed (make setup installs it)")
def test_ruff_is_clean():
    out = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", *SOURCES,
                          "tests"], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
