"""The tabulated contact laws (H(p), H(j_tau)): piecewise-linear functions of a table of
points, written once for numpy and UFL.

- ``PiecewiseLinear``: f through the points as a sum of ramps (x - x_k)^+, with its exact
  primitive and its slope (app/model/primitives.py's backend: numpy and UFL alike);
- ``TableCompliance``: p(r) through [[0, 0], ...], nondecreasing, constant beyond its last
  point, P its exact primitive;
- ``TableFriction``: tau(rho) = psi'(rho) through a table (nonmonotone, tau(0) > 0), linear
  beyond its last point, psi its exact primitive; m_j of (2.6) is its steepest softening.

The slip table theta(s) is ``TableSlip`` in app/model/contact_laws.py, beside the slip
weakening; ``contact_law`` of app/model/contactregistry.py builds every law from a case.
COMPLIANCE_TABLE and FRICTION_TABLE, at the end of the module, declare the two tables as
laws of the case file (app/model/contactspec.py; the registries NORMALS and BOUNDS of
app/model/contactregistry.py).
"""
from __future__ import annotations

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.contactspec import (
    TABLE,
    ContactKey,
    ContactLawSpec,
    Drawing,
    table_points,
    table_values,
)
from vpcontact.model.laws import ScalarLaw
from vpcontact.model.primitives import backend, positive_slip


class PiecewiseLinear:
    """A continuous piecewise-linear function f of a table of points (x_0, f_0), ...,
    (x_K, f_K), x increasing, as a sum of ramps,
        f(x) = f_0 + s_0 (x - x_0) + sum_{k=1..K-1} (s_k - s_{k-1}) (x - x_k)^+,
    s_k the slope on [x_k, x_{k+1}], continued beyond x_K with ``last_slope`` (s_{K-1}: linear
    extrapolation; 0: constant), with its exact primitive F (F(x_0) = 0, piecewise quadratic)
    and its derivative f' (piecewise constant), written with the primitives of
    app/model/primitives.py (numpy and UFL alike).

    Args:
        table: the points [[x, f], ...], at least two, x increasing.
        extrapolate: beyond x_K, "linear" (the last slope) or "constant".
    """

    def __init__(self, table, extrapolate: str = "linear"):
        pts = np.asarray(table, dtype=float)
        self.x, self.f = pts[:, 0], pts[:, 1]
        self.slopes = np.diff(self.f) / np.diff(self.x)                # s_0 .. s_{K-1}
        last = self.slopes[-1] if extrapolate == "linear" else 0.0
        s = np.append(self.slopes, last)
        # the kinks x_1 .. x_K and the slope changes there (a zero change is left out)
        self.kinks = [(float(xk), float(dk)) for xk, dk in zip(self.x[1:], np.diff(s))
                      if dk != 0.0]
        self.x0, self.f0, self.s0 = float(self.x[0]), float(self.f[0]), float(s[0])

    def value(self, x):
        """f(x) (x >= x_0).

        Args:
            x: the argument (numpy array, number or UFL expression).

        Returns:
            f(x), elementwise.
        """
        ops = backend(x)
        out = self.f0 + self.s0 * (x - self.x0)
        for xk, dk in self.kinks:
            out = out + dk * ops.pos(x - xk)
        return out

    def primitive(self, x):
        """F(x) = int_{x_0}^x f, exact (x >= x_0).

        Args:
            x: the argument.

        Returns:
            F(x), elementwise.
        """
        ops = backend(x)
        dx = x - self.x0
        out = self.f0 * dx + 0.5 * self.s0 * dx**2
        for xk, dk in self.kinks:
            out = out + 0.5 * dk * ops.pos(x - xk) ** 2
        return out

    def slope(self, x):
        """f'(x): the slope of the segment of x (the right one at a kink).

        Args:
            x: the argument.

        Returns:
            f'(x), elementwise.
        """
        ops = backend(x)
        out = self.s0 + 0.0 * x
        for xk, dk in self.kinks:
            out = out + ops.where(ops.gt(x, xk), dk, 0.0)
        return out


class TableCompliance(ScalarLaw):
    """Normal compliance from a table (H(p)): p(r) piecewise linear through the points
    [[0, 0], [r_1, p_1], ...] (nondecreasing), constant beyond the last point, 0 for r <= 0;
    P its exact primitive, p' its slope.

    Args:
        table: the points [[r, p], ...], starting at [0, 0].
    """

    name = "normal compliance"

    def __init__(self, table):
        self.p = PiecewiseLinear(table, "constant")

    def constants(self):
        """Returns: the table's points, r [m] against p [N/m^2]."""
        return {"table": ([[float(a), float(b)] for a, b in zip(self.p.x, self.p.f)],
                          "m, N/m^2")}

    def energy(self, r):
        """P(r) = int_0^r p.

        Args:
            r: normal displacements u_nu.

        Returns:
            P(r), elementwise.
        """
        return self.p.primitive(backend(r).pos(r))

    def derivative(self, r):
        """p(r).

        Args:
            r: normal displacements u_nu.

        Returns:
            p(r), elementwise.
        """
        return self.p.value(backend(r).pos(r))

    def second_derivative(self, r):
        """p'(r) (0 for r <= 0).

        Args:
            r: normal displacements u_nu.

        Returns:
            p'(r), elementwise.
        """
        ops = backend(r)
        return ops.where(ops.gt(r, 0.0), self.p.slope(r), 0.0)


class TableFriction(ScalarLaw):
    """Friction from a table (H(j_tau)): the friction stress tau(rho) = psi'(rho) of the slip
    rho = |u_tau| piecewise linear through [[0, tau_0], [rho_1, tau_1], ...] (nonmonotone
    allowed, tau_0 > 0 the bound at zero slip), extrapolated linearly beyond the last point;
    psi its exact primitive (piecewise quadratic, psi(0) = 0), psi'' its slope.  The table
    [[0, b], [u1, b - c1 u1], [2 u1, b - c1 u1 + c2 u1]] is law (4.2).

    Args:
        table: the points [[rho, tau], ...], rho increasing from 0.
    """

    name = "friction (regularised Clarke term)"

    def __init__(self, table):
        self.tau = PiecewiseLinear(table, "linear")

    def constants(self):
        """Returns: the table's points, rho [m] against tau [N/m^2]."""
        return {"table": ([[float(a), float(b)] for a, b in zip(self.tau.x, self.tau.f)],
                          "m, N/m^2")}

    @property
    def m_j(self) -> float:
        """The largest decreasing slope of tau, the constant m_j of (2.6) (0 if none)."""
        return float(max(0.0, -float(np.min(self.tau.slopes))))

    def energy(self, rho):
        """psi(rho) = int_0^rho tau.

        Args:
            rho: the (regularised) slip |u_tau| >= 0.

        Returns:
            psi(rho), elementwise.
        """
        # rho^+ (= rho) keeps a conditional in the UFL form (a table of one segment)
        return self.tau.primitive(positive_slip(rho))

    def derivative(self, rho):
        """psi'(rho) = tau(rho), the friction bound |sigma_tau| at slip rho > 0.

        Args:
            rho: the (regularised) slip.

        Returns:
            tau(rho), elementwise.
        """
        return self.tau.value(rho)

    def second_derivative(self, rho):
        """psi''(rho), the slope of tau (the right one at a kink).

        Args:
            rho: the (regularised) slip.

        Returns:
            psi''(rho), elementwise.
        """
        return self.tau.slope(rho)


def _check_compliance_table(given: dict, path: str, source: str) -> None:
    """contact.normal_compliance.table: r from 0, increasing; p from [0, 0], nondecreasing."""
    path = f"{path}.table"
    _, ps = table_points(given["table"], path, source)
    if ps[0] != 0.0 or any(b < a for a, b in zip(ps, ps[1:])):
        raise CaseError(f"{source}: {path}: p must start at [0, 0] and be nondecreasing "
                        "(H(p): an increasing compliance)")


def _check_friction_table(given: dict, path: str, source: str) -> None:
    """contact.friction.table: rho from 0, increasing; tau(0) > 0, tau >= 0, its last
    segment nondecreasing."""
    path = f"{path}.table"
    _, tau = table_points(given["table"], path, source)
    if not tau[0] > 0:
        raise CaseError(f"{source}: {path}: tau(0) must be > 0 (the friction bound at "
                        f"zero slip), got {tau[0]:g}")
    if min(tau) < 0 or tau[-1] < tau[-2]:
        raise CaseError(f"{source}: {path}: tau must be >= 0 and its last segment "
                        "nondecreasing (it is extrapolated linearly): the friction "
                        "force may not change sign")


# the tables as laws of the case file (app/model/contactspec.py): NORMALS' build(constants,
# param, x), BOUNDS' build(constants, param); their stress levels for the blow-up bound
COMPLIANCE_TABLE = ContactLawSpec(
    name="table", formula="a table",
    keys={"table": ContactKey({**TABLE, "minItems": 2,
                               "description": "[[r, p], ...]: p(r) [N/m^2] piecewise linear "
                                              "in the normal displacement r [m], "
                                              "nondecreasing, starting at [0, 0], constant "
                                              "beyond the last point (instead of c_nu)"})},
    build=lambda c, param, x: TableCompliance(c["table"]), check=_check_compliance_table,
    levels=lambda c, r: [max(p for _, p in c["table"])])
FRICTION_TABLE = ContactLawSpec(
    name="table", formula="a friction table", title="nonmonotone friction (table)",
    keys={"table": ContactKey({**TABLE, "minItems": 2,
                               "description": "[[rho, tau], ...]: the friction stress "
                                              "tau(rho) = psi'(rho) [N/m^2] piecewise linear "
                                              "in the slip rho = |u_tau| [m] (instead of b, "
                                              "c1, c2, u1): rho increasing from 0, tau(0) > 0 "
                                              "the bound at zero slip, tau >= 0, nonmonotone "
                                              "allowed (m_j of (2.6) is the largest "
                                              "decreasing slope), extrapolated linearly "
                                              "beyond the last point (its slope >= 0); psi "
                                              "its exact primitive"})},
    build=lambda c, param: TableFriction(c["table"]), check=_check_friction_table,
    levels=lambda c: table_values(c["table"]),
    drawing=lambda c: Drawing(1.5 * c["table"][-1][0], "tau(|u_tau|) (table)", c["table"][0][1],
                              "|u_tau| = 0: [0, tau(0)] (stick)"))
