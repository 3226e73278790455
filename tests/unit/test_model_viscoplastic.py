"""The viscoplastic law interface (app/model/laws.py): a law declares m and gives G,
Gk vectorised over cells; its explicit update (3.2)-(3.3) and its implicit variant follow
from them, so a new law is one class.  A toy law with m = 2 (linear relaxation) checks the
defaults against the scheme written out by hand; Perzyna's specialised updates equal the
interface's defaults."""
import numpy as np
import pytest

from vpcontact.model.lawregistry import viscoplastic_law
from vpcontact.model.laws import ExplicitUpdate, ViscoplasticLaw
from vpcontact.model.material import Elasticity, from_voigt
from vpcontact.model.viscoplastic import Perzyna

EL = Elasticity(1000.0, 0.4, 2)


class Relaxation(ViscoplasticLaw):
    """G = -a sigma, Gk = (b ||sigma||_VM, -c kappa_2): linear in sigma, two variables."""

    m = 2

    def rates(self, t, kappa):
        vm = self.elasticity.von_mises(t)
        return -0.3 * t, np.column_stack([0.2 * vm, -0.1 * kappa[:, 1]])


def _stresses(n, seed=0):
    return np.random.default_rng(seed).normal(size=(n, EL.m)) * 10.0


def test_explicit_default_is_the_scheme():
    law = Relaxation(EL)
    t = _stresses(5)
    kappa = np.random.default_rng(1).uniform(size=(5, 2))
    H = np.zeros(5 * 4)
    k0 = kappa.copy()
    law.explicit()(from_voigt(t).reshape(-1), H, kappa, 0.5)
    np.testing.assert_allclose(H, from_voigt(-0.15 * t).reshape(-1), rtol=1e-15)
    np.testing.assert_allclose(kappa[:, 0], k0[:, 0] + 0.1 * EL.von_mises(t), rtol=1e-15)
    np.testing.assert_allclose(kappa[:, 1], 0.95 * k0[:, 1], rtol=1e-15)


def test_implicit_default_solves_backward_euler():
    """sigma = s_tr + k G(sigma): sigma = s_tr / (1 + 0.3 k); kappa_2 = kappa_2' / (1 + 0.1 k)."""
    law = Relaxation(EL)
    s_tr = _stresses(6, 2)
    kp = np.random.default_rng(3).uniform(size=(6, 2))
    k = 0.4
    sigma, kappa, C = law.implicit().solve(s_tr, kp, k)
    np.testing.assert_allclose(sigma, s_tr / (1 + 0.3 * k), rtol=1e-10)
    np.testing.assert_allclose(kappa[:, 1], kp[:, 1] / (1 + 0.1 * k), rtol=1e-10)
    np.testing.assert_allclose(kappa[:, 0], kp[:, 0] + k * 0.2 * EL.von_mises(sigma),
                               rtol=1e-10)
    np.testing.assert_allclose(C, np.broadcast_to(EL.Cmat / (1 + 0.3 * k), C.shape),
                               rtol=1e-6)


def test_perzyna_specialisations_equal_the_defaults():
    """Perzyna's own residual and elastic test equal the interface's defaults from its
    rates, and its compiled (or numpy) explicit update equals ExplicitUpdate."""
    law = Perzyna(EL, 100.0, 50.0)
    t = _stresses(200, 4) * 5.0
    kappa = np.abs(np.random.default_rng(5).normal(size=(200, 1))) * 20.0
    z = np.column_stack([t, kappa])
    s_tr = t + 1.0
    default = ViscoplasticLaw.implicit_residual(law, z, s_tr, kappa * 0.5, 0.1)
    np.testing.assert_allclose(law.implicit_residual(z, s_tr, kappa * 0.5, 0.1), default,
                               rtol=1e-12, atol=1e-12 * np.abs(default).max())
    assert np.array_equal(law.elastic(t, kappa), ViscoplasticLaw.elastic(law, t, kappa))
    assert 0 < law.elastic(t, kappa).sum() < 200
    sigma = from_voigt(t).reshape(-1).copy()
    H1, k1 = np.zeros(800), kappa.copy()
    H2, k2 = np.zeros(800), kappa.copy()
    law.explicit()(sigma, H1, k1, 0.01)
    ExplicitUpdate(law)(sigma, H2, k2, 0.01)
    np.testing.assert_allclose(H1, H2, rtol=0, atol=1e-12 * np.abs(H2).max())
    np.testing.assert_allclose(k1, k2, rtol=1e-12)


def test_relaxation_rate():
    """Perzyna: r_max = lambda_max(E) / (2 lambda1) (the stability indicator's rate); a law
    that does not know its rate gives None (no indicator)."""
    lam_max = np.linalg.eigvalsh(0.5 * (EL.Cmat + EL.Cmat.T)).max()
    assert Perzyna(EL, 100.0, 50.0).relaxation_rate() == pytest.approx(lam_max / 200.0,
                                                                     rel=1e-13)
    assert Relaxation(EL).relaxation_rate() is None


def test_law_of_a_case():
    class VP:
        lambda1, lambda2 = 10.0, 20.0
    law = viscoplastic_law(VP, EL)
    assert isinstance(law, Perzyna) and law.m == 1 and (law.lambda1, law.lambda2) == (10, 20)
    assert viscoplastic_law(None, EL) is None
    with pytest.raises(TypeError):
        ViscoplasticLaw(EL)                 # abstract: rates is required
