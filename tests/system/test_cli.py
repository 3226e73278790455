"""The command line: the demo case writes its outputs; bad input exits 2 before any work;
earlier results are not overwritten; PETSc options reach the solver; failures exit 1."""
import csv
import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from conftest import PAPER_CASE, ROOT, run_cli

STEP_KEYS = {"t", "norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa",
             "newton_iterations", "wall_s"}


@pytest.fixture(scope="module")
def demo_out(paper_cli_run):
    """The paper case's results directory (conftest.paper_cli_run), read only."""
    return paper_cli_run[0]


def test_verbose_prints_each_step_and_the_petsc_monitor(tmp_path):
    """--verbose: a line per step with its Newton iterations, and PETSc's monitor (h = 1/4,
    the paper's 16 steps)."""
    proc = run_cli(["run", PAPER_CASE, "--out", tmp_path / "o", "--set", "mesh.n=4",
                    "--verbose"])
    assert proc.returncode == 0, proc.stderr
    assert "step  16/16" in proc.stdout and "newton" in proc.stdout    # per-step lines
    assert "SNES Function norm" in proc.stdout                       # PETSc monitor


def test_demo_writes_the_three_outputs(demo_out):
    assert (demo_out / "solution.xdmf").is_file() and (demo_out / "solution.h5").is_file()
    root = ET.parse(demo_out / "solution.xdmf").getroot()
    collections = [g for g in root.iter("Grid") if g.get("GridType") == "Collection"]
    assert [g.get("Name") for g in collections] == ["solution"]     # one dataset
    grids = collections[0].findall("Grid")
    times = [float(g.find("Time").get("Value")) for g in grids]
    assert times == pytest.approx([n / 16 for n in range(17)])
    for g in grids:
        assert [a.get("Name") for a in g.findall("Attribute")] == [
            "u", "sigma", "sigma_vm", "kappa", "eps", "eps_vp", "sigma_nodal", "eta"]

    s = json.loads((demo_out / "summary.json").read_text())
    assert s["case"] == "wang_cheng_2021" and s["status"] == "completed"
    assert s["mesh"] == {**s["mesh"], "cells": 512, "vertices": 289, "dofs": 578}
    assert len(s["steps"]) == 16 and all(STEP_KEYS <= set(st) for st in s["steps"])
    assert s["wall_s"] > 0 and s["steps"][-1]["t"] == pytest.approx(1.0)
    kappa = [st["max_kappa"] for st in s["steps"]]
    assert kappa[0] == 0.0 and np.all(np.diff(kappa) > 0)   # kappa grows from kappa0 = 0

    rows = list(csv.DictReader(open(demo_out / "contact.csv")))
    assert list(rows[0])[:8] == ["x", "y", "u_x", "u_y", "u_nu", "u_tau", "neg_sigma_nu",
                                 "neg_sigma_tau"]
    x = [float(r["x"]) for r in rows]
    assert len(rows) == 16 and x == sorted(x)
    u_nu = np.array([float(r["u_nu"]) for r in rows])
    np.testing.assert_allclose(u_nu, -np.array([float(r["u_y"]) for r in rows]))


def test_existing_results_are_not_overwritten(demo_out, tmp_path):
    out = tmp_path / "paper"
    shutil.copytree(demo_out, out)          # a copy: the session's run stays as it was
    before = (out / "summary.json").read_text()
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "time.N=1"])
    assert proc.returncode == 2 and "--overwrite" in proc.stderr
    assert (out / "summary.json").read_text() == before


def test_bad_case_exits_2_and_writes_nothing(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(PAPER_CASE.read_text().replace("lambda1:", "lamda1:"))
    out = tmp_path / "out"
    proc = run_cli(["run", bad, "--out", out])
    assert proc.returncode == 2
    assert "bad.yaml" in proc.stderr and "material.viscoplastic.lamda1" in proc.stderr
    assert "did you mean 'lambda1'" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "mesh.diagonal=up"])
    assert proc.returncode == 2 and "mesh.diagonal" in proc.stderr and not out.exists()


def test_petsc_options_reach_the_solver(tmp_path):
    proc = run_cli(["run", PAPER_CASE, "--out", tmp_path / "o", "--set", "time.N=1",
                    "--set", "solver.method=snes_vi", "-snes_monitor", "-snes_rtol", "1e-12"])
    assert proc.returncode == 0, proc.stderr
    assert "SNES Function norm" in proc.stdout


def test_solver_failure_names_the_step(tmp_path):
    out = tmp_path / "o"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "time.N=3",
                    "--set", "solver.method=snes_vi", "-snes_max_it", "1"])
    assert proc.returncode == 1
    assert "step 1" in proc.stderr and "DIVERGED_MAX_IT" in proc.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and s["last_good_step"] == 0
    assert s["failure"]["step"] == 1


def test_console_script_help():
    script = Path(ROOT) / ".venv" / "bin" / "vpcontact"
    if not script.exists():
        pytest.skip("console script is installed by make setup")
    import subprocess
    proc = subprocess.run([script, "run", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and "--set" in proc.stdout and "--overwrite" in proc.stdout


def _outputs_line(stdout: str, out: Path) -> list[str]:
    """The names of the closing ``outputs: <out>/{a, b, ...}`` line."""
    lines = [x for x in stdout.splitlines() if x.startswith("[vpcontact] outputs: ")]
    assert len(lines) == 1, stdout
    listed = lines[0].split("outputs: ", 1)[1]
    assert listed.startswith(f"{out}/{{") and listed.endswith("}"), listed
    return listed[len(f"{out}/{{"):-1].split(", ")


@pytest.mark.parametrize("case, sets, plots", [
    (PAPER_CASE, ["mesh.n=4", "time.N=3", "output.checkpoint_every=1"], True),
    (ROOT / "cases" / "norton_relaxation.yaml", ["time.N=2"], False),
])
def test_outputs_line_names_every_file_written(case, sets, plots, tmp_path):
    """The closing ``outputs:`` line names exactly the files in the output directory
   : contact.xdmf, contact.h5, history.csv, the checkpoints kept (step 1's is
    removed: the newest 2 are kept), the figures; without Gamma3 no contact files."""
    out = tmp_path / "o"
    args = ["run", case, "--out", out, *[a for s in sets for a in ("--set", s)]]
    proc = run_cli(args, plots=plots)
    assert proc.returncode == 0, proc.stderr
    listed = _outputs_line(proc.stdout, out)
    assert len(listed) == len(set(listed))
    assert set(listed) == {p.name for p in out.iterdir()}
    if plots:
        assert {"contact.xdmf", "contact.h5", "history.csv", "checkpoint_000002.npz",
                "checkpoint_000003.npz", "fig2_laws.png"} <= set(listed)
    else:
        assert set(listed) == {"solution.xdmf", "solution.h5", "history.csv", "summary.json"}
