"""The nodal contact energy of the fast solver's Gamma3 problem.

With the nodal (vertex) Gamma3 rule every boundary term of the step problem (3.4) is a sum of
nodal energies: at node i with weight w_i, displacement y_i, r = y_i . nu and
y_tau = y_i - r nu,
    phi_i(y_i) = P(r) + xi_i (r)^+_delta + theta_i psi(|y_tau|_delta),
with the normal compliance P of (4.1), the memory term xi_n (r^+ regularised) and the friction
potential psi of law (4.2) at the regularised slip |y_tau|_delta, times theta(s_n) with slip
dependence (app/model/contact_laws.py).  ``NodalContact`` evaluates sum_i w_i phi_i, its
gradient and its nodal Hessian blocks by the C kernel nodal_contact (kernels/contact.c)
or, without a C compiler, by ``nodal_contact_numpy``, the reference the tests compare it
with.
"""
from __future__ import annotations

import numpy as np

from vpcontact.kernels import buf
from vpcontact.model import contact_laws as laws


def nodal_contact_numpy(y, nu, c, xi, theta, fr, delta, w, need_hessian=True):
    """sum_i w_i phi_i(y_i), its gradient and nodal Hessian blocks (numpy reference of the
    C kernel nodal_contact).

    Args:
        y: the nodal displacements, shape (n, d).
        nu: the outward unit normal, shape (d,).
        c: the normal compliance coefficient c_nu of (4.1) (0: none).
        xi: the memory term xi_n at the nodes, shape (n,), or None.
        theta: the slip factor theta(s_n) at the nodes, shape (n,), or None (1).
        fr: the friction parameters (b, c1, c2, u1) of (4.2), or None (frictionless).
        delta: the regularisation width.
        w: the nodal weights, shape (n,).
        need_hessian: whether to compute the Hessian blocks.

    Returns:
        (energy, gradient (n, d), Hessian blocks (n, d, d) or None).
    """
    d = y.shape[1]
    r = y @ nu
    energy = laws.normal_compliance_energy(r, c)
    dr = laws.normal_compliance(r, c)
    hr = laws.normal_compliance_slope(r, c)
    if xi is not None:
        energy = energy + xi * laws.regularised_positive_part(r, delta)
        dr = dr + xi * laws.regularised_positive_part_slope(r, delta)
        hr = hr + xi * laws.regularised_positive_part_curvature(r, delta)
    grad = dr[:, None] * nu[None, :]
    H = hr[:, None, None] * np.outer(nu, nu)[None] if need_hessian else None
    if fr is not None:
        tau = y - r[:, None] * nu[None, :]
        rho = laws.regularised_norm(tau, delta)
        psi, d1, d2 = laws.psi(rho, *fr), laws.dpsi(rho, *fr), laws.d2psi(rho, *fr)
        th = theta if theta is not None else 1.0
        energy = energy + th * psi
        grad = grad + (th * d1 / rho)[:, None] * tau
        if need_hessian:
            P = np.eye(d) - np.outer(nu, nu)
            tt = np.einsum("ni,nj->nij", tau, tau)
            H = H + (th * (d2 / rho**2 - d1 / rho**3))[:, None, None] * tt \
                + (th * d1 / rho)[:, None, None] * P[None]
    return np.sum(w * energy), w[:, None] * grad, \
        (w[:, None, None] * H if need_hessian else None)


class NodalContact:
    """Energy, gradient and Hessian of sum_i w_i phi_i(y_i) (vectorised over nodes).

    Args:
        w: the nodal weights of the Gamma3 rule, shape (n,).
        normal: the outward unit normal nu of Gamma3, shape (d,).
        c_nu: the normal compliance coefficient of (4.1), or None.
        friction: (b, c1, c2, u1) of law (4.2), or None (frictionless).
        delta: the regularisation width.
        module: the compiled kernels (kernels.load()), or None: numpy.

    The memory term ``xi`` and slip factor ``theta`` (arrays of length n, or None) are set
    by the caller before each step.
    """

    def __init__(self, w, normal, c_nu, friction, delta, module=None):
        self.w, self.nu = np.ascontiguousarray(w, dtype=float), np.asarray(normal, dtype=float)
        self.c = 0.0 if c_nu is None else c_nu
        self.fr, self.delta = friction, delta
        self.xi = None
        self.theta = None
        self.mod = module                 # kernels' nodal_contact, or None: numpy
        if module is not None:
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
        if self.mod is not None:
            return self._evaluate_compiled(np.ascontiguousarray(y, dtype=float), need_hessian)
        return self._evaluate_numpy(y, need_hessian)

    def _evaluate_compiled(self, y, need_hessian):
        ffi = self.mod.ffi

        def ptr(a):
            return buf(ffi, None if a is None else np.ascontiguousarray(a, dtype=float))
        b, c1, c2, u1 = self.fr if self.fr is not None else (0.0, 0.0, 0.0, 0.0)
        e = self.mod.lib.nodal_contact(
            y.shape[0], y.shape[1], ptr(y), ptr(self.nu), self.c, ptr(self.xi),
            ptr(self.theta), int(self.fr is not None), b, c1, c2, u1, self.delta,
            ptr(self.w), ptr(self._grad), ptr(self._hess if need_hessian else None))
        return e, self._grad, (self._hess if need_hessian else None)

    def _evaluate_numpy(self, y, need_hessian=True):
        return nodal_contact_numpy(y, self.nu, self.c, self.xi, self.theta, self.fr,
                                   self.delta, self.w, need_hessian)
