"""Local refinement of the built-in rectangle or box: the marked cells' edges are split by
dolfinx's ``mesh.refine`` (Plaza's algorithm; neighbours are split as far as conformity
needs), and the sides are tagged again by their planes (``rectangle.tag_sides``), so the
refined mesh keeps the named boundary groups (a gmsh mesh's groups: meshes/retag.py).  A
refined mesh is unstructured: ``n`` and ``diagonal`` are None, ``h`` its largest cell
diameter.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .extent import mesh_extent
from .rectangle import RectangleMesh, tag_sides


def marked_edges(msh, cells: np.ndarray) -> np.ndarray:
    """The local edges of the given local cells, each once.

    Args:
        msh: the dolfinx mesh.
        cells: local cell indices.

    Returns:
        Sorted local edge indices (int32).
    """
    tdim = msh.topology.dim
    msh.topology.create_entities(1)
    msh.topology.create_connectivity(tdim, 1)
    c2e = msh.topology.connectivity(tdim, 1)
    per_cell = len(c2e.links(0)) if len(cells) else 0
    if not per_cell:
        return np.zeros(0, dtype=np.int32)
    edges = c2e.array.reshape(-1, per_cell)[np.asarray(cells, dtype=np.int64)]
    return np.unique(edges).astype(np.int32)


def refine_cells(domain: RectangleMesh, cells: np.ndarray) -> RectangleMesh:
    """The domain with the given cells refined (collective; each rank gives its own).

    Args:
        domain: a RectangleMesh or BoxMesh (the built-in meshes), or a FileMesh.
        cells: this rank's local indices of the cells to refine.

    Returns:
        A mesh of the same class: the built-in meshes with their sides tagged again,
        redistributed over the ranks; a FileMesh with its groups carried over
        (``meshes.retag.refine_file_mesh``).
    """
    from dolfinx import mesh as dmesh

    from .gmshfile import FileMesh
    if isinstance(domain, FileMesh):
        from .retag import refine_file_mesh
        return refine_file_mesh(domain, marked_edges(domain.mesh, cells))

    msh = dmesh.refine(domain.mesh, marked_edges(domain.mesh, cells), redistribute=True)
    L = (domain.L1, domain.L2, domain.L3)[:domain.dim]
    ct, ft = tag_sides(msh, L)
    h_min, h_max, bbox = mesh_extent(msh)
    return dataclasses.replace(domain, mesh=msh, cell_tags=ct, facet_tags=ft,
                               structured=False, n=None, h=h_max, diagonal=None,
                               h_min=h_min, bbox=bbox)
