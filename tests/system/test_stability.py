"""Stiff and extreme cases: explicit vs implicit history, adaptive steps, the
stability indicator and the well-posedness check of (2.6)."""
import json

import numpy as np
import pytest
from mpi4py import MPI

from conftest import PAPER_CASE, make_case, paper_raw, run_case, run_cli, validate_raw
from vpcontact.model.problem import ContactProblem
from vpcontact.post.diagnostics import trace_constant
from vpcontact.simulation import build_mesh


def _coarse(**time):
    raw = paper_raw()
    raw["mesh"]["n"] = 8
    raw["time"] = {"T": 1.0, "N": 8, **time}
    return raw


def _sigma(res):
    return np.array([s["norm_sigma_Q"] for s in res.summary["steps"]])


def test_stiff_case_explicit_blows_up_implicit_stays_bounded():
    raw = _coarse()
    raw["material"]["viscoplastic"]["lambda1"] = 1.0      # k r_max = 104
    explicit = run_case(validate_raw(raw))
    assert explicit.summary["diagnostics"]["explicit_stable"] is False
    s = _sigma(explicit)
    assert explicit.status in ("failed", "diverged") or s.max() / s[0] > 1e6
    raw["time"]["scheme"] = "implicit"
    implicit = run_case(validate_raw(raw))
    assert implicit.status == "completed"
    s = _sigma(implicit)
    assert np.all(np.isfinite(s)) and s.max() / s[0] < 2.0


def test_implicit_and_explicit_converge_to_each_other():
    """Where both are stable they differ by O(k): the gap shrinks about 2x per halving."""
    gaps = []
    for N in (8, 16, 32):
        raw = _coarse()
        raw["time"]["N"] = N
        a = run_case(validate_raw(raw))
        raw["time"]["scheme"] = "implicit"
        b = run_case(validate_raw(raw))
        ua, ub = a.problem.u.x.array, b.problem.u.x.array
        gaps.append(np.abs(ua - ub).max() / np.abs(ua).max())
    assert gaps[0] > gaps[1] > gaps[2] > 0
    assert gaps[0] / gaps[2] > 3.0   # about first order: 4 for exactly O(k)


def test_implicit_local_update_and_tangent():
    from vpcontact.model.material import Elasticity
    from vpcontact.model.viscoplastic import Perzyna
    law = Elasticity(1000.0, 0.4, 2)
    be = Perzyna(law, 1.0, 10.0).implicit()     # stiff: k/(2 lambda1) E ~ 80
    rng = np.random.default_rng(3)
    s_tr = rng.normal(size=(200, 3)) * 30
    kp = rng.uniform(0.0, 10.0, (200, 1))
    sig, kap, C = be.solve(s_tr, kp, 0.1)
    r = be.law.implicit_residual(np.column_stack([sig, kap]), s_tr, kp, 0.1)
    assert np.abs(r).max() < 1e-9 * np.abs(s_tr).max()
    assert np.all(kap >= kp - 1e-12)
    # central differences with a step well above the local Newton's stopping error (its
    # residual is only below rtol = 1e-12, and where it stops may move with round-off):
    # the noise / h stays 100x below the tolerance, the O(h^2) error far below it
    eps = np.array([1e-3, -2e-3, 5e-4])
    h = 1e-4
    fd = (be.solve(s_tr + h * (eps @ law.Cmat.T), kp, 0.1)[0]
          - be.solve(s_tr - h * (eps @ law.Cmat.T), kp, 0.1)[0]) / (2 * h)
    np.testing.assert_allclose(fd, np.einsum("nij,j->ni", C, eps), atol=1e-5 * np.abs(fd).max())


def test_adaptive_explicit_stays_bounded_and_matches_implicit():
    raw = _coarse(adaptive={})
    raw["material"]["viscoplastic"]["lambda1"] = 10.0     # r_max = 83 /s: k <= 0.012
    res = run_case(validate_raw(raw))
    assert res.status == "completed"
    ks = [s["k"] for s in res.summary["steps"]]
    assert max(ks) * res.summary["diagnostics"]["relaxation_rate"] <= 1.0 + 1e-12
    assert res.summary["steps"][-1]["t"] == pytest.approx(1.0)
    hist = res.summary["step_history"]
    assert any(h.get("reason") == "stability indicator" for h in hist)
    raw["time"] = {"T": 1.0, "N": 64, "scheme": "implicit"}
    imp = run_case(validate_raw(raw))
    a, b = _sigma(res)[-1], _sigma(imp)[-1]
    assert abs(a - b) < 0.02 * b


def test_adaptive_rejection_restores_every_history(monkeypatch):
    """A solver failure injected for k > 0.3: starting from k = 1 the step is rejected twice
    (all histories rolled back) and the run continues with k = 0.25.  With memory and slip
    dependence active, the result must equal the fixed grid N = 4 to round-off."""
    from conftest import ROOT
    from vpcontact.case import load_raw
    from vpcontact.io.errors import StepSolveError
    from vpcontact.solvers.snesvi import SNESVISolver

    raw = load_raw(ROOT / "cases" / "memory.yaml")
    raw["mesh"]["n"] = 8
    raw["contact"]["friction"]["slip"] = {"theta_inf": 0.3, "s0": 0.002}
    raw["solver"] = {"method": "snes_vi"}
    raw["time"] = {"T": 1.0, "N": 4}
    fixed = run_case(validate_raw(raw))

    original = SNESVISolver.solve
    last_t = {"t": 0.0}

    def failing(self):
        t = float(self.problem.time_data.t.value)
        if t - last_t["t"] > 0.3 + 1e-12:
            raise StepSolveError("injected failure", -5)
        last_t["t"] = t
        return original(self)

    monkeypatch.setattr(SNESVISolver, "solve", failing)
    # max_indicator 10 (k r_max <= 10, i.e. k <= 1.2): only the injected failures halve k
    raw["time"] = {"T": 1.0, "N": 1, "adaptive": {"grow": 1.0, "max_indicator": 10.0}}
    adaptive = run_case(validate_raw(raw))
    assert adaptive.status == "completed"
    hist = adaptive.summary["step_history"]
    assert [h["k"] for h in hist if not h["accepted"]] == [1.0, 0.5]
    assert all(h["reason"] == "injected failure" for h in hist if not h["accepted"])
    assert [s["k"] for s in adaptive.summary["steps"]] == [0.25] * 4
    for a, b in zip(adaptive.summary["steps"], fixed.summary["steps"], strict=True):
        for key in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y"):
            assert a[key] == pytest.approx(b[key], rel=1e-12), key
    np.testing.assert_allclose(adaptive.problem.u.x.array, fixed.problem.u.x.array,
                               rtol=0, atol=1e-14)


def test_stepper_unit():
    from vpcontact.model.stepping import AdaptiveSteps
    st = AdaptiveSteps(1.0, 0.25, rate=10.0, scheme="explicit", grow=2.0, max_change=0.1,
                       max_indicator=1.0)
    assert st.next_k(0.0) == 0.0625          # halved twice: 0.25 r = 2.5 > 1
    st.accept(0.0625, 0.05)
    assert st.k == 0.1                        # grows, capped at the limit 1/r
    assert not st.reject(0.1 / 2**10, "x")    # below k_min: give up
    st = AdaptiveSteps(1.0, 0.4, rate=None, scheme="implicit")
    assert st.next_k(0.9) == pytest.approx(0.1)  # lands on T
    assert st.next_k(1.0) is None


def test_trace_constant_converges():
    vals = []
    for n in (16, 32):
        case = make_case(mesh={"n": n})
        disc = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD)).disc
        vals.append(trace_constant(disc)[0])
    assert vals[0] == pytest.approx(vals[1], rel=0.03)
    assert 3.0 < vals[1] < 3.6


@pytest.mark.parametrize("c1,b,warned", [(60.0, 1.0, False), (300.0, 3.0, True)])
def test_wellposedness_warning_exactly_when_margin_negative(tmp_path, c1, b, warned):
    out = tmp_path / "o"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "time.N=1", "--set", "mesh.n=8",
                    "--set", f"contact.friction.c1={c1}", "--set", f"contact.friction.b={b}"])
    assert proc.returncode == 0, proc.stderr
    d = json.loads((out / "summary.json").read_text())["diagnostics"]
    assert (d["wellposedness_margin"] < 0) == warned
    assert ("uniqueness of the solution is not guaranteed" in proc.stdout) == warned


@pytest.mark.slow
def test_stability_sweep_cli(tmp_path):
    """The default sweep on a tiny mesh: every variant converges or stops with a reason, no
    traceback; the stiff explicit variants are flagged unbounded, the implicit ones not."""
    import csv
    out = tmp_path / "stab"
    proc = run_cli(["stability", PAPER_CASE, "--out", out, "--n", "4", "--steps", "4"])
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    rows = list(csv.DictReader(open(out / "stability.csv")))
    assert len(rows) >= 40
    for r in rows:
        assert r["status"] in ("completed", "failed", "diverged"), r
        if r["status"] != "completed":
            assert r["reason"], r
    # a run stopped as diverged (norms past their bound) is unbounded whatever its growth
    # up to the stop
    stiff = {(r["variant"], r["scheme"]): r["bounded"] == "True" and r["status"] != "diverged"
             for r in rows if r["variant"].startswith("lambda1=0.01")}
    assert stiff and all(v for (name, s), v in stiff.items() if s == "implicit")
    assert not any(v for (name, s), v in stiff.items() if s == "explicit")
    md = (out / "stability.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("- Explicit scheme unbounded"))
    assert "lambda1=0.01, k=1/16" in line and "lambda1=100" not in line


def _norton_relaxation(k: float, strain: float):
    """cases/norton_relaxation.yaml (a uniaxial bar, plane stress, E = 1000 Pa, nu = 0.3,
    A = 1e-6, n = 3) held at the strain from t_1 = k, three explicit steps of k."""
    from conftest import ROOT
    from vpcontact.case import load_raw
    raw = load_raw(ROOT / "cases" / "norton_relaxation.yaml")
    raw["loads"]["displacement"]["right"] = [strain, None]
    raw["time"] = {"T": 3 * k, "N": 3}
    result = run_case(validate_raw(raw))
    assert result.status == "completed"
    return result


@pytest.mark.parametrize("factor, stable", [(0.95, True), (1.25, False)])
def test_norton_bound_against_the_explicit_relaxation(factor, stable):
    """The indicator of Norton's law at the data's stress scale: S = E u / L = 40 Pa, r(S) =
    n A S^(n-1) 3 mu = 5.538 1/s (by hand); k = 0.95 and 1.25 times 2 / r(S).  The
    explicit scheme's own linearisation, measured: two runs whose held strains differ by
    1e-4 (relative), the perturbation of sigma_11 = sigma_vm after the first relaxation
    step over the one before (both at sigma = S) is 1 - k n E A S^(n-1) (the uniaxial
    closed form: the bar relaxes with E, not 3 mu): -0.647 (decays) below the bound,
    -1.167 (alternates and grows: unstable) above.  The bound is conservative by at most
    the factor 3 mu / E = 1.154 of this uniaxial state (the scheme is stable up to
    1.154 x 2 / r(S) here), so 1.25 is above both."""
    E, nu, A, n, S = 1000.0, 0.3, 1e-6, 3.0, 40.0
    r = n * A * S ** (n - 1) * 3 * E / (2 * (1 + nu))
    assert r == pytest.approx(5.538461538, rel=1e-9)
    k = factor * 2.0 / r
    a, b = _norton_relaxation(k, 0.04), _norton_relaxation(k, 0.04 * (1 + 1e-4))
    d = a.summary["diagnostics"]
    assert d["indicator_source"] == "stress_scale" and d["stress_scale"] == pytest.approx(S)
    assert d["rate_estimate"] == pytest.approx(r, rel=1e-12)
    assert d["stability_indicator"] == pytest.approx(2.0 * factor, rel=1e-12)
    assert d["explicit_stable"] is stable
    vm = [np.array([s["max_vm"] for s in res.summary["steps"]]) for res in (a, b)]
    assert vm[0][0] == pytest.approx(S, rel=1e-12)                      # sigma_1 = E u / L
    delta = vm[1] - vm[0]
    amplification = delta[1] / delta[0]
    assert amplification == pytest.approx(1 - k * n * E * A * S ** (n - 1), abs=1e-3)
    assert bool(abs(amplification) < 1) == stable
    if not stable:
        assert amplification < -1.1                                     # oscillating growth


def test_load_variants_scale_the_rigid_caps():
    """The load variants scale a rigid cap's force and moment (and, with every load, its
    prescribed displacement and rotation), never its reference point; the stress-scaling
    variant leaves the prescribed motions (u unchanged)."""
    from vpcontact.studies.stability import _loads_scaled, _scaled, apply_changes
    raw = {"mesh": {"file": "x.msh", "dim": 2},
           "material": {"E": 1000.0, "nu": 0.3},
           "loads": {"rigid": {"cap.top": {"force": [None, "-2*t"], "moment": 0.5,
                                           "displacement": [0.01, None], "rotation": 0.0,
                                           "reference": [0.0, 1.0]}}}}
    every = apply_changes(raw, _loads_scaled(raw, 100.0))["loads"]["rigid"]["cap.top"]
    assert every == {"force": [None, "(-2*t)*(100.0)"], "moment": 50.0,
                     "displacement": [1.0, None], "rotation": 0.0, "reference": [0.0, 1.0]}
    stress = apply_changes(raw, _scaled(raw, 10.0)[0])["loads"]["rigid"]["cap.top"]
    assert stress == {"force": [None, "(-2*t)*(10.0)"], "moment": 5.0,
                      "displacement": [0.01, None], "rotation": 0.0, "reference": [0.0, 1.0]}
