"""Laws written by the user (app/model/userlaw.py, the protocol of app/model/laws.py): the
adapter's conversions between the user's tensors and the t-coordinates, its checks (m, shapes,
finiteness), the strain eps it passes (E^-1 (sigma - H) in the explicit update, the trial
strain in the implicit one), the user's derivatives as the local Jacobian, and the built-in
laws in the same protocol; a contact law written by the user in both back ends.  The
references are the built-in Perzyna law, hand-made states and closed forms."""
import math

import numpy as np
import pytest
import ufl

from userlaws.perzyna_law import (
    NotFinite,
    UserPerzyna,
    UserPerzynaTangent,
    WrongM,
    WrongShape,
)
from vpcontact.io.errors import CaseError
from vpcontact.model.implicit import BackwardEuler
from vpcontact.model.laws import ScalarLaw
from vpcontact.model.material import Elasticity, from_voigt, to_voigt
from vpcontact.model.primitives import backend
from vpcontact.model.userlaw import LawEvaluationError, UserLaw, as_viscoplastic_law
from vpcontact.model.viscoplastic import Perzyna

EL = {2: Elasticity(1000.0, 0.4, 2), 3: Elasticity(1000.0, 0.3, 3)}


def _state(dim, n=40, seed=0):
    """Random stresses (n, mt) of a few times kappa, and kappa (n, 1) >= 0."""
    rng = np.random.default_rng(seed)
    t = rng.normal(size=(n, EL[dim].m)) * 10.0
    return t, np.abs(rng.normal(size=(n, 1))) * 8.0


@pytest.mark.parametrize("dim", [2, 3])
def test_adapter_equals_the_builtin(dim):
    """UserLaw(UserPerzyna): rates in t-coordinates of the shapes (n, mt), (n, 1) equal the
    built-in Perzyna's; the built-in's own G, Gk (tensors) equal its rates."""
    el = EL[dim]
    ref = Perzyna(el, 100.0, 50.0)
    law = as_viscoplastic_law(lambda e: UserPerzyna(e, 100.0, 50.0), el)
    assert isinstance(law, UserLaw) and law.m == 1 and law.name == "user perzyna"
    t, kappa = _state(dim)
    eps = np.zeros_like(t)
    G, Gk = law.rates(t, kappa, eps)
    G0, Gk0 = ref.rates(t, kappa)
    assert G.shape == (40, el.m) and Gk.shape == (40, 1)
    assert 0 < (Gk0[:, 0] > 0).sum() < 40              # some cells flow, some do not
    np.testing.assert_allclose(G, G0, rtol=0, atol=1e-14 * np.abs(G0).max())
    np.testing.assert_allclose(Gk, Gk0, rtol=0, atol=1e-14 * np.abs(Gk0).max())
    sigma = from_voigt(t, dim)
    assert ref.G(sigma, None, kappa).shape == (40, dim, dim)
    np.testing.assert_allclose(to_voigt(ref.G(sigma, None, kappa), dim), G0, rtol=0,
                               atol=1e-15 * np.abs(G0).max())
    np.testing.assert_allclose(ref.Gk(sigma, None, kappa), Gk0, rtol=1e-15)
    np.testing.assert_array_equal(law.elastic(t, kappa, eps), ref.elastic(t, kappa))
    assert law.relaxation_rate() == pytest.approx(ref.relaxation_rate(), rel=1e-14)


def test_a_builtin_object_in_the_adapter():
    """A built-in law passed where a user's object is expected (wrapped in UserLaw) gives
    its own rates; as_viscoplastic_law keeps a ViscoplasticLaw as it is."""
    el = EL[2]
    ref = Perzyna(el, 100.0, 50.0)
    assert as_viscoplastic_law(ref, el) is ref
    wrapped = UserLaw(ref, el, "builtin")
    t, kappa = _state(2, seed=3)
    G, Gk = wrapped.rates(t, kappa, np.zeros_like(t))
    G0, Gk0 = ref.rates(t, kappa)
    np.testing.assert_allclose(G, G0, rtol=0, atol=1e-15 * np.abs(G0).max())
    np.testing.assert_allclose(Gk, Gk0, rtol=1e-15)


class _Recorder:
    """G = -c sigma (so the implicit update has a closed form), Gk = 0; records eps."""

    m = 1

    def __init__(self, elasticity, c=0.5):
        self.c, self.seen = c, []

    def G(self, sigma, eps, kappa):
        self.seen.append(eps.copy())
        return -self.c * sigma

    def Gk(self, sigma, eps, kappa):
        return np.zeros((len(sigma), 1))


@pytest.mark.parametrize("dim", [2, 3])
def test_explicit_update_passes_eps(dim):
    """The explicit update gives the law eps_{n-1} with sigma_{n-1} = E eps_{n-1} + H_{n-1}
    (the state built here from a chosen eps and H) and writes H_n = H_{n-1} - k c sigma."""
    el = EL[dim]
    rng = np.random.default_rng(dim)
    eps_t, H_t = rng.normal(size=(6, el.m)) * 1e-3, rng.normal(size=(6, el.m))
    sigma_t = eps_t @ el.Cmat.T + H_t
    user = _Recorder(el)
    law = UserLaw(user, el, "recorder")
    user.seen.clear()
    H = from_voigt(H_t, dim).reshape(-1).copy()
    kappa = np.zeros((6, 1))
    law.explicit()(from_voigt(sigma_t, dim).reshape(-1), H, kappa, 0.1)
    np.testing.assert_allclose(user.seen[0], from_voigt(eps_t, dim), rtol=0, atol=1e-15)
    np.testing.assert_allclose(to_voigt(H, dim), H_t - 0.05 * sigma_t, rtol=1e-14)


def test_implicit_update_passes_the_trial_strain():
    """The implicit update gives the law the trial strain (fixed in the local iteration)
    and solves sigma = s_tr - k c sigma: sigma = s_tr / (1 + k c)."""
    el = EL[2]
    rng = np.random.default_rng(7)
    s_tr, eps = rng.normal(size=(5, 3)) * 10.0, rng.normal(size=(5, 3)) * 1e-3
    user = _Recorder(el, c=2.0)
    law = UserLaw(user, el, "recorder")
    user.seen.clear()
    sigma, kappa, C = BackwardEuler(law).solve(s_tr, np.zeros((5, 1)), 0.25, eps)
    np.testing.assert_allclose(sigma, s_tr / 1.5, rtol=1e-12)
    np.testing.assert_allclose(C, np.broadcast_to(el.Cmat / 1.5, C.shape), rtol=1e-6)
    assert user.seen and all(np.array_equal(e, from_voigt(eps)) for e in user.seen
                             if len(e) == 5)


@pytest.mark.parametrize("dim", [2, 3])
def test_user_derivatives_are_the_jacobian(dim):
    """implicit_jacobian from the user's dG, dGk (tensor derivatives, summed over the two
    entries of a shear) equals the finite-difference Jacobian of the same residual, and the
    local solve with it equals the one without (to the local tolerance)."""
    el = EL[dim]
    with_d = UserLaw(UserPerzynaTangent(el, 100.0, 50.0), el, "tangent")
    without = UserLaw(UserPerzyna(el, 100.0, 50.0), el, "plain")
    assert with_d.derivatives and not without.derivatives
    t, kappa = _state(dim, seed=11)
    z, eps, k = np.column_stack([t, kappa]), np.zeros_like(t), 0.2
    r0 = without.implicit_residual(z, t * 0.9, kappa * 0.5, k, eps)
    J = with_d.implicit_jacobian(z, t * 0.9, kappa * 0.5, k, eps)
    J_fd = BackwardEuler(without)._jacobian(z, r0, t * 0.9, kappa * 0.5, k,
                                            np.abs(t).max(axis=1), eps)
    assert without.implicit_jacobian(z, t, kappa, k, eps) is None
    np.testing.assert_allclose(J, J_fd, rtol=0, atol=1e-5)
    a = BackwardEuler(with_d).solve(t, kappa * 0.5, k, eps)
    b = BackwardEuler(without).solve(t, kappa * 0.5, k, eps)
    for x, y in zip(a[:2], b[:2]):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-10 * np.abs(y).max())


@pytest.mark.parametrize("cls, message", [
    (WrongM, "m = 0: the number of internal variables"),
    (WrongShape, "Gk returned an array of shape (6,), expected (6, 1)"),
    (NotFinite, "non-finite values (NaN/Inf) at 6 cell(s) at sigma = 0"),
])
def test_protocol_refusals(cls, message):
    """A wrong m, a wrong shape, NaN at the zero state: a CaseError naming the law."""
    with pytest.raises(CaseError) as err:
        as_viscoplastic_law(cls(EL[2], 100.0, 50.0), EL[2], "mylaw.py: class X")
    assert str(err.value).startswith("mylaw.py: class X: ") and message in str(err.value)


def test_incomplete_laws_refused():
    class NoGk:
        m = 1

        def G(self, sigma, eps, kappa):
            return -sigma

    class OnlyDG(UserPerzyna):
        def dG(self, sigma, eps, kappa):
            return None

    with pytest.raises(CaseError, match="no method Gk"):
        UserLaw(NoGk(), EL[2], "x")
    with pytest.raises(CaseError, match="give both dG and dGk"):
        UserLaw(OnlyDG(EL[2], 1.0, 1.0), EL[2], "x")


def test_non_finite_during_a_step():
    """NaN from G at a later state: the explicit update raises LawEvaluationError (a
    RuntimeError: the step fails) naming the law and the cells, and writes nothing."""
    class Overflow(UserPerzyna):
        def G(self, sigma, eps, kappa):
            big = np.abs(sigma).max(axis=(1, 2)) > 1e3
            return np.where(big[:, None, None], np.inf, super().G(sigma, eps, kappa))

    law = UserLaw(Overflow(EL[2], 100.0, 50.0), EL[2], "mylaw.py: class Overflow")
    t, kappa = _state(2, n=4)
    t[1] = 1e4
    H = np.zeros(16)
    with pytest.raises(LawEvaluationError, match="class Overflow: G or Gk returned "
                                                 "non-finite values .* at 1 cell"):
        law.explicit()(from_voigt(t).reshape(-1), H, kappa, 0.1)
    assert not H.any()


class ExpCompliance(ScalarLaw):
    """A user's contact law: p(r) = c (exp(a r^+) - 1) / a, written with backend(r)."""

    name = "exponential compliance"

    def __init__(self, c, a):
        self.c, self.a = c, a

    def energy(self, r):
        ops = backend(r)
        x = self.a * ops.pos(r)
        return self.c * (ops.exp(x) - 1.0 - x) / self.a ** 2

    def derivative(self, r):
        ops = backend(r)
        return self.c * (ops.exp(self.a * ops.pos(r)) - 1.0) / self.a

    def second_derivative(self, r):
        ops = backend(r)
        return ops.where(ops.gt(r, 0.0), self.c * ops.exp(self.a * ops.pos(r)), 0.0)


def test_a_user_contact_law_in_both_back_ends():
    """One definition: numpy over nodes equals the closed form (math.exp), and its UFL
    evaluation and UFL's derivatives of its energy equal the numpy values."""
    law = ExpCompliance(100.0, 50.0)
    r = np.array([-0.01, 0.0, 0.002, 0.02])
    closed = [100.0 * (math.expm1(50.0 * max(x, 0.0))) / 50.0 for x in r]
    np.testing.assert_allclose(law.derivative(r), closed, rtol=1e-14)
    for x, e, p, h in zip(r, law.energy(r), law.derivative(r), law.second_derivative(r)):
        v = ufl.variable(ufl.as_ufl(float(x)))
        e_ufl = law.energy(v)
        d1 = ufl.diff(e_ufl, v)
        values = [float(f((0.0,))) for f in (e_ufl, d1, ufl.diff(d1, v), law.derivative(v))]
        assert values == pytest.approx([e, p, h, p], rel=1e-12, abs=1e-12)


def test_rate_bound_checked():
    class Negative(UserPerzyna):
        def rate_bound(self):
            return -1.0

    law = UserLaw(Negative(EL[2], 100.0, 50.0), EL[2], "x")
    with pytest.raises(CaseError, match=r"rate_bound\(\) = -1.0: a rate"):
        law.relaxation_rate()
