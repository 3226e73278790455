"""The condensed solver under mpirun: one distributed MUMPS factorisation of K with the Gamma3
dofs G as Schur variables (kernels/mumps_schur.c, MUMPS's C interface through cffi).

K = L D L^T is factorised once, distributed over the ranks (lower triangle without stored
zeros, each rank its own rows), in the G-last order of the serial path
(schur.interior_last_ordering, computed on rank 0 from the gathered matrix once); MUMPS
returns the Schur complement S = K_GG - K_GI K_II^-1 K_IG on rank 0, where the Gamma3 problem
is solved (threads.GAMMA3_ROOT), and its Cholesky factor C comes from LAPACK's dpotrf there.
A step is a condensation (the forward sweep: r = F_G - K_GI K_II^-1 F_I on rank 0, from the
distributed right-hand side), the Gamma3 problem on rank 0, and an expansion (the backward
sweep with u_G = y: the distributed solution), so only r and y (m values) go through rank 0.
Where the wrapper cannot be built (no MUMPS headers, no compiler) ``load`` returns None and the
condensed solver factorises twice (PETSc's MUMPS and a G-last factorisation on rank 0).
"""
from __future__ import annotations

import logging

import numpy as np
from petsc4py import PETSc

from vpcontact import kernels
from vpcontact.solvers.schur import (
    gather_csr,
    interior_last_ordering,
    mirror_upper,
    spd_cholesky,
)
from vpcontact.threads import root_call

log = logging.getLogger("vpcontact")

MUMPS = kernels.Library("_vpcontact_mumps", ("mumps_schur",),
                        "MUMPS with Gamma3 Schur variables (factorising twice under mpirun)",
                        libraries=("dmumps", "mumps_common"))


def load():
    """The MUMPS wrapper (kernels/mumps_schur.c, linked to libdmumps).

    Returns:
        The cffi module (``.lib``, ``.ffi``), or None if it cannot be built here.
    """
    return MUMPS.load()


# INFOG(1) of a workspace estimate too small (integer, real): MUMPS's remedy is a larger
# ICNTL(14), doubled at most this many times (20 % -> 1280 %)
WORKSPACE_ERRORS = (-8, -9)
WORKSPACE_RETRIES = 6


class MumpsError(RuntimeError):
    """MUMPS failed (INFOG(1) < 0, the same on every rank)."""


def lower_triplets(K: PETSc.Mat) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """This rank's entries of K's lower triangle without stored zeros, 1-based.

    Args:
        K: the distributed stiffness matrix (AIJ).

    Returns:
        (irn, jcn, a): rows, columns (intc) and values (float64).
    """
    indptr, indices, data = K.getValuesCSR()
    start = K.getOwnershipRange()[0]
    rows = start + np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
    keep = (indices <= rows) & (data != 0.0)
    return ((rows[keep] + 1).astype(np.intc), (indices[keep] + 1).astype(np.intc),
            np.ascontiguousarray(data[keep], dtype=float))


def schur_from_buffer(buffer: np.ndarray) -> np.ndarray:
    """The symmetric S from MUMPS's centralised Schur buffer, in the buffer's memory (no
    m x m copies: the strict upper part, MUMPS's work, is overwritten by the lower one's
    transpose).

    Args:
        buffer: the m x m buffer (C order): S's lower triangle by rows.

    Returns:
        S, dense (m, m), symmetric: the buffer itself.
    """
    mirror_upper(buffer.T)            # buffer.T's upper triangle is the buffer's lower one
    return buffer


class SchurMumps:
    """K = L D L^T by MUMPS, distributed, with the Gamma3 dofs last as Schur variables
    (collective).  ``S``, ``C``: the Schur complement and its Cholesky factor, on rank 0
    (threads.GAMMA3_ROOT; None on the others);
    ``forward`` and ``backward``: a step's condensation and expansion.  ``destroy`` frees
    MUMPS's data (collective).

    Args:
        module: the wrapper (``load()``).
        K: the assembled stiffness matrix (PETSc, distributed AIJ, symmetric positive
            definite).
        G: the global rows of the Gamma3 dofs, shape (m,), on every rank.
        bs: the dofs per node (the order keeps a node's dofs together).
        comm: K's communicator (mpi4py).
        semidefinite: K is singular in rigid motions that G holds (a body held only by a
            contact pair: K_II stays definite, S is positive semidefinite): C is None.

    Raises:
        MumpsError: MUMPS failed (on every rank).
    """

    def __init__(self, module, K: PETSc.Mat, G: np.ndarray, bs: int, comm,
                 semidefinite: bool = False):
        self.ffi, self.lib, self.comm = module.ffi, module.lib, comm
        self.semidefinite = semidefinite
        self.m = len(G)
        status = self.ffi.new("int *")
        h = self.lib.ms_init(comm.py2f(), status)
        if h == self.ffi.NULL:
            raise MemoryError("MUMPS: out of memory")
        self._h, self._scatter = h, None
        try:
            self._factorise(K, G, bs, status[0])
        except Exception:
            self.destroy()
            raise
        self._setup_solve(K)

    def _factorise(self, K, G, bs, status: int) -> None:
        """Analysis and factorisation; sets S and C on rank 0."""
        comm, h = self.comm, self._h
        self._check(status, "initialisation")
        self._keep = list(lower_triplets(K))          # arrays MUMPS points to
        perm_in, listvar = self._host_order(K, G, bs)
        self._keep += [perm_in, listvar]
        irn, jcn, a = self._keep[:3]
        n = K.getSize()[0]
        buf = self._buf
        self._check(self.lib.ms_analyse(h, n, len(a), buf(irn), buf(jcn), buf(a), buf(perm_in),
                                        self.m, buf(listvar)), "analysis")
        S = np.zeros((self.m, self.m)) if comm.rank == 0 else None
        self._factor(S)
        self.S = schur_from_buffer(S) if comm.rank == 0 else None
        self.C = None
        if self.semidefinite:                # no factor of S: the Gamma3 problem uses S y0
            return

        def cholesky():                      # on rank 0, MUMPS's host and threads.GAMMA3_ROOT
            self.C = spd_cholesky(self.S)
            return self.C is not None
        if not root_call(comm, cholesky):
            raise MumpsError("the Schur complement from MUMPS is not positive definite")

    def _factor(self, S: np.ndarray | None) -> None:
        """The numerical factorisation (JOB = 2), repeated with the workspace margin ICNTL(14)
        doubled while MUMPS reports its workspace estimate too small (INFOG(1) = -8, -9:
        the remedy its user guide names): the default margin is too small now and then, as
        the partition varies (docs/performance.md, section 9)."""
        h, lib = self._h, self.lib
        messages = lib.ms_icntl(h, 1)
        lib.ms_set_icntl(h, 1, 0)                   # no MUMPS message for a retried attempt
        try:
            for attempt in range(WORKSPACE_RETRIES + 1):
                status = lib.ms_factor(h, self._buf(S))
                if status not in WORKSPACE_ERRORS or attempt == WORKSPACE_RETRIES:
                    break
                margin = lib.ms_icntl(h, 14)
                lib.ms_set_icntl(h, 14, 2 * max(margin, 10))
                log.info("  MUMPS: workspace estimate too small (INFOG(1) = %d, INFOG(2) = %d): "
                         "factorising again with ICNTL(14) = %d %%", status,
                         lib.ms_infog(h, 2), lib.ms_icntl(h, 14))
        finally:
            lib.ms_set_icntl(h, 1, messages)
        self._check(status, "factorisation")

    def _buf(self, a: np.ndarray | None):
        return kernels.buf(self.ffi, a)

    def _check(self, infog1: int, what: str) -> None:
        if infog1 < 0:
            raise MumpsError(f"MUMPS {what}: INFOG(1) = {infog1}, INFOG(2) = "
                             f"{self.lib.ms_infog(self._h, 2)}")

    def _host_order(self, K, G, bs) -> tuple[np.ndarray | None, np.ndarray | None]:
        """PERM_IN (the position of each dof, 1-based) and LISTVAR_SCHUR (G, 1-based) on
        rank 0: the serial path's G-last order (one gather of K, at set-up)."""
        A = gather_csr(K, self.comm)
        if self.comm.rank != 0:
            return None, None
        order = interior_last_ordering(A, G, bs)
        perm_in = np.empty(len(order), dtype=np.intc)
        perm_in[order] = np.arange(1, len(order) + 1, dtype=np.intc)
        return perm_in, (np.asarray(G) + 1).astype(np.intc)

    def _setup_solve(self, K) -> None:
        """The arrays of the steps: right-hand side (owned rows), r / y on rank 0, the
        distributed solution and the scatter from it to a vector of K's layout."""
        lo, hi = K.getOwnershipRange()
        self._irhs = np.arange(lo + 1, hi + 1, dtype=np.intc)
        self.rhs = np.zeros(hi - lo)
        self.redrhs = np.zeros(self.m)
        lsol = self.lib.ms_sol_length(self._h)
        self.sol = np.zeros(max(lsol, 1))
        self._isol = np.zeros(max(lsol, 1), dtype=np.intc)
        buf = self._buf
        self.lib.ms_set_solve(self._h, hi - lo, buf(self._irhs), buf(self.rhs),
                              buf(self.redrhs), lsol, buf(self.sol), buf(self._isol))
        self._lsol, self._scatter = lsol, None
        self._x = K.createVecRight()                   # the scatter's target

    def forward(self, b: np.ndarray) -> np.ndarray:
        """The condensation: r = b_G - K_GI K_II^-1 b_I (collective).

        Args:
            b: this rank's owned entries of the right-hand side.

        Returns:
            r, shape (m,), on rank 0; None on the others.
        """
        self.rhs[:] = b
        self._check(self.lib.ms_solve(self._h, 1), "condensation")
        return self.redrhs.copy() if self.comm.rank == 0 else None

    def backward(self, y: np.ndarray, x: np.ndarray) -> None:
        """The expansion: x = K^-1 (b + E_G lambda) with x_G = y, for the b of the last
        ``forward`` (collective; as kernels.GLastSolve.backward).

        Args:
            y: the Gamma3 values, shape (m,) (read on rank 0).
            x: this rank's owned entries of the solution, overwritten.
        """
        if self.comm.rank == 0:
            self.redrhs[:] = y
        self._check(self.lib.ms_solve(self._h, 2), "expansion")
        if self._scatter is None:
            self._src = PETSc.Vec().createWithArray(self.sol[:self._lsol], comm=PETSc.COMM_SELF)
            index = PETSc.IS().createGeneral((self._isol[:self._lsol] - 1).astype(PETSc.IntType),
                                             comm=PETSc.COMM_SELF)
            self._scatter = PETSc.Scatter().create(self._src, None, self._x, index)
            index.destroy()
        self._scatter.scatter(self._src, self._x, addv=PETSc.InsertMode.INSERT,
                              mode=PETSc.ScatterMode.FORWARD)
        x[:] = self._x.array_r

    def destroy(self) -> None:
        """Free MUMPS's data (JOB = -2) and the scatter (collective)."""
        if self._h is not None:
            self.lib.ms_free(self._h)
            self._h = None
        if self._scatter is not None:
            self._scatter.destroy()
            self._src.destroy()
            self._scatter = None
        if getattr(self, "_x", None) is not None:
            self._x.destroy()
            self._x = None
