/* The split solve with K = L D L^T, Gamma3 dofs last: L's interior columns in node blocks
   and the two triangular sweeps around the Gamma3 problem (ldl_blocks.c). */
#ifndef VPCONTACT_LDL_BLOCKS_H
#define VPCONTACT_LDL_BLOCKS_H

/* The first nbc block columns of L (CSC: Lp, Li, Lx) in bs x bs blocks (Bp, Bi, Bx) and the
   strictly lower parts of the diagonal blocks (Ld); with Bi == NULL it only counts the blocks
   of each column into Bp[J + 1].  Returns the number of blocks. */
int ldl_blocks(int bs, int nbc, const int *Lp, const int *Li, const double *Lx, int *Bp,
               int *Bi, double *Bx, double *Ld, int *mark, int *slot);

/* The forward sweep over the interior: x_I <- L_II^-1 x_I, x_G <- x_G - L_GI x_I. */
void ldl_forward_interior(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                          const double *Ld, double *x);

/* The backward sweep with x_G given: x_I <- L_II^-T (D_I^-1 x_I - L_GI^T x_G). */
void ldl_backward_given_tail(int bs, int nbc, const int *Bp, const int *Bi, const double *Bx,
                             const double *Ld, const double *dinv, double *x);

/* The two sweeps with the block columns 0..s1-1 and s1..s2-1 two independent subtrees of
   the elimination tree, swept by two threads at once (y: n work values). */
void ldl_forward_split(int bs, int nbc, int s1, int s2, int n, const int *Bp, const int *Bi,
                       const double *Bx, const double *Ld, double *x, double *y);
void ldl_backward_split(int bs, int nbc, int s1, int s2, const int *Bp, const int *Bi,
                        const double *Bx, const double *Ld, const double *dinv, double *x);

#endif
