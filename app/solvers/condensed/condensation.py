"""The Condensation interface of the condensed solver, and the choice of its back end.

K is factorised once per run.  A step's linear algebra is then
    condense:  y0 = (K^-1 b)_G, the Gamma3 values without contact forces (on GAMMA3_ROOT),
    expand:    x = K^-1 (b + E_G lambda) with x_G = y, once the Gamma3 problem gave y,
with the Schur complement S = K_GG - K_GI K_II^-1 K_IG and its Cholesky factor C (S = C C^T)
from the same factorisation (PETSc: from a second one).  The back ends:
    CholmodCondensation  serial: CHOLMOD's L D L^T with G last (SuperLU's L U without it),
                         compiled forward and backward sweeps (app/solvers/condensed/cholmod.py)
    MumpsCondensation    mpirun: one distributed MUMPS factorisation, G as Schur variables
                         (app/solvers/condensed/mumps.py)
    PetscCondensation    PETSc's direct solver, two solves per step; S from a G-last
                         factorisation on rank 0 (app/solvers/condensed/petsc.py): without a
                         C compiler or the MUMPS wrapper, or with PETSc options fast_* given.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np
from petsc4py import PETSc

from vpcontact.solvers.options import FAST_PREFIX, PREFIX

OPTIONS = FAST_PREFIX[len(PREFIX):]     # case options fast_* configure PETSc's solver of K


class Condensation(Protocol):
    """One factorisation of K, and per step a condensation onto Gamma3 and an expansion.

    Attributes:
        S: the Schur complement (m, m) on GAMMA3_ROOT (None elsewhere, or without Gamma3).
        C: its lower Cholesky factor, Fortran order, where S is.
        factorisations: sparse factorisations of K made (1, or 2 by PetscCondensation).
    """

    S: np.ndarray | None
    C: np.ndarray | None
    factorisations: int

    def condense(self, b: PETSc.Vec) -> np.ndarray | None:
        """y0 = (K^-1 b)_G in G order (collective).

        Args:
            b: the right-hand side (K's row layout); kept until ``expand``.

        Returns:
            y0 on GAMMA3_ROOT (None without Gamma3, and on the other ranks).
        """

    def reduce(self, b: PETSc.Vec) -> np.ndarray | None:
        """r = b_G - K_GI K_II^-1 b_I = S y0 in G order, for S only positive semidefinite too
        (collective; two bodies: app/solvers/condensed/pairs.py).

        Args:
            b: the right-hand side (K's row layout); kept until ``expand``.

        Returns:
            r on GAMMA3_ROOT (None without Gamma3, and on the other ranks).
        """

    def expand(self, y: np.ndarray, x: PETSc.Vec) -> None:
        """x = K^-1 (b + E_G lambda) with x_G = y, for the b of the last ``condense``
        (collective).

        Args:
            y: the Gamma3 values in G order (every rank; empty without Gamma3).
            x: the solution (K's row layout), overwritten.
        """

    def destroy(self) -> None:
        """Free the factorisation (collective)."""


def factorise(K: PETSc.Mat, G_rows: np.ndarray, d: int, layout, options: dict,
              comm, semidefinite: bool = False) -> Condensation:
    """Factorise K once with the back end that applies (collective).

    Args:
        K: the assembled elasticity matrix (BAIJ serially, AIJ under mpirun).
        G_rows: the global rows of the Gamma3 dofs in G order, shape (m,) (m may be 0).
        d: the dofs per node.
        layout: the Gamma3Layout (None without Gamma3).
        options: the case's PETSc options; any named fast_* selects PetscCondensation.
        comm: the run's communicator.
        semidefinite: K is singular in rigid motions that G holds (a body held only by a
            contact pair): S is positive semidefinite, C may be None; the serial back end
            with the compiled kernels (CholmodCondensation) and MUMPS under mpirun take it.

    Returns:
        CholmodCondensation (serial, with the compiled kernels), MumpsCondensation (mpirun,
        with Gamma3 dofs and the MUMPS wrapper), else PetscCondensation.

    Raises:
        CaseError: ``semidefinite`` where the CHOLMOD back end does not serve.
    """
    from vpcontact import kernels
    petsc_options = any(str(k).startswith(OPTIONS) for k in options)
    module = kernels.load() if comm.size == 1 and not petsc_options else None
    if module is not None:
        from vpcontact.solvers.condensed.cholmod import CholmodCondensation
        return CholmodCondensation(K, G_rows, d, module, comm, semidefinite)
    if comm.size > 1 and not petsc_options and len(G_rows):
        from vpcontact.solvers.condensed.mumps import MumpsCondensation
        condensation = MumpsCondensation.build(K, G_rows, d, comm, semidefinite)
        if condensation is not None:
            return condensation
    if semidefinite:
        from vpcontact.io.errors import CaseError
        raise CaseError("solver.method: the condensed solver takes a body held only by "
                        "contact with its compiled kernels (serially) or MUMPS (under "
                        "mpirun) only, without fast_* options (allowed here: snes_vi)")
    from vpcontact.solvers.condensed.petsc import PetscCondensation
    return PetscCondensation(K, G_rows, layout, options, comm)
