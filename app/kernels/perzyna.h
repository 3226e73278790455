/* The explicit Perzyna update of the viscoplastic history, cell by cell (perzyna.c). */
#ifndef VPCONTACT_PERZYNA_H
#define VPCONTACT_PERZYNA_H

/* H_c += k Gfun(sigma_c, kappa_c), kappa_c += k Gk(sigma_c, kappa_c) for every cell c: one
   explicit step of the history terms (3.2)-(3.3) with the Perzyna law, the von Mises
   projection by its secular equation, on nthreads threads (1 or 2: each half of the cells).
   Returns the number of cells whose root search did not converge (then nothing is written). */
int perzyna_advance(int ncells, int dd, int m, const double *sigma, double *H, double *kappa,
                    double k, double l1, double l2, const double *C, const double *M,
                    const double *AV, const double *V, const double *lam, const int *flat,
                    const int *from_, double rtol, int max_iter, int ng, const double *glam,
                    const double *GM, double *Z, double *mu_start, int nthreads);

#endif
