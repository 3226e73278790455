"""The back ends of the Condensation (CHOLMOD, CHOLMOD on rank 0, MUMPS Schur, PETSc)
against dense linear algebra on the paper case's elasticity matrix: S = K_GG - K_GI K_II^-1
K_IG, condense(b) = (K^-1 b)_G, and expand(y) = the u with u_G = y whose interior rows of
K u = b hold."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import make_case
from vpcontact.solvers.schur import gather_csr

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial: dense references")


@pytest.fixture(scope="module")
def solver():
    from vpcontact.model.problem import ContactProblem
    from vpcontact.simulation import build_mesh
    from vpcontact.solvers.condensed import CondensedStepSolver
    case = make_case(mesh={"n": 6}, solver={"method": "fast"})
    problem = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD))
    s = CondensedStepSolver(problem)
    yield s
    s.destroy()


def _cholmod(s, G):
    from vpcontact import kernels
    from vpcontact.solvers.condensed.cholmod import CholmodCondensation
    module = kernels.load()
    if module is None:
        pytest.skip("no C compiler")
    return CholmodCondensation(s.K, G, s.problem.disc.dim, module, s.comm)


def _root(s, G):
    """CHOLMOD on rank 0 with gathered right-hand sides (SNES VI's back end under mpirun;
    serial here: the gather is a copy)."""
    from vpcontact import kernels
    from vpcontact.solvers.condensed.cholmod import RootCondensation
    module = kernels.load()
    if module is None:
        pytest.skip("no C compiler")
    return RootCondensation(s.K, G, s.problem.disc.dim, module, s.comm)


def _mumps(s, G):
    from vpcontact.solvers.condensed.mumps import MumpsCondensation
    K = s.K.convert("aij")                   # MUMPS reads AIJ rows
    c = MumpsCondensation.build(K, G, s.problem.disc.dim, s.comm)
    if c is None:
        pytest.skip("no MUMPS wrapper")
    return c


def _petsc(s, G):
    from vpcontact.solvers.condensed.petsc import PetscCondensation
    return PetscCondensation(s.K, G, s.layout, {}, s.comm)


@pytest.mark.parametrize("build", [_cholmod, _root, _mumps, _petsc],
                         ids=["cholmod", "root", "mumps", "petsc"])
def test_condensation_equals_dense_algebra(solver, build):
    G = solver.layout.global_rows()
    Kd = gather_csr(solver.K, solver.comm).scipy().toarray()
    n = len(Kd)
    interior = np.setdiff1d(np.arange(n), G)
    K_II, K_IG = Kd[np.ix_(interior, interior)], Kd[np.ix_(interior, G)]
    S_ref = Kd[np.ix_(G, G)] - K_IG.T @ np.linalg.solve(K_II, K_IG)
    c = build(solver, G)
    rng = np.random.default_rng(3)
    b, x = solver.K.createVecRight(), solver.K.createVecRight()
    b.array[:] = rng.normal(size=n)
    b_ref = b.array.copy()
    try:
        np.testing.assert_allclose(c.S, S_ref, rtol=1e-9, atol=1e-9 * np.abs(S_ref).max())
        assert np.allclose(c.C @ c.C.T, c.S, rtol=1e-10, atol=1e-10 * np.abs(S_ref).max())
        y0 = c.condense(b)
        u_free = np.linalg.solve(Kd, b_ref)
        np.testing.assert_allclose(y0, u_free[G], rtol=1e-9, atol=1e-9 * np.abs(u_free).max())
        y = y0 + rng.normal(size=len(G)) * np.abs(y0).max()
        c.expand(y, x)
        u = x.array.copy()
        np.testing.assert_allclose(u[G], y, rtol=1e-9, atol=1e-12 * np.abs(y).max())
        r = Kd @ u - b_ref                      # K u = b + E_G lambda: zero off Gamma3
        assert np.abs(r[interior]).max() <= 1e-8 * np.abs(b_ref).max()
        assert np.abs(r[G]).max() > 1e-3 * np.abs(b_ref).max()   # the forces act on G
    finally:
        c.destroy()
        b.destroy()
        x.destroy()
