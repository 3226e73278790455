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
  b(t) is a ``MemoryKernel`` (app/model/memory_kernels.py);
- nonmonotone friction (4.2), ``PiecewiseLinearFriction``: j_tau(x) = psi(|x|_delta),
  psi' piecewise linear, at the regularised slip |x|_delta = sqrt(|x|^2 + delta^2)
  (``RegularisedNorm``), times theta(s_n) with slip dependence (``SlipWeakening``).

The general laws of the model (H(p), H(j_tau)), chosen by the case's keys:

- ``PowerCompliance``: p(x, r) = c_nu(x) (r^+)^m, m >= 1, c_nu a number or a field of x
  (``space_field``: a UFL expression of x in the forms, its values at the nodes in numpy);
- ``TableCompliance``: p(r) piecewise linear through a table from [0, 0], nondecreasing,
  constant beyond its last point;
- ``TableFriction``: tau(rho) = psi'(rho) piecewise linear through a table (nonmonotone,
  tau(0) > 0), linear beyond its last point, psi its exact primitive; m_j of (2.6) is its
  steepest softening;
- ``TableSlip``: theta(s) piecewise linear, constant beyond its last point.

The compliance and friction tables are ``PiecewiseLinear`` functions written as sums of ramps
(r - r_k)^+, so their primitive and slope are exact and serve numpy and UFL alike; they live
in app/model/contact_tables.py.  b(t, x) = b0(x) b(t) (an
expression b0 of x) is summed by app/model/gamma3.py.

``ContactLaw`` composes them into the nodal energy density of (3.4),
    phi(r, tau; xi, theta) = P(r) + xi r^+_delta + theta psi(|tau|_delta),
and ``contact_law`` (app/model/contactregistry.py) builds it from a case.  A new law (a
user's superpotential) is a new class with the three methods; the condensed solver's nodal problem
(app/solvers/nodal.py) and the forms use it as they are (the compiled kernel serves only
the paper's laws with numbers; any other law takes its numpy path).  A user's law replaces
P or psi of the case's through the Python API (``Simulation(case, comm,
contact_laws={"normal": P, "friction": psi})``, ``replace_laws``);
``ContactProblem.contact_law`` (app/model/problem.py) composes the run's laws in one place
for the forms, the condensed solver and the reports.  A law written by the user named in
the case file (``law: python`` of contact.normal_compliance or contact.friction, the class
of ``--law-module FILE.py``) takes the same path: the case's part is a ``PythonLawSlot``
that ContactProblem replaces by the law built from the module (app/model/lawmodule.py:
``python_contact_laws``).  The built-in laws' declarations as laws of the case file
(``ContactLawSpec``, app/model/contactspec.py) follow the classes: SLIP_WEAKENING,
SLIP_TABLE, COMPLIANCE, FRICTION.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.contact_tables import TableCompliance, TableFriction  # noqa: F401
from vpcontact.model.contactspec import (
    EXPRESSION,
    NONNEGATIVE,
    POSITIVE,
    TABLE,
    ContactKey,
    ContactLawSpec,
    Drawing,
    table_points,
)
from vpcontact.model.laws import ScalarLaw
from vpcontact.model.primitives import NUMPY, backend


@dataclass(frozen=True)
class NormalCompliance(ScalarLaw):
    """Normal compliance (4.1): P(r) = c_nu / 2 (r^+)^2, p(r) = c_nu r^+, p'(r) = c_nu [r > 0].

    Attributes:
        c_nu: the compliance coefficient (a number, or a UFL constant in the forms).
    """

    c_nu: object
    name = "normal compliance"

    def constants(self):
        """Returns: c_nu [N/m^3] (p = c_nu r^+)."""
        return {"c_nu": (self.c_nu, "N/m^3")}

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
class PowerCompliance(ScalarLaw):
    """Normal compliance p(r) = c_nu (r^+)^m, m >= 1 (H(p)): P(r) = c_nu / (m + 1)
    (r^+)^(m + 1), p'(r) = m c_nu (r^+)^(m - 1) for r > 0, else 0.

    Attributes:
        c_nu: the coefficient (a number, a UFL expression of x, or an array over the nodes).
        m: the exponent m >= 1 (m = 1 is (4.1)).
    """

    c_nu: object
    m: float
    name = "normal compliance"

    def constants(self):
        """Returns: c_nu [N/m^(2+m)], m [-] (p = c_nu (r^+)^m)."""
        return {"c_nu": (self.c_nu, f"N/m^{2 + self.m:g}"), "m": (self.m, "-")}

    def energy(self, r):
        """P(r) = c_nu / (m + 1) (r^+)^(m + 1).

        Args:
            r: normal displacements u_nu.

        Returns:
            P(r), elementwise.
        """
        return self.c_nu / (self.m + 1.0) * backend(r).pos(r) ** (self.m + 1.0)

    def derivative(self, r):
        """p(r) = c_nu (r^+)^m.

        Args:
            r: normal displacements u_nu.

        Returns:
            p(r), elementwise.
        """
        return self.c_nu * backend(r).pos(r) ** self.m

    def second_derivative(self, r):
        """p'(r) = m c_nu (r^+)^(m - 1) for r > 0, else 0.

        Args:
            r: normal displacements u_nu.

        Returns:
            p'(r), elementwise (0 at r = 0).
        """
        ops = backend(r)
        return ops.where(ops.gt(r, 0.0), self.m * self.c_nu * ops.pos(r) ** (self.m - 1.0),
                         0.0)


@dataclass(frozen=True)
class RegularisedPositivePart(ScalarLaw):
    """r^+ regularised as (r + sqrt(r^2 + delta^2)) / 2: the memory term xi_n r^+ of (3.4).

    Attributes:
        delta: the regularisation width.
    """

    delta: object
    name = "memory term xi_n u_nu^+ (regularised)"

    def constants(self):
        """Returns: delta [m], the regularisation width."""
        return {"delta": (self.delta, "m")}

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

    def constants(self):
        """Returns: b [N/m^2], c1 and c2 [N/m^3], u1 [m] of law (4.2)."""
        return {"b": (self.b, "N/m^2"), "c1": (self.c1, "N/m^3"), "c2": (self.c2, "N/m^3"),
                "u1": (self.u1, "m")}

    @property
    def m_j(self):
        """m_j of (2.6), the relaxed-monotonicity constant: the largest decreasing slope of
        psi' (psi'' = -c1 on [0, u1], c2 >= 0 beyond), so m_j = c1."""
        return self.c1

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

    def constants(self):
        """Returns: theta_inf [-], s0 [m s]."""
        return {"theta_inf": (self.theta_inf, "-"), "s0": (self.s0, "m s")}

    @property
    def theta_max(self) -> float:
        """The largest theta(s), 1 (theta falls from theta(0) = 1 to theta_inf <= 1): the
        factor of the friction law's m_j in (2.6)."""
        return 1.0

    def theta(self, s):
        """theta(s).

        Args:
            s: accumulated slips s_n at the nodes.

        Returns:
            theta(s), elementwise.
        """
        return self.theta_inf + (1.0 - self.theta_inf) * backend(s).exp(-s / self.s0)


class TableSlip:
    """The slip dependence of friction from a table: theta(s) piecewise linear through
    [[0, theta_0], [s_1, theta_1], ...], constant beyond the last point.

    Args:
        table: the points [[s, theta], ...], s increasing from 0, theta in [0, 1].
    """

    name = SlipWeakening.name

    def __init__(self, table):
        pts = np.asarray(table, dtype=float)
        self._s, self._theta = pts[:, 0], pts[:, 1]

    def constants(self):
        """Returns: the table's points, s [m s] against theta [-]."""
        return {"table": ([[float(a), float(b)] for a, b in zip(self._s, self._theta)],
                          "m s, -")}

    @property
    def theta_max(self) -> float:
        """The largest theta(s) of the table: the factor of the friction law's m_j in
        (2.6)."""
        return float(np.max(self._theta))

    def theta(self, s):
        """theta(s).

        Args:
            s: accumulated slips s_n at the nodes (numpy).

        Returns:
            theta(s), elementwise.
        """
        return np.interp(s, self._s, self._theta)


class StaticKineticSlip:
    """The static/kinetic Coulomb coefficient as a slip dependence: the bound mu(s) p_n with
    mu(s) = mu_s - (mu_s - mu_k) min(s / L, 1) is mu_s theta(s) p_n with

        theta(s) = 1 - (1 - mu_k / mu_s) min(s / L, 1)

    (theta = 1 for mu_s = 0), s the accumulated slip of (3.4) and L the slip length.

    Args:
        mu_s: the static coefficient (mu(0)).
        mu_k: the kinetic coefficient (mu(s) for s >= L), 0 <= mu_k <= mu_s.
        slip_length: L > 0 [m s].
    """

    name = "static/kinetic Coulomb slip dependence theta(s) = 1 - (1 - mu_k/mu_s) min(s/L, 1)"

    def __init__(self, mu_s: float, mu_k: float, slip_length: float):
        self.mu_s, self.mu_k, self.slip_length = mu_s, mu_k, slip_length
        self._drop = 1.0 - mu_k / mu_s if mu_s > 0 else 0.0

    def constants(self):
        """Returns: mu_s [-], mu_k [-], slip_length L [m s]."""
        return {"mu_s": (self.mu_s, "-"), "mu_k": (self.mu_k, "-"),
                "slip_length": (self.slip_length, "m s")}

    @property
    def theta_max(self) -> float:
        """The largest theta(s), theta(0) = 1."""
        return 1.0

    def theta(self, s):
        """theta(s) = mu(s) / mu_s.

        Args:
            s: accumulated slips s_n at the nodes (numpy).

        Returns:
            theta(s), elementwise.
        """
        return 1.0 - self._drop * np.minimum(s / self.slip_length, 1.0)


def _check_slip_table(given: dict, path: str, source: str) -> None:
    """contact.friction.slip.table: s from 0, increasing; theta in [0, 1]."""
    _, theta = table_points(given["table"], f"{path}.table", source)
    if any(not 0.0 <= v <= 1.0 for v in theta):
        raise CaseError(f"{source}: {path}.table: theta must be in [0, 1]")


def _check_friction(given: dict, path: str, source: str) -> None:
    """Law (4.2): b - c1 u1 >= 0 (the friction force may not change sign)."""
    if given["b"] - given["c1"] * given["u1"] < 0:
        raise CaseError(f"{source}: {path}: b - c1 u1 must be >= 0 (the friction "
                        f"force of law (4.2) may not change sign), got "
                        f"{given['b'] - given['c1'] * given['u1']:g}")


def _compliance(c: dict, param, x):
    """(4.1) for c_nu without m, else c_nu (r^+)^m; c_nu a number or an expression of x."""
    c_nu = space_field(c["c_nu"], x) if isinstance(c["c_nu"], str) else param("c_nu", c["c_nu"])
    return NormalCompliance(c_nu) if c.get("m") is None else PowerCompliance(c_nu, c["m"])


# the laws of this module as laws of the case file (app/model/contactspec.py), collected by
# app/model/contactregistry.py: the slip laws (SLIPS: build(constants)), the normal
# compliance c_nu (r^+)^m (NORMALS: build(constants, param, x)) and law (4.2) (BOUNDS:
# build(constants, param)); the tables' are app/model/contact_tables.py's
SLIP_WEAKENING = ContactLawSpec(
    name="weakening", formula="theta_inf + (1 - theta_inf) exp(-s/s0)",
    keys={"theta_inf": ContactKey({"type": "number", "minimum": 0, "maximum": 1,
                                   "description": "limit of theta(s) for large accumulated "
                                                  "slip"}),
          "s0": ContactKey({**POSITIVE, "description": "slip scale of theta(s) [m s]"})},
    build=lambda c: SlipWeakening(c["theta_inf"], c["s0"]))
SLIP_TABLE = ContactLawSpec(
    name="table", formula="a table",
    keys={"table": ContactKey({**TABLE, "minItems": 2,
                               "description": "[[s, theta], ...]: theta(s) piecewise linear "
                                              "in the accumulated slip s [m s], s "
                                              "increasing from 0, theta in [0, 1] "
                                              "(dimensionless), constant beyond the last "
                                              "point (instead of theta_inf, s0)"})},
    build=lambda c: TableSlip(c["table"]), check=_check_slip_table)
COMPLIANCE = ContactLawSpec(
    name="power", formula="c_nu (r^+)^m",
    keys={"c_nu": ContactKey({"oneOf": [NONNEGATIVE, EXPRESSION],
                              "description": "stiffness of p(r) = c_nu (r^+)^m [N/m^(2+m)] "
                                             "(m = 1: N/m^3): a number >= 0 or an expression "
                                             "in x, y, z, >= 0 on Gamma3 (p(x, r))"},
                             field="the compliance coefficient"),
          "m": ContactKey({"type": "number", "minimum": 1,
                           "description": "exponent m >= 1 of p(r) = c_nu (r^+)^m "
                                          "(dimensionless; absent: 1, the law (4.1)); only "
                                          "with c_nu"},
                          required=False, only="only with c_nu (a table gives p(r) itself)")},
    build=_compliance,
    levels=lambda c, r: [] if isinstance(c["c_nu"], str) else
    [c["c_nu"] * r ** (c.get("m") or 1.0)])
FRICTION = ContactLawSpec(
    name="4.2", formula="law (4.2)", title="nonmonotone friction (4.2)",
    keys={"b": ContactKey({**NONNEGATIVE, "description": "friction bound at zero slip "
                                                         "[N/m^2]"}),
          "c1": ContactKey({**NONNEGATIVE, "description": "softening slope on 0 < |u_tau| < "
                                                          "u1"}),
          "c2": ContactKey({**NONNEGATIVE, "description": "hardening slope on |u_tau| >= "
                                                          "u1"}),
          "u1": ContactKey({**POSITIVE, "description": "slip where softening turns into "
                                                       "hardening [m]"})},
    build=lambda c, param: PiecewiseLinearFriction(*(param(k, c[k])
                                                     for k in ("b", "c1", "c2", "u1"))),
    check=_check_friction,
    levels=lambda c: [abs(c["b"]), abs(c["c1"] * c["u1"]), abs(c["c2"] * c["u1"])],
    drawing=lambda c: Drawing(3 * c["u1"], "psi'(|u_tau|)", c["b"],
                              "|u_tau| = 0: [0, b] (stick)", (c["u1"], "u1")))


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
    with the ``MemoryKernel`` (app/model/memory_kernels.py) and ``SlipWeakening`` laws).
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


REPLACEABLE = {"normal": "contact.normal_compliance", "friction": "contact.friction"}


def replace_laws(law: ContactLaw, replacements: dict | None) -> ContactLaw:
    """The case's contact laws with some parts replaced by laws given through the Python API
    (``Simulation(case, comm, contact_laws={"normal": P, "friction": psi})``): each a
    ``ScalarLaw`` written with the primitives of ``backend(r)`` (numpy and UFL), replacing
    the normal compliance P (4.1) or the friction potential psi (4.2) of
    phi = P(r) + xi r^+_delta + theta psi(|tau|_delta).  The case keeps the section of the
    part it replaces (its term, the regularisation delta and theta(s) stay the case's).

    Args:
        law: the case's ContactLaw.
        replacements: {"normal" | "friction": ScalarLaw}, or None / {} (``law`` itself).

    Returns:
        The ContactLaw with the parts replaced.

    Raises:
        ValueError: an unknown part, a law without energy, derivative and
            second_derivative, or a part the case does not have.
    """
    if not replacements:
        return law
    parts = {}
    for part, user in replacements.items():
        if part not in REPLACEABLE:
            raise ValueError(f"contact_laws: {part!r} is not a replaceable part (one of "
                             f"{', '.join(REPLACEABLE)})")
        if not all(callable(getattr(user, f, None))
                   for f in ("energy", "derivative", "second_derivative")):
            raise ValueError(f"contact_laws[{part!r}]: {type(user).__name__} is not a "
                             "ScalarLaw (energy, derivative, second_derivative)")
        if getattr(law, part) is None:
            raise ValueError(f"contact_laws[{part!r}]: the case has no {REPLACEABLE[part]} "
                             "(the term a law replaces must be in the case)")
        parts[part] = user
    return replace(law, **parts)


class PythonLawSlot(ScalarLaw):
    """The place of a contact law written by the user (``law: python``) in the case's
    ContactLaw: it names the class and must be replaced (``replace_laws``) by the law built
    from --law-module before it is evaluated.

    Args:
        key: the case's key (contact.normal_compliance or contact.friction).
        spec: the case's PythonLaw (class name, params).
    """

    m_j = None                         # stated by the user's law, not by its place

    def __init__(self, key: str, spec):
        self.key, self.cls, self.params = key, spec.cls, dict(spec.params)
        self.name = f"the user's law {spec.cls}"

    def constants(self):
        """Returns: the params the class is built with (no units)."""
        return {k: (v, "") for k, v in self.params.items()}

    def _unbuilt(self, *_):
        """Evaluating the place itself is an error of the caller."""
        raise RuntimeError(f"{self.key}: the user's law {self.cls} is built from --law-module "
                           "and replaces this place (ContactProblem.contact_law)")

    energy = derivative = second_derivative = _unbuilt


# Coulomb friction: psi(rho) = rho (law (4.2) with b = 1, c1 = c2 = 0), the nodal factor
# mu p_n (app/model/coulomb.py) multiplying it as theta(s_n) does
COULOMB_PSI = {"b": 1.0, "c1": 0.0, "c2": 0.0, "u1": 1.0}


def varies_in_space(contact) -> bool:
    """Whether a contact law's parameter is an expression of x, y, z (c_nu(x)).

    Args:
        contact: the case's ``contact`` section.

    Returns:
        True if the laws need the coordinates ``x`` of ``contact_law``.
    """
    normal = getattr(contact, "normal", None)
    return any(isinstance(v, str) for v in getattr(normal, "constants", {}).values())


def space_field(text: str, x):
    """An expression of x, y, z at points.

    Args:
        text: the expression (checked by the case's validation).
        x: a UFL SpatialCoordinate, numpy coordinates (n, d), or None: the text itself (a
            law built to describe itself, e.g. for summary.json, not to be evaluated).

    Returns:
        The UFL expression, its values (n,), or the text.
    """
    from vpcontact.case import expressions
    if x is None:
        return text
    tree = expressions.parse(text, ("x", "y", "z"))
    if backend(x) is NUMPY:
        pts = np.asarray(x, dtype=float)
        sym = {a: pts[:, i] for i, a in enumerate("xyz"[:pts.shape[1]])}
        sym.setdefault("z", np.zeros(len(pts)))
        return np.broadcast_to(expressions.evaluate(tree, sym), (len(pts),)).copy()
    d = x.ufl_shape[0]
    sym = {a: x[i] for i, a in enumerate("xyz"[:d])}
    sym.setdefault("z", 0.0)
    return expressions.to_ufl(tree, sym)
