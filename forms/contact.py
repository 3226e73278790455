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
    """The measure ds restricted to Gamma3 with the selected quadrature rule."""
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
    """r^+ = max(r, 0)."""
    return ufl.conditional(ufl.gt(r, 0.0), r, 0.0)


def regularised_positive_part(r, delta):
    """r^+ regularised as (r + sqrt(r^2 + delta^2)) / 2."""
    return 0.5 * (r + ufl.sqrt(r**2 + delta**2))


def normal_compliance_energy(u_nu, c_nu):
    """P(u_nu) = c_nu / 2 (u_nu^+)^2, whose derivative is p(u_nu) = c_nu u_nu^+ (4.1)."""
    return 0.5 * c_nu * positive_part(u_nu) ** 2


def regularised_norm(xi, delta):
    """|xi|_delta = sqrt(xi . xi + delta^2)."""
    return ufl.sqrt(ufl.dot(xi, xi) + delta**2)


def psi(r, b, c1, c2, u1):
    """The friction potential of law (4.2), psi(r) for r >= 0:

    psi(r) = b r - c1 r^2 / 2                                   for 0 <= r <= u1,
    psi(r) = c2/2 (r-u1)^2 + (b - c1 u1)(r - u1) + b u1 - c1 u1^2/2   for r >= u1,
    so psi'(r) = b - c1 r, then c2 (r - u1) + b - c1 u1: C^1, nonconvex on [0, u1].
    """
    low = b * r - 0.5 * c1 * r**2
    high = 0.5 * c2 * (r - u1) ** 2 + (b - c1 * u1) * (r - u1) + b * u1 - 0.5 * c1 * u1**2
    return ufl.conditional(ufl.le(r, u1), low, high)


def friction_energy(u_tau, delta, b, c1, c2, u1):
    """j_tau(u_tau) = psi(|u_tau|_delta), the regularised Clarke friction potential."""
    return psi(regularised_norm(u_tau, delta), b, c1, c2, u1)
