"""K = L D L^T by CHOLMOD (SuiteSparse, Debian's libsuitesparse-dev) in a given order.

The fast solver factorises the symmetric positive definite elasticity matrix once per run
with the Gamma3 dofs ordered last (schur.py).  SuperLU (scipy) computes L and U, twice the
work of a Cholesky factorisation; CHOLMOD's supernodal Cholesky L L^T gives the same L D L^T
(L_ldl = L D^-1/2, D = diag(L)^2) in a fraction of the time (at h = 1/128, 33,282 dofs: see
schur.GLastLDL).  The order is the caller's: CHOLMOD_GIVEN without postordering, and the
factor's permutation is checked against it.  The supernodal factor is not converted to
CHOLMOD's simplicial form: its interior columns go straight into the node blocks of the
split solve (kernels.GLastSolve), written over CHOLMOD's own value array, and the trailing
Gamma3 block L_GG is read out densely (at h = 1/128: 13 ms of conversion, 33 + 22 MB of
fresh memory and 30-50 ms of block building from the simplicial copy saved; set-up faults
18.3k -> 11.0k, measured).

The wrapper is compiled with cffi like kernels.py and linked to libcholmod; where that is
not possible (no headers, no compiler) ``load`` returns None and SuperLU is used.
"""
from __future__ import annotations

import numpy as np

from app.solvers import kernels

CDEF = """
void *ldl_factor(int n, const int *Ap, const int *Ai, const double *Ax, const int *perm,
                 int *status);
int ldl_blocks_super(void *handle, int bs, int nbc, int m, int *Bp, int *Bi, double *Bx,
                     double *Ld, double *D, double *LGG, int *mark, int *slot);
double *ldl_values(void *handle);
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
   = P^T L L^T P, CHOLMOD's supernodal factor, in the given order perm (position j <- dof
   perm[j]).  status: 0 ok, 1 not positive definite, 2 CHOLMOD changed the order,
   3 CHOLMOD failed. */
void *ldl_factor(int n, const int *Ap, const int *Ai, const double *Ax, const int *perm,
                 int *status)
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
    h->c.supernodal = CHOLMOD_SUPERNODAL;     /* kept as it is: no simplicial copy */
    h->c.final_asis = 1;
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
    if (h->c.status < CHOLMOD_OK || !h->L->is_super || !h->L->is_ll) {
        ldl_free(h); return NULL;
    }
    *status = 0;
    return h;
}

/* CHOLMOD's value array of the supernodal factor (xsize doubles). */
double *ldl_values(void *handle)
{
    return ((ldl_handle *)handle)->L->x;
}

/* The L D L^T form of the supernodal L L^T (L_ldl = L D^-1/2, D = diag(L)^2): D (n), the
   dense unit lower L_GG of the last m columns (row-major), and the first nbc block columns
   (bs columns each) in the block form of kernels.ldl_blocks (Bp, Bi, Bx, Ld; exact zeros,
   e.g. of CHOLMOD's relaxed supernodes, skipped).  Supernode sn holds the columns
   super[sn] .. super[sn+1]-1 as a dense column-major panel of nsrow = pi[sn+1] - pi[sn]
   rows s[pi[sn]..] (the diagonal block's rows first) at x + px[sn].
   With Bi == NULL it only counts: D, L_GG, Bp[J + 1] = the blocks of column J, and returns
   1 if Bx may be CHOLMOD's own value array (every block column's blocks end before the next
   column's panel starts, so the values are read before they are overwritten), else 0.
   Then the caller makes Bp cumulative, and calls again with Bi (Bx: a new array, or
   ldl_values()).  mark, slot: one int per block row, all -1 on entry.  Returns -1 if out
   of memory. */
int ldl_blocks_super(void *handle, int bs, int nbc, int m, int *Bp, int *Bi, double *Bx,
                     double *Ld, double *D, double *LGG, int *mark, int *slot)
{
    const cholmod_factor *L = ((ldl_handle *)handle)->L;
    const int n = (int)L->n, nsuper = (int)L->nsuper, ni = n - m, b2 = bs * bs;
    const int *super = L->super, *pi = L->pi, *px = L->px, *s = L->s;
    double *x = L->x;
    int *sn_of = malloc((size_t)n * sizeof(int)), maxrow = 0;
    if (!sn_of) return -1;
    for (int sn = 0; sn < nsuper; ++sn) {
        for (int j = super[sn]; j < super[sn + 1]; ++j) sn_of[j] = sn;
        if (pi[sn + 1] - pi[sn] > maxrow) maxrow = pi[sn + 1] - pi[sn];
    }
#define COLUMN(j, sn, off, nsrow) const int sn = sn_of[j], off = (j) - super[sn],         \
    nsrow = pi[sn + 1] - pi[sn]
    int in_place = 1;
    if (!Bi) {
        for (int j = 0; j < n; ++j) {                       /* D, L_GG */
            COLUMN(j, sn, off, nsrow);
            const double *v = x + px[sn] + (size_t)off * nsrow;
            const double ljj = v[off];
            D[j] = ljj * ljj;
            if (j >= ni)
                for (int q = off; q < nsrow; ++q)
                    LGG[(size_t)(s[pi[sn] + q] - ni) * m + (j - ni)] = q == off ? 1.0
                                                                       : v[q] / ljj;
        }
        long out = 0;
        for (int J = 0; J < nbc; ++J) {
            int count = 0;
            for (int a = 0; a < bs; ++a) {
                const int j = bs * J + a;
                COLUMN(j, sn, off, nsrow);
                const double *v = x + px[sn] + (size_t)off * nsrow;
                for (int q = off + 1; q < nsrow; ++q) {
                    const int I = s[pi[sn] + q] / bs;
                    if (I == J || v[q] == 0.0 || mark[I] == J) continue;
                    mark[I] = J;
                    ++count;
                }
            }
            Bp[J + 1] = count;
            out += (long)count * b2;
            if (bs * (J + 1) < n) {                         /* the next column's panel */
                const int j = bs * (J + 1);
                COLUMN(j, sn, off, nsrow);
                in_place &= out <= (long)px[sn] + (long)off * nsrow;
            }
        }
        free(sn_of);
        return in_place;
    }
    /* fill: each block column's values are copied out first (they may be overwritten) */
    double *tv = malloc((size_t)bs * maxrow * sizeof(double)), tl[3];
    int *tr = malloc((size_t)bs * maxrow * sizeof(int)), tn[3];
    if (!tv || !tr) { free(sn_of); free(tv); free(tr); return -1; }
    for (int J = 0; J < nbc; ++J) {
        for (int a = 0; a < bs; ++a) {
            const int j = bs * J + a;
            COLUMN(j, sn, off, nsrow);
            const double *v = x + px[sn] + (size_t)off * nsrow;
            tl[a] = v[off];
            tn[a] = nsrow - off - 1;
            for (int q = off + 1; q < nsrow; ++q) {
                tr[a * maxrow + q - off - 1] = s[pi[sn] + q];
                tv[a * maxrow + q - off - 1] = v[q];
            }
        }
        for (size_t q = (size_t)Bp[J] * b2; q < (size_t)Bp[J + 1] * b2; ++q) Bx[q] = 0.0;
        int count = 0;
        for (int a = 0; a < bs; ++a)
            for (int q = 0; q < tn[a]; ++q) {
                const int i = tr[a * maxrow + q], I = i / bs, b = i - bs * I;
                const double raw = tv[a * maxrow + q], val = raw / tl[a];
                if (I == J) {                       /* the diagonal block: b > a */
                    Ld[(size_t)J * b2 + a * bs + b] = val;
                    continue;
                }
                if (raw == 0.0) continue;           /* as counted */
                if (mark[I] != J) {
                    mark[I] = J;
                    slot[I] = Bp[J] + count;
                    Bi[Bp[J] + count] = I;
                    ++count;
                }
                Bx[(size_t)slot[I] * b2 + a * bs + b] = val;
            }
    }
#undef COLUMN
    free(sn_of); free(tv); free(tr);
    return 0;
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
    the lower triangle is read) by CHOLMOD's supernodal Cholesky in the given order, the last
    m positions being Gamma3's.  Kept for the split solve (kernels.GLastSolve) and the Schur
    complement: ``D``, ``L_GG`` (dense unit lower, m x m) and ``blocks`` = (bs, nbc, Bp, Bi,
    Bx, Ld), the interior columns of L in bs x bs blocks.  Bx is written over CHOLMOD's own
    value array where that is safe (it is for the nodal orders of schur.py): no copy of the
    factor at all, so the factor's memory (22 MB at h = 1/128) is touched once; it lives as
    long as this object.  ``in_place=False`` (or an order where it is not safe) copies the
    blocks into a new array and frees CHOLMOD's factor; ``blocks=False`` keeps D and L_GG
    only."""

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
        self.D, self.L_GG = np.empty(n), np.zeros((m, m))
        Bp = np.zeros(nbc + 1, dtype=i)
        mark, slot = np.full(nbr, -1, dtype=i), np.empty(nbr, dtype=i)
        safe = lib.ldl_blocks_super(h, bs, nbc, m, buf(ffi, Bp), ffi.NULL, ffi.NULL, ffi.NULL,
                                    buf(ffi, self.D), buf(ffi, self.L_GG), buf(ffi, mark),
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
                                buf(ffi, Ld), buf(ffi, self.D), buf(ffi, self.L_GG),
                                buf(ffi, mark), buf(ffi, slot)) < 0:
            raise MemoryError("CHOLMOD factor: out of memory")
        self.in_place = bool(in_place)
        self._handle = handle if in_place else None     # else freed with the last reference
        self.blocks = (bs, nbc, Bp, Bi, Bx, Ld)
