"""The nodal forces the boundary exerts on the body: the bulk residual
    r_i = (sigma_n, eps(phi_i)) - f_n(phi_i)
of (3.4) without the Gamma3 terms, at the nodes of the Dirichlet groups, of Gamma3 and of the
pairs' targets (the step records' reactions and contact forces, the contact table, Coulomb's
p_n).

With P1 displacements sigma_n is constant on each cell, so (sigma_n, eps(phi_i)) sums over
the cells around node i: r is exact at these nodes from the cells that touch them alone, a
thin layer of the mesh (StrainOperator.stress_load, the compiled cell pass over those cells),
and f_n is the run's LoadVector.  Against an assembly of the bulk residual form on the
layer's cells: the same values to round-off, from the stress instead of E eps(u) + H_n, in
a fraction of the time (docs/performance.md, sections 2 and 9).
"""
from __future__ import annotations

import numpy as np
from dolfinx import mesh as dmesh


def layer_cells(disc, groups: list[str]) -> np.ndarray:
    """The owned cells with a vertex on one of the facet groups, as rows of the DG0 space Q
    (the StrainOperator's cell order).

    Args:
        disc: the Discretisation (mesh, facets of its groups, Q).
        groups: facet group names (Dirichlet groups, Gamma3 sides, pair targets).

    Returns:
        Sorted rows of Q's owned blocks.
    """
    msh, tdim = disc.mesh, disc.dim
    facets = np.unique(np.concatenate([disc.facets[g] for g in groups] or
                                      [np.zeros(0, np.int32)])).astype(np.int32)
    msh.topology.create_connectivity(tdim - 1, 0)
    msh.topology.create_connectivity(0, tdim)
    verts = dmesh.compute_incident_entities(msh, facets, tdim - 1, 0)
    cells = np.unique(dmesh.compute_incident_entities(msh, verts, 0, tdim))
    cells = cells[cells < msh.topology.index_map(tdim).size_local]
    return np.sort(disc.Q.dofmap.list.array[cells])    # DG0: one block per cell


class BoundaryLayer:
    """r = (sigma_n, eps(phi_i)) - f_n(phi_i) at the owned nodes, exact at the layer's nodes.

    Args:
        problem: the ContactProblem; its sigma must hold the stress of its u when
            ``residual`` is called (after the stress update, or ``current_stress``).
        groups: the facet groups whose nodes need r.
    """

    def __init__(self, problem, groups: list[str]):
        self.problem = problem
        self.cells = problem.strain_operator.subset(layer_cells(problem.disc, groups))

    def residual(self) -> np.ndarray:
        """r at the owned nodes (exact at the layer's; collective).

        Returns:
            (owned nodes, d) nodal forces.
        """
        p, d = self.problem, self.problem.disc.dim
        owned = p.disc.V.dofmap.index_map.size_local * d
        r = p.strain_operator.stress_load(p.sigma, self.cells).array_r[:owned].copy()
        if p.load_vector is not None:
            r -= p.load_vector.at_current_time().array_r[:owned]
        return r.reshape(-1, d)
