"""The physical groups of a gmsh mesh carried to a locally refined copy of it, found
geometrically: dolfinx 0.5.2's ``refine`` with an edge list gives no parent cells or facets
(``plaza_refine_data``, which does, refines every cell).

- A facet of the refined mesh lies in exactly one facet of the parent (the refinement is
  nested); it takes that parent's tag when all its vertices lie on the parent facet (the
  segment in 2D, the triangle in 3D, up to 1e-9 of the parent's size).  The parent's tagged
  facets are gathered to every rank (boundary groups: few facets).
- A cell of the refined mesh lies in exactly one parent cell and takes its tag, found the
  same way among the parent's cells gathered to every rank (skipped for a body of one
  group: every cell takes its tag).

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


def _gathered(msh, tags, comm) -> tuple[np.ndarray, np.ndarray]:
    """Tagged entities from every rank: ((n, dim + 1, gdim) vertices, (n,) tags)."""
    pts = entity_points(msh, tags.dim, tags.indices)
    pts = np.concatenate(comm.allgather(pts))
    return pts, np.concatenate(comm.allgather(np.asarray(tags.values)))


def locate(parents: np.ndarray, tags: np.ndarray, children: np.ndarray) -> np.ndarray:
    """The tag of the parent simplex holding each child simplex.

    Args:
        parents: (n, m, gdim) the parent simplices' vertices.
        tags: (n,) their tags.
        children: (c, k, gdim) the child simplices' vertices.

    Returns:
        (c,) the tag of a parent holding all k vertices of the child (``in_simplices``), -1
        where none does.
    """
    from scipy.spatial import cKDTree

    out = np.full(len(children), -1, dtype=np.int32)
    if len(parents) and len(children):
        centre = parents.mean(axis=1)                 # a child's centre is within reach
        reach = np.linalg.norm(parents - centre[:, None], axis=2).max(axis=1) * (1 + 1e-6)
        near = cKDTree(children.mean(axis=1)).query_ball_point(centre, reach)
        j = np.repeat(np.arange(len(parents)), [len(n) for n in near])
        i = np.fromiter((k for n in near for k in n), dtype=np.int64, count=len(j))
        hit = in_simplices(children[i], parents[j])
        out[i[hit]] = tags[j[hit]]
    return out


def in_simplices(points: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Whether points lie in simplices (segments, triangles, tetrahedra; flat or not).

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


def transfer_tags(parent, parent_tags, msh, comm):
    """Tags of the parent mesh on the refined mesh (module docstring); collective.

    Args:
        parent: the parent dolfinx mesh.
        parent_tags: its MeshTags (facets or cells).
        msh: the refined dolfinx mesh.
        comm: the MPI communicator.

    Returns:
        The refined mesh's MeshTags of that dimension: every local entity lying in a tagged
        parent entity.

    Raises:
        RuntimeError: a refined cell lies in no parent cell.
    """
    from dolfinx.mesh import meshtags

    dim = parent_tags.dim
    msh.topology.create_entities(dim)
    imap = msh.topology.index_map(dim)
    local = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    values = np.asarray(parent_tags.values)
    one = comm.allgather(np.unique(values))
    if dim == msh.topology.dim and len(np.unique(np.concatenate(one))) == 1:
        tags = np.full(len(local), np.concatenate(one)[0], dtype=np.int32)   # one body
    else:
        tags = locate(*_gathered(parent, parent_tags, comm), entity_points(msh, dim, local))
    if dim == msh.topology.dim and np.any(tags < 0):
        raise RuntimeError("a cell of the refined mesh lies in no cell of the mesh refined")
    keep = np.flatnonzero(tags >= 0).astype(np.int32)
    return meshtags(msh, dim, keep, tags[keep])


def refine_file_mesh(domain, edges: np.ndarray):
    """A FileMesh with the given edges refined, its physical groups carried over.

    Args:
        domain: the FileMesh (meshes/gmshfile.py).
        edges: this rank's local edges to split (``meshes.adapt.marked_edges``).

    Returns:
        A FileMesh of the refined mesh (redistributed): the same groups and names, h,
        h_min and bbox of the refined mesh.
    """
    from dolfinx import mesh as dmesh

    msh = dmesh.refine(domain.mesh, edges, redistribute=True)
    ct = transfer_tags(domain.mesh, domain.cell_tags, msh, msh.comm)
    ft = transfer_tags(domain.mesh, domain.facet_tags, msh, msh.comm)
    h_min, h_max, bbox = mesh_extent(msh)
    return dataclasses.replace(domain, mesh=msh, cell_tags=ct, facet_tags=ft, h=h_max,
                               h_min=h_min, bbox=bbox)
