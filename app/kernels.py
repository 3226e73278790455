"""Compiled per-cell kernels (C, built once with cffi and cached like dolfinx's JIT forms).

At h = 1/128 the explicit Perzyna update of the 32,768 cells took 10 ms per step in numpy
(whole-array Newton iterations on the secular equation, temporaries): more than the two
back-substitutions of the fast solver.  The same algorithm as material.VonMisesProjection,
one cell at a time in C, takes well under a millisecond.  The numpy code stays the reference
(tests/unit/test_kernels.py compares them) and the fallback when no C compiler is available.

The build goes to $VPCONTACT_CACHE/kernels (default ~/.cache/vpcontact/kernels), keyed by a
hash of the C source; concurrent builds (mpirun ranks) write to private directories and
publish the library by an atomic rename.
"""
from __future__ import annotations

import hashlib
import importlib.util
import logging
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

log = logging.getLogger("vpcontact")

CDEF = """
int perzyna_advance(int ncells, int dd, int m, const double *sigma, double *H, double *kappa,
                    double k, double l1, double l2, const double *C, const double *M,
                    const double *AV, const double *V, const double *lam, const int *flat,
                    const int *from_, double rtol, int max_iter, int ng, const double *glam,
                    const int *group, int *act, int *todo, double *Z);
int ldl_blocks(int bs, int nbc, const int *Lp, const int *Li, const double *Lx, int *Bp,
               int *Bi, double *Bx, double *Ld, int *mark, int *slot);
void ldl_forward_interior(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                          const double *Ld, double *x);
void ldl_backward_given_tail(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                             const double *Ld, const double *dinv, double *x);
double nodal_contact(int n, int d, const double *y, const double *nu, double c,
                     const double *xi, const double *theta, int friction, double b, double c1,
                     double c2, double u1, double delta, const double *w, double *grad,
                     double *hess);
double cell_pass(int ncells, int d, const int *dofs, const double *Dx, const double *vol,
                 double lmbda, double two_mu, const double *u, const double *H, double *sigma,
                 double *vm, double *ss);
void cell_load(int ncells, int d, const int *dofs, const double *Dx, const double *H,
               double *b);
"""

SOURCE = r"""
#include <math.h>
#include <stddef.h>

/* The explicit Perzyna update (3.2)-(3.3) of every cell c, in the coordinates t of
   material.py (m = 3 in 2D, 6 in 3D; sigma, H: d x d row-major per cell, dd = d*d):
     e = t - P t,  P = projection onto {||tau||_VM <= kappa_c} in the energy inner product,
     H_c += k (-1/(2 l1)) E e,   kappa_c += k 2/(3 l2) ||e||_VM.
   The projection is VonMisesProjection's: z = V^T A s / ||s||_VM, the root mu of the secular
   equation q(mu) = sum lam_j z_j^2 / (1 + mu lam_j)^2 = kappa^2 / ||s||_VM^2 by Newton from
   its lower bound, P s = ||s||_VM V diag(1 / (1 + mu lam)) z.  Rows are scaled by their
   largest entry first (P is positively homogeneous), so nothing overflows.  Equal
   eigenvalues are grouped (glam: the ng distinct ones, group[j]: the group of lam_j).
   The Newton iterations run as sweeps over all cells still iterating, so the divisions of
   different cells overlap (one cell at a time, their latency made this 3x slower).
   Returns the number of cells whose iteration did not converge (their H, kappa: NaN). */
static inline __attribute__((always_inline)) int perzyna_impl(
                    int ncells, int dd, int m, const double *sigma, double *H, double *kappa,
                    double k, double l1, double l2, const double *C, const double *M,
                    const double *AV, const double *V, const double *lam, const int *flat,
                    const int *from_, double rtol, int max_iter, int ng, const double *glam,
                    const int *group, int *act, int *todo, double *Z)
{
    int failed = 0, nact = 0;
    double lam_max = 0.0;
    for (int j = 0; j < m; ++j) if (lam[j] > lam_max) lam_max = lam[j];
    /* work arrays (allocated once by the caller: fresh pages cost 2 ms per call here):
       act, todo: ncells ints; Z: per active cell a: z (m), ||s||_VM, kappa/||s||_VM, mu,
       w (ng), ncells * (m + 3 + ng) doubles */
    const int stride = m + 3 + ng;
    for (int c = 0; c < ncells; ++c) {
        double t[6];
        const double *s = sigma + (long)c * dd;
        double kap = kappa[c], amax = 0.0;
        int finite = isfinite(kap);
        for (int i = 0; i < m; ++i) {
            t[i] = s[flat[i]];
            finite = finite && isfinite(t[i]);
            if (fabs(t[i]) > amax) amax = fabs(t[i]);
        }
        if (!finite) {                                      /* propagate as NaN */
            for (int i = 0; i < dd; ++i) H[(long)c * dd + i] = NAN;
            kappa[c] = NAN;
            continue;
        }
        if (amax == 0.0) continue;                          /* s = 0 lies in K(kappa >= 0) */
        double ia = 1.0 / amax, vm2 = 0.0;                 /* ||s / amax||_VM^2 */
        for (int i = 0; i < m; ++i) t[i] *= ia;
        for (int i = 0; i < m; ++i) {
            double Mt = 0.0;
            for (int j = 0; j < m; ++j) Mt += M[i * m + j] * t[j];
            vm2 += Mt * t[i];
        }
        double kk = kap * ia;
        if (!(vm2 > kk * kk)) continue;                     /* inside: no viscoplastic flow */
        double *a = Z + (size_t)nact * stride;
        act[nact++] = c;
        double sv = sqrt(vm2), cs = amax * sv, kr = kk / sv;   /* ||s||_VM, kappa/||s||_VM */
        double isv = 1.0 / sv;
        double *z = a, *w = a + m + 3;
        for (int g = 0; g < ng; ++g) w[g] = 0.0;
        for (int j = 0; j < m; ++j) {
            double acc = 0.0;
            for (int i = 0; i < m; ++i) acc += t[i] * AV[i * m + j];
            z[j] = acc * isv;
            w[group[j]] += z[j] * z[j];
        }
        double sw = 0.0;
        for (int g = 0; g < ng; ++g) { w[g] *= glam[g]; sw += w[g]; }
        double mu = 0.0;
        if (kr > 1e-150 && lam_max > 0.0) {                 /* the root's lower bound */
            mu = (sqrt(sw) / kr - 1.0) / lam_max;
            if (mu < 0.0) mu = 0.0;
        }
        a[m] = cs; a[m + 1] = kr; a[m + 2] = mu;
    }
    /* Newton sweeps on phi = q^-1/2 - 1/kappa over the cells not yet converged */
    int ntodo = 0;
    for (int i = 0; i < nact; ++i)
        if (Z[(size_t)i * stride + m + 1] > 1e-150) todo[ntodo++] = i;
    for (int it = 0; it < max_iter && ntodo > 0; ++it) {
        int keep = 0;
        for (int i = 0; i < ntodo; ++i) {
            double *a = Z + (size_t)todo[i] * stride;
            const double *w = a + m + 3;
            double ikr = 1.0 / a[m + 1], mu = a[m + 2], q = 0.0, dq = 0.0;
            for (int g = 0; g < ng; ++g) {
                double r = 1.0 / (1.0 + mu * glam[g]), tg = w[g] * r * r;
                q += tg;
                dq -= 2.0 * glam[g] * tg * r;
            }
            if (fabs(1.0 - q * ikr * ikr) <= 2.0 * rtol) continue;      /* converged */
            a[m + 2] = mu + 2.0 * q * (1.0 - sqrt(q) * ikr) / dq;
            todo[keep++] = todo[i];
        }
        ntodo = keep;
    }
    for (int i = 0; i < ntodo; ++i) Z[(size_t)todo[i] * stride + m + 1] = NAN;   /* failed */
    failed = ntodo;
    for (int i = 0; i < nact; ++i) {
        const double *a = Z + (size_t)i * stride, *z = a;
        int c = act[i];
        double cs = a[m], kr = a[m + 1], mu = a[m + 2], f[6], t[6], e[6], g[6];
        if (isnan(kr)) {
            for (int j = 0; j < dd; ++j) H[(long)c * dd + j] = NAN;
            kappa[c] = NAN;
            continue;
        }
        double fg[6];
        for (int gi = 0; gi < ng; ++gi)  /* kappa = 0: only the directions with lam = 0 */
            fg[gi] = kr <= 1e-150 ? (glam[gi] == 0.0 ? 1.0 : 0.0) : 1.0 / (1.0 + mu * glam[gi]);
        for (int j = 0; j < m; ++j) f[j] = fg[group[j]];
        const double *s = sigma + (long)c * dd;
        for (int j = 0; j < m; ++j) t[j] = s[flat[j]];
        for (int r = 0; r < m; ++r) {                       /* e = s - P s */
            double acc = 0.0;
            for (int j = 0; j < m; ++j) acc += V[r * m + j] * z[j] * f[j];
            e[r] = t[r] - acc * cs;
        }
        double evm2 = 0.0;
        for (int r = 0; r < m; ++r) {
            double Ce = 0.0, Me = 0.0;
            for (int j = 0; j < m; ++j) { Ce += C[r * m + j] * e[j]; Me += M[r * m + j] * e[j]; }
            g[r] = (-0.5 / l1) * Ce;
            evm2 += Me * e[r];
        }
        for (int j = 0; j < dd; ++j) H[(long)c * dd + j] += k * g[from_[j]];
        kappa[c] += k * (2.0 / (3.0 * l2)) * sqrt(evm2 > 0.0 ? evm2 : 0.0);
    }
    return failed;
}

/* dd, m (and ng in 2D) as compile-time constants: the small loops unrolled (3x faster for
   the cell kernels below, measured) */
int perzyna_advance(int ncells, int dd, int m, const double *sigma, double *H, double *kappa,
                    double k, double l1, double l2, const double *C, const double *M,
                    const double *AV, const double *V, const double *lam, const int *flat,
                    const int *from_, double rtol, int max_iter, int ng, const double *glam,
                    const int *group, int *act, int *todo, double *Z)
{
#define PERZYNA_ARGS sigma, H, kappa, k, l1, l2, C, M, AV, V, lam, flat, from_, rtol, max_iter
    if (dd == 4 && m == 3 && ng == 2)
        return perzyna_impl(ncells, 4, 3, PERZYNA_ARGS, 2, glam, group, act, todo, Z);
    if (dd == 4 && m == 3)
        return perzyna_impl(ncells, 4, 3, PERZYNA_ARGS, ng, glam, group, act, todo, Z);
    if (dd == 9 && m == 6)
        return perzyna_impl(ncells, 9, 6, PERZYNA_ARGS, ng, glam, group, act, todo, Z);
    return perzyna_impl(ncells, dd, m, PERZYNA_ARGS, ng, glam, group, act, todo, Z);
#undef PERZYNA_ARGS
}

/* One solve with K = L D L^T (L unit lower, D diagonal), ordered interior first, G last
   (schur.GLastLU: SuperLU's K = L U without pivoting of the symmetric K, so U = D L^T to
   round-off and only L and D are kept).  The interior columns of L are stored in bs x bs
   blocks (bs = d: a node's dofs are consecutive in the nested-dissection order), which reads
   one index per block and half the factor of an L U sweep pair.
   Block k of block column J (block row I = Bi[k] > J, interior or G):
       Bx[k bs^2 + a bs + b] = L[bs I + b, bs J + a],
   and the strictly lower part of the diagonal block J: Ld[J bs^2 + a bs + b] = L[bs J + b, bs J + a].

   ldl_blocks: the block form of the first nbc block columns of L (CSC).  With Bi == NULL it
   only counts: Bp[J + 1] = the number of blocks of column J; then the caller makes Bp
   cumulative, zeroes Bx and Ld, and calls again to fill them.  mark, slot: one int per
   block row, mark all -1 on entry.  Exact zeros of L are skipped.  Returns the number of
   blocks. */
int ldl_blocks(int bs, int nbc, const int *Lp, const int *Li, const double *Lx, int *Bp,
               int *Bi, double *Bx, double *Ld, int *mark, int *slot)
{
    int nnzb = 0;
    const int b2 = bs * bs;
    for (int J = 0; J < nbc; ++J) {
        int count = 0;
        for (int a = 0; a < bs; ++a) {
            const int j = bs * J + a;
            for (int p = Lp[j]; p < Lp[j + 1]; ++p) {
                const int i = Li[p], I = i / bs, b = i - bs * I;
                if (Lx[p] == 0.0) continue;        /* e.g. CHOLMOD's relaxed supernodes */
                if (I == J) {
                    if (Bi && b > a) Ld[(long)J * b2 + a * bs + b] = Lx[p];
                    continue;
                }
                if (I < J) continue;
                if (mark[I] != J) {
                    mark[I] = J;
                    slot[I] = Bi ? Bp[J] + count : 0;
                    if (Bi) Bi[Bp[J] + count] = I;
                    ++count;
                }
                if (Bi) Bx[(long)slot[I] * b2 + a * bs + b] = Lx[p];
            }
        }
        if (!Bi) Bp[J + 1] = count;
        nnzb += count;
    }
    return nnzb;
}

/* forward over the interior: x_I <- L_II^-1 b_I, x_G <- b_G - L_GI x_I (= r) */
#define LDL_FORWARD(BS)                                                                    \
static void ldl_forward_##BS(int nbc, const int *Bp, const int *Bi, const double *Bx,     \
                             const double *Ld, double *x)                                  \
{                                                                                          \
    for (int J = 0; J < nbc; ++J) {                                                        \
        double *xJ = x + BS * J, t[BS];                                                    \
        const double *l = Ld + (long)J * BS * BS;                                          \
        for (int a = 0; a < BS; ++a) {                                                     \
            for (int b = 0; b < a; ++b) xJ[a] -= l[b * BS + a] * xJ[b];                    \
            t[a] = xJ[a];                                                                  \
        }                                                                                  \
        for (int k = Bp[J]; k < Bp[J + 1]; ++k) {                                          \
            const double *M = Bx + (long)k * BS * BS;                                      \
            double *xI = x + (long)BS * Bi[k];                                             \
            for (int b = 0; b < BS; ++b) {                                                 \
                double acc = 0.0;                                                          \
                for (int a = 0; a < BS; ++a) acc += M[a * BS + b] * t[a];                  \
                xI[b] -= acc;                                                              \
            }                                                                              \
        }                                                                                  \
    }                                                                                      \
}
/* backward with x_G given (the Gamma3 values): x_I <- L_II^-T (D_I^-1 x_I - L_GI^T x_G) */
#define LDL_BACKWARD(BS)                                                                   \
static void ldl_backward_##BS(int nbc, const int *Bp, const int *Bi, const double *Bx,    \
                              const double *Ld, const double *dinv, double *x)            \
{                                                                                          \
    for (int J = nbc - 1; J >= 0; --J) {                                                   \
        double *xJ = x + BS * J, t[BS], s[BS][BS];                                         \
        for (int a = 0; a < BS; ++a) {                                                     \
            t[a] = xJ[a] * dinv[BS * J + a];                                               \
            for (int b = 0; b < BS; ++b) s[a][b] = 0.0;    /* independent chains */        \
        }                                                                                  \
        for (int k = Bp[J]; k < Bp[J + 1]; ++k) {                                          \
            const double *M = Bx + (long)k * BS * BS, *xI = x + (long)BS * Bi[k];          \
            for (int a = 0; a < BS; ++a)                                                   \
                for (int b = 0; b < BS; ++b) s[a][b] += M[a * BS + b] * xI[b];             \
        }                                                                                  \
        for (int a = 0; a < BS; ++a)                                                       \
            for (int b = 0; b < BS; ++b) t[a] -= s[a][b];                                  \
        const double *l = Ld + (long)J * BS * BS;                                          \
        for (int a = BS - 1; a >= 0; --a) {                                                \
            for (int b = a + 1; b < BS; ++b) t[a] -= l[a * BS + b] * t[b];                 \
            xJ[a] = t[a];                                                                  \
        }                                                                                  \
    }                                                                                      \
}
LDL_FORWARD(1) LDL_FORWARD(2) LDL_FORWARD(3)
LDL_BACKWARD(1) LDL_BACKWARD(2) LDL_BACKWARD(3)

void ldl_forward_interior(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                          const double *Ld, double *x)
{
    if (bs == 2) ldl_forward_2(nbc, Bp, Bi, Bx, Ld, x);
    else if (bs == 3) ldl_forward_3(nbc, Bp, Bi, Bx, Ld, x);
    else ldl_forward_1(nbc, Bp, Bi, Bx, Ld, x);
}

void ldl_backward_given_tail(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                             const double *Ld, const double *dinv, double *x)
{
    if (bs == 2) ldl_backward_2(nbc, Bp, Bi, Bx, Ld, dinv, x);
    else if (bs == 3) ldl_backward_3(nbc, Bp, Bi, Bx, Ld, dinv, x);
    else ldl_backward_1(nbc, Bp, Bi, Bx, Ld, dinv, x);
}

/* The nodal contact energy of the fast solver's Gamma3 problem (fastsolver.NodalContact):
   E = sum_i w_i phi_i(y_i) with r = y.nu,
   phi = c/2 (r+)^2 + xi (r + sqrt(r^2 + delta^2))/2 + theta psi(sqrt(|y_tau|^2 + delta^2)),
   its gradient (n x d) and, if hess != NULL, the nodal Hessian blocks (n x d x d).
   xi, theta: NULL when the case has no memory term / no slip dependence (theta = 1);
   friction = 0: no friction term.  psi: law (4.2). */
double nodal_contact(int n, int d, const double *y, const double *nu, double c,
                     const double *xi, const double *theta, int friction, double b, double c1,
                     double c2, double u1, double delta, const double *w, double *grad,
                     double *hess)
{
    double energy = 0.0, d2 = delta * delta;
    for (int i = 0; i < n; ++i) {
        const double *yi = y + (long)i * d;
        double *gi = grad + (long)i * d, *Hi = hess ? hess + (long)i * d * d : NULL;
        double r = 0.0;
        for (int a = 0; a < d; ++a) r += yi[a] * nu[a];
        double rp = r > 0.0 ? r : 0.0;
        double e = 0.5 * c * rp * rp, dr = c * rp, hr = r > 0.0 ? c : 0.0;
        if (xi) {
            double sq = sqrt(r * r + d2);
            e += xi[i] * 0.5 * (r + sq);
            dr += xi[i] * 0.5 * (1.0 + r / sq);
            hr += xi[i] * 0.5 * d2 / (sq * sq * sq);
        }
        for (int a = 0; a < d; ++a) gi[a] = dr * nu[a];
        if (Hi)
            for (int a = 0; a < d; ++a)
                for (int bb = 0; bb < d; ++bb) Hi[a * d + bb] = hr * nu[a] * nu[bb];
        if (friction) {
            double tau[3], t2 = 0.0, th = theta ? theta[i] : 1.0;
            for (int a = 0; a < d; ++a) { tau[a] = yi[a] - r * nu[a]; t2 += tau[a] * tau[a]; }
            double rho = sqrt(t2 + d2), psi, d1, dd2;
            if (rho <= u1) {
                psi = b * rho - 0.5 * c1 * rho * rho; d1 = b - c1 * rho; dd2 = -c1;
            } else {
                double s = rho - u1;
                psi = 0.5 * c2 * s * s + (b - c1 * u1) * s + b * u1 - 0.5 * c1 * u1 * u1;
                d1 = c2 * s + b - c1 * u1; dd2 = c2;
            }
            e += th * psi;
            double f = th * d1 / rho;
            for (int a = 0; a < d; ++a) gi[a] += f * tau[a];
            if (Hi) {
                double ft = th * (dd2 / (rho * rho) - d1 / (rho * rho * rho));
                for (int a = 0; a < d; ++a)
                    for (int bb = 0; bb < d; ++bb)
                        Hi[a * d + bb] += ft * tau[a] * tau[bb]
                                          + f * ((a == bb ? 1.0 : 0.0) - nu[a] * nu[bb]);
            }
        }
        energy += w[i] * e;
        for (int a = 0; a < d; ++a) gi[a] *= w[i];
        if (Hi) for (int a = 0; a < d * d; ++a) Hi[a] *= w[i];
    }
    return energy;
}

/* The cell-strain operator (strain.StrainOperator) cell by cell: Dx holds its rows
   (D u)_c = |c| eps_c(u) per cell, dd = d*d rows of nd = (d+1) d entries at the cell's dofs.
   cell_pass: eps_c = (D u)_c / |c|, returns sum_c |c| eps_c : eps_c; if sigma != NULL also
   sigma_c = E eps_c + H_c (H == NULL: 0; E tau = lmbda tr(tau) I + two_mu tau),
   vm_c = ||sigma_c||_VM = sqrt(3/2 s:s - 1/2 tr(s)^2) (plane stress in 2D: sigma_33 = 0) and
   *ss = sum_c |c| sigma_c : sigma_c (the square of ||sigma||_Q). */
#define CELL_PASS(D)                                                                       \
static double cell_pass_##D(int ncells, const int *dofs, const double *Dx,                  \
                            const double *vol, double lmbda, double two_mu, const double *u, \
                            const double *H, double *sigma, double *vm, double *ss)          \
{                                                                                          \
    enum { DD = D * D, ND = (D + 1) * D };                                                 \
    double se = 0.0, sq = 0.0;                                                             \
    for (int c = 0; c < ncells; ++c) {                                                     \
        const int *dc = dofs + (long)c * ND;                                               \
        const double *Dc = Dx + (long)c * DD * ND;                                         \
        double uc[ND], e[DD], ee = 0.0;                                                    \
        for (int j = 0; j < ND; ++j) uc[j] = u[dc[j]];                                     \
        for (int q = 0; q < DD; ++q) {                                                     \
            double acc = 0.0;                                                              \
            for (int j = 0; j < ND; ++j) acc += Dc[q * ND + j] * uc[j];                    \
            e[q] = acc / vol[c];                                                           \
            ee += e[q] * e[q];                                                             \
        }                                                                                  \
        se += vol[c] * ee;                                                                 \
        if (!sigma) continue;                                                              \
        double tr = 0.0, s2 = 0.0, trs = 0.0, *sc = sigma + (long)c * DD;                  \
        for (int a = 0; a < D; ++a) tr += e[a * D + a];                                    \
        for (int q = 0; q < DD; ++q) sc[q] = two_mu * e[q] + (H ? H[(long)c * DD + q] : 0.0); \
        for (int a = 0; a < D; ++a) sc[a * D + a] += lmbda * tr;                           \
        for (int q = 0; q < DD; ++q) s2 += sc[q] * sc[q];                                  \
        for (int a = 0; a < D; ++a) trs += sc[a * D + a];                                  \
        double v2 = 1.5 * s2 - 0.5 * trs * trs;                                            \
        vm[c] = sqrt(v2 > 0.0 ? v2 : 0.0);                                                 \
        sq += vol[c] * s2;                                                                 \
    }                                                                                      \
    if (ss) *ss = sq;                                                                      \
    return se;                                                                             \
}
CELL_PASS(2) CELL_PASS(3)

double cell_pass(int ncells, int d, const int *dofs, const double *Dx, const double *vol,
                 double lmbda, double two_mu, const double *u, const double *H, double *sigma,
                 double *vm, double *ss)
{
    return d == 2 ? cell_pass_2(ncells, dofs, Dx, vol, lmbda, two_mu, u, H, sigma, vm, ss)
                  : cell_pass_3(ncells, dofs, Dx, vol, lmbda, two_mu, u, H, sigma, vm, ss);
}

/* b[dofs_c] += D_c^T H_c for every cell: b = D^T H = (H, eps(v)) for all v (local dofs). */
#define CELL_LOAD(D)                                                                       \
static void cell_load_##D(int ncells, const int *dofs, const double *Dx, const double *H,   \
                          double *b)                                                       \
{                                                                                          \
    enum { DD = D * D, ND = (D + 1) * D };                                                 \
    for (int c = 0; c < ncells; ++c) {                                                     \
        const int *dc = dofs + (long)c * ND;                                               \
        const double *Dc = Dx + (long)c * DD * ND, *Hc = H + (long)c * DD;                 \
        double r[ND];                                                                      \
        for (int j = 0; j < ND; ++j) r[j] = 0.0;                                           \
        for (int q = 0; q < DD; ++q)                                                       \
            for (int j = 0; j < ND; ++j) r[j] += Dc[q * ND + j] * Hc[q];                   \
        for (int j = 0; j < ND; ++j) b[dc[j]] += r[j];                                     \
    }                                                                                      \
}
CELL_LOAD(2) CELL_LOAD(3)

void cell_load(int ncells, int d, const int *dofs, const double *Dx, const double *H,
               double *b)
{
    if (d == 2) cell_load_2(ncells, dofs, Dx, H, b);
    else cell_load_3(ncells, dofs, Dx, H, b);
}
"""

_MODULES: dict[str, object] = {}


def cache_dir() -> Path:
    base = Path(os.environ.get("VPCONTACT_CACHE", Path.home() / ".cache" / "vpcontact"))
    return base / "kernels"


def _build(name: str, target: Path, cdef: str, source: str, **kwargs) -> None:
    import cffi
    ffi = cffi.FFI()
    ffi.cdef(cdef)
    ffi.set_source(name, source, extra_compile_args=["-O3", "-std=c99"], **kwargs)
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        built = Path(ffi.compile(tmpdir=tmp, verbose=False))
        os.replace(built, target)                      # atomic: other ranks see all or nothing


def compiled(prefix: str, cdef: str, source: str, what: str, **kwargs):
    """The cffi module of ``source`` (built once into cache_dir(), keyed by a hash of the
    source), or None if it cannot be built here (``what`` names it in the warning)."""
    digest = hashlib.sha256((cdef + source + repr(sorted(kwargs.items())) + sys.version)
                            .encode()).hexdigest()[:16]
    name = f"{prefix}_{digest}"
    if name in _MODULES:
        return _MODULES[name]
    target = cache_dir() / f"{name}.so"
    module = None
    try:
        if not target.exists():
            log.info("compiling %s into %s", what, target.parent)
            _build(name, target, cdef, source, **kwargs)
        spec = importlib.util.spec_from_file_location(name, target)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except Exception as exc:                            # no compiler (or library): fallback
        log.warning("%s unavailable (%s)", what, exc)
        module = None
    _MODULES[name] = module
    return module


def load():
    """The compiled cell kernels (``.lib``, ``.ffi``), or None (numpy is used then)."""
    return compiled("_vpcontact_kernels", CDEF, SOURCE, "compiled cell kernels (using numpy)",
                    libraries=["m"])


_CTYPES = {np.dtype(np.float64): "double[]", np.dtype(np.intc): "int[]"}


def buf(ffi, a: np.ndarray | None):
    """A C array argument for the contiguous numpy array ``a`` (float64 -> double *,
    intc -> int *), which it keeps alive; NULL for None."""
    if a is None:
        return ffi.NULL
    if a.dtype not in _CTYPES:
        raise TypeError(f"kernel arrays must be float64 or intc, not {a.dtype}")
    return ffi.from_buffer(_CTYPES[a.dtype], a)        # refuses non-contiguous arrays


class GLastSolve:
    """u = K^-1 (b + E_G lambda) in one forward and one backward sweep, with the Gamma3 values
    y = u_G found in between (fastsolver.py): with K = L D L^T ordered interior first, G last,
        forward:  z_I = L_II^-1 b_I,  r = b_G - L_GI z_I,
        Gamma3:   S u_G = r + lambda (S = L_GG D_G L_GG^T), i.e. y0 = S^-1 r without contact,
        backward: u_I = L_II^-T (D_I^-1 z_I - L_GI^T y).
    One factorisation serves the Schur complement and every step.  The interior columns of
    L are kept in bs x bs blocks (ldl_blocks; bs = 1 if the interior is not a whole number
    of blocks)."""

    def __init__(self, factor, module, bs: int = 1):
        self.mod, self.n, self.m = module, factor.n, factor.m
        self.ni = self.n - self.m
        self.bs = bs if bs in (1, 2, 3) and self.ni % bs == 0 else 1
        self.perm = factor.perm
        ffi, lib, i = module.ffi, module.lib, np.intc
        L = factor.L
        Lp, Li = L.indptr.astype(i), L.indices.astype(i)
        Lx = np.ascontiguousarray(L.data)
        nbc, nbr = self.ni // self.bs, -(-self.n // self.bs)
        mark, slot = np.full(nbr, -1, dtype=i), np.empty(nbr, dtype=i)
        Bp = np.zeros(nbc + 1, dtype=i)
        args = (buf(ffi, Lp), buf(ffi, Li), buf(ffi, Lx))
        lib.ldl_blocks(self.bs, nbc, *args, buf(ffi, Bp), ffi.NULL, ffi.NULL, ffi.NULL,
                       buf(ffi, mark), buf(ffi, slot))
        np.cumsum(Bp, out=Bp)
        b2 = self.bs * self.bs
        self.Bp, self.Bi = Bp, np.empty(max(int(Bp[-1]), 1), dtype=i)
        self.Bx, self.Ld = np.zeros(max(int(Bp[-1]), 1) * b2), np.zeros(max(nbc, 1) * b2)
        mark.fill(-1)
        lib.ldl_blocks(self.bs, nbc, *args, buf(ffi, Bp), buf(ffi, self.Bi),
                       buf(ffi, self.Bx), buf(ffi, self.Ld), buf(ffi, mark), buf(ffi, slot))
        self.nbc = nbc
        self.dinv = 1.0 / np.asarray(factor.D)[:self.ni]
        self.x = np.empty(self.n)
        self._blocks = tuple(buf(ffi, a) for a in (self.Bp, self.Bi, self.Bx, self.Ld))
        self._dinv, self._x = buf(ffi, self.dinv), buf(ffi, self.x)

    def forward(self, b: np.ndarray) -> np.ndarray:
        """Permute b and sweep the interior columns; returns r = x[ni:] (a view)."""
        np.take(b, self.perm, out=self.x)
        self.mod.lib.ldl_forward_interior(self.bs, self.nbc, *self._blocks, self._x)
        return self.x[self.ni:]

    def backward(self, y: np.ndarray, out: np.ndarray) -> None:
        """Set u_G = y, sweep back through the interior, write u (natural order) to out."""
        self.x[self.ni:] = y
        self.mod.lib.ldl_backward_given_tail(self.bs, self.nbc, *self._blocks, self._dinv,
                                             self._x)
        out[self.perm] = self.x


class PerzynaKernel:
    """perzyna_advance for one law (material.Perzyna), on flat DG0 arrays."""

    def __init__(self, law, projection, lambda1: float, lambda2: float, module,
                 rtol: float = 1e-14, max_iter: int = 100):
        from .material import _FLAT, _FROM
        d = law.dim
        self.mod, self.d, self.m = module, d, law.m
        self.l1, self.l2, self.rtol, self.max_iter = lambda1, lambda2, rtol, max_iter
        c = np.ascontiguousarray
        self.C, self.M = c(law.Cmat, dtype=float), c(law.M, dtype=float)
        self.AV, self.V = c(projection.AV, dtype=float), c(projection.V, dtype=float)
        self.lam = c(projection.lam, dtype=float)
        self.flat = c(_FLAT[d], dtype=np.intc)
        self.from_ = c(_FROM[d], dtype=np.intc)
        self.glam = c([projection.lam[g[0]] for g in projection.groups], dtype=float)
        self.group = np.empty(self.m, dtype=np.intc)
        for i, g in enumerate(projection.groups):
            self.group[g] = i
        self._work = None

    def advance(self, sigma: np.ndarray, H: np.ndarray, kappa: np.ndarray, k: float) -> int:
        """H += k Gfun(sigma, kappa), kappa += k Gk(sigma, kappa) in place (flat float64
        arrays: sigma, H of length ncells * d * d, kappa of length ncells)."""
        ffi, lib = self.mod.ffi, self.mod.lib
        for a in (sigma, H, kappa):
            if a.dtype != np.float64 or not a.flags.c_contiguous:
                raise TypeError("kernel arrays must be contiguous float64")
        n = len(kappa)
        if sigma.size != n * self.d ** 2 or H.size != n * self.d ** 2:
            raise ValueError("sigma, H and kappa sizes do not match")
        if self._work is None or len(self._work[0]) != n:
            self._work = (np.empty(max(n, 1), dtype=np.intc), np.empty(max(n, 1), dtype=np.intc),
                          np.empty(max(n, 1) * (self.m + 3 + len(self.glam))))
        act, todo, Z = self._work
        return lib.perzyna_advance(
            n, self.d ** 2, self.m, buf(ffi, sigma), buf(ffi, H), buf(ffi, kappa), k, self.l1,
            self.l2, buf(ffi, self.C), buf(ffi, self.M), buf(ffi, self.AV), buf(ffi, self.V),
            buf(ffi, self.lam), buf(ffi, self.flat), buf(ffi, self.from_), self.rtol,
            self.max_iter, len(self.glam), buf(ffi, self.glam), buf(ffi, self.group),
            buf(ffi, act), buf(ffi, todo), buf(ffi, Z))
