"""The serial cell partitioner (meshes/partition.py): on one rank the mesh built with it is
the mesh dolfinx's default partitioner builds, array for array (geometry, its cell-node map,
the cells' original indices, the topology), for triangles and tetrahedra given in a scrambled
order; on more ranks dolfinx's partitioner is kept."""
import types

import numpy as np
import pytest
import ufl
from dolfinx import cpp as _cpp
from dolfinx import mesh as dmesh
from mpi4py import MPI

from vpcontact.meshes.partition import _all_on_this_rank, cell_partitioner


def _scrambled(cell: str, n: int):
    """The cells and vertices of a structured mesh, both in a random order."""
    comm = MPI.COMM_SELF
    if cell == "triangle":
        m = dmesh.create_unit_square(comm, n, n)
    else:
        m = dmesh.create_unit_cube(comm, n, n, n)
    rng = np.random.default_rng(7)
    x = m.geometry.x[:, :m.geometry.dim]
    cells = m.geometry.dofmap.array.reshape(m.topology.index_map(m.topology.dim).size_local, -1)
    perm = rng.permutation(len(x))
    inverse = np.argsort(perm)
    return inverse[cells][rng.permutation(len(cells))].astype(np.int64), x[perm].copy()


def _arrays(m) -> list[np.ndarray]:
    tdim = m.topology.dim
    m.topology.create_connectivity(tdim - 1, tdim)
    return [m.geometry.x, m.geometry.dofmap.array, np.asarray(m.topology.original_cell_index),
            m.topology.connectivity(tdim, 0).array, m.topology.connectivity(tdim - 1, tdim).array,
            m.geometry.input_global_indices]


@pytest.mark.parametrize("cell, n", [("triangle", 9), ("tetrahedron", 4)])
def test_one_rank_builds_the_mesh_the_default_partitioner_builds(cell, n):
    cells, x = _scrambled(cell, n)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", getattr(ufl, cell), 1))
    comm = MPI.COMM_SELF
    default = dmesh.create_mesh(comm, cells, x, domain)
    shortcut = dmesh.create_mesh(comm, cells, x, domain, partitioner=cell_partitioner(comm))
    for a, b in zip(_arrays(default), _arrays(shortcut), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_more_ranks_keep_dolfinx_partitioner():
    assert cell_partitioner(MPI.COMM_SELF) is _all_on_this_rank
    two = types.SimpleNamespace(size=2)
    assert cell_partitioner(two) is not _all_on_this_rank
    assert type(cell_partitioner(two)) is type(_cpp.mesh.create_cell_partitioner())
