"""The user's own mesh: a gmsh ``.msh`` file or a ``.geo`` script meshed at load time.

Gmsh runs on rank 0 only: it merges the ``.msh`` (format 4.1 or 2.2, ASCII or binary) or opens the
``.geo`` and meshes it in ``dim`` dimensions with its characteristic lengths multiplied by
``size`` (``Mesh.MeshSizeFactor``, on top of any factor the script sets itself; transfinite
lines keep their node counts).  dolfinx's ``gmshio.model_to_mesh`` then distributes the mesh.
It reads only the elements of physical groups: the cells are those of the physical groups of
dimension ``dim`` (the body: a ``Physical Surface`` in 2D, a ``Physical Volume`` in 3D), the
facet tags those of the groups of dimension ``dim - 1`` (the boundary parts, named by the
group's name or referred to by its number).

Every check runs on rank 0 before dolfinx is called and its verdict is broadcast, so a bad
file raises ``MeshFileError`` on every rank (no rank is left waiting in a collective call).

Before gmsh reads anything, ``meshes.geoscan.mesh_files`` checks every script gmsh would
parse (the ``.geo``, the files it includes or merges, the ``.opt`` files gmsh merges with
them; a ``.msh`` that does not start with a mesh header is a script to gmsh): a case's file
may not run commands, write files or end gmsh.  A ``.geo`` is meshed in a child process
(``meshes/geomesh.py``): SIGINT/SIGTERM kill it at once (``KeyboardInterrupt`` on every
rank), its memory is bounded and a mesh of more than ``max_vertices`` nodes is refused, from
an estimate before meshing when the mesh sizes ask for one.
"""
from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .bodycheck import BodyError, check_body
from .extent import mesh_extent
from .geomesh import memory_budget as _memory_budget
from .geomesh import refusal, run_child
from .geoscan import GeoScanError, mesh_files

SUFFIXES = (".msh", ".geo")
# the linear simplex gmsh element type of each dimension (gmsh's MSH numbering)
_LINEAR = {1: 1, 2: 2, 3: 4}
_SIMPLEX = {1: "lines", 2: "triangles", 3: "tetrahedra"}
_PHYSICAL = {0: "Physical Point", 1: "Physical Curve", 2: "Physical Surface",
             3: "Physical Volume"}
_ENTITY = {0: "point", 1: "curve", 2: "surface", 3: "volume"}
MAX_VERTICES = 1e8            # the most nodes of a mesh gmsh makes from a .geo (by default)
_INTERRUPTED = "\0interrupted"  # rank 0's verdict when a signal stopped the meshing


class MeshFileError(ValueError):
    """A mesh file that cannot be used; the one-line message says what is wrong and the fix."""


@dataclass
class FileMesh:
    """A distributed dolfinx mesh read from a gmsh file, with its tags and geometry data.

    Attributes:
        mesh: the dolfinx mesh (linear triangles in 2D, linear tetrahedra in 3D).
        cell_tags: the cells' physical tags (the groups of dimension dim).
        facet_tags: the boundary facets' physical tags (the groups of dimension dim - 1).
        groups: physical name -> physical tag of the named groups of dimension dim - 1.
        tags: every physical tag of dimension dim - 1 (named or not), sorted.
        dim: the space dimension, 2 or 3.
        path: the file read.
        h: the largest cell diameter.
        h_min: the smallest cell diameter.
        bbox: (lo, hi), the corners of the bounding box of all vertices, each (dim,).
        L1, L2, L3: the bounding box's extents in x, y, z (L3 = 0 in 2D).
        other_groups: physical name -> dimension of the named groups of other dimensions
            (the body, edges, points), so that a case naming one gets a clear error.
        interior: physical tag -> (facets inside the body, facets) of the groups of
            dimension dim - 1 with facets shared by two cells (meshes.bodycheck).
        cell_groups: physical name -> physical tag of the named groups of dimension dim
            (the body's parts, whose tags ``cell_tags`` holds).
    """

    mesh: object
    cell_tags: object
    facet_tags: object
    groups: dict[str, int]
    tags: tuple[int, ...]
    dim: int
    path: str
    h: float
    h_min: float
    bbox: tuple[np.ndarray, np.ndarray]
    L1: float
    L2: float
    L3: float
    other_groups: dict = field(default_factory=dict)
    interior: dict = field(default_factory=dict)
    cell_groups: dict = field(default_factory=dict)

    # what the built-in meshes also say about themselves: an unstructured mesh, no grid, and
    # no single contact normal (the boundary's normals come from its facets)
    structured = False
    n = None
    diagonal = None
    normal = None
    tangent = None


def import_gmsh():
    """The gmsh module, imported without its side effect on SIGINT: gmsh.py sets SIGINT to
    the default action (the process dies, no exit code 3) when imported and puts back, in
    ``finalize``, the handler of that moment; both are undone here.

    Returns:
        The gmsh module.
    """
    import signal
    import threading
    main = threading.current_thread() is threading.main_thread()
    handler = signal.getsignal(signal.SIGINT) if main else None
    import gmsh
    gmsh.oldsig = None                # finalize() leaves SIGINT alone
    if main and handler is not None:
        signal.signal(signal.SIGINT, handler)
    return gmsh


def on_root(comm: MPI.Comm, work, failure, keep: bool = False, share: bool = True,
            error: type = MeshFileError, reraise: bool = False):
    """``work(gmsh)`` on rank 0 with gmsh initialised, its verdict broadcast; collective.

    Gmsh runs on one rank only; any failure there is broadcast so that no rank is left
    waiting for rank 0 in a collective call.  gmsh comes from ``import_gmsh`` (the process's
    SIGINT handler is kept, so SIGINT/SIGTERM end the run with exit code 3).  Gmsh is
    finalised on rank 0 afterwards, unless ``keep`` and ``work`` succeeded (the caller then
    reads gmsh's model, e.g. with ``gmshio.model_to_mesh``, and finalises it), and unless a
    gmsh call an interrupt left running in its thread (``_busy``) still uses gmsh.

    Args:
        comm: the MPI communicator.
        work: called on rank 0 as ``work(gmsh)``; its result is returned.
        failure: ``failure(err)``, the message of an Exception ``work`` raised (made one
            line: gmsh's messages may span lines).
        keep: leave gmsh initialised on rank 0 when ``work`` succeeded.
        share: return the result on every rank (else on rank 0, None elsewhere).
        error: the exception class raised with the message.
        reraise: rank 0 raises ``work``'s own exception (the other ranks ``error``).

    Returns:
        ``work``'s result (on every rank if ``share``).

    Raises:
        KeyboardInterrupt: on every rank, with the signal's name as rank 0's had, when
            SIGINT/SIGTERM stopped ``work``.
        Exception: ``error(message)`` on every rank (rank 0: ``work``'s own if ``reraise``)
            when ``work`` failed.
    """
    gmsh = import_gmsh()
    result = verdict = raised = None
    if comm.rank == 0:
        gmsh.initialize(readConfigFiles=False)
        gmsh.option.setNumber("General.Terminal", 0)
        done = False
        try:
            result, done = work(gmsh), True
        except KeyboardInterrupt as stop:       # its argument names the signal
            verdict = (_INTERRUPTED, *stop.args)
        except Exception as err:                # never leave the other ranks waiting
            raised, verdict = err, " ".join(str(failure(err)).splitlines())
        finally:
            if not (keep and done) and not _busy:   # else gmsh is in use (model, signal)
                gmsh.finalize()
    verdict, shared = comm.bcast((verdict, result if share else None), root=0)
    if isinstance(verdict, tuple):
        raise KeyboardInterrupt(*verdict[1:])
    if raised is not None and reraise:
        raise raised
    if verdict is not None:
        raise error(verdict)
    return shared if share else result


def file_failure(path, doing: str):
    """The message of a failure reading a gmsh file, for ``on_root``.

    Args:
        path: the file.
        doing: the verb of the message, e.g. "load".

    Returns:
        ``failure(err)``: a MeshFileError's own message, else "cannot <doing> <path>: ...".
    """
    def failure(err: Exception) -> str:
        if isinstance(err, MeshFileError):
            return str(err)
        return f"cannot {doing} {path}: {type(err).__name__}: {err}"
    return failure


def load_mesh_file(comm: MPI.Comm, path, dim: int, size: float = 1.0,
                   max_vertices: float = MAX_VERTICES) -> FileMesh:
    """Read a gmsh ``.msh`` or mesh a ``.geo`` and distribute it; collective on ``comm``.

    Args:
        comm: the communicator the mesh is distributed over.
        path: the ``.msh`` or ``.geo`` file.
        dim: the space dimension, 2 (triangles in the plane z = 0) or 3 (tetrahedra).
        size: the factor on a ``.geo``'s characteristic lengths (ignored for a ``.msh``).
        max_vertices: the most nodes gmsh may make from a ``.geo``.

    Returns:
        The FileMesh.

    Raises:
        MeshFileError: on every rank, for a missing or unreadable file, a suffix other than
            .msh/.geo, a file gmsh cannot read or mesh, no elements, no physical group for the
            body, a mesh of the other dimension or not in the plane z = 0, elements other
            than linear triangles/tetrahedra, groups sharing elements or names, a script
            statement a case may not use, a .geo asking for more than max_vertices nodes.
        KeyboardInterrupt: on every rank, when SIGINT/SIGTERM stopped gmsh's meshing.
        ValueError: for dim not 2 or 3, or size not > 0.
    """
    gmsh = import_gmsh()
    from dolfinx.io import gmshio

    path = str(path)
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    if not size > 0:
        raise ValueError(f"size must be > 0, got {size!r}")
    found = on_root(comm, lambda gmsh: (*_read(gmsh, path, dim, size, max_vertices),
                                        _other_groups(gmsh, dim), _named_groups(gmsh, dim)),
                    file_failure(path, "load"), keep=True)
    try:
        msh, ct, ft = gmshio.model_to_mesh(gmsh.model if comm.rank == 0 else None, comm, 0,
                                           gdim=dim)
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    groups, tags, interior, other, cell_groups = found
    h_min, h_max, (lo, hi) = mesh_extent(msh)
    ext = hi - lo
    return FileMesh(msh, ct, ft, groups, tags, dim, path, h_max, h_min, (lo, hi),
                    float(ext[0]), float(ext[1]), float(ext[2]) if dim == 3 else 0.0, other,
                    interior, cell_groups)


def _named_groups(gmsh, dim: int) -> dict:
    """Rank 0: name -> tag of the named physical groups of dimension dim (the body's)."""
    return {gmsh.model.getPhysicalName(dim, tag): int(tag)
            for _, tag in gmsh.model.getPhysicalGroups(dim)
            if gmsh.model.getPhysicalName(dim, tag)}


def _other_groups(gmsh, dim: int) -> dict:
    """Rank 0: name -> dimension of the named physical groups not of dimension dim - 1."""
    return {gmsh.model.getPhysicalName(d, tag): int(d)
            for d, tag in gmsh.model.getPhysicalGroups()
            if d != dim - 1 and gmsh.model.getPhysicalName(d, tag)}


def _read(gmsh, path: str, dim: int, size: float, max_vertices: float = MAX_VERTICES):
    """Rank 0: load the file into gmsh's current model, check it; (groups, tags, interior)."""
    p = Path(path)
    if not p.exists():
        raise MeshFileError(f"{path}: no such file; give a gmsh .msh or .geo file (a path "
                            "relative to the case file)")
    if not p.is_file():
        raise MeshFileError(f"{path} is not a file; give a gmsh .msh or .geo file")
    try:
        with open(p, "rb"):
            pass
    except OSError as err:
        raise MeshFileError(f"cannot read {path}: {err.strerror}; check its permissions") \
            from None
    suffix = p.suffix.lower()
    if suffix not in SUFFIXES:
        raise MeshFileError(f"{path}: unknown suffix {p.suffix!r}; give a gmsh mesh (.msh, "
                            "format 4.1 or 2.2) or a gmsh geometry script (.geo)")
    try:
        mesh_files(p)                       # refuses what a case's file may not do
    except GeoScanError as err:
        raise MeshFileError(str(err)) from None
    if suffix == ".geo":
        _check_last_line(p, path)
        _mesh_geo(gmsh, path, dim, size, max_vertices)
    else:
        _check_file_size(p, path)
        try:
            _interruptible(gmsh.merge, str(p))
        except Exception as err:
            raise MeshFileError(f"gmsh cannot read {path}: {err}") from None
        _unpartition(gmsh)
    _check_elements(gmsh, path, dim)
    _check_groups(gmsh, path, dim)
    if dim == 2:
        _check_planar(gmsh, path)
    try:
        interior = check_body(gmsh, path, dim)
    except BodyError as err:
        raise MeshFileError(str(err)) from None
    nodes = gmsh.model.mesh.getNodes()[0]
    if not np.array_equal(np.sort(nodes), np.arange(1, len(nodes) + 1)):
        gmsh.model.mesh.renumberNodes()     # model_to_mesh needs node tags 1..N
    return (*_boundary_groups(gmsh, path, dim), interior)


def _unpartition(gmsh) -> None:
    """Rank 0: a mesh saved partitioned (``gmsh -part N``, Mesh.PartitionCreate; MSH 4.1 or
    2.2) as one mesh: gmsh reads its elements into partition entities, whose parents are the
    entities of the physical groups; unpartition puts them back (the physical groups then
    hold their elements again).  The mesh is distributed by dolfinx as any other."""
    if any(len(gmsh.model.getPartitions(d, tag)) for d, tag in gmsh.model.getEntities()):
        gmsh.model.mesh.unpartition()


_busy = []      # a gmsh call an interrupt left running in its thread (gmsh is not usable)


def _interruptible(call, *args):
    """Rank 0: ``call(*args)`` (a long gmsh call, e.g. reading a large .msh) in a thread,
    the main thread waiting: SIGINT/SIGTERM raise KeyboardInterrupt here at once (Python runs
    signal handlers in the main thread only, never inside gmsh's C++ code).  The call is
    left running: the process is ending (the CLI exits with 3)."""
    import threading
    if threading.current_thread() is not threading.main_thread():
        return call(*args)
    out = {}

    def work():
        try:
            out["value"] = call(*args)
        except BaseException as err:   # noqa: BLE001 (raised again in the main thread)
            out["error"] = err
    thread = threading.Thread(target=work, daemon=True, name="gmsh")
    thread.start()
    try:
        while thread.is_alive():
            thread.join(0.1)
    except KeyboardInterrupt:
        _busy.append(thread)
        raise
    if "error" in out:
        raise out["error"]
    return out.get("value")


def _check_file_size(p: Path, path: str) -> None:
    """Rank 0: a .msh larger than half the machine's memory cannot be held by gmsh."""
    size, budget = p.stat().st_size, _memory_budget()
    if budget and size > budget:
        raise MeshFileError(f"{path} is {size / 2**30:.1f} GB, more than half this machine's "
                            f"memory ({2 * budget / 2**30:.1f} GB): gmsh could not hold the "
                            "mesh; use a coarser mesh")


def _check_last_line(p: Path, path: str) -> None:
    """Rank 0: gmsh 4.8 skips every statement but the first of an unterminated last line."""
    last = p.read_bytes().rsplit(b"\n", 1)[-1].split(b"//", 1)[0]
    if last.count(b";") > 1:
        raise MeshFileError(f"{path}: its last line has no line break, so gmsh would skip all "
                            "but its first statement; end the file with a line break")


def _mesh_geo(gmsh, path: str, dim: int, size: float, most: float,
              memory: int | None = None) -> None:
    """Rank 0: mesh the ``.geo`` in ``dim`` dimensions, lengths scaled by ``size``, in a
    child process (meshes/geomesh.py), and merge its mesh into gmsh's model.

    SIGINT/SIGTERM (KeyboardInterrupt here) kill the child and are raised again."""
    memory = _memory_budget() if memory is None else memory
    with tempfile.TemporaryDirectory(prefix="vpcontact-geo-") as tmp:
        out = os.path.join(tmp, "mesh.msh")
        code, _, err = run_child([path, out, str(dim), repr(float(size)), repr(float(most))],
                                 memory)
        if code != 0 or not os.path.exists(out):
            raise MeshFileError(_child_failure(path, code, err, memory))
        try:
            gmsh.merge(out)
        except Exception as exc:
            raise MeshFileError(f"gmsh cannot read the mesh of {path}: {exc}") from None


def _child_failure(path: str, code: int, err: str, memory: int) -> str:
    """The one-line reason why the meshing child failed."""
    lines = [line for line in err.splitlines() if line.strip()]
    said = refusal(err)
    if said is not None and "out of memory" not in said:
        return said
    if said is not None or "bad_alloc" in err or "MemoryError" in err or code in (-6, -9):
        return (f"gmsh ran out of memory meshing {path} (limit {memory / 2**30:.1f} GB more "
                "than gmsh itself): its mesh sizes ask for too fine a mesh; use larger "
                "mesh sizes (Mesh.MeshSizeMax, the points' sizes, mesh.size)")
    tail = lines[-1] if lines else f"exit status {code}"
    return f"gmsh failed meshing {path}: {tail}"


def _type_names(gmsh, types) -> str:
    return ", ".join(sorted({gmsh.model.mesh.getElementProperties(t)[0] for t in types}))


def _check_elements(gmsh, path: str, dim: int) -> None:
    """Rank 0: there are elements, of dimension ``dim`` at most and at least."""
    types, tags, _ = gmsh.model.mesh.getElements()
    if sum(len(t) for t in tags) == 0:
        raise MeshFileError(f"{path}: no mesh elements (save a .msh after meshing it; a .geo "
                            f"must define the {_ENTITY[dim]}s to mesh)")
    dims = {t: gmsh.model.mesh.getElementProperties(t)[1] for t in types}
    top = max(dims.values())
    if top > dim:
        names = _type_names(gmsh, [t for t, d in dims.items() if d == top])
        raise MeshFileError(f"{path} holds a {top}D mesh ({names}) but mesh.dim is {dim}; "
                            f"set mesh.dim: {top}")
    if top < dim and gmsh.model.getDimension() >= dim:
        raise MeshFileError(f"{path}: its {_ENTITY[dim]}s have no elements (only a {top}D "
                            f"mesh); mesh them in {dim}D (Mesh {dim}) before saving")
    if top < dim:
        hint = "set mesh.dim: 2" if top == 2 else f"give it {_ENTITY[dim]}s to mesh"
        raise MeshFileError(f"{path} holds no {dim}D elements (it is a {top}D mesh) but "
                            f"mesh.dim is {dim}; {hint}")


def _label(gmsh, d: int, tag: int) -> str:
    name = gmsh.model.getPhysicalName(d, tag)
    return f"{_PHYSICAL[d]} {tag} ({name!r})" if name else f"{_PHYSICAL[d]} {tag}"


def _check_groups(gmsh, path: str, dim: int) -> None:
    """Rank 0: a body group; every group's entities meshed with one linear simplex type; no
    element in two groups of dimension dim or dim - 1."""
    if not gmsh.model.getPhysicalGroups(dim):
        raise MeshFileError(f"{path}: no physical group of dimension {dim}, so gmsh saves no "
                            f"cells; add a {_PHYSICAL[dim]} for the body (e.g. "
                            f"{_PHYSICAL[dim]}(\"body\") = {{...}};)")
    members = {dim: ([], []), dim - 1: ([], [])}
    # the body's groups first: their element types say most about the file
    for d, tag in sorted(gmsh.model.getPhysicalGroups(), key=lambda g: (-g[0], g[1])):
        for entity in gmsh.model.getEntitiesForPhysicalGroup(d, tag):
            types, elements, _ = gmsh.model.mesh.getElements(d, entity)
            if len(types) == 0:
                raise MeshFileError(f"{path}: {_label(gmsh, d, tag)} holds {_ENTITY[d]} "
                                    f"{entity}, which has no elements; mesh it or remove it "
                                    "from the group")
            if len(types) > 1 or (d in members and types[0] != _LINEAR[d]):
                raise MeshFileError(
                    f"{path}: {_label(gmsh, d, tag)} has {_type_names(gmsh, types)} "
                    f"elements; vpcontact needs linear {_SIMPLEX[dim]} (no Recombine, "
                    "Mesh.ElementOrder = 1)")
            if d in members:
                members[d][0].append(elements[0])
                members[d][1].append(np.full(len(elements[0]), tag))
    for d, (elements, owners) in members.items():
        if not elements:
            continue
        elements, owners = np.concatenate(elements), np.concatenate(owners)
        order = np.argsort(elements, kind="stable")
        elements, owners = elements[order], owners[order]
        twice = np.flatnonzero(elements[1:] == elements[:-1])
        if twice.size:
            a, b = owners[twice[0]], owners[twice[0] + 1]
            kind = "cell" if d == dim else "facet"
            raise MeshFileError(f"{path}: {_label(gmsh, d, a)} and {_label(gmsh, d, b)} share "
                                f"elements; a {kind} may belong to one physical group only")


def _check_planar(gmsh, path: str) -> None:
    """Rank 0: the body's nodes lie in the plane z = 0."""
    xyz = [gmsh.model.mesh.getNodesForPhysicalGroup(2, tag)[1].reshape(-1, 3)
           for _, tag in gmsh.model.getPhysicalGroups(2)]
    xyz = np.concatenate(xyz)
    extent = max(float(np.ptp(xyz[:, 0])), float(np.ptp(xyz[:, 1])))
    z = xyz[:, 2]
    tol = 1e-12 * max(extent, np.finfo(float).tiny)
    if np.ptp(z) <= tol < np.abs(z).max():
        raise MeshFileError(f"{path}: the 2D mesh lies in the plane z = {z[0]:g}, not z = 0; "
                            "move it to z = 0 (a 2D mesh must lie in the plane z = 0)")
    if np.abs(z).max() > tol:
        raise MeshFileError(f"{path}: the 2D mesh is not planar (z from {z.min():g} to "
                            f"{z.max():g}); a 2D mesh must lie in the plane z = 0")


def _boundary_groups(gmsh, path: str, dim: int):
    """Rank 0: (name -> tag of the named groups of dimension dim - 1, all their tags)."""
    groups = {}
    tags = sorted(tag for _, tag in gmsh.model.getPhysicalGroups(dim - 1))
    for tag in tags:
        name = gmsh.model.getPhysicalName(dim - 1, tag)
        if not name:
            continue
        if name in groups:
            raise MeshFileError(f"{path}: two {_PHYSICAL[dim - 1]}s are named {name!r} "
                                f"(tags {groups[name]} and {tag}); rename one")
        groups[name] = int(tag)
    return groups, tuple(int(t) for t in tags)
