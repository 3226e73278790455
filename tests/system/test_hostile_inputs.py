"""Hostile inputs through the command line: `check` refuses them with exit code 2 and one
line before anything is built; a body of any size gives the scaled answer; contact.csv's
node states do not depend on the size of g or c_nu."""
import csv
import os

import numpy as np
import pytest

from conftest import PAPER_CASE, make_case, paper_raw, run_case, run_cli

SMALL = ["--set", "mesh.n=4", "--set", "time.N=2"]


def _one_line_exit_2(proc, pattern: str):
    assert proc.returncode == 2, (proc.returncode, proc.stdout[-1500:], proc.stderr[-1500:])
    assert "Traceback" not in proc.stdout + proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("vpcontact: error: "), proc.stderr
    assert pattern in lines[0], lines[0]


@pytest.mark.parametrize("setting,pattern", [
    ("name=..", "name: '..' cannot name an output directory (allowed: letters"),
    ('loads.traction.top=[0,"sqrt(-1)"]', "loads.traction.top[1]"),
    ('material.viscoplastic.kappa0="sqrt(x-0.5)"', "nan is not a finite number at x = 0"),
    ('loads.f0=[0,"1e308*10"]', "inf is not a finite number"),
    ('initial.u0=[0,"-x"]', "initial.u0: violates u_nu <= g on Gamma3"),
    ('material.viscoplastic.kappa0="-100"', "must be >= 0 everywhere"),
    ("time.adaptive={k_min: 1, k_max: 1e-6}", "1 is larger than time.adaptive.k_max"),
    ("material.E=[1", "line 1, column 3"),
    ("petsc={ksp_type: nonexistent}", "petsc.ksp_type: 'nonexistent' is not a KSP type"),
    ("mesh.L2=1e-9", "1e-09 m is too thin"),
    ('loads.f0=["z*1e200",0]', "unknown name 'z' (allowed: t, x, y, e, pi)"),
])
def test_check_refuses_bad_data_in_one_line(setting, pattern):
    _one_line_exit_2(run_cli(["check", PAPER_CASE, *SMALL, "--set", setting]), pattern)


@pytest.mark.parametrize("path", ["/dev/zero", "DIR", "FIFO"])
def test_check_refuses_files_that_are_not_regular(path, tmp_path):
    if path == "FIFO":
        path = tmp_path / "fifo"
        os.mkfifo(path)
    elif path == "DIR":
        path = tmp_path
    _one_line_exit_2(run_cli(["check", path], timeout=120), "not a regular file")


def test_a_name_that_is_a_path_writes_nothing(tmp_path):
    before = sorted(os.listdir(tmp_path))
    proc = run_cli(["run", PAPER_CASE, *SMALL, "--set", "name=..",
                    "--set", "loads.traction.top=[0,-1]"], cwd=tmp_path)
    _one_line_exit_2(proc, "name: '..'")
    assert sorted(os.listdir(tmp_path)) == before


def _read_states(path):
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return [r["state"] for r in rows], np.array([float(r["u_nu"]) for r in rows])


@pytest.mark.parametrize("setting", ["contact.g=1e8", "contact.normal_compliance.c_nu=1e20"])
def test_penetrating_nodes_are_in_compliance_whatever_g_and_c_nu(setting, tmp_path):
    """Every Gamma3 node penetrates (u_nu > 0) under the paper's loads, with a bound far
    away (g = 1e8) or a stiff compliance (penetration 1e-20 m)."""
    proc = run_cli(["run", PAPER_CASE, *SMALL, "--set", setting, "--out", tmp_path / "r"])
    assert proc.returncode == 0, proc.stderr[-2000:]
    states, u_nu = _read_states(tmp_path / "r" / "contact.csv")
    assert len(states) == 4 and (u_nu > 0).all()
    assert states == ["compliance"] * 4


def _scaled_case(s: float, method: str):
    """The paper case on (0, s)^2 with lengths [m] scaled by s: the same stresses, u s."""
    return make_case(paper_raw(), mesh={"L1": s, "L2": s, "n": 4}, time={"N": 2},
                     contact={"g": 0.012 * s, "normal_compliance": {"c_nu": 100.0 / s},
                              "friction": {"b": 1.0, "c1": 60.0 / s, "c2": 60.0 / s,
                                           "u1": 0.01 * s}},
                     solver={"method": method, "delta": 1e-7 * s})


@pytest.mark.parametrize("method", ["snes_vi", "fast"])
def test_a_tiny_body_gives_the_scaled_answer(method):
    unit = run_case(_scaled_case(1.0, method))
    tiny = run_case(_scaled_case(1e-9, method))
    assert tiny.status == "completed" and len(tiny.problem.disc.gamma3.nodes) == 4
    u1, u_tiny = unit.problem.u.x.array, tiny.problem.u.x.array / 1e-9
    assert np.abs(u1).max() > 1e-3
    assert np.abs(u_tiny - u1).max() <= 1e-12 * np.abs(u1).max()


def test_a_tiny_body_run_from_the_command_line_finds_gamma3(tmp_path):
    proc = run_cli(["run", PAPER_CASE, *SMALL, "--set", "mesh.L1=1e-9", "--set", "mesh.L2=1e-9",
                    "--out", tmp_path / "r"])
    assert proc.returncode == 0, proc.stderr[-2000:]
    states, u_nu = _read_states(tmp_path / "r" / "contact.csv")
    assert len(states) == 4 and np.abs(u_nu).max() > 0


def test_petsc_options_that_write_files_or_load_code_are_refused_before_anything(tmp_path):
    """A case file's petsc section (and --set petsc.*, and the command line) cannot make
    PETSc write a file outside --out or petsc4py import code: exit 2, one line, no file."""
    outside = tmp_path / "outside.txt"
    case = tmp_path / "case.yaml"
    case.write_text(open(PAPER_CASE).read() + f"petsc:\n  ksp_monitor: ascii:{outside}\n")
    for args, pattern in [
            (["check", case], f"case.yaml: petsc.ksp_monitor (line 43): 'ascii:{outside}' "
                              "would write to a file or a window"),
            (["run", case, "--out", tmp_path / "out", *SMALL],
             "petsc.ksp_monitor (line 43): 'ascii:"),
            (["check", PAPER_CASE, "--set", f"petsc.snes_view=binary:{outside}"],
             "(the value of --set petsc.snes_view=binary:/"),
            (["run", PAPER_CASE, "--out", tmp_path / "out", *SMALL, "-snes_monitor",
              f"ascii:{outside}"],
             "command line: -snes_monitor: 'ascii:"),
            (["check", PAPER_CASE, "--set", "petsc={pc_type: python, pc_python_type: os.X}"],
             "petsc.pc_type: a python type makes petsc4py import and run Python code")]:
        _one_line_exit_2(run_cli(args), pattern)
        assert not outside.exists() and not (tmp_path / "out").exists()
