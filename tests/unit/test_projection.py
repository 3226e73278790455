"""Exact energy-norm projection onto the von Mises ball (MODEL.md section 2): KKT checks."""
import numpy as np
import pytest

from app.material import PlaneStress, VonMisesProjection


@pytest.fixture(scope="module")
def law():
    return PlaneStress(1000.0, 0.4)


@pytest.fixture(scope="module")
def proj(law):
    return VonMisesProjection(law)


def test_kkt_on_random_stresses(law, proj):
    rng = np.random.default_rng(1)
    s = rng.normal(size=(2000, 3)) * rng.uniform(0.01, 100, size=(2000, 1))
    kappa = rng.uniform(0.0, 50.0, size=2000)
    x = proj(s, kappa)
    vm_x, vm_s = law.von_mises(x), law.von_mises(s)
    outside = vm_s > kappa
    assert outside.sum() > 500 and (~outside).sum() > 100  # both branches exercised
    # feasibility, and the constraint is active for every projected point
    assert np.all(vm_x <= kappa * (1 + 1e-12) + 1e-14)
    np.testing.assert_allclose(vm_x[outside], kappa[outside], rtol=1e-11)
    # normal cone: A (s - x) = mu M x with mu >= 0
    r = (s - x) @ law.A
    mx = x @ law.M
    o = outside
    mu = np.einsum("ni,ni->n", r[o], mx[o]) / np.einsum("ni,ni->n", mx[o], mx[o])
    assert np.all(mu >= 0)
    resid = np.linalg.norm(r[o] - mu[:, None] * mx[o], axis=1) / np.linalg.norm(r[o], axis=1)
    assert resid.max() < 1e-10
    # variational inequality (s - x)^T A (y - x) <= 0 for random feasible y
    for i in np.flatnonzero(o)[:50]:
        y = rng.normal(size=(200, 3))
        y *= (kappa[i] * rng.uniform(0, 1, 200) / np.maximum(law.von_mises(y), 1e-300))[:, None]
        vals = (y - x[i]) @ law.A @ (s[i] - x[i])
        assert vals.max() <= 1e-9 * (1 + np.abs(vals).max())


def test_inside_ball_is_identity(law, proj):
    rng = np.random.default_rng(2)
    s = rng.normal(size=(100, 3))
    kappa = law.von_mises(s) * 1.5
    np.testing.assert_array_equal(proj(s, kappa), s)


def test_kappa_zero_gives_zero(proj):
    rng = np.random.default_rng(3)
    s = rng.normal(size=(100, 3))
    assert np.all(proj(s, np.zeros(100)) == 0.0)


def test_projection_is_energy_closest_point(law, proj):
    """Against brute force: the closest point of the ellipse boundary in the energy norm."""
    s = np.array([[30.0, -5.0, 12.0]])
    kappa = 10.0
    x = proj(s, np.array([kappa]))[0]
    # parametrise the boundary ||y||_VM = kappa: y = kappa * w / ||w||_VM over directions w
    rng = np.random.default_rng(4)
    w = rng.normal(size=(400000, 3))
    y = kappa * w / law.von_mises(w)[:, None]
    d = np.einsum("ni,ij,nj->n", y - s, law.A, y - s)
    dx = (x - s[0]) @ law.A @ (x - s[0])
    assert dx <= d.min() + 1e-12 * d.min()
    assert d.min() - dx < 1e-3 * dx  # the sampled minimum approaches the exact one


# ----------------------------------------------------------------------------- 3D
from app.material import Elasticity, RadialReturn, make_projection  # noqa: E402


@pytest.fixture(scope="module")
def law3():
    return Elasticity(1000.0, 0.3, 3)


def test_3d_closed_form_against_numerical_minimisation(law3):
    """min (y - s)^T A (y - s) s.t. y^T M y <= kappa^2, solved by scipy's SLSQP."""
    from scipy.optimize import minimize

    proj = RadialReturn(law3)
    rng = np.random.default_rng(11)
    M = law3.M
    A = law3.A / np.linalg.norm(law3.A)          # scaled: SLSQP wants O(1) numbers
    for _ in range(20):
        s = rng.normal(size=6) * 20.0
        kappa = rng.uniform(0.5, 15.0)
        x = proj(s[None], np.array([kappa]))[0]
        c = np.linalg.norm(s)
        sc, kc = s / c, kappa / c
        res = minimize(lambda z: (z - sc) @ A @ (z - sc), np.zeros(6),
                       jac=lambda z: 2 * A @ (z - sc),
                       constraints=[{"type": "ineq", "fun": lambda z: kc**2 - z @ M @ z,
                                     "jac": lambda z: -2 * M @ z}],
                       method="SLSQP", options={"ftol": 1e-12, "maxiter": 1000})
        assert res.success, res.message
        y = c * res.x
        fx, fy = (x - s) @ A @ (x - s), (y - s) @ A @ (y - s)
        assert law3.von_mises(x[None])[0] <= kappa * (1 + 1e-12)
        assert law3.von_mises(y[None])[0] <= kappa * (1 + 1e-6)
        assert fx <= fy * (1 + 1e-8)                   # nothing feasible is closer
        np.testing.assert_allclose(x, y, atol=1e-5 * c)


def test_3d_closed_form_equals_generic_projection(law3):
    rng = np.random.default_rng(12)
    s = rng.normal(size=(500, 6)) * 10.0
    kappa = rng.uniform(0.0, 20.0, 500)
    kappa[:5] = 0.0
    closed = RadialReturn(law3)(s, kappa)
    generic = VonMisesProjection(law3)(s, kappa)
    np.testing.assert_allclose(closed, generic, atol=1e-10 * np.abs(s).max())
    # kappa = 0 keeps exactly the hydrostatic part
    mean = s[:5, :3].mean(axis=1)
    np.testing.assert_allclose(closed[:5, :3], np.repeat(mean[:, None], 3, axis=1), atol=1e-13)
    np.testing.assert_allclose(closed[:5, 3:], 0.0, atol=1e-13)
    assert isinstance(make_projection(law3), RadialReturn)


def test_3d_von_mises_is_three_halves_dev_dev(law3):
    from app.material import from_voigt
    rng = np.random.default_rng(13)
    t = rng.normal(size=(50, 6))
    tau = from_voigt(t, 3)
    dev = tau - np.einsum("nii->n", tau)[:, None, None] / 3 * np.eye(3)
    np.testing.assert_allclose(law3.von_mises(t) ** 2, 1.5 * np.einsum("nij,nij->n", dev, dev),
                               rtol=1e-13)
