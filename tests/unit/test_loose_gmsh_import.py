"""gmsh is imported in this process only through meshes.gmshfile.import_gmsh, which keeps the
process's SIGINT handler: gmsh's module sets SIGINT to its default action when first
imported (and dolfinx.io.gmshio imports gmsh), so Ctrl-C killed the process with no line
and no exit code 3.  The meshing children (meshes/geomesh.py run as a program) are other
processes, killed by their parent on a signal."""
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
IMPORT = re.compile(r"^\s*(import gmsh\b|from gmsh\b|from dolfinx\.io import gmshio|"
                    r"from dolfinx\.io\.gmshio|import dolfinx\.io\.gmshio)", re.M)
CHILDREN = {"meshes/geomesh.py": "__main__"}


def _imports(path: Path) -> list[int]:
    text = path.read_text()
    return [text.count("\n", 0, m.start()) + 1 for m in IMPORT.finditer(text)]


def _function(before: str) -> tuple[str, str]:
    """The name and the text so far of the function a line is in ("" at module level)."""
    starts = list(re.finditer(r"^\s*def (\w+)", before, re.M))
    return (starts[-1].group(1), before[starts[-1].start():]) if starts else ("", before)


def test_every_import_of_gmsh_goes_through_import_gmsh():
    found = []
    for path in sorted([*ROOT.glob("app/**/*.py"), *ROOT.glob("meshes/**/*.py")]):
        rel = str(path.relative_to(ROOT))
        lines = path.read_text().splitlines()
        for line in _imports(path):
            before = "\n".join(lines[:line - 1])
            name, body = _function(before)
            if rel == "meshes/gmshfile.py" and name == "import_gmsh":
                continue                           # import_gmsh itself
            if rel in CHILDREN and CHILDREN[rel] in before:
                continue                           # a child process's own script
            if "gmshio" in lines[line - 1] and "import_gmsh()" in body:
                continue                           # gmshio after import_gmsh, its gmsh
            found.append(f"{rel}:{line}: {lines[line - 1].strip()}")
    assert not found, found


def test_the_sigint_handler_is_kept_while_the_builtin_meshes_are_built(tmp_path):
    script = """
import signal, sys
from mpi4py import MPI
def ours(signum, frame):
    raise KeyboardInterrupt
signal.signal(signal.SIGINT, ours)
import dolfinx.io
from vpcontact.meshes import box, rectangle
seen = []
def watch(module, name):
    real = getattr(module, name)
    def watched(*args, **kwargs):
        seen.append(signal.getsignal(signal.SIGINT) is ours)
        return real(*args, **kwargs)
    setattr(module, name, watched)
watch(rectangle, "_gmsh_model")
watch(box, "_gmsh_model")
rectangle.build_rectangle(MPI.COMM_SELF, n=2)
from vpcontact.meshes import meshcache
watch(meshcache, "model_arrays")
box.build_box(MPI.COMM_SELF, n=2)
rectangle.build_rectangle(MPI.COMM_SELF, h=0.5)
seen.append(signal.getsignal(signal.SIGINT) is ours)
print(seen)
"""
    proc = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                          text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT),
                                                       "VPCONTACT_CACHE": str(tmp_path)})
    assert proc.stdout.strip() == str([True] * 6), proc.stdout + proc.stderr[-2000:]
