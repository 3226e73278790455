"""Contact and friction terms on Gamma3 (paper (4.1)-(4.2)).

All terms enter as energies whose derivative gives the step residual:
- normal compliance P(r) = c_nu / 2 (r^+)^2, P' = p(r) = c_nu r^+;
- friction j_tau(xi) = psi(|xi|_delta), psi of law (4.2), |xi|_delta = sqrt(|xi|^2 + delta^2)
  (the regularised Clarke term: the kink of |xi| at 0 is smoothed over a width delta), times
  theta(s_n) with slip dependence;
- memory term xi_n r^+ with r^+ regularised as (r + sqrt(r^2 + delta^2)) / 2.
The bound u_nu <= g is not a form: it is a box constraint on the normal dofs (SNES VI).
"""
from __future__ import annotations

import ufl

# Quadrature for Gamma3 integrals.  "vertex" is the nodal (trapezoid) rule: it lumps every
# boundary term to the Gamma3 nodes, so the discrete contact and friction laws hold node by
# node.  FFCx 0.5.0's own "vertex" scheme fails on facet integrals (AssertionError); the
# 2-point Gauss-Lobatto rule (GLL, degree 1) on an interval is exactly the trapezoid rule, and
# on triangle facets (3D) a custom rule puts weight 1/6 on each reference vertex.
QUADRATURE = ("vertex", "gauss")


def gamma3_measure(mesh, facet_tags, tag: int, quadrature: str = "vertex", degree: int = 2):
    """The measure ds restricted to Gamma3 with the selected quadrature rule.

    Args:
        mesh: the dolfinx mesh (2D or 3D).
        facet_tags: the boundary facet tags.
        tag: Gamma3's tag.
        quadrature: "vertex" (the nodal rule) or "gauss".
        degree: the Gauss rule's degree (quadrature "gauss").

    Returns:
        The UFL measure.

    Raises:
        ValueError: for an unknown quadrature.
    """
    if quadrature == "vertex" and mesh.topology.dim == 2:
        md = {"quadrature_rule": "GLL", "quadrature_degree": 1}
    elif quadrature == "vertex":   # triangle facets: weight 1/6 at each reference vertex
        md = {"quadrature_rule": "custom",
              "quadrature_points": ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)),
              "quadrature_weights": (1.0 / 6.0,) * 3}
    elif quadrature == "gauss":
        md = {"quadrature_degree": int(degree)}
    else:
        raise ValueError(f"quadrature must be one of {QUADRATURE}, got {quadrature!r}")
    return ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags, subdomain_id=tag, metadata=md)


def positive_part(r):
    """The positive part.

    Args:
        r: a UFL scalar.

    Returns:
        r^+ = max(r, 0).
    """
    return ufl.conditional(ufl.gt(r, 0.0), r, 0.0)


def regularised_positive_part(r, delta):
    """The positive part, regularised (the memory term of (3.4)).

    Args:
        r: a UFL scalar.
        delta: the regularisation width.

    Returns:
        (r + sqrt(r^2 + delta^2)) / 2.
    """
    return 0.5 * (r + ufl.sqrt(r**2 + delta**2))


def normal_compliance_energy(u_nu, c_nu):
    """The normal compliance potential of law (4.1).

    Args:
        u_nu: the normal displacement (UFL scalar).
        c_nu: the normal compliance stiffness.

    Returns:
        P(u_nu) = c_nu / 2 (u_nu^+)^2, whose derivative is p(u_nu) = c_nu u_nu^+.
    """
    return 0.5 * c_nu * positive_part(u_nu) ** 2


def regularised_norm(xi, delta):
    """The regularised norm of the Clarke term.

    Args:
        xi: a UFL vector.
        delta: the regularisation width.

    Returns:
        |xi|_delta = sqrt(xi . xi + delta^2).
    """
    return ufl.sqrt(ufl.dot(xi, xi) + delta**2)


def psi(r, b, c1, c2, u1):
    """The friction potential of law (4.2), psi(r) for r >= 0.

    psi(r) = b r - c1 r^2 / 2                                   for 0 <= r <= u1,
    psi(r) = c2/2 (r-u1)^2 + (b - c1 u1)(r - u1) + b u1 - c1 u1^2/2   for r >= u1,
    so psi'(r) = b - c1 r, then c2 (r - u1) + b - c1 u1: C^1, nonconvex on [0, u1].

    Args:
        r: the slip magnitude (UFL scalar, >= 0).
        b, c1, c2, u1: the law's parameters.

    Returns:
        psi(r) (UFL scalar).
    """
    low = b * r - 0.5 * c1 * r**2
    high = 0.5 * c2 * (r - u1) ** 2 + (b - c1 * u1) * (r - u1) + b * u1 - 0.5 * c1 * u1**2
    return ufl.conditional(ufl.le(r, u1), low, high)


def friction_energy(u_tau, delta, b, c1, c2, u1):
    """The regularised Clarke friction potential of law (4.2).

    Args:
        u_tau: the tangential displacement (UFL vector).
        delta: the regularisation width of |u_tau|.
        b, c1, c2, u1: the law's parameters.

    Returns:
        j_tau(u_tau) = psi(|u_tau|_delta).
    """
    return psi(regularised_norm(u_tau, delta), b, c1, c2, u1)
