"""Elasticity tensors and the small-strain operator.

d = 2 (the paper, Section 4): plane stress,
  (E tau)_ij = E s / (1 - s^2) (tau_11 + tau_22) delta_ij + E / (1 + s) tau_ij;
d = 3: isotropic Hooke's law, E tau = lambda tr(tau) I + 2 mu tau with the Lame constants
  lambda = E s / ((1 + s)(1 - 2 s)), 2 mu = E / (1 + s).
(E Young's modulus, s Poisson's ratio.)  Both are E tau = lmbda tr(tau) I + two_mu tau.
Any other E (anisotropic, or varying per cell) is its matrix C in t-coordinates,
t = (t11, t22, t12) in 2D, (t11, t22, t33, t23, t13, t12) in 3D: (E tau)_t = C t(tau)
(``voigt_operator``; C a constant or a DG0 (m, m) field, app/model/stiffness.py).
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


PAIRS = {2: [(0, 0), (1, 1), (0, 1)],
         3: [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]}


def voigt(tau, dim: int):
    """t-coordinates of a symmetric tensor.

    Args:
        tau: a symmetric UFL tensor.
        dim: space dimension (2 or 3).

    Returns:
        The UFL vector (t11, t22, t12) or (t11, t22, t33, t23, t13, t12).
    """
    return ufl.as_vector([tau[i, j] for i, j in PAIRS[dim]])


def voigt_operator(C, dim: int):
    """The elasticity operator of a matrix in t-coordinates: (E tau)_t = C t(tau).

    Args:
        C: the (m, m) matrix (UFL: a Constant, or a DG0 tensor Function for E per cell).
        dim: space dimension (2 or 3).

    Returns:
        A function tau -> E tau building UFL (a symmetric tensor).
    """
    pairs = PAIRS[dim]
    where = {p: k for k, p in enumerate(pairs)}

    def apply(tau):
        s = ufl.dot(C, voigt(tau, dim))
        return ufl.as_matrix([[s[where[(min(i, j), max(i, j))]] for j in range(dim)]
                              for i in range(dim)])

    return apply
