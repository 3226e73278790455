/* The projected Newton direction of the condensed solver's Gamma3 problem (dense.c). */
#ifndef VPCONTACT_DENSE_H
#define VPCONTACT_DENSE_H

/* p_f = -(S + W)_ff^-1 g_f on the nf free dofs free_, p = 0 on the others, by LAPACK's
   Cholesky factorisation of the free block.  Returns LAPACK's info (0: done; > 0: the free
   block is not positive definite). */
int newton_direction(int m, int d, const double *S, const double *W, const int *free_,
                     int nf, const double *g, double *p, double *work);

/* x = S^-1 x in place from S's Cholesky factor C (S = C C^T; C lower triangular, m x m,
   column major; only its lower triangle is read): BLAS trsv with C, then with C^T; in double
   (cholesky_solve_d) or single precision (cholesky_solve_s). */
void cholesky_solve_d(int m, const double *C, double *x);
void cholesky_solve_s(int m, const float *C, float *x);

#endif
