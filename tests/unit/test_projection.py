"""Exact energy-norm projection onto the von Mises ball: KKT checks, and references that
cannot depend on the CPU or BLAS (bisection on the multiplier, brute-force sampling)."""
import numpy as np
import pytest

from vpcontact.model.material import PlaneStress, VonMisesProjection


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
from vpcontact.model.material import Elasticity, RadialReturn, make_projection  # noqa: E402


@pytest.fixture(scope="module")
def law3():
    return Elasticity(1000.0, 0.3, 3)


def _bisection_projection(law, s, kappa):
    """Reference projection by bisection on the scalar multiplier (no optimiser, no
    iteration tolerance): x(mu) = (A + mu M)^-1 A s and phi(mu) = x(mu)^T M x(mu) decreases
    strictly in mu (phi' = -2 (M x)^T (A + mu M)^-1 M x), so the root of phi(mu) = kappa^2 is
    bracketed and halved until the bracket has no float inside.  Returns (x, mu)."""
    A, M = law.A, law.M
    As = A @ s

    def x_of(mu):
        return np.linalg.solve(A + mu * M, As)

    def phi(mu):
        x = x_of(mu)
        return x @ M @ x

    if phi(0.0) <= kappa * kappa:
        return s.copy(), 0.0
    lo, hi = 0.0, 1.0 / np.abs(A).max()
    while phi(hi) > kappa * kappa:
        hi *= 2.0
    while lo < 0.5 * (lo + hi) < hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if phi(mid) > kappa * kappa else (lo, mid)
    return x_of(hi), hi


@pytest.mark.parametrize("dim", [2, 3])
def test_projection_satisfies_kkt_and_equals_bisection(dim):
    """min (y - s)^T A (y - s) s.t. ||y||_VM <= kappa: the closed form (3D) and the secular
    Newton iteration (2D) against the KKT conditions in closed form and the bisection
    reference, and the variational inequality against feasible points."""
    law = Elasticity(1000.0, 0.3, 3) if dim == 3 else PlaneStress(1000.0, 0.4)
    proj = make_projection(law)
    A, M = law.A, law.M
    rng = np.random.default_rng(11)
    for i in range(24):
        s = rng.normal(size=law.m) * 20.0
        kappa = rng.uniform(0.5, 15.0) if i % 4 else 2.0 * law.von_mises(s[None])[0]
        x = proj(s[None], np.array([kappa]))[0]
        vm_x, vm_s = law.von_mises(x[None])[0], law.von_mises(s[None])[0]
        ref, mu_ref = _bisection_projection(law, s, kappa)
        assert np.abs(x - ref).max() <= 1e-12 * np.abs(s).max()
        assert vm_x <= kappa * (1 + 1e-12)                                  # feasibility
        if vm_s <= kappa:                            # inside: P s = s (3D: mean + dev)
            assert np.abs(x - s).max() <= 1e-15 * np.abs(s).max() and mu_ref == 0.0
            continue
        # stationarity A (x - s) + mu M x = 0 with the least-squares multiplier
        r, Mx = A @ (s - x), M @ x
        mu = (Mx @ r) / (Mx @ Mx)
        assert mu >= 0.0                                                     # sign
        assert np.linalg.norm(A @ (x - s) + mu * Mx) <= 1e-12 * np.linalg.norm(A @ s)
        assert abs(mu - mu_ref) <= 1e-10 * mu_ref
        assert abs(vm_x - kappa) <= 1e-12 * kappa           # complementarity: mu > 0, active
        # variational inequality (y - x)^T A (s - x) <= 0 for feasible y (inside and on
        # the boundary); true for every y, so the sample cannot matter
        w = rng.normal(size=(500, law.m))
        y = w * (kappa * rng.uniform(0.0, 1.0, 500) / law.von_mises(w))[:, None]
        y[:250] = w[:250] * (kappa / law.von_mises(w[:250]))[:, None]
        assert ((y - x) @ A @ (s - x)).max() <= 1e-12 * (s @ A @ s)


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
    from vpcontact.model.material import from_voigt
    rng = np.random.default_rng(13)
    t = rng.normal(size=(50, 6))
    tau = from_voigt(t, 3)
    dev = tau - np.einsum("nii->n", tau)[:, None, None] / 3 * np.eye(3)
    np.testing.assert_allclose(law3.von_mises(t) ** 2, 1.5 * np.einsum("nij,nij->n", dev, dev),
                               rtol=1e-13)
