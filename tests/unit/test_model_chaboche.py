"""Chaboche's law (app/model/chaboche.py): f = ||sigma - X||_VM - R - k, p' = <f/K>^n,
eps_vp' = p' N(sigma - X), X' = 2/3 C eps_vp' - gamma X p', R' = b (Q - R) p', G = -E
eps_vp', kappa = (X (6), R, p).  The rates against a hand computation with 3 x 3 tensors; a
strain-controlled cycle of a uniaxial bar (the explicit update, 2D plane stress and 3D; the
backward-Euler update with its finite-difference tangent of size mt + 8) against an
independent integration of the 1D equations (solve_ivp), first order in k; the case keys and
their refusals."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import make_case, paper_raw
from vpcontact.io.errors import CaseError
from vpcontact.model.chaboche import Chaboche
from vpcontact.model.lawregistry import viscoplastic_law
from vpcontact.model.laws import ExplicitUpdate
from vpcontact.model.material import Elasticity

E_, NU = 1000.0, 0.3
K0, KD, N_EXP, C_, GAMMA, Q_, B_ = 10.0, 20.0, 3.0, 2000.0, 50.0, 5.0, 10.0
EMAX, T_END = 0.03, 4.0


def _law(dim):
    return Chaboche(Elasticity(E_, NU, dim), K0, KD, N_EXP, C_, GAMMA, Q_, B_)


def _sym(v):
    """The 3 x 3 tensor of 3D t-coordinates (11, 22, 33, 23, 13, 12)."""
    a11, a22, a33, a23, a13, a12 = v
    return np.array([[a11, a12, a13], [a12, a22, a23], [a13, a23, a33]])


def _hand_rates(sig, kappa):
    """G (3D) and Gk from the formulas written with 3 x 3 tensors."""
    lmbda = E_ * NU / ((1 + NU) * (1 - 2 * NU))
    two_mu = E_ / (1 + NU)
    tau = _sym(sig) - _sym(kappa[:6])
    dev = tau - np.trace(tau) / 3 * np.eye(3)
    vm = np.sqrt(1.5 * np.sum(dev * dev))
    f = vm - kappa[6] - K0
    p_rate = max(f / KD, 0.0) ** N_EXP
    eps = p_rate * 1.5 * dev / vm
    X_rate = 2 / 3 * C_ * eps - GAMMA * _sym(kappa[:6]) * p_rate
    G = -(lmbda * np.trace(eps) * np.eye(3) + two_mu * eps)
    coords = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
    return np.array([G[i, j] for i, j in coords]), \
        np.array([X_rate[i, j] for i, j in coords] + [B_ * (Q_ - kappa[6]) * p_rate, p_rate])


def test_rates_by_hand():
    """Random stresses and deviatoric back stresses in 3D (some inside f <= 0), and 2D plane
    stress against 3D with sigma_33 = sigma_13 = sigma_23 = 0."""
    rng = np.random.default_rng(11)
    t = rng.normal(size=(8, 6)) * 30.0
    kappa = np.zeros((8, 8))
    kappa[:, :6] = rng.normal(size=(8, 6)) * 10.0
    kappa[:, :3] -= kappa[:, :3].mean(axis=1, keepdims=True)        # deviatoric X
    kappa[:, 6] = rng.uniform(0.0, 5.0, 8)
    kappa[:, 7] = rng.uniform(0.0, 0.1, 8)
    kappa[3, 6] = 1e4                                                # f < 0: no flow
    G, Gk = _law(3).rates(t, kappa)
    for i in range(8):
        Gh, Gkh = _hand_rates(t[i], kappa[i])
        np.testing.assert_allclose(G[i], Gh, rtol=1e-12, atol=1e-12 * np.abs(Gh).max())
        np.testing.assert_allclose(Gk[i], Gkh, rtol=1e-12, atol=1e-12 * np.abs(Gkh).max())
    assert np.all(G[3] == 0) and np.all(Gk[3] == 0) and np.abs(G).max() > 0
    assert list(_law(3).elastic(t, kappa)) == [i == 3 for i in range(8)]
    # 2D: the in-plane stress, its G the plane-stress E on the in-plane eps_vp'
    t2 = t[:, [0, 1, 5]]
    kap2 = kappa.copy()
    kap2[:, 3:5] = 0.0
    G2, Gk2 = _law(2).rates(t2, kap2)
    lmbda, two_mu = E_ * NU / (1 - NU ** 2), E_ / (1 + NU)
    for i in range(8):
        _, Gkh = _hand_rates(np.r_[t2[i, :2], 0, 0, 0, t2[i, 2]], kap2[i])
        np.testing.assert_allclose(Gk2[i], Gkh, rtol=1e-12, atol=1e-12 * np.abs(Gkh).max())
        e = Gkh[:6] - (-GAMMA * kap2[i, :6] * Gkh[7])          # 2/3 C eps_vp'
        e = e / (2 / 3 * C_)
        want = -np.array([lmbda * (e[0] + e[1]) + two_mu * e[0],
                          lmbda * (e[0] + e[1]) + two_mu * e[1], two_mu * e[5]])
        np.testing.assert_allclose(G2[i], want, rtol=1e-10, atol=1e-10 * np.abs(want).max())


def test_plane_strain_rates_against_3d():
    """Plane strain (m = 9, kappa = (X, R, p, eps_vp33)): random states built in 3D (total
    strain with eps_33 = eps_13 = eps_23 = 0, an isochoric creep strain with eps_vp33, sigma
    = C3 (eps - eps_vp) by 3D Hooke, X deviatoric with X_13 = X_23 = 0, some cells inside
    f <= 0): G = the in-plane part of 3D Chaboche's -C3 eps_vp', Gk = (X', R', p') of the
    3D law and eps_vp33' its 33 creep rate."""
    from vpcontact.forms.elasticity import plane_strain_moduli
    law = Chaboche(Elasticity(*plane_strain_moduli(E_, NU), 2), K0, KD, N_EXP, C_, GAMMA,
                   Q_, B_, "strain")
    assert law.m == 9 and law.fields[-1] == ("eps_vp33", 1)
    lmbda, two_mu = E_ * NU / ((1 + NU) * (1 - 2 * NU)), E_ / (1 + NU)
    rng = np.random.default_rng(4)
    t, kappa, s3, flows = [], [], [], 0
    for i in range(10):
        a, b = rng.normal(size=(2, 3)) * 0.03
        eps = np.array([[a[0], a[2], 0], [a[2], a[1], 0], [0, 0, 0]])
        evp = np.array([[b[0], b[2], 0], [b[2], b[1], 0], [0, 0, -b[0] - b[1]]])
        e = eps - evp
        sigma = lmbda * np.trace(e) * np.eye(3) + two_mu * e
        X = rng.normal(size=4) * 5.0
        X[:3] -= X[:3].mean()
        R = rng.uniform(0, 5) if i % 3 else 1e4                    # 1e4: f < 0, no flow
        kappa.append(np.r_[X[:3], 0.0, 0.0, X[3], R, rng.uniform(0, 0.1), evp[2, 2]])
        t.append([sigma[0, 0], sigma[1, 1], sigma[0, 1]])
        s3.append([sigma[0, 0], sigma[1, 1], sigma[2, 2], 0, 0, sigma[0, 1]])
    G, Gk = law.rates(np.array(t), np.array(kappa))
    for i in range(10):
        Gh, Gkh = _hand_rates(np.array(s3[i]), kappa[i][:8])
        rate33 = (Gkh[2] + GAMMA * kappa[i][2] * Gkh[7]) / (2 / 3 * C_)
        np.testing.assert_allclose(G[i], Gh[[0, 1, 5]], rtol=1e-12,
                                   atol=1e-12 * max(np.abs(Gh).max(), 1.0))
        np.testing.assert_allclose(Gk[i], np.r_[Gkh, rate33], rtol=1e-12,
                                   atol=1e-12 * max(np.abs(Gkh).max(), 1.0))
        flows += Gkh[7] > 0
    assert flows == 6


def _strain(t):
    """The axial strain of the cycle 0 -> EMAX -> -EMAX -> 0 over [0, 4]."""
    return EMAX * np.interp(t, [0.0, 1.0, 3.0, 4.0], [0.0, 1.0, -1.0, 0.0])


def _ode_reference(t_end):
    """The 1D equations of the uniaxial bar: with x = 3/2 X_11 (X = X_11 diag(1, -1/2,
    -1/2)), f = |s - x| - R - k, p' = <f/K>^n, e_vp' = p' sign(s - x),
    s' = E (e' - e_vp'), x' = C e_vp' - gamma x p', R' = b (Q - R) p'."""
    def rhs(rate):
        def f(_, y):
            s, x, R, p = y
            pr = max((abs(s - x) - R - K0) / KD, 0.0) ** N_EXP
            ev = pr * np.sign(s - x)
            return [E_ * (rate - ev), C_ * ev - GAMMA * x * pr, B_ * (Q_ - R) * pr, pr]
        return f
    y = [0.0, 0.0, 0.0, 0.0]
    knots = [0.0, 1.0, 3.0, 4.0]
    for a, b in zip(knots, knots[1:]):
        if a >= t_end:
            break
        b = min(b, t_end)
        rate = (_strain(b) - _strain(a)) / (b - a)
        with np.errstate(over="ignore", invalid="ignore"):     # rejected trial steps
            sol = solve_ivp(rhs(rate), (a, b), y, method="DOP853", rtol=1e-12, atol=1e-14)
        assert sol.status == 0
        y = sol.y[:, -1]
    return y


def _bar_stress(el, H, e1):
    """sigma = E eps + H with the axial strain e1 and the lateral stresses zero."""
    C = el.Cmat
    lat = list(range(1, el.dim))
    eps = np.zeros(el.m)
    eps[0] = e1
    eps[lat] = np.linalg.solve(C[np.ix_(lat, lat)], -(C[lat, 0] * e1 + H[lat]))
    return C @ eps + H


def _explicit_cycle(dim, steps):
    """The explicit update (3.2)-(3.3) on the bar over the cycle: (s, x, R, p) at T."""
    law = _law(dim)
    el = law.elasticity
    update = law.explicit()
    assert type(update) is ExplicitUpdate
    sigma, H, kappa = np.zeros(el.m), np.zeros(dim * dim), np.zeros((1, 8))
    times = np.linspace(0.0, T_END, steps + 1)
    for t0, t1 in zip(times, times[1:]):
        update(el.from_voigt(sigma[None]).reshape(-1), H, kappa, t1 - t0)
        sigma = _bar_stress(el, el.to_voigt(H)[0], _strain(t1))
    np.testing.assert_allclose(sigma[1:], 0.0, atol=1e-12 * abs(sigma[0]))
    X = kappa[0, :6]
    np.testing.assert_allclose(X[1:3], -X[0] / 2, rtol=1e-12)       # uniaxial deviator
    np.testing.assert_allclose(X[3:], 0.0, atol=1e-14)
    return np.array([sigma[0], 1.5 * X[0], kappa[0, 6], kappa[0, 7]])


@pytest.mark.parametrize("dim", [2, 3])
def test_strain_cycle_first_order(dim):
    """The cycle: stress, back stress, R, p at T against the 1D ODE; the error halves with
    k (ratios in [1.8, 2.2]) and is below 1e-3 of the scale at k = T/3200."""
    ref = _ode_reference(T_END)
    scale = np.array([abs(ref[0]) + K0, abs(ref[1]), abs(ref[2]), ref[3]])
    assert ref[3] > 0.01 and abs(ref[1]) > 5.0 and ref[2] > 0.1 * Q_     # it hardened
    errors = []
    for steps in (800, 1600, 3200):
        errors.append(np.abs(_explicit_cycle(dim, steps) - ref) / scale)
    print(f"{dim}D chaboche cycle, relative errors (s, x, R, p) at k = T/800, T/1600, "
          f"T/3200:", [e.tolist() for e in errors])
    worst = [e.max() for e in errors]
    assert worst[-1] < 1e-3
    for a, b in zip(worst, worst[1:]):
        assert 1.8 < a / b < 2.2


def test_implicit_loading_first_order():
    """The backward-Euler update (m = 8, finite-difference tangent of size 6 + 8) on the
    loading branch t in [0, 1.5] (yield, hardening, the start of the unloading) against the
    ODE: first order in k."""
    law = _law(3)
    el, local = law.elasticity, law.implicit()
    lat, t_end = [1, 2], 1.5
    ref = _ode_reference(t_end)
    errors = []
    for steps in (60, 120):
        eps, H, kappa = np.zeros(6), np.zeros(6), np.zeros((1, 8))
        times = np.linspace(0.0, t_end, steps + 1)
        for t1 in times[1:]:
            eps[0] = _strain(t1)
            for _ in range(30):         # Newton on the lateral strains: lateral stresses 0
                s, kap, C = local.solve((el.Cmat @ eps + H)[None], kappa, t_end / steps)
                if np.abs(s[0, lat]).max() <= 1e-12 * (abs(s[0, 0]) + K0):
                    break
                eps[lat] -= np.linalg.solve(C[0][np.ix_(lat, lat)], s[0, lat])
            kappa, H = kap, s[0] - el.Cmat @ eps
        got = np.array([s[0, 0], 1.5 * kappa[0, 0], kappa[0, 6], kappa[0, 7]])
        errors.append((np.abs(got - ref) / np.abs(ref)).max())
    print("3D chaboche loading, backward Euler, relative errors at k = T/60, T/120:", errors)
    assert errors[-1] < 2e-2 and 1.7 < errors[0] / errors[1] < 2.3


def _raw(**vp):
    raw = paper_raw()
    raw["material"]["viscoplastic"] = {"law": "chaboche", **vp}
    return raw


KEYS = {"k": K0, "K": KD, "n": N_EXP, "C": C_, "gamma": GAMMA, "Q": Q_, "b": B_}


def test_case_keys():
    case = make_case(_raw(**KEYS))
    vp = case.material.viscoplastic
    assert (vp.law, vp.k, vp.K, vp.n, vp.C, vp.gamma, vp.Q, vp.b, vp.lambda1) == \
        ("chaboche", K0, KD, N_EXP, C_, GAMMA, Q_, B_, None)
    law = viscoplastic_law(vp, Elasticity(E_, NU, 2))
    assert isinstance(law, Chaboche) and law.m == 8
    assert (law.k, law.K, law.n, law.C, law.gamma, law.Q, law.b) == \
        (K0, KD, N_EXP, C_, GAMMA, Q_, B_)
    assert any(term.startswith("Chaboche (k = 10, K = 20, n = 3") for term in
               case.active_terms())


@pytest.mark.parametrize("change, key", [
    ({"K": None}, "material.viscoplastic.K"),
    ({"gamma": None}, "material.viscoplastic.gamma"),
    ({"n": 0.5}, "material.viscoplastic.n"),
    ({"K": 0.0}, "material.viscoplastic.K"),
    ({"C": -1.0}, "material.viscoplastic.C"),
    ({"k": -1.0}, "material.viscoplastic.k"),
    ({"Q": -20.0}, "material.viscoplastic.Q"),
    ({"kappa0": 1.0}, "material.viscoplastic.kappa0"),
    ({"lambda1": 1.0}, "material.viscoplastic.lambda1"),
    ({"A": 1.0}, "material.viscoplastic.A"),
])
def test_refusals(change, key):
    vp = {**KEYS, **change}
    with pytest.raises(CaseError) as info:
        make_case(_raw(**{k: v for k, v in vp.items() if v is not None}))
    msg = str(info.value)
    assert key in msg and "\n" not in msg


def test_rate_at_stress_by_hand_and_against_the_jacobian():
    """r(S) = phi'(S - k) (3 mu + C + b |Q|) + max(gamma, b) phi(S - k), phi(f) = <f/K>^n:
    at S = 30 Pa (f / K = 1) 0.15 x (1153.846 + 2000 + 50) + 50 = 530.577 1/s, none at
    S <= k (no flow).  The spectral radius of the Jacobian of (G, Gk) by (sigma, kappa) of the
    hand-written rates (central differences, 3D, X = R = 0) at uniaxial, shear and random
    stresses of von Mises norm S = 15, 30, 60 Pa is at most r(S) and above 0.9 r(S)."""
    law = _law(3)
    assert law.rate_at_stress(30.0) == pytest.approx(0.15 * (3 * E_ / 2.6 + 2050.0) + 50.0,
                                                     rel=1e-12)
    assert law.rate_at_stress(30.0) == pytest.approx(530.5769230769, rel=1e-10)
    assert law.rate_at_stress(K0) is None and law.rate_at_stress(0.5 * K0) is None
    assert _law(2).rate_at_stress(30.0) == pytest.approx(law.rate_at_stress(30.0), rel=1e-12)
    rng = np.random.default_rng(3)
    dirs = [np.eye(6)[0], np.eye(6)[5], *rng.normal(size=(3, 6))]
    for S in (15.0, 30.0, 60.0):
        for d in dirs:
            tau = _sym(d)
            dev = tau - np.trace(tau) / 3 * np.eye(3)
            z0 = np.concatenate([d * S / np.sqrt(1.5 * np.sum(dev * dev)), np.zeros(8)])
            h = 1e-6 * S
            cols = [(np.concatenate(_hand_rates((z0 + h * e)[:6], (z0 + h * e)[6:]))
                     - np.concatenate(_hand_rates((z0 - h * e)[:6], (z0 - h * e)[6:])))
                    / (2 * h) for e in np.eye(14)]
            rho = np.max(np.abs(np.linalg.eigvals(np.array(cols).T)))
            assert 0.9 * law.rate_at_stress(S) < rho <= law.rate_at_stress(S) * (1 + 1e-6)
