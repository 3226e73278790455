/* The cell-strain operator of P1 displacements applied cell by cell (cells.c). */
#ifndef VPCONTACT_CELLS_H
#define VPCONTACT_CELLS_H

/* eps_c(u) of every cell; returns sum_c |c| eps_c : eps_c (||u||_V^2).  If sigma != NULL also
   sigma_c = E eps_c + H_c (3.2), vm_c = ||sigma_c||_VM and *ss = ||sigma||_Q^2.  On nthreads
   threads (1 or 2). */
double cell_pass(int ncells, int d, const int *nodes, const double *G, const double *vol,
                 double lmbda, double two_mu, const double *u, const double *H, double *sigma,
                 double *vm, double *ss, int nthreads);

/* b += D^T H = (H, eps(v)) for all v: the pre-stress term of the step's load (3.4). */
void cell_load(int ncells, int d, const int *nodes, const double *G, const double *H,
               double *b);

/* The connected components of the cells' graph (nodes joined by a cell): label[i] = the
   component of node i (0 .. count - 1, numbered by their lowest node); returns the count. */
int cell_components(int n, int ncells, int nv, const int *nodes, int *label);

/* run(mine) on this thread and run(other) on a second one; both done on return (other on
   this thread after mine where no thread can be started).  The kernels' two-thread passes
   (cell_pass, perzyna_advance, the split sweeps of ldl_blocks.c) share it. */
void run_two(void *(*run)(void *), void *mine, void *other);

#endif
