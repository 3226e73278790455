"""The compiled Perzyna update (app/solvers/kernels.py) equals the numpy reference (material.py)."""
import numpy as np
import pytest

from app.solvers import kernels
from app.model.material import Elasticity, Perzyna, VonMisesProjection, from_voigt, to_voigt

module = kernels.load()
pytestmark = pytest.mark.skipif(module is None, reason="no C compiler")


def _reference(law, sigma, H, kappa, k, l1, l2):
    t = to_voigt(sigma, law.dim)
    gs, gk = Perzyna(law, l1, l2).rates(t, kappa)
    return H + k * from_voigt(gs, law.dim).reshape(-1), kappa + k * gk


@pytest.mark.parametrize("dim", [2, 3])
def test_kernel_equals_numpy(dim):
    rng = np.random.default_rng(dim)
    law = Elasticity(1000.0, 0.4 if dim == 2 else 0.3, dim)
    n = 4000
    t = rng.normal(size=(n, law.m)) * 10.0 ** rng.uniform(-3, 3, size=(n, 1))
    t[:5] = 0.0                                         # zero stress
    t[5:10] *= 1e150                                    # |s|^2 would overflow
    sigma = from_voigt(t, dim).reshape(-1).copy()
    vm = law.von_mises(t)
    kappa = vm * rng.uniform(0.0, 2.0, size=n)          # about half inside, half outside
    kappa[10:20] = 0.0                                  # projection onto {0} (3D: hydrostatic)
    kappa[20:25] = vm[20:25]                            # on the boundary
    H0 = rng.normal(size=n * dim * dim)
    H0 = from_voigt(to_voigt(H0, dim), dim).reshape(-1).copy()   # symmetric
    H_ref, kappa_ref = _reference(law, sigma, H0, kappa, 0.01, 100.0, 50.0)
    kern = kernels.PerzynaKernel(law, VonMisesProjection(law), 100.0, 50.0, module)
    H, kap = H0.copy(), kappa.copy()
    assert kern.advance(sigma, H, kap, 0.01) == 0
    # round-off of the excess t - P t is relative to |t|: the update's scale k/(2 l1) E |t|
    scale = np.abs(H0).reshape(n, -1).max(axis=1) + 0.01 / 200.0 * 1000.0 * np.abs(t).max(axis=1)
    err = np.abs(H - H_ref).reshape(n, -1).max(axis=1) / scale
    assert err.max() <= 1e-12
    assert np.allclose(kap, kappa_ref, rtol=1e-12, atol=0.0)
    inside = law.von_mises(t) < kappa * (1 - 1e-12)
    assert np.array_equal(H.reshape(n, -1)[inside], H0.reshape(n, -1)[inside])   # no flow


def test_kernel_propagates_nan():
    law = Elasticity(1000.0, 0.4, 2)
    t = np.array([[1.0, 2.0, np.nan], [3.0, 0.0, 1.0]])
    sigma = from_voigt(t, 2).reshape(-1).copy()
    H, kappa = np.zeros(8), np.array([0.1, 0.1])
    kernels.PerzynaKernel(law, VonMisesProjection(law), 1.0, 1.0, module).advance(
        sigma, H, kappa, 0.1)
    assert np.isnan(H[:4]).all() and np.isnan(kappa[0])
    assert np.isfinite(H[4:]).all() and np.isfinite(kappa[1])


def test_kernel_checks_arrays():
    law = Elasticity(1000.0, 0.4, 2)
    kern = kernels.PerzynaKernel(law, VonMisesProjection(law), 1.0, 1.0, module)
    with pytest.raises(ValueError):
        kern.advance(np.zeros(8), np.zeros(8), np.zeros(3), 0.1)
    with pytest.raises(TypeError):
        kern.advance(np.zeros(8, dtype=np.float32), np.zeros(8), np.zeros(2), 0.1)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("terms", ["compliance", "memory", "friction", "all"])
def test_nodal_contact_equals_numpy(dim, terms):
    """The compiled nodal contact energy of the fast solver equals the numpy reference, for
    nodes in separation, compliance, stick (|y_tau| ~ delta) and slip on both branches."""
    from app.solvers.fast import NodalContact
    rng = np.random.default_rng(7 + dim)
    n = 300
    nu = np.zeros(dim)
    nu[1] = -1.0
    w = rng.uniform(0.5, 2.0, size=n) / n
    fr = (1.0, 60.0, 60.0, 0.01) if terms in ("friction", "all") else None
    y = rng.normal(size=(n, dim)) * 10.0 ** rng.uniform(-9, -1, size=(n, 1))
    args = (w, nu, 100.0 if terms != "friction" else None, fr, 1e-7)
    ref, comp = NodalContact(*args), NodalContact(*args, module=module)
    if terms in ("memory", "all"):
        ref.xi = comp.xi = rng.uniform(0.0, 5.0, size=n)
    if terms == "all":
        ref.theta = comp.theta = rng.uniform(0.3, 1.0, size=n)
    e0, g0, H0 = ref.evaluate(y)
    e1, g1, H1 = comp.evaluate(y)
    assert abs(e1 - e0) <= 1e-13 * max(abs(e0), 1e-300)
    assert np.abs(g1 - g0).max() <= 1e-13 * np.abs(g0).max()
    assert np.abs(H1 - H0).max() <= 1e-13 * np.abs(H0).max()
    assert comp.evaluate(y, need_hessian=False)[2] is None


@pytest.mark.parametrize("factor", [1.0, 1e3, 1e-3])
def test_kernel_start_from_last_roots(factor):
    """Each cell's root search starts from its root of the last call (PerzynaKernel.mu); a
    start above or below the root gives the same update as the cold start."""
    rng = np.random.default_rng(7)
    law = Elasticity(1000.0, 0.4, 2)
    t = rng.normal(size=(500, law.m))
    sigma = from_voigt(t, 2).reshape(-1).copy()
    kappa0 = law.von_mises(t) * rng.uniform(0.1, 0.9, size=500)     # all outside
    kern = kernels.PerzynaKernel(law, VonMisesProjection(law), 100.0, 50.0, module)
    H1, k1 = np.zeros(2000), kappa0.copy()
    assert kern.advance(sigma, H1, k1, 0.01) == 0                   # cold: mu = 0 on entry
    assert np.all(kern.mu > 0)
    kern.mu *= factor
    H2, k2 = np.zeros(2000), kappa0.copy()
    assert kern.advance(sigma, H2, k2, 0.01) == 0
    assert np.abs(H2 - H1).max() <= 1e-13 * np.abs(H1).max()
    assert np.abs(k2 - k1).max() <= 1e-13 * np.abs(k1).max()


def test_kernel_failure_writes_nothing():
    """If a cell's root search does not converge (here: one sweep allowed), the kernel says
    so and leaves H and kappa as they were (the history keeps step n - 1)."""
    rng = np.random.default_rng(3)
    law = Elasticity(1000.0, 0.4, 2)
    t = rng.normal(size=(50, law.m))
    sigma = from_voigt(t, 2).reshape(-1).copy()
    kappa = law.von_mises(t) * 0.5
    H = rng.normal(size=200)
    H0, kappa0 = H.copy(), kappa.copy()
    kern = kernels.PerzynaKernel(law, VonMisesProjection(law), 1.0, 1.0, module, max_iter=1)
    assert kern.advance(sigma, H, kappa, 0.1) > 0
    assert np.array_equal(H, H0) and np.array_equal(kappa, kappa0)
