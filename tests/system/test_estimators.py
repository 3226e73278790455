"""The a posteriori error estimate of every run (app/post/estimators.py, app/model/recovery.py):
the space part vanishes on a homogeneous stress (patch test) and equals an independent numpy
recovery on the paper case; the time part of Norton relaxation equals its closed form to
first order in k and its effectivity tends to the one of the scheme's error expansion;
the command line writes it to history.csv, summary.json, the log and solution.xdmf (eta);
mpirun -n 2 equals the serial run."""
import csv
import json

import h5py
import numpy as np
import pytest
import yaml
from mpi4py import MPI

from conftest import PAPER_CASE, ROOT, make_case, run_case, run_cli

NORTON = ROOT / "cases" / "norton_relaxation.yaml"
EST = ("est_time", "est_space", "est_total", "est_max", "est_space_sigma_Q", "est_space_u_V",
       "est_space_kappa_Y")


def _norton(N: int):
    from vpcontact.case import load_case
    from vpcontact.simulation import run
    res = run(load_case(NORTON, [f"time.N={N}"]), MPI.COMM_WORLD)
    assert res.status == "completed"
    return res.summary


def test_space_estimate_vanishes_on_a_homogeneous_stress():
    """Patch test: Norton relaxation's stress, strain and p are uniform (P1, uniaxial), so
    sigma* = sigma_h, eps* = eps_h, kappa* = kappa_h and every indicator is round-off."""
    s = _norton(10)
    for rec in s["steps"]:
        assert rec["est_space_sigma_Q"] <= 1e-12 * rec["norm_sigma_Q"]
        assert rec["est_space_u_V"] <= 1e-12 * rec["norm_u_V"]
        assert rec["est_space_kappa_Y"] <= 1e-12 * max(rec["norm_kappa_Y"], 1e-3)


def _numpy_eta_sigma(problem) -> float:
    """eta_Q of the current sigma by an independent recovery (serial): the volume-weighted
    nodal mean of sigma over the cells around each vertex, and the exact integral of a
    linear function, int_K (sum_i g_i lambda_i)^2 = |K| (sum g_i^2 + (sum g_i)^2) / 12."""
    msh = problem.mesh
    x = msh.geometry.x[:, :2]
    cells = msh.geometry.dofmap.array.reshape(-1, 3)
    sig = problem.sigma.x.array.reshape(-1, 4)[np.asarray(problem.Q.dofmap.list.array)
                                                .reshape(-1)[:len(cells)]]
    a, b, c = x[cells[:, 0]], x[cells[:, 1]], x[cells[:, 2]]
    vol = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
                       - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    num, den = np.zeros((len(x), 4)), np.zeros(len(x))
    for i in range(3):
        np.add.at(num, cells[:, i], (vol / 3)[:, None] * sig)
        np.add.at(den, cells[:, i], vol / 3)
    star = num / den[:, None]
    g = star[cells] - sig[:, None, :]                       # (cells, 3 vertices, 4)
    per = vol * ((g**2).sum(axis=(1, 2)) + (g.sum(axis=1)**2).sum(axis=1)) / 12
    return float(np.sqrt(per.sum()))


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial numpy reference")
def test_space_estimate_equals_an_independent_recovery():
    """The paper case at h = 1/8 (non-uniform stress): eta_Q at T equals the numpy recovery
    to 1e-12, and is not round-off (the indicator sees the stress's variation)."""
    res = run_case(make_case(mesh={"n": 8}, time={"N": 4}))
    rec = res.summary["steps"][-1]
    ref = _numpy_eta_sigma(res.problem)
    assert ref > 1e-3 * rec["norm_sigma_Q"]
    assert rec["est_space_sigma_Q"] == pytest.approx(ref, rel=1e-12)
    assert rec["est_space"] == pytest.approx(rec["est_space_sigma_Q"] + rec["est_space_u_V"]
                                             + rec["est_space_kappa_Y"], rel=1e-14)


def _norton_data():
    raw = yaml.safe_load(NORTON.read_text())
    m, vp = raw["material"], raw["material"]["viscoplastic"]
    return m["E"], m["nu"], vp["A"], vp["n"], m["E"] * 0.04


def _error_coefficient(steps: int = 20000) -> float:
    """max_t |epsilon(t)| of forward Euler's error expansion sigma_n - sigma(t_n) = k
    epsilon(t_n) + O(k^2) for sigma' = f(sigma) = -E A sigma^n (held strain):
    epsilon' = f'(sigma) epsilon - sigma''/2, epsilon(0) = 0 (RK4, independent of the code);
    the kappa part (|p error| = |sigma error| / E) added."""
    E, _, A, n, s0 = _norton_data()

    def rhs(y):
        s, e = y
        f, fp = -E * A * s**n, -n * E * A * s**(n - 1)
        return np.array([f, fp * e - 0.5 * fp * f])

    y, h, best = np.array([s0, 0.0]), 1.0 / steps, 0.0
    for _ in range(steps):
        k1 = rhs(y)
        k2 = rhs(y + h / 2 * k1)
        k3 = rhs(y + h / 2 * k2)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + rhs(y + h * k3))
        best = max(best, abs(y[1]))
    return best * (1 + 1 / E)


def test_norton_time_estimate_closed_form_and_effectivity():
    """Held uniaxial strain in plane stress: G = -E A sigma^3 (1 - nu/2, nu - 1/2) / (1 -
    nu^2) (its Frobenius norm c_F E A sigma^3) and Gk = A sigma^3, monotone in t, so the
    summed local errors are (k/2) (|G(sigma_1)| + |G(sigma_1)| - |G(sigma_N)|) (the first
    from G(sigma_0) = 0: the load's jump) plus the same for Gk: est_time / k tends to that
    closed form (to 1 %), halves with k (first order), and est_total / (true error) tends to
    the closed form over the error expansion's max |epsilon| (to 3 % at N = 80; the sum of
    local errors is not damped by the relaxation, hence about 4.9 > 2)."""
    E, nu, A, n, s0 = _norton_data()
    cF = np.hypot(1 - nu / 2, nu - 0.5) / (1 - nu**2)
    sT = (s0 ** (1 - n) + (n - 1) * E * A * 1.0) ** (1 / (1 - n))     # k -> 0: t_1 -> 0
    limit = 0.5 * (cF * E + 1) * A * (2 * s0**n - sT**n)
    coeff = _error_coefficient()
    est, ratio = [], []
    for N in (20, 40, 80):
        s = _norton(N)
        k, t1 = 1.0 / N, 1.0 / N
        true = max(abs(r["max_vm"] - (s0 ** (1 - n) + (n - 1) * E * A * (r["t"] - t1))
                       ** (1 / (1 - n))) * (1 + 1 / E) for r in s["steps"])
        e = s["error_estimate"]
        assert e["time"] / k == pytest.approx(limit, rel=0.01)
        assert e["space"] < 1e-12 * e["time"]
        est.append(e["estimate"])
        ratio.append(e["estimate"] / true)
    assert est[0] / est[1] == pytest.approx(2.0, rel=0.01)
    assert est[1] / est[2] == pytest.approx(2.0, rel=0.01)
    assert ratio[-1] == pytest.approx(limit / coeff, rel=0.03)
    assert abs(ratio[-1] - limit / coeff) < abs(ratio[0] - limit / coeff)


def _cli_outputs(out):
    summary = json.loads((out / "summary.json").read_text())
    with open(out / "history.csv") as f:
        rows = list(csv.DictReader(f))
    return summary, rows


def test_cli_writes_the_estimate(tmp_path):
    """history.csv has the est_* columns equal to summary.json's steps; summary.json's
    error_estimate is the max of est_total; the log has its line; solution.xdmf has eta."""
    out = tmp_path / "run"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "mesh.n=4", "--set", "time.N=3"])
    assert proc.returncode == 0, proc.stderr
    summary, rows = _cli_outputs(out)
    steps = summary["steps"]
    for rec, row in zip(steps, rows, strict=True):
        for c in EST:
            assert float(row[c]) == pytest.approx(rec[c], rel=1e-12)
    e = summary["error_estimate"]
    assert e["estimate"] == max(r["est_total"] for r in steps) == steps[-1]["est_max"]
    assert e["estimate"] == pytest.approx(e["time"] + e["space"], rel=1e-14)
    assert "error estimate: " in proc.stdout + proc.stderr
    with h5py.File(out / "solution.h5") as f:
        names = set(f["Function"].keys())
    assert "eta" in names


@pytest.mark.mpi
def test_mpirun_equals_serial(tmp_path):
    """mpirun -n 2: every estimate of every step equals the serial run's to 1e-12."""
    outs = {}
    for nprocs in (1, 2):
        outs[nprocs] = tmp_path / f"np{nprocs}"
        proc = run_cli(["run", PAPER_CASE, "--out", outs[nprocs], "--set", "mesh.n=8",
                        "--set", "time.N=4", "--quiet"], nprocs=nprocs)
        assert proc.returncode == 0, proc.stderr
    a, b = (_cli_outputs(outs[p])[0]["steps"] for p in (1, 2))
    for ra, rb in zip(a, b, strict=True):
        for c in EST:
            assert rb[c] == pytest.approx(ra[c], rel=1e-12, abs=1e-15)


def test_convergence_reports_the_effectivity(tmp_path):
    """convergence.csv's estimate of a level is that level's own run's error_estimate (an
    independent run), its effectivity estimate / Error; the table and a second, cached
    study show the same."""
    out, cache = tmp_path / "conv", tmp_path / "cache"
    for _ in range(2):                                   # computed, then from the cache
        proc = run_cli(["convergence", PAPER_CASE, "--levels", "4", "--reference", "8",
                        "--out", out, "--overwrite", "--cache-dir", cache])
        assert proc.returncode == 0, proc.stderr
        with open(out / "convergence.csv") as f:
            row = next(csv.DictReader(f))
        own = run_case(make_case(mesh={"n": 4}, time={"N": 4})).summary["error_estimate"]
        assert float(row["estimate"]) == pytest.approx(own["estimate"], rel=1e-12)
        assert float(row["est_time"]) == pytest.approx(own["time"], rel=1e-12)
        assert float(row["effectivity"]) == pytest.approx(own["estimate"]
                                                          / float(row["error"]), rel=1e-12)
        assert "effectivity" in (out / "convergence.md").read_text()
        assert "effectivity " in proc.stdout + proc.stderr
