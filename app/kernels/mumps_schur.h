/* One distributed MUMPS L D L^T of K with the Gamma3 dofs as Schur variables
   (mumps_schur.c; app/solvers/mumps.py). */
#ifndef VPCONTACT_MUMPS_SCHUR_H
#define VPCONTACT_MUMPS_SCHUR_H

/* A MUMPS instance on the Fortran communicator comm (symmetric positive definite, the host
   works). Returns NULL (no memory) or a handle; *status = INFOG(1). */
void *ms_init(int comm, int *status);

/* Analysis of the distributed lower triangle (1-based triplets irn, jcn, a of this rank),
   in the order perm_in (host only: position of each dof, 1-based) with the m Schur
   variables listvar (host only, 1-based). Returns INFOG(1). */
int ms_analyse(void *handle, int n, long nnz_loc, int *irn, int *jcn, double *a,
               int *perm_in, int m, int *listvar);

/* Numerical factorisation; the Schur complement goes to schur (host only, m x m, its lower
   triangle by rows). Returns INFOG(1). */
int ms_factor(void *handle, double *schur);

/* The length of this rank's distributed solution (INFO(23)), after the factorisation. */
int ms_sol_length(void *handle);

/* The arrays of the step: the distributed right-hand side (nloc rows irhs_loc, 1-based),
   the reduced right-hand side redrhs (host, m) and the distributed solution. */
void ms_set_solve(void *handle, int nloc, int *irhs_loc, double *rhs_loc, double *redrhs,
                  int lsol, double *sol_loc, int *isol_loc);

/* Condensation (phase 1, redrhs = the reduced right-hand side) or expansion (phase 2, from
   the Schur variables' values in redrhs). Returns INFOG(1). */
int ms_solve(void *handle, int phase);

/* ICNTL(i) (1-based) and its setter: the factorisation is repeated with a larger
   workspace (ICNTL(14)) where MUMPS's estimate was too small (INFOG(1) = -8, -9). */
int ms_icntl(void *handle, int i);
void ms_set_icntl(void *handle, int i, int value);

/* INFOG(i) (1-based). */
int ms_infog(void *handle, int i);

/* Frees MUMPS's data (JOB = -2) and the handle (NULL: nothing). */
void ms_free(void *handle);

#endif
