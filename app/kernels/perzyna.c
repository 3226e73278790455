/* The explicit Perzyna update of the history terms (3.2)-(3.3), vectorised across cells.
   The numpy reference is app/model/viscoplastic.py (ExplicitUpdate of Perzyna.rates, with
   material.VonMisesProjection); tests/unit/test_kernels.py compares them. */
#include <math.h>
#include <stddef.h>

#include "cells.h"
#include "perzyna.h"

/* The explicit Perzyna update (3.2)-(3.3) of every cell c, in the coordinates t of
   material.py (m = 3 in 2D, 6 in 3D; sigma, H: d x d row-major per cell, dd = d*d):
     e = t - P t,  P = projection onto {||tau||_VM <= kappa_c} in the energy inner product,
     H_c += k (-1/(2 l1)) E e,   kappa_c += k 2/(3 l2) ||e||_VM.
   The projection is VonMisesProjection's: z = V^T A s / ||s||_VM, the root mu of the secular
   equation q(mu) = sum lam_j z_j^2 / (1 + mu lam_j)^2 = kappa^2 / ||s||_VM^2 by Newton from
   its lower bound (or from mu_start[c], the cell's root of the last call, if larger),
   P s = ||s||_VM V diag(1 / (1 + mu lam)) z.  Rows are scaled by their largest entry first
   (P is positively homogeneous), so nothing overflows.  Equal eigenvalues are grouped
   (glam: the ng distinct ones; GM[g][j] = 1 if lam_j is in group g, else 0).
   Every pass runs over all cells without branches (selects instead), on a structure of
   arrays Z (ncells doubles per field), so that the compiler vectorises them across cells:
   3.1 -> 1.8 ms per call at h = 1/128 (32,768 cells), the same results bit for bit
   (measured against the earlier one-cell-at-a-time version).
   Returns the number of cells whose iteration did not converge in max_iter sweeps; then
   nothing is written (H, kappa keep the previous step's state).  Cells with non-finite data
   get NaN. */
/* perzyna_advance's arguments, for the threads that share its cells. */
struct perzyna_args {
    int ncells, dd, m;
    const double *sigma;
    double *H, *kappa;
    double k, l1, l2;
    const double *C, *M, *AV, *V, *lam;
    const int *flat, *from_;
    double rtol;
    int max_iter, ng;
    const double *glam, *GM;
    double *Z, *mu_start;
};

#define R *restrict
static inline __attribute__((always_inline)) int perzyna_impl(
        int c0, int c1, int phase, int ncells, int dd, int m, const double R sigma, double R H, double R kappa, double k,
        double l1, double l2, const double R C, const double R M, const double R AV,
        const double R V, const double R lam, const int R flat, const int R from_, double rtol,
        int max_iter, int ng, const double R glam, const double R GM, double R ZZ,
        double R CS, double R KR, double R IKR, double R MU, double R LB, double R ST,
        double R W, double R mu_start)
{
    double lam_max = 0.0;
    _Pragma("GCC unroll 9")
    for (int j = 0; j < m; ++j) if (lam[j] > lam_max) lam_max = lam[j];
    const size_t N = (size_t)ncells;
    const double kr_min = lam_max > 0.0 ? 1e-150 : INFINITY;
    if (phase == 2)                 /* the roots are known (phase 1 on these cells) */
        goto write;
    /* pass 1: the state of every cell (ST: 0 inside K(kappa), 1 outside and iterating,
       2 outside with kappa ~ 0, 3 not finite) and the secular equation's data */
    for (int c = c0; c < c1; ++c) {
        double t[6] = {0}, amax = 0.0, kap = kappa[c], nf = kap * 0.0;
        const double *s = sigma + (long)c * dd;
        _Pragma("GCC unroll 9")
        for (int i = 0; i < m; ++i) {
            t[i] = s[flat[i]];
            nf += t[i] * 0.0;                               /* NaN if anything is not finite */
            double a = fabs(t[i]);
            amax = a > amax ? a : amax;
        }
        double ia = 1.0 / amax, vm2 = 0.0;
        _Pragma("GCC unroll 9")
        for (int i = 0; i < m; ++i) t[i] *= ia;
        _Pragma("GCC unroll 9")
        for (int i = 0; i < m; ++i) {
            double Mt = 0.0;
            _Pragma("GCC unroll 9")
            for (int j = 0; j < m; ++j) Mt += M[i * m + j] * t[j];
            vm2 += Mt * t[i];
        }
        double kk = kap * ia;
        double sv = sqrt(vm2), cs = amax * sv, kr = kk / sv, isv = 1.0 / sv, w[6] = {0}, sw = 0.0;
        _Pragma("GCC unroll 9")
        for (int g = 0; g < ng; ++g) w[g] = 0.0;
        _Pragma("GCC unroll 9")
        for (int j = 0; j < m; ++j) {
            double acc = 0.0;
            _Pragma("GCC unroll 9")
            for (int i = 0; i < m; ++i) acc += t[i] * AV[i * m + j];
            double zj = acc * isv;
            ZZ[j * N + c] = zj;
            _Pragma("GCC unroll 9")
            for (int g = 0; g < ng; ++g) w[g] += GM[g * m + j] * (zj * zj);
        }
        _Pragma("GCC unroll 9")
        for (int g = 0; g < ng; ++g) { w[g] *= glam[g]; sw += w[g]; W[g * N + c] = w[g]; }
        /* the state: 3 not finite, 0 s = 0 or inside, 1 iterating, 2 kappa ~ 0 */
        double st = nf != 0.0 ? 3.0 : amax == 0.0 ? 0.0 : !(vm2 > kk * kk) ? 0.0
                    : kr > kr_min ? 1.0 : 2.0;
        double mu = (sqrt(sw) / kr - 1.0) / lam_max;
        mu = st == 1.0 ? (mu > 0.0 ? mu : 0.0) : 0.0;
        CS[c] = cs; KR[c] = kr; IKR[c] = 1.0 / kr; LB[c] = mu;
        double ms = mu_start[c];
        MU[c] = ms > mu ? ms : mu;
        ST[c] = st;
    }
    /* Newton sweeps on phi = q^-1/2 - 1/kappa over all cells, branch-free (a converged or
       non-iterating cell keeps its mu) */
    double left = 1.0;
    for (int it = 0; it < max_iter && left > 0.0; ++it) {
        left = 0.0;
        for (int c = c0; c < c1; ++c) {
            double mu = MU[c], q = 0.0, dq = 0.0, ikr = IKR[c];
            _Pragma("GCC unroll 9")
            for (int g = 0; g < ng; ++g) {
                double r = 1.0 / (1.0 + mu * glam[g]), tg = W[g * N + c] * r * r;
                q += tg;
                dq -= 2.0 * glam[g] * tg * r;
            }
            int conv = (ST[c] != 1.0) | (fabs(1.0 - q * ikr * ikr) <= 2.0 * rtol);
            double next = mu + 2.0 * q * (1.0 - sqrt(q) * ikr) / dq;
            next = next > LB[c] ? next : LB[c];
            MU[c] = conv ? mu : next;
            left += conv ? 0.0 : 1.0;
        }
    }
    return (int)left;          /* > 0: some cell did not converge (nothing is written) */
write:
    /* pass 2: e = s - P s, H += k (-1/(2 l1)) E e, kappa += k 2/(3 l2) ||e||_VM */
    const double a1 = -0.5 / l1, a2 = 2.0 / (3.0 * l2);
    double f0[6] = {0};                  /* kappa = 0: only the directions with lam = 0 */
    for (int gi = 0; gi < ng; ++gi) f0[gi] = glam[gi] == 0.0 ? 1.0 : 0.0;
    for (int c = c0; c < c1; ++c) {
        double st = ST[c], cs = CS[c], kr = KR[c], mu = MU[c];
        double f[6] = {0}, t[6] = {0}, e[6] = {0}, g[6] = {0}, fg[6] = {0};
        _Pragma("GCC unroll 9")
        for (int gi = 0; gi < ng; ++gi)
            fg[gi] = kr <= 1e-150 ? f0[gi] : 1.0 / (1.0 + mu * glam[gi]);
        _Pragma("GCC unroll 9")
        for (int j = 0; j < m; ++j) {
            double fj = 0.0;
            _Pragma("GCC unroll 9")
            for (int gi = 0; gi < ng; ++gi) fj += GM[gi * m + j] * fg[gi];
            f[j] = fj;
        }
        const double *s = sigma + (long)c * dd;
        _Pragma("GCC unroll 9")
        for (int j = 0; j < m; ++j) t[j] = s[flat[j]];
        _Pragma("GCC unroll 9")
        for (int r = 0; r < m; ++r) {
            double acc = 0.0;
            _Pragma("GCC unroll 9")
            for (int j = 0; j < m; ++j) acc += V[r * m + j] * ZZ[j * N + c] * f[j];
            e[r] = t[r] - acc * cs;
        }
        double evm2 = 0.0;
        _Pragma("GCC unroll 9")
        for (int r = 0; r < m; ++r) {
            double Ce = 0.0, Me = 0.0;
            _Pragma("GCC unroll 9")
            for (int j = 0; j < m; ++j) { Ce += C[r * m + j] * e[j]; Me += M[r * m + j] * e[j]; }
            g[r] = a1 * Ce;
            evm2 += Me * e[r];
        }
        /* st: 0 unchanged, 1 and 2 updated (3, not finite: set to NaN below) */
        _Pragma("GCC unroll 9")
        for (int j = 0; j < dd; ++j) {
            double h = H[(long)c * dd + j];
            double dh = k * g[from_[j]];
            H[(long)c * dd + j] = h + (st == 0.0 ? 0.0 : dh);
        }
        double kap = kappa[c], kn = kap + k * a2 * sqrt(evm2 > 0.0 ? evm2 : 0.0);
        kappa[c] = kap + (st == 0.0 ? 0.0 : kn - kap);
        mu_start[c] = st == 1.0 ? mu : mu_start[c];
    }
    for (int c = c0; c < c1; ++c)                     /* not finite: NaN */
            if (ST[c] == 3.0) {
                for (int j = 0; j < dd; ++j) H[(long)c * dd + j] = NAN;
                kappa[c] = NAN;
            }
    return 0;
}

#undef R

/* The t-coordinates of material.py (_FLAT, _FROM) as constants, so that the cell records are
   read and written with fixed offsets. */
static const int FLAT2[3] = {0, 3, 1}, FROM2[4] = {0, 2, 2, 1};
static const int FLAT3[6] = {0, 4, 8, 5, 2, 1}, FROM3[9] = {0, 5, 4, 5, 1, 3, 4, 3, 2};

/* 1 if the n ints of a and b are equal, else 0. */
static int same(const int *a, const int *b, int n)
{
    for (int i = 0; i < n; ++i) if (a[i] != b[i]) return 0;
    return 1;
}

/* perzyna_impl on the cells c0..c1-1 (phase 1: the states and the roots, returning the
   cells not converged; phase 2: the writes) with the 2D and 3D coordinates as constants where
   the arguments are those of material.py, else as given.
   The cell loops vectorise 4 wide with AVX2 where the CPU has it (chosen at load time);
   without FMA contraction (-std=c99), so both versions give the same results. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
__attribute__((target_clones("avx2", "default")))
#endif
static int perzyna_part(int c0, int c1, int phase, const struct perzyna_args *a)
{
    /* Z: z (m fields), then ||s||_VM, kappa/||s||_VM, its inverse, mu, mu's lower bound,
       the state, w (ng fields), ncells doubles each */
    const int m = a->m;
    const size_t N = (size_t)a->ncells;
    double *Z = a->Z;
#define PZ(DD, M_, FLAT, FROM, NG) \
    perzyna_impl(c0, c1, phase, a->ncells, DD, M_, a->sigma, a->H, a->kappa, a->k, a->l1, \
                 a->l2, a->C, a->M, a->AV, a->V, a->lam, FLAT, FROM, a->rtol, a->max_iter, NG, \
                 a->glam, a->GM, Z, Z + m * N, Z + (m + 1) * N, Z + (m + 2) * N, \
                 Z + (m + 3) * N, Z + (m + 4) * N, Z + (m + 5) * N, Z + (m + 6) * N, \
                 a->mu_start)
    const int dd = a->dd, ng = a->ng;
    int d2 = dd == 4 && m == 3 && same(a->flat, FLAT2, 3) && same(a->from_, FROM2, 4);
    int d3 = dd == 9 && m == 6 && same(a->flat, FLAT3, 6) && same(a->from_, FROM3, 9);
    if (d2 && ng == 2) return PZ(4, 3, FLAT2, FROM2, 2);
    if (d3 && ng == 2) return PZ(9, 6, FLAT3, FROM3, 2);
    if (d3 && ng == 3) return PZ(9, 6, FLAT3, FROM3, 3);
    return PZ(dd, m, a->flat, a->from_, ng);
#undef PZ
}

/* One thread's share: perzyna_part on its cells. */
struct perzyna_job {
    int c0, c1, phase, result;
    const struct perzyna_args *a;
};

static void *perzyna_job_run(void *arg)
{
    struct perzyna_job *job = arg;
    job->result = perzyna_part(job->c0, job->c1, job->phase, job->a);
    return NULL;
}

/* Both phases on the cells, on two threads (each half of the cells; one if a thread cannot
   be started) or on this one: a cell's result does not depend on the others, and nothing is
   written unless every cell converged. */
static int perzyna_run(const struct perzyna_args *a, int nthreads)
{
    const int n = a->ncells, half = n / 2;
    struct perzyna_job jobs[2] = {{0, half, 1, 0, a}, {half, n, 1, 0, a}};
    if (nthreads < 2 || half == 0) {
        int left = perzyna_part(0, n, 1, a);
        return left > 0 ? left : perzyna_part(0, n, 2, a);
    }
    for (int phase = 1; phase <= 2; ++phase) {
        jobs[0].phase = jobs[1].phase = phase;
        run_two(perzyna_job_run, &jobs[0], &jobs[1]);
        if (phase == 1 && jobs[0].result + jobs[1].result > 0)
            return jobs[0].result + jobs[1].result;
    }
    return 0;
}

/* perzyna_advance (perzyna.h). */
int perzyna_advance(int ncells, int dd, int m, const double *sigma, double *H, double *kappa,
                    double k, double l1, double l2, const double *C, const double *M,
                    const double *AV, const double *V, const double *lam, const int *flat,
                    const int *from_, double rtol, int max_iter, int ng, const double *glam,
                    const double *GM, double *Z, double *mu_start, int nthreads)
{
    const struct perzyna_args a = {ncells, dd, m, sigma, H, kappa, k, l1, l2, C, M, AV, V,
                                   lam, flat, from_, rtol, max_iter, ng, glam, GM, Z,
                                   mu_start};
    return perzyna_run(&a, nthreads);
}
