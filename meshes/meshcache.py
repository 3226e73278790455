"""A cache of the meshes gmsh builds for the built-in geometries (the rectangle, the box), so
that a run whose mesh was built before neither imports gmsh (docs/performance.md, section 3)
nor meshes again.

What is kept is exactly what ``dolfinx.io.gmshio.model_to_mesh`` (dolfinx 0.5.2) reads from
gmsh's model on rank 0: the node coordinates, the cells and the marked facets (gmsh's node
order) with their physical markers, and gmsh's cell types (``model_arrays``).  ``to_mesh``
builds the distributed dolfinx mesh and its tags from them with the calls model_to_mesh makes,
in its order, so a mesh from the cache is the mesh gmsh's model gives (same arrays, same
calls): the results of a run do not depend on whether its mesh came from the cache.

The entries live in the ``meshes`` directory of the run cache (app/cachepaths.py), one
``.npz`` per key: a hash of the builder's name and parameters, the text of the module that
builds the model and gmsh's version (read from gmsh.py without importing it), so that a change
of any of them builds anew.  An entry is written atomically (a temporary file renamed); one
that cannot be read is built anew and replaced; a cache that cannot be written is skipped.
Rank 0 alone reads and writes the cache, as it alone holds gmsh's model.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import logging
import os
import re
from pathlib import Path

import numpy as np
import ufl
from dolfinx import cpp as _cpp
from dolfinx.mesh import CellType, create_mesh, meshtags, meshtags_from_entities

from .partition import cell_partitioner

log = logging.getLogger("vpcontact")

# gmsh's element types of the built-in meshes -> (the UFL cell, the degree): gmshio's table
_GMSH_CELLS = {1: ("interval", 1), 2: ("triangle", 1), 4: ("tetrahedron", 1)}
_FORMAT = 1                    # of the stored arrays (changed: every entry is built anew)


def gmsh_version() -> str:
    """gmsh's version from its Python module's text (``GMSH_API_VERSION``), not imported.

    Returns:
        The version, or "unknown".
    """
    spec = importlib.util.find_spec("gmsh")
    if spec is None or spec.origin is None:
        return "unknown"
    try:
        text = Path(spec.origin).read_text(errors="replace")
    except OSError:
        return "unknown"
    found = re.search(r'GMSH_API_VERSION\s*=\s*"([^"]+)"', text)
    return found.group(1) if found else "unknown"


def cache_key(builder: str, params: dict, source: Path) -> str:
    """The key of a built-in mesh: its builder, parameters, builder's source, gmsh.

    Args:
        builder: the builder's name ("rectangle", "box").
        params: the parameters the model depends on (JSON-serialisable).
        source: the module whose text builds the model.

    Returns:
        A hex digest naming the entry.
    """
    text = json.dumps({"builder": builder, "params": params, "format": _FORMAT,
                       "gmsh": gmsh_version()}, sort_keys=True)
    digest = hashlib.sha256(text.encode())
    digest.update(Path(source).read_bytes())
    return f"{builder}-{digest.hexdigest()[:24]}"


def _directory() -> Path:
    from vpcontact.cachepaths import cache_root
    return cache_root() / "meshes"


def load(key: str) -> dict | None:
    """The stored arrays of ``key``, or None (absent or unreadable: then built anew).

    Args:
        key: the entry's key (``cache_key``).

    Returns:
        The arrays of ``model_arrays``, or None.
    """
    path = _directory() / f"{key}.npz"
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            return {name: data[name] for name in data.files}
    except Exception as err:            # a damaged entry: built anew (and replaced)
        log.debug("mesh cache: %s unreadable (%s); building the mesh anew", path, err)
        return None


def store(key: str, arrays: dict) -> None:
    """Store ``arrays`` under ``key`` atomically; a cache that cannot be written is skipped.

    Args:
        key: the entry's key.
        arrays: the arrays of ``model_arrays``.
    """
    folder = _directory()
    tmp = folder / f".{key}.{os.getpid()}.tmp.npz"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, folder / f"{key}.npz")
    except OSError as err:
        log.debug("mesh cache: cannot write %s (%s)", folder, err)
        try:
            tmp.unlink(missing_ok=True)
        except OSError:                 # e.g. the folder's parent is a file
            pass


def model_arrays(model) -> dict:
    """What model_to_mesh reads from gmsh's model (rank 0): coordinates, the cells of the
    highest dimension and the facets below them, with their physical markers.

    Args:
        model: gmsh.model, meshed.

    Returns:
        {"x", "cells", "cell_values", "cell_id", "num_nodes"} and, with marked facets,
        {"facets", "facet_values", "num_facet_nodes"}.
    """
    from .gmshfile import import_gmsh
    import_gmsh()                     # before gmshio, whose import of gmsh resets SIGINT
    from dolfinx.io.gmshio import extract_geometry, extract_topology_and_markers
    x = extract_geometry(model)
    topologies = extract_topology_and_markers(model)
    info = []
    for element in topologies:
        _, dim, _, num_nodes, _, _ = model.mesh.getElementProperties(element)
        info.append((dim, element, num_nodes))
    order = np.argsort(np.array([dim for dim, _, _ in info], dtype=np.int32))
    tdim, cell_id, num_nodes = info[order[-1]]
    out = {"x": x, "cell_id": np.int64(cell_id), "num_nodes": np.int64(num_nodes),
           "cells": np.asarray(topologies[cell_id]["topology"], dtype=np.int64),
           "cell_values": np.asarray(topologies[cell_id]["cell_data"], dtype=np.int32)}
    if tdim - 1 in [dim for dim, _, _ in info]:
        _, facet_id, num_facet_nodes = info[order[-2]]
        out.update(facets=np.asarray(topologies[facet_id]["topology"], dtype=np.int64),
                   facet_values=np.asarray(topologies[facet_id]["cell_data"], dtype=np.int32),
                   num_facet_nodes=np.int64(num_facet_nodes))
    return out


def _cell_tags(mesh, cells: np.ndarray, a: dict):
    """The cell tags of gmsh's physical volumes (surfaces in 2D).  One volume (the built-in
    rectangle and box): every local cell, owned and ghost, carries its tag, which is what
    distributing the cells' data finds (``_distributed_tags``) without its search of the
    cells by their vertices, a large part of a 3D mesh's construction (docs/performance.md,
    section 9)."""
    tdim = mesh.topology.dim
    if a["one_cell_value"] is None:
        ct = _distributed_tags(mesh, tdim, cells, a["cell_values"])
    else:
        imap = mesh.topology.index_map(tdim)
        n = imap.size_local + imap.num_ghosts
        ct = meshtags(mesh, tdim, np.arange(n, dtype=np.int32),
                      np.full(n, a["one_cell_value"], dtype=np.int32))
    ct.name = "Cell tags"
    return ct


def _distributed_tags(mesh, dim: int, entities: np.ndarray, values: np.ndarray):
    """The tags of rank 0's entities (vertex lists in the input numbering) on the ranks that
    hold them: gmshio.model_to_mesh's distribution of the entity data."""
    local, local_values = _cpp.io.distribute_entity_data(mesh._mesh, dim, entities, values)
    return meshtags_from_entities(mesh, dim, _cpp.graph.AdjacencyList_int32(local),
                                  local_values.astype(np.int32))


def _ufl_domain(cell_id: int, gdim: int) -> ufl.Mesh:
    """gmshio.ufl_mesh: the UFL mesh of a gmsh cell type."""
    shape, degree = _GMSH_CELLS[cell_id]
    cell = ufl.Cell(shape, geometric_dimension=gdim)
    return ufl.Mesh(ufl.VectorElement(ufl.FiniteElement("Lagrange", cell, degree,
                                                        variant="equispaced")))


def _shared(comm, arrays: dict | None, gdim: int) -> dict:
    """Rank 0's arrays, and on the other ranks empty ones of the same kinds (as
    model_to_mesh broadcasts the cell types and keeps the entities on rank 0)."""
    head = None
    if comm.rank == 0:
        values = np.unique(arrays["cell_values"])
        head = {"cell_id": int(arrays["cell_id"]), "num_nodes": int(arrays["num_nodes"]),
                "num_facet_nodes": int(arrays["num_facet_nodes"])
                if "facets" in arrays else None,
                "one_cell_value": int(values[0]) if len(values) == 1 else None}
    head = comm.bcast(head, root=0)
    if comm.rank == 0:
        return {**arrays, **head}
    out = {**head, "x": np.empty([0, gdim]), "cell_values": np.empty((0,), dtype=np.int32),
           "cells": np.empty([0, head["num_nodes"]], dtype=np.int32)}
    if head["num_facet_nodes"] is not None:
        out.update(facets=np.empty((0, head["num_facet_nodes"]), dtype=np.int32),
                   facet_values=np.empty((0,), dtype=np.int32))
    return out


def to_mesh(comm, arrays: dict | None, gdim: int):
    """The distributed mesh and its cell and facet tags from ``model_arrays`` on rank 0
    (None on the others): gmshio.model_to_mesh's construction; collective.

    Args:
        comm: the communicator the mesh is distributed over.
        arrays: rank 0's arrays (from the model or the cache), None elsewhere.
        gdim: the geometric dimension.

    Returns:
        (mesh, cell tags, facet tags).
    """
    a = _shared(comm, arrays, gdim)
    domain = _ufl_domain(a["cell_id"], gdim)
    cell_type = _cpp.mesh.to_type(str(domain.ufl_cell()))
    cells = a["cells"][:, _cpp.io.perm_gmsh(cell_type, a["num_nodes"])]
    mesh = create_mesh(comm, cells, a["x"][:, :gdim], domain,
                       partitioner=cell_partitioner(comm))
    tdim = mesh.topology.dim
    mesh.topology.create_connectivity(tdim, 0)
    ct = _cell_tags(mesh, cells, a)
    if a["num_facet_nodes"] is None:
        ft = meshtags(mesh, tdim - 1, np.empty(0, dtype=np.int32), np.empty(0, dtype=np.int32))
        return mesh, ct, ft
    if mesh.topology.cell_type in (CellType.prism, CellType.pyramid):
        raise RuntimeError(f"Unsupported cell type {mesh.topology.cell_type}")
    facet_type = _cpp.mesh.cell_entity_type(cell_type, tdim - 1, 0)
    facets = a["facets"][:, _cpp.io.perm_gmsh(facet_type, a["num_facet_nodes"])]
    mesh.topology.create_connectivity(tdim - 1, tdim)
    ft = _distributed_tags(mesh, tdim - 1, facets, a["facet_values"])
    ft.name = "Facet tags"
    return mesh, ct, ft
