"""The Gamma3 Schur complement solve of SNES VI's Newton systems (app/solvers/inactiveschur.py)
against an independent reference: scipy's sparse LU of the submatrix J_II of the assembled
Jacobian J = K + B, for an inactive set that drops half of the bounded dofs."""
import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from mpi4py import MPI
from petsc4py import PETSc

from conftest import make_case
from vpcontact.simulation import build_mesh


def _solver_at_contact():
    """SNES VI (schur) on the paper case at h = 1/8 with its Jacobian assembled at a u that
    presses Gamma3 into the foundation (Gamma3 terms B nonzero)."""
    from vpcontact.model.problem import ContactProblem
    from vpcontact.solvers.snesvi import SNESVISolver
    case = make_case(mesh={"n": 8}, time={"N": 2}, solver={"method": "snes_vi"})
    problem = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD))
    solver = SNESVISolver(problem, case.petsc, linear="schur")
    rng = np.random.default_rng(1)
    problem.u.x.array[:] = 0.05 * rng.standard_normal(problem.u.x.array.shape)
    solver._F(solver.snes, problem.u.vector, solver.b)
    solver._J(solver.snes, None, solver.A, solver.A)
    return solver


def test_inactive_solve_equals_a_sparse_lu_of_the_submatrix():
    solver = _solver_at_contact()
    try:
        assert solver.linear == "schur"
        schur = solver.schur
        lb, ub = solver.problem.disc.bounds(solver.problem.u.vector)
        bounded = np.flatnonzero((lb.array_r > PETSc.NINFINITY) | (ub.array_r < PETSc.INFINITY))
        active = bounded[::2]
        rows = np.setdiff1d(np.arange(schur.n), active)
        ai, aj, av = solver.A.getValuesCSR()
        J = scipy.sparse.csr_matrix((av, aj, ai), shape=(schur.n, schur.n))
        J_II = J[rows][:, rows].tocsc()
        B_rows = np.flatnonzero(np.diff(solver.B.getValuesCSR()[0]))
        assert np.abs(solver.B.getValuesCSR()[2]).max() > 0         # the Gamma3 terms act
        assert np.isin(B_rows, rows).any()
        r = np.random.default_rng(2).standard_normal(len(rows))
        expected = scipy.sparse.linalg.spsolve(J_II, r)
        gI, how = schur.factor(rows)
        assert len(gI) == schur.m - len(active)
        assert how[0] == "cholesky"             # the nodal rule: symmetric nodal blocks
        lu = ("lu", schur._lu(gI, *schur.gamma3_entries()))     # the general path
        for way in (how, lu):
            x = np.empty(len(rows))
            schur.solve(rows, gI, way, r, x)
            assert np.abs(x - expected).max() < 1e-10 * np.abs(expected).max()
        # all dofs inactive (the first Newton iteration's operator J itself)
        gI, how = schur.factor(None)
        r = np.random.default_rng(3).standard_normal(schur.n)
        x = np.empty(schur.n)
        schur.solve(None, gI, how, r, x)
        expected = scipy.sparse.linalg.spsolve(J.tocsc(), r)
        assert np.abs(x - expected).max() < 1e-10 * np.abs(expected).max()
    finally:
        solver.destroy()
