"""The cell partitioner of a mesh's construction: in a serial run, every cell stays on the
one rank without building the distributed dual graph and calling the graph partitioner.

dolfinx 0.5.2's ``create_mesh`` partitions the cells before it builds the topology, also on
one rank: the default partitioner builds the cells' dual graph and hands it to the graph
partitioner (SCOTCH or ParMETIS), to learn that every cell belongs to rank 0.  That costs a
third of the mesh's construction and grows with the mesh (docs/performance.md, section 3).
``cell_partitioner`` answers that question directly on one rank; the mesh built is the
same array for array (the cells are reordered afterwards by dolfinx in either case).  Runs on
several ranks keep dolfinx's partitioner.
"""
from __future__ import annotations

import numpy as np
from dolfinx import cpp as _cpp


def _all_on_this_rank(comm, nparts, tdim, cells, ghost_mode):
    """dolfinx's partitioner interface: the destination rank of each local cell (all 0)."""
    return _cpp.graph.AdjacencyList_int32(np.zeros(cells.num_nodes, dtype=np.int32))


def cell_partitioner(comm):
    """The partitioner for ``create_mesh``, ``create_rectangle`` and ``create_box`` on ``comm``
    (gmshio.model_to_mesh of dolfinx 0.5.2 takes none: a user's mesh file keeps the default).

    Args:
        comm: the communicator the mesh is built on.

    Returns:
        The one-rank shortcut on a communicator of one rank, dolfinx's default (the dual
        graph and the graph partitioner) on more.
    """
    if comm.size == 1:
        return _all_on_this_rank
    return _cpp.mesh.create_cell_partitioner()
