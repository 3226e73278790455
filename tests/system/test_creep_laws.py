"""Whole runs of the laws norton and chaboche (app/model/norton.py, app/model/chaboche.py):
the shipped cases cases/norton_relaxation.yaml (the closed form of uniaxial relaxation,
first order in k) and cases/chaboche_cycle.yaml (an independent 1D recursion of the explicit
scheme, every step); Norton creep under a constant load (exact: u_x = x (s/E + A s^n (T -
t_1))); both step solvers agree to 1e-8 on a contact scene in 2D and 3D (power too);
mpirun -n 2 equals
the serial run, solution.xdmf holds X, R, p, and its checkpoint (kappa in R^8) restarts a
serial run that equals the uninterrupted one."""
import copy
import json

import h5py
import numpy as np
import pytest
import yaml
from mpi4py import MPI

from conftest import ROOT, make_case, paper_raw, run_case, run_cli
from vpcontact.simulation import run

NORTON = ROOT / "cases" / "norton_relaxation.yaml"
CHABOCHE = ROOT / "cases" / "chaboche_cycle.yaml"
BOX = ROOT / "cases" / "box3d.yaml"
NORMS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")


def _run(path, overrides=(), **kwargs):
    from vpcontact.case import load_case
    from vpcontact.simulation import run
    result = run(load_case(path, list(overrides)), MPI.COMM_WORLD, **kwargs)
    assert result.status == "completed"
    return result


def _cells(result):
    """sigma (cells, d, d) and kappa (cells, m) of a run at T."""
    p = result.problem
    d = p.disc.dim
    return p.sigma.x.array.reshape(-1, d, d), p.state.kappa.x.array.reshape(-1, p.law.m)


def test_norton_relaxation_case_first_order(tmp_path):
    """The shipped case: sigma_xx(T) against [s0^(1-n) + (n-1) E A (T - t_1)]^(1/(1-n)),
    s0 = E u / L at t_1 = k; the error halves with k; p = u/L - sigma_xx / E (the creep strain
    replaced the elastic one); solution.xdmf holds p (not kappa) as a cell field."""
    from vpcontact.observers import FieldOutput
    out = tmp_path / "out"
    out.mkdir()
    raw = yaml.safe_load(NORTON.read_text())
    vp, E, e = raw["material"]["viscoplastic"], raw["material"]["E"], 0.04
    errors = []
    for N in (20, 40):
        res = _run(NORTON, [f"time.N={N}"], **({"observers": [FieldOutput()], "outdir": out}
                                               if N == 20 else {}))
        sigma, kappa = _cells(res)
        s = sigma[:, 0, 0]
        np.testing.assert_allclose(s, s[0], rtol=1e-12)                    # homogeneous
        np.testing.assert_allclose(sigma[:, 1, 1], 0.0, atol=1e-10 * s[0])  # uniaxial
        t1, n = 1.0 / N, vp["n"]
        exact = ((E * e) ** (1 - n) + (n - 1) * E * vp["A"] * (1.0 - t1)) ** (1 / (1 - n))
        errors.append(abs(s[0] - exact) / exact)
        np.testing.assert_allclose(kappa[:, 0], e - s / E, rtol=1e-10)
    print("norton_relaxation.yaml: relative errors of sigma(T) at N = 20, 40:", errors)
    text = (out / "solution.xdmf").read_text()
    assert text.count('Attribute Name="p" AttributeType="Scalar" Center="Cell"') == 21
    assert 'Name="kappa"' not in text
    assert exact < 0.6 * E * e                 # it relaxed
    assert errors[1] < 2e-2 and 1.8 < errors[0] / errors[1] < 2.2


def _creep_raw(dim, method):
    raw = yaml.safe_load(NORTON.read_text())
    sides = ({"left": [0.0, None], "bottom": [None, 0.0]} if dim == 2 else
             {"left": [0.0, None, None], "front": [None, 0.0, None],
              "bottom": [None, None, 0.0]})
    raw["mesh"] = {"dim": dim, "n": 2}
    raw["loads"] = {"displacement": sides,
                    "traction": {"right": [25.0, 0.0] + [0.0] * (dim - 2)}}
    raw["solver"] = {"method": method}
    raw["time"] = {"T": 1.0, "N": 5}
    return raw


@pytest.mark.parametrize("dim", [2, 3])
def test_norton_creep_under_constant_load(dim):
    """Rollers and a traction s = 25 Pa on the right: the stress is s at every step, so the
    scheme's creep strain is exact, A s^n (t - t_1) (the first step only loads): u_x = x
    (s/E + A s^n (T - t_1)), the lateral u = -y (nu s/E + A s^n (T - t_1)/2); both step
    solvers."""
    results = {m: run_case(make_case(_creep_raw(dim, m))) for m in ("fast", "snes_vi")}
    E, nu, A, n, s = 1000.0, 0.3, 1e-6, 3.0, 25.0
    creep = A * s ** n * (1.0 - 0.2)
    for res in results.values():
        assert res.status == "completed"
        p = res.problem
        x = p.disc.V.tabulate_dof_coordinates()[:, :dim]
        u = p.u.x.array.reshape(-1, dim)
        np.testing.assert_allclose(u[:, 0], x[:, 0] * (s / E + creep), rtol=0, atol=1e-12)
        for j in range(1, dim):
            np.testing.assert_allclose(u[:, j], -x[:, j] * (nu * s / E + creep / 2), rtol=0,
                                       atol=1e-12)
        assert creep > 0.4 * s / E              # the creep strain is not small


def _cycle_recursion(raw, times):
    """The explicit scheme (3.2)-(3.3) of the homogeneous bar written in 1D: with x = 3/2
    X_11, the rates at step j - 1 update e_vp, x, R, p, then s_j = E (e(t_j) - e_vp_j)."""
    vp, E = raw["material"]["viscoplastic"], raw["material"]["E"]
    table = np.array(raw["loads"]["displacement"]["right"][0]["table"])
    s = x = R = p = ev = 0.0
    out = []
    for t0, t1 in zip(times, times[1:]):
        k = t1 - t0
        pr = max((abs(s - x) - R - vp["k"]) / vp["K"], 0.0) ** vp["n"]
        dev = pr * np.sign(s - x)
        ev, x, R, p = (ev + k * dev, x + k * (vp["C"] * dev - vp["gamma"] * x * pr),
                       R + k * vp["b"] * (vp["Q"] - R) * pr, p + k * pr)
        s = E * (np.interp(t1, table[:, 0], table[:, 1]) - ev)
        out.append((s, x, R, p))
    return np.array(out)


@pytest.mark.parametrize("dim", [2, 3])
def test_chaboche_cycle_against_a_1d_recursion(dim):
    """The shipped cycle (2D; in 3D the unit cube on rollers): max ||sigma||_VM = |s_j| at
    every step and sigma_xx, X, R, p at T equal the 1D recursion to 1e-10; X is uniaxial and
    deviatoric; the cycle went through yield, hardening and reversal."""
    raw = yaml.safe_load(CHABOCHE.read_text())
    run_raw = copy.deepcopy(raw)
    run_raw["time"]["N"] = 100
    if dim == 3:
        run_raw["mesh"]["dim"] = 3
        disp = run_raw["loads"]["displacement"]
        disp.update({"left": [0.0, None, None], "bottom": [None, None, 0.0],
                     "front": [None, 0.0, None], "right": disp["right"] + [None]})
    res = run_case(make_case(run_raw))
    assert res.status == "completed"
    ref = _cycle_recursion(raw, np.linspace(0.0, 4.0, 101))
    vm = np.array([st["max_vm"] for st in res.summary["steps"]])
    np.testing.assert_allclose(vm, np.abs(ref[:, 0]), rtol=1e-10, atol=1e-10 * 40)
    sigma, kappa = _cells(res)
    s, x, R, p = ref[-1]
    np.testing.assert_allclose(sigma[:, 0, 0], s, rtol=1e-10)
    np.testing.assert_allclose(1.5 * kappa[:, 0], x, rtol=1e-10)
    np.testing.assert_allclose(kappa[:, 1], -kappa[:, 0] / 2, rtol=1e-10)
    np.testing.assert_allclose(kappa[:, 2], -kappa[:, 0] / 2, rtol=1e-10)
    np.testing.assert_allclose(kappa[:, 3:6], 0.0, atol=1e-12)
    np.testing.assert_allclose(kappa[:, 6:], np.broadcast_to([R, p], (len(kappa), 2)),
                               rtol=1e-10)
    assert p > 0.01 and R > 0.5 and ref[:, 0].max() > 20 and ref[:, 0].min() < -20


LAWS = {"norton": {"law": "norton", "A": 2e-5, "n": 3},
        "power": {"law": "power", "lambda1": 100.0, "lambda2": 100.0, "n": 3, "s_ref": 20.0},
        "chaboche": {"law": "chaboche", "k": 2.0, "K": 200.0, "n": 1.5, "C": 500.0,
                     "gamma": 20.0, "Q": 2.0, "b": 5.0}}


@pytest.mark.parametrize("law", ["norton", "chaboche", "power"])
@pytest.mark.parametrize("dim, plane", [(2, "stress"), (2, "strain"), (3, None)])
def test_fast_equals_snes_vi_on_contact(law, dim, plane):
    """The paper's scene (2D, h = 1/4, 8 steps; plane stress and plane strain, where kappa
    carries eps_vp33 for norton and chaboche) and its 3D analogue (h = 1/2, 4 steps) with the
    law (power: n = 3, s_ref = 20 Pa, stable at these steps): the condensed
    solver and SNES VI agree to 1e-8 (u, sigma, kappa at T and the norms of every step); the
    law flowed."""
    raw = paper_raw() if dim == 2 else yaml.safe_load(BOX.read_text())
    raw["material"]["viscoplastic"] = dict(LAWS[law])
    if plane is not None:
        raw["material"]["plane"] = plane
    sections = {"mesh": {"n": 4 if dim == 2 else 2}, "time": {"N": 8 if dim == 2 else 4}}
    runs = {m: run_case(make_case(raw, solver={"method": m}, **copy.deepcopy(sections)))
            for m in ("condensed", "snes_vi")}
    a, b = runs["condensed"], runs["snes_vi"]
    assert a.status == b.status == "completed"
    for x, y in zip(a.summary["steps"], b.summary["steps"], strict=True):
        for key in NORMS:
            assert x[key] == pytest.approx(y[key], rel=1e-8, abs=1e-14), key
    for f in ("u", "sigma"):
        fa, fb = getattr(a.problem, f).x.array, getattr(b.problem, f).x.array
        assert np.abs(fa - fb).max() <= 1e-8 * np.abs(fb).max()
    ka, kb = _cells(a)[1], _cells(b)[1]
    assert np.abs(ka - kb).max() <= 1e-8 * np.abs(kb).max()
    assert kb[:, 7 if law == "chaboche" else 0].max() > 0          # p grew


@pytest.fixture(scope="module")
def mpi_cycle(tmp_path_factory):
    """The chaboche cycle (h = 1/2, 20 steps) by mpirun -n 2, with a checkpoint at step 10."""
    out = tmp_path_factory.mktemp("chaboche_mpi") / "np2"
    proc = run_cli(["run", CHABOCHE, "--out", out, "--quiet", "--set", "mesh.n=2",
                    "--set", "time.N=20", "--set", "output.checkpoint_every=10"], nprocs=2)
    assert proc.returncode == 0, proc.stderr
    return out


def test_mpi_equals_serial_and_checkpoint_restarts(mpi_cycle, tmp_path):
    """mpirun -n 2 equals the serial run (every step's norms to 1e-10); solution.xdmf holds
    X (a cell tensor), X_33, R and p at every output time, and X_33 = -X_11 - X_22; the
    checkpoint of step 10 written on two ranks (kappa with 8 columns) restarts a serial run
    whose steps equal the uninterrupted run's."""
    from vpcontact.io.checkpoint import Checkpoint
    sets = ["mesh.n=2", "time.N=20"]
    serial = _run(CHABOCHE, sets)
    two = json.loads((mpi_cycle / "summary.json").read_text())
    for x, y in zip(two["steps"], serial.summary["steps"], strict=True):
        for key in NORMS:
            assert x[key] == pytest.approx(y[key], rel=1e-10, abs=1e-14), key
    text = (mpi_cycle / "solution.xdmf").read_text()
    for name, kind in (("X", "Tensor"), ("X_33", "Scalar"), ("R", "Scalar"), ("p", "Scalar")):
        assert text.count(f'Attribute Name="{name}" AttributeType="{kind}" Center="Cell"') == 21
    with h5py.File(mpi_cycle / "solution.h5", "r") as f:
        last = sorted(f["Function/X"].keys(), key=lambda k: float(k.replace("_", ".")))[-1]
        X, X33 = f[f"Function/X/{last}"][:], f[f"Function/X_33/{last}"][:, 0]
        p = f[f"Function/p/{last}"][:, 0]
    np.testing.assert_allclose(X33, -X[:, 0] - X[:, 4], atol=1e-12 * np.abs(X).max())
    np.testing.assert_allclose(p, _cells(serial)[1][0, 7], rtol=1e-10)
    restarted = _run(CHABOCHE, sets, restart=Checkpoint(mpi_cycle / "checkpoint_000010.npz"))
    for x, y in zip(restarted.summary["steps"], serial.summary["steps"], strict=True):
        for key in NORMS:
            assert x[key] == pytest.approx(y[key], rel=1e-10, abs=1e-14), key
    np.testing.assert_allclose(_cells(restarted)[1], _cells(serial)[1], rtol=1e-10,
                               atol=1e-12)


@pytest.mark.parametrize("law", [{"law": "norton", "A": 1e-4, "n": 3},
                                 {"law": "chaboche", "k": 2.0, "K": 5.0, "n": 3, "C": 500.0,
                                  "gamma": 20.0, "Q": 2.0, "b": 5.0}])
def test_stiff_step_implicit_completes(law):
    """A step far beyond the explicit limit (the paper's scene, h = 1/4, k = 1/4): the
    explicit scheme is stopped as diverged by the blow-up monitor, the implicit one (the local
    Newton per cell with the finite-difference tangent, m = 1 or 8) completes with p > 0."""
    raw = paper_raw()
    raw["material"]["viscoplastic"] = dict(law)
    out = {}
    for scheme in ("explicit", "implicit"):
        out[scheme] = run_case(make_case(raw, mesh={"n": 4}, time={"N": 4, "scheme": scheme}))
    assert out["explicit"].status == "diverged"
    res = out["implicit"]
    assert res.status == "completed"
    sigma, kappa = _cells(res)
    assert np.isfinite(sigma).all() and np.isfinite(kappa).all() and kappa[:, -1].max() > 0


def _plane_strain_pair(path, steps):
    """The shipped case in 2D plane strain and on the unit cube with eps_33 = 0 (u_z = 0 on
    its bottom and top; y = 0 on rollers, the back face free): the same homogeneous state."""
    raw = yaml.safe_load(path.read_text())
    raw["time"]["N"] = steps
    two = copy.deepcopy(raw)
    two["material"]["plane"] = "strain"
    two["mesh"]["n"] = 1
    three = copy.deepcopy(raw)
    three["mesh"] = {"dim": 3, "n": 1}
    right = raw["loads"]["displacement"]["right"]
    three["loads"]["displacement"] = {"left": [0.0, None, None], "front": [None, 0.0, None],
                                      "bottom": [None, None, 0.0], "top": [None, None, 0.0],
                                      "right": right + [None]}
    return make_case(two), make_case(three)


@pytest.mark.parametrize("path, steps", [(NORTON, 20), (CHABOCHE, 40)])
def test_plane_strain_equals_3d(path, steps, tmp_path):
    """law norton (kappa = (p, eps_vp33)) and chaboche (kappa = (X, R, p, eps_vp33)) in 2D
    plane strain equal the 3D law on a cube held at eps_33 = 0 (the 3D law knows nothing of
    plane strain): at T sigma_11, sigma_22, sigma_12, p (Chaboche: X, R, p) to 1e-10, and the
    3D sigma_33 is nu (sigma_11 + sigma_22) - E eps_vp33 of the 2D run; solution.xdmf of the
    2D run holds eps_vp33."""
    from vpcontact.observers import FieldOutput
    two, three = _plane_strain_pair(path, steps)
    a = run(two, MPI.COMM_WORLD, observers=[FieldOutput()], outdir=tmp_path) \
        if path == NORTON else run_case(two)
    b = run_case(three)
    assert a.status == b.status == "completed"
    (s2, k2), (s3, k3) = _cells(a), _cells(b)
    scale = np.abs(s3).max()
    np.testing.assert_allclose(s2[:, [0, 1, 0], [0, 1, 1]],
                               np.broadcast_to(s3[0, [0, 1, 0], [0, 1, 1]], (len(s2), 3)),
                               rtol=0, atol=1e-10 * scale)
    E, nu = two.material.E, two.material.nu
    np.testing.assert_allclose(nu * (s2[:, 0, 0] + s2[:, 1, 1]) - E * k2[:, -1], s3[0, 2, 2],
                               rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(k2[:, :-1], np.broadcast_to(k3[0], (len(k2), k3.shape[1])),
                               rtol=1e-10, atol=1e-12 * np.abs(k3).max())
    print(f"{two.material.viscoplastic.law} plane strain = 3D with eps_33 = 0: p = "
          f"{k3[0, -1]:.3g}, eps_vp33 = {k2[0, -1]:.3g}, sigma_33 = {s3[0, 2, 2]:.3g}")
    assert k3[0, -1] > 5e-3 and abs(k2[0, -1]) > 5e-4                        # it crept
    if path == NORTON:
        text = (tmp_path / "solution.xdmf").read_text()
        assert text.count('Attribute Name="eps_vp33" AttributeType="Scalar" '
                          'Center="Cell"') == steps + 1


@pytest.mark.parametrize("law", [
    {"law": "norton", "A": 1e-3, "n": 300},
    {"law": "chaboche", "k": 1.0, "K": 1e-90, "n": 200, "C": 0.0, "gamma": 0.0, "Q": 0.0,
     "b": 0.0},
    {"law": "power", "lambda1": 1.0, "lambda2": 1.0, "n": 100, "s_ref": 1e-90},
], ids=["norton", "chaboche", "power"])
def test_rates_that_overflow_end_the_run_cleanly(law):
    """Law constants whose rates overflow a float at the case's stresses (the paper's scene,
    tractions of 8 N/m: 20^299 > 1.8e308 for Norton's r(S)): the stability indicator is
    infinite (the warning says no time step is stable) and the run ends with a summary;
    before, the diagnostics raised numpy's LinAlgError on the non-finite Jacobian (an
    internal error of the set-up, or of the rate watch after step 1)."""
    raw = paper_raw()
    raw["material"]["viscoplastic"] = law
    res = run_case(make_case(raw, mesh={"n": 8}, time={"N": 4}))
    d = res.summary["diagnostics"]
    assert res.status in ("failed", "diverged") and res.summary["failure"] is not None
    if law["law"] == "power":                 # no r(S): estimated from step 1 on
        assert d["estimated_indicator_max"] == np.inf
    else:
        assert d["stability_indicator"] == np.inf and d["explicit_stable"] is False
