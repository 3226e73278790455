"""The primitives the contact laws are written in, with a numpy and a UFL back end.

A law of app/model/contact_laws.py is written once, with Python's arithmetic and these
functions; evaluated on numpy arrays it gives the nodal values of the condensed solver and
the figures, on UFL expressions the integrands of the step energy J_n (forms/step.py), which
UFL differentiates.  The back end is chosen by the argument: a UFL expression selects UFL
(``backend``).  Both back ends perform the same operations in the same order.
"""
from __future__ import annotations

import operator
import sys

import numpy as np


class _Numpy:
    """The primitives on numpy arrays (or floats), elementwise."""

    le, gt = operator.le, operator.gt
    sqrt, exp = np.sqrt, np.exp

    @staticmethod
    def pos(r):
        """r^+ = max(r, 0)."""
        return np.maximum(r, 0.0)

    @staticmethod
    def where(condition, a, b):
        """a where condition holds, else b."""
        return np.where(condition, a, b)

    @staticmethod
    def sqnorm(x):
        """|x|^2 of the vectors along the last axis."""
        return np.sum(np.asarray(x) ** 2, axis=-1)


class _Ufl:
    """The primitives on UFL expressions (ufl is imported where first used: the figures
    evaluate the laws without it)."""

    @staticmethod
    def le(a, b):
        """a <= b."""
        import ufl
        return ufl.le(a, b)

    @staticmethod
    def gt(a, b):
        """a > b."""
        import ufl
        return ufl.gt(a, b)

    @staticmethod
    def sqrt(x):
        """The square root."""
        import ufl
        return ufl.sqrt(x)

    @staticmethod
    def exp(x):
        """The exponential."""
        import ufl
        return ufl.exp(x)

    @staticmethod
    def pos(r):
        """r^+ = max(r, 0)."""
        import ufl
        return ufl.conditional(ufl.gt(r, 0.0), r, 0.0)

    @staticmethod
    def where(condition, a, b):
        """a where condition holds, else b."""
        import ufl
        return ufl.conditional(condition, a, b)

    @staticmethod
    def sqnorm(x):
        """|x|^2 of a UFL vector."""
        import ufl
        return ufl.dot(x, x)


NUMPY = _Numpy()
UFL = _Ufl()


def positive_slip(rho):
    """The regularised slip rho = |u_tau|_delta > 0 as rho^+ (= rho) for a friction law
    psi(rho): in a UFL form it keeps a conditional, without which FFCx 0.5 fails to
    generate the Jacobian of a psi smooth in rho (AttributeError: 'LiteralFloat' object
    has no attribute 'args'; a friction table of one segment, a user's psi = b rho +
    a rho^2 / 2); in numpy the values are rho's.

    Args:
        rho: the regularised slip (numpy array, number or UFL expression).

    Returns:
        rho^+, elementwise.
    """
    return backend(rho).pos(rho)


def backend(x):
    """The back end of an argument.

    Args:
        x: a numpy array, a number or a UFL expression.

    Returns:
        ``UFL`` for a UFL expression, else ``NUMPY``.
    """
    ufl = sys.modules.get("ufl")
    return UFL if ufl is not None and isinstance(x, ufl.core.expr.Expr) else NUMPY
