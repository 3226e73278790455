"""The contact laws (app/model/contact_laws.py): each written once, evaluated by the numpy
and the UFL back ends (app/model/primitives.py); their hand-written derivatives against
UFL's differentiation of the same energy; closed forms of (4.1)-(4.2), theta(s) and the
memory kernels; the composition ContactLaw and the builder from a case."""

import numpy as np
import pytest
import ufl

from vpcontact.case.model import Compliance, Contact, Friction
from vpcontact.model import contact_laws as laws
from vpcontact.model import contactregistry as registry
from vpcontact.model.primitives import NUMPY, UFL, backend

FR = (1.0, 60.0, 60.0, 0.01)                 # b, c1, c2, u1 of the paper's Sec. 4
ORIGIN = (0.0,)                              # UFL evaluates the constant expressions anywhere


def _ufl(expr) -> float:
    return float(expr(ORIGIN))


def _ufl_derivatives(energy, x):
    """energy(x), energy'(x), energy''(x) of a law's energy evaluated in UFL, by UFL's
    differentiation."""
    v = ufl.variable(ufl.as_ufl(float(x)))
    e = energy(v)
    d1 = ufl.diff(e, v)
    return _ufl(e), _ufl(d1), _ufl(ufl.diff(d1, v))


# Chosen points: both branches of (4.2) (and u1 itself), both signs of u_nu, 0, and large and
# small magnitudes.  UFL evaluates the same formulas in Python floats, in its own order (and
# differentiates them symbolically): equal to a few ulps, so 1e-13 relative.
SLIPS = [0.0, 1e-9, 0.003, 0.0099, 0.01, 0.0101, 0.02, 0.5, 12.0]
NORMALS = [-0.3, -1e-8, 0.0, 1e-8, 0.004, 0.012, 2.0]
# (law, points, tolerances of energy, derivative, second derivative).  Beyond |r| ~ 1e-4 the
# second derivative of the regularised r^+ is below 1e-12 and UFL's form of it cancels
# (1/sqrt - r^2/sqrt^3), so there it is compared to 1e-12 absolute.
EXACT = {"rel": 1e-13, "abs": 1e-300}
SCALAR_LAWS = [(laws.PiecewiseLinearFriction(*FR), SLIPS, (EXACT, EXACT, EXACT)),
               (laws.NormalCompliance(100.0), NORMALS,
                ({"rel": 1e-14, "abs": 1e-300}, {"rel": 1e-14, "abs": 1e-300}, {"rel": 0.0})),
               (laws.RegularisedPositivePart(1e-7), NORMALS,
                (EXACT, {"rel": 1e-13}, {"rel": 1e-13}))]


def test_backend_follows_the_argument():
    assert backend(np.zeros(3)) is NUMPY and backend(0.5) is NUMPY
    assert backend(ufl.as_ufl(0.5)) is UFL
    x = ufl.as_ufl(-2.0)
    assert _ufl(UFL.pos(x)) == 0.0 and _ufl(UFL.pos(-x)) == 2.0
    assert np.array_equal(NUMPY.pos(np.array([-2.0, 2.0])), [0.0, 2.0])
    assert _ufl(UFL.sqnorm(ufl.as_vector([3.0, 4.0]))) == 25.0
    assert NUMPY.sqnorm(np.array([[3.0, 4.0]]))[0] == 25.0


@pytest.mark.parametrize("law,points,tol", SCALAR_LAWS,
                         ids=["friction (4.2)", "compliance (4.1)", "memory r^+_delta"])
def test_derivatives_are_those_of_the_energy(law, points, tol):
    """The numpy energy equals the same definition in UFL, and the hand-written derivative
    and second derivative equal UFL's derivatives of that energy, at every point."""
    for x in points:
        expected = _ufl_derivatives(law.energy, x)
        got = law.energy(x), law.derivative(x), law.second_derivative(x)
        for value, ref, t in zip(got, expected, tol):
            assert value == pytest.approx(ref, **t), (x, value, ref)
    x = np.array(points)                     # vectorised = pointwise (numpy's array power
    for f in (law.energy, law.derivative, law.second_derivative):    # may differ in an ulp)
        np.testing.assert_allclose(f(x), [f(p) for p in points], rtol=1e-15, atol=0.0)


def test_psi_closed_form():
    """(4.2): psi(0) = 0, psi'(0) = b, continuous psi and psi' at u1, the values there."""
    b, c1, c2, u1 = FR
    psi = laws.PiecewiseLinearFriction(*FR)
    assert psi.energy(0.0) == 0.0 and psi.derivative(0.0) == b
    assert psi.energy(u1) == pytest.approx(b * u1 - 0.5 * c1 * u1**2, rel=1e-15)
    assert psi.derivative(u1) == pytest.approx(b - c1 * u1, rel=1e-15)
    eps = 1e-9
    for f in (psi.energy, psi.derivative):
        assert f(u1 + eps) == pytest.approx(f(u1 - eps), abs=1e-7)
    assert psi.second_derivative(u1 - eps) == -c1 and psi.second_derivative(u1 + eps) == c2
    assert psi.derivative(0.02) == pytest.approx(c2 * (0.02 - u1) + b - c1 * u1, rel=1e-15)
    assert psi.energy(0.02) == pytest.approx(
        0.5 * c2 * 0.01**2 + (b - c1 * u1) * 0.01 + b * u1 - 0.5 * c1 * u1**2, rel=1e-15)


@pytest.mark.parametrize("r", NORMALS)
def test_normal_compliance_closed_form(r):
    """(4.1) below the bound: -sigma_nu = c_nu u_nu^+; P = c_nu / 2 (u_nu^+)^2."""
    p = laws.NormalCompliance(100.0)
    assert p.derivative(r) == 100.0 * max(r, 0.0)
    assert p.energy(r) == pytest.approx(50.0 * max(r, 0.0) ** 2, rel=1e-15)
    assert p.second_derivative(r) == (100.0 if r > 0 else 0.0)


def test_regularised_positive_part_and_norm_closed_forms():
    m = laws.RegularisedPositivePart(0.5)
    assert m.energy(0.0) == 0.25 and m.derivative(0.0) == 0.5 and m.second_derivative(0.0) == 1.0
    assert m.energy(1e6) == pytest.approx(1e6, rel=1e-12) and m.energy(-1e6) < 1e-6
    rng = np.random.default_rng(1)
    x = rng.normal(size=(5, 3)) * 10.0 ** rng.uniform(-9, 1, size=(5, 1))
    norm = laws.RegularisedNorm(1e-7)
    ref = [_ufl(norm.value(ufl.as_vector(list(v)))) for v in x]
    assert np.allclose(norm.value(x), ref, rtol=1e-14, atol=0.0)
    assert np.allclose(norm.value(x), np.sqrt((x**2).sum(axis=1) + 1e-14), rtol=1e-15)
    assert laws.RegularisedNorm(0.5).value(np.zeros(2)) == 0.5


def test_slip_weakening_theta():
    theta = laws.SlipWeakening(theta_inf=0.4, s0=0.01)
    s = np.array([0.0, 0.0125, 1.0])
    expected = [1.0, 0.4 + 0.6 * np.exp(-1.25), 0.4 + 0.6 * np.exp(-100.0)]
    assert np.allclose(theta.theta(s), expected, rtol=1e-15)
    s_ufl = ufl.variable(ufl.as_ufl(0.0125))         # a variable: UFL does not fold it
    assert _ufl(theta.theta(s_ufl)) == pytest.approx(expected[1], rel=1e-15)


def test_memory_kernels_closed_forms():
    t = np.array([0.0, 0.3, 2.0])
    exp = registry.memory_kernel("exponential", 3.0, beta=2.5)
    assert np.allclose(exp(t), 3.0 * np.exp(-2.5 * t), rtol=1e-15) and exp.recursive
    xi, r, k = np.array([1.0, 2.0]), np.array([0.5, 0.0]), 0.1
    assert np.allclose(exp.recursion(xi, r, k), np.exp(-0.25) * (xi + 0.3 * r), rtol=1e-15)
    power = registry.memory_kernel("power", 2.0, alpha=0.7, tau=0.3)
    assert np.allclose(power(t), 2.0 * (1.0 + t / 0.3) ** -0.7, rtol=1e-15)
    table = registry.memory_kernel("table", 2.0, table=[[0, 1.0], [0.5, 0.2], [2, 0.0]])
    assert np.allclose(table(t), [2.0, 2.0 * (1.0 - 0.8 * 0.6), 0.0], rtol=1e-15)
    for kernel in (power, table):
        assert not kernel.recursive
        with pytest.raises(NotImplementedError, match="no exact recursion"):
            kernel.recursion(xi, r, k)
    with pytest.raises(ValueError, match="unknown kernel"):
        registry.memory_kernel("bogus", 1.0)


def _paper_law(memory=True, normal=True):
    return laws.ContactLaw(
        normal=laws.NormalCompliance(100.0) if normal else None,
        memory=laws.RegularisedPositivePart(1e-7) if memory else None,
        friction=laws.PiecewiseLinearFriction(*FR), norm=laws.RegularisedNorm(1e-7))


def test_composition_terms_and_names():
    """phi = P(r) + xi r^+_delta + theta psi(|tau|_delta), term by term, in the forms' order
    of names; absent parts add nothing."""
    r, tau = np.array([0.004, -0.01]), np.array([[0.02, 0.0], [0.0, 0.001]])
    xi, theta = np.array([2.0, 3.0]), np.array([0.5, 0.9])
    values, names = _paper_law().energy_terms(r, tau, xi, theta)
    assert names == ["normal compliance", "memory term xi_n u_nu^+ (regularised)",
                     "slip dependence theta(s_n)", "friction (regularised Clarke term)"]
    rho = np.sqrt((tau**2).sum(axis=1) + 1e-14)
    assert np.allclose(values[0], 50.0 * np.maximum(r, 0.0) ** 2, rtol=1e-15)
    assert np.allclose(values[1], xi * 0.5 * (r + np.sqrt(r**2 + 1e-14)), rtol=1e-15)
    assert np.allclose(values[2], theta * laws.PiecewiseLinearFriction(*FR).energy(rho))
    values, names = _paper_law(memory=False, normal=False).energy_terms(r, tau)
    assert names == ["friction (regularised Clarke term)"] and len(values) == 1
    assert laws.ContactLaw().energy_terms(r, tau) == ([], [])


def test_contact_law_from_a_case():
    """The builder: each parameter through ``const`` once (delta shared by the memory term
    and the norm), in the order the forms' Constants were always made; absent parts None."""
    fr = Friction("4.2", {"b": 1.0, "c1": 60.0, "c2": 50.0, "u1": 0.01})
    contact = Contact(None, Compliance("power", {"c_nu": 100.0}), fr, memory=object())
    made = []

    def const(name, value):
        made.append(name)
        return ("C", name, value)
    law = registry.contact_law(contact, 1e-7, const)
    assert made == ["b", "c1", "c2", "u1", "c_nu", "delta"]
    assert law.normal == laws.NormalCompliance(("C", "c_nu", 100.0))
    assert law.friction.c2 == ("C", "c2", 50.0)
    assert law.memory.delta is law.norm.delta
    plain = registry.contact_law(Contact(None, None, None), 1e-7)
    assert plain == laws.ContactLaw()
    numbers = registry.contact_law(contact, 1e-7)
    assert numbers.friction == laws.PiecewiseLinearFriction(1.0, 60.0, 50.0, 0.01)
    assert numbers.norm == laws.RegularisedNorm(1e-7)
