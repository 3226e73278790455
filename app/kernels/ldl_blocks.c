/* The split solve of the condensed solver: K = L D L^T ordered interior first, Gamma3 last, with
   the interior columns of L in node blocks (kernels/sweeps.py: GLastSolve, and its numpy
   reference split_solve_numpy). */
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
/* backward with x_G given (the Gamma3 values): x_I <- L_II^-T (D_I^-1 x_I - L_GI^T x_G).
   The blocks are read in one descending stream (columns and, within a column, blocks from
   last to first): 1.9 against 2.4 ms per sweep at h = 1/128 with the blocks of a column read
   forwards (measured), as the prefetchers follow a single direction. */
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

/* x_I <- L_II^-1 x_I, x_G <- x_G - L_GI x_I with blocks of size bs (1, 2 or 3). */
void ldl_forward_interior(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                          const double *Ld, double *x)
{
    if (bs == 2) ldl_forward_2(nbc, Bp, Bi, Bx, Ld, x);
    else if (bs == 3) ldl_forward_3(nbc, Bp, Bi, Bx, Ld, x);
    else ldl_forward_1(nbc, Bp, Bi, Bx, Ld, x);
}

/* x_I <- L_II^-T (D_I^-1 x_I - L_GI^T x_G) with blocks of size bs (1, 2 or 3). */
void ldl_backward_given_tail(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                             const double *Ld, const double *dinv, double *x)
{
    if (bs == 2) ldl_backward_2(nbc, Bp, Bi, Bx, Ld, dinv, x);
    else if (bs == 3) ldl_backward_3(nbc, Bp, Bi, Bx, Ld, dinv, x);
    else ldl_backward_1(nbc, Bp, Bi, Bx, Ld, dinv, x);
}

