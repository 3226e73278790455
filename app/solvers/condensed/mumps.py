"""The back end of the Condensation under mpirun: one distributed MUMPS factorisation of K with
the Gamma3 dofs as Schur variables (app/solvers/mumps.py).  MUMPS gives S on rank 0
(GAMMA3_ROOT); a step's condensation is MUMPS's reduced right-hand side r, on rank 0, and its
expansion the solution with x_G = y, distributed; only r and y (m values) pass through rank 0.
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from vpcontact.solvers.dense import cholesky_solve

log = logging.getLogger("vpcontact")


class MumpsCondensation:
    """A Condensation (condensation.py) by MUMPS with Schur variables (collective).

    Args:
        schur: the factorisation (mumps.SchurMumps).
    """

    def __init__(self, schur):
        self._mumps = schur
        self.S, self.C = schur.S, schur.C
        self.factorisations = 1
        log.info("  condensed solver: one distributed MUMPS factorisation, Gamma3 as Schur "
                 "variables")

    @classmethod
    def build(cls, K, G_rows: np.ndarray, d: int, comm,
              semidefinite: bool = False) -> MumpsCondensation | None:
        """Factorise K with MUMPS (collective).

        Args:
            K: the assembled elasticity matrix (AIJ, distributed).
            G_rows: the global rows of the Gamma3 dofs in G order, shape (m,), m > 0.
            d: the dofs per node.
            comm: the run's communicator.
            semidefinite: K singular in motions G holds: S semidefinite, no C (``reduce``
                only).

        Returns:
            The condensation, or None (the same on every rank) where the wrapper cannot be
            built on every rank or MUMPS fails.
        """
        from vpcontact.solvers import mumps
        module = mumps.load()
        if not comm.allreduce(module is not None, op=MPI.LAND):
            return None
        try:
            schur = mumps.SchurMumps(module, K, G_rows, d, comm, semidefinite)
        except mumps.MumpsError as exc:
            log.warning("  condensed solver: %s; %s", exc,
                        "no other back end takes a body held only by the contact"
                        if semidefinite else "factorising twice instead")
            return None
        return cls(schur)

    def condense(self, b) -> np.ndarray | None:
        """y0 = S^-1 r with MUMPS's condensed right-hand side r (collective).

        Args:
            b: the right-hand side (distributed).

        Returns:
            y0 in G order on rank 0; None on the others.
        """
        r = self._mumps.forward(b.array_r)
        return cholesky_solve(self.C, r) if r is not None else None

    def reduce(self, b) -> np.ndarray | None:
        """MUMPS's condensed right-hand side r = b_G - K_GI K_II^-1 b_I (collective).

        Args:
            b: the right-hand side (distributed).

        Returns:
            r in G order on rank 0; None on the others.
        """
        return self._mumps.forward(b.array_r)

    def expand(self, y: np.ndarray, x) -> None:
        """MUMPS's solution with x_G = y (collective).

        Args:
            y: the Gamma3 values (read on rank 0).
            x: the solution (distributed), overwritten.
        """
        self._mumps.backward(y, x.array)

    def destroy(self) -> None:
        """Free MUMPS's data (collective)."""
        self._mumps.destroy()
