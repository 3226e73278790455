"""What a run does with each pair of two bodies in contact (``contact.pairs``), as ``check``
and the run's log show it: the surface and its target, the coupling rule, the surface
nodes, the target facets, the measured initial distance d_i (app/model/pairs.py: the
bound [u]_nu <= d + g) and the nodes touching at the start (d_i = 0 within round-off).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from vpcontact.model.pairs import PENETRATION_TOL, local_facets

# a mortar pair whose surface facets are longer than COARSER times the target's: noted (the
# finer side as the surface passes the contact patch test exactly, the coarser one nearly)
COARSER = 1.2


@dataclass(frozen=True)
class PairSummary:
    """One pair at the start of a run (over all ranks).

    Attributes:
        index: the pair's position in contact.pairs.
        surface, target: the groups.
        rule: "mortar" or "node_to_segment".
        nodes: the surface nodes (Gamma3 nodes of the pair).
        facets: the target's facets.
        h_surface, h_target: the mean facet size (longest edge) of the surface and the
            target [m].
        d_min, d_max: the smallest and largest initial distance d_i [m].
        g: the pair's extra gap [m].
        touching: the nodes with d_i = 0 within round-off (PENETRATION_TOL times the size).
    """

    index: int
    surface: str | int
    target: str | int
    rule: str
    nodes: int
    facets: int
    h_surface: float
    h_target: float
    d_min: float
    d_max: float
    g: float
    touching: int

    def line(self) -> str:
        """The pair in one line (check and the run's log).

        Returns:
            The line.
        """
        coarser = self.rule == "mortar" and self.h_surface > COARSER * self.h_target
        return (f"contact pair {self.index}: {self.surface} -> {self.target} ({self.rule}): "
                f"{self.nodes} surface nodes (h = {self.h_surface:.3g} m), {self.facets} "
                f"target facets (h = {self.h_target:.3g} m), initial distance "
                f"d = {self.d_min:.3g}..{self.d_max:.3g} m, g = {self.g:g} m, "
                f"{self.touching} node(s) touching (d = 0)"
                + ("; the surface is the coarser side: with the finer side as the surface "
                   "the mortar rule passes the contact patch test exactly" if coarser else ""))


def pair_summaries(disc) -> list[PairSummary]:
    """The pairs of a discretisation at the start (collective; empty without pairs).

    Args:
        disc: the Discretisation (its pairs, Gamma3 nodes and facets).

    Returns:
        A PairSummary per entry of contact.pairs.
    """
    geo, comm = disc.pairs, disc.comm
    if geo is None:
        return []
    owned = disc.gamma3_local_nodes < disc.V.dofmap.index_map.size_local
    tol = PENETRATION_TOL * disc.length_scale
    out = []
    for i, p in enumerate(disc.case.contact.pairs):
        d = geo.distance[owned & (geo.pair == i)]
        d = np.where(d <= tol, 0.0, d)              # round-off: touching
        n_facets, h_target = _facet_size(disc, p.target)
        out.append(PairSummary(
            i, p.surface, p.target, p.rule, comm.allreduce(len(d), op=MPI.SUM), n_facets,
            _facet_size(disc, p.surface)[1], h_target,
            comm.allreduce(float(d.min(initial=np.inf)), op=MPI.MIN),
            comm.allreduce(float(d.max(initial=-np.inf)), op=MPI.MAX), p.g,
            comm.allreduce(int(np.sum(d <= tol)), op=MPI.SUM)))
    return out


def _facet_size(disc, ref) -> tuple[int, float]:
    """(the facets of a group, their mean longest edge) over all ranks (collective)."""
    x = local_facets(disc, ref, owned=True)[0]
    edges = [(a, b) for a in range(x.shape[1]) for b in range(a + 1, x.shape[1])]
    longest = np.max([np.linalg.norm(x[:, a] - x[:, b], axis=1) for a, b in edges], axis=0)
    n = disc.comm.allreduce(len(x), op=MPI.SUM)
    return n, disc.comm.allreduce(float(np.sum(longest)), op=MPI.SUM) / max(n, 1)


def pair_lines(disc) -> list[str]:
    """One line per pair (``PairSummary.line``); collective.

    Args:
        disc: the Discretisation.

    Returns:
        The lines (none without pairs).
    """
    return [s.line() for s in pair_summaries(disc)]
