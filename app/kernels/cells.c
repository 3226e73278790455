/* The cell-strain operator of P1 displacements cell by cell (app/model/strain.py; wrappers
   and numpy references in kernels/cells.py). */
#include <math.h>
#include <pthread.h>

#include "cells.h"

/* The cell-strain operator (strain.StrainOperator) cell by cell, for P1 displacements:
   G holds per cell |c| grad phi_a of its d + 1 vertex functions (row a: d entries) and nodes
   its vertices (local node numbers, dofs node * d + k), so that (D u)_c = |c| eps_c(u) =
   sym(sum_a u_a (x) G_a): a quarter of the data of D's rows (memory traffic dominates).
   cell_pass: eps_c = (D u)_c / |c|, returns sum_c |c| eps_c : eps_c; if sigma != NULL also
   sigma_c = E eps_c + H_c (H == NULL: 0; E tau = lmbda tr(tau) I + two_mu tau),
   vm_c = ||sigma_c||_VM = sqrt(3/2 s:s - 1/2 tr(s)^2) (plane stress in 2D: sigma_33 = 0) and
   *ss = sum_c |c| sigma_c : sigma_c (the square of ||sigma||_Q). */
#define CELL_PASS(D)                                                                       \
static double cell_pass_##D(int ncells, const int *nodes, const double *G,                  \
                            const double *vol, double lmbda, double two_mu, const double *u, \
                            const double *H, double *sigma, double *vm, double *ss)          \
{                                                                                          \
    enum { DD = D * D, NV = D + 1 };                                                       \
    double se = 0.0, sq = 0.0;                                                             \
    for (int c = 0; c < ncells; ++c) {                                                     \
        const int *nc = nodes + (long)c * NV;                                              \
        const double *Gc = G + (long)c * NV * D;                                           \
        double gu[DD] = {0}, e[DD], ee = 0.0;              /* gu[k][j] = sum_a u_ak G_aj */ \
        for (int a = 0; a < NV; ++a) {                                                     \
            const double *ua = u + (long)D * nc[a];                                        \
            for (int k = 0; k < D; ++k)                                                    \
                for (int j = 0; j < D; ++j) gu[k * D + j] += ua[k] * Gc[a * D + j];        \
        }                                                                                  \
        for (int i = 0; i < D; ++i)                                                        \
            for (int j = 0; j < D; ++j) {                                                  \
                e[i * D + j] = 0.5 * (gu[i * D + j] + gu[j * D + i]) / vol[c];             \
                ee += e[i * D + j] * e[i * D + j];                                         \
            }                                                                              \
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

/* run_two (cells.h). */
void run_two(void *(*run)(void *), void *mine, void *other)
{
    pthread_t thread;
    const int started = pthread_create(&thread, NULL, run, other) == 0;
    run(mine);
    if (started) pthread_join(thread, NULL);
    else run(other);
}

/* One thread's share of cell_pass: the cells c0..c1-1, their sums in se and ss. */
struct pass_job {
    int c0, c1, d;
    const int *nodes;
    const double *G, *vol;
    double lmbda, two_mu;
    const double *u, *H;
    double *sigma, *vm;
    double se, ss;
};

static void *pass_run(void *arg)
{
    struct pass_job *j = arg;
    const long c0 = j->c0, nv = j->d + 1, dd = (long)j->d * j->d;
    const int n = j->c1 - j->c0;
    const int *nodes = j->nodes + c0 * nv;
    const double *G = j->G + c0 * nv * j->d, *vol = j->vol + c0, *H = j->H ? j->H + c0 * dd : 0;
    double *sigma = j->sigma ? j->sigma + c0 * dd : 0, *vm = j->vm ? j->vm + c0 : 0;
    j->ss = 0.0;
    j->se = j->d == 2
        ? cell_pass_2(n, nodes, G, vol, j->lmbda, j->two_mu, j->u, H, sigma, vm, &j->ss)
        : cell_pass_3(n, nodes, G, vol, j->lmbda, j->two_mu, j->u, H, sigma, vm, &j->ss);
    return NULL;
}

/* cell_pass_2 or cell_pass_3 for the dimension d, on nthreads threads (1 or 2: each half of
   the cells; the cells are independent, only the two sums are added). */
double cell_pass(int ncells, int d, const int *nodes, const double *G, const double *vol,
                 double lmbda, double two_mu, const double *u, const double *H, double *sigma,
                 double *vm, double *ss, int nthreads)
{
    const int half = nthreads >= 2 ? ncells / 2 : ncells;
    struct pass_job jobs[2] = {
        {0, half, d, nodes, G, vol, lmbda, two_mu, u, H, sigma, vm, 0.0, 0.0},
        {half, ncells, d, nodes, G, vol, lmbda, two_mu, u, H, sigma, vm, 0.0, 0.0}};
    if (half < ncells) run_two(pass_run, &jobs[0], &jobs[1]);
    else pass_run(&jobs[0]);
    if (ss) *ss = jobs[0].ss + jobs[1].ss;
    return jobs[0].se + jobs[1].se;
}

/* b[dofs_c] += D_c^T H_c for every cell: b = D^T H = (H, eps(v)) for all v (local dofs);
   (D_c^T H_c)_ak = sum_j G_aj (H_kj + H_jk) / 2. */
#define CELL_LOAD(D)                                                                       \
static void cell_load_##D(int ncells, const int *nodes, const double *G, const double *H,   \
                          double *b)                                                       \
{                                                                                          \
    enum { DD = D * D, NV = D + 1 };                                                       \
    for (int c = 0; c < ncells; ++c) {                                                     \
        const int *nc = nodes + (long)c * NV;                                              \
        const double *Gc = G + (long)c * NV * D, *Hc = H + (long)c * DD;                   \
        double Hs[DD];                                                                     \
        for (int k = 0; k < D; ++k)                                                        \
            for (int j = 0; j < D; ++j) Hs[k * D + j] = 0.5 * (Hc[k * D + j] + Hc[j * D + k]); \
        for (int a = 0; a < NV; ++a) {                                                     \
            double *ba = b + (long)D * nc[a];                                              \
            for (int k = 0; k < D; ++k) {                                                  \
                double r = 0.0;                                                            \
                for (int j = 0; j < D; ++j) r += Gc[a * D + j] * Hs[k * D + j];            \
                ba[k] += r;                                                                \
            }                                                                              \
        }                                                                                  \
    }                                                                                      \
}
CELL_LOAD(2) CELL_LOAD(3)

/* cell_load_2 or cell_load_3 for the dimension d. */
void cell_load(int ncells, int d, const int *nodes, const double *G, const double *H,
               double *b)
{
    if (d == 2) cell_load_2(ncells, nodes, G, H, b);
    else cell_load_3(ncells, nodes, G, H, b);
}

/* The root of node i, halving the path on the way. */
static int root_of(int *parent, int i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

/* cell_components (cells.h): union-find that links the higher root to the lower, so that a
   component's root is its lowest node and every parent is lower than its node (path halving
   keeps that); then the components are numbered in the order of their roots. */
int cell_components(int n, int ncells, int nv, const int *nodes, int *label)
{
    for (int i = 0; i < n; ++i) label[i] = i;
    for (int c = 0; c < ncells; ++c) {
        const int *nc = nodes + (long)c * nv;
        int r = root_of(label, nc[0]);
        for (int a = 1; a < nv; ++a) {
            int q = root_of(label, nc[a]);
            if (q < r) { label[r] = q; r = q; }
            else if (q > r) label[q] = r;
        }
    }
    /* every parent is lower than its node: in ascending order a node's parent holds its
       component's number already when the node is reached */
    int count = 0;
    for (int i = 0; i < n; ++i) label[i] = label[i] == i ? count++ : label[label[i]];
    return count;
}
