/* The projected Newton direction of the condensed solver's Gamma3 problem by LAPACK
   (app/solvers/dense.py: NewtonDirection, whose numpy reference is NewtonDirection._numpy). */
#include <stddef.h>

#include "dense.h"

/* LAPACK's Cholesky factorisation and solve (Fortran calling convention). */
void dpotrf_(const char *uplo, const int *n, double *a, const int *lda, int *info, size_t);
void dpotrs_(const char *uplo, const int *n, const int *nrhs, const double *a, const int *lda,
             double *b, const int *ldb, int *info, size_t);

/* BLAS's triangular solves (Fortran calling convention). */
void dtrsv_(const char *uplo, const char *trans, const char *diag, const int *n,
            const double *a, const int *lda, double *x, const int *incx, size_t, size_t,
            size_t);
void strsv_(const char *uplo, const char *trans, const char *diag, const int *n,
            const float *a, const int *lda, float *x, const int *incx, size_t, size_t, size_t);

/* cholesky_solve_d, cholesky_solve_s (dense.h): C y = x, then C^T x = y. */
void cholesky_solve_d(int m, const double *C, double *x)
{
    const int one = 1;
    dtrsv_("L", "N", "N", &m, C, &m, x, &one, 1, 1, 1);
    dtrsv_("L", "T", "N", &m, C, &m, x, &one, 1, 1, 1);
}

void cholesky_solve_s(int m, const float *C, float *x)
{
    const int one = 1;
    strsv_("L", "N", "N", &m, C, &m, x, &one, 1, 1, 1);
    strsv_("L", "T", "N", &m, C, &m, x, &one, 1, 1, 1);
}

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
