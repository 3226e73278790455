"""The contact laws on Gamma3: one interface, each law written once (numpy and UFL).

A law has no state.  A scalar law (``ScalarLaw``) gives the energy, its derivative and its
second derivative of one scalar per node, vectorised (arrays in, arrays out); it is written
with the primitives of app/model/primitives.py, so the same definition evaluated on UFL
expressions is the integrand of the step energy J_n (forms/step.py) that UFL differentiates.
The laws of the paper:

- normal compliance (4.1), ``NormalCompliance``: P(r) = c_nu / 2 (r^+)^2,
  p(r) = P'(r) = c_nu r^+, for the normal displacement r = u_nu < g; at r = g the law
  allows any -sigma_nu >= c_nu g (the bound u_nu <= g is a constraint of the step problem,
  not a law);
- the memory term xi_n r^+ of (3.4), ``RegularisedPositivePart``: r^+ regularised as
  (r + sqrt(r^2 + delta^2)) / 2, times the nodal xi_n (app/model/gamma3.py), whose kernel
  b(t) is a ``MemoryKernel``;
- nonmonotone friction (4.2), ``PiecewiseLinearFriction``: j_tau(x) = psi(|x|_delta),
  psi' piecewise linear, at the regularised slip |x|_delta = sqrt(|x|^2 + delta^2)
  (``RegularisedNorm``), times theta(s_n) with slip dependence (``SlipWeakening``).

``ContactLaw`` composes them into the nodal energy density of (3.4),
    phi(r, tau; xi, theta) = P(r) + xi r^+_delta + theta psi(|tau|_delta),
and ``contact_law`` builds it from a case.  A new law (a table, a power law, a user's
superpotential) is a new class with the three methods; the condensed solver's nodal problem
(app/solvers/nodal.py) and the forms use it as they are.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from vpcontact.model.laws import ScalarLaw
from vpcontact.model.primitives import backend


@dataclass(frozen=True)
class NormalCompliance(ScalarLaw):
    """Normal compliance (4.1): P(r) = c_nu / 2 (r^+)^2, p(r) = c_nu r^+, p'(r) = c_nu [r > 0].

    Attributes:
        c_nu: the compliance coefficient (a number, or a UFL constant in the forms).
    """

    c_nu: object
    name = "normal compliance"

    def energy(self, r):
        """P(r) = c_nu / 2 (r^+)^2.

        Args:
            r: normal displacements u_nu.

        Returns:
            P(r), elementwise.
        """
        return 0.5 * self.c_nu * backend(r).pos(r) ** 2

    def derivative(self, r):
        """p(r) = c_nu r^+: -sigma_nu for u_nu = r < g (at r = g, the least admissible value).

        Args:
            r: normal displacements u_nu.

        Returns:
            p(r), elementwise.
        """
        return self.c_nu * backend(r).pos(r)

    def second_derivative(self, r):
        """p'(r) = c_nu for r > 0, else 0.

        Args:
            r: normal displacements u_nu.

        Returns:
            p'(r), elementwise (0 at r = 0).
        """
        ops = backend(r)
        return ops.where(ops.gt(r, 0.0), self.c_nu, 0.0)


@dataclass(frozen=True)
class RegularisedPositivePart(ScalarLaw):
    """r^+ regularised as (r + sqrt(r^2 + delta^2)) / 2: the memory term xi_n r^+ of (3.4).

    Attributes:
        delta: the regularisation width.
    """

    delta: object
    name = "memory term xi_n u_nu^+ (regularised)"

    def energy(self, r):
        """(r + sqrt(r^2 + delta^2)) / 2.

        Args:
            r: normal displacements u_nu.

        Returns:
            The regularised r^+, elementwise.
        """
        return 0.5 * (r + backend(r).sqrt(r**2 + self.delta**2))

    def derivative(self, r):
        """(1 + r / sqrt(r^2 + delta^2)) / 2.

        Args:
            r: normal displacements u_nu.

        Returns:
            The derivative, elementwise.
        """
        return 0.5 * (1 + r / backend(r).sqrt(r**2 + self.delta**2))

    def second_derivative(self, r):
        """delta^2 / (2 (r^2 + delta^2)^3/2).

        Args:
            r: normal displacements u_nu.

        Returns:
            The second derivative, elementwise.
        """
        return 0.5 * self.delta**2 / backend(r).sqrt(r**2 + self.delta**2) ** 3


@dataclass(frozen=True)
class PiecewiseLinearFriction(ScalarLaw):
    """The nonmonotone friction law (4.2): the potential psi of the slip rho >= 0,
        psi(rho) = b rho - c1 rho^2 / 2                                    (rho <= u1),
        psi(rho) = c2 / 2 (rho - u1)^2 + (b - c1 u1)(rho - u1) + b u1 - c1 u1^2 / 2,
    so |sigma_tau| = psi'(rho) = b - c1 rho, then c2 (rho - u1) + b - c1 u1 (continuous).

    Attributes:
        b: the friction bound at zero slip.
        c1: the softening slope on [0, u1].
        c2: the hardening slope beyond u1.
        u1: the slip where softening turns into hardening.
    """

    b: object
    c1: object
    c2: object
    u1: object
    name = "friction (regularised Clarke term)"

    def energy(self, rho):
        """psi(rho).

        Args:
            rho: the (regularised) slip |u_tau| >= 0.

        Returns:
            psi(rho), elementwise.
        """
        ops, b, c1, c2, u1 = backend(rho), self.b, self.c1, self.c2, self.u1
        return ops.where(ops.le(rho, u1), b * rho - 0.5 * c1 * rho**2,
                         0.5 * c2 * (rho - u1) ** 2 + (b - c1 * u1) * (rho - u1) + b * u1
                         - 0.5 * c1 * u1**2)

    def derivative(self, rho):
        """psi'(rho), the friction bound |sigma_tau| at slip rho > 0.

        Args:
            rho: the (regularised) slip.

        Returns:
            b - c1 rho for rho <= u1, else c2 (rho - u1) + b - c1 u1.
        """
        ops, b, c1, c2, u1 = backend(rho), self.b, self.c1, self.c2, self.u1
        return ops.where(ops.le(rho, u1), b - c1 * rho, c2 * (rho - u1) + b - c1 * u1)

    def second_derivative(self, rho):
        """psi''(rho), the slope of the friction bound (jumps at u1).

        Args:
            rho: the (regularised) slip.

        Returns:
            -c1 for rho <= u1, else c2.
        """
        ops = backend(rho)
        return ops.where(ops.le(rho, self.u1), -self.c1, self.c2)


@dataclass(frozen=True)
class RegularisedNorm:
    """|x|_delta = sqrt(|x|^2 + delta^2), the regularised slip of the friction term (4.2).

    Attributes:
        delta: the regularisation width.
    """

    delta: object

    def value(self, x):
        """|x|_delta.

        Args:
            x: vectors along the last axis (numpy, shape (..., d)) or a UFL vector.

        Returns:
            |x|_delta, shape (...).
        """
        ops = backend(x)
        return ops.sqrt(ops.sqnorm(x) + self.delta**2)


@dataclass(frozen=True)
class SlipWeakening:
    """The slip dependence of friction: j_tau(s, x) = theta(s) psi(|x|) with
    theta(s) = theta_inf + (1 - theta_inf) exp(-s / s0) of the accumulated slip s.

    Attributes:
        theta_inf: theta(s) for s -> infinity.
        s0: the slip scale.
    """

    theta_inf: float
    s0: float
    name = "slip dependence theta(s_n)"

    def theta(self, s):
        """theta(s).

        Args:
            s: accumulated slips s_n at the nodes.

        Returns:
            theta(s), elementwise.
        """
        return self.theta_inf + (1.0 - self.theta_inf) * backend(s).exp(-s / self.s0)


# ----------------------------------------------------------------------------- memory kernels
class MemoryKernel:
    """The interface of a memory kernel b(t) of the memory term xi_n of (3.4): no state.

    ``recursive`` kernels also give the exact O(1) update of the memory sum
    (app/model/gamma3.py: ``MemorySum``); the others are summed directly.
    """

    recursive = False

    def __call__(self, t):
        """b(t).

        Args:
            t: time(s) since the contribution, >= 0 (a number or an array).

        Returns:
            b(t), elementwise (an array of t's shape).
        """
        raise NotImplementedError

    def recursion(self, xi, r_plus, k):
        """xi_n from xi_{n-1} exactly (recursive kernels only).

        Args:
            xi: xi_{n-1} at the nodes.
            r_plus: u_{n-1,nu}^+ at the nodes.
            k: the step k_n.

        Returns:
            xi_n.
        """
        raise NotImplementedError(f"{type(self).__name__} has no exact recursion")


@dataclass(frozen=True)
class ExponentialKernel(MemoryKernel):
    """b(t) = b0 exp(-beta t), with the exact recursion
    xi_n = exp(-beta k_n) (xi_{n-1} + k_n b0 u_{n-1,nu}^+) (split off the j = n term and factor
    exp(-beta (t_n - t_{n-1})) out of the rest; exact for non-uniform steps).

    Attributes:
        b0: the factor b0.
        beta: the rate.
    """

    b0: float
    beta: float = 0.0
    recursive = True

    def __call__(self, t):
        """b(t) = b0 exp(-beta t).

        Args:
            t: time(s) since the contribution (a number or an array).

        Returns:
            b(t), elementwise.
        """
        return self.b0 * np.exp(-self.beta * np.asarray(t, dtype=float))

    def recursion(self, xi, r_plus, k):
        """xi_n = exp(-beta k_n) (xi_{n-1} + k_n b0 u_{n-1,nu}^+).

        Args:
            xi: xi_{n-1} at the nodes.
            r_plus: u_{n-1,nu}^+ at the nodes.
            k: the step k_n.

        Returns:
            xi_n.
        """
        decay = np.exp(-self.beta * k)
        return decay * (xi + k * self.b0 * r_plus)


@dataclass(frozen=True)
class PowerKernel(MemoryKernel):
    """b(t) = b0 (1 + t / tau)^-alpha.

    Attributes:
        b0: the factor b0.
        alpha: the exponent.
        tau: the time scale.
    """

    b0: float
    alpha: float = 1.0
    tau: float = 1.0

    def __call__(self, t):
        """b(t) = b0 (1 + t / tau)^-alpha.

        Args:
            t: time(s) since the contribution (a number or an array).

        Returns:
            b(t), elementwise.
        """
        return self.b0 * (1.0 + np.asarray(t, dtype=float) / self.tau) ** (-self.alpha)


class TableKernel(MemoryKernel):
    """b(t) = b0 times the piecewise-linear interpolation of a table of (t, b) points.

    Args:
        b0: the factor b0.
        table: the (t, b) points, t increasing.
    """

    def __init__(self, b0: float, table):
        pts = np.asarray(table, dtype=float)
        self.b0, self._ts, self._bs = b0, pts[:, 0], pts[:, 1]

    def __call__(self, t):
        """b(t) = b0 interp(t).

        Args:
            t: time(s) since the contribution (a number or an array).

        Returns:
            b(t), elementwise.
        """
        return self.b0 * np.interp(np.asarray(t, dtype=float), self._ts, self._bs)


def memory_kernel(kind: str, b0: float, beta: float = 0.0, alpha: float = 1.0,
                  tau: float = 1.0, table=None) -> MemoryKernel:
    """The memory kernel a case names.

    Args:
        kind: "exponential", "power" or "table".
        b0: the factor b0.
        beta: the exponential kernel's rate.
        alpha: the power law's exponent.
        tau: the power law's time scale.
        table: (t, b) points of the table kernel.

    Returns:
        The kernel.

    Raises:
        ValueError: an unknown ``kind``.
    """
    if kind == "exponential":
        return ExponentialKernel(b0, beta)
    if kind == "power":
        return PowerKernel(b0, alpha, tau)
    if kind == "table":
        return TableKernel(b0, table)
    raise ValueError(f"unknown kernel {kind!r}")


# ----------------------------------------------------------------------------- composition
class Term(NamedTuple):
    """One term of the nodal energy density: ``factor * law.energy(x)``.

    Attributes:
        law: the scalar law.
        factor: the nodal factor (xi_n, theta(s_n)), or None (1).
        tangential: x is the regularised slip |tau|_delta (True) or r = u_nu (False).
        names: the names of the term in the forms' list (the factor's first).
    """

    law: ScalarLaw
    factor: object
    tangential: bool
    names: tuple


@dataclass(frozen=True)
class ContactLaw:
    """The laws of Gamma3 composed into the nodal energy density of (3.4),
        phi(r, tau; xi, theta) = P(r) + xi r^+_delta + theta psi(|tau|_delta),
    with r = u_nu and tau = u_tau; a part that is None is absent.

    Attributes:
        normal: the normal compliance law P (4.1), or None.
        memory: the law multiplied by the memory term xi_n, or None.
        friction: the friction potential psi (4.2), or None.
        norm: the regularised norm of the slip (with friction).

    The nodal factors xi_n and theta(s_n) come from the Gamma3 history (app/model/gamma3.py,
    with the ``MemoryKernel`` and ``SlipWeakening`` laws).
    """

    normal: ScalarLaw | None = None
    memory: ScalarLaw | None = None
    friction: ScalarLaw | None = None
    norm: RegularisedNorm | None = None

    def terms(self, xi=None, theta=None) -> list[Term]:
        """The terms of phi in order: normal compliance, memory, friction.

        Args:
            xi: the memory term xi_n at the nodes (with ``memory``).
            theta: theta(s_n) at the nodes, or None (1).

        Returns:
            The present terms.
        """
        out = []
        if self.normal is not None:
            out.append(Term(self.normal, None, False, (self.normal.name,)))
        if self.memory is not None:
            out.append(Term(self.memory, xi, False, (self.memory.name,)))
        if self.friction is not None:
            names = (self.friction.name,) if theta is None else \
                (SlipWeakening.name, self.friction.name)
            out.append(Term(self.friction, theta, True, names))
        return out

    def energy_terms(self, r, tau, xi=None, theta=None) -> tuple[list, list[str]]:
        """The terms of phi(r, tau; xi, theta), in numpy or UFL (the integrands of J_n).

        Args:
            r: the normal displacement u_nu.
            tau: the tangential displacement u_tau (vectors along the last axis in numpy).
            xi: the memory term xi_n (with ``memory``).
            theta: theta(s_n), or None (1).

        Returns:
            (the terms' values, their names).
        """
        values, names = [], []
        for term in self.terms(xi, theta):
            x = self.norm.value(tau) if term.tangential else r
            e = term.law.energy(x)
            values.append(e if term.factor is None else term.factor * e)
            names += term.names
        return values, names


def contact_law(contact, delta, const=None) -> ContactLaw:
    """The laws of a case's contact section.

    Args:
        contact: the case's ``contact`` section (c_nu, friction, memory).
        delta: the regularisation width (``solver.delta``).
        const: (name, value) -> the parameter in the laws (the forms' dolfinx Constants);
            None: the numbers themselves.

    Returns:
        The ContactLaw.
    """
    param = const if const is not None else (lambda name, value: value)
    fr = contact.friction
    friction = None if fr is None else \
        PiecewiseLinearFriction(*(param(k, getattr(fr, k)) for k in ("b", "c1", "c2", "u1")))
    normal = None if contact.c_nu is None else NormalCompliance(param("c_nu", contact.c_nu))
    d = param("delta", delta) if fr is not None or contact.memory is not None else None
    return ContactLaw(
        normal=normal,
        memory=None if contact.memory is None else RegularisedPositivePart(d),
        friction=friction, norm=None if fr is None else RegularisedNorm(d))
