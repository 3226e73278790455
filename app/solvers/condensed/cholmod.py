"""The serial back end of the Condensation: K = L D L^T by CHOLMOD with the Gamma3 dofs last
(SuperLU's L U where CHOLMOD is missing; app/solvers/schur.py), its trailing blocks giving
S = L_GG D_G L_GG^T, and a step's condensation and expansion as one forward and one backward
sweep through L's interior columns (kernels.GLastSolve: node blocks, compiled), faster than
the two PETSc back-substitutions of PetscCondensation (docs/performance.md, section 4).
``RootCondensation`` is the same on GAMMA3_ROOT under mpirun: K gathered
there once, each right-hand side gathered and each solution scattered back by PETSc (n values
each way), while the other ranks wait asleep.
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact import kernels, threads
from vpcontact.solvers.dense import cholesky_solve
from vpcontact.solvers.schur import (
    CSR,
    GLastLDL,
    GLastLU,
    g_last_factor,
    gather_csr,
    schur_pair,
)

log = logging.getLogger("vpcontact")

THREADED_FACTOR_MIN = 50_000    # dofs from which the G-last factorisation uses BLAS threads


class CholmodCondensation:
    """A Condensation (condensation.py) by one G-last factorisation and compiled sweeps
    (serial).

    Args:
        K: the assembled elasticity matrix, or its CSR (schur.gather_csr).
        G_rows: the rows of the Gamma3 dofs in G order, shape (m,).
        d: the dofs per node.
        module: the compiled kernels (kernels.load()).
        comm: the (one-rank) communicator.
        semidefinite: K is singular in rigid motions that G holds (a body held only by a
            contact pair): SuperLU's G-last L U (CHOLMOD refuses the vanishing pivots), S
            positive semidefinite and C None where it has no Cholesky factor (``reduce``
            serves then, ``condense`` does not).
    """

    def __init__(self, K, G_rows: np.ndarray, d: int, module, comm,
                 semidefinite: bool = False):
        A = K if isinstance(K, CSR) else gather_csr(K, comm)
        with threads.blas_threads(large=A.n >= THREADED_FACTOR_MIN):
            # K singular in a motion G holds: its last pivots vanish, which CHOLMOD refuses
            factor = GLastLU(A, G_rows, d) if semidefinite else g_last_factor(A, G_rows, d)
        self._split = kernels.GLastSolve(factor, module, d, threads=threads.cores())
        self.factorisations = 1
        split = self._split.split
        log.info("  condensed solver: one %s factorisation (Gamma3 last), compiled sweeps%s",
                 "CHOLMOD L D L^T" if isinstance(factor, GLastLDL) else "SuperLU L U",
                 "" if split is None else
                 f" (two threads: block columns 0-{split[0] - 1} and {split[0]}-{split[1] - 1}"
                 f" at once, then {split[1]}-{self._split.nbc - 1})")
        self.S, self.C = (schur_pair(factor) if not semidefinite else
                          _semidefinite_schur(factor)) if len(G_rows) else (None, None)

    def condense(self, b) -> np.ndarray | None:
        """y0 = S^-1 r with r = b_G - K_GI K_II^-1 b_I from the forward sweep.

        Args:
            b: the right-hand side.

        Returns:
            y0 in G order, None without Gamma3.
        """
        r = self._split.forward(b.array_r)
        return None if self.C is None else cholesky_solve(self.C, r)

    def reduce(self, b) -> np.ndarray | None:
        """r = b_G - K_GI K_II^-1 b_I from the forward sweep (S y0 = r).

        Args:
            b: the right-hand side.

        Returns:
            r in G order, None without Gamma3.
        """
        r = self._split.forward(b.array_r)
        return None if self.S is None else r

    def expand(self, y: np.ndarray, x) -> None:
        """The backward sweep with x_G = y.

        Args:
            y: the Gamma3 values (empty without Gamma3).
            x: the solution, overwritten.
        """
        self._split.backward(y, x.array)

    def destroy(self) -> None:
        """Nothing to free: the factor goes with this object."""


class RootCondensation:
    """A Condensation (condensation.py) under mpirun by CholmodCondensation on GAMMA3_ROOT
    (collective): K gathered there and factorised once, each right-hand side gathered there
    and each solution scattered back (PETSc's scatter to zero), the sweeps on the root while
    the other ranks wait asleep (threads.root_call).  S and C are on the root, None elsewhere.

    Args:
        K: the assembled elasticity matrix (distributed).
        G_rows: the global rows of the Gamma3 dofs in G order, shape (m,), m > 0.
        d: the dofs per node.
        module: the compiled kernels (kernels.load(), on the root).
        comm: the run's communicator.

    Raises:
        np.linalg.LinAlgError: S is not positive definite (on every rank).
    """

    def __init__(self, K, G_rows: np.ndarray, d: int, module, comm):
        self.comm = comm
        A = gather_csr(K, comm)
        self._b = K.createVecRight()          # (the layout of the scatter to the root)
        self._scatter, self._whole = PETSc.Scatter.toZero(self._b)
        self._root = None           # the CholmodCondensation, on the root

        def factorise():
            self._root = CholmodCondensation(A, G_rows, d, module, MPI.COMM_SELF)

        threads.root_call(comm, factorise)
        self.S = None if self._root is None else self._root.S
        self.C = None if self._root is None else self._root.C
        self.factorisations = 1

    def condense(self, b) -> np.ndarray | None:
        """y0 = S^-1 r with r of ``reduce`` (collective; the solve with C on the root).

        Args:
            b: the right-hand side (distributed).

        Returns:
            y0 in G order on the root; None on the others.
        """
        r = self.reduce(b)
        return None if r is None or self.C is None else cholesky_solve(self.C, r)

    def reduce(self, b) -> np.ndarray | None:
        """r = b_G - K_GI K_II^-1 b_I (collective; ``CholmodCondensation.reduce``).

        Args:
            b: the right-hand side (distributed).

        Returns:
            r in G order on the root; None on the others.
        """
        self._gather(b)
        return self._on_root(lambda: self._root.reduce(self._whole))

    def expand(self, y: np.ndarray, x) -> None:
        """The backward sweep with x_G = y on the root, scattered to x (collective).

        Args:
            y: the Gamma3 values (read on the root).
            x: the solution (distributed), overwritten.
        """
        self._on_root(lambda: self._root.expand(y, self._whole))
        self._scatter.scatter(self._whole, x, PETSc.InsertMode.INSERT,
                              PETSc.ScatterMode.REVERSE)

    def _gather(self, b) -> None:
        """The whole b on the root (collective)."""
        self._scatter.scatter(b, self._whole, PETSc.InsertMode.INSERT,
                              PETSc.ScatterMode.FORWARD)

    def _on_root(self, work):
        """work() on the root while the others wait asleep; its result there, None
        elsewhere (collective; an exception is raised on every rank)."""
        out = []
        threads.root_call(self.comm, lambda: out.append(work()))
        return out[0] if out else None

    def destroy(self) -> None:
        """Free the gather's vectors and scatter."""
        for obj in (self._b, self._scatter, self._whole):
            obj.destroy()


def _semidefinite_schur(factor) -> tuple[np.ndarray, np.ndarray | None]:
    """(S, C) of ``schur_pair``, or (S, None) where S is only positive semidefinite (a body
    whose rigid motion the contact holds: K is singular in it, K_II is not)."""
    try:
        return schur_pair(factor)
    except np.linalg.LinAlgError:
        L_GG, U_GG = factor.trailing()
        S = L_GG @ U_GG
        return 0.5 * (S + S.T), None
