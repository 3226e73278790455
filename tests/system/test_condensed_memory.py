"""The condensed solver's dense m x m Gamma3 matrices and the memory a machine has
(app/solvers/choice.py dense_fits): auto takes SNES VI where they would not fit, and an
explicit ``solver.method: condensed`` is refused before anything is factorised."""
import pytest
from mpi4py import MPI

from conftest import ROOT, validate_raw
from vpcontact.case import load_raw
from vpcontact.io.errors import CaseError
from vpcontact.solvers import choice


def test_dense_fits_counts_the_matrices():
    comm = MPI.COMM_WORLD
    m = 1000
    need = choice.DENSE_BYTES_PER_ENTRY * m * m
    assert choice.dense_fits(m, comm, memory=need * 1.01) == (True, "")
    ok, why = choice.dense_fits(m, comm, memory=need * 0.99)
    assert not ok
    assert "1000 dofs" in why and f"{need / 1e9:.1f} GB" in why
    assert choice.dense_fits(m, comm, memory=None)[0] in (True, False)   # reads MemAvailable


def _setup(method, monkeypatch, memory):
    import vpcontact.meshes.refine as refine
    from vpcontact.simulation import Simulation
    monkeypatch.setattr(refine, "available_memory", lambda: memory)
    raw = load_raw(ROOT / "cases" / "wang_cheng_2021.yaml")
    raw["mesh"]["n"] = 4
    raw["solver"] = {"method": method}
    sim = Simulation(validate_raw(raw), MPI.COMM_WORLD)
    sim.setup()
    return sim.solver.name


def test_auto_takes_snes_vi_where_the_dense_matrices_do_not_fit(monkeypatch):
    assert _setup("auto", monkeypatch, 1e12) == "condensed"
    assert _setup("auto", monkeypatch, 1e3) == "snes_vi"


def test_condensed_is_refused_where_they_do_not_fit(monkeypatch):
    with pytest.raises(CaseError, match=r"solver.method: 'condensed' is not possible here: "
                                        r"its Gamma3 problem \(\d+ dofs\) needs about .* GB "
                                        r".*\(allowed: snes_vi, auto\)"):
        _setup("condensed", monkeypatch, 1e3)
