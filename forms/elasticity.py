"""Plane-stress elasticity tensor of the paper (Section 4) and the small-strain operator.

(E tau)_ij = E s / (1 - s^2) (tau_11 + tau_22) delta_ij + E / (1 + s) tau_ij
(E Young's modulus, s Poisson's ratio), i.e. Lame-type constants
lmbda = E s / (1 - s^2) and 2 mu = E / (1 + s).
"""
from __future__ import annotations

import ufl


def eps(u):
    """Linearised strain eps(u) = (grad u + grad u^T) / 2."""
    return ufl.sym(ufl.grad(u))


def plane_stress_constants(E: float, nu: float) -> tuple[float, float]:
    """(lmbda, two_mu) of the plane-stress law: E tau = lmbda tr(tau) I + two_mu tau."""
    return E * nu / (1.0 - nu**2), E / (1.0 + nu)


def elasticity_operator(E: float, nu: float):
    """Return tau -> E tau (plane stress) as a UFL-building function."""
    lmbda, two_mu = plane_stress_constants(E, nu)

    def apply(tau):
        return lmbda * ufl.tr(tau) * ufl.Identity(2) + two_mu * tau

    return apply
