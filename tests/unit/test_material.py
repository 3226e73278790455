"""Plane-stress matrices agree with the UFL operator; Perzyna rates follow the paper."""
import numpy as np
import pytest
from dolfinx import fem, mesh
from mpi4py import MPI

from vpcontact.forms.elasticity import elasticity_operator
from vpcontact.model.material import PlaneStress, from_voigt, to_voigt
from vpcontact.model.viscoplastic import Perzyna


def test_voigt_roundtrip():
    t = np.random.default_rng(0).normal(size=(7, 3))
    np.testing.assert_array_equal(to_voigt(from_voigt(t)), t)


def test_numpy_operator_matches_ufl():
    """E tau computed by the numpy matrices equals the UFL operator of the forms."""
    E, nu = 1000.0, 0.4
    law = PlaneStress(E, nu)
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    tau = np.array([[1.3, -0.7], [-0.7, 2.1]])
    C = elasticity_operator(E, nu)
    Q = fem.TensorFunctionSpace(msh, ("DG", 0))
    f = fem.Function(Q)
    f.interpolate(fem.Expression(C(fem.Constant(msh, tau)), Q.element.interpolation_points()))
    ufl_val = f.x.array.reshape(-1, 2, 2)[0]
    np.testing.assert_allclose(from_voigt(law.apply(to_voigt(tau)))[0], ufl_val, rtol=1e-14)
    # the energy form counts shear twice: (E tau):tau = t^T A t
    t = to_voigt(tau)[0]
    assert t @ law.A @ t == pytest.approx(np.sum(ufl_val * tau), rel=1e-14)
    # von Mises (plane stress): t11^2 + t22^2 - t11 t22 + 3 t12^2
    assert law.von_mises(to_voigt(tau))[0] ** 2 == pytest.approx(
        1.3**2 + 2.1**2 - 1.3 * 2.1 + 3 * 0.7**2, rel=1e-14)


def test_perzyna_rates():
    law = PlaneStress(1000.0, 0.4)
    pz = Perzyna(law, lambda1=100.0, lambda2=50.0)
    t = np.array([[30.0, -5.0, 12.0], [1.0, 1.0, 0.0]])
    kappa = np.array([10.0, 100.0])
    gs, gk = pz.rates(t, kappa[:, None])
    assert gk.shape == (2, 1)
    gk = gk[:, 0]
    excess = t[0] - pz.project(t[:1], kappa[:1])[0]
    np.testing.assert_allclose(gs[0], -law.Cmat @ excess / 200.0, rtol=1e-13)
    assert gk[0] == pytest.approx(2.0 / 150.0 * law.von_mises(excess[None])[0], rel=1e-13)
    # inside the ball: no viscoplastic flow
    assert np.all(gs[1] == 0.0) and gk[1] == 0.0
