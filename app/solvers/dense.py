"""The projected Newton direction of the fast solver's Gamma3 problem (fastsolver.py).

Each Newton iteration of the step problem on Gamma3 solves
    (S + W)_ff p_f = -g_f,   p = 0 on the binding dofs,
with S the (dense, m x m) Schur complement, W the nodal d x d Hessian blocks of the contact
energy and f the free dofs (not held at the bound u_nu <= g).  The matrix is positive
definite where the step energy is strictly convex ((2.6)), so it is factorised by Cholesky.

The compiled version (cffi, LAPACK's dpotrf/dpotrs) gathers the free block straight from S
and the nodal blocks, so only the nf x nf block is built and factorised; at h = 1/128
(m = 258, about 180 free dofs) that is a third of the flops of factorising the whole m x m
matrix with the binding rows replaced by the identity, and no copy of S per iteration.
Without a C compiler or LAPACK the same direction is computed with numpy.
"""
from __future__ import annotations

import numpy as np

from app.solvers import kernels

CDEF = """
int newton_direction(int m, int d, const double *S, const double *W, const int *free_,
                     int nf, const double *g, double *p, double *work);
"""

SOURCE = r"""
#include <stddef.h>

void dpotrf_(const char *uplo, const int *n, double *a, const int *lda, int *info, size_t);
void dpotrs_(const char *uplo, const int *n, const int *nrhs, const double *a, const int *lda,
             double *b, const int *ldb, int *info, size_t);

/* p = 0, then p_f = -(S + W)_ff^-1 g_f for the nf free dofs free_ (ascending; S: m x m,
   symmetric; W: the nodal blocks, W[(i/d) d^2 + (i%d) d + j%d] couples dofs i, j of one
   node).  The lower triangle of the free block is gathered into work (nf x nf, column
   major) and factorised there.  Returns LAPACK's info: 0, or > 0 if the free block is not
   positive definite (then p is 0). */
int newton_direction(int m, int d, const double *S, const double *W, const int *free_,
                     int nf, const double *g, double *p, double *work)
{
    for (int i = 0; i < m; ++i) p[i] = 0.0;
    if (nf == 0) return 0;
    for (int b = 0; b < nf; ++b) {
        const double *Sb = S + (size_t)free_[b] * m;           /* column = row (symmetric) */
        double *col = work + (size_t)b * nf;
        for (int a = b; a < nf; ++a) col[a] = Sb[free_[a]];
    }
    for (int a = 0; a < nf; ++a) {                        /* the nodal blocks, lower part */
        const int i = free_[a], node = i / d;
        for (int b = a; b >= 0 && free_[b] / d == node; --b) {
            const int j = free_[b];
            work[(size_t)b * nf + a] += W[(size_t)node * d * d + (i % d) * d + j % d];
        }
    }
    int info = 0, one = 1;
    dpotrf_("L", &nf, work, &nf, &info, 1);
    if (info != 0) return info;
    double *rhs = work + (size_t)nf * nf;
    for (int a = 0; a < nf; ++a) rhs[a] = -g[free_[a]];
    dpotrs_("L", &nf, &one, work, &nf, rhs, &nf, &info, 1);
    if (info != 0) return info;
    for (int a = 0; a < nf; ++a) p[free_[a]] = rhs[a];
    return 0;
}
"""


def load():
    """The compiled Newton direction (``.lib``, ``.ffi``), or None (numpy is used then)."""
    return kernels.compiled("_vpcontact_dense", CDEF, SOURCE,
                            "compiled Newton direction (using numpy)", libraries=["lapack"])


class NewtonDirection:
    """p = -(S + W)_ff^-1 g_f on the free dofs, 0 on the binding ones, for a fixed S."""

    def __init__(self, S: np.ndarray, d: int, module=None):
        self.S, self.d, self.m = np.ascontiguousarray(S, dtype=float), d, S.shape[0]
        self.mod = module
        self.p = np.empty(self.m)
        self.work = np.empty(self.m * (self.m + 1))
        m, n = self.m, self.m // d
        node = np.repeat(np.arange(n), d * d)         # numpy: (row, column) of every W entry
        a, b = np.tile(np.repeat(np.arange(d), d), n), np.tile(np.arange(d), d * n)
        self._rows, self._cols = node * d + a, node * d + b
        if module is not None:
            self._S, self._p, self._work = (kernels.buf(module.ffi, x)
                                            for x in (self.S, self.p, self.work))

    def __call__(self, W: np.ndarray, g: np.ndarray, binding: np.ndarray) -> np.ndarray | None:
        """The direction (a new array), or None if (S + W)_ff is not positive definite."""
        free = np.flatnonzero(~binding).astype(np.intc)
        if self.mod is not None:
            ffi, buf = self.mod.ffi, kernels.buf
            info = self.mod.lib.newton_direction(
                self.m, self.d, self._S, buf(ffi, np.ascontiguousarray(W, dtype=float)),
                buf(ffi, free), len(free), buf(ffi, np.ascontiguousarray(g, dtype=float)),
                self._p, self._work)
            return None if info != 0 else self.p.copy()
        return self._numpy(W, g, free)

    def matrix(self, W: np.ndarray) -> np.ndarray:
        """S + W (a new m x m array)."""
        H = self.S.copy()
        H[self._rows, self._cols] += np.asarray(W).ravel()
        return H

    def _numpy(self, W, g, free):
        H = self.matrix(W)[np.ix_(free, free)]
        p = np.zeros(self.m)
        try:
            L = np.linalg.cholesky(H)
        except np.linalg.LinAlgError:
            return None
        p[free] = -np.linalg.solve(L.T, np.linalg.solve(L, g[free]))
        return p
