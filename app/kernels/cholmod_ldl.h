/* K = L D L^T by CHOLMOD's supernodal Cholesky factorisation in a given order
   (cholmod_ldl.c). */
#ifndef VPCONTACT_CHOLMOD_LDL_H
#define VPCONTACT_CHOLMOD_LDL_H

/* A[perm][:, perm] = L L^T for the symmetric positive definite A (CSC, lower triangle read).
   Returns the factor's handle, or NULL with *status = 1 (not positive definite), 2 (CHOLMOD
   changed the order) or 3 (CHOLMOD failed). */
void *ldl_factor(int n, const int *Ap, const int *Ai, const double *Ax, const int *perm,
                 int *status);

/* The L D L^T form of the factor: D, the dense unit lower L_GG of the last m columns and the
   first nbc block columns in node blocks (as ldl_blocks); with Bi == NULL it only counts.
   Returns 1/0 (counting: may Bx be CHOLMOD's own value array), 0 (filling), -1 (no memory). */
int ldl_blocks_super(void *handle, int bs, int nbc, int m, int *Bp, int *Bi, double *Bx,
                     double *Ld, double *D, double *LGG, int *mark, int *slot);

/* CHOLMOD's value array of the supernodal factor. */
double *ldl_values(void *handle);

/* Frees the factor and CHOLMOD's workspace (NULL: nothing). */
void ldl_free(void *handle);

/* A fill-reducing order of a symmetric graph given as CSR with the full pattern: CHOLMOD's
   own choice (AMD or METIS), postordered; 0 ok, -1 failed. */
int metis_order(int n, const int *Ap, const int *Ai, int *perm);

#endif
