"""SNES VI with the Gamma3 Schur complement PC (solver.linear: schur,
app/solvers/inactiveschur.py) takes the same Newton iterates as SNES VI with LU of every
Newton system (solver.linear: direct), both run here: every Newton iterate, every step's u
and contact table agree to 1e-10 and every step's Newton iterations are equal, on the paper
case and on a Coulomb slide (the linear solves differ by round-off only; the Gamma3 block
B scaled by 1 - 1e-6 moved the paper case's iterates by 2.7e-8, measured, while the
converged steps stay within 1e-10).  Where the PC does not apply, SNES VI keeps LU and says
why.  Under mpirun -n 2 (K factorised on rank 0, right-hand sides gathered there) the
steps equal the serial run's to 1e-10, also where rank 0 owns no Gamma3 node and where the
Gauss rule's B couples neighbouring nodes (LU of (S + B)_{gI,gI}).
"""
import copy
import csv
import json
import logging

import numpy as np
import pytest
from mpi4py import MPI
from test_coulomb import _raw as coulomb_raw

from conftest import PAPER_CASE, make_case, paper_raw, run_cli
from vpcontact.observers import Observer
from vpcontact.post.quantities import contact_table
from vpcontact.simulation import run

TOL = 1e-10


class _Steps(Observer):
    """Every Newton iterate of SNES VI (its monitor), and u, the contact table and the
    Newton iterations after every accepted step."""

    def __init__(self):
        self.u, self.tables, self.iterations, self.iterates = [], [], [], []

    def start(self, sim):
        sim.solver.snes.setMonitor(
            lambda snes, its, fnorm: self.iterates.append(snes.getSolution().array.copy()))

    def end(self, sim, summary):
        schur = getattr(sim.solver, "schur", None)
        self.dense = None if schur is None else \
            (schur.direction.factorisations, schur.direction.cg_iterations)
        pc = sim.solver.snes.getKSP().getPC()
        self.pc = pc.getType(), getattr(pc.getPythonContext(), "setups", None) \
            if pc.getType() == "python" else None

    def step(self, sim, record):
        self.u.append(sim.problem.u.x.array.copy())
        self.tables.append(contact_table(sim.problem))
        self.iterations.append(record["newton_iterations"])


def _run(raw: dict, linear: str, **sections):
    raw = copy.deepcopy(raw)
    raw.setdefault("solver", {}).update(method="snes_vi", linear=linear)
    steps = _Steps()
    result = run(make_case(raw, **sections), MPI.COMM_WORLD, [steps])
    assert result.status == "completed"
    return result, steps


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    scale = np.abs(a).max()
    return float(np.abs(a - b).max() / scale) if scale > 0 else float(np.abs(b).max())


def _same_steps(raw: dict, **sections) -> None:
    """The schur run equals the direct run step by step (and the schur run used the PC:
    one factorisation, not a silent fall back to LU)."""
    direct, a = _run(raw, "direct", **sections)
    schur, b = _run(raw, "schur", **sections)
    assert direct.summary["solver"]["linear"] == "direct"
    assert schur.summary["solver"]["linear"] == "schur"
    assert schur.summary["solver"]["factorisations"] == 1
    assert a.iterations == b.iterations and sum(a.iterations) > len(a.iterations)
    # every Newton system by this PC (vinewtonrsls resets its KSP from the options database
    # when the inactive set changes: a pc_type lu there would have taken over)
    assert b.pc == ("python", sum(b.iterations)) and a.pc[0] == "lu"
    assert len(a.u) == len(b.u) > 1
    assert len(a.iterates) == len(b.iterates) > len(a.u)
    for xa, xb in zip(a.iterates, b.iterates):
        assert _relative(xa, xb) < TOL
    for ua, ub, ta, tb in zip(a.u, b.u, a.tables, b.tables):
        assert _relative(ua, ub) < TOL
        assert ta.keys() == tb.keys()
        for key in ta:
            assert _relative(np.asarray(ta[key], float), np.asarray(tb[key], float)) < TOL, key
    return b


def test_schur_takes_the_lu_iterates_on_the_paper_case():
    steps = _same_steps(paper_raw(), mesh={"n": 16}, time={"N": 16})
    assert steps.dense == (sum(steps.iterations), 0)    # a Cholesky per Newton iteration


def test_schur_with_cg_on_the_kept_factor_takes_the_lu_iterates(monkeypatch):
    """The 3D path (CG preconditioned by the kept Cholesky factor of an earlier Newton
    iteration, from dense.PCG_MIN Gamma3 dofs) on the paper case, with PCG_MIN lowered."""
    from vpcontact.solvers import dense
    monkeypatch.setattr(dense, "PCG_MIN", 0)
    steps = _same_steps(paper_raw(), mesh={"n": 16}, time={"N": 16})
    factorisations, cg_iterations = steps.dense
    assert cg_iterations > 0 and factorisations < sum(steps.iterations)


def test_schur_takes_the_lu_iterates_with_coulomb_friction():
    """Coulomb's slide: the friction makes the Newton matrix unsymmetric."""
    _same_steps(coulomb_raw("slide"), mesh={"n": 8}, time={"N": 4})


def test_schur_refused_with_a_user_linear_solver(caplog):
    """A case's own pc_type keeps LU (its PC), and the log says why."""
    raw = paper_raw()
    raw["petsc"] = {"pc_type": "lu", "pc_factor_mat_solver_type": "petsc"}
    with caplog.at_level(logging.INFO, logger="vpcontact"):
        result, _ = _run(raw, "schur", mesh={"n": 4}, time={"N": 2})
    assert result.summary["solver"]["linear"] == "direct"
    assert result.summary["solver"]["factorisations"] is None
    assert "pc_factor_mat_solver_type" in caplog.text and "does not apply" in caplog.text


def test_schur_refused_for_the_implicit_scheme(caplog):
    with caplog.at_level(logging.INFO, logger="vpcontact"):
        result, _ = _run(paper_raw(), "schur", mesh={"n": 4}, time={"N": 2, "scheme": "implicit"})
    assert result.summary["solver"]["linear"] == "direct"
    assert "implicit scheme" in caplog.text


def test_user_linear_options_are_those_that_choose_a_solver():
    from vpcontact.solvers.inactiveschur import user_linear_options
    from vpcontact.solvers.options import DEFAULT_PETSC
    assert user_linear_options(dict(DEFAULT_PETSC)) == []
    assert user_linear_options({**DEFAULT_PETSC, "ksp_view": None, "ksp_monitor": None}) == []
    assert user_linear_options({**DEFAULT_PETSC, "ksp_type": "gmres", "pc_type": "ilu"}) == \
        ["ksp_type", "pc_type"]


def _cli(tmp_path, nprocs: int, sets: list[str]) -> tuple[dict, dict]:
    """summary.json and contact.csv's columns of a schur run by the command line."""
    out = tmp_path / f"np{nprocs}"
    args = ["run", PAPER_CASE, "--out", out, "--quiet", "--set", "solver.linear=schur"]
    for s in sets:
        args += ["--set", s]
    proc = run_cli(args, nprocs=nprocs)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = list(csv.DictReader(open(out / "contact.csv")))
    return json.loads((out / "summary.json").read_text()), \
        {k: [r[k] for r in rows] for k in rows[0]}


@pytest.mark.mpi
@pytest.mark.parametrize("sets", [
    ["mesh.n=16", "time.N=16"],
    ["mesh.n=4", "time.N=4"],                         # rank 0 owns no Gamma3 node
    ["mesh.n=8", "time.N=4", "solver.quadrature=gauss"],
], ids=["paper", "no-gamma3-on-root", "gauss"])
def test_schur_under_mpirun_takes_the_serial_steps(tmp_path, sets):
    serial, a = _cli(tmp_path, 1, sets)
    parallel, b = _cli(tmp_path, 2, sets)
    for summary in (serial, parallel):
        assert summary["solver"]["linear"] == "schur"
        assert summary["solver"]["factorisations"] == 1
    assert parallel["mpi_ranks"] == 2
    assert [s["newton_iterations"] for s in serial["steps"]] == \
        [s["newton_iterations"] for s in parallel["steps"]]
    assert a["state"] == b["state"] and len(a["x"]) > 0
    for col in ("x", "u_x", "u_y", "neg_sigma_nu", "neg_sigma_tau"):
        assert _relative(np.array(a[col], float), np.array(b[col], float)) < TOL, col
