"""History terms of scheme (3.2)-(3.3), explicit (left end point) as in the paper.

H_n     = sum_{j=1..n} k_j Gfun(sigma_{j-1}, kappa_{j-1}) + sigma0 - E eps(u0)   (DG0 tensor)
kappa_n = sum_{j=1..n} k_j Gk(sigma_{j-1}, kappa_{j-1}) + kappa0                  (DG0 scalar)
so H_n = H_{n-1} + k_n Gfun(sigma_{n-1}, kappa_{n-1}) with H_0 = sigma0 - E eps(u0), and
likewise for kappa.  Only a case with a viscoplastic law has this history; an elastic case
creates no history object at all.  The state is committed only through ``advance`` (after
the previous step converged), so a failed step leaves it untouched.
"""
from __future__ import annotations

from dolfinx import fem

from .material import Perzyna


class ViscoplasticHistory:
    """Holds H_n (the problem's DG0 function ``H``) and kappa_n, and advances them.
    H_0 = sigma0 - E eps(u0) and kappa_0 are set by ``problem.set_initial_values``."""

    def __init__(self, problem, lambda1: float, lambda2: float):
        self.elasticity = problem.law
        self.law = Perzyna(problem.law, lambda1, lambda2)
        self.H = problem.H
        self.kappa = fem.Function(problem.Y, name="kappa")

    def advance(self, sigma_prev, k: float) -> None:
        """H_n = H_{n-1} + k_n Gfun(sigma_{n-1}, kappa_{n-1}), same for kappa (3.2)-(3.3).

        ``sigma_prev`` is the DG0 function holding sigma_{n-1}; ``self.kappa`` holds kappa_{n-1}
        on entry and kappa_n on exit.  All local cells (owned and ghost) are updated with the
        same data, so ghosts stay consistent without communication.
        """
        t = self.elasticity.to_voigt(sigma_prev.x.array)
        g_sigma, g_kappa = self.law.rates(t, self.kappa.x.array)
        self.H.x.array[:] += k * self.elasticity.from_voigt(g_sigma).reshape(-1)
        self.kappa.x.array[:] += k * g_kappa
