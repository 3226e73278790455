"""The (2.6) diagnostic's upper bound from the condensed solver's Schur complement
(diagnostics.trace_constant_bound): lam_max(A x = lam S x) as lam_max(C^-1 A C^-T) with
S = C C^T against the dense generalised eigenproblem, by both of its paths, and the bound
against the trace constant itself on the paper case."""
import numpy as np
import pytest
import scipy.linalg
from mpi4py import MPI

from conftest import paper_raw, validate_raw
from vpcontact.post import diagnostics


def _pair(m=40, seed=0):
    """A semidefinite A of rank m / 4 (as M_G on part of the dofs) and an SPD S."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((m, m))
    V = rng.standard_normal((m, m // 4))
    return V @ V.T, B @ B.T + m * np.eye(m)


@pytest.mark.parametrize("sparse", [False, True], ids=["dense_A", "sparse_A"])
@pytest.mark.parametrize("path", ["lanczos", "dense_reduction", "numpy"])
def test_reduced_eigenvalue_equals_the_generalised_one(monkeypatch, path, sparse):
    """A dense or scipy sparse (as M_G from PCG_MIN Gamma3 dofs on); ARPACK, the dense
    reduction where it fails, and numpy's below LAPACK_MIN dofs."""
    import scipy.sparse.linalg as sla
    from scipy.sparse import csr_matrix
    A, S = _pair()
    C = np.asfortranarray(np.linalg.cholesky(S))
    ref = scipy.linalg.eigh(A, S, eigvals_only=True)[-1]
    if sparse:
        A = csr_matrix(A)
    if path != "numpy":                             # the scipy paths, at any size
        monkeypatch.setattr(diagnostics, "LAPACK_MIN", 0)
    if path == "dense_reduction":                   # ARPACK fails: the dense reduction
        def refuse(*args, **kwargs):
            raise sla.ArpackNoConvergence("refused", np.zeros(0), np.zeros((0, 0)))
        monkeypatch.setattr(sla, "eigsh", refuse)
    assert diagnostics._largest_generalised_eigenvalue(A, C) == pytest.approx(ref, rel=1e-10)


def test_bound_brackets_the_trace_constant_on_the_paper_case():
    """||gamma||^2 <= c_max lam_K <= (c_max / c_min) ||gamma||^2, with c_min, c_max the
    extreme eigenvalues of E: lam_K = max |v|^2_Gamma3 / (E eps(v), eps(v)) lies between
    ||gamma||^2 / c_max and ||gamma||^2 / c_min."""
    from vpcontact.model.problem import ContactProblem
    from vpcontact.simulation import build_mesh
    from vpcontact.solvers.condensed import CondensedStepSolver
    case = validate_raw(paper_raw())
    problem = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD))
    solver = CondensedStepSolver(problem)
    bound = diagnostics.trace_constant_bound(problem, solver)
    value, _ = diagnostics.trace_constant(problem.disc, rtol=1e-12, max_iter=5000)
    c = np.linalg.eigvalsh(problem.elasticity.Cmat)
    assert value * (1 - 1e-9) <= bound <= value * c[-1] / c[0] * (1 + 1e-9)
    solver.destroy()


def test_snes_vi_with_the_schur_complement_gives_the_condensed_bound():
    """SNES VI's Gamma3 Schur complement PC holds the same S (of the same K): the same
    bound; with LU of every Newton system, none (the diagnostic computes ||gamma||^2)."""
    from vpcontact.model.problem import ContactProblem
    from vpcontact.simulation import build_mesh
    from vpcontact.solvers.condensed import CondensedStepSolver
    from vpcontact.solvers.snesvi import SNESVISolver
    case = validate_raw(paper_raw())
    problem = ContactProblem(case, build_mesh(case, MPI.COMM_WORLD))
    condensed = CondensedStepSolver(problem)
    expected = diagnostics.trace_constant_bound(problem, condensed)
    condensed.destroy()
    for linear, bound in (("schur", pytest.approx(expected, rel=1e-10)), ("direct", None)):
        solver = SNESVISolver(problem, case.petsc, linear=linear)
        assert solver.linear == linear
        assert diagnostics.trace_constant_bound(problem, solver) == bound
        solver.destroy()
