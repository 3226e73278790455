"""The contact laws (4.1)-(4.2) in numpy (app/model/contact_laws.py) against their UFL form
(forms/contact.py) and closed forms; the nodal contact energy of the fast solver, compiled
(kernels/contact.c) against its numpy reference (app/solvers/nodal.py)."""
import numpy as np
import pytest
import ufl

from vpcontact import kernels
from vpcontact.forms import contact as forms
from vpcontact.model import contact_laws as laws
from vpcontact.solvers.nodal import NodalContact, nodal_contact_numpy

FR = (1.0, 60.0, 60.0, 0.01)                 # b, c1, c2, u1 of the paper's Sec. 4
ORIGIN = (0.0,)                              # UFL evaluates the constant expressions anywhere


def _ufl(expr) -> float:
    return float(expr(ORIGIN))


def _derivatives(law, x):
    """law(x), law'(x), law''(x) of a UFL scalar law, by UFL's differentiation."""
    v = ufl.variable(ufl.as_ufl(float(x)))
    e = law(v)
    d1 = ufl.diff(e, v)
    return _ufl(e), _ufl(d1), _ufl(ufl.diff(d1, v))


# Chosen points: both branches of (4.2) (and u1 itself), both signs of u_nu, 0, and large and
# small magnitudes.  UFL evaluates the same formulas in Python floats, in its own order (and
# differentiates them symbolically): equal to a few ulps, so 1e-13 relative.
SLIPS = [0.0, 1e-9, 0.003, 0.0099, 0.01, 0.0101, 0.02, 0.5, 12.0]
NORMALS = [-0.3, -1e-8, 0.0, 1e-8, 0.004, 0.012, 2.0]


@pytest.mark.parametrize("rho", SLIPS)
def test_psi_and_its_derivatives_equal_the_ufl_law(rho):
    e, d1, d2 = _derivatives(lambda r: forms.psi(r, *FR), rho)
    assert laws.psi(rho, *FR) == pytest.approx(e, rel=1e-13, abs=1e-300)
    assert laws.dpsi(rho, *FR) == pytest.approx(d1, rel=1e-13, abs=1e-300)
    assert laws.d2psi(rho, *FR) == pytest.approx(d2, rel=1e-13, abs=1e-300)


def test_psi_closed_form():
    """(4.2): psi(0) = 0, psi'(0) = b, continuous psi and psi' at u1, the values there, and
    vectorised evaluation equal to pointwise."""
    b, c1, c2, u1 = FR
    assert laws.psi(0.0, *FR) == 0.0 and laws.dpsi(0.0, *FR) == b
    assert laws.psi(u1, *FR) == pytest.approx(b * u1 - 0.5 * c1 * u1**2, rel=1e-15)
    assert laws.dpsi(u1, *FR) == pytest.approx(b - c1 * u1, rel=1e-15)
    eps = 1e-9
    for f in (laws.psi, laws.dpsi):
        assert f(u1 + eps, *FR) == pytest.approx(f(u1 - eps, *FR), abs=1e-7)
    assert laws.d2psi(u1 - eps, *FR) == -c1 and laws.d2psi(u1 + eps, *FR) == c2
    rho = np.array(SLIPS)
    assert np.array_equal(laws.psi(rho, *FR), [laws.psi(r, *FR) for r in SLIPS])
    assert laws.dpsi(0.02, *FR) == pytest.approx(c2 * (0.02 - u1) + b - c1 * u1, rel=1e-15)


@pytest.mark.parametrize("r", NORMALS)
def test_normal_compliance_equals_the_ufl_law(r):
    c = 100.0
    e, d1, d2 = _derivatives(lambda x: forms.normal_compliance_energy(x, c), r)
    assert laws.normal_compliance_energy(r, c) == pytest.approx(e, rel=1e-14, abs=1e-300)
    assert laws.normal_compliance(r, c) == pytest.approx(d1, rel=1e-14, abs=1e-300)
    assert laws.normal_compliance_slope(r, c) == d2
    assert laws.normal_compliance(r, c) == c * max(r, 0.0)           # (4.1) below the bound


@pytest.mark.parametrize("r", NORMALS)
def test_regularised_positive_part_equals_the_ufl_term(r):
    delta = 1e-7
    e, d1, d2 = _derivatives(lambda x: forms.regularised_positive_part(x, delta), r)
    assert laws.regularised_positive_part(r, delta) == pytest.approx(e, rel=1e-13, abs=1e-300)
    assert laws.regularised_positive_part_slope(r, delta) == pytest.approx(d1, rel=1e-13)
    assert laws.regularised_positive_part_curvature(r, delta) == pytest.approx(d2, rel=1e-13)


def test_regularised_norm_equals_the_ufl_norm():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(5, 3)) * 10.0 ** rng.uniform(-9, 1, size=(5, 1))
    ref = [_ufl(forms.regularised_norm(ufl.as_vector(list(v)), 1e-7)) for v in x]
    assert np.allclose(laws.regularised_norm(x, 1e-7), ref, rtol=1e-14, atol=0.0)
    assert laws.regularised_norm(np.zeros(2), 0.5) == 0.5


def _ufl_phi(y, nu, c, xi, theta, fr, delta):
    """phi(y) of one node and its gradient and Hessian, composed from forms/contact.py."""
    d = len(y)
    yv = ufl.variable(ufl.as_vector([float(a) for a in y]))
    n = ufl.as_vector([float(a) for a in nu])
    r = ufl.dot(yv, n)
    phi = forms.normal_compliance_energy(r, c)
    if xi is not None:
        phi = phi + xi * forms.regularised_positive_part(r, delta)
    if fr is not None:
        phi = phi + theta * forms.friction_energy(yv - r * n, delta, *fr)
    g = ufl.diff(phi, yv)
    H = ufl.diff(g, yv)
    grad = np.array([_ufl(g[i]) for i in range(d)])
    hess = np.array([[_ufl(H[i, j]) for j in range(d)] for i in range(d)])
    return _ufl(phi), grad, hess


@pytest.mark.parametrize("dim", [2, 3])
def test_nodal_reference_equals_the_ufl_energy(dim):
    """The numpy nodal energy (the fast solver's reference) is the SNES path's energy
    density: phi, its gradient and Hessian at nodes in separation, compliance, stick and on
    both slip branches, against UFL's derivatives of forms/contact.py.  The two evaluate the
    same derivatives in different orders (round-off of some 1e-15 of the largest entry), so
    1e-12 of the largest entry."""
    rng = np.random.default_rng(dim)
    nu = np.zeros(dim)
    nu[1] = -1.0
    ys = [rng.normal(size=dim) * s for s in (1e-9, 1e-3, 5e-3, 2e-2, 0.3)]
    w = np.ones(1)
    for y in ys:
        for xi, theta in ((None, 1.0), (2.5, 0.7)):
            e0, g0, H0 = _ufl_phi(y, nu, 100.0, xi, theta, FR, 1e-7)
            e, g, H = nodal_contact_numpy(
                y[None], nu, 100.0, None if xi is None else np.array([xi]),
                np.array([theta]), FR, 1e-7, w)
            assert e == pytest.approx(e0, rel=1e-12)
            assert np.abs(g[0] - g0).max() <= 1e-12 * np.abs(g0).max()
            assert np.abs(H[0] - H0).max() <= 1e-12 * np.abs(H0).max()


# ------------------------------------------------------------------ the C kernel
module = kernels.load()
needs_c = pytest.mark.skipif(module is None, reason="no C compiler")


def _nodes(dim, n, rng):
    """Nodes in separation, compliance, stick (|y_tau| ~ delta) and slip on both branches of
    (4.2) (|y_tau| up to 10 u1)."""
    y = rng.normal(size=(n, dim)) * 10.0 ** rng.uniform(-9, -1, size=(n, 1))
    nu = rng.normal(size=dim)
    return y, nu / np.linalg.norm(nu)


@needs_c
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("friction", [False, True])
@pytest.mark.parametrize("memory", [False, True])
@pytest.mark.parametrize("slip", [False, True])
def test_compiled_nodal_contact_equals_numpy(dim, friction, memory, slip):
    """The C nodal_contact against nodal_contact_numpy: energy, gradient and Hessian.  The
    formulas are the same and in the same order; what differs is the summation of y . nu and
    |y_tau|^2 (a loop in C, BLAS or pairwise sums in numpy, with or without FMA by CPU),
    a few ulps of |y|.  So the tolerance is relative to the largest entry, 1e-12 (the
    differences are some 1e-15 of it on any CPU); the branch of every node is the same."""
    if slip and not friction:
        pytest.skip("theta scales the friction term only")
    rng = np.random.default_rng(11 * dim + 2 * friction + memory)
    n = 400
    y, nu = _nodes(dim, n, rng)
    w = rng.uniform(0.5, 2.0, size=n) / n
    fr = FR if friction else None
    args = (w, nu, 100.0, fr, 1e-7)
    ref, comp = NodalContact(*args), NodalContact(*args, module=module)
    if memory:
        ref.xi = comp.xi = rng.uniform(0.0, 5.0, size=n)
    if slip:
        ref.theta = comp.theta = rng.uniform(0.3, 1.0, size=n)
    e0, g0, H0 = ref.evaluate(y)
    e1, g1, H1 = comp.evaluate(y)
    assert abs(e1 - e0) <= 1e-12 * abs(e0)
    assert np.abs(g1 - g0).max() <= 1e-12 * np.abs(g0).max()
    assert np.abs(H1 - H0).max() <= 1e-12 * np.abs(H0).max()
    e2, g2, H2 = comp.evaluate(y, need_hessian=False)
    assert H2 is None and e2 == e1 and np.array_equal(g2, g1)


@needs_c
def test_compiled_nodal_contact_without_compliance():
    """c_nu = None (friction and memory only) is c = 0 in both."""
    rng = np.random.default_rng(5)
    y, nu = _nodes(2, 100, rng)
    args = (np.full(100, 0.01), nu, None, FR, 1e-7)
    ref, comp = NodalContact(*args), NodalContact(*args, module=module)
    ref.xi = comp.xi = rng.uniform(0.0, 5.0, size=100)
    e0, g0, H0 = ref.evaluate(y)
    e1, g1, H1 = comp.evaluate(y)
    assert abs(e1 - e0) <= 1e-12 * abs(e0)
    assert np.abs(g1 - g0).max() <= 1e-12 * np.abs(g0).max()
    assert np.abs(H1 - H0).max() <= 1e-12 * np.abs(H0).max()
