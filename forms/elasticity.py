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
    """The linearised strain.

    Args:
        u: a displacement (UFL vector).

    Returns:
        eps(u) = (grad u + grad u^T) / 2.
    """
    return ufl.sym(ufl.grad(u))


def plane_strain_moduli(E: float, nu: float) -> tuple[float, float]:
    """The plane stress moduli that give plane strain: with E' = E / (1 - s^2) and
    s' = s / (1 - s) the plane stress law above is E tau = lambda tr(tau) I + 2 mu tau with
    the 3D Lame constants of (E, s) (the out-of-plane strain is zero).

    Args:
        E: Young's modulus.
        nu: Poisson's ratio s (< 1/2).

    Returns:
        (E', s').
    """
    return E / (1.0 - nu * nu), nu / (1.0 - nu)


def lame_constants(E, nu, dim: int = 2):
    """The constants of E tau = lmbda tr(tau) I + two_mu tau.

    Plane stress in 2D, isotropic Hooke in 3D.

    Args:
        E: Young's modulus (float or UFL constant).
        nu: Poisson's ratio (float or UFL constant).
        dim: space dimension (2 or 3).

    Returns:
        (lmbda, two_mu).

    Raises:
        ValueError: if dim is not 2 or 3.
    """
    if dim == 2:
        return E * nu / (1.0 - nu**2), E / (1.0 + nu)
    if dim == 3:
        return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (1.0 + nu)
    raise ValueError(f"dim must be 2 or 3, got {dim}")


def plane_stress_constants(E, nu):
    """The constants of the paper's plane-stress law.

    Args:
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        (lmbda, two_mu), as lame_constants(E, nu, 2).
    """
    return lame_constants(E, nu, 2)


def elasticity_operator(E, nu, dim: int = 2):
    """The elasticity operator E.

    Args:
        E: Young's modulus (float or UFL constant).
        nu: Poisson's ratio (float or UFL constant).
        dim: space dimension (2 or 3).

    Returns:
        A function tau -> E tau building UFL.
    """
    lmbda, two_mu = lame_constants(E, nu, dim)

    def apply(tau):
        return lmbda * ufl.tr(tau) * ufl.Identity(dim) + two_mu * tau

    return apply
