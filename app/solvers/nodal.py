"""The nodal contact energy of the condensed solver's Gamma3 problem, composed from the laws.

With the nodal (vertex) Gamma3 rule every boundary term of the step problem (3.4) is a sum of
nodal energies: at node i with weight w_i, displacement y_i, r = y_i . nu and
y_tau = y_i - r nu,
    phi_i(y_i) = P(r) + xi_i (r)^+_delta + theta_i psi(|y_tau|_delta),
the energy density of the case's ``ContactLaw`` (app/model/contact_laws.py: normal
compliance (4.1), memory term, friction (4.2) times theta(s_n)).  ``nodal_contact_numpy``
composes sum_i w_i phi_i, its gradient and its nodal Hessian blocks from the laws' energy,
derivative and second derivative, for any law; for the paper's laws ``NodalContact`` calls
the C kernel nodal_contact (app/kernels/contact.c), whose reference it is; any other law
(a table, c_nu (r^+)^m, c_nu(x) given per node) takes the numpy path.
"""
from __future__ import annotations

import numpy as np

from vpcontact.kernels.contact import nodal_contact
from vpcontact.model.contact_laws import (
    ContactLaw,
    NormalCompliance,
    PiecewiseLinearFriction,
    RegularisedNorm,
    RegularisedPositivePart,
    varies_in_space,
)


def nodal_contact_numpy(y, nu, law: ContactLaw, xi, theta, w, need_hessian=True):
    """sum_i w_i phi_i(y_i), its gradient and nodal Hessian blocks, from the laws (numpy
    reference of the C kernel nodal_contact).

    A term f(r) of r = y . nu adds f' nu and f'' nu nu^T; a term g(rho) of rho = |y_tau|_delta
    adds g'/rho y_tau and (g''/rho^2 - g'/rho^3) y_tau y_tau^T + g'/rho (I - nu nu^T).

    Args:
        y: the nodal displacements, shape (n, d).
        nu: the outward unit normal, shape (d,).
        law: the contact laws.
        xi: the memory term xi_n at the nodes, shape (n,) (with ``law.memory``).
        theta: the slip factor theta(s_n) at the nodes, shape (n,), or None (1).
        w: the nodal weights, shape (n,).
        need_hessian: whether to compute the Hessian blocks.

    Returns:
        (energy, gradient (n, d), Hessian blocks (n, d, d) or None).
    """
    d = y.shape[1]
    r = y @ nu
    energy = dr = hr = np.zeros(len(r))
    tau = rho = None
    grad_tau, hess_tt, hess_p = [], [], []
    for term in law.terms(xi, theta):
        f = 1.0 if term.factor is None else term.factor
        if not term.tangential:
            energy = energy + f * term.law.energy(r)
            dr = dr + f * term.law.derivative(r)
            hr = hr + f * term.law.second_derivative(r)
            continue
        if tau is None:
            tau = y - r[:, None] * nu[None, :]
            rho = law.norm.value(tau)
        d1, d2 = term.law.derivative(rho), term.law.second_derivative(rho)
        energy = energy + f * term.law.energy(rho)
        grad_tau.append(f * d1 / rho)
        hess_tt.append(f * (d2 / rho**2 - d1 / rho**3))
        hess_p.append(f * d1 / rho)
    grad = dr[:, None] * nu[None, :]
    H = hr[:, None, None] * np.outer(nu, nu)[None] if need_hessian else None
    for g in grad_tau:
        grad = grad + g[:, None] * tau
    if need_hessian and tau is not None:
        P = np.eye(d) - np.outer(nu, nu)
        tt = np.einsum("ni,nj->nij", tau, tau)
        for a, b in zip(hess_tt, hess_p):
            H = H + a[:, None, None] * tt + b[:, None, None] * P[None]
    return np.sum(w * energy), w[:, None] * grad, \
        (w[:, None, None] * H if need_hessian else None)


def _kernel_parameters(law: ContactLaw):
    """(c, friction, delta) of the C kernel if it implements every part of the law, else
    None."""
    parts = ((law.normal, NormalCompliance), (law.memory, RegularisedPositivePart),
             (law.friction, PiecewiseLinearFriction), (law.norm, RegularisedNorm))
    if any(part is not None and type(part) is not cls for part, cls in parts):
        return None
    if law.normal is not None and np.ndim(law.normal.c_nu) > 0:      # c_nu(x): numpy
        return None
    deltas = {x.delta for x in (law.memory, law.norm) if x is not None}
    if len(deltas) > 1:
        return None
    fr = law.friction
    return (0.0 if law.normal is None else law.normal.c_nu,
            None if fr is None else (fr.b, fr.c1, fr.c2, fr.u1),
            deltas.pop() if deltas else 0.0)


def gamma3_points(problem, layout):
    """The Gamma3 nodes' coordinates in G order where a contact law's parameter varies in
    space (c_nu(x)); collective.

    Args:
        problem: the ContactProblem (its owned Gamma3 nodes and coordinates, the case).
        layout: the condensed solver's Gamma3Layout (G order).

    Returns:
        (n, d) coordinates on every rank, or None where no parameter varies in space.
    """
    if not varies_in_space(problem.case.contact):
        return None
    return layout.place_on_all(layout.local_owned_g, problem.disc.gamma3.x,
                               (len(layout.g_nodes), problem.disc.dim))


class NodalContact:
    """Energy, gradient and Hessian of sum_i w_i phi_i(y_i) (vectorised over nodes).

    Args:
        w: the nodal weights of the Gamma3 rule, shape (n,).
        normal: the outward unit normal nu of Gamma3, shape (d,).
        law: the contact laws (``contact_law`` of the case, with numbers as parameters).
        module: the compiled kernels (kernels.load()), or None: numpy.  The C kernel serves
            the paper's laws; any other law is evaluated by ``nodal_contact_numpy``.

    The memory term ``xi`` and slip factor ``theta`` (arrays of length n, or None) are set
    by the caller before each step.
    """

    def __init__(self, w, normal, law: ContactLaw, module=None):
        self.w, self.nu = np.ascontiguousarray(w, dtype=float), np.asarray(normal, dtype=float)
        self.law = law
        self.xi = None
        self.theta = None
        params = _kernel_parameters(law) if module is not None else None
        self.mod = module if params is not None else None     # None: numpy
        self._params = params
        if self.mod is not None:
            n, d = len(self.w), len(self.nu)
            self._grad, self._hess = np.empty((n, d)), np.empty((n, d, d))

    def evaluate(self, y, need_hessian=True):
        """The energy and its derivatives at y.

        Args:
            y: the nodal displacements, shape (n, d).
            need_hessian: whether to compute the Hessian blocks.

        Returns:
            (energy, gradient (n, d), Hessian blocks (n, d, d) or None).  The compiled
            kernel returns views of work arrays that the next call overwrites.
        """
        if self.mod is None:
            return nodal_contact_numpy(y, self.nu, self.law, self.xi, self.theta, self.w,
                                       need_hessian)
        c, friction, delta = self._params
        hess = self._hess if need_hessian else None
        e = nodal_contact(self.mod, np.ascontiguousarray(y, dtype=float), self.nu, c, friction,
                          delta, self.xi, self.theta, self.w, self._grad, hess)
        return e, self._grad, hess
