"""The power-law Perzyna law (app/model/viscoplastic.py, PowerLaw): r = ||sigma - P
sigma||_VM / s_ref, G = -r^(n-1)/(2 lambda1) E (sigma - P sigma), Gk = 2 r^(n-1)/(3 lambda2)
||sigma - P sigma||_VM.  n = 1 is Perzyna's law on whole runs (both step solvers); the rates
against a hand computation; the explicit update against an ODE solution of uniaxial
relaxation under held strain (first order in k); the case keys' refusals."""
import copy

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import make_case, paper_raw, run_case
from vpcontact.io.errors import CaseError
from vpcontact.model.lawregistry import viscoplastic_law
from vpcontact.model.laws import ExplicitUpdate
from vpcontact.model.material import Elasticity, from_voigt
from vpcontact.model.viscoplastic import Perzyna, PowerLaw

E_, NU = 1000.0, 0.3
EL3 = Elasticity(E_, NU, 3)


def _raw(**vp):
    raw = paper_raw()
    raw["material"]["viscoplastic"].update(vp)
    return raw


def _final(result):
    p = result.problem
    return p.u.x.array.copy(), p.sigma.x.array.copy(), p.state.kappa.x.array.copy()


@pytest.mark.parametrize("method", ["snes_vi", "condensed"])
def test_n1_is_perzyna_on_a_run(method):
    """law power with n = 1 gives Perzyna's run (u, sigma, kappa at T) to 1e-12, with
    SNES VI and the condensed solver (auto picks the condensed one here)."""
    sections = {"mesh": {"n": 8}, "time": {"N": 8}, "solver": {"method": method}}
    ref = run_case(make_case(paper_raw(), **copy.deepcopy(sections)))
    case = make_case(_raw(law="power", n=1, s_ref=3.0), **copy.deepcopy(sections))
    assert isinstance(viscoplastic_law(case.material.viscoplastic, EL3), PowerLaw)
    power = run_case(case)
    assert ref.status == power.status == "completed"
    assert isinstance(power.problem.law, PowerLaw)
    for a, b in zip(_final(ref), _final(power)):
        scale = np.abs(a).max()
        assert scale > 0
        print(method, "max |perzyna - power n=1| / max |perzyna|:", np.abs(a - b).max() / scale)
        assert np.abs(a - b).max() <= 1e-12 * scale


def _hand_rates(t, kappa, lambda1, lambda2, n, s_ref):
    """The rates in 3D from the formula, with full 3 x 3 tensors: P tau = tr/3 I +
    min(1, kappa/||tau||_VM) dev(tau) (the energy-norm projection for isotropic E)."""
    lmbda = E_ * NU / ((1 + NU) * (1 - 2 * NU))
    two_mu = E_ / (1 + NU)
    G_out, Gk_out = [], []
    for row, kap in zip(t, kappa[:, 0]):
        s11, s22, s33, s23, s13, s12 = row
        tau = np.array([[s11, s12, s13], [s12, s22, s23], [s13, s23, s33]])
        dev = tau - np.trace(tau) / 3 * np.eye(3)
        vm = np.sqrt(1.5 * np.sum(dev * dev))
        P = np.trace(tau) / 3 * np.eye(3) + min(1.0, kap / vm) * dev
        ex = tau - P
        vm_ex = np.sqrt(1.5 * np.sum((ex - np.trace(ex) / 3 * np.eye(3)) ** 2))
        r = vm_ex / s_ref
        Eex = lmbda * np.trace(ex) * np.eye(3) + two_mu * ex
        g = -r ** (n - 1) / (2 * lambda1) * Eex
        G_out.append([g[0, 0], g[1, 1], g[2, 2], g[1, 2], g[0, 2], g[0, 1]])
        Gk_out.append([2 * r ** (n - 1) / (3 * lambda2) * vm_ex])
    return np.array(G_out), np.array(Gk_out)


def test_rates_by_hand():
    """n = 3: the rates at a few stress states (inside and outside the ball) against the
    formula written out with 3 x 3 tensors."""
    law = PowerLaw(EL3, 50.0, 20.0, 3.0, 7.0)
    rng = np.random.default_rng(7)
    t = rng.normal(size=(6, 6)) * 20.0
    kappa = np.array([[5.0], [0.0], [12.0], [1e3], [30.0], [2.0]])   # the 4th inside
    G, Gk = law.rates(t, kappa)
    Gh, Gkh = _hand_rates(t, kappa, 50.0, 20.0, 3.0, 7.0)
    np.testing.assert_allclose(G, Gh, rtol=1e-12, atol=1e-12 * np.abs(Gh).max())
    np.testing.assert_allclose(Gk, Gkh, rtol=1e-12, atol=1e-12 * np.abs(Gkh).max())
    assert np.all(G[3] == 0) and Gk[3, 0] == 0
    assert np.abs(Gh).max() > 0
    # 2D plane stress: on pure shear P scales radially, E acts as 2 mu
    el2 = Elasticity(E_, NU, 2)
    law2 = PowerLaw(el2, 50.0, 20.0, 3.0, 7.0)
    tau, kap = 10.0, 4.0
    vm = np.sqrt(3.0) * tau
    ex = (1 - kap / vm) * tau
    r = np.sqrt(3.0) * ex / 7.0
    G2, Gk2 = law2.rates(np.array([[0.0, 0.0, tau]]), np.array([[kap]]))
    np.testing.assert_allclose(G2[0], [0, 0, -r ** 2 / 100.0 * E_ / (1 + NU) * ex],
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Gk2[0, 0], 2 * r ** 2 / 60.0 * np.sqrt(3.0) * ex, rtol=1e-12)


def test_n1_rates_are_perzyna():
    rng = np.random.default_rng(3)
    t = rng.normal(size=(50, 6)) * 20.0
    kappa = np.abs(rng.normal(size=(50, 1))) * 10.0
    a, b = PowerLaw(EL3, 50.0, 20.0, 1.0, 7.0).rates(t, kappa), \
        Perzyna(EL3, 50.0, 20.0).rates(t, kappa)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


LAM1, LAM2, N_EXP, S_REF = 100.0, 50.0, 3.0, 10.0
S0, KAPPA0, T_END = 40.0, 5.0, 0.05


def _ode_solution():
    """Uniaxial stress s0 held by a fixed strain in 3D: the mean stays, the deviator stays
    uniaxial; with q = ||sigma||_VM and x = q - kappa > 0:
    q' = -mu/lambda1 (x/s_ref)^(n-1) x,  kappa' = 2/(3 lambda2) (x/s_ref)^(n-1) x."""
    mu = E_ / (2 * (1 + NU))

    def f(_, y):
        x = y[0] - y[1]
        w = (x / S_REF) ** (N_EXP - 1) * x
        return [-mu / LAM1 * w, 2 / (3 * LAM2) * w]
    sol = solve_ivp(f, (0, T_END), [S0, KAPPA0], method="DOP853", rtol=1e-13, atol=1e-12)
    return sol.y[0, -1], sol.y[1, -1]


def _explicit_relaxation(steps: int):
    """The law's explicit update, held strain: sigma_j = E eps + H_j = sigma_0 + H_j."""
    law = PowerLaw(EL3, LAM1, LAM2, N_EXP, S_REF)
    update = law.explicit()
    assert type(update) is ExplicitUpdate
    sigma0 = from_voigt(np.array([[S0, 0, 0, 0, 0, 0]]), 3).reshape(-1)
    H, kappa, k = np.zeros(9), np.array([[KAPPA0]]), T_END / steps
    for _ in range(steps):
        update(sigma0 + H, H, kappa, k)
    t = EL3.to_voigt(sigma0 + H)
    return float(EL3.von_mises(t)[0]), float(kappa[0, 0]), t[0]


def test_uniaxial_relaxation_against_the_ode():
    """The explicit update converges to the ODE solution at first order: relative errors
    below 1e-3 at k = T/4000, and halving k halves the error (ratio in [1.8, 2.2])."""
    q_ref, kappa_ref = _ode_solution()
    assert q_ref < 0.8 * S0             # the run relaxes, away from the start and the ball
    errors = []
    for steps in (2000, 4000):
        q, kappa, t = _explicit_relaxation(steps)
        np.testing.assert_allclose(t[3:], 0.0, atol=1e-12 * S0)            # no shear
        np.testing.assert_allclose(t[:3].sum(), S0, rtol=1e-12)           # mean kept
        np.testing.assert_allclose(t[1], t[2], rtol=1e-12)                # uniaxial deviator
        errors.append(max(abs(q - q_ref) / q_ref, abs(kappa - kappa_ref) / kappa_ref))
    print("relative errors at k = T/2000, T/4000:", errors)
    assert errors[1] < 1e-3
    assert 1.8 < errors[0] / errors[1] < 2.2


@pytest.mark.parametrize("vp, key", [
    ({"law": "power", "n": 0.5, "s_ref": 1.0}, "material.viscoplastic.n"),
    ({"law": "power", "s_ref": 0.0}, "material.viscoplastic.s_ref"),
    ({"law": "power", "s_ref": -2.0}, "material.viscoplastic.s_ref"),
    ({"law": "power"}, "material.viscoplastic.s_ref"),
    ({"n": 2.0}, "material.viscoplastic.n"),
    ({"law": "perzyna", "n": 1.0}, "material.viscoplastic.n"),
    ({"s_ref": 5.0}, "material.viscoplastic.s_ref"),
    ({"law": "plastic"}, "material.viscoplastic.law"),
])
def test_refusals(vp, key):
    with pytest.raises(CaseError) as info:
        make_case(_raw(**vp))
    msg = str(info.value)
    assert key in msg and "\n" not in msg


def test_case_keys():
    vp = make_case(_raw(law="power", n=2.5, s_ref=4.0)).material.viscoplastic
    assert (vp.law, vp.n, vp.s_ref) == ("power", 2.5, 4.0)
    vp = make_case(_raw(law="power", s_ref=4.0)).material.viscoplastic
    assert (vp.law, vp.n, vp.s_ref) == ("power", 1.0, 4.0)
    vp = make_case(paper_raw()).material.viscoplastic
    assert (vp.law, vp.n, vp.s_ref) == ("perzyna", None, None)
    law = viscoplastic_law(make_case(_raw(law="power", n=2.5, s_ref=4.0)).material.viscoplastic,
                           EL3)
    assert isinstance(law, PowerLaw) and (law.n, law.s_ref) == (2.5, 4.0)
    assert law.relaxation_rate() is None


def test_implicit_scheme():
    """time.scheme implicit through the interface's default residual: n = 1 is Perzyna's run
    to 1e-10; n = 3 with a small s_ref (where the explicit scheme diverges at this step)
    completes."""
    sections = {"mesh": {"n": 8}, "time": {"N": 8, "scheme": "implicit"}}
    ref = run_case(make_case(paper_raw(), **copy.deepcopy(sections)))
    one = run_case(make_case(_raw(law="power", n=1, s_ref=3.0), **copy.deepcopy(sections)))
    for a, b in zip(_final(ref), _final(one)):
        assert np.abs(a - b).max() <= 1e-10 * np.abs(a).max()
    three = run_case(make_case(_raw(law="power", n=3, s_ref=2.0), **copy.deepcopy(sections)))
    assert three.status == "completed"
    assert np.all(np.isfinite(_final(three)[1]))
