"""K = L D L^T by CHOLMOD (SuiteSparse, Debian's libsuitesparse-dev) in a given order.

The fast solver factorises the symmetric positive definite elasticity matrix once per run
with the Gamma3 dofs ordered last (schur.py).  SuperLU (scipy) computes L and U, twice the
work of a Cholesky factorisation; CHOLMOD's supernodal Cholesky, turned into the simplicial
L D L^T form at the end, gives the same L and D = diag(U) in a fraction of the time (at
h = 1/128, 33,282 dofs: see schur.GLastLDL).  The order is the caller's: CHOLMOD_GIVEN
without postordering, and the factor's permutation is checked against it.

The wrapper is compiled with cffi like kernels.py and linked to libcholmod; where that is
not possible (no headers, no compiler) ``load`` returns None and SuperLU is used.
"""
from __future__ import annotations

import numpy as np

from . import kernels

CDEF = """
void *ldl_factor(int n, const int *Ap, const int *Ai, const double *Ax, const int *perm,
                 long *nnz, int *status);
void ldl_arrays(void *handle, int **Lp, int **Li, double **Lx);
void ldl_free(void *handle);
"""

SOURCE = r"""
#include <stdlib.h>
#include <string.h>
#include <cholmod.h>

typedef struct { cholmod_common c; cholmod_factor *L; } ldl_handle;

void ldl_free(void *handle)
{
    ldl_handle *h = handle;
    if (!h) return;
    if (h->L) cholmod_free_factor(&h->L, &h->c);
    cholmod_finish(&h->c);
    free(h);
}

/* A (n x n, CSC; only its lower triangle is read: a symmetric CSR matrix is its own CSC)
   = P^T L D L^T P with the given order perm (position j <- dof perm[j]).  status: 0 ok,
   1 not positive definite, 2 CHOLMOD changed the order, 3 CHOLMOD failed. */
void *ldl_factor(int n, const int *Ap, const int *Ai, const double *Ax, const int *perm,
                 long *nnz, int *status)
{
    ldl_handle *h = calloc(1, sizeof *h);
    *status = 3;
    if (!h) return NULL;
    cholmod_start(&h->c);
    h->c.print = 0;
    h->c.error_handler = NULL;
    h->c.nmethods = 1;
    h->c.method[0].ordering = CHOLMOD_GIVEN;
    h->c.postorder = 0;                       /* keep the given order (Gamma3 last) */
    h->c.final_ll = 0;                        /* L D L^T, unit diagonal L ... */
    h->c.final_super = 0;                     /* ... simplicial, packed, monotonic CSC */
    h->c.final_pack = 1;
    h->c.final_monotonic = 1;
    cholmod_sparse A;
    memset(&A, 0, sizeof A);
    A.nrow = A.ncol = n;
    A.nzmax = Ap[n];
    A.p = (void *)Ap; A.i = (void *)Ai; A.x = (void *)Ax;
    A.stype = -1;
    A.itype = CHOLMOD_INT; A.xtype = CHOLMOD_REAL; A.dtype = CHOLMOD_DOUBLE;
    A.sorted = 1; A.packed = 1;
    h->L = cholmod_analyze_p(&A, (int *)perm, NULL, 0, &h->c);
    if (!h->L || h->c.status < CHOLMOD_OK) { ldl_free(h); return NULL; }
    const int *P = h->L->Perm;
    for (int j = 0; j < n; ++j)
        if (P[j] != perm[j]) { *status = 2; ldl_free(h); return NULL; }
    cholmod_factorize(&A, h->L, &h->c);
    if (h->c.status == CHOLMOD_NOT_POSDEF || h->L->minor < (size_t)n) {
        *status = 1; ldl_free(h); return NULL;
    }
    if (h->c.status < CHOLMOD_OK) { ldl_free(h); return NULL; }
    if (h->L->is_super || h->L->is_ll || !h->L->is_monotonic)
        cholmod_change_factor(CHOLMOD_REAL, 0, 0, 1, 1, h->L, &h->c);
    if (h->c.status < CHOLMOD_OK || h->L->is_super || h->L->is_ll) { ldl_free(h); return NULL; }
    *nnz = ((const int *)h->L->p)[n];
    *status = 0;
    return h;
}

/* The arrays of L (unit lower, with D stored on its diagonal, CSC: the simplicial L D L^T
   form), in place: valid until ldl_free(handle). */
void ldl_arrays(void *handle, int **Lp, int **Li, double **Lx)
{
    ldl_handle *h = handle;
    *Lp = h->L->p;
    *Li = h->L->i;
    *Lx = h->L->x;
}
"""


def load():
    """The CHOLMOD wrapper, or None if it cannot be built here (SuperLU is used then)."""
    return kernels.compiled("_vpcontact_cholmod", CDEF, SOURCE,
                            "CHOLMOD L D L^T (using SuperLU)",
                            include_dirs=["/usr/include/suitesparse"], libraries=["cholmod"])


class NotPositiveDefinite(RuntimeError):
    pass


class Factor:
    """A[perm][:, perm] = L diag(D) L^T for a symmetric positive definite A (CSR arrays; only
    the lower triangle is read), by CHOLMOD in the given order.  ``Lp``, ``Li``, ``Lx``: L in
    CSC, unit diagonal, viewed in place in CHOLMOD's memory (no copy of the 2.7 million
    entries at h = 1/128: 45 ms, measured), so they are valid only while this object lives;
    ``D``: the pivots (a copy).  The memory is freed with the object."""

    def __init__(self, module, indptr, indices, data, perm: np.ndarray):
        ffi, lib, buf = module.ffi, module.lib, kernels.buf
        i = np.intc
        n = len(indptr) - 1
        Ap, Ai = np.ascontiguousarray(indptr, dtype=i), np.ascontiguousarray(indices, dtype=i)
        Ax = np.ascontiguousarray(data, dtype=float)
        P = np.ascontiguousarray(perm, dtype=i)
        nnz, status = ffi.new("long *"), ffi.new("int *")
        h = lib.ldl_factor(n, buf(ffi, Ap), buf(ffi, Ai), buf(ffi, Ax), buf(ffi, P), nnz,
                           status)
        if h == ffi.NULL:
            if status[0] == 1:
                raise NotPositiveDefinite("CHOLMOD: the matrix is not positive definite")
            raise RuntimeError(f"CHOLMOD L D L^T failed (status {status[0]})")
        self._handle = ffi.gc(h, lib.ldl_free)
        p, r, x = ffi.new("int **"), ffi.new("int **"), ffi.new("double **")
        lib.ldl_arrays(h, p, r, x)
        size = np.dtype(i).itemsize
        self.n = n
        self.Lp = np.frombuffer(ffi.buffer(p[0], (n + 1) * size), dtype=i)
        self.Li = np.frombuffer(ffi.buffer(r[0], nnz[0] * size), dtype=i)
        self.Lx = np.frombuffer(ffi.buffer(x[0], nnz[0] * 8), dtype=float)
        diagonal = self.Lp[:-1]                # monotonic, sorted: the diagonal comes first
        self.D = self.Lx[diagonal].copy()
        if not np.all(self.D > 0):             # a simplicial L D L^T does not stop at these
            raise NotPositiveDefinite("CHOLMOD: the matrix is not positive definite")
        self.Lx[diagonal] = 1.0
