"""The Gamma3 measure of the contact terms of (3.4) (laws (4.1)-(4.2)).

The terms themselves are energies whose derivative gives the step residual; their
integrands come from the contact laws (app/model/contact_laws.py, written once for numpy
and UFL) through ``ContactData.law`` (forms/step.py).  The bound u_nu <= g is not a form:
it is a box constraint on the normal dofs (SNES VI).
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
