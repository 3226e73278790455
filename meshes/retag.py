"""The physical groups of a gmsh mesh carried to a locally refined copy of it, found
geometrically: dolfinx 0.5.2's ``refine`` with an edge list gives no parent cells or facets
(``plaza_refine_data``, which does, refines every cell).

- A facet of the refined mesh lies in exactly one facet of the parent (the refinement is
  nested); it takes that parent's tag when all its vertices lie on the parent facet (the
  segment in 2D, the triangle in 3D, up to 1e-9 of the parent's size).  The parent's tagged
  facets are gathered to every rank (boundary groups: few facets).
- A cell of the refined mesh lies in exactly one parent cell; it takes that cell's tag, the
  parent found by the refined cell's centroid in the parent's local cells
  (``dolfinx.geometry``).  This needs the refined cells on the rank of their parent: the
  refinement is not redistributed (``refine_file_mesh``).

New vertices are edge midpoints: a curved boundary (the Hertz arc) keeps the chords of the
mesh read, as in the uniform refinement of meshes/refine.py (gmsh's geometry is not used).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .extent import mesh_extent

EPS = 1e-9                  # on a parent facet: within EPS of its size


def entity_points(msh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The vertex coordinates of local entities of a P1 simplex mesh.

    Args:
        msh: the dolfinx mesh.
        dim: the entities' dimension (tdim - 1 for facets, tdim for cells).
        entities: their local indices.

    Returns:
        (n, dim + 1, gdim) coordinates.
    """
    from dolfinx.cpp.mesh import entities_to_geometry
    msh.topology.create_connectivity(dim, msh.topology.dim)
    cpp_mesh = getattr(msh, "_mesh", msh)          # the C++ mesh behind dolfinx's wrapper
    nodes = entities_to_geometry(cpp_mesh, dim, np.asarray(entities, dtype=np.int32), False)
    return msh.geometry.x[:, :msh.geometry.dim][nodes.reshape(len(entities), dim + 1)]


def _gathered_facets(parent, comm) -> tuple[np.ndarray, np.ndarray]:
    """The parent's tagged facets from every rank: ((n, tdim, gdim) vertices, (n,) tags)."""
    ft, fdim = parent.facet_tags, parent.mesh.topology.dim - 1
    pts = entity_points(parent.mesh, fdim, ft.indices)
    pts = np.concatenate(comm.allgather(pts))
    return pts, np.concatenate(comm.allgather(np.asarray(ft.values)))


def on_facets(points: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Whether points lie on simplices (segments or triangles) of one dimension less.

    Args:
        points: (n, k, gdim) k points per pair.
        facets: (n, m, gdim) the simplex of each pair (m vertices, m - 1 <= gdim).

    Returns:
        (n,) True where all k points lie on the pair's simplex (within EPS of its size).
    """
    a0 = facets[:, :1]                                         # (n, 1, gdim)
    E = np.transpose(facets[:, 1:] - a0, (0, 2, 1))            # (n, gdim, m - 1)
    d = np.transpose(points - a0, (0, 2, 1))                   # (n, gdim, k)
    lam = np.linalg.pinv(E) @ d                                # (n, m - 1, k)
    size = np.linalg.norm(E, axis=1).max(axis=1)               # (n,)
    off = np.linalg.norm(E @ lam - d, axis=1).max(axis=1)      # (n,)
    inside = (lam.min(axis=(1, 2)) >= -EPS) & (lam.sum(axis=1).max(axis=1) <= 1 + EPS)
    return inside & (off <= EPS * size)


def transfer_facet_tags(parent, msh, comm):
    """The parent's facet tags on the refined mesh (module docstring); collective.

    Args:
        parent: the FileMesh refined.
        msh: the refined dolfinx mesh.
        comm: the MPI communicator.

    Returns:
        The refined mesh's facet MeshTags (every local facet lying on a tagged parent facet).
    """
    from dolfinx.mesh import meshtags
    from scipy.spatial import cKDTree

    fdim = msh.topology.dim - 1
    pfacets, ptags = _gathered_facets(parent, comm)
    msh.topology.create_entities(fdim)
    imap = msh.topology.index_map(fdim)
    local = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    child = entity_points(msh, fdim, local)
    tags = np.full(len(local), -1, dtype=np.int32)
    if len(pfacets) and len(local):
        centre = pfacets.mean(axis=1)
        reach = np.linalg.norm(pfacets - centre[:, None], axis=2).max() * (1 + 1e-6)
        near = cKDTree(centre).query_ball_point(child.mean(axis=1), reach)
        i = np.repeat(np.arange(len(local)), [len(n) for n in near])
        j = np.fromiter((k for n in near for k in n), dtype=np.int64, count=len(i))
        hit = on_facets(child[i], pfacets[j])
        tags[i[hit]] = ptags[j[hit]]
    keep = np.flatnonzero(tags >= 0).astype(np.int32)
    return meshtags(msh, fdim, keep, tags[keep])


def transfer_cell_tags(parent, msh):
    """The parent's cell tags on the refined mesh (its cells on their parents' rank).

    Args:
        parent: the FileMesh refined.
        msh: the refined dolfinx mesh, not redistributed.

    Returns:
        The refined mesh's cell MeshTags (all local cells).

    Raises:
        RuntimeError: a refined cell's centroid is in no local parent cell (the refined
            mesh was redistributed).
    """
    from dolfinx import geometry
    from dolfinx.mesh import meshtags

    tdim, pm = msh.topology.dim, parent.mesh
    pimap = pm.topology.index_map(tdim)
    ptag = np.full(pimap.size_local + pimap.num_ghosts, -1, dtype=np.int32)
    ptag[parent.cell_tags.indices] = parent.cell_tags.values
    imap = msh.topology.index_map(tdim)
    cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    centroid = np.zeros((len(cells), 3))
    centroid[:, :msh.geometry.dim] = entity_points(msh, tdim, cells).mean(axis=1)
    tree = geometry.BoundingBoxTree(pm, tdim)
    hits = geometry.compute_colliding_cells(pm, geometry.compute_collisions(tree, centroid),
                                            centroid)
    count = np.diff(hits.offsets)
    if np.any(count == 0):
        raise RuntimeError("a refined cell lies in no local cell of the mesh refined")
    return meshtags(msh, tdim, cells, ptag[hits.array[hits.offsets[:-1]]])


def refine_file_mesh(domain, edges: np.ndarray):
    """A FileMesh with the given edges refined, its physical groups carried over.

    Args:
        domain: the FileMesh (meshes/gmshfile.py).
        edges: this rank's local edges to split (``meshes.adapt.marked_edges``).

    Returns:
        A FileMesh of the refined mesh: the same groups and names, the refined cells on the
        rank of their parent (not redistributed), h, h_min and bbox of the refined mesh.
    """
    from dolfinx import mesh as dmesh

    msh = dmesh.refine(domain.mesh, edges, redistribute=False)
    ct = transfer_cell_tags(domain, msh)
    ft = transfer_facet_tags(domain, msh, msh.comm)
    h_min, h_max, bbox = mesh_extent(msh)
    return dataclasses.replace(domain, mesh=msh, cell_tags=ct, facet_tags=ft, h=h_max,
                               h_min=h_min, bbox=bbox)
