"""The wrapper of the compiled nodal contact energy (contact.c).

The C function implements the paper's laws composed as the condensed solver's nodal energy
(app/solvers/nodal.py: ``NodalContact``); its numpy reference is the composition of the law
objects there (``nodal_contact_numpy``), which the tests compare it with.
"""
from __future__ import annotations

import numpy as np

from vpcontact.kernels.build import buf


def nodal_contact(module, y, nu, c, friction, delta, xi, theta, w, grad, hess):
    """E = sum_i w_i phi_i(y_i) with phi = P(r) + xi r^+_delta + theta psi(|y_tau|_delta)
    ((4.1)-(4.2), the memory term of (3.4)), its gradient and nodal Hessian blocks, in C.

    Args:
        module: the compiled kernels (kernels.load()).
        y: the nodal displacements, shape (n, d), C-contiguous floats.
        nu: the unit normal, shape (d,).
        c: the normal compliance coefficient c_nu (0: none).
        friction: (b, c1, c2, u1) of law (4.2), or None (frictionless).
        delta: the regularisation width.
        xi: the memory term xi_n at the nodes, or None.
        theta: theta(s_n) at the nodes, or None (1).
        w: the nodal weights, shape (n,).
        grad: the output gradient, shape (n, d).
        hess: the output Hessian blocks, shape (n, d, d), or None (not computed).

    Returns:
        The energy E (grad and hess are written in place).
    """
    ffi = module.ffi

    def ptr(a):
        return buf(ffi, None if a is None else np.ascontiguousarray(a, dtype=float))
    b, c1, c2, u1 = friction if friction is not None else (0.0, 0.0, 0.0, 0.0)
    return module.lib.nodal_contact(
        y.shape[0], y.shape[1], ptr(y), ptr(nu), c, ptr(xi), ptr(theta),
        int(friction is not None), b, c1, c2, u1, delta, ptr(w), ptr(grad), ptr(hess))
