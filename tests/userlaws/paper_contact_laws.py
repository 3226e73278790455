"""Contact laws written as a user would, for --law-module in the tests: the paper's normal
compliance (4.1) and nonmonotone friction (4.2) (Section 4) typed out from the paper's
formulas as ScalarLaws with the primitives of backend(x) (numpy at the nodes, UFL in the
forms), not the built-in classes; a compliance that is a duck-typed law (no ScalarLaw base);
and objects that break the protocol (no second derivative, wrong shapes, NaN, numpy's
functions, a negative m_j, a derivative that raises during the run); a friction psi smooth
in the slip with a constant psi'' (QuadraticFriction)."""
import numpy as np

from vpcontact.model.laws import ScalarLaw
from vpcontact.model.primitives import backend


class UserCompliance(ScalarLaw):
    """(4.1): P(r) = c/2 (r^+)^2, p(r) = c r^+, p'(r) = c for r > 0, else 0."""

    name = "user compliance (4.1)"

    def __init__(self, c):
        self.c = c

    def energy(self, r):
        return 0.5 * self.c * backend(r).pos(r) ** 2

    def derivative(self, r):
        return self.c * backend(r).pos(r)

    def second_derivative(self, r):
        ops = backend(r)
        return ops.where(ops.gt(r, 0.0), self.c, 0.0)


class UserFriction(ScalarLaw):
    """(4.2): psi'(rho) = b - c1 rho for rho <= u1, then c2 (rho - u1) + b - c1 u1; psi its
    primitive from psi(0) = 0; m_j = c1, the softening slope."""

    name = "user friction (4.2)"

    def __init__(self, b, c1, c2, u1):
        self.b, self.c1, self.c2, self.u1 = b, c1, c2, u1
        self.m_j = c1

    def energy(self, rho):
        ops, b, c1, c2, u1 = backend(rho), self.b, self.c1, self.c2, self.u1
        return ops.where(ops.le(rho, u1), b * rho - 0.5 * c1 * rho**2,
                         0.5 * c2 * (rho - u1) ** 2 + (b - c1 * u1) * (rho - u1) + b * u1
                         - 0.5 * c1 * u1**2)

    def derivative(self, rho):
        ops, b, c1, c2, u1 = backend(rho), self.b, self.c1, self.c2, self.u1
        return ops.where(ops.le(rho, u1), b - c1 * rho, c2 * (rho - u1) + b - c1 * u1)

    def second_derivative(self, rho):
        ops = backend(rho)
        return ops.where(ops.le(rho, self.u1), -self.c1, self.c2)


class UnstatedFriction(UserFriction):
    """UserFriction that states no m_j ((2.6) is then not checked)."""

    def __init__(self, b, c1, c2, u1):
        super().__init__(b, c1, c2, u1)
        del self.m_j


class DuckCompliance:
    """(4.1) without the ScalarLaw base: the three methods are enough."""

    def __init__(self, c):
        self.c = c

    def energy(self, r):
        return 0.5 * self.c * backend(r).pos(r) ** 2

    def derivative(self, r):
        return self.c * backend(r).pos(r)

    def second_derivative(self, r):
        ops = backend(r)
        return ops.where(ops.gt(r, 0.0), self.c, 0.0)


class NoSecondDerivative:
    """Energy and derivative only: not a contact law."""

    def __init__(self, c):
        self.c = c

    def energy(self, r):
        return 0.5 * self.c * r**2

    def derivative(self, r):
        return self.c * r


class WrongShape(UserCompliance):
    """The derivative as one number per call (the sum), not per node."""

    def derivative(self, r):
        return np.array([np.sum(self.c * np.maximum(r, 0.0))] * 2)


class NotFinite(UserCompliance):
    """The energy divided by r: NaN at r = 0."""

    def energy(self, r):
        with np.errstate(invalid="ignore", divide="ignore"):
            return 0.5 * self.c * r**3 / r


class NumpyOnly(UserCompliance):
    """(4.1) with numpy's functions: right on arrays, no UFL expression for the forms."""

    def energy(self, r):
        return 0.5 * self.c * np.maximum(r, 0.0) ** 2


class NegativeMj(UserFriction):
    """m_j < 0."""

    def __init__(self, b, c1, c2, u1):
        super().__init__(b, c1, c2, u1)
        self.m_j = -1.0


class QuadraticFriction(ScalarLaw):
    """psi(rho) = b rho + a rho^2 / 2 written as plain arithmetic (no conditional): psi' =
    b + a rho, psi'' = a returned as the number itself; m_j = 0 (psi' increases).  The
    friction table [[0, b], [1, b + a]] (linear beyond its last point) is the same law."""

    name = "quadratic friction"
    m_j = 0.0

    def __init__(self, b, a):
        self.b, self.a = b, a

    def energy(self, rho):
        return self.b * rho + 0.5 * self.a * rho * rho

    def derivative(self, rho):
        return self.b + self.a * rho

    def second_derivative(self, rho):
        return self.a


class RaisingCompliance(UserCompliance):
    """UserCompliance whose derivative raises (KeyError) once r exceeds a level: accepted
    before the run (the probe stays below), the step that reaches it fails."""

    def __init__(self, c, level):
        super().__init__(c)
        self.level = level

    def derivative(self, r):
        if not hasattr(r, "ufl_shape") and np.max(r, initial=0.0) > self.level:
            raise KeyError("beyond my table")
        return super().derivative(r)
