"""The laws' descriptions and constants: what ``check`` lists and summary.json records
(app/post/lawreport.py), the Lipschitz constant L_G of Perzyna's law against its closed form,
m_j of the friction law, the estimated relaxation rate of a law without a rate bound
(app/post/diagnostics.py) against Jacobians written by hand."""
import json

import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT, make_case, paper_raw
from vpcontact.model.contact_laws import (
    NormalCompliance,
    PiecewiseLinearFriction,
    SlipWeakening,
)
from vpcontact.model.material import Elasticity
from vpcontact.model.memory_kernels import ExponentialKernel
from vpcontact.model.viscoplastic import Perzyna, PowerLaw
from vpcontact.post.diagnostics import estimated_rate
from vpcontact.records import RunSummary

E, NU, LAMBDA1, LAMBDA2 = 1000.0, 0.4, 100.0, 50.0


def _energy_norm(el, t):
    return np.sqrt(np.einsum("ni,ij,nj->n", t, el.A, t))


@pytest.mark.parametrize("dim, lam_max, attained, e", [
    (2, E / (1 - NU), E / (1 - NU), [1.0, 1.0, 0.0]),       # plane stress: (1, 1, 0)
    (3, E / (1 - 2 * NU), E / (1 + NU), [1.0, -1.0, 0, 0, 0, 0])])    # 3D: 3 K; 2 mu
def test_perzyna_lipschitz_constant(dim, lam_max, attained, e):
    """L_G = lambda_max(E) / (2 lambda1) (the largest eigenvalue by hand) bounds
    |G(s1) - G(s2)|_E / |s1 - s2|_E on random pairs and kappas; at kappa = 0 the ratio along
    e reaches it in 2D (K(0) = {0}) and 2 mu / (2 lambda1) in 3D (P keeps the hydrostatic
    part there, so the bound is not attained)."""
    el = Elasticity(E, NU, dim)
    law = Perzyna(el, LAMBDA1, LAMBDA2)
    L = law.lipschitz_constant()
    assert L == pytest.approx(lam_max / (2 * LAMBDA1), rel=1e-13)
    rng = np.random.default_rng(3)
    s1, s2 = rng.normal(size=(2, 400, el.m)) * 10.0
    kappa = rng.uniform(0.0, 15.0, size=(400, 1))
    dG = law.rates(s1, kappa)[0] - law.rates(s2, kappa)[0]
    assert (_energy_norm(el, dG) / _energy_norm(el, s1 - s2)).max() <= L * (1 + 1e-12)
    e = np.array([e])
    G0 = law.rates(e, np.zeros((1, 1)))[0]
    assert (_energy_norm(el, G0) / _energy_norm(el, e))[0] == \
        pytest.approx(attained / (2 * LAMBDA1), rel=1e-12)


def test_power_law_lipschitz_constant():
    el = Elasticity(E, NU, 2)
    assert PowerLaw(el, LAMBDA1, LAMBDA2, 1.0, 3.0).lipschitz_constant() == \
        pytest.approx(E / (1 - NU) / (2 * LAMBDA1), rel=1e-13)
    assert PowerLaw(el, LAMBDA1, LAMBDA2, 2.0, 3.0).lipschitz_constant() is None


def test_viscoplastic_descriptions():
    el = Elasticity(E, NU, 2)
    d = Perzyna(el, LAMBDA1, LAMBDA2).describe()
    assert d == {"name": "perzyna", "m": 1,
                 "constants": {"lambda1": [100.0, "N s/m^2"], "lambda2": [50.0, "s"]},
                 "lipschitz_constant": pytest.approx(E / (1 - NU) / 200.0, rel=1e-13)}
    d = PowerLaw(el, LAMBDA1, LAMBDA2, 3.0, 2.5).describe()
    assert (d["name"], d["constants"]["n"], d["constants"]["s_ref"]) == \
        ("power", [3.0, "-"], [2.5, "N/m^2"])
    assert d["lipschitz_constant"] is None
    json.dumps(d)


def test_contact_law_constants():
    assert NormalCompliance(100.0).constants() == {"c_nu": (100.0, "N/m^3")}
    fr = PiecewiseLinearFriction(1.0, 60.0, 40.0, 0.01)
    assert fr.constants()["c1"] == (60.0, "N/m^3") and fr.constants()["u1"] == (0.01, "m")
    # m_j: the largest decreasing slope of psi' (sampled), c1
    rho = np.linspace(0.0, 0.05, 5001)
    slopes = np.diff(fr.derivative(rho)) / np.diff(rho)
    assert fr.m_j == pytest.approx(-slopes.min(), rel=1e-9)
    slip = SlipWeakening(0.3, 0.002)
    assert slip.theta_max == pytest.approx(slip.theta(np.linspace(0, 1, 1001)).max())
    assert ExponentialKernel(200.0, 1.0).constants() == {"b0": (200.0, "N/(m^3 s)"),
                                                         "beta": (1.0, "1/s")}


def _power_jacobian_2d(el, t, n, s_ref):
    """dG/dsigma of the power law at kappa = 0 in plane stress (P = 0) by hand: G = -f(t)
    C t / (2 lambda1), f = (vm / s_ref)^(n-1), grad vm = M t / vm."""
    C, M = el.Cmat, el.M
    vm = np.sqrt(t @ M @ t)
    f = (vm / s_ref) ** (n - 1)
    return -(f * C + (n - 1) * f * np.outer(C @ t, M @ t) / vm ** 2) / (2 * LAMBDA1)


def test_estimated_rate_against_the_jacobian_by_hand():
    """2D: the spectral radius of the Jacobian by hand; 3D uniaxial at kappa = 0 (P keeps the
    hydrostatic part): n mu (sigma_eq / s_ref)^(n-1) / lambda1 (radial deviatoric
    direction); at rest: None."""
    n, s_ref = 3.0, 2.0
    el = Elasticity(E, NU, 2)
    law = PowerLaw(el, LAMBDA1, LAMBDA2, n, s_ref)
    t = np.array([[1.0, 0.2, 0.1], [5.0, -1.0, 2.0], [0.5, 0.5, 0.0]])   # the second: largest
    rate = estimated_rate(law, t, np.zeros((3, 1)))
    exact = np.max(np.abs(np.linalg.eigvals(_power_jacobian_2d(el, t[1], n, s_ref))))
    assert rate == pytest.approx(exact, rel=1e-7)
    el3 = Elasticity(E, NU, 3)
    s = 6.0
    t3 = np.array([[s, 0, 0, 0, 0, 0.0]])
    rate3 = estimated_rate(PowerLaw(el3, LAMBDA1, LAMBDA2, n, s_ref), t3, np.zeros((1, 1)),
                           comm=MPI.COMM_SELF)
    mu = E / (2 * (1 + NU))
    assert rate3 == pytest.approx(n * mu * (s / s_ref) ** (n - 1) / LAMBDA1, rel=1e-7)
    assert estimated_rate(law, np.zeros((4, 3)), np.zeros((4, 1))) is None


def test_summary_records_the_laws_when_given():
    args = dict(case="c", source="s", case_data={}, status="completed", mesh={}, time={},
                mpi_ranks=1, active_terms=[], diagnostics={}, solver={}, steps=[],
                setup_s=0.0, loop_s=0.0, wall_s=0.0)
    assert "laws" not in RunSummary(**args).as_dict()
    d = RunSummary(**args, laws={"viscoplastic": None}).as_dict()
    assert d["laws"] == {"viscoplastic": None}
    assert list(d)[:11] == ["case", "source", "case_data", "status", "mesh", "time",
                            "mpi_ranks", "active_terms", "diagnostics", "solver", "laws"]


@pytest.fixture(scope="module")
def paper_check():
    from vpcontact.cli.checkrun import report
    return report(make_case(mesh={"n": 4}), MPI.COMM_SELF)


def test_check_lists_the_paper_laws(paper_check):
    """The paper's constants (cases/wang_cheng_2021.yaml) with units; m_E = E / (1 + nu)
    (plane stress: the deviatoric eigenvalue), L_G = E / (1 - nu) / (2 lambda1), m_j = c1."""
    raw = paper_raw()
    mat, fr = raw["material"], raw["contact"]["friction"]
    E_, nu, l1 = mat["E"], mat["nu"], mat["viscoplastic"]["lambda1"]
    text = "\n".join(paper_check)
    assert f"elasticity: isotropic, plane stress: E = {E_:g} N/m^2, nu = {nu:g}; " \
           f"m_E = {E_ / (1 + nu):.4g} N/m^2" in text
    assert f"viscoplastic law: perzyna: lambda1 = {l1:g} N s/m^2, lambda2 = " \
           f"{mat['viscoplastic']['lambda2']:g} s (m = 1)" in text
    assert f"L_G = {E_ / (1 - nu) / (2 * l1):.4g} 1/s" in text
    assert f"c1 = {fr['c1']:g} N/m^3" in text and f"m_j = {fr['c1']:g} N/m^3" in text
    assert f"contact: normal compliance: c_nu = " \
           f"{raw['contact']['normal_compliance']['c_nu']:g} N/m^3" in text


def test_check_estimates_the_indicator_of_a_law_without_bound():
    """The power law (no rate bound) from a uniform initial stress at kappa0 = 0: the
    indicator is k_max times the spectral radius of the Jacobian by hand, marked estimated;
    from rest it is unknown."""
    from vpcontact.model.problem import ContactProblem
    from vpcontact.post.diagnostics import diagnose
    from vpcontact.simulation import build_mesh
    n, s_ref, s = 3.0, 2.0, 4.0
    vp = {"law": "power", "lambda1": LAMBDA1, "lambda2": LAMBDA2, "n": n, "s_ref": s_ref,
          "kappa0": 0.0}
    for sigma0, source in (([[s, 0.0], [0.0, 0.0]], "estimated"), (None, "unknown")):
        case = make_case(mesh={"n": 4}, time={"T": 1.0, "N": 4}, contact=None,
                         material={**paper_raw()["material"], "viscoplastic": vp},
                         initial={} if sigma0 is None else {"sigma0": sigma0})
        problem = ContactProblem(case, build_mesh(case, MPI.COMM_SELF))
        problem.set_initial_values()
        diag = diagnose(problem)
        assert diag.relaxation_rate is None and diag.indicator_source == source
        if sigma0 is None:
            assert diag.stability_indicator is None
            assert "unknown" in diag.messages()[0][1]
            continue
        jac = _power_jacobian_2d(problem.elasticity, np.array([s, 0.0, 0.0]), n, s_ref)
        rate = np.max(np.abs(np.linalg.eigvals(jac)))
        assert diag.rate_estimate == pytest.approx(rate, rel=1e-6)
        assert diag.stability_indicator == pytest.approx(0.25 * rate, rel=1e-6)
        assert "(estimated" in diag.messages()[0][1]


def _check_of(name: str) -> tuple[dict, str]:
    """(the case file's data, ``check``'s report) of a shipped case, in this process."""
    from vpcontact.case import load_case, load_raw
    from vpcontact.cli.checkrun import report
    path = f"{ROOT}/cases/{name}.yaml"
    return load_raw(path), "\n".join(report(load_case(path), MPI.COMM_SELF))


@pytest.mark.parametrize("name, m", [("norton_relaxation", 1), ("chaboche_cycle", 8)])
def test_check_lists_a_shipped_creep_law(name, m):
    """Every constant of the case file's law, the law's m, no L_G (n > 1: no rate bound),
    no contact law."""
    raw, text = _check_of(name)
    vp = dict(raw["material"]["viscoplastic"])
    line = next(x for x in text.splitlines() if x.startswith("viscoplastic law: "))
    assert line.startswith(f"viscoplastic law: {vp.pop('law')}: ")
    for key, value in vp.items():
        assert f"{key} = {value:g}" in line, (key, line)
    assert f"(m = {m})" in line and "L_G: not stated by the law" in line
    assert "contact laws: none" in text


def test_check_lists_the_friction_table_and_its_m_j():
    """m_j of (2.6) is the table's largest decreasing slope (from the case file)."""
    raw, text = _check_of("friction_table")
    tab = np.array(raw["contact"]["friction"]["table"])
    m_j = max(0.0, -np.min(np.diff(tab[:, 1]) / np.diff(tab[:, 0])))
    friction = next(x for x in text.splitlines() if "table = " in x and "m_j" in x)
    assert f"m_j = {m_j:g} N/m^3" in friction
    assert f"vs max(sqrt(3) c1~, m_j) ||gamma||^2 = {m_j:.4g} x" in text


def test_check_lists_each_material():
    raw, text = _check_of("bimaterial_punch")
    mats = raw["materials"]
    for group, mat in mats.items():
        vp = mat.get("viscoplastic")
        law = f"perzyna: lambda1 = {vp['lambda1']:g} N s/m^2, lambda2 = " \
              f"{vp['lambda2']:g} s (m = 1)" if vp else "none (elastic)"
        assert f"viscoplastic law ({group}): {law}" in text
        assert f"{group} (E = {mat['E']}, nu = {mat['nu']}" in text


def test_no_trace_constant_without_softening(monkeypatch):
    """Coulomb friction (m_j = 0): the (2.6) margin is m_E and ||gamma||^2 is neither needed
    nor computed (it costs a generalised eigenproblem: seconds in 3D); with the paper's
    softening law it is computed."""
    import vpcontact.post.diagnostics as diagnostics
    from vpcontact.model.problem import ContactProblem
    from vpcontact.simulation import build_mesh
    calls = []
    real = diagnostics.trace_constant
    monkeypatch.setattr(diagnostics, "trace_constant",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    for friction, computed in (({"coulomb": {"mu": 0.3}}, False), (None, True)):
        contact = dict(paper_raw()["contact"])
        if friction is not None:
            contact["friction"] = friction
        case = make_case(mesh={"n": 4}, time={"T": 1.0, "N": 2}, contact=contact)
        diag = diagnostics.diagnose(ContactProblem(case, build_mesh(case, MPI.COMM_SELF)))
        assert bool(calls) == computed and diag.unique
        if not computed:
            assert diag.gamma2 is None and diag.wellposedness_margin == diag.m_E
            assert "m_j = 0" in diag.messages()[-1][1]


@pytest.mark.parametrize("name, S, rate", [
    ("norton_relaxation", 40.0, 3 * 1e-6 * 40.0 ** 2 * 3 * 1000.0 / 2.6),
    ("chaboche_cycle", 30.0, 3 / 20 * ((30.0 - 10.0) / 20) ** 2 * (3 * 1000.0 / 2.6 + 2000.0
                                                                   + 10 * 5.0) + 50.0)])
def test_check_states_the_creep_laws_indicator_at_the_stress_scale(name, S, rate):
    """Norton's and Chaboche's indicator in ``check``: S = E u_max / L of the case file (E =
    1000 Pa, L = 1 m, u = 0.04 and 0.03 m), r(S) = n A S^(n-1) 3 mu and phi'(S - k) (3 mu + C
    + b Q) + max(gamma, b) phi(S - k) by hand, times k_max = T / N."""
    raw, text = _check_of(name)
    k = raw["time"]["T"] / raw["time"]["N"]
    line = next(x for x in text.splitlines() if x.startswith("stability indicator"))
    assert f"(the law's linearisation at the data's stress scale S = {S:.4g} Pa) k_max " \
           f"r_max = {k:g} x {rate:.4g} = {k * rate:.3g} (explicit limit 2)" in line
    hardens = name == "chaboche_cycle"        # Q = 5 >= 0: r(S) is a bound before hardening
    assert ("unstable where the stresses reach S" in line) == (k * rate > 2 and not hardens)
    assert ("before the law hardens" in line) == (k * rate > 2 and hardens)


@pytest.mark.parametrize("before_hardening", [False, True])
def test_a_bound_before_hardening_is_no_warning(before_hardening):
    """An indicator above 2 at the stress scale is a warning, unless the rate is the
    hardening law's at its initial state (chaboche_cycle: 10.6 at X = R = 0, the run's own
    estimate below 0.2): then an info line that says so and that the run watches."""
    from vpcontact.post.diagnostics import Diagnostics
    d = Diagnostics("explicit", 0.02, None, 10.6, 2.0, False, 1.0, None, 0.0, None, None,
                    None, rate_estimate=530.0, indicator_source="stress_scale",
                    stress_scale=30.0, before_hardening=before_hardening)
    (level, text), = d.messages()
    assert level == ("info" if before_hardening else "warning")
    assert ("warns if it passes the limit" in text) == before_hardening


@pytest.mark.parametrize("Q, hardens", [(5.0, True), (0.0, True), (-5.0, False)])
def test_chaboche_hardens_with_a_nonnegative_Q(Q, hardens):
    """R' = b (Q - R) phi: with Q < 0 the law softens and r(S) at R = 0 bounds nothing."""
    from vpcontact.model.chaboche import Chaboche
    from vpcontact.model.material import Elasticity
    law = Chaboche(Elasticity(1000.0, 0.3, 2), 10.0, 20.0, 3.0, 2000.0, 50.0, Q, 10.0)
    assert law.hardens is hardens


@pytest.mark.parametrize("source, scale", [("estimated", None), ("stress_scale", 40.0)])
def test_adaptive_steps_do_not_claim_an_estimated_rate(source, scale):
    """An indicator above 2 that the law does not state (estimated, or at the stress scale)
    is a warning with time.adaptive too: the adaptive steps only know a stated r_max
    (make_stepper gets Diagnostics.relaxation_rate, None here)."""
    from vpcontact.post.diagnostics import Diagnostics
    d = Diagnostics("explicit", 1.0, None, 3.0, 2.0, False, 1.0, None, 0.0, None, None, None,
                    adaptive=True, rate_estimate=3.0, indicator_source=source,
                    stress_scale=scale)
    (level, text), = d.messages()
    assert level == "warning" and "adaptive steps will keep" not in text
    assert "unstable" in text


@pytest.mark.parametrize("coulomb, line", [
    ({"mu": 0.3}, "Coulomb friction mu p_n |u_tau|_delta (p_n by a fixed point): mu = 0.3"),
    ({"mu_s": 0.4, "mu_k": 0.25, "slip_length": 1e-4},
     "Coulomb friction mu(s) p_n |u_tau|_delta, mu(s) = mu_s - (mu_s - mu_k) "
     "min(s/slip_length, 1) (p_n by a fixed point): mu_s = 0.4, mu_k = 0.25, "
     "slip_length = 0.0001 m s")])
def test_check_lists_coulombs_variant_in_its_own_words(coulomb, line):
    """Each Coulomb variant describes itself (its CoulombLaw's name and constants with
    units), as the other laws do."""
    from vpcontact.cli.checkrun import report
    raw = paper_raw()
    raw["contact"]["friction"] = {"coulomb": coulomb}
    text = "\n".join(report(make_case(raw, mesh={"n": 4}), MPI.COMM_SELF))
    assert line in text
