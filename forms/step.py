"""The energy J_n of one time step of scheme (3.2)-(3.4) and its derivatives.

u_n is the stationary point over U^h = {v in V^h : v_nu <= g at Gamma3 nodes} of
  J_n(v) = 1/2 (E eps(v), eps(v)) + (H_n, eps(v)) - f_n(v)
           + int_Gamma3 [ P(v_nu) + xi_n v_nu^+ + theta(s_n) psi(|v_tau|) ]
with H_n the DG0 pre-stress (viscoplastic history).  The residual F = dJ_n/du gives (3.4)
with sigma_n = E eps(u_n) + H_n; the constraint is imposed by SNES VI bounds, not here.
The data of J_n come in two parts: the bulk (``BulkData``: elasticity, H_n, loads f_n) and
the contact surface Gamma3 (``ContactData``: laws (4.1)-(4.2), memory xi_n, slip theta(s_n)).
Terms a case does not enable are simply not added (no friction form when frictionless).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import ufl

from .elasticity import elasticity_operator, eps, voigt


@dataclass
class StepForms:
    """UFL forms of one step: residual, Jacobian, the bulk residual and the parts of them.

    ``bulk_residual`` is (E eps(u) + H, eps(v)) - f(v): at a Gamma3 node its value divided by
    the node's weight int phi_i ds is minus the contact force density (sigma nu at the node).

    Attributes:
        residual: F = dJ_n/du (3.4) (implicit variant: (sigma, eps(v)) - f_n(v) + Gamma3 terms).
        jacobian: dF/du.
        bulk_residual: the residual without the Gamma3 terms.
        terms: names of the terms present, for logs and tests.
        loads: f_n(v) alone (body force and tractions); None without loads.
        bulk_jacobian: (E eps(du), eps(v)), constant in time (explicit variant only).
        boundary_jacobian: the Gamma3 terms' Jacobian alone (explicit variant, None without
            Gamma3 terms).
        boundary_residual: the Gamma3 terms' residual alone (explicit variant, None without
            Gamma3 terms).
        bulk_load: the bulk residual at u = 0, (H_n, eps(v)) - f_n(v) (explicit variant, None
            without H_n and loads): bulk_residual = bulk_jacobian u + bulk_load.
    """

    residual: ufl.Form
    jacobian: ufl.Form
    bulk_residual: ufl.Form
    terms: list = field(default_factory=list)
    loads: ufl.Form | None = None
    bulk_jacobian: ufl.Form | None = None
    boundary_jacobian: ufl.Form | None = None
    boundary_residual: ufl.Form | None = None
    bulk_load: ufl.Form | None = None


@dataclass
class BulkData:
    """The bulk part of J_n: elasticity, pre-stress H_n and loads f_n.

    Numbers may be floats or dolfinx Constants (Constants keep one compiled form for all
    values).

    Attributes:
        E: Young's modulus (isotropic E; None with ``C``).
        nu: Poisson's ratio (isotropic E; None with ``C``).
        dim: space dimension d (2: plane stress, 3: isotropic Hooke).
        H: DG0 tensor Function, the pre-stress H_n of (3.2)-(3.3), or None.
        f0: body force (UFL vector) or None.
        tractions: (traction UFL vector, subdomain id) pairs on the parts of Gamma2.
        ds: the boundary measure with the facet tags, for the tractions.
        stress: the implicit history variant (app/model/implicit.py): a per-cell stress
            Function whose residual (stress, eps(v)) replaces the elastic energy and H_n.
        tangent: with ``stress``, the algorithmic tangent per cell in t-coordinates (shears
            weighted twice): the Jacobian (tangent eps_t(du)) . eps_t(v).
        C: the operator tau -> E tau of an E other than the isotropic (E, nu) one
            (forms.elasticity.voigt_operator: anisotropic, or per cell), or None.
    """

    E: object
    nu: object
    dim: int = 2
    H: object = None
    f0: object = None
    tractions: list = field(default_factory=list)
    ds: object = None
    stress: object = None
    tangent: object = None
    C: object = None


@dataclass
class ContactData:
    """The Gamma3 part of J_n: normal compliance (4.1), friction (4.2), history terms.

    Attributes:
        ds_c: the Gamma3 measure (forms.contact.gamma3_measure).
        normal: the unit normal nu of Gamma3: a UFL vector (constant where Gamma3 is flat or
            the approach direction is fixed) or the P1 Function of the nodal normals.
        law: the contact laws composed into the energy density phi(u_nu, u_tau; xi, theta)
            (app/model/contact_laws.ContactLaw, its parameters the forms' Constants): its
            ``energy_terms`` gives the integrands and their names.
        theta: P1 Function theta(s_n) of the slip-dependent friction, or None.
        xi: P1 Function xi_n of the memory term, or None.
    """

    ds_c: object
    normal: object
    law: object = None
    theta: object = None
    xi: object = None


def build_step_forms(u, bulk: BulkData, gamma3: ContactData | None = None) -> StepForms:
    """Build J_n of (3.4) and its derivatives.

    Args:
        u: the P1 displacement Function.
        bulk: elasticity, pre-stress H_n and loads f_n (or the implicit variant's stress).
        gamma3: the Gamma3 terms, or None without contact.

    Returns:
        The residual, Jacobian and their bulk and boundary parts.
    """
    dx = ufl.dx(domain=u.function_space.mesh)
    loads, terms = _loads(u, bulk, dx)
    boundary, boundary_terms = _boundary_energy(u, gamma3)
    build = _explicit_forms if bulk.stress is None else _implicit_forms
    forms = build(u, bulk, loads, boundary, terms + boundary_terms, dx)
    # f_n(v) written in v (the same form as d/du f_n(u), without a derivative to expand)
    forms.loads = _loads(ufl.TestFunction(u.function_space), bulk, dx)[0]
    return forms


def build_boundary_forms(w, parts: list[ContactData]):
    """The Gamma3 terms of J_n alone, on a displacement w of their own (two bodies: w at a
    Gamma3 node is the relative displacement less the initial distance, app/model/pairs.py).

    Args:
        w: the P1 Function the Gamma3 terms are evaluated on.
        parts: the Gamma3 terms: one ContactData, or one per pair (laws per pair, each on
            its surface's measure); their energies are summed.

    Returns:
        (residual, jacobian, term names): d/dw and d^2/dw^2 of the boundary energy, or
        (None, None, []) without terms.
    """
    boundary, terms = None, []
    for i, gamma3 in enumerate(parts):
        energy, named = _boundary_energy(w, gamma3)
        if energy is not None:
            boundary = energy if boundary is None else boundary + energy
            terms += named if len(parts) == 1 else [f"pair {i}: {t}" for t in named]
    if boundary is None:
        return None, None, []
    V = w.function_space
    residual = ufl.derivative(boundary, w, ufl.TestFunction(V))
    return residual, ufl.derivative(residual, w, ufl.TrialFunction(V)), terms


def _loads(u, bulk: BulkData, dx):
    """f_n(u) = (f0, u) + sum of (traction, u)_Gamma2-part, or None; the term names."""
    parts, terms = [], []
    if bulk.f0 is not None:
        parts.append(ufl.dot(bulk.f0, u) * dx)
        terms.append("body force f0")
    for traction, tag in bulk.tractions:
        parts.append(ufl.dot(traction, u) * bulk.ds(tag))
        terms.append(f"traction on part {tag}")
    return (sum(parts) if parts else None), terms


def _boundary_energy(u, gamma3: ContactData | None):
    """int_Gamma3 [P(u_nu) + xi_n u_nu^+ + theta(s_n) psi(|u_tau|)] (4.1)-(4.2), regularised
    with delta, or None; the term names."""
    if gamma3 is None or gamma3.law is None:
        return None, []
    nu_vec = gamma3.normal if isinstance(gamma3.normal, ufl.core.expr.Expr) \
        else ufl.as_vector(gamma3.normal)
    u_nu = ufl.dot(u, nu_vec)
    values, terms = gamma3.law.energy_terms(u_nu, u - u_nu * nu_vec, gamma3.xi, gamma3.theta)
    parts = [e * gamma3.ds_c for e in values]
    return (sum(parts) if parts else None), terms


def _explicit_forms(u, bulk: BulkData, loads, boundary, terms, dx) -> StepForms:
    """The paper's scheme: J_n = 1/2 (E eps(u), eps(u)) + (H_n, eps(u)) - f_n(u) + boundary."""
    V = u.function_space
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    C = elasticity_operator(bulk.E, bulk.nu, bulk.dim) if bulk.C is None else bulk.C
    energy = 0.5 * ufl.inner(C(eps(u)), eps(u)) * dx
    named = ["elasticity"]
    linear = []                                   # the energy's terms linear in u
    if bulk.H is not None:
        linear.append(ufl.inner(bulk.H, eps(u)) * dx)
        named.append("pre-stress H_n")
    if loads is not None:
        linear.append(-loads)
    for term in linear:
        energy += term
    bulk_residual = ufl.derivative(energy, u, v)
    boundary_residual = None
    if boundary is not None:
        energy = energy + boundary
        boundary_residual = ufl.derivative(boundary, u, v)
    residual = ufl.derivative(energy, u, v)
    return StepForms(
        residual=residual, jacobian=ufl.derivative(residual, u, du),
        bulk_residual=bulk_residual, terms=named + terms,
        bulk_jacobian=ufl.inner(C(eps(du)), eps(v)) * dx,
        boundary_jacobian=(ufl.derivative(boundary_residual, u, du)
                           if boundary is not None else None),
        boundary_residual=boundary_residual,
        bulk_load=ufl.derivative(sum(linear[1:], linear[0]), u, v) if linear else None)


def _implicit_forms(u, bulk: BulkData, loads, boundary, terms, dx) -> StepForms:
    """The implicit history variant: residual (stress, eps(v)) - f_n(v) + boundary terms, and
    the Jacobian from the algorithmic tangent."""
    V, dim = u.function_space, bulk.dim
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    w = [1.0] * dim + [2.0] * (len(voigt(eps(u), dim)) - dim)
    ev = voigt(eps(v), dim)
    weighted = ufl.as_vector([w[i] * ev[i] for i in range(len(w))])
    bulk_residual = ufl.inner(bulk.stress, eps(v)) * dx
    if loads is not None:
        bulk_residual -= ufl.derivative(loads, u, v)
    bulk_jacobian = ufl.dot(ufl.dot(bulk.tangent, voigt(eps(du), dim)), weighted) * dx
    residual, jacobian = bulk_residual, bulk_jacobian
    if boundary is not None:
        contact_residual = ufl.derivative(boundary, u, v)
        residual = residual + contact_residual
        jacobian = jacobian + ufl.derivative(contact_residual, u, du)
    return StepForms(residual=residual, jacobian=jacobian, bulk_residual=bulk_residual,
                     terms=["implicit Perzyna stress (algorithmic tangent)"] + terms)
