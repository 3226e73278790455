"""SNES VI's residual with the explicit scheme from the kept bulk matrix
(app/solvers/bulkresidual.py: K x + c_n + the Gamma3 terms) against the full assembly of
(3.4) with dolfinx's lifting, at iterates away from the solution, after B entered SNES VI's
matrix, with a stiff compliance, with prescribed displacements, and over whole runs."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT, run_case, validate_raw
from vpcontact.case import load_raw


def _solver(raw):
    from vpcontact.simulation import Simulation
    sim = Simulation(validate_raw(raw), MPI.COMM_WORLD)
    sim.setup()
    return sim.solver


def _both(solver, x):
    """(the residual from K x, the residual by full assembly) at x."""
    fast, full = solver.b.duplicate(), solver.b.duplicate()
    solver._F(solver.snes, x, fast)
    kept, solver._residual = solver._residual, None
    try:
        solver._F(solver.snes, x, full)
    finally:
        solver._residual = kept
    return fast.array.copy(), full.array.copy()


def _random_iterate(solver, seed, size):
    x = solver.x.duplicate()
    x.array[:] = np.random.default_rng(seed).uniform(-size, size, len(x.array))
    x.ghostUpdate()
    return x


def _check(solver, size, rtol=1e-13):
    assert solver._residual is not None
    for seed in (1, 2):
        x = _random_iterate(solver, seed, size)
        fast, full = _both(solver, x)
        assert np.abs(full).max() > 0
        assert np.abs(fast - full).max() <= rtol * np.abs(full).max(), seed
        # B(x) into SNES VI's matrix: the next residual's rows R come from K alone
        solver._J(solver.snes, x, solver.A, solver.A)
    return solver


@pytest.mark.parametrize("c_nu,quadrature", [(100.0, "vertex"), (1e20, "vertex"),
                                              (100.0, "gauss")])
def test_residual_from_K_equals_assembly_contact(c_nu, quadrature):
    """The paper's scene: its clamped corner lies on Gamma3 (with the Gauss rule B couples
    it to the Gamma3 rows: the Gamma3 terms' lifting)."""
    raw = load_raw(ROOT / "cases" / "memory.yaml")
    raw["mesh"]["n"] = 6
    raw["contact"]["normal_compliance"]["c_nu"] = c_nu
    raw["contact"]["friction"]["slip"] = {"theta_inf": 0.3, "s0": 0.002}
    raw["solver"] = {"method": "snes_vi", "quadrature": quadrature}
    solver = _check(_solver(raw), 0.02)
    assert solver._residual.K_R is not None          # rows R of B taken from K
    assert solver.B is not None


def test_residual_from_K_equals_assembly_prescribed_displacement():
    raw = load_raw(ROOT / "cases" / "norton_relaxation.yaml")
    raw["mesh"]["n"] = 4
    raw["solver"] = {"method": "snes_vi"}
    solver = _check(_solver(raw), 0.05)
    assert solver.B is None and solver._residual.K_R is None


@pytest.mark.parametrize("case", ["memory.yaml", "norton_relaxation.yaml"])
def test_runs_equal_with_the_full_assembly(monkeypatch, case):
    """Whole runs (loads and prescribed displacements changing every step: c_n assembled
    again per solve) equal those with the full assembly to the solver's tolerance."""
    import vpcontact.solvers.snesvi as snesvi
    raw = load_raw(ROOT / "cases" / case)
    raw["mesh"]["n"] = 6
    raw["solver"] = {"method": "snes_vi"}
    raw["time"] = {"T": 1.0, "N": 8}
    fast = run_case(validate_raw(raw))
    monkeypatch.setattr(snesvi, "BulkProductResidual", lambda *args: None)
    full = run_case(validate_raw(raw))
    assert fast.status == full.status == "completed"
    u, v = fast.problem.u.x.array, full.problem.u.x.array
    assert np.abs(u).max() > 0
    np.testing.assert_allclose(u, v, rtol=0, atol=1e-9 * np.abs(v).max())
