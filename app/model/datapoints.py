"""The case's data checked on the points of a loaded mesh file, before anything is computed.

Validation cannot sample the data of a mesh.file where they depend on the position (the body
is not known then, app/case/datacheck.py).  Once the mesh is loaded, the same checks run on its
own points: the nodes and cell midpoints of the body for the body's data (f0, u0, sigma0,
kappa0), the nodes and facet midpoints of each group for the data acting on it (tractions,
pressures, prescribed displacements, the gap g on Gamma3), each also rounded to 1e-9 of the
body's size (gmsh's round-off).  Every rank checks its part of the
mesh; the first error (of the lowest rank that finds one) is raised on every rank.
"""
from __future__ import annotations

import numpy as np
from dolfinx import cpp as dcpp
from dolfinx import mesh as dmesh
from mpi4py import MPI

from vpcontact.case import Case, CaseError
from vpcontact.case.datacheck import PointSamples
from vpcontact.case.pairrules import as_written
from vpcontact.case.values import check_values_on_mesh


def entity_points(msh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The vertices and midpoints of mesh entities.

    Args:
        msh: the dolfinx mesh.
        dim: the entities' dimension (tdim for cells, tdim - 1 for facets).
        entities: local entity indices.

    Returns:
        (P, gdim) points: the distinct vertices of the entities, then their midpoints.
    """
    gdim = msh.geometry.dim
    entities = np.asarray(entities, dtype=np.int32)
    if entities.size == 0:
        return np.zeros((0, gdim))
    msh.topology.create_connectivity(dim, msh.topology.dim)
    cpp_mesh = getattr(msh, "_mesh", msh)          # the C++ mesh behind dolfinx's wrapper
    nodes = np.unique(dcpp.mesh.entities_to_geometry(cpp_mesh, dim, entities, False))
    mids = dmesh.compute_midpoints(msh, dim, entities)
    return np.concatenate([msh.geometry.x[nodes], mids])[:, :gdim]


def with_rounded(points: np.ndarray, length: float) -> np.ndarray:
    """The points and, for those that are round-off away from a point of 9 significant
    digits (relative to the body's size), that point as well.

    gmsh's coordinates carry round-off (a node meant at x = 0.5 is at 0.5000000000021): a
    datum infinite at x = 0.5 is sampled there too, as on the built-in mesh's grid.  Only
    points that every coordinate puts within 1e-11 L of such a value are added (a node on a
    curved boundary stays where it is: moved, it could leave the body).

    Args:
        points: (P, d) points.
        length: the body's size L.

    Returns:
        (P', d) points, P <= P' <= 2 P.
    """
    if points.size == 0 or not length > 0:
        return points
    digits = 9 - int(np.floor(np.log10(length)))
    rounded = np.round(points, digits)
    moved = np.any(rounded != points, axis=1) & \
        np.all(np.abs(rounded - points) <= 1e-11 * length, axis=1)
    return np.concatenate([points, rounded[moved]])


def mesh_samples(case: Case, body) -> PointSamples:
    """The sample points of a loaded mesh file for the case's data (this rank's part).

    Args:
        case: the validated case.
        body: the meshes.FileMesh (mesh, facet_tags, groups, tags, bbox).

    Returns:
        The PointSamples: the body's points, and the points of every group the case names
        (by its name or tag; a group the mesh does not have gets none: ContactProblem refuses
        it).
    """
    msh, ft = body.mesh, body.facet_tags
    tdim = msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    refs = set(case.boundaries.clamped) | set(case.boundaries.contact)
    for kind in (case.loads.traction, case.loads.pressure, case.loads.displacement):
        refs |= set(kind)
    lo, hi = (np.asarray(b, dtype=float)[:tdim] for b in body.bbox)
    length = float(np.max(hi - lo))
    groups = {}
    for ref in refs:
        tag = body.groups.get(ref) if isinstance(ref, str) else ref
        if tag is not None:
            groups[ref] = with_rounded(entity_points(msh, tdim - 1, ft.indices[ft.values == tag]),
                                       length)
    return PointSamples(with_rounded(entity_points(msh, tdim, cells), length), groups, hi - lo,
                        case.time.times, case.time.adaptive is not None)


def check_data_on_mesh(case: Case, body) -> float:
    """Refuse data that are not finite or not in the model's set on the loaded mesh's points
    (collective: every rank raises the same error).

    Args:
        case: the validated case.
        body: the meshes.FileMesh.

    Returns:
        The stress scale of the data (the largest over the ranks), for rescale_for_length.

    Raises:
        CaseError: on every rank, naming the key and the point (x, t).
    """
    comm = body.mesh.comm
    lo, hi = body.bbox
    error, stress = None, 0.0
    try:
        stress = check_values_on_mesh(case, mesh_samples(case, body), float(np.max(hi - lo)))
    except CaseError as exc:         # a pair's law named where it is written
        error = as_written(str(exc), case.laws_written)
    errors = [e for e in comm.allgather(error) if e is not None]
    if errors:
        raise CaseError(errors[0])
    return comm.allreduce(stress, op=MPI.MAX)
