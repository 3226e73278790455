"""The condensed step solver solves the same discrete problem as SNES VI."""
import csv
import json

import numpy as np
import pytest
from test_step_kkt import check_complementarity

from conftest import PAPER_CASE, ROOT, paper_raw, run_case, run_cli, validate_raw
from vpcontact.io.errors import CaseError


def _pair(raw):
    raw.setdefault("solver", {})["method"] = "snes_vi"
    a = run_case(validate_raw(raw))
    raw["solver"]["method"] = "condensed"
    b = run_case(validate_raw(raw))
    assert b.summary["solver"]["used"] == "condensed" and a.summary["solver"]["used"] == "snes_vi"
    return a, b


def _diff(a, b):
    ua, ub = a.problem.u.x.array, b.problem.u.x.array
    du = np.abs(ua - ub).max() / np.abs(ua).max()
    dn = max(abs(x[k] - y[k]) / abs(x[k]) for x, y in zip(a.summary["steps"], b.summary["steps"])
             for k in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y") if x[k])
    return du, dn


def test_condensed_equals_snes_vi_on_the_paper_case():
    """Both solve the same regularised discrete problem (delta = 1e-7): they agree to the
    solver tolerances (measured 1.6e-13), far inside the regularisation's consistency error
    (3e-11, tests/system/test_regularisation.py)."""
    a, b = _pair(paper_raw())
    du, dn = _diff(a, b)
    assert du < 1e-9 and dn < 1e-10
    counts = check_complementarity(b)
    assert counts["bound"] > 0 and counts["compliance"] > 0
    assert b.summary["solver"]["factorisations"] == 1


def test_condensed_equals_snes_vi_with_memory_and_slip():
    from vpcontact.case import load_raw
    raw = load_raw(ROOT / "cases" / "memory.yaml")
    raw["contact"]["friction"]["slip"] = {"theta_inf": 0.3, "s0": 0.002}
    raw["mesh"]["n"] = 8
    raw["time"]["N"] = 8
    du, dn = _diff(*_pair(raw))
    assert du < 1e-9 and dn < 1e-10


def test_condensed_equals_snes_vi_in_3d():
    from vpcontact.case import load_raw
    raw = load_raw(ROOT / "cases" / "box3d.yaml")
    raw["mesh"]["n"] = 4
    raw["time"]["N"] = 2
    du, dn = _diff(*_pair(raw))
    assert du < 1e-9 and dn < 1e-10


def _box3d_n12() -> dict:
    from vpcontact.case import load_raw
    raw = load_raw(ROOT / "cases" / "box3d.yaml")
    raw["mesh"]["n"] = 12
    return raw


@pytest.fixture(scope="module")
def box3d_n12_snes_vi():
    """box3d at n = 12 with SNES VI, run once: the reference of both condensed paths (the
    kept factor is the condensed solver's; SNES VI does not use it)."""
    raw = _box3d_n12()
    raw.setdefault("solver", {})["method"] = "snes_vi"
    return run_case(validate_raw(raw))


@pytest.mark.slow
@pytest.mark.parametrize("kept_factor", [False, True])
def test_box3d_n12_iterations_bounded_and_solvers_agree(monkeypatch, kept_factor,
                                                        box3d_n12_snes_vi):
    """box3d at n = 12 (8 steps): every step of both solvers within 20 iterations (the
    Gamma3 problem's line search once stalled for 160-200 iterations at the energy's round-off
    in 3D), and the two agree to 1e-8; also with the Gamma3 Newton systems solved by CG with
    a kept factor (the large-m path, here forced at m = 468)."""
    from vpcontact.solvers import dense
    if kept_factor:
        monkeypatch.setattr(dense, "PCG_MIN", 0)
    raw = _box3d_n12()
    raw.setdefault("solver", {})["method"] = "condensed"
    a, b = box3d_n12_snes_vi, run_case(validate_raw(raw))
    assert b.summary["solver"]["used"] == "condensed" and a.summary["solver"]["used"] == "snes_vi"
    for run in (a, b):
        its = [st["newton_iterations"] for st in run.summary["steps"]]
        assert len(its) == 8 and max(its) <= 20, its
    g3 = b.summary["solver"]["gamma3"]
    assert g3["dofs"] == 468
    assert (g3["cg_iterations"] > 0) == kept_factor
    assert g3["factorisations"] < (20 if kept_factor else 100)
    du, dn = _diff(a, b)
    assert du < 1e-8 and dn < 1e-8


def test_fast_refuses_the_implicit_scheme():
    """Refused at validation, before any computation."""
    raw = dict(paper_raw())
    raw["solver"]["method"] = "fast"
    raw["time"]["scheme"] = "implicit"
    raw["time"]["N"] = 1
    with pytest.raises(CaseError, match=r"solver\.method: 'fast' is not possible"):
        validate_raw(raw)
    raw["solver"]["method"] = "auto"
    assert run_case(validate_raw(raw)).summary["solver"]["used"] == "snes_vi"


@pytest.mark.mpi
def test_condensed_serial_equals_two_ranks(tmp_path):
    """Under mpirun (MUMPS with Schur variables) as serially; ``fast``, the former name, is
    still accepted in a case."""
    out = {}
    for n in (1, 2):
        d = tmp_path / f"np{n}"
        proc = run_cli(["run", PAPER_CASE, "--out", d, "--quiet", "--set", "solver.method=fast"],
                       nprocs=n)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        out[n] = (json.loads((d / "summary.json").read_text()),
                  list(csv.DictReader(open(d / "contact.csv"))))
    (s1, c1), (s2, c2) = out[1], out[2]
    assert s1["solver"]["used"] == s2["solver"]["used"] == "condensed"
    for a, b in zip(s1["steps"], s2["steps"], strict=True):
        for key in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa"):
            assert b[key] == pytest.approx(a[key], rel=1e-10), key
    for col in ("u_x", "u_y", "neg_sigma_nu", "neg_sigma_tau"):
        v1 = np.array([float(r[col]) for r in c1])
        v2 = np.array([float(r[col]) for r in c2])
        np.testing.assert_allclose(v2, v1, rtol=1e-10, atol=1e-12 * np.abs(v1).max())


def test_compiled_split_equals_petsc_path():
    """Serial condensed solver: the compiled one-solve path (CholmodCondensation: one
    factorisation) and the general path (PetscCondensation: PETSc LU + S from a G-last
    factorisation, two factorisations, chosen when PETSc options fast_* are given) give the
    same solution."""
    raw = paper_raw()
    raw.setdefault("solver", {})["method"] = "condensed"
    a = run_case(validate_raw(raw))
    raw["petsc"] = {"fast_pc_factor_mat_solver_type": "petsc"}
    b = run_case(validate_raw(raw))
    assert a.summary["solver"]["factorisations"] == 1
    assert b.summary["solver"]["factorisations"] == 2
    du, dn = _diff(a, b)
    assert du < 1e-11 and dn < 1e-11
