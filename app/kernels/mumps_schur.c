/* One distributed MUMPS L D L^T of K with the Gamma3 dofs as Schur variables, called
   directly: analysis in a given order, factorisation with the Schur complement on the host,
   and per step a condensation and an expansion with distributed right-hand side and
   solution (app/solvers/mumps.py). */
#include <stdlib.h>
#include <dmumps_c.h>

#include "mumps_schur.h"

#define ICNTL(id, i) ((id)->icntl[(i) - 1])

static int ms_job(DMUMPS_STRUC_C *id, int job)
{
    id->job = job;
    dmumps_c(id);
    return id->infog[0];
}

void *ms_init(int comm, int *status)
{
    DMUMPS_STRUC_C *id = calloc(1, sizeof *id);
    if (!id) return NULL;
    id->comm_fortran = comm;
    id->par = 1;              /* the host takes part in the factorisation */
    id->sym = 1;              /* symmetric positive definite */
    *status = ms_job(id, -1);
    ICNTL(id, 1) = 6;         /* error messages only */
    ICNTL(id, 2) = 0;
    ICNTL(id, 3) = 0;
    ICNTL(id, 4) = 1;
    return id;
}

int ms_analyse(void *handle, int n, long nnz_loc, int *irn, int *jcn, double *a,
               int *perm_in, int m, int *listvar)
{
    DMUMPS_STRUC_C *id = handle;
    id->n = n;
    ICNTL(id, 18) = 3;        /* distributed assembled matrix */
    id->nnz_loc = nnz_loc;
    id->irn_loc = irn;
    id->jcn_loc = jcn;
    id->a_loc = a;
    ICNTL(id, 28) = 1;        /* sequential analysis ... */
    ICNTL(id, 7) = 1;         /* ... in the given order */
    id->perm_in = perm_in;
    ICNTL(id, 19) = 1;        /* Schur complement centralised on the host */
    id->size_schur = m;
    id->listvar_schur = listvar;
    return ms_job(id, 1);
}

int ms_factor(void *handle, double *schur)
{
    DMUMPS_STRUC_C *id = handle;
    id->schur = schur;
    id->schur_lld = id->size_schur;
    return ms_job(id, 2);
}

int ms_sol_length(void *handle)
{
    return ((DMUMPS_STRUC_C *)handle)->info[22];
}

void ms_set_solve(void *handle, int nloc, int *irhs_loc, double *rhs_loc, double *redrhs,
                  int lsol, double *sol_loc, int *isol_loc)
{
    DMUMPS_STRUC_C *id = handle;
    id->nrhs = 1;
    ICNTL(id, 20) = 10;       /* distributed right-hand side */
    id->nloc_rhs = nloc;
    id->lrhs_loc = nloc;
    id->irhs_loc = irhs_loc;
    id->rhs_loc = rhs_loc;
    ICNTL(id, 21) = 1;        /* distributed solution */
    id->lsol_loc = lsol;
    id->sol_loc = sol_loc;
    id->isol_loc = isol_loc;
    id->redrhs = redrhs;
    id->lredrhs = id->size_schur;
}

int ms_solve(void *handle, int phase)
{
    DMUMPS_STRUC_C *id = handle;
    ICNTL(id, 26) = phase;
    return ms_job(id, 3);
}

int ms_icntl(void *handle, int i)
{
    return ICNTL((DMUMPS_STRUC_C *)handle, i);
}

void ms_set_icntl(void *handle, int i, int value)
{
    ICNTL((DMUMPS_STRUC_C *)handle, i) = value;
}

int ms_infog(void *handle, int i)
{
    return ((DMUMPS_STRUC_C *)handle)->infog[i - 1];
}

void ms_free(void *handle)
{
    DMUMPS_STRUC_C *id = handle;
    if (!id) return;
    ms_job(id, -2);
    free(id);
}
