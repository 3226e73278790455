"""The memory kernels b(t) of the memory term xi(t) = int_0^t b(t - s) u_nu^+(s) ds (H(b)):
exponential b0 exp(-beta t) (with its exact O(1) recursion), power b0 (1 + t/tau)^-alpha, a
table, and b0(x) b(t) with b0 an expression of x (``FieldKernel``).  The nodal sums xi_n are
app/model/gamma3.py's.

Each kernel is declared once here by its ``ContactLawSpec`` (app/model/contactspec.py:
EXPONENTIAL, POWER, TABLE, after the classes): its keys of ``contact.memory``, its formula
for the schema, its checks, its factory and its stress level; the registry ``KERNELS`` of
app/model/contactregistry.py collects them (its ``memory_kernel`` builds a kernel by
name).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vpcontact.io.errors import CaseError
from vpcontact.model.contactspec import (
    NONNEGATIVE,
    POSITIVE,
    TABLE,
    ContactKey,
    ContactLawSpec,
    table_values,
)


class MemoryKernel:
    """The interface of a memory kernel b(t) of the memory term xi_n of (3.4): no state.

    ``recursive`` kernels also give the exact O(1) update of the memory sum
    (app/model/gamma3.py: ``MemorySum``); the others are summed directly.
    """

    recursive = False
    name = "memory kernel"

    def constants(self) -> dict:
        """The kernel's constants with their units (``check`` lists them).

        Returns:
            name -> (value, unit).
        """
        return {}

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
    name = "memory kernel b0 exp(-beta t)"

    def constants(self):
        """Returns: b0 [N/(m^3 s)], beta [1/s]."""
        return {"b0": (self.b0, "N/(m^3 s)"), "beta": (self.beta, "1/s")}

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
    name = "memory kernel b0 (1 + t/tau)^-alpha"

    def constants(self):
        """Returns: b0 [N/(m^3 s)], alpha [-], tau [s]."""
        return {"b0": (self.b0, "N/(m^3 s)"), "alpha": (self.alpha, "-"), "tau": (self.tau, "s")}

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

    name = "memory kernel b0 table(t)"

    def __init__(self, b0: float, table):
        pts = np.asarray(table, dtype=float)
        self.b0, self._ts, self._bs = b0, pts[:, 0], pts[:, 1]

    def constants(self):
        """Returns: b0 [N/(m^3 s)] and the table's number of points."""
        return {"b0": (self.b0, "N/(m^3 s)"), "points": (len(self._ts), "-")}

    def __call__(self, t):
        """b(t) = b0 interp(t).

        Args:
            t: time(s) since the contribution (a number or an array).

        Returns:
            b(t), elementwise.
        """
        return self.b0 * np.interp(np.asarray(t, dtype=float), self._ts, self._bs)


class FieldKernel(MemoryKernel):
    """b(t, x) = b0(x) b(t) (H(b)): a kernel of factor 1 whose factor b0(x), an expression
    of x, y, z, multiplies u_{j-1,nu}^+ at each node (app/model/gamma3.py); it describes
    itself with the expression.

    Args:
        kernel: the kernel b(t) of factor 1.
        b0: the expression b0(x).
    """

    def __init__(self, kernel: MemoryKernel, b0: str):
        self.kernel, self.b0 = kernel, b0
        self.recursive = kernel.recursive
        self.name = kernel.name

    def constants(self) -> dict:
        """Returns: the kernel's constants, b0 the expression."""
        out = dict(self.kernel.constants())
        if "b0" in out:
            out["b0"] = (self.b0, out["b0"][1])
        return out

    def __call__(self, t):
        """b(t) of factor 1.

        Args:
            t: time(s) since the contribution (a number or an array).

        Returns:
            b(t) / b0(x), elementwise.
        """
        return self.kernel(t)

    def recursion(self, xi, r_plus, k):
        """The kernel of factor 1's recursion (r_plus already times b0(x)).

        Args:
            xi: xi_{n-1} at the nodes.
            r_plus: b0(x) u_{n-1,nu}^+ at the nodes.
            k: the step k_n.

        Returns:
            xi_n.
        """
        return self.kernel.recursion(xi, r_plus, k)


def _check_table(given: dict, path: str, source: str) -> None:
    """The table kernel's table: times from 0, increasing strictly; values >= 0."""
    ts = [row[0] for row in given["table"]]
    if ts[0] != 0.0 or any(b <= a for a, b in zip(ts, ts[1:])) \
            or any(row[1] < 0 for row in given["table"]):
        raise CaseError(f"{source}: {path}.table: times must start at 0 and increase "
                        "strictly; values must be >= 0")


# the kernels' declarations (app/model/contactspec.py), collected by KERNELS of
# app/model/contactregistry.py: build(constants, b0) -> the kernel of factor b0
EXPONENTIAL = ContactLawSpec(
    name="exponential", formula="b0 exp(-beta t)", recursive=True,
    keys={"beta": ContactKey({**NONNEGATIVE, "default": 0.0,
                              "description": "decay rate of the exponential kernel b0 "
                                             "exp(-beta t) [1/s]"}, required=False)},
    build=lambda c, b0: ExponentialKernel(b0, c.get("beta", 0.0)))
POWER = ContactLawSpec(
    name="power", formula="b0 (1 + t/tau)^-alpha",
    keys={"alpha": ContactKey({**POSITIVE, "description": "exponent of the power kernel"}),
          "tau": ContactKey({**POSITIVE, "description": "time scale of the power kernel "
                                                        "[s]"})},
    build=lambda c, b0: PowerKernel(b0, c["alpha"], c["tau"]))
TABLE_KERNEL = ContactLawSpec(
    name="table", formula="b0 times the piecewise-linear table",
    keys={"table": ContactKey({**TABLE, "description": "[[t, b], ...] of the table "
                                                       "kernel"})},
    build=lambda c, b0: TableKernel(b0, c["table"]), check=_check_table,
    levels=lambda c: table_values(c["table"]))
