"""The condensed solver's nodal contact energy (app/solvers/nodal.py), composed from the laws:
its numpy path against UFL's derivatives of the same laws' energy density, the compiled
kernel (app/kernels/contact.c) against the numpy path, and a law the kernel does not know
(evaluated by numpy, whatever module is given)."""
from dataclasses import dataclass

import numpy as np
import pytest
import ufl

from vpcontact import kernels
from vpcontact.model import contact_laws as laws
from vpcontact.model.laws import ScalarLaw
from vpcontact.model.primitives import backend
from vpcontact.solvers.nodal import NodalContact, nodal_contact_numpy

FR = (1.0, 60.0, 60.0, 0.01)                 # b, c1, c2, u1 of the paper's Sec. 4
ORIGIN = (0.0,)
module = kernels.load()
needs_c = pytest.mark.skipif(module is None, reason="no C compiler")


def _law(c_nu=100.0, friction=True, memory=True, delta=1e-7):
    return laws.ContactLaw(
        normal=None if c_nu is None else laws.NormalCompliance(c_nu),
        memory=laws.RegularisedPositivePart(delta) if memory else None,
        friction=laws.PiecewiseLinearFriction(*FR) if friction else None,
        norm=laws.RegularisedNorm(delta) if friction else None)


def _ufl(expr) -> float:
    return float(expr(ORIGIN))


def _ufl_phi(law, y, nu, xi, theta):
    """phi(y) of one node and its gradient and Hessian: the law's energy terms in UFL,
    differentiated by UFL."""
    d = len(y)
    yv = ufl.variable(ufl.as_vector([float(a) for a in y]))
    n = ufl.as_vector([float(a) for a in nu])
    r = ufl.dot(yv, n)
    values, _ = law.energy_terms(r, yv - r * n, xi, theta)
    phi = sum(values)
    g = ufl.diff(phi, yv)
    H = ufl.diff(g, yv)
    grad = np.array([_ufl(g[i]) for i in range(d)])
    hess = np.array([[_ufl(H[i, j]) for j in range(d)] for i in range(d)])
    return _ufl(phi), grad, hess


@pytest.mark.parametrize("dim", [2, 3])
def test_nodal_reference_equals_the_ufl_energy(dim):
    """The numpy nodal energy (the condensed solver's reference) is the SNES path's energy
    density: phi, its gradient and Hessian at nodes in separation, compliance, stick and on
    both slip branches, against UFL's derivatives of the laws' energy.  The two evaluate the
    same derivatives in different orders (round-off of some 1e-15 of the largest entry), so
    1e-12 of the largest entry."""
    rng = np.random.default_rng(dim)
    nu = np.zeros(dim)
    nu[1] = -1.0
    ys = [rng.normal(size=dim) * s for s in (1e-9, 1e-3, 5e-3, 2e-2, 0.3)]
    w = np.ones(1)
    for y in ys:
        for xi, theta in ((None, None), (2.5, 0.7)):
            law = _law(memory=xi is not None)
            e0, g0, H0 = _ufl_phi(law, y, nu, xi, theta)
            e, g, H = nodal_contact_numpy(
                y[None], nu, law, None if xi is None else np.array([xi]),
                None if theta is None else np.array([theta]), w)
            assert e == pytest.approx(e0, rel=1e-12)
            assert np.abs(g[0] - g0).max() <= 1e-12 * np.abs(g0).max()
            assert np.abs(H[0] - H0).max() <= 1e-12 * np.abs(H0).max()


def _nodes(dim, n, rng):
    """Nodes in separation, compliance, stick (|y_tau| ~ delta) and slip on both branches of
    (4.2) (|y_tau| up to 10 u1)."""
    y = rng.normal(size=(n, dim)) * 10.0 ** rng.uniform(-9, -1, size=(n, 1))
    nu = rng.normal(size=dim)
    return y, nu / np.linalg.norm(nu)


def _compare(law, y, nu, w, xi=None, theta=None):
    ref, comp = NodalContact(w, nu, law), NodalContact(w, nu, law, module=module)
    assert ref.mod is None and comp.mod is module
    ref.xi = comp.xi = xi
    ref.theta = comp.theta = theta
    e0, g0, H0 = ref.evaluate(y)
    e1, g1, H1 = comp.evaluate(y)
    assert abs(e1 - e0) <= 1e-12 * abs(e0)
    assert np.abs(g1 - g0).max() <= 1e-12 * np.abs(g0).max()
    assert np.abs(H1 - H0).max() <= 1e-12 * np.abs(H0).max()
    return comp, (e1, g1.copy())


@needs_c
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("friction", [False, True])
@pytest.mark.parametrize("memory", [False, True])
@pytest.mark.parametrize("slip", [False, True])
def test_compiled_nodal_contact_equals_numpy(dim, friction, memory, slip):
    """The C nodal_contact against nodal_contact_numpy: energy, gradient and Hessian.  The
    formulas are the same; what differs is the summation of y . nu and |y_tau|^2 (a loop
    in C, BLAS or pairwise sums in numpy) and the order of a few products, a few ulps of |y|.
    So the tolerance is relative to the largest entry, 1e-12 (the differences are some 1e-15
    of it on any CPU); the branch of every node is the same."""
    if slip and not friction:
        pytest.skip("theta scales the friction term only")
    rng = np.random.default_rng(11 * dim + 2 * friction + memory)
    n = 400
    y, nu = _nodes(dim, n, rng)
    w = rng.uniform(0.5, 2.0, size=n) / n
    xi = rng.uniform(0.0, 5.0, size=n) if memory else None
    theta = rng.uniform(0.3, 1.0, size=n) if slip else None
    comp, (e1, g1) = _compare(_law(friction=friction, memory=memory), y, nu, w, xi, theta)
    e2, g2, H2 = comp.evaluate(y, need_hessian=False)
    assert H2 is None and e2 == e1 and np.array_equal(g2, g1)


@needs_c
def test_compiled_nodal_contact_without_compliance():
    """c_nu = None (friction and memory only) is c = 0 in the kernel."""
    rng = np.random.default_rng(5)
    y, nu = _nodes(2, 100, rng)
    _compare(_law(c_nu=None), y, nu, np.full(100, 0.01), xi=rng.uniform(0.0, 5.0, size=100))


@dataclass(frozen=True)
class PowerCompliance(ScalarLaw):
    """A law the kernel does not know: P(r) = c (r^+)^3 / 3, p = c (r^+)^2."""

    c: float
    name = "power compliance"

    def energy(self, r):
        return self.c * backend(r).pos(r) ** 3 / 3.0

    def derivative(self, r):
        return self.c * backend(r).pos(r) ** 2

    def second_derivative(self, r):
        return 2.0 * self.c * backend(r).pos(r)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_new_law_is_composed_by_numpy(dim):
    """A user's compliance law: NodalContact evaluates it with numpy even when given the
    compiled module, equal to UFL's derivatives of its energy."""
    law = laws.ContactLaw(normal=PowerCompliance(1e4), friction=laws.PiecewiseLinearFriction(
        *FR), norm=laws.RegularisedNorm(1e-7))
    nu = np.zeros(dim)
    nu[-1] = 1.0
    rng = np.random.default_rng(7)
    y = rng.normal(size=(6, dim)) * 0.01
    y[:3, -1] = np.abs(y[:3, -1])                         # some nodes pressed
    contact = NodalContact(np.ones(6), nu, law, module=module)
    assert contact.mod is None
    e, g, H = contact.evaluate(y)
    for i in range(6):
        e0, g0, H0 = _ufl_phi(law, y[i], nu, None, None)
        assert np.abs(g[i] - g0).max() <= 1e-12 * np.abs(g0).max()
        assert np.abs(H[i] - H0).max() <= 1e-12 * np.abs(H0).max()
    assert e == pytest.approx(sum(_ufl_phi(law, y[i], nu, None, None)[0] for i in range(6)),
                              rel=1e-12)
