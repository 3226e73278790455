"""3D: patch test, the box case's nodal contact laws, and serial == mpirun -n 2."""
import csv
import json
import os

import numpy as np
import pytest

from conftest import ROOT, paper_raw, run_case, run_cli, validate_raw
from vpcontact.forms.elasticity import lame_constants
from vpcontact.post.quantities import contact_table

BOX = ROOT / "cases" / "box3d.yaml"


@pytest.mark.parametrize("size", [{"kind": "structured", "n": 2},
                                  {"kind": "unstructured", "h": 0.5}])
def test_3d_uniform_stress_patch(size):
    """u = (a x, b x, c x) vanishes on x = 0 with uniform strain; tractions sigma n on the
    other five faces make it exact, and P1 tetrahedra must reproduce it to round-off."""
    E, nu, a, b, c = 1000.0, 0.3, 2e-3, -1e-3, 5e-4
    lmbda, two_mu = lame_constants(E, nu, 3)
    grad = np.zeros((3, 3))
    grad[:, 0] = (a, b, c)
    eps = 0.5 * (grad + grad.T)
    sigma = lmbda * np.trace(eps) * np.eye(3) + two_mu * eps
    normals = {"right": [1, 0, 0], "top": [0, 0, 1], "bottom": [0, 0, -1],
               "front": [0, -1, 0], "back": [0, 1, 0]}
    raw = paper_raw()
    del raw["contact"]
    raw["material"] = {"E": E, "nu": nu}
    raw["mesh"] = {"dim": 3, "L1": 1.0, "L2": 0.5, "L3": 0.75, **size}
    raw["loads"] = {"traction": {k: [float(v) for v in sigma @ n] for k, n in normals.items()}}
    raw["time"] = {"T": 1.0, "N": 1}
    p = run_case(validate_raw(raw)).problem
    x = p.disc.V.tabulate_dof_coordinates()
    exact = np.outer(x[:, 0], [a, b, c])
    u = p.u.x.array.reshape(-1, 3)
    assert np.abs(u - exact).max() <= 1e-11 * np.abs(exact).max()
    s = p.sigma.x.array.reshape(-1, 3, 3)
    assert np.abs(s - sigma).max() <= 1e-9 * np.abs(sigma).max()


def test_box_case_nodal_laws():
    """Normal law (4.1) and the vector friction law at every Gamma3 node of the 3D case."""
    from vpcontact.case import load_raw
    raw = load_raw(BOX)
    raw["mesh"]["n"] = 4
    raw["time"]["N"] = 4
    res = run_case(validate_raw(raw))
    case, tab = res.problem.case, contact_table(res.problem)
    c_nu, g, fr = case.contact.c_nu, case.contact.g, case.contact.friction
    tol = 1e-7 * c_nu * g
    u_nu, f_nu = tab["u_nu"], tab["neg_sigma_nu"]
    bound = u_nu >= g * (1 - 1e-9)
    inside = (u_nu > 0) & ~bound
    assert bound.sum() > 0 and inside.sum() > 0
    np.testing.assert_allclose(f_nu[inside], c_nu * u_nu[inside], atol=tol)
    assert np.all(f_nu[bound] >= c_nu * g - tol)
    ut = np.column_stack([tab["u_tau1"], tab["u_tau2"]])
    ft = np.column_stack([tab["neg_sigma_tau1"], tab["neg_sigma_tau2"]])
    r = np.linalg.norm(ut, axis=1)
    assert np.all(r > 1e-5)
    dpsi = np.where(r <= fr.u1, fr.b - fr.c1 * r, fr.c2 * (r - fr.u1) + fr.b - fr.c1 * fr.u1)
    np.testing.assert_allclose(ft, (dpsi / r)[:, None] * ut, rtol=1e-6, atol=tol)


@pytest.mark.mpi
@pytest.mark.slow
@pytest.mark.parametrize("extra", [
    ["--set", "time.N=4"],
    # m = 1026 >= PCG_MIN: the kept factor and CG; under mpirun rank 0 borrows rank 1's core
    ["--set", "time.N=2", "--set", "mesh.n=18"],
    # PETSc's MUMPS for the steps, S from a G-last factorisation on rank 0
    ["--set", "time.N=4", "--set", "petsc.fast_pc_factor_mat_solver_type=mumps"],
], ids=["mumps_schur", "kept_factor", "petsc_path"])
def test_box_serial_equals_two_ranks(tmp_path, extra):
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(2) as pool:           # the two runs side by side
        procs = pool.map(lambda n: run_cli(["run", BOX, "--out", tmp_path / f"np{n}",
                                            "--quiet", *extra], nprocs=n), (1, 2))
    out = {}
    for n, proc in zip((1, 2), procs, strict=True):
        assert proc.returncode == 0, proc.stdout + proc.stderr
        out[n] = (json.loads((tmp_path / f"np{n}" / "summary.json").read_text()),
                  list(csv.DictReader(open(tmp_path / f"np{n}" / "contact.csv"))))
    (s1, c1), (s2, c2) = out[1], out[2]
    assert s2["mpi_ranks"] == 2 and s1["mesh"] == s2["mesh"]
    g1, g2 = s1["solver"]["gamma3"], s2["solver"]["gamma3"]
    assert s1["solver"]["used"] == s2["solver"]["used"] == "condensed"
    assert s2["solver"]["factorisations"] == (2 if "petsc" in extra[-1] else 1)
    if "mesh.n=18" in extra:                 # the Gamma3 problem's threads: both cores
        assert g1["cg_iterations"] > 0 and g2["cg_iterations"] > 0
        assert g2["threads"] == min(2, len(os.sched_getaffinity(0)))
    for a, b in zip(s1["steps"], s2["steps"], strict=True):
        for key in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa"):
            assert b[key] == pytest.approx(a[key], rel=1e-8), key
    assert list(c1[0]) == ["x", "y", "z", "u_x", "u_y", "u_z", "u_nu", "u_tau1", "u_tau2",
                           "u_tau", "neg_sigma_nu", "neg_sigma_tau1", "neg_sigma_tau2", "state"]
    for col in ("u_x", "u_y", "u_z", "neg_sigma_nu", "neg_sigma_tau1", "neg_sigma_tau2"):
        v1 = np.array([float(r[col]) for r in c1])
        v2 = np.array([float(r[col]) for r in c2])
        np.testing.assert_allclose(v2, v1, rtol=1e-8, atol=1e-10 * np.abs(v1).max())


def test_convergence_refuses_3d(tmp_path):
    proc = run_cli(["convergence", BOX, "--levels", "2", "--reference", "4", "--out",
                    tmp_path / "o", "--no-cache"])
    assert proc.returncode == 2 and "mesh.dim" in proc.stderr


def _gamg_events() -> dict:
    from petsc4py import PETSc
    PETSc.Log.begin()                     # (the runs begin it too: app/post/phases.py)
    return {e: PETSc.Log.Event(e).getPerfInfo()["count"]
            for e in ("MatCoarsen", "PCGAMG Gal l00", "vpcontact Galerkin")}


def test_box_amg_equals_lu():
    """SNES VI with CG + GAMG (on J with the active rows replaced by the identity) and with
    LU on the 3D box: with exact linear solves (snes_ksp_ew off) the same Newton iterations
    and the same u_n to 1e-8; with the default inexact Newton (Eisenstat-Walker forcing) the
    same u_n to 1e-8 with fewer Krylov iterations.  GAMG's interpolation is built at most
    once per step: the other set-ups recompute the levels only (PETSc's events)."""
    from vpcontact.case import load_raw
    runs = {}
    for name, linear, petsc in (("lu", "direct", {}), ("exact", "amg", {"snes_ksp_ew": False}),
                                ("ew", "amg", {}), ("own", "amg", {"amg_keep_levels": False})):
        raw = load_raw(BOX)
        raw["mesh"]["n"] = 6
        raw["time"]["N"] = 3
        raw["solver"] = {"method": "snes_vi", "linear": linear}
        raw["petsc"] = {**raw.get("petsc", {}), **petsc}
        before = _gamg_events()
        res = run_case(validate_raw(raw))
        steps = res.summary["steps"]
        assert res.summary["solver"]["linear"] == linear
        amg = res.summary["solver"]["amg"]
        if name == "own":          # GAMG's own re-set-ups, as under MPI: no kept levels
            events = {k: v - before[k] for k, v in _gamg_events().items()}
            assert events["vpcontact Galerkin"] == 0
            assert events["PCGAMG Gal l00"] == amg["setups"] + 1
        elif linear == "amg":
            events = {k: v - before[k] for k, v in _gamg_events().items()}
            # GAMG sets itself up (aggregation, the Galerkin product of level 0) once per
            # interpolation (and once for the trace constant); the other set-ups recompute
            # the levels outside it (app/solvers/levels.py)
            assert amg["interpolations"] <= len(steps) < amg["setups"]
            assert events["PCGAMG Gal l00"] == amg["interpolations"] + 1
            assert events["vpcontact Galerkin"] == amg["setups"] - amg["interpolations"]
            assert 0 < events["MatCoarsen"]
        else:
            assert amg is None
        runs[name] = (res.problem.u.x.array.copy(), steps)
    (u_lu, lu), (u_amg, amg), (u_ew, ew) = runs["lu"], runs["exact"], runs["ew"]
    assert np.linalg.norm(runs["own"][0] - u_lu) <= 1e-8 * np.linalg.norm(u_lu)
    assert [s["newton_iterations"] for s in amg] == [s["newton_iterations"] for s in lu]
    assert np.linalg.norm(u_amg - u_lu) <= 1e-8 * np.linalg.norm(u_lu)
    assert all(s["linear_iterations"] > s["newton_iterations"] for s in amg)
    assert np.linalg.norm(u_ew - u_lu) <= 1e-8 * np.linalg.norm(u_lu)
    assert sum(s["linear_iterations"] for s in ew) < sum(s["linear_iterations"] for s in amg)


@pytest.mark.mpi
def test_box_amg_serial_equals_two_ranks(tmp_path):
    """SNES VI with CG + GAMG under mpirun -n 2 (the embedded Jacobian's rows split over the
    ranks) equals the serial run: u at the Gamma3 nodes and the contact forces to 1e-8."""
    out = {}
    for n in (1, 2):
        proc = run_cli(["run", BOX, "--out", tmp_path / f"np{n}", "--quiet", "--no-plots",
                        "--set", "mesh.n=8", "--set", "time.N=3", "--set",
                        "solver.method=snes_vi", "--set", "solver.linear=amg"], nprocs=n)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        summary = json.loads((tmp_path / f"np{n}" / "summary.json").read_text())
        assert summary["solver"]["amg"]["setups"] > 1
        rows = list(csv.DictReader(open(tmp_path / f"np{n}" / "contact.csv")))
        out[n] = {k: np.array([float(r[k]) for r in rows])
                  for k in ("u_x", "u_y", "u_z", "neg_sigma_nu", "neg_sigma_tau1")}
    for key, v1 in out[1].items():
        np.testing.assert_allclose(out[2][key], v1, rtol=0, atol=1e-8 * np.abs(v1).max())
