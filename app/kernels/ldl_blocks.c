/* The split solve of the condensed solver: K = L D L^T ordered interior first, Gamma3 last, with
   the interior columns of L in node blocks (kernels/sweeps.py: GLastSolve, and its numpy
   reference split_solve_numpy). */

#include "cells.h"
#include "ldl_blocks.h"

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
static void ldl_forward_##BS(int J0, int J1, const int *Bp, const int *Bi,                \
                             const double *Bx, const double *Ld, double *x)                \
{                                                                                          \
    for (int J = J0; J < J1; ++J) {                                                        \
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
/* backward with x_G given (the Gamma3 values): x_I <- L_II^-T (D_I^-1 x_I - L_GI^T x_G).
   The blocks are read in one descending stream (columns and, within a column, blocks from
   last to first): 1.9 against 2.4 ms per sweep at h = 1/128 with the blocks of a column read
   forwards (measured), as the prefetchers follow a single direction. */
#define LDL_BACKWARD(BS)                                                                   \
static void ldl_backward_##BS(int J0, int J1, const int *Bp, const int *Bi,               \
                              const double *Bx, const double *Ld, const double *dinv,     \
                              double *x)                                                   \
{                                                                                          \
    for (int J = J1 - 1; J >= J0; --J) {                                                   \
        double *xJ = x + BS * J, t[BS], s[BS][BS];                                         \
        for (int a = 0; a < BS; ++a) {                                                     \
            t[a] = xJ[a] * dinv[BS * J + a];                                               \
            for (int b = 0; b < BS; ++b) s[a][b] = 0.0;    /* independent chains */        \
        }                                                                                  \
        for (int k = Bp[J + 1] - 1; k >= Bp[J]; --k) {     /* one descending stream */    \
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

/* the forward sweep over the block columns J0..J1-1 */
static void forward_range(int bs, int J0, int J1, const int *Bp, const int *Bi,
                          const double *Bx, const double *Ld, double *x)
{
    if (bs == 2) ldl_forward_2(J0, J1, Bp, Bi, Bx, Ld, x);
    else if (bs == 3) ldl_forward_3(J0, J1, Bp, Bi, Bx, Ld, x);
    else ldl_forward_1(J0, J1, Bp, Bi, Bx, Ld, x);
}

/* the backward sweep over the block columns J1-1 down to J0 */
static void backward_range(int bs, int J0, int J1, const int *Bp, const int *Bi,
                           const double *Bx, const double *Ld, const double *dinv, double *x)
{
    if (bs == 2) ldl_backward_2(J0, J1, Bp, Bi, Bx, Ld, dinv, x);
    else if (bs == 3) ldl_backward_3(J0, J1, Bp, Bi, Bx, Ld, dinv, x);
    else ldl_backward_1(J0, J1, Bp, Bi, Bx, Ld, dinv, x);
}

/* x_I <- L_II^-1 x_I, x_G <- x_G - L_GI x_I with blocks of size bs (1, 2 or 3). */
void ldl_forward_interior(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                          const double *Ld, double *x)
{
    forward_range(bs, 0, nbc, Bp, Bi, Bx, Ld, x);
}

/* x_I <- L_II^-T (D_I^-1 x_I - L_GI^T x_G) with blocks of size bs (1, 2 or 3). */
void ldl_backward_given_tail(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                             const double *Ld, const double *dinv, double *x)
{
    backward_range(bs, 0, nbc, Bp, Bi, Bx, Ld, dinv, x);
}

/* One of the two independent subtrees of a split sweep, run by a second thread. */
struct part {
    int bs, J0, J1;
    const int *Bp, *Bi;
    const double *Bx, *Ld, *dinv;
    double *x;
};

static void *forward_part(void *arg)
{
    const struct part *p = arg;
    forward_range(p->bs, p->J0, p->J1, p->Bp, p->Bi, p->Bx, p->Ld, p->x);
    return NULL;
}

static void *backward_part(void *arg)
{
    const struct part *p = arg;
    backward_range(p->bs, p->J0, p->J1, p->Bp, p->Bi, p->Bx, p->Ld, p->dinv, p->x);
    return NULL;
}

/* ldl_forward_interior with the block columns 0..s1-1 and s1..s2-1 two subtrees of the
   elimination tree (no block of one in the other's rows): they are swept at once, the
   second on y (n values: its rows copied from x, the rows from s2 on zeroed, then its
   updates of those rows added to x), then s2..nbc-1 on x. */
void ldl_forward_split(int bs, int nbc, int s1, int s2, int n, const int *Bp, const int *Bi,
                       const double *Bx, const double *Ld, double *x, double *y)
{
    const long a = (long)bs * s1, b = (long)bs * s2;
    for (long i = a; i < b; ++i) y[i] = x[i];
    for (long i = b; i < n; ++i) y[i] = 0.0;
    struct part mine = {bs, 0, s1, Bp, Bi, Bx, Ld, NULL, x};
    struct part other = {bs, s1, s2, Bp, Bi, Bx, Ld, NULL, y};
    run_two(forward_part, &mine, &other);
    for (long i = a; i < b; ++i) x[i] = y[i];
    for (long i = b; i < n; ++i) x[i] += y[i];
    forward_range(bs, s2, nbc, Bp, Bi, Bx, Ld, x);
}

/* ldl_backward_given_tail with the two subtrees of ldl_forward_split: s2..nbc-1 first, then
   the subtrees at once (each reads only its own rows and those from s2 on). */
void ldl_backward_split(int bs, int nbc, int s1, int s2, const int *Bp, const int *Bi,
                        const double *Bx, const double *Ld, const double *dinv, double *x)
{
    backward_range(bs, s2, nbc, Bp, Bi, Bx, Ld, dinv, x);
    struct part mine = {bs, 0, s1, Bp, Bi, Bx, Ld, dinv, x};
    struct part other = {bs, s1, s2, Bp, Bi, Bx, Ld, dinv, x};
    run_two(backward_part, &mine, &other);
}
