"""The closed forms of line contact (tests/references/contact_closed_forms.py) against numbers
worked out by hand from Johnson, Contact Mechanics (ch. 4 and 7), the textbook's other forms
of the same result, and numerical integration of the tractions (scipy quad)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from references.contact_closed_forms import (
    hertz_cylinders,
    hertz_pressure,
    mindlin_shear,
    mindlin_stick_halfwidth,
)

# (P, R1, R2, E1, nu1, E2, nu2): steel on steel, the shipped two-cylinder and Mindlin
# geometries, a cylinder on a rigid flat
CASES = [(1e5, 0.05, 0.05, 210e9, 0.3, 210e9, 0.3),
         (8.63, 1.0, 2.0, 1000.0, 0.3, 2000.0, 0.3),
         (4.32, 1.0, math.inf, 1000.0, 0.3, 1000.0, 0.3),
         (3.0, 1.0, math.inf, 1000.0, 0.25, math.inf, 0.0)]


def _combined(R1, R2, E1, nu1, E2, nu2):
    """R*, E* (plane strain) written out, independently of the module."""
    R = R1 * R2 / (R1 + R2) if math.isfinite(R2) else R1
    E = 1.0 / ((1 - nu1 * nu1) / E1 + ((1 - nu2 * nu2) / E2 if math.isfinite(E2) else 0.0))
    return R, E


def test_hertz_steel_cylinders_by_hand():
    # E* = 210 GPa / (2 (1 - 0.09)) = 115.3846 GPa, R* = 0.025 m, P = 100 kN/m:
    # a = sqrt(4 P R* / (pi E*)) = 0.166093 mm, p0 = 2 P / (pi a) = 383.291 MPa
    a, p0 = hertz_cylinders(1e5, 0.05, 0.05, 210e9, 0.3, 210e9, 0.3)
    assert a == pytest.approx(1.66093e-4, rel=1e-5)
    assert p0 == pytest.approx(3.83291e8, rel=1e-5)


def test_hertz_design_loads_of_the_shipped_geometries():
    # cases/two_cylinders.geo: E* = 1 / (0.91e-3 + 0.455e-3) = 732.601, R* = 2/3: a = 0.1 at
    # P = pi E* a^2 / (4 R*) = 8.63075; cases/mindlin.geo: E* = 1000 / 1.82, R* = 1:
    # P = 4.31537
    assert hertz_cylinders(8.630749, 1.0, 2.0, 1000.0, 0.3, 2000.0, 0.3)[0] == \
        pytest.approx(0.1, rel=1e-7)
    assert hertz_cylinders(4.3153745, 1.0, math.inf, 1000.0, 0.3, 1000.0, 0.3)[0] == \
        pytest.approx(0.1, rel=1e-7)
    # plane stress: E* = 1 / (1e-3 + 0.5e-3)
    assert hertz_cylinders(8.63, 1.0, 2.0, 1000.0, 0.3, 2000.0, 0.3, plane_strain=False)[0] \
        == pytest.approx(0.1048239, rel=1e-6)


@pytest.mark.parametrize("case", CASES)
def test_hertz_equals_the_textbooks_other_forms(case):
    """p0 = E* a / (2 R*) = sqrt(P E* / (pi R*)), and P = pi a^2 E* / (4 R*); swapping the
    bodies changes nothing."""
    P, R1, R2, E1, nu1, E2, nu2 = case
    R, E = _combined(R1, R2, E1, nu1, E2, nu2)
    a, p0 = hertz_cylinders(*case)
    assert p0 == pytest.approx(E * a / (2 * R), rel=1e-12)
    assert p0 == pytest.approx(math.sqrt(P * E / (math.pi * R)), rel=1e-12)
    assert P == pytest.approx(math.pi * a * a * E / (4 * R), rel=1e-12)
    assert hertz_cylinders(P, R2, R1, E2, nu2, E1, nu1) == pytest.approx((a, p0), rel=1e-12)


@pytest.mark.parametrize("case", CASES)
def test_hertz_pressure_carries_the_load(case):
    a, p0 = hertz_cylinders(*case)
    total, err = quad(lambda x: float(hertz_pressure(x, a, p0)), -a, a, epsabs=0,
                      epsrel=1e-11, limit=200)
    assert total == pytest.approx(case[0], rel=1e-8)
    assert hertz_pressure(0.0, a, p0) == pytest.approx(p0, rel=1e-15)
    assert np.all(hertz_pressure(np.array([-2 * a, -a, a, 1.5 * a]), a, p0) == 0.0)


@pytest.mark.parametrize("ratio", [0.0, 0.25, 0.5, 0.9, 1.0])
def test_mindlin_shear_carries_Q_within_the_coulomb_bound(ratio):
    """Q = ratio mu P: the integral of q over the strip is Q; |q| <= mu p everywhere, with
    equality in the slip zones c <= |x| < a; q is continuous at |x| = c."""
    P, mu = 8.63, 0.3
    a, p0 = hertz_cylinders(P, 1.0, 2.0, 1000.0, 0.3, 2000.0, 0.3)
    Q = ratio * mu * P
    c = mindlin_stick_halfwidth(a, Q, mu, P)
    assert c == pytest.approx(a * math.sqrt(1 - ratio), rel=1e-12, abs=1e-15)
    q = lambda x: float(mindlin_shear(x, a, c, p0, mu))  # noqa: E731
    pieces = [(-a, -c), (-c, c), (c, a)] if c > 0 else [(-a, a)]
    total = sum(quad(q, lo, hi, epsabs=0, epsrel=1e-11, limit=200)[0] for lo, hi in pieces)
    assert total == pytest.approx(Q, rel=1e-8, abs=1e-12 * mu * P)
    x = np.linspace(-1.2 * a, 1.2 * a, 2401)
    bound = mu * hertz_pressure(x, a, p0)
    shear = mindlin_shear(x, a, c, p0, mu)
    assert np.all(shear <= bound + 1e-12 * mu * p0) and np.all(shear >= -1e-12 * mu * p0)
    slip = np.abs(x) >= c
    assert np.allclose(shear[slip], bound[slip], rtol=0, atol=1e-12 * mu * p0)
    if 0 < c < a:
        inside = mindlin_shear(c * (1 - 1e-9), a, c, p0, mu)
        assert inside == pytest.approx(mu * hertz_pressure(c, a, p0), rel=1e-4)


def test_mindlin_refuses_gross_sliding():
    with pytest.raises(ValueError, match="no partial slip"):
        mindlin_stick_halfwidth(0.1, 1.01 * 0.3 * 8.63, 0.3, 8.63)
    with pytest.raises(ValueError, match="no partial slip"):
        mindlin_stick_halfwidth(0.1, -1.0, 0.3, 8.63)
