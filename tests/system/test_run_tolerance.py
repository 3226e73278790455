"""run --tol (app/studies/tolerance.py, meshes/adapt.py): passes from t = 0 until est_max <=
tol * scale.  Checked against the outputs, recomputed independently: the stop rule, the
estimate falling from pass to pass, passes.csv = passes.json = each pass's summary.json,
the scale from history.csv, the refined mesh's Gamma3 (the re-tagged bottom side) against
its vertices at y = 0, Doerfler's marking against a brute-force minimal set, the refusals,
and mpirun -n 2 = serial."""
import csv
import json

import h5py
import numpy as np
import pytest

from conftest import PAPER_CASE, run_cli

SMALL = ["--set", "mesh.n=4", "--set", "time.N=8", "--quiet"]


def _passes(out):
    with open(out / "passes.csv") as f:
        rows = list(csv.DictReader(f))
    return rows, json.loads((out / "passes.json").read_text())


def _times(where):
    with open(where / "history.csv") as f:
        return np.array([float(r["t"]) for r in csv.DictReader(f)])


def _tol_run(out, tol, *extra, nprocs=1):
    return run_cli(["run", PAPER_CASE, "--out", out, "--tol", tol, *SMALL, *extra],
                   nprocs=nprocs)


def test_doerfler_marks_the_smallest_set_holding_theta():
    """The threshold marks the cells of a minimal set (largest first) whose sum reaches
    theta of the total, ties included."""
    from vpcontact.studies.tolerance import doerfler
    rng = np.random.default_rng(0)
    for theta in (0.1, 0.5, 0.9):
        eta2 = rng.random(200) ** 4
        marked = eta2 >= doerfler(eta2, theta)
        desc = np.sort(eta2)[::-1]
        need = next(i + 1 for i in range(len(desc)) if desc[:i + 1].sum() >= theta * eta2.sum())
        assert marked.sum() == need
    assert (np.ones(10) >= doerfler(np.ones(10), 0.5)).all()      # ties: all or none


def test_passes_reach_the_tolerance(tmp_path):
    """h = 1/4, k = 1/8, tol 0.3: several passes, est_max falls at every pass, only the last is
    within the tolerance; its outputs are DIR's and agree with passes.csv."""
    out, tol = tmp_path / "tol", 0.3
    proc = _tol_run(out, tol)
    assert proc.returncode == 0, proc.stderr
    rows, js = _passes(out)
    assert 3 <= len(rows) <= 5 and js["met"] and js["tol"] == tol
    est = [float(r["est_max"]) for r in rows]
    rel = [float(r["relative"]) for r in rows]
    assert all(b < a for a, b in zip(est, est[1:]))
    assert rel[-1] <= tol and all(r > tol for r in rel[:-1])
    assert [r["next"] for r in rows][-1] == "stop"
    for a, b in zip(rows, rows[1:]):              # each pass refined what it said
        assert (int(b["cells"]) > int(a["cells"])) == ("h" in a["next"])
        assert (int(b["steps"]) > int(a["steps"])) == ("k" in a["next"])
        if "k" in a["next"]:                      # the time part fell by at least 2
            assert float(b["est_time"]) <= 0.5 * float(a["est_time"])
    assert "k" in rows[0]["next"]
    grids = [_times(out / f"pass_{i}") for i in range(1, len(rows))] + [_times(out)]
    for a, b in zip(grids, grids[1:]):  # nested; the load's first step split most
        assert set(np.round(a, 12)) <= set(np.round(b, 12))
        k = np.diff(np.concatenate([[0.0], b]))
        assert k[0] == pytest.approx(k.min(), rel=1e-12)
        assert np.allclose(np.log2(np.diff(np.concatenate([[0.0], a]))[0] / k[0]) % 1, 0)
    for i, r in enumerate(rows[:-1], 1):          # the passes' own summaries
        s = json.loads((out / f"pass_{i}" / "summary.json").read_text())
        assert s["error_estimate"]["estimate"] == pytest.approx(float(r["est_max"]), rel=1e-14)
        assert s["mesh"]["cells"] == int(r["cells"])
    # the final pass's outputs in DIR: the scale and the estimate from history.csv
    with open(out / "history.csv") as f:
        hist = list(csv.DictReader(f))
    scale = max(float(h["norm_sigma_Q"]) + float(h["norm_u_V"]) + float(h["norm_kappa_Y"])
                for h in hist)
    assert len(hist) == int(rows[-1]["steps"])
    assert float(hist[-1]["est_max"]) / scale == pytest.approx(rel[-1], rel=1e-12)
    s = json.loads((out / "summary.json").read_text())
    assert s["mesh"]["cells"] == int(rows[-1]["cells"]) > 32


def test_refined_mesh_keeps_the_contact_side(tmp_path):
    """The refined mesh's Gamma3 (re-tagged bottom side) has every vertex at y = 0 but the
    clamped corner, and only those: contact.csv's nodes at T against solution.h5's
    geometry."""
    out = tmp_path / "tol"
    proc = _tol_run(out, 0.3)
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out / "solution.h5") as f:
        x = f["Mesh"]["mesh"]["geometry"][:]
    bottom = np.isclose(x[:, 1], 0.0, atol=1e-12) & (x[:, 0] > 1e-12)   # (0, 0) is clamped
    with open(out / "contact.csv") as f:             # the Gamma3 nodes at T
        xs = sorted(float(r["x"]) for r in csv.DictReader(f))
    assert np.allclose(xs, np.sort(x[bottom, 0]), atol=1e-12)
    assert len(xs) > 5                                # more than the 1/4 mesh's


def test_tolerance_not_reached_and_refusals(tmp_path):
    """--max-passes 2 too few: the warning and exit 1 with the outputs of pass 2; a
    --restart refused with exit 2 before any computation (a mesh.file case is refined:
    test_run_tolerance_meshfile.py)."""
    proc = _tol_run(tmp_path / "few", 0.3, "--max-passes", "2")
    assert proc.returncode == 1
    assert "not reached after 2 passes" in proc.stdout + proc.stderr
    rows, js = _passes(tmp_path / "few")
    assert len(rows) == 2 and not js["met"]
    proc = _tol_run(tmp_path / "r", 0.3, "--restart", tmp_path / "few")
    assert proc.returncode == 2 and "--tol" in proc.stderr


@pytest.mark.mpi
def test_mpirun_equals_serial(tmp_path):
    """mpirun -n 2: the same passes (cells, steps, estimates to 1e-10) as the serial run."""
    runs = {}
    for nprocs in (1, 2):
        out = tmp_path / f"np{nprocs}"
        proc = _tol_run(out, 0.5, nprocs=nprocs)
        assert proc.returncode == 0, proc.stderr
        runs[nprocs] = _passes(out)[0]
    assert len(runs[1]) == len(runs[2]) >= 2
    for a, b in zip(runs[1], runs[2]):
        assert (a["cells"], a["steps"], a["next"]) == (b["cells"], b["steps"], b["next"])
        assert float(b["est_max"]) == pytest.approx(float(a["est_max"]), rel=1e-10)


def test_overwrite_replaces_the_passes(tmp_path):
    """A directory of a run --tol is one of vpcontact's: refused without --overwrite,
    and with it the earlier passes (pass_<i>, passes.csv) are replaced, none left over."""
    out = tmp_path / "tol"
    assert _tol_run(out, 0.3).returncode == 0
    before = sorted(p.name for p in out.glob("pass_*"))
    assert _tol_run(out, 0.5).returncode == 2
    proc = _tol_run(out, 0.5, "--overwrite")
    assert proc.returncode == 0, proc.stderr
    rows, _ = _passes(out)
    after = sorted(p.name for p in out.glob("pass_*"))
    assert len(after) == len(rows) - 1 < len(before)
