"""The contact and friction laws of the paper, (4.1) and (4.2), in numpy (vectorised).

This is the numpy reference of the laws: the fast solver's nodal contact energy
(app/solvers/nodal.py: its numpy path, and the test reference of the C kernel
kernels/contact.c) and the figure of the laws (app/post/plot.py) use these functions; the
weak forms of the SNES path are the same laws in UFL (forms/contact.py), and the tests compare
the two.

- Normal compliance (4.1): P(r) = c_nu / 2 (r^+)^2, p(r) = P'(r) = c_nu r^+, for the normal
  displacement r = u_nu < g; at r = g the law allows any -sigma_nu >= c_nu g (the bound
  u_nu <= g is a constraint of the step problem, not part of these functions).
- Nonmonotone friction (4.2): j_tau(x) = psi(|x|) with
      psi(r) = b r - c1 r^2 / 2                                         (0 <= r <= u1),
      psi(r) = c2 / 2 (r - u1)^2 + (b - c1 u1)(r - u1) + b u1 - c1 u1^2 / 2   (r >= u1),
  so |sigma_tau| = psi'(|u_tau|) for u_tau != 0; with slip dependence it is multiplied by
  theta(s_n).
- Regularisation for Newton's method: |x| -> |x|_delta = sqrt(|x|^2 + delta^2) in the
  friction term, and r^+ -> (r + sqrt(r^2 + delta^2)) / 2 in the memory term xi_n r^+.
"""
from __future__ import annotations

import numpy as np


def normal_compliance_energy(r, c_nu: float):
    """P(r) = c_nu / 2 (r^+)^2, the potential of the normal compliance of (4.1).

    Args:
        r: normal displacements u_nu (array or float).
        c_nu: the compliance coefficient.

    Returns:
        P(r), elementwise.
    """
    return 0.5 * c_nu * np.maximum(r, 0.0) ** 2


def normal_compliance(r, c_nu: float):
    """p(r) = P'(r) = c_nu r^+: -sigma_nu of (4.1) for u_nu = r < g (at r = g, the least of
    the admissible values [c_nu g, inf)).

    Args:
        r: normal displacements u_nu (array or float).
        c_nu: the compliance coefficient.

    Returns:
        p(r), elementwise.
    """
    return c_nu * np.maximum(r, 0.0)


def normal_compliance_slope(r, c_nu: float):
    """p'(r) = c_nu for r > 0, else 0 (the second derivative of P, (4.1)).

    Args:
        r: normal displacements u_nu (array or float).
        c_nu: the compliance coefficient.

    Returns:
        p'(r), elementwise (0 at r = 0).
    """
    return c_nu * (np.asarray(r) > 0)


def regularised_positive_part(r, delta: float):
    """r^+ regularised as (r + sqrt(r^2 + delta^2)) / 2 (the memory term xi_n r^+).

    Args:
        r: normal displacements (array or float).
        delta: the regularisation width.

    Returns:
        The regularised r^+, elementwise.
    """
    return 0.5 * (r + np.sqrt(r**2 + delta**2))


def regularised_positive_part_slope(r, delta: float):
    """The first derivative of ``regularised_positive_part``: (1 + r / sqrt(r^2 + delta^2)) / 2.

    Args:
        r: normal displacements (array or float).
        delta: the regularisation width.

    Returns:
        The derivative, elementwise.
    """
    return 0.5 * (1 + r / np.sqrt(r**2 + delta**2))


def regularised_positive_part_curvature(r, delta: float):
    """The second derivative of ``regularised_positive_part``: delta^2 / (2 (r^2 + delta^2)^3/2).

    Args:
        r: normal displacements (array or float).
        delta: the regularisation width.

    Returns:
        The second derivative, elementwise.
    """
    return 0.5 * delta**2 / np.sqrt(r**2 + delta**2) ** 3


def regularised_norm(x, delta: float):
    """|x|_delta = sqrt(|x|^2 + delta^2), the regularised norm of the friction term of (4.2).

    Args:
        x: vectors along the last axis (shape (..., d)).
        delta: the regularisation width.

    Returns:
        |x|_delta, shape (...).
    """
    return np.sqrt(np.sum(np.asarray(x) ** 2, axis=-1) + delta**2)


def psi(rho, b: float, c1: float, c2: float, u1: float):
    """The friction potential psi of law (4.2).

    Args:
        rho: the (regularised) slip |u_tau| >= 0 (array or float).
        b: the friction bound at zero slip.
        c1: the softening slope on [0, u1].
        c2: the hardening slope beyond u1.
        u1: the slip where softening turns into hardening.

    Returns:
        psi(rho) = b rho - c1 rho^2 / 2 for rho <= u1, else
        c2 / 2 (rho - u1)^2 + (b - c1 u1)(rho - u1) + b u1 - c1 u1^2 / 2.
    """
    return np.where(rho <= u1, b * rho - 0.5 * c1 * rho**2,
                    0.5 * c2 * (rho - u1) ** 2 + (b - c1 * u1) * (rho - u1) + b * u1
                    - 0.5 * c1 * u1**2)


def dpsi(rho, b: float, c1: float, c2: float, u1: float):
    """psi', the friction bound |sigma_tau| of law (4.2) at slip rho > 0.

    Args:
        rho: the (regularised) slip (array or float).
        b, c1, c2, u1: the parameters of (4.2), as in ``psi``.

    Returns:
        psi'(rho) = b - c1 rho for rho <= u1, else c2 (rho - u1) + b - c1 u1 (continuous).
    """
    return np.where(rho <= u1, b - c1 * rho, c2 * (rho - u1) + b - c1 * u1)


def d2psi(rho, b: float, c1: float, c2: float, u1: float):
    """psi'', the slope of the friction bound of law (4.2) (jumps at u1).

    Args:
        rho: the (regularised) slip (array or float).
        b, c1, c2, u1: the parameters of (4.2), as in ``psi``.

    Returns:
        -c1 for rho <= u1, else c2 (an array of rho's shape).
    """
    return np.where(rho <= u1, -c1, c2)
