/* The nodal contact energy of the condensed solver (wrapper: app/kernels/contact.py, used by
   app/solvers/nodal.py: NodalContact; its numpy reference nodal_contact_numpy composes the
   laws of app/model/contact_laws.py). */
#include <math.h>

#include "contact.h"

/* The nodal contact energy of the condensed solver's Gamma3 problem (nodal.NodalContact):
   E = sum_i w_i phi_i(y_i) with r = y.nu,
   phi = c/2 (r+)^2 + xi (r + sqrt(r^2 + delta^2))/2 + theta psi(sqrt(|y_tau|^2 + delta^2)),
   its gradient (n x d) and, if hess != NULL, the nodal Hessian blocks (n x d x d).
   xi, theta: NULL when the case has no memory term / no slip dependence (theta = 1);
   friction = 0: no friction term.  psi: law (4.2). */
double nodal_contact(int n, int d, const double *y, const double *nu, double c,
                     const double *xi, const double *theta, int friction, double b, double c1,
                     double c2, double u1, double delta, const double *w, double *grad,
                     double *hess)
{
    double energy = 0.0, d2 = delta * delta;
    for (int i = 0; i < n; ++i) {
        const double *yi = y + (long)i * d;
        double *gi = grad + (long)i * d, *Hi = hess ? hess + (long)i * d * d : NULL;
        double r = 0.0;
        for (int a = 0; a < d; ++a) r += yi[a] * nu[a];
        double rp = r > 0.0 ? r : 0.0;
        double e = 0.5 * c * rp * rp, dr = c * rp, hr = r > 0.0 ? c : 0.0;
        if (xi) {
            double sq = sqrt(r * r + d2);
            e += xi[i] * 0.5 * (r + sq);
            dr += xi[i] * 0.5 * (1.0 + r / sq);
            hr += xi[i] * 0.5 * d2 / (sq * sq * sq);
        }
        for (int a = 0; a < d; ++a) gi[a] = dr * nu[a];
        if (Hi)
            for (int a = 0; a < d; ++a)
                for (int bb = 0; bb < d; ++bb) Hi[a * d + bb] = hr * nu[a] * nu[bb];
        if (friction) {
            double tau[3], t2 = 0.0, th = theta ? theta[i] : 1.0;
            for (int a = 0; a < d; ++a) { tau[a] = yi[a] - r * nu[a]; t2 += tau[a] * tau[a]; }
            double rho = sqrt(t2 + d2), psi, d1, dd2;
            if (rho <= u1) {
                psi = b * rho - 0.5 * c1 * rho * rho; d1 = b - c1 * rho; dd2 = -c1;
            } else {
                double s = rho - u1;
                psi = 0.5 * c2 * s * s + (b - c1 * u1) * s + b * u1 - 0.5 * c1 * u1 * u1;
                d1 = c2 * s + b - c1 * u1; dd2 = c2;
            }
            e += th * psi;
            double f = th * d1 / rho;
            for (int a = 0; a < d; ++a) gi[a] += f * tau[a];
            if (Hi) {
                double ft = th * (dd2 / (rho * rho) - d1 / (rho * rho * rho));
                for (int a = 0; a < d; ++a)
                    for (int bb = 0; bb < d; ++bb)
                        Hi[a * d + bb] += ft * tau[a] * tau[bb]
                                          + f * ((a == bb ? 1.0 : 0.0) - nu[a] * nu[bb]);
            }
        }
        energy += w[i] * e;
        for (int a = 0; a < d; ++a) gi[a] *= w[i];
        if (Hi) for (int a = 0; a < d * d; ++a) Hi[a] *= w[i];
    }
    return energy;
}

