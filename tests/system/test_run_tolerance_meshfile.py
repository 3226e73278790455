"""run --tol on a gmsh mesh (cases/hertz_cylinder.yaml, meshes/retag.py): the passes refine
the file's mesh with its boundary groups carried over.  Checked against the geometry (the
quarter disc of radius 1 centred at (0, 1); new vertices on the chords of the arc), the
boundary data (u_x = 0 on x = 0, u_y = -0.015 on the top) at every vertex of the refined
mesh, the equilibrium of the contact force and the reactions, and mpirun -n 2 = serial."""
import csv
import json

import h5py
import numpy as np
import pytest

from conftest import ROOT, run_cli

HERTZ = ROOT / "cases" / "hertz_cylinder.yaml"
COARSE = ["--set", "mesh.size=8", "--quiet"]       # 83 cells; 3 passes to tol 0.15


def _run(out, tol, nprocs=1):
    proc = run_cli(["run", HERTZ, "--out", out, "--tol", tol, *COARSE], nprocs=nprocs)
    assert proc.returncode == 0, proc.stderr
    with open(out / "passes.csv") as f:
        return list(csv.DictReader(f))


def _contact_nodes(path):
    with open(path) as f:
        return np.array([[float(r["x"]), float(r["y"])] for r in csv.DictReader(f)])


def _on_chords(points, corners):
    """Whether each point lies on the polygon through the corners (sorted along the arc)."""
    a, b = corners[:-1], corners[1:]
    d = b - a
    t = np.clip(np.einsum("pij,ij->pi", points[:, None] - a, d) / np.einsum("ij,ij->i", d, d),
                0, 1)
    dist = np.linalg.norm(points[:, None] - (a + t[..., None] * d), axis=2)
    return dist.min(axis=1) < 1e-9


def test_hertz_passes_keep_the_groups(tmp_path):
    """Three passes, the estimate falling; the contact group of the final mesh holds every
    Gamma3 node of pass 1 (on the circle) and more, all on the chords of pass 1's arc; every
    vertex on x = 0 has u_x = 0 and every vertex of the top u_y = -0.015; the contact force
    balances the reactions."""
    out = tmp_path / "tol"
    rows = _run(out, 0.15)
    est = [float(r["est_max"]) for r in rows]
    assert len(rows) == 3 and all(b < a for a, b in zip(est, est[1:]))
    assert json.loads((out / "passes.json").read_text())["met"]
    first, last = _contact_nodes(out / "pass_1" / "contact.csv"), _contact_nodes(
        out / "contact.csv")
    assert np.allclose(np.hypot(first[:, 0], first[:, 1] - 1.0), 1.0, atol=1e-9)
    assert len(last) > len(first) + 3
    assert {tuple(p) for p in np.round(first, 12)} <= {tuple(p) for p in np.round(last, 12)}
    corners = first[np.argsort(np.arctan2(first[:, 0], 1.0 - first[:, 1]))]
    assert _on_chords(last, corners).all()
    with h5py.File(out / "solution.h5") as f:
        x = f["Mesh"]["mesh"]["geometry"][:]
        u = f["Function"]["u"][sorted(f["Function"]["u"])[-1]][:]
    assert len(x) > 2 * 60
    sym, top = np.abs(x[:, 0]) < 1e-12, np.abs(x[:, 1] - x[:, 1].max()) < 1e-12
    assert sym.sum() > 3 and top.sum() > 1
    assert np.allclose(u[sym, 0], 0.0, atol=1e-14)
    assert np.allclose(u[top, 1], -0.015, rtol=1e-12)
    with open(out / "history.csv") as f:
        h = list(csv.DictReader(f))[-1]
    total = sum(float(h[k]) for k in ("contact_force_y", "reaction_sym_y", "reaction_top_y"))
    assert abs(total) < 1e-8 * float(h["contact_force_y"]) and float(h["contact_force_y"]) > 0


@pytest.mark.mpi
def test_hertz_mpirun_equals_serial(tmp_path):
    """mpirun -n 2: the same passes (cells, estimates to 1e-10) as the serial run."""
    runs = {n: _run(tmp_path / f"np{n}", 0.2, nprocs=n) for n in (1, 2)}
    assert len(runs[1]) == len(runs[2]) == 2
    for a, b in zip(runs[1], runs[2]):
        assert (a["cells"], a["dofs"], a["next"]) == (b["cells"], b["dofs"], b["next"])
        assert float(b["est_max"]) == pytest.approx(float(a["est_max"]), rel=1e-10)


@pytest.mark.mpi
def test_bimaterial_keeps_its_materials_on_two_ranks(tmp_path):
    """cases/bimaterial_punch.yaml (foot y < 0.25, cap above) refined under mpirun -n 2 and
    serially: the same passes, and the final mesh's material field (the cells' physical tag)
    is the foot's (10) exactly at the cells whose centroid is below y = 0.25."""
    rows = {}
    for n in (1, 2):
        out = tmp_path / f"np{n}"
        proc = run_cli(["run", ROOT / "cases" / "bimaterial_punch.yaml", "--out", out, "--tol",
                        "0.2", "--set", "mesh.size=4", "--set", "time.N=2", "--set",
                        "time.T=0.2", "--quiet"], nprocs=n)
        assert proc.returncode == 0, proc.stderr
        with open(out / "passes.csv") as f:
            rows[n] = list(csv.DictReader(f))
        with h5py.File(out / "solution.h5") as f:
            x, cells = f["Mesh"]["mesh"]["geometry"][:], f["Mesh"]["mesh"]["topology"][:]
            group = f["Function"]["material"]
            material = group[sorted(group)[-1]][:, 0]
        assert len(cells) == int(rows[n][-1]["cells"]) > int(rows[n][0]["cells"])
        below = x[cells].mean(axis=1)[:, 1] < 0.25
        assert below.any() and (~below).any()
        assert np.array_equal(material == 10, below) and set(material) == {10.0, 11.0}
    assert [(r["cells"], r["steps"]) for r in rows[1]] == [(r["cells"], r["steps"])
                                                         for r in rows[2]]
    for a, b in zip(rows[1], rows[2]):
        assert float(b["est_max"]) == pytest.approx(float(a["est_max"]), rel=1e-10)
