"""K = L D L^T by CHOLMOD (SuiteSparse, Debian's libsuitesparse-dev) in a given order.

The condensed solver factorises the symmetric positive definite elasticity matrix once per run
with the Gamma3 dofs ordered last (schur.py).  SuperLU (scipy) computes L and U, twice the
work of a Cholesky factorisation; CHOLMOD's supernodal Cholesky L L^T gives the same L D L^T
(L_ldl = L D^-1/2, D = diag(L)^2) in a fraction of the time (at h = 1/128, 33,282 dofs: see
schur.GLastLDL).  The order is the caller's: CHOLMOD_GIVEN without postordering, and the
factor's permutation is checked against it.  The supernodal factor is not converted to
CHOLMOD's simplicial form: its interior columns go straight into the node blocks of the
split solve (kernels.GLastSolve), written over CHOLMOD's own value array, and the trailing
Gamma3 block L_GG is read out densely: no conversion, no fresh copy and fewer page faults
(docs/performance.md, section 3).

The wrapper (kernels/cholmod_ldl.c) is compiled with cffi like the other kernels and linked to
libcholmod; where that is not possible (no headers, no compiler) ``load`` returns None and
SuperLU is used.  ``ldl_numpy`` is the same factorisation by numpy (the tests' reference).
"""
from __future__ import annotations

import numpy as np

from vpcontact import kernels

CHOLMOD = kernels.Library("_vpcontact_cholmod", ("cholmod_ldl",), "CHOLMOD L D L^T (using SuperLU)",
                          libraries=("cholmod",), include_dirs=("/usr/include/suitesparse",))


def load():
    """The CHOLMOD wrapper (kernels/cholmod_ldl.c, linked to libcholmod).

    Returns:
        The cffi module (``.lib``, ``.ffi``), or None if it cannot be built here (SuperLU is
        used then).
    """
    return CHOLMOD.load()


def ldl_numpy(A: np.ndarray, perm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A[perm][:, perm] = L diag(D) L^T by numpy's dense Cholesky factorisation (the
    reference of ``Factor``).

    Args:
        A: a symmetric positive definite matrix, dense (n x n).
        perm: the dof at each position.

    Returns:
        (L, D): L dense unit lower (n x n), D the pivots (n).

    Raises:
        numpy.linalg.LinAlgError: if A is not positive definite.
    """
    C = np.linalg.cholesky(np.asarray(A)[np.ix_(perm, perm)])
    c = np.diag(C)
    return C / c, c * c


class NotPositiveDefinite(RuntimeError):
    """CHOLMOD found the matrix not positive definite."""


class Factor:
    """A[perm][:, perm] = L diag(D) L^T for a symmetric positive definite A (CSR arrays; only
    the lower triangle is read) by CHOLMOD's supernodal Cholesky in the given order, the last
    m positions being Gamma3's.  Kept for the split solve (kernels.GLastSolve) and the Schur
    complement: ``D``, ``L_GG`` (dense unit lower, m x m) and ``blocks`` = (bs, nbc, Bp, Bi,
    Bx, Ld), the interior columns of L in bs x bs blocks.  Bx is written over CHOLMOD's own
    value array where that is safe (it is for the nodal orders of schur.py): no copy of the
    factor at all, so the factor's memory is touched once; it lives as
    long as this object.  ``in_place=False`` (or an order where it is not safe) copies the
    blocks into a new array and frees CHOLMOD's factor; ``blocks=False`` keeps D and L_GG
    only.  Numpy reference: ``ldl_numpy``.

    Args:
        module: the CHOLMOD wrapper (``load()``).
        indptr, indices, data: A's CSR arrays (a symmetric CSR matrix is its own CSC).
        perm: the dof at each position (Gamma3's m dofs last).
        m: the number of Gamma3 dofs.
        bs: the dofs per node (the block size where the interior is whole nodes).
        in_place: write the blocks over CHOLMOD's value array where that is safe.
        blocks: build the blocks of the interior columns (else D and L_GG only).

    Raises:
        NotPositiveDefinite: if A is not positive definite.
        RuntimeError: if CHOLMOD fails otherwise (or changes the order).
        MemoryError: if the blocks cannot be allocated.
    """

    def __init__(self, module, indptr, indices, data, perm: np.ndarray, m: int, bs: int = 1,
                 in_place: bool = True, blocks: bool = True):
        ffi, lib, buf = module.ffi, module.lib, kernels.buf
        i = np.intc
        n = len(indptr) - 1
        Ap, Ai = np.ascontiguousarray(indptr, dtype=i), np.ascontiguousarray(indices, dtype=i)
        Ax = np.ascontiguousarray(data, dtype=float)
        P = np.ascontiguousarray(perm, dtype=i)
        status = ffi.new("int *")
        h = lib.ldl_factor(n, buf(ffi, Ap), buf(ffi, Ai), buf(ffi, Ax), buf(ffi, P), status)
        if h == ffi.NULL:
            if status[0] == 1:
                raise NotPositiveDefinite("CHOLMOD: the matrix is not positive definite")
            raise RuntimeError(f"CHOLMOD L L^T failed (status {status[0]})")
        handle = ffi.gc(h, lib.ldl_free)
        ni = n - m
        bs = kernels.block_size(bs, ni)
        nbc, nbr = ni // bs, -(-n // bs)
        # L_GG in Fortran order: the kernel writes each column's rows in turn (C is then
        # L_GG D_G^1/2 without a transposing copy, schur._schur_pair_cholesky)
        self.D, self.L_GG = np.empty(n), np.zeros((m, m), order="F")
        LGG_buffer = self.L_GG.T                          # C-contiguous: the same memory
        Bp = np.zeros(nbc + 1, dtype=i)
        mark, slot = np.full(nbr, -1, dtype=i), np.empty(nbr, dtype=i)
        safe = lib.ldl_blocks_super(h, bs, nbc, m, buf(ffi, Bp), ffi.NULL, ffi.NULL, ffi.NULL,
                                    buf(ffi, self.D), buf(ffi, LGG_buffer), buf(ffi, mark),
                                    buf(ffi, slot))
        if safe < 0:
            raise MemoryError("CHOLMOD factor: out of memory")
        in_place = in_place and safe == 1
        self.in_place, self._handle, self.blocks = False, None, None
        if not blocks:                  # D and L_GG only (the Schur complement of mpirun)
            return
        np.cumsum(Bp, out=Bp)
        b2, nnzb = bs * bs, int(Bp[-1])
        Bi, Ld = np.empty(max(nnzb, 1), dtype=i), np.zeros(max(nbc, 1) * b2)
        if in_place:
            Bx = np.frombuffer(ffi.buffer(lib.ldl_values(h), max(nnzb, 1) * b2 * 8),
                               dtype=float)
        else:
            Bx = np.empty(max(nnzb, 1) * b2)
        mark.fill(-1)
        if lib.ldl_blocks_super(h, bs, nbc, m, buf(ffi, Bp), buf(ffi, Bi), buf(ffi, Bx),
                                buf(ffi, Ld), buf(ffi, self.D), buf(ffi, LGG_buffer),
                                buf(ffi, mark), buf(ffi, slot)) < 0:
            raise MemoryError("CHOLMOD factor: out of memory")
        self.in_place = bool(in_place)
        self._handle = handle if in_place else None     # else freed with the last reference
        self.blocks = (bs, nbc, Bp, Bi, Bx, Ld)
