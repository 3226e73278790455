"""The general back end of the Condensation: PETSc's direct solver of K (LU serially, MUMPS
under mpirun), two solves per step, u_free = K^-1 F_n and u = K^-1 (F_n + E_G lambda) with
the Gamma3 forces lambda = S (y - y0); S and C from a G-last factorisation of the matrix
gathered on rank 0 (app/solvers/schur.py): two factorisations per run, counted.  It serves
runs without a C compiler or the MUMPS wrapper, and runs given PETSc options for the
condensed solver's direct solver (fast_ksp_type, fast_pc_factor_mat_solver_type, ...).
"""
from __future__ import annotations

import logging

import numpy as np

from vpcontact import threads
from vpcontact.solvers.options import FAST_PREFIX, PREFIX, push_options, remove_options
from vpcontact.solvers.schur import gamma3_schur_pair

log = logging.getLogger("vpcontact")


class PetscCondensation:
    """A Condensation (condensation.py) by PETSc's direct solver (collective).

    Args:
        K: the assembled elasticity matrix.
        G_rows: the global rows of the Gamma3 dofs in G order, shape (m,) (m may be 0).
        layout: the Gamma3Layout (None without Gamma3).
        options: the case's PETSc options (those named fast_* configure the KSP).
        comm: the run's communicator.
    """

    def __init__(self, K, G_rows: np.ndarray, layout, options: dict, comm):
        from vpcontact.solvers.snesvi import direct_solver
        self.comm, self.layout = comm, layout
        self.ksp = direct_solver(K, comm, FAST_PREFIX)
        push_options(options, PREFIX)      # user options, e.g. -fast_ksp_view
        try:
            self.ksp.setFromOptions()
        finally:
            remove_options(options, PREFIX)
        self.ksp.setUp()
        self.factorisations = 1
        log.info("  condensed solver: PETSc %s for the steps%s",
                 self.ksp.getPC().getFactorSolverType() or "LU",
                 ", a G-last factorisation on rank 0 for S" if len(G_rows) else "")
        self.S = self.C = None
        if len(G_rows):
            self.factorisations += 1
            self.S, self.C = gamma3_schur_pair(K, G_rows, comm) or (None, None)
        self._free = K.createVecRight()
        self._b, self._y0 = None, None

    def condense(self, b) -> np.ndarray | None:
        """u_free = K^-1 b and its Gamma3 values (collective).

        Args:
            b: the right-hand side; ``expand`` adds the Gamma3 forces to it.

        Returns:
            y0 = (u_free)_G in G order on every rank; None without Gamma3.
        """
        self.ksp.solve(b, self._free)
        self._b = b
        self._y0 = self.layout.gather_vector(self._free) if self._gamma3() else None
        return self._y0

    def reduce(self, b) -> np.ndarray | None:
        """r = S y0, y0 of ``condense`` (collective; K positive definite here).

        Args:
            b: the right-hand side; ``expand`` adds the Gamma3 forces to it.

        Returns:
            r in G order on GAMMA3_ROOT; None elsewhere and without Gamma3.
        """
        y0 = self.condense(b)
        if y0 is None or self.comm.rank != threads.GAMMA3_ROOT:
            return None
        return self.S @ y0

    def _gamma3(self) -> bool:
        """Whether there is a Gamma3 problem (S lives on the root only)."""
        return self.layout is not None and self.layout.m > 0

    def expand(self, y: np.ndarray, x) -> None:
        """x = K^-1 (b + E_G lambda), lambda = S (y - y0) (collective).

        Args:
            y: the Gamma3 values in G order (every rank; empty without Gamma3).
            x: the solution, overwritten.
        """
        if self._y0 is None:
            self._free.copy(x)
            return
        on_root = self.comm.rank == threads.GAMMA3_ROOT
        lam = self.S @ (y - self._y0) if on_root else None           # Gamma3 forces
        lam = self.comm.bcast(lam, root=threads.GAMMA3_ROOT)
        layout = self.layout
        self._b.array[layout.owned_dofs_local] += lam[layout.owned_positions]
        self.ksp.solve(self._b, x)

    def destroy(self) -> None:
        """Free the KSP and the work vector."""
        self.ksp.destroy()
        self._free.destroy()
