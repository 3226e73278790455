"""Sizes and bounding box of a distributed simplex mesh, reduced over its communicator."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI


def cell_diameters(msh) -> np.ndarray:
    """The diameters (longest edges) of the rank's owned cells of a P1 simplex mesh.

    Args:
        msh: a dolfinx mesh of triangles or tetrahedra (affine geometry).

    Returns:
        (number of owned cells,) array.
    """
    tdim = msh.topology.dim
    ncell = msh.topology.index_map(tdim).size_local
    cells = msh.geometry.dofmap.array.reshape(-1, tdim + 1)[:ncell]
    x = msh.geometry.x[cells]                      # (ncell, tdim + 1, 3)
    d = np.zeros(ncell)
    for i in range(tdim + 1):
        for j in range(i + 1, tdim + 1):
            d = np.maximum(d, np.linalg.norm(x[:, i] - x[:, j], axis=1))
    return d


def mesh_extent(msh) -> tuple[float, float, tuple[np.ndarray, np.ndarray]]:
    """The smallest and largest cell diameters and the bounding box; collective.

    Args:
        msh: a dolfinx mesh of triangles or tetrahedra.

    Returns:
        (h_min, h_max, (lo, hi)): the diameters over all ranks and the corners of the box
        holding every vertex, each (gdim,).
    """
    comm = msh.comm
    d = cell_diameters(msh)
    h_min = comm.allreduce(float(d.min()) if d.size else np.inf, op=MPI.MIN)
    h_max = comm.allreduce(float(d.max()) if d.size else 0.0, op=MPI.MAX)
    gdim = msh.geometry.dim
    x = msh.geometry.x[:, :gdim]
    lo = np.full(gdim, np.inf) if x.size == 0 else x.min(axis=0)
    hi = np.full(gdim, -np.inf) if x.size == 0 else x.max(axis=0)
    lo_all, hi_all = np.empty(gdim), np.empty(gdim)
    comm.Allreduce(np.ascontiguousarray(lo), lo_all, op=MPI.MIN)
    comm.Allreduce(np.ascontiguousarray(hi), hi_all, op=MPI.MAX)
    return h_min, h_max, (lo_all, hi_all)
