"""The energy J_n of one time step of scheme (3.2)-(3.4) and its derivatives.

u_n is the stationary point over U^h = {v in V^h : v_nu <= g at Gamma3 nodes} of
  J_n(v) = 1/2 (E eps(v), eps(v)) + (H_n, eps(v)) - f_n(v)
           + int_Gamma3 [ P(v_nu) + xi_n v_nu^+ + theta(s_n) psi(|v_tau|) ]
with H_n the DG0 pre-stress (viscoplastic history).  The residual F = dJ_n/du gives (3.4)
with sigma_n = E eps(u_n) + H_n; the constraint is imposed by SNES VI bounds, not here.
Terms a case does not enable are simply not added (no friction form when frictionless).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import ufl

from . import contact
from .elasticity import elasticity_operator, eps


@dataclass
class StepForms:
    """UFL forms of one step: energy, residual, Jacobian, and the bulk residual.

    ``bulk_residual`` is (E eps(u) + H, eps(v)) - f(v): at a Gamma3 node its value divided by
    the node's weight int phi_i ds is minus the contact force density (sigma nu at the node).
    """

    energy: ufl.Form | None   # None for the implicit variant (no potential)
    residual: ufl.Form
    jacobian: ufl.Form
    bulk_residual: ufl.Form
    terms: list = field(default_factory=list)
    rhs: ufl.Form | None = None   # F_n = f_n(v) - (H_n, eps(v)), the explicit step's load vector
    loads: ufl.Form | None = None  # f_n(v) alone (body force and tractions)
    bulk_jacobian: ufl.Form | None = None      # (E eps(du), eps(v)): constant (explicit)
    boundary_jacobian: ufl.Form | None = None  # the Gamma3 terms' Jacobian alone


def voigt(tau, dim: int):
    """t-coordinates of a symmetric tensor: (t11, t22, t12) or (t11, t22, t33, t23, t13, t12)."""
    pairs = [(0, 0), (1, 1), (0, 1)] if dim == 2 else \
        [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
    return ufl.as_vector([tau[i, j] for i, j in pairs])


def build_step_forms(u, H, *, E, nu, dim=2, f0, tractions, ds, ds_c=None, normal=None,
                     c_nu=None, friction=None, theta=None, xi=None, delta=None,
                     stress=None, tangent=None) -> StepForms:
    """Build J_n and its derivatives.

    Parameters may be floats or dolfinx Constants (Constants keep one compiled form for all
    values).  u: P1 displacement Function; H: DG0 tensor Function (pre-stress H_n) or None;
    f0: body force (UFL vector) or None; tractions: list of (traction UFL vector, subdomain
    id) on Gamma2 parts, integrated with ``ds``; ds_c: Gamma3 measure; normal: nu (tuple);
    c_nu: normal compliance stiffness or None; friction: dict(b, c1, c2, u1) or None;
    theta: P1 Function theta(s_n) of the slip law or None; xi: P1 Function xi_n (memory
    term) or None; delta: regularisation width of |u_tau| and u_nu^+.
    stress, tangent: the implicit history variant (app/model/implicit.py) replaces the elastic
    energy and H_n by the residual (stress, eps(v)) with a per-cell stress Function and the
    Jacobian (tangent eps_t(du)) . eps_t(v) (t-coordinates, shears weighted twice).
    """
    V = u.function_space
    v = ufl.TestFunction(V)
    du = ufl.TrialFunction(V)
    C = elasticity_operator(E, nu, dim)
    dx = ufl.dx(domain=V.mesh)

    loads = 0
    terms = []
    if f0 is not None:
        loads += ufl.dot(f0, u) * dx
        terms.append("body force f0")
    for traction, tag in tractions:
        loads += ufl.dot(traction, u) * ds(tag)
        terms.append(f"traction on part {tag}")
    if stress is None:
        bulk = 0.5 * ufl.inner(C(eps(u)), eps(u)) * dx
        terms.insert(0, "elasticity")
        if H is not None:
            bulk += ufl.inner(H, eps(u)) * dx
            terms.insert(1, "pre-stress H_n")
        if loads != 0:
            bulk -= loads
    else:
        terms.insert(0, "implicit Perzyna stress (algorithmic tangent)")

    boundary = 0
    if c_nu is not None or friction is not None or xi is not None:
        nu_vec = ufl.as_vector(normal)
        u_nu = ufl.dot(u, nu_vec)
        if c_nu is not None:
            boundary += contact.normal_compliance_energy(u_nu, c_nu) * ds_c
            terms.append("normal compliance")
        if xi is not None:
            boundary += xi * contact.regularised_positive_part(u_nu, delta) * ds_c
            terms.append("memory term xi_n u_nu^+ (regularised)")
        if friction is not None:
            u_tau = u - u_nu * nu_vec
            j = contact.friction_energy(u_tau, delta, **friction)
            if theta is not None:
                j = theta * j
                terms.append("slip dependence theta(s_n)")
            boundary += j * ds_c
            terms.append("friction (regularised Clarke term)")

    if stress is None:
        energy = bulk + boundary if boundary != 0 else bulk
        residual = ufl.derivative(energy, u, v)
        jacobian = ufl.derivative(residual, u, du)
        f_n = ufl.derivative(loads, u, v) if loads != 0 else None
        rhs = f_n
        if H is not None:
            rhs = -ufl.inner(H, eps(v)) * dx if rhs is None else rhs - ufl.inner(H, eps(v)) * dx
        bulk_jacobian = ufl.inner(C(eps(du)), eps(v)) * dx
        boundary_jacobian = ufl.derivative(ufl.derivative(boundary, u, v), u, du) \
            if boundary != 0 else None
        return StepForms(energy, residual, jacobian, ufl.derivative(bulk, u, v), terms, rhs,
                         f_n, bulk_jacobian, boundary_jacobian)
    w = [1.0] * dim + [2.0] * (len(voigt(eps(u), dim)) - dim)
    ev = voigt(eps(v), dim)
    weighted = ufl.as_vector([w[i] * ev[i] for i in range(len(w))])
    bulk_residual = ufl.inner(stress, eps(v)) * dx
    if loads != 0:
        bulk_residual -= ufl.derivative(loads, u, v)
    bulk_jacobian = ufl.dot(ufl.dot(tangent, voigt(eps(du), dim)), weighted) * dx
    residual, jacobian = bulk_residual, bulk_jacobian
    if boundary != 0:
        contact_residual = ufl.derivative(boundary, u, v)
        residual = residual + contact_residual
        jacobian = jacobian + ufl.derivative(contact_residual, u, du)
    return StepForms(None, residual, jacobian, bulk_residual, terms)
