"""Closed forms of two-dimensional (line) contact: Hertz for two cylinders and the
Cattaneo-Mindlin partial slip under a tangential force, from K. L. Johnson, Contact
Mechanics, Cambridge University Press 1985: chapter 4 (the Hertz contact of two cylinders
with parallel axes) and chapter 7 (tangential loading: the partial slip of cylinders).

Forces are per unit length of the cylinders' axis (N/m): P the normal force, Q the tangential
force, both of the whole contact.  The combined curvature and modulus (Johnson, ch. 4):

    1/R* = 1/R1 + 1/R2                                   (R = inf: a flat body)
    1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2               (plane strain; E = inf: rigid)

In plane stress (thin discs) the in-plane modulus of each body is E instead of
E/(1 - nu^2), so that 1/E* = 1/E1 + 1/E2.
"""
from __future__ import annotations

import math

import numpy as np


def effective_radius(R1: float, R2: float) -> float:
    """R* of two cylinders in contact: 1/R* = 1/R1 + 1/R2 (Johnson, ch. 4).

    Args:
        R1: radius of the first cylinder [m] (math.inf: a flat body).
        R2: radius of the second cylinder [m] (math.inf: a flat body).

    Returns:
        R* [m].
    """
    return 1.0 / (1.0 / R1 + 1.0 / R2)


def effective_modulus(E1: float, nu1: float, E2: float, nu2: float,
                      plane_strain: bool = True) -> float:
    """E* of two elastic bodies: 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2 in plane strain
    (Johnson, ch. 4), 1/E* = 1/E1 + 1/E2 in plane stress.

    Args:
        E1: Young's modulus of the first body [Pa] (math.inf: rigid).
        nu1: its Poisson ratio.
        E2: Young's modulus of the second body [Pa] (math.inf: rigid).
        nu2: its Poisson ratio.
        plane_strain: plane strain (long cylinders) if True, else plane stress.

    Returns:
        E* [Pa].
    """
    if plane_strain:
        return 1.0 / ((1.0 - nu1 ** 2) / E1 + (1.0 - nu2 ** 2) / E2)
    return 1.0 / (1.0 / E1 + 1.0 / E2)


def hertz_cylinders(P: float, R1: float, R2: float, E1: float, nu1: float, E2: float,
                    nu2: float, plane_strain: bool = True) -> tuple[float, float]:
    """Hertz contact of two cylinders with parallel axes (Johnson, ch. 4): the
    half-width a = sqrt(4 P R* / (pi E*)) of the contact strip and the peak pressure
    p0 = 2 P / (pi a).

    Args:
        P: the normal force per unit length [N/m], > 0.
        R1: radius of the first cylinder [m] (math.inf: a flat body).
        R2: radius of the second cylinder [m] (math.inf: a flat body).
        E1: Young's modulus of the first body [Pa].
        nu1: its Poisson ratio.
        E2: Young's modulus of the second body [Pa].
        nu2: its Poisson ratio.
        plane_strain: the combined modulus of plane strain if True, else of plane stress.

    Returns:
        (a, p0): the half-width [m] and the peak pressure [Pa].
    """
    R = effective_radius(R1, R2)
    E = effective_modulus(E1, nu1, E2, nu2, plane_strain)
    a = math.sqrt(4.0 * P * R / (math.pi * E))
    return a, 2.0 * P / (math.pi * a)


def hertz_pressure(x, a: float, p0: float) -> np.ndarray:
    """The Hertz pressure p(x) = p0 sqrt(1 - x^2/a^2) for |x| < a, 0 outside (Johnson,
    ch. 4); its integral over the strip is pi a p0 / 2 = P.

    Args:
        x: distance(s) from the centre of the contact [m].
        a: the half-width [m].
        p0: the peak pressure [Pa].

    Returns:
        p(x) [Pa], of the shape of x.
    """
    s = 1.0 - (np.asarray(x, dtype=float) / a) ** 2
    return p0 * np.sqrt(np.maximum(s, 0.0))


def mindlin_stick_halfwidth(a: float, Q: float, mu: float, P: float) -> float:
    """The half-width of the central stick zone of a Hertz line contact under a tangential
    force 0 <= Q <= mu P (Cattaneo-Mindlin, Johnson ch. 7): c = a sqrt(1 - Q/(mu P)).

    Args:
        a: the Hertz half-width [m].
        Q: the tangential force per unit length [N/m], 0 <= Q <= mu P.
        mu: the Coulomb friction coefficient, > 0.
        P: the normal force per unit length [N/m], > 0.

    Returns:
        c [m] (0 when Q = mu P: the whole strip slides).

    Raises:
        ValueError: if Q is negative or exceeds mu P (gross sliding: no stick zone).
    """
    if not 0.0 <= Q <= mu * P:
        raise ValueError(f"Q = {Q:g} outside [0, mu P = {mu * P:g}]: no partial slip")
    return a * math.sqrt(1.0 - Q / (mu * P))


def mindlin_shear(x, a: float, c: float, p0: float, mu: float) -> np.ndarray:
    """The Cattaneo-Mindlin shear traction of a Hertz line contact (Johnson, ch. 7):
    q(x) = mu p0 sqrt(1 - x^2/a^2) - mu p0 (c/a) sqrt(1 - x^2/c^2), the second term only in
    the stick zone |x| < c; q = mu p(x) in the slip zones c <= |x| < a, 0 outside.  Its
    integral over the strip is mu P (1 - c^2/a^2) = Q.

    Args:
        x: distance(s) from the centre of the contact [m].
        a: the Hertz half-width [m].
        c: the stick zone's half-width [m] (mindlin_stick_halfwidth), 0 <= c <= a.
        p0: the Hertz peak pressure [Pa].
        mu: the Coulomb friction coefficient.

    Returns:
        q(x) [Pa], of the shape of x (in the direction of Q).
    """
    q = mu * hertz_pressure(x, a, p0)
    if c > 0.0:
        q = q - (c / a) * mu * hertz_pressure(x, c, p0)
    return q
