"""The step solvers' PETSc options (app/solvers/options.py): the defaults scaled to a case,
the prefix they reach PETSc's database under, and their life there: put in once when a
solver is built, read by every SNES it makes, taken out when it is destroyed."""
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from conftest import make_case
from vpcontact.solvers.options import (
    PREFIX,
    push_options,
    remove_options,
    scaled_defaults,
    tolerance_limits,
)


def _ours() -> dict:
    """The options of PETSc's database under our prefix."""
    return {k: v for k, v in PETSc.Options().getAll().items() if k.startswith(PREFIX)}


def test_options_go_in_under_the_prefix_and_come_out_again():
    assert _ours() == {}
    options = {"snes_rtol": 1e-9, "snes_monitor": None, "snes_lag_jacobian": 2,
               "amg_reuse": False, "ksp_converged_reason": True}
    push_options(options)
    db = PETSc.Options()
    assert db.getString("vpcontact_snes_rtol") == "1e-09"
    assert db.getInt("vpcontact_snes_lag_jacobian") == 2
    assert db.getString("vpcontact_amg_reuse") == "false"
    assert db.hasName("vpcontact_snes_monitor") and db.hasName("vpcontact_ksp_converged_reason")
    assert db.getString("vpcontact_snes_monitor") in ("", None)      # a flag, no value
    remove_options(options)
    assert _ours() == {}


def test_the_absolute_tolerances_scale_with_stress_length_and_gap():
    # the paper's scales (stress 8 N/m^2 on the unit square): the defaults as they are
    assert scaled_defaults(8.0, 1.0, 2, None) == {"snes_atol": 1e-11,
                                                  "snes_vi_zero_tolerance": 1e-8}
    # a body 1000 times larger in 3D under 4 N/m^2: forces 4e6 N, half of 8e6 per 8
    d = scaled_defaults(4.0, 1000.0, 3, None)
    assert d["snes_atol"] == pytest.approx(1e-11 * 4e6 / 8.0)
    assert d["snes_vi_zero_tolerance"] == pytest.approx(1e-5)
    # a gap of 1e-6 m: at most 1e-4 g; no loads: the default atol
    d = scaled_defaults(0.0, 1.0, 2, 1e-6)
    assert d["snes_atol"] == 1e-11 and d["snes_vi_zero_tolerance"] == pytest.approx(1e-10)
    limits = tolerance_limits(8.0, 2.0, 2, 1e-3)
    assert limits["snes_atol"][0] == pytest.approx(1e-3 * 16.0)
    assert limits["snes_vi_zero_tolerance"][0] == pytest.approx(1e-6)
    assert "the gap g" in limits["snes_vi_zero_tolerance"][1]
    # no loads: no residual limit; a gap larger than the body: the body's size counts
    limits = tolerance_limits(0.0, 2.0, 2, 5.0)
    assert "snes_atol" not in limits
    assert limits["snes_vi_zero_tolerance"][0] == pytest.approx(2e-3)


def _line_search(snes, path) -> str:
    """The type of a SNES's line search, as its view shows it."""
    viewer = PETSc.Viewer().createASCII(str(path), comm=snes.getComm())
    snes.view(viewer)
    viewer.destroy()
    text = path.read_text()
    return text[text.index("SNESLineSearch Object"):].split("type:")[1].split()[0]


def test_snes_vi_keeps_its_options_in_the_database_while_it_lives(tmp_path):
    from vpcontact.simulation import Simulation

    case = make_case(mesh={"n": 4}, time={"N": 8}, solver={"method": "snes_vi"},
                     petsc={"snes_rtol": 1e-9, "snes_max_it": 30})
    sim = Simulation(case, MPI.COMM_WORLD)
    sim.setup()
    solver = sim.solver
    ours = _ours()
    assert ours["vpcontact_snes_rtol"] == "1e-09" and ours["vpcontact_snes_max_it"] == "30"
    assert ours["vpcontact_snes_linesearch_type"] == "basic"
    rtol, _, _, max_it = solver.snes.getTolerances()
    assert rtol == 1e-9 and max_it == 30
    # the fallback SNES reads the backtracking line search; the database keeps ours
    assert _line_search(solver.robust, tmp_path / "robust.txt") == "bt"
    assert _line_search(solver.snes, tmp_path / "basic.txt") == "basic"
    assert _ours() == ours
    sim.run()
    assert sim.n == 8
    assert _ours() == {}                   # destroyed at the end of the run
