/* The cell-strain operator of P1 displacements cell by cell (app/model/strain.py; wrappers
   and numpy references in kernels/cells.py). */
#include <math.h>

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

/* cell_pass_2 or cell_pass_3 for the dimension d. */
double cell_pass(int ncells, int d, const int *nodes, const double *G, const double *vol,
                 double lmbda, double two_mu, const double *u, const double *H, double *sigma,
                 double *vm, double *ss)
{
    return d == 2 ? cell_pass_2(ncells, nodes, G, vol, lmbda, two_mu, u, H, sigma, vm, ss)
                  : cell_pass_3(ncells, nodes, G, vol, lmbda, two_mu, u, H, sigma, vm, ss);
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
