"""The committed/trial State (app/model/state.py): commit() keeps a copy of the live fields,
restore() puts exactly that copy back (the adaptive rollback), snapshot() is a copy, not a
view; a run that cannot roll back keeps no copy; kappa has m components per cell."""
import numpy as np
from mpi4py import MPI

from conftest import make_case, paper_raw
from vpcontact.meshes import build_rectangle
from vpcontact.model.history import ViscoplasticHistory
from vpcontact.model.problem import ContactProblem
from vpcontact.model.state import State


def _problem(**sections):
    case = make_case(mesh={"n": 2}, **sections)
    return ContactProblem(case, build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=2))


def _random_sigma(problem, seed):
    s = np.random.default_rng(seed).normal(size=(problem.sigma.x.array.size // 4, 2, 2)) * 5.0
    problem.sigma.x.array[:] = (0.5 * (s + s.transpose(0, 2, 1))).reshape(-1)


def test_commit_and_restore_undo_a_step():
    problem = _problem(time={"adaptive": {}})
    state = problem.state
    assert state.rollback and state.committed is None
    state.kappa.x.array[:] = 0.5
    _random_sigma(problem, 3)
    problem.u.x.array[:] = np.linspace(0.0, 1e-3, problem.u.x.array.size)
    state.commit()
    before = {k: f.x.array.copy() for k, f in state.fields().items()}
    hist = ViscoplasticHistory(problem, problem.law)
    hist.advance(problem.sigma, 0.25)                 # the trial H_n, kappa_n
    problem.u.x.array[:] += 1.0
    problem.sigma.x.array[:] = 0.0
    assert not np.array_equal(problem.H.x.array, before["H"])
    assert not np.array_equal(state.kappa.x.array, before["kappa"])
    state.restore()
    for name, f in state.fields().items():
        np.testing.assert_array_equal(f.x.array, before[name])
    # the committed copy is not a view: a second trial and restore give the same again
    hist.advance(problem.sigma, 0.25)
    state.restore()
    np.testing.assert_array_equal(state.kappa.x.array, 0.5)


def test_no_copy_without_rollback():
    problem = _problem()
    assert problem.state.rollback is False
    problem.state.commit()
    assert problem.state.committed is None


def test_snapshot_is_a_copy():
    state = _problem().state
    state.kappa.x.array[:] = 2.0
    snap = state.snapshot()
    state.kappa.x.array[:] = 3.0
    np.testing.assert_array_equal(snap["fields"]["kappa"], 2.0)
    state.load(snap)
    np.testing.assert_array_equal(state.kappa.x.array, 2.0)


def test_fields_follow_the_case():
    """Elastic body without initial values: no H, no kappa; with the law: both, kappa m = 1
    as a scalar DG0 Function (the outputs' layout)."""
    raw = paper_raw()
    del raw["material"]["viscoplastic"]
    case = make_case(raw, mesh={"n": 2})
    elastic = ContactProblem(case, build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=2)).state
    assert list(elastic.fields()) == ["u", "sigma"] and elastic.kappa_cells is None
    vp = _problem().state
    assert list(vp.fields()) == ["u", "sigma", "H", "kappa"]
    assert vp.kappa.function_space.dofmap.index_map_bs == 1
    assert vp.kappa_cells.shape == (vp.kappa.x.array.size, 1)


def test_kappa_with_m_components():
    """A law with m internal variables: kappa is DG0 with m components, (cells, m) per cell,
    and the cells view writes through to the Function."""
    p = _problem()
    state = State(p.disc.V, p.disc.Q, p.disc.Y, True, 8)
    ncells = p.disc.Y.dofmap.index_map.size_local + p.disc.Y.dofmap.index_map.num_ghosts
    assert state.kappa_cells.shape == (ncells, 8)
    state.kappa_cells[:, 3] = 1.5
    assert state.kappa.x.array.reshape(-1, 8)[:, 3].tolist() == [1.5] * ncells
    assert state.kappa.x.array.sum() == 1.5 * ncells
