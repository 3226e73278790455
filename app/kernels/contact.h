/* The nodal contact energy of the fast solver's Gamma3 problem (contact.c). */
#ifndef VPCONTACT_CONTACT_H
#define VPCONTACT_CONTACT_H

/* E = sum_i w_i phi_i(y_i), the normal compliance P of (4.1), the memory term and
   theta psi(|y_tau|_delta) of law (4.2) at the Gamma3 nodes; writes the gradient (n x d) and,
   if hess != NULL, the nodal Hessian blocks (n x d x d).  Returns E. */
double nodal_contact(int n, int d, const double *y, const double *nu, double c,
                     const double *xi, const double *theta, int friction, double b, double c1,
                     double c2, double u1, double delta, const double *w, double *grad,
                     double *hess);

#endif
