"""Mesh a ``.geo`` in a child process: ``python meshes/geomesh.py GEO MSH DIM SIZE MAX MEMORY``
(or tell a gmsh file's dimension: ``python meshes/geomesh.py --dimension FILE MEMORY``).

``meshes.gmshfile`` runs this file as a separate process (gmsh and the standard library only;
it imports nothing of vpcontact) and merges the ``.msh`` it writes.  A child can be stopped:
gmsh's meshing is C++ code that Python's signal handlers cannot interrupt, so SIGINT/SIGTERM
would wait for the whole mesh; the parent kills the child instead and the run ends at once
(exit 3).  Its address space is bounded (``MEMORY`` bytes more than it has at the start),
so a mesh too fine for the machine ends with a clear refusal instead of the kernel's
out-of-memory killer, and it dies with its parent (``PR_SET_PDEATHSIG``).

Before meshing the surfaces and volumes, the number of nodes is estimated twice and refused
above ``MAX``: from gmsh's upper bound of the mesh size (``Mesh.MeshSizeMax``, the
bounding box, ``Mesh.MeshSizeFactor`` and ``SIZE``: no size anywhere exceeds it, so the
curves alone have at least 2 (largest extent) / h nodes), then from a mesh of the curves
with sizes floored at 1e-5 of the bounding box (mean segment length h1: about (bounding box
measure) / h1^dim nodes; the floor keeps that mesh small).  The mesh made is counted too.

``--dimension`` opens the file the same way and prints ``gmsh.model.getDimension()``
(meshes/fileinfo.py).  ``run_child`` is the parent's side of both.

Exit status: 0 the mesh is written to MSH (the dimension printed); 2 refused, with one line
on stderr.
"""
from __future__ import annotations

import math
import os
import sys

REFUSED = "vpcontact-refused: "
FLOOR = 1e-5          # the curves' sizes of the estimate, relative to the bounding box


def _refuse(message: str):
    sys.stderr.write(REFUSED + " ".join(str(message).splitlines()) + "\n")
    sys.stderr.flush()
    os._exit(2)


def memory_budget() -> int:
    """Bytes of address space a gmsh child may add: half the machine's memory (0: unknown).

    Returns:
        The budget in bytes.
    """
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2
    except (ValueError, OSError):
        return 0


def run_child(args: list[str], memory: int) -> tuple[int, str, str]:
    """Run this file as a child process (gmsh and the standard library only) and wait.

    Args:
        args: its arguments (see the module docstring) before MEMORY.
        memory: the bytes of address space the child may add (``_limit_process``).

    Returns:
        (exit status, stdout, stderr).

    Raises:
        KeyboardInterrupt: SIGINT/SIGTERM while it runs: the child is killed first (gmsh's
            C++ code would not return before it is done).
    """
    import subprocess
    cmd = [sys.executable, os.path.abspath(__file__), *args, str(int(memory))]
    env = {**os.environ, "VPCONTACT_PARENT": str(os.getpid()), "PYTHONPATH": ""}
    child = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, env=env)
    try:
        out, err = child.communicate()
    except BaseException:          # KeyboardInterrupt (SIGINT/SIGTERM): stop gmsh now
        child.kill()
        child.wait()
        raise
    return child.returncode, out.decode(errors="replace"), err.decode(errors="replace")


def refusal(err: str) -> str | None:
    """The one-line reason a child refused.

    Args:
        err: the child's stderr.

    Returns:
        The text of its last ``REFUSED`` line, or None.
    """
    said = [line[len(REFUSED):] for line in err.splitlines() if line.startswith(REFUSED)]
    return said[-1] if said else None


def _limit_process(memory: int, parent: int) -> None:
    """Die with the parent; at most ``memory`` more bytes of address space."""
    import ctypes
    import resource
    import signal
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))   # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:
        os._exit(3)
    if memory > 0:
        with open("/proc/self/statm") as f:
            used = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        resource.setrlimit(resource.RLIMIT_AS, (used + memory, used + memory))


def size_bound(gmsh) -> float:
    """gmsh 4.8's largest possible mesh size (BGM_MeshSize): min(Mesh.MeshSizeMax, max(the
    bounding box diagonal, Mesh.MeshSizeMin)) times Mesh.MeshSizeFactor.

    Args:
        gmsh: the gmsh module with the geometry loaded.

    Returns:
        The bound h_max.
    """
    lo, hi = _bbox(gmsh)
    opt = gmsh.option.getNumber
    return opt("Mesh.MeshSizeFactor") * min(opt("Mesh.MeshSizeMax"),
                                            max(math.dist(lo, hi), opt("Mesh.MeshSizeMin")))


def _bbox(gmsh):
    b = gmsh.model.getBoundingBox(-1, -1)
    return b[:3], b[3:]


def _curves(gmsh) -> tuple[int, float, float]:
    """(number of segments, total length, shortest segment) of the curves' mesh."""
    import numpy as np
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    if len(tags) == 0:
        return 0, 0.0, math.inf
    where = np.zeros(int(np.max(tags)) + 1, dtype=np.int64)
    where[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    xyz = np.asarray(xyz).reshape(-1, 3)
    count, length, shortest = 0, 0.0, math.inf
    types, _, nodes = gmsh.model.mesh.getElements(1)
    for t, block in zip(types, nodes):
        n = gmsh.model.mesh.getElementProperties(t)[3]
        ends = where[np.asarray(block, dtype=np.int64).reshape(-1, n)[:, :2]]
        seg = np.linalg.norm(xyz[ends[:, 0]] - xyz[ends[:, 1]], axis=1)
        length += float(seg.sum())
        shortest = min(shortest, float(seg.min(initial=math.inf)))
        count += len(ends)
    return count, length, shortest


def estimate(gmsh, path: str, dim: int, most: float) -> None:
    """Refuse a mesh of more than ``most`` nodes before meshing surfaces and volumes (the
    module docstring).  The curves are meshed with the sizes floored at FLOOR times the
    bounding box diagonal (so that tiny sizes cannot make this mesh itself huge): a floor
    only coarsens, so a guess above ``most`` from this mesh is a refusal; the curves' mesh
    is then cleared and gmsh meshes them again with the true sizes.

    Args:
        gmsh: the gmsh module with the geometry loaded and its size factor set.
        path: the .geo, for the message.
        dim: the space dimension.
        most: the most nodes a mesh may have.
    """
    lo, hi = _bbox(gmsh)
    extent = sorted((b - a for a, b in zip(lo, hi)), reverse=True)
    h = size_bound(gmsh)
    advice = ("; use larger mesh sizes (Mesh.MeshSizeMin/Max, the points' sizes, "
              "Mesh.MeshSizeFactor, mesh.size)")
    if h > 0 and 2 * extent[0] / h > most:
        _refuse(f"{path}: its mesh sizes (at most {h:.3g} on a body {extent[0]:.3g} long) "
                f"ask for more than {2 * extent[0] / h:.3g} nodes (limit {most:.0e})"
                + advice)
    factor, size_min = (gmsh.option.getNumber(f"Mesh.{k}") for k in ("MeshSizeFactor",
                                                                     "MeshSizeMin"))
    floor = FLOOR * math.dist(lo, hi)
    floored = factor > 0 and floor / factor > size_min
    if floored:
        gmsh.option.setNumber("Mesh.MeshSizeMin", floor / factor)
    gmsh.model.mesh.generate(1)
    segments, length, shortest = _curves(gmsh)
    if floored:                             # gmsh meshes the curves again with true sizes
        gmsh.option.setNumber("Mesh.MeshSizeMin", size_min)
        gmsh.model.mesh.clear()
    if segments == 0 or length == 0:
        return
    h1 = length / segments
    guess = math.prod(max(e, 0.0) for e in extent[:dim]) / h1 ** dim
    if guess > most:
        _refuse(f"{path}: its mesh sizes (about {h1:.3g} on the curves"
                f"{' or less' if shortest < 2 * floor else ''}) ask for about {guess:.3g} "
                f"nodes (limit {most:.0e})" + advice)


def mesh(gmsh, path: str, out: str, dim: int, size: float, most: float) -> None:
    """Open the .geo, check its dimension and size, mesh it and write ``out`` (msh 4.1).

    Args:
        gmsh: the gmsh module (not initialised).
        path: the .geo file.
        out: the .msh file to write.
        dim: the space dimension.
        size: the factor on the characteristic lengths.
        most: the most nodes the mesh may have.
    """
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.open(path)
    except Exception as err:
        _refuse(f"gmsh cannot read {path}: {err}")
    top = gmsh.model.getDimension()
    if top > dim:
        what = {1: "curve", 2: "surface", 3: "volume"}[top]
        _refuse(f"{path}: the geometry is {top}D (it has {what}s) but mesh.dim is {dim}; "
                f"set mesh.dim: {top}")
    try:
        factor = gmsh.option.getNumber("Mesh.MeshSizeFactor")
        gmsh.option.setNumber("Mesh.MeshSizeFactor", factor * size)
        estimate(gmsh, path, dim, most)
        gmsh.model.mesh.generate(dim)
    except Exception as err:
        _refuse(f"gmsh cannot mesh {path}: {err}")
    nodes = gmsh.option.getNumber("Mesh.NbNodes")
    if nodes > most:
        _refuse(f"{path}: gmsh made {nodes:.0f} nodes (limit {most:.0e}); use larger mesh "
                "sizes")
    for name, value in (("Mesh.MshFileVersion", 4.1), ("Mesh.Binary", 1), ("Mesh.SaveAll", 1),
                        ("Mesh.ScalingFactor", 1), ("Mesh.SaveParametric", 0),
                        ("Mesh.PartitionSplitMeshFiles", 0)):
        gmsh.option.setNumber(name, value)
    gmsh.write(out)
    gmsh.finalize()


def dimension(gmsh, path: str) -> None:
    """Print the dimension of the gmsh file ``path`` (``gmsh.model.getDimension()``).

    Args:
        gmsh: the gmsh module.
        path: the file, scanned by the parent (meshes/geoscan.py).
    """
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.open(path)
    except Exception as err:
        _refuse(str(err))
    print(gmsh.model.getDimension(), flush=True)
    gmsh.finalize()


if __name__ == "__main__":
    _args, _memory = sys.argv[1:-1], int(sys.argv[-1])
    import gmsh as _gmsh  # the libraries first: their mappings count in the limit
    import numpy  # noqa: F401
    _limit_process(_memory, int(os.environ.get("VPCONTACT_PARENT", os.getppid())))
    try:
        if _args[0] == "--dimension":
            dimension(_gmsh, _args[1])
        else:
            _geo, _out, _dim, _size, _most = _args
            mesh(_gmsh, _geo, _out, int(_dim), float(_size), float(_most))
    except MemoryError:
        _refuse("out of memory")
    os._exit(0)
