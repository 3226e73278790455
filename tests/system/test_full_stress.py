"""The full stress in 2D plane strain: sigma_33 and the 3D von Mises norm in
solution.xdmf, history.csv and the Python API, against references independent of the code:
the hand formulas of sigma_33 and of the 3D norm, the 3D Lame constants of a uniform strain,
and a Norton plane-strain relaxation integrated by scipy's ODE solver."""
from __future__ import annotations

import csv

import h5py
import numpy as np
import pytest
import yaml
from mpi4py import MPI
from scipy.integrate import solve_ivp

from conftest import ROOT, run_cli

HERTZ = ROOT / "cases" / "hertz_cylinder.yaml"
NORTON = ROOT / "cases" / "norton_relaxation.yaml"


def vm3(s11, s22, s33, s12):
    """The 3D von Mises norm written out (independent of the code's forms)."""
    return np.sqrt(0.5 * ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2)
                   + 3.0 * s12 ** 2)


def _history(outdir):
    with open(outdir / "history.csv") as f:
        return [{k: float(v) if v not in ("", None) else None for k, v in row.items()}
                for row in csv.DictReader(f)]


def _last_fields(outdir):
    """The written sigma (9 components per cell) and sigma_vm at the last output time."""
    with h5py.File(outdir / "solution.h5", "r") as f:
        key = sorted(f["Function/sigma"], key=lambda k: float(k.replace("_", ".")))[-1]
        return f["Function/sigma"][key][:], f["Function/sigma_vm"][key][:, 0]


@pytest.mark.parametrize("nprocs", [1, 2])
def test_hertz_cylinder_writes_the_3d_von_mises(tmp_path, nprocs):
    """hertz_cylinder (plane strain, elastic): the written sigma has sigma_33 = nu (s11 +
    s22) in every row (also gathered from 2 ranks), sigma_vm and history.csv's max_vm are the
    3D norm of the written components (the in-plane norm with sigma_33 = 0 was 51.0 against
    32.0)."""
    out = tmp_path / "hertz"
    r = run_cli(["run", HERTZ, "--out", out], nprocs=nprocs)
    assert r.returncode == 0, r.stderr
    s, vm = _last_fields(out)
    nu = 0.3
    s33 = nu * (s[:, 0] + s[:, 4])
    np.testing.assert_allclose(s[:, 8], s33, rtol=0, atol=1e-12 * np.abs(s).max())
    assert np.all(s[:, [2, 5, 6, 7]] == 0.0)
    want = vm3(s[:, 0], s[:, 4], s33, s[:, 1])
    np.testing.assert_allclose(vm, want, rtol=1e-12, atol=1e-12 * want.max())
    max_vm = _history(out)[-1]["max_vm"]
    assert max_vm == pytest.approx(want.max(), rel=1e-12)
    print(f"hertz_cylinder: max von Mises {max_vm:.4g} (3D, sigma_33 = nu (s11 + s22))")
    assert max_vm < 0.7 * vm3(s[:, 0], s[:, 4], 0.0, s[:, 1]).max()   # 32.0 against 51.0


def _norton_reference(times, E, nu, A, n, e11):
    """The 3D Norton law at eps_11 = e11 held, sigma_22 = 0 (rollers), eps_33 = 0 (plane
    strain), by scipy's solve_ivp: y = (eps_vp11, eps_vp22, eps_vp33); the elastic strains
    give s11 - nu s33 = E (e11 - eps_vp11), s33 - nu s11 = -E eps_vp33."""
    M = np.array([[1.0, -nu], [-nu, 1.0]])

    def stress(y):
        s11, s33 = np.linalg.solve(M, E * np.array([e11 - y[0], -y[2]]))
        return s11, s33

    def rate(_, y):
        s11, s33 = stress(y)
        s = np.array([s11, 0.0, s33])
        dev = s - s.mean()
        seq = np.sqrt(1.5 * dev @ dev)
        return A * seq ** n * 1.5 * dev / seq if seq > 0 else np.zeros(3)

    sol = solve_ivp(rate, (times[0], times[-1]), np.zeros(3), t_eval=times, method="LSODA",
                    rtol=1e-11, atol=1e-14)
    s11, s33 = np.array([stress(y) for y in sol.y.T]).T
    return s11, s33, vm3(s11, 0.0, s33, 0.0), sol.y.T


def test_norton_plane_strain_relaxation_against_scipy(tmp_path):
    """cases/norton_relaxation.yaml in plane strain (100 steps): history.csv's max_vm and
    the written sigma_11, sigma_33 follow the 3D law at eps_33 = 0 integrated by scipy,
    within the explicit scheme's first-order error (the in-plane norm gave 44.0 against
    39.1 at t_1)."""
    out, N = tmp_path / "norton", 100
    r = run_cli(["run", NORTON, "--out", out, "--set", "material.plane=strain",
                 "--set", f"time.N={N}"])
    assert r.returncode == 0, r.stderr
    rows = _history(out)
    t = np.array([row["t"] for row in rows])
    s11, s33, vm, eps_vp = _norton_reference(t, 1000.0, 0.3, 1.0e-6, 3, 0.04)
    got = np.array([row["max_vm"] for row in rows])
    assert got[0] == pytest.approx(vm[0], rel=1e-12)          # t_1: elastic, exact
    err = np.abs(got - vm).max() / vm[0]
    print(f"norton plane strain: max_vm {got[0]:.4g} -> {got[-1]:.4g}, scipy "
          f"{vm[0]:.4g} -> {vm[-1]:.4g}; largest difference {err:.2e} of sigma_vm(t_1)")
    assert err < 5e-3
    s, written_vm = _last_fields(out)
    np.testing.assert_allclose(s[:, 0], s11[-1], rtol=5e-3)
    np.testing.assert_allclose(s[:, 8], s33[-1], rtol=5e-3)
    np.testing.assert_allclose(written_vm, vm3(s[:, 0], s[:, 4], s[:, 8], s[:, 1]),
                               rtol=1e-12)
    with h5py.File(out / "solution.h5", "r") as f:          # the creep strain tensor
        g = f["Function/eps_vp"]
        vp = g[sorted(g, key=lambda k: float(k.replace("_", ".")))[-1]][:]
    np.testing.assert_allclose(vp[:, [0, 4, 8]], np.broadcast_to(eps_vp[-1], (len(vp), 3)),
                               rtol=1e-2)
    np.testing.assert_allclose(vp[:, 0] + vp[:, 4] + vp[:, 8], 0.0, atol=1e-15)


def _patch(tmp_path, material):
    from vpcontact.case import load_case
    from vpcontact.simulation import run
    ux, uy = "t*(0.001*x + 0.0005*y)", "t*(0.0005*x - 0.002*y)"
    raw = {"mesh": {"n": 4, "diagonal": "left"}, "material": material,
           "boundaries": {"clamped": [], "contact": []},
           "loads": {"displacement": {s: [ux, uy] for s in ("left", "right", "bottom", "top")}},
           "time": {"T": 1.0, "N": 1}}
    path = tmp_path / "patch.yaml"
    path.write_text(yaml.safe_dump(raw))
    res = run(load_case(path, []), MPI.COMM_WORLD)
    assert res.status == "completed"
    return res.problem


def test_elastic_plane_strain_patch(tmp_path):
    """A uniform strain (eps_33 = 0): in every cell sigma = lambda tr(eps) I + 2 mu eps with
    the 3D Lame constants, sigma_33 = lambda tr(eps) = nu (s11 + s22) (problem.sigma_33,
    problem.stress_3d()) and sigma_vm the 3D norm of that tensor."""
    E, nu = 1000.0, 0.3
    p = _patch(tmp_path, {"E": E, "nu": nu, "plane": "strain"})
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    e = np.array([[0.001, 0.0005, 0.0], [0.0005, -0.002, 0.0], [0.0, 0.0, 0.0]])
    sigma = lam * np.trace(e) * np.eye(3) + 2 * mu * e
    full = p.stress_3d()
    np.testing.assert_allclose(full, np.broadcast_to(sigma, full.shape), rtol=0, atol=1e-12)
    n = p.disc.num_owned_cells
    np.testing.assert_allclose(p.sigma_33.x.array[:n], sigma[2, 2], rtol=0, atol=1e-12)
    want = vm3(sigma[0, 0], sigma[1, 1], sigma[2, 2], sigma[0, 1])
    np.testing.assert_allclose(p.sigma_vm.x.array[:n], want, rtol=1e-13)


def test_plane_strain_patch_nu_per_cell(tmp_path):
    """nu(x) an expression (one nu per cell, at its midpoint): sigma_33 = nu_cell (s11 +
    s22) in every cell, nu_cell evaluated here from the cells' vertices."""
    p = _patch(tmp_path, {"E": 1000.0, "nu": "0.1 + 0.3*x", "plane": "strain"})
    n = p.disc.num_owned_cells
    geo = p.disc.mesh.geometry
    dofs = geo.dofmap.links if hasattr(geo.dofmap, "links") else None
    mid = np.array([geo.x[dofs(c)].mean(axis=0) for c in range(n)])
    rows = p.disc.Y.dofmap.list.array[:n]
    nu = 0.1 + 0.3 * mid[:, 0]
    s = p.sigma.x.array.reshape(-1, 2, 2)[rows]
    np.testing.assert_allclose(p.sigma_33.x.array[rows], nu * (s[:, 0, 0] + s[:, 1, 1]),
                               rtol=1e-13, atol=1e-13)


def test_plane_stress_keeps_sigma_33_zero(tmp_path):
    """Plane stress: sigma_33 = 0 by definition; stress_3d has it 0, the norm is the 2D
    one."""
    p = _patch(tmp_path, {"E": 1000.0, "nu": 0.3})
    assert p.sigma_33 is None
    full = p.stress_3d()
    assert np.all(full[:, 2, :] == 0.0)
    n = p.disc.num_owned_cells
    s = full[0]
    assert p.sigma_vm.x.array[0] == pytest.approx(vm3(s[0, 0], s[1, 1], 0.0, s[0, 1]),
                                                  rel=1e-13)
    assert n > 0


def test_orthotropic_plane_strain_patch(tmp_path):
    """Orthotropic 3D data in plane strain (axes at 30 degrees), a uniform strain: the 3D
    stress of eps (eps_33 = 0), computed here by rotating eps into the material axes,
    applying C3 = S^-1 of the engineering constants written out and rotating back, is
    problem.stress_3d() in every cell, sigma_33 included."""
    E, nu, G = [1000.0, 400.0, 250.0], [0.25, 0.3, 0.35], [150.0, 120.0, 90.0]
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    p = _patch(tmp_path, {"plane": "strain", "elasticity": {"orthotropic": {
        "E": E, "nu": nu, "G": G, "axes": [[float(c), float(s)]]}}})
    S = np.zeros((6, 6))
    S[:3, :3] = [[1 / E[0], -nu[0] / E[0], -nu[1] / E[0]],
                 [-nu[0] / E[0], 1 / E[1], -nu[2] / E[1]],
                 [-nu[1] / E[0], -nu[2] / E[1], 1 / E[2]]]
    S[3:, 3:] = np.diag([1 / G[2], 1 / G[1], 1 / G[0]])
    R = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    e = R @ np.array([[0.001, 0.0005, 0.0], [0.0005, -0.002, 0.0], [0.0, 0.0, 0.0]]) @ R.T
    t = np.linalg.solve(S, [e[0, 0], e[1, 1], e[2, 2], 2 * e[1, 2], 2 * e[0, 2], 2 * e[0, 1]])
    local = np.array([[t[0], t[5], t[4]], [t[5], t[1], t[3]], [t[4], t[3], t[2]]])
    sigma = R.T @ local @ R
    full = p.stress_3d()
    np.testing.assert_allclose(full, np.broadcast_to(sigma, full.shape), rtol=0,
                               atol=1e-12 * np.abs(sigma).max())


def test_voigt_plane_strain_has_no_sigma_33(tmp_path, caplog):
    """A 2D Voigt matrix in plane strain (the in-plane law alone): sigma_33 is NaN, not 0,
    sigma_vm the in-plane norm, and the log says so."""
    D = [[1346.15, 576.92, 0.0], [576.92, 1346.15, 0.0], [0.0, 0.0, 384.62]]
    with caplog.at_level("WARNING", logger="vpcontact"):
        p = _patch(tmp_path, {"plane": "strain", "elasticity": {"voigt": D}})
    assert any("sigma_33 is written NaN" in r.getMessage() for r in caplog.records)
    n = p.disc.num_owned_cells
    assert np.isnan(p.sigma_33.x.array[:n]).all()
    s = p.sigma.x.array.reshape(-1, 2, 2)[0]
    assert p.sigma_vm.x.array[0] == pytest.approx(vm3(s[0, 0], s[1, 1], 0.0, s[0, 1]),
                                                  rel=1e-13)
