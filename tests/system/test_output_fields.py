"""The fields engineers post-process in solution.xdmf: the material id, the
strain eps(u), the viscoplastic strain eps_vp, the nodal averaged stress sigma_nodal, and
internal variables only where a law has them (NaN elsewhere); serial equals 2 ranks."""
from __future__ import annotations

import h5py
import numpy as np
import pytest
import yaml

from conftest import ROOT, run_cli

PUNCH = ROOT / "cases" / "bimaterial_punch.yaml"
HERTZ = ROOT / "cases" / "hertz_cylinder.yaml"


def _fields(outdir):
    """{name: dataset at the last time}, the cell midpoints and the node coordinates."""
    with h5py.File(outdir / "solution.h5", "r") as f:
        x = f["Mesh/mesh/geometry"][:]
        cells = f["Mesh/mesh/topology"][:]
        out = {}
        for name, g in f["Function"].items():
            key = sorted(g, key=lambda k: float(k.replace("_", ".")))[-1]
            out[name] = g[key][:]
    return out, x[cells].mean(axis=1), x


def _by_position(values, points):
    """The rows sorted by their points' coordinates (a partition-free order)."""
    order = np.lexsort(np.round(points, 12).T[::-1])
    return values[order]


@pytest.fixture(scope="module")
def punch(tmp_path_factory):
    """bimaterial_punch (Perzyna foot, elastic cap, plane strain), 6 steps, on 1 and 2
    ranks."""
    base = tmp_path_factory.mktemp("punch")
    raw = yaml.safe_load(PUNCH.read_text())
    raw["mesh"]["file"] = str(ROOT / "cases" / "bimaterial_punch.geo")
    raw["time"] = {"T": 0.6, "N": 6}
    case = base / "punch.yaml"
    case.write_text(yaml.safe_dump(raw))
    runs = {}
    for n in (1, 2):
        r = run_cli(["run", case, "--out", base / f"n{n}"], nprocs=n)
        assert r.returncode == 0, r.stderr
        runs[n] = _fields(base / f"n{n}")
    return runs


def test_material_id_and_fields_only_where_a_law_is(punch):
    """material is the physical tag (foot 10, cap 11); kappa and eps_vp are NaN exactly on
    the elastic cap's cells and finite on the foot's, where kappa grew."""
    f, mid, _ = punch[1]
    mat = f["material"][:, 0]
    assert set(np.unique(mat)) == {10.0, 11.0}
    cap = mat == 11.0
    assert np.all(mid[~cap, 1] < 0.25 + 1e-12) and np.all(mid[cap, 1] > 0.25 - 1e-12)
    for name, comps in (("kappa", [0]), ("eps_vp", [0, 1, 3, 4, 8])):   # dolfinx: 13, 23 0
        assert np.isnan(f[name][cap][:, comps]).all(), name
        assert np.isfinite(f[name][~cap]).all(), name
    assert f["kappa"][~cap].max() > 1.0
    # eps = eps(u): in-plane, eps_33 = 0 in plane strain; the foot's eps_vp is the
    # strain the elastic law does not carry: eps - E^-1 (sigma) with E of the foot
    E, nu = 1000.0, 0.3
    s, e, vp = f["sigma"][~cap], f["eps"][~cap], f["eps_vp"][~cap]
    tr = s[:, 0] + s[:, 4] + s[:, 8]
    elastic = ((1 + nu) * s - nu * tr[:, None] * np.eye(3).reshape(1, 9)) / E
    np.testing.assert_allclose(vp, e - elastic, rtol=0, atol=1e-10 * np.abs(e).max())
    assert np.all(e[:, [2, 5, 6, 7, 8]] == 0.0)


def test_serial_equals_two_ranks(punch):
    """Every field of the last time, serial and on 2 ranks, matched by position."""
    (a, mid_a, x_a), (b, mid_b, x_b) = punch[1], punch[2]
    assert set(a) == set(b) >= {"material", "eps", "eps_vp", "sigma_nodal", "sigma", "kappa"}
    for name in a:
        pts = (x_a, x_b) if len(a[name]) == len(x_a) and name in ("u", "sigma_nodal") \
            else (mid_a, mid_b)
        va, vb = _by_position(a[name], pts[0]), _by_position(b[name], pts[1])
        scale = np.nanmax(np.abs(va)) or 1.0
        np.testing.assert_allclose(vb, va, rtol=0, atol=1e-8 * scale, equal_nan=True,
                                   err_msg=name)


def test_elastic_scene_writes_what_it_has(tmp_path):
    """hertz_cylinder (one body, elastic): no eps_vp, no kappa, no material id; eps and
    sigma_nodal and eta written."""
    out = tmp_path / "hertz"
    r = run_cli(["run", HERTZ, "--out", out])
    assert r.returncode == 0, r.stderr
    f, _, _ = _fields(out)
    assert set(f) == {"u", "sigma", "sigma_vm", "eps", "sigma_nodal", "eta"}


@pytest.mark.parametrize("plane", ["strain", "stress"])
def test_nodal_stress_patch(tmp_path, plane):
    """A uniform strain prescribed on the whole boundary: sigma_nodal is the uniform
    stress at every node (plane strain: the 3D lambda tr(eps) I + 2 mu eps, sigma_33 =
    lambda tr(eps); plane stress: E/(1 - nu^2) ((1 - nu) eps + nu tr(eps) I), sigma_33 =
    0) and eps the prescribed strain in every cell."""
    ux, uy = "t*(0.001*x + 0.0005*y)", "t*(0.0005*x - 0.002*y)"
    raw = {"mesh": {"n": 4, "diagonal": "left"},
           "material": {"E": 1000.0, "nu": 0.3, "plane": plane},
           "boundaries": {"clamped": [], "contact": []},
           "loads": {"displacement": {s: [ux, uy] for s in ("left", "right", "bottom", "top")}},
           "time": {"T": 1.0, "N": 1}}
    case = tmp_path / "patch.yaml"
    case.write_text(yaml.safe_dump(raw))
    r = run_cli(["run", case, "--out", tmp_path / "out"])
    assert r.returncode == 0, r.stderr
    f, _, _ = _fields(tmp_path / "out")
    E, nu = 1000.0, 0.3
    e = np.array([[0.001, 0.0005, 0.0], [0.0005, -0.002, 0.0], [0.0, 0.0, 0.0]])
    if plane == "strain":
        lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
        sigma = lam * np.trace(e) * np.eye(3) + 2 * mu * e
    else:
        sigma = E / (1 - nu ** 2) * ((1 - nu) * e + nu * np.trace(e) * np.diag([1, 1, 0]))
    nodal = f["sigma_nodal"]
    np.testing.assert_allclose(nodal, np.broadcast_to(sigma.reshape(9), nodal.shape),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(f["eps"], np.broadcast_to(e.reshape(9), f["eps"].shape),
                               rtol=0, atol=1e-15)
