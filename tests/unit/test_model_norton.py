"""Norton's creep law (app/model/norton.py): eps_vp' = A sigma_eq^n N, G = -E eps_vp',
Gk = A sigma_eq^n.  The rates against hand computations with 3 x 3 tensors (uniaxial, pure
shear, random states, 2D and 3D; the engineering-shear weights of the t-coordinates); the
explicit update on a uniaxial bar under held strain against the closed form sigma(t) =
[sigma0^(1-n) + (n-1) E A t]^(1/(1-n)), first order in k; the backward-Euler update on the
same bar; creep under a constant load; the case keys and their refusals."""
import numpy as np
import pytest

from conftest import make_case, paper_raw
from vpcontact.forms.elasticity import plane_strain_moduli
from vpcontact.io.errors import CaseError
from vpcontact.model.lawregistry import viscoplastic_law
from vpcontact.model.laws import ExplicitUpdate
from vpcontact.model.material import Elasticity
from vpcontact.model.norton import Norton

E_, NU = 1000.0, 0.3
A_, N_EXP = 1e-6, 3.0
S0, T_END = 40.0, 0.5


def _tensor(row, dim):
    """The 3 x 3 tensor of t-coordinates (2D: the in-plane stress, sigma_33 = 0)."""
    if dim == 2:
        s11, s22, s12 = row
        return np.array([[s11, s12, 0.0], [s12, s22, 0.0], [0.0, 0.0, 0.0]])
    s11, s22, s33, s23, s13, s12 = row
    return np.array([[s11, s12, s13], [s12, s22, s23], [s13, s23, s33]])


def _coords(tau, dim):
    if dim == 2:
        return np.array([tau[0, 0], tau[1, 1], tau[0, 1]])
    return np.array([tau[0, 0], tau[1, 1], tau[2, 2], tau[1, 2], tau[0, 2], tau[0, 1]])


def _hand_rates(t, dim, A, n):
    """G, Gk from eps_vp' = A sigma_eq^n (3/2) dev(sigma)/sigma_eq with 3 x 3 tensors and
    G = -E eps_vp' (2D plane stress: E on the in-plane part, the paper's constants)."""
    if dim == 3:
        lmbda = E_ * NU / ((1 + NU) * (1 - 2 * NU))
    else:
        lmbda = E_ * NU / (1 - NU ** 2)
    two_mu = E_ / (1 + NU)
    G, Gk = [], []
    for row in t:
        tau = _tensor(row, dim)
        dev = tau - np.trace(tau) / 3 * np.eye(3)
        seq = np.sqrt(1.5 * np.sum(dev * dev))
        eps_vp = A * seq ** n * 1.5 * dev / seq
        e = eps_vp[:dim, :dim]
        Ee = lmbda * np.trace(e) * np.eye(dim) + two_mu * e
        G.append(-_coords(Ee if dim == 3 else np.pad(Ee, (0, 1)), dim))
        Gk.append([A * seq ** n])
    return np.array(G), np.array(Gk)


@pytest.mark.parametrize("dim", [2, 3])
def test_rates_by_hand(dim):
    """Random stress states: G and Gk against the formula written with 3 x 3 tensors."""
    el = Elasticity(E_, NU, dim)
    law = Norton(el, 2e-5, 2.5)
    t = np.random.default_rng(5).normal(size=(8, el.m)) * 30.0
    G, Gk = law.rates(t, np.zeros((8, 1)))
    Gh, Gkh = _hand_rates(t, dim, 2e-5, 2.5)
    np.testing.assert_allclose(G, Gh, rtol=1e-12, atol=1e-12 * np.abs(Gh).max())
    np.testing.assert_allclose(Gk, Gkh, rtol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_uniaxial_and_shear_creep_rates(dim):
    """Uniaxial s: eps_vp' = A s^n (1, -1/2(, -1/2)), p' = A s^n.  Pure shear tau:
    sigma_eq = sqrt(3) tau, the engineering shear rate 2 eps_vp12' = sqrt(3) A
    (sqrt(3) tau)^n, G12 = -2 mu eps_vp12'."""
    el = Elasticity(E_, NU, dim)
    law = Norton(el, A_, N_EXP)
    s, tau = 30.0, 12.0
    uni, shear = np.zeros((1, el.m)), np.zeros((1, el.m))
    uni[0, 0], shear[0, -1] = s, tau
    eps, p = law.creep_rate(uni)
    rate = A_ * s ** N_EXP
    want = [rate, -rate / 2, 0.0] if dim == 2 else [rate, -rate / 2, -rate / 2, 0, 0, 0]
    np.testing.assert_allclose(eps[0], want, rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(p, [rate], rtol=1e-13)
    eps, p = law.creep_rate(shear)
    gamma_rate = np.sqrt(3.0) * A_ * (np.sqrt(3.0) * tau) ** N_EXP
    np.testing.assert_allclose(2 * eps[0, -1], gamma_rate, rtol=1e-13)
    np.testing.assert_allclose(eps[0, :-1], 0.0, atol=1e-16)
    np.testing.assert_allclose(p, [A_ * (np.sqrt(3.0) * tau) ** N_EXP], rtol=1e-13)
    G, Gk = law.rates(shear, np.zeros((1, 1)))
    np.testing.assert_allclose(G[0, -1], -E_ / (1 + NU) * gamma_rate / 2, rtol=1e-13)


def test_zero_stress_and_elastic_cells():
    """No creep at sigma = 0 (n = 1 too) or under a hydrostatic stress in 3D; ``elastic``
    is exactly those cells."""
    el = Elasticity(E_, NU, 3)
    t = np.array([[0.0] * 6, [5.0, 5.0, 5.0, 0, 0, 0], [1.0, 0, 0, 0, 0, 0]])
    for n in (1.0, 3.0):
        G, Gk = Norton(el, A_, n).rates(t, np.zeros((3, 1)))
        assert np.all(G[:2] == 0) and np.all(Gk[:2] == 0) and Gk[2, 0] > 0
        assert list(Norton(el, A_, n).elastic(t, np.zeros((3, 1)))) == [True, True, False]


def _closed_form(t, E=E_):
    """sigma(t) = [sigma0^(1-n) + (n-1) E A t]^(1/(1-n)) of the uniaxial bar."""
    return (S0 ** (1 - N_EXP) + (N_EXP - 1) * E * A_ * t) ** (1 / (1 - N_EXP))


def _bar_stress(el, H, e1):
    """sigma = E eps + H of the bar: the axial strain e1 held, the lateral stresses zero."""
    C = el.Cmat
    lat = list(range(1, el.dim))
    eps = np.zeros(el.m)
    eps[0] = e1
    eps[lat] = np.linalg.solve(C[np.ix_(lat, lat)], -(C[lat, 0] * e1 + H[lat]))
    return C @ eps + H


def _explicit_bar(dim, steps):
    """The law's explicit update (3.2)-(3.3) on the bar; returns sigma_11(T), p(T)."""
    el = Elasticity(E_, NU, dim)
    update = Norton(el, A_, N_EXP).explicit()
    assert type(update) is ExplicitUpdate
    sigma = np.zeros(el.m)
    sigma[0] = S0
    e1 = np.linalg.solve(el.Cmat, sigma)[0]
    H, kappa, k = np.zeros(dim * dim), np.zeros((1, 1)), T_END / steps
    for _ in range(steps):
        update(el.from_voigt(sigma[None]).reshape(-1), H, kappa, k)
        sigma = _bar_stress(el, el.to_voigt(H)[0], e1)
    np.testing.assert_allclose(sigma[1:], 0.0, atol=1e-12 * S0)
    return sigma[0], kappa[0, 0]


@pytest.mark.parametrize("dim", [2, 3])
def test_relaxation_first_order(dim):
    """Held strain: the explicit stresses converge to the closed form at order 1 (the error
    halves with k), and p(T) = (sigma0 - sigma(T)) / E (the creep strain replaces the elastic
    one)."""
    ref = _closed_form(T_END)
    assert ref < 0.7 * S0
    errors = []
    for steps in (100, 200, 400):
        s, p = _explicit_bar(dim, steps)
        errors.append(abs(s - ref) / ref)
        np.testing.assert_allclose(p, (S0 - s) / E_, rtol=1e-10)
    print(f"{dim}D norton relaxation, relative errors at k = T/100, T/200, T/400:", errors)
    assert errors[-1] < 2e-3
    for a, b in zip(errors, errors[1:]):
        assert 1.85 < a / b < 2.15


def test_relaxation_implicit():
    """The backward-Euler update (the protocol's default residual, the finite-difference
    tangent) on the bar converges to the closed form at order 1 too."""
    el = Elasticity(E_, NU, 3)
    local = Norton(el, A_, N_EXP).implicit()
    lat = [1, 2]
    ref, errors = _closed_form(T_END), []
    for steps in (100, 200):
        eps = np.linalg.solve(el.Cmat, np.r_[S0, np.zeros(5)])
        H, kappa, k = np.zeros(6), np.zeros((1, 1)), T_END / steps
        for _ in range(steps):
            for _ in range(30):      # Newton on the lateral strains: lateral stresses 0
                s, kap, C = local.solve((el.Cmat @ eps + H)[None], kappa, k)
                if np.abs(s[0, lat]).max() <= 1e-13 * S0:
                    break
                eps[lat] -= np.linalg.solve(C[0][np.ix_(lat, lat)], s[0, lat])
            kappa, H = kap, s[0] - el.Cmat @ eps
        np.testing.assert_allclose(s[0, 1:], 0.0, atol=1e-12 * S0)
        errors.append(abs(s[0, 0] - ref) / ref)
    print("3D norton relaxation, backward Euler, relative errors at k = T/100, T/200:", errors)
    assert errors[-1] < 2e-3 and 1.85 < errors[0] / errors[1] < 2.15


def test_creep_under_constant_load():
    """Constant uniaxial stress s: the creep strain grows at A s^n; with the stress held,
    the explicit update's H rate gives the creep strain rate eps_vp' = -E^-1 G exactly."""
    el = Elasticity(E_, NU, 3)
    law = Norton(el, A_, N_EXP)
    s = np.array([[25.0, 0, 0, 0, 0, 0]])
    G, Gk = law.rates(s, np.zeros((1, 1)))
    eps_rate = -np.linalg.solve(el.Cmat, G[0])
    np.testing.assert_allclose(eps_rate[0], A_ * 25.0 ** N_EXP, rtol=1e-13)
    np.testing.assert_allclose(eps_rate[1:3], -A_ * 25.0 ** N_EXP / 2, rtol=1e-13)
    np.testing.assert_allclose(Gk[0, 0], A_ * 25.0 ** N_EXP, rtol=1e-13)


def _raw(**vp):
    raw = paper_raw()
    raw["material"]["viscoplastic"] = {"law": "norton", **vp}
    return raw


def test_case_keys():
    case = make_case(_raw(A=2e-6, n=4))
    vp = case.material.viscoplastic
    assert (vp.law, vp.A, vp.n, vp.lambda1, vp.lambda2, vp.kappa0) == \
        ("norton", 2e-6, 4.0, None, None, 0.0)
    law = viscoplastic_law(vp, Elasticity(E_, NU, 2))
    assert isinstance(law, Norton) and (law.A, law.n, law.m) == (2e-6, 4.0, 1)
    assert any("Norton (A = 2e-06, n = 4)" in term for term in case.active_terms())
    perzyna = make_case(paper_raw()).material.viscoplastic
    assert (perzyna.law, perzyna.A, perzyna.K) == ("perzyna", None, None)


@pytest.mark.parametrize("vp, key", [
    ({"A": 1e-6}, "material.viscoplastic.n"),
    ({"n": 3}, "material.viscoplastic.A"),
    ({"A": 0.0, "n": 3}, "material.viscoplastic.A"),
    ({"A": -1.0, "n": 3}, "material.viscoplastic.A"),
    ({"A": 1e-6, "n": 0.5}, "material.viscoplastic.n"),
    ({"A": 1e-6, "n": 3, "lambda1": 1.0}, "material.viscoplastic.lambda1"),
    ({"A": 1e-6, "n": 3, "s_ref": 1.0}, "material.viscoplastic.s_ref"),
    ({"A": 1e-6, "n": 3, "K": 1.0}, "material.viscoplastic.K"),
])
def test_refusals(vp, key):
    with pytest.raises(CaseError) as info:
        make_case(_raw(**vp))
    msg = str(info.value)
    assert key in msg and "\n" not in msg


def test_perzyna_needs_lambdas():
    raw = paper_raw()
    del raw["material"]["viscoplastic"]["lambda2"]
    with pytest.raises(CaseError, match=r"material.viscoplastic.lambda2.*: required with law "
                                        "perzyna"):
        make_case(raw)
    raw = paper_raw()
    raw["material"]["viscoplastic"]["A"] = 1.0
    with pytest.raises(CaseError, match=r"material.viscoplastic.A.*: not used with law perzyna"):
        make_case(raw)


@pytest.mark.parametrize("dim", [2, 3])
def test_rates_of_the_linear_law(dim):
    """n = 1: the relaxation rate and L_G are 3 mu A (isotropic E commutes with the flow
    direction: in 3D on the deviators, in plane stress on (1, -1, 0) and the shear); none for
    n > 1."""
    law = Norton(Elasticity(E_, NU, dim), 2e-4, 1.0)
    mu = E_ / (2 * (1 + NU))
    assert law.relaxation_rate() == pytest.approx(3 * mu * 2e-4, rel=1e-12)
    assert law.lipschitz_constant() == pytest.approx(3 * mu * 2e-4, rel=1e-12)
    assert Norton(Elasticity(E_, NU, dim), 2e-4, 2.0).relaxation_rate() is None
    assert Norton(Elasticity(E_, NU, dim), 2e-4, 2.0).lipschitz_constant() is None


# ---------------------------------------------------------------- plane strain (eps_33 = 0)
def _ps_elasticity():
    """The 2D model's E in plane strain (the plane-stress form with the moduli of
    plane_strain_moduli), as the step problem builds it."""
    return Elasticity(*plane_strain_moduli(E_, NU), 2)


def _hooke3(e):
    """3D isotropic Hooke's law with E_, NU, on 3 x 3 tensors."""
    lmbda, mu = E_ * NU / ((1 + NU) * (1 - 2 * NU)), E_ / (2 * (1 + NU))
    return lmbda * np.trace(e) * np.eye(3) + 2 * mu * e


def _norton3(sigma, A, n):
    """3D Norton by hand: eps_vp' = A s^n (3/2) dev(sigma) / s, s = ||sigma||_VM; p'."""
    dev = sigma - np.trace(sigma) / 3 * np.eye(3)
    s = np.sqrt(1.5 * np.sum(dev * dev))
    return A * s ** (n - 1) * 1.5 * dev, A * s ** n


def test_plane_strain_rates_against_3d_norton():
    """Random plane-strain states built in 3D: total strain with eps_33 = eps_13 = eps_23 = 0,
    an isochoric creep strain eps_vp (eps_vp13 = eps_vp23 = 0), sigma = C3 (eps - eps_vp) by
    3D Hooke; 3D Norton's sigma' = -C3 eps_vp' at held strain.  The 2D law given the
    in-plane sigma and kappa = (p, eps_vp33) gives G = the in-plane sigma', p' and
    eps_vp33' = the 33 creep rate."""
    rng = np.random.default_rng(8)
    for n in (1.0, 3.0):
        law = Norton(_ps_elasticity(), A_, n, "strain")
        assert law.m == 2 and law.fields == (("p", 1), ("eps_vp33", 1))
        t, kappa, want_G, want_Gk = [], [], [], []
        for _ in range(10):
            a, b = rng.normal(size=(2, 3)) * 0.02
            eps = np.array([[a[0], a[2], 0], [a[2], a[1], 0], [0, 0, 0]])
            evp = np.array([[b[0], b[2], 0], [b[2], b[1], 0], [0, 0, -b[0] - b[1]]])
            sigma = _hooke3(eps - evp)
            rate, p_rate = _norton3(sigma, A_, n)
            t.append([sigma[0, 0], sigma[1, 1], sigma[0, 1]])
            kappa.append([rng.uniform(), evp[2, 2]])
            sdot = -_hooke3(rate)
            want_G.append([sdot[0, 0], sdot[1, 1], sdot[0, 1]])
            want_Gk.append([p_rate, rate[2, 2]])
        G, Gk = law.rates(np.array(t), np.array(kappa))
        want_G, want_Gk = np.array(want_G), np.array(want_Gk)
        np.testing.assert_allclose(G, want_G, rtol=0, atol=1e-12 * np.abs(want_G).max())
        np.testing.assert_allclose(Gk, want_Gk, rtol=0, atol=1e-12 * np.abs(want_Gk).max())


def test_plane_strain_uniaxial_and_biaxial_creep():
    """Closed forms with eps_33 = 0 (2 mu = E/(1 + nu), the creep being isochoric):
    uniaxial s with eps_vp33 = nu s / E (sigma_33 = 0): eps_vp' = A s^n (1, -1/2, -1/2);
    equibiaxial s with eps_vp33 = 0: sigma_33 = 2 nu s, s_eq = (1 - 2 nu) s, eps_vp' =
    A s_eq^n (1/2, 1/2, -1); the steady state sigma_33 = s/2 under uniaxial s: eps_vp33' = 0,
    s_eq = sqrt(3)/2 s, eps_vp' = A s_eq^(n-1) (3/4) s (1, -1, 0)."""
    law, s, two_mu = Norton(_ps_elasticity(), A_, N_EXP, "strain"), 30.0, E_ / (1 + NU)
    t = np.array([[s, 0, 0], [s, s, 0], [s, 0, 0]])
    kappa = np.array([[0, NU * s / E_], [0, 0], [0, (NU - 0.5) * s / E_]])
    r_uni, seq_bi, seq_st = A_ * s ** N_EXP, (1 - 2 * NU) * s, np.sqrt(3) / 2 * s
    r_bi = A_ * seq_bi ** N_EXP
    r_st = A_ * seq_st ** (N_EXP - 1) * 0.75 * s
    G, Gk = law.rates(t, kappa)
    np.testing.assert_allclose(G, -two_mu * np.array([[r_uni, -r_uni / 2, 0],
                                                      [r_bi / 2, r_bi / 2, 0],
                                                      [r_st, -r_st, 0]]),
                               rtol=1e-12, atol=1e-12 * two_mu * r_uni)
    np.testing.assert_allclose(Gk, [[r_uni, -r_uni / 2], [r_bi, -r_bi],
                                    [A_ * seq_st ** N_EXP, 0]], rtol=1e-12, atol=1e-15 * r_uni)
    np.testing.assert_allclose(law.creep_rate(t, kappa)[0][0],
                               [r_uni, -r_uni / 2, -r_uni / 2, 0, 0, 0], rtol=1e-12)


def test_plane_strain_relaxation_against_3d():
    """Every strain held (eps_33 = 0): the explicit update (3.2)-(3.3) of the 2D law with
    kappa = (p, eps_vp33) is 3D relaxation, dev(sigma3)' = -3 mu A s^(n-1) dev(sigma3): the
    mean stress stays, s(t) = [s0^(1-n) + (n-1) 3 mu A t]^(1/(1-n)) (sigma_33 = nu
    (sigma_11 + sigma_22) - E eps_vp33 by hand), first order in k; p = the integral of p'."""
    el = _ps_elasticity()
    lmbda, mu = E_ * NU / ((1 + NU) * (1 - 2 * NU)), E_ / (2 * (1 + NU))
    eps = np.array([0.02, -0.01, 0.015])                    # (eps_11, eps_22, eps_12)
    sig0 = el.Cmat @ eps
    s33 = lmbda * (eps[0] + eps[1])
    mean0 = (sig0[0] + sig0[1] + s33) / 3
    seq0 = np.sqrt(1.5 * ((sig0[0] - mean0) ** 2 + (sig0[1] - mean0) ** 2
                          + (s33 - mean0) ** 2 + 2 * sig0[2] ** 2))
    T = 0.5 / (3 * mu * A_ * seq0 ** (N_EXP - 1))          # s falls by about a third
    exact = (seq0 ** (1 - N_EXP) + (N_EXP - 1) * 3 * mu * A_ * T) ** (1 / (1 - N_EXP))
    errors = []
    for steps in (100, 200):
        update = Norton(el, A_, N_EXP, "strain").explicit()
        H, kappa, k = np.zeros(4), np.zeros((1, 2)), T / steps
        for _ in range(steps):
            update(el.from_voigt((el.Cmat @ eps + el.to_voigt(H)[0])[None]).reshape(-1), H,
                   kappa, k)
        s = el.Cmat @ eps + el.to_voigt(H)[0]
        s33 = NU * (s[0] + s[1]) - E_ * kappa[0, 1]
        mean = (s[0] + s[1] + s33) / 3
        seq = np.sqrt(1.5 * ((s[0] - mean) ** 2 + (s[1] - mean) ** 2 + (s33 - mean) ** 2
                             + 2 * s[2] ** 2))
        np.testing.assert_allclose(mean, mean0, rtol=1e-12)
        errors.append(abs(seq - exact) / exact)
    print("plane strain norton relaxation, relative errors at k = T/100, T/200:", errors)
    assert exact < 0.75 * seq0 and errors[-1] < 3e-3 and 1.85 < errors[0] / errors[1] < 2.15


def test_plane_strain_rates_of_the_linear_law():
    """n = 1 in plane strain: the relaxation rate is 3D's, 3 mu A (mu = E/(2 (1 + nu)) of
    the 3D constants); L_G too, attained by an in-plane shear, and no sampled ratio of G's
    differences at fixed eps_vp33 exceeds it in the energy norm."""
    el, A1 = _ps_elasticity(), 2e-4
    law = Norton(el, A1, 1.0, "strain")
    mu = E_ / (2 * (1 + NU))
    assert law.relaxation_rate() == pytest.approx(3 * mu * A1, rel=1e-12)
    L = law.lipschitz_constant()
    assert L == pytest.approx(3 * mu * A1, rel=1e-12)
    rng = np.random.default_rng(2)
    t = np.vstack([[0.0, 0.0, 1.0], rng.normal(size=(50, 3))])
    kap = np.zeros((51, 2))
    kap[:, 1] = 1e-3
    G = law.rates(t, kap)[0] - law.rates(np.zeros_like(t), kap)[0]
    ratio = np.sqrt(np.einsum("ni,ij,nj->n", G, el.A, G) / np.einsum("ni,ij,nj->n", t, el.A, t))
    assert ratio[0] == pytest.approx(L, rel=1e-12) and np.all(ratio <= L * (1 + 1e-12))
    assert Norton(el, A1, 2.0, "strain").relaxation_rate() is None


def test_plane_strain_per_cell_and_anisotropic():
    """E per cell (CellElasticity): each row's rates are its own E's; an anisotropic E in
    plane strain is refused (its 2D matrix has no out-of-plane coupling); plane stress and
    3D ignore ``plane``."""
    from vpcontact.model.material import CellElasticity, MatrixElasticity
    soft = Elasticity(*plane_strain_moduli(E_ / 2, 0.2), 2)
    el = CellElasticity.from_rows(np.stack([_ps_elasticity().Cmat, soft.Cmat]), 2)
    t, kappa = np.array([[30.0, -5.0, 4.0], [12.0, 7.0, -3.0]]), np.array([[0, 1e-3], [0, -2e-3]])
    G, Gk = Norton(el, A_, N_EXP, "strain").rates(t, kappa)
    for i, one in enumerate((_ps_elasticity(), soft)):
        Gi, Gki = Norton(one, A_, N_EXP, "strain").rates(t[i:i + 1], kappa[i:i + 1])
        np.testing.assert_allclose(G[i], Gi[0], rtol=1e-13)
        np.testing.assert_allclose(Gk[i], Gki[0], rtol=1e-13)
    C = _ps_elasticity().Cmat.copy()
    C[0, 0] *= 1.5
    with pytest.raises(ValueError, match="isotropic"):
        Norton(MatrixElasticity(C, 2), A_, N_EXP, "strain")
    assert Norton(Elasticity(E_, NU, 3), A_, N_EXP, "strain").m == 1
    assert Norton(Elasticity(E_, NU, 2), A_, N_EXP).m == 1


def test_plane_strain_case():
    """material.plane: strain gives the law kappa = (p, eps_vp33); a Voigt matrix there and
    kappa0 != 0 are refused, each on one line naming the key."""
    raw = _raw(A=2e-6, n=4)
    raw["material"]["plane"] = "strain"
    case = make_case(raw)
    law = viscoplastic_law(case.material.viscoplastic, _ps_elasticity(), case.material.plane)
    assert law.m == 2 and law.plane_strain is not None
    bad = _raw(A=2e-6, n=4, kappa0=0.1)
    bad["material"]["plane"] = "strain"
    with pytest.raises(CaseError, match=r"material.viscoplastic.kappa0.*: law norton in "
                                        "plane strain") as info:
        make_case(bad)
    assert "\n" not in str(info.value)
    bad = _raw(A=2e-6, n=4)
    bad["material"]["plane"] = "strain"
    for key in ("E", "nu"):
        del bad["material"][key]
    bad["material"]["elasticity"] = {"voigt": (_ps_elasticity().Cmat
                                               * [[1, 1, 0.5], [1, 1, 0.5], [1, 1, 0.5]]).tolist()}
    with pytest.raises(CaseError, match=r"material.elasticity.*: law norton in plane strain"):
        make_case(bad)


# ------------------------------------------------ the stability estimate at a stress scale
def _jacobian(rates, t0: np.ndarray, rel: float = 1e-6) -> np.ndarray:
    """dG/dsigma of ``rates`` (t-coordinates -> G rows) by central differences."""
    h = rel * np.abs(t0).max()
    cols = [(rates(t0 + h * e) - rates(t0 - h * e)) / (2 * h) for e in np.eye(len(t0))]
    return np.array(cols).T


@pytest.mark.parametrize("dim, plane", [(2, "stress"), (2, "strain"), (3, None)])
def test_rate_at_stress_by_hand(dim, plane):
    """r(S) = n A S^(n-1) 3 mu (mu = E / (2 (1 + nu)) the 3D shear modulus, in plane stress
    and plane strain too): E = 1000 Pa, nu = 0.3, A = 1e-6, n = 3, S = 40 Pa gives
    3e-6 x 1600 x 1153.846... = 5.538462 1/s; n = 1: the relaxation rate 3 mu A at every S;
    S = 0 with n > 1: none (the rate vanishes)."""
    el = _ps_elasticity() if plane == "strain" else Elasticity(E_, NU, dim)
    law = Norton(el, A_, N_EXP, plane or "stress")
    assert law.rate_at_stress(40.0) == pytest.approx(5.538461538461538, rel=1e-12)
    assert law.rate_at_stress(0.0) is None
    linear = Norton(el, 2e-4, 1.0, plane or "stress")
    assert linear.rate_at_stress(77.0) == pytest.approx(linear.relaxation_rate(), rel=1e-12)
    assert linear.rate_at_stress(77.0) == pytest.approx(3 * 2e-4 * E_ / 2.6, rel=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_rate_at_stress_bounds_the_jacobian(dim):
    """The spectral radius of dG/dsigma of the hand-written rates (3 x 3 tensors, central
    differences) at random stresses of von Mises norm S is at most r(S), and equals it for a
    pure shear (the radial direction of a deviatoric stress under held strain)."""
    S, rng = 40.0, np.random.default_rng(5)
    law = Norton(Elasticity(E_, NU, dim), A_, N_EXP)
    shear = np.zeros(3 if dim == 2 else 6)
    shear[-1] = S / np.sqrt(3.0)
    states = [shear] + list(rng.normal(size=(6, len(shear))))
    for i, t0 in enumerate(states):
        tau = _tensor(t0, dim)
        dev = tau - np.trace(tau) / 3 * np.eye(3)
        t0 = t0 * S / np.sqrt(1.5 * np.sum(dev * dev))              # ||sigma||_VM = S
        jac = _jacobian(lambda t: _hand_rates(t[None], dim, A_, N_EXP)[0][0], t0)
        rho = np.max(np.abs(np.linalg.eigvals(jac)))
        assert rho <= law.rate_at_stress(S) * (1 + 1e-6)
        if i == 0:
            assert rho == pytest.approx(law.rate_at_stress(S), rel=1e-6)
