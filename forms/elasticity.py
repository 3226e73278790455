"""Elasticity tensors and the small-strain operator.

d = 2 (the paper, Section 4): plane stress,
  (E tau)_ij = E s / (1 - s^2) (tau_11 + tau_22) delta_ij + E / (1 + s) tau_ij;
d = 3: isotropic Hooke's law, E tau = lambda tr(tau) I + 2 mu tau with the Lame constants
  lambda = E s / ((1 + s)(1 - 2 s)), 2 mu = E / (1 + s).
(E Young's modulus, s Poisson's ratio.)  Both are E tau = lmbda tr(tau) I + two_mu tau.
"""
from __future__ import annotations

import ufl


def eps(u):
    """Linearised strain eps(u) = (grad u + grad u^T) / 2."""
    return ufl.sym(ufl.grad(u))


def lame_constants(E, nu, dim: int = 2):
    """(lmbda, two_mu) with E tau = lmbda tr(tau) I + two_mu tau: plane stress in 2D,
    isotropic Hooke in 3D.  Works for floats and UFL constants."""
    if dim == 2:
        return E * nu / (1.0 - nu**2), E / (1.0 + nu)
    if dim == 3:
        return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (1.0 + nu)
    raise ValueError(f"dim must be 2 or 3, got {dim}")


def plane_stress_constants(E, nu):
    """(lmbda, two_mu) of the paper's plane-stress law."""
    return lame_constants(E, nu, 2)


def elasticity_operator(E, nu, dim: int = 2):
    """Return tau -> E tau as a UFL-building function."""
    lmbda, two_mu = lame_constants(E, nu, dim)

    def apply(tau):
        return lmbda * ufl.tr(tau) * ufl.Identity(dim) + two_mu * tau

    return apply
