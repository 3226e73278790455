"""The Gamma3 dofs G of the condensed solver and how they are spread over the ranks.

G is ordered by the global number of its nodes, d dofs per node; every rank owns the Gamma3
nodes of its part of the mesh.  ``Gamma3Layout`` places a rank's values at its positions in G
(``place_on_all``, ``gather_vector``, ``gather_nodal``), gives the global matrix rows of G
(``global_rows``) and assembles an m x m matrix from the ranks' rows (``gather_matrix``).
"""
from __future__ import annotations

import numpy as np

from vpcontact.threads import GAMMA3_ROOT


class Gamma3Layout:
    """The Gamma3 nodes of all ranks in G order (collective).

    Attributes:
        g_nodes: the global node numbers, sorted (G order), on every rank.
        w: their nodal weights of the Gamma3 rule, in G order.
        m: the number of Gamma3 dofs (nodes times d).
        local_owned_g: the positions in G of this rank's owned Gamma3 nodes.
        owned_dofs_local: their dofs in this rank's vector of u.
        owned_positions: the positions of those dofs in G.
        owned_rows: the global matrix rows of those dofs (K's row layout).

    Args:
        disc: the Discretisation (V, gamma3: its owned nodes and weights).
        row_start: the first global row of K this rank owns.
        nodes: this rank's owned nodes of G (None: its Gamma3 nodes; two bodies: also the
            target nodes coupled to them, app/solvers/condensed/pairs.py).
        weight: their nodal weights (None: those of the Gamma3 rule).
    """

    def __init__(self, disc, row_start: int, nodes=None, weight=None):
        self.comm, d = disc.comm, disc.dim
        self.d = d
        imap = disc.V.dofmap.index_map
        owned_nodes = disc.gamma3.nodes if nodes is None else nodes
        glob_nodes = imap.local_to_global(owned_nodes.astype(np.int32))
        parts = self.comm.allgather((glob_nodes, disc.gamma3.weight if weight is None
                                     else weight))
        gn = np.concatenate([a for a, _ in parts])
        w = np.concatenate([b for _, b in parts])
        order = np.argsort(gn)
        self.g_nodes, self.w = gn[order], w[order]
        self.m = d * len(self.g_nodes)
        self.local_owned_g = np.searchsorted(self.g_nodes, glob_nodes)   # positions in G
        self.owned_dofs_local = (owned_nodes[:, None] * d + np.arange(d)).ravel()
        self.owned_positions = (self.local_owned_g[:, None] * d + np.arange(d)).ravel()
        self.owned_rows = row_start + self.owned_dofs_local

    def place_on_all(self, positions, values, shape, dtype=float) -> np.ndarray:
        """The array whose entries at every rank's positions are that rank's values, on
        every rank (collective).

        Args:
            positions: this rank's positions in the array.
            values: this rank's values there.
            shape: the array's shape.
            dtype: its type.

        Returns:
            The assembled array.
        """
        out = np.empty(shape, dtype=dtype)
        for pos, vals in self.comm.allgather((positions, values)):
            out[pos] = vals
        return out

    def global_rows(self) -> np.ndarray:
        """The global dof numbers of the Gamma3 dofs (collective).

        Returns:
            The global matrix row of every Gamma3 dof, in G order, shape (m,) (int32), on
            every rank.
        """
        return self.place_on_all(self.owned_positions, self.owned_rows, self.m, np.int32)

    def gather_vector(self, vec) -> np.ndarray:
        """The values of a vector of u's layout at the Gamma3 dofs (collective).

        Args:
            vec: a PETSc vector with u's layout.

        Returns:
            Its values at G, in G order, shape (m,), on every rank.
        """
        return self.place_on_all(self.owned_positions, vec.array_r[self.owned_dofs_local],
                                 self.m)

    def gather_nodal(self, disc, field) -> np.ndarray:
        """A Gamma3 NodalField's values at the Gamma3 nodes (collective).

        Args:
            disc: the Discretisation (its Gamma3 nodes).
            field: the NodalField (xi_n or theta(s_n)).

        Returns:
            The values in G's node order, shape (m / d,), on every rank.
        """
        pos = np.searchsorted(disc.gamma3_local_nodes, disc.gamma3.nodes)
        return self.place_on_all(self.local_owned_g, field.function.x.array[field.dofs[pos]],
                                 len(self.g_nodes))

    def gather_matrix(self, local_rows: np.ndarray) -> np.ndarray | None:
        """Assemble an m x m matrix from the ranks' rows (collective).

        Args:
            local_rows: this rank's rows, at its owned Gamma3 positions in G order, shape
                (number owned, m), columns in G order.

        Returns:
            The whole matrix, shape (m, m), on GAMMA3_ROOT; None on the other ranks.
        """
        rows = np.ascontiguousarray(local_rows, dtype=float)
        pos = np.ascontiguousarray(self.owned_positions, dtype=np.int64)
        # one rank: no pickled copy of the m x m rows (docs/performance.md, section 9)
        if self.comm.size == 1:
            out = np.empty((self.m, self.m))
            out[pos] = rows
            return out
        counts = self.comm.gather(len(pos), root=GAMMA3_ROOT)
        root = self.comm.rank == GAMMA3_ROOT
        all_pos = np.empty(sum(counts) if root else 0, dtype=np.int64)
        all_rows = np.empty((len(all_pos), self.m)) if root else None
        self.comm.Gatherv(pos, (all_pos, counts) if root else None, root=GAMMA3_ROOT)
        self.comm.Gatherv(rows, (all_rows, [c * self.m for c in counts]) if root else None,
                          root=GAMMA3_ROOT)
        if not root:
            return None
        out = np.empty((self.m, self.m))
        out[all_pos] = all_rows
        return out
