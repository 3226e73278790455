"""schur.py: S and its Cholesky factor from the trailing blocks of a G-last factorisation equal
the dense K_GG - K_GI K_II^-1 K_IG; the split solve; MUMPS with Schur variables."""
import numpy as np
import pytest
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.solvers import ldl
from vpcontact.solvers.schur import CSR, GLastLDL, GLastLU, gamma3_schur_pair


def _spd(n=60, seed=0):
    rng = np.random.default_rng(seed)
    lap = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    A = sp.kron(lap, sp.eye(2)) + sp.kron(sp.eye(n), sp.csr_matrix(rng.random((2, 2)) * 0.1))
    A = (A + A.T) * 0.5 + sp.diags(rng.random(2 * n) + 0.5)
    return A.tocsr()


def _csr(A):
    return CSR(A.indptr, A.indices, A.data)


def _check_cholesky(C, S):
    """C is lower triangular and C C^T = S."""
    assert np.array_equal(C, np.tril(C))
    assert np.abs(C @ C.T - S).max() <= 1e-13 * np.abs(S).max()


def test_schur_complement_equals_the_inverse_of_the_dense_flexibility():
    A = _spd()
    G = np.array([7, 3, 50, 51, 119, 0])          # any order, not sorted
    K = PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                            A.indices.astype(PETSc.IntType), A.data),
                              comm=MPI.COMM_SELF)
    S, C = gamma3_schur_pair(K, G, MPI.COMM_SELF)
    Sd = np.linalg.inv(np.linalg.inv(A.toarray())[np.ix_(G, G)])
    assert np.abs(S - Sd).max() <= 1e-12 * np.abs(Sd).max()
    _check_cholesky(C, S)


@pytest.mark.parametrize("lapack", [False, True])
def test_schur_pair_by_triangular_products(monkeypatch, lapack):
    """S = K_GG - K_GI K_II^-1 K_IG and its Cholesky factor from CHOLMOD's trailing blocks,
    by the general products and by LAPACK's dlauum (chosen above LAPACK_MIN dofs)."""
    from vpcontact.solvers import dense, schur
    monkeypatch.setattr(schur, "LAPACK_MIN", 0 if lapack else 10**9)
    A = _spd(80, seed=4)
    G = np.array([3, 9, 40, 41, 42, 43, 100, 159, 12])
    f = _factor("cholmod", A, G, 1)
    S, C = schur.schur_pair(f)
    Ad = A.toarray()
    interior = np.setdiff1d(np.arange(A.shape[0]), G)
    Sd = Ad[np.ix_(G, G)] - Ad[np.ix_(G, interior)] @ np.linalg.solve(
        Ad[np.ix_(interior, interior)], Ad[np.ix_(interior, G)])
    assert np.abs(S - Sd).max() <= 1e-13 * np.abs(Sd).max()
    assert np.array_equal(S, S.T)
    _check_cholesky(C, S)
    r = np.arange(len(G), dtype=float)
    assert np.abs(Sd @ dense.cholesky_solve(C, r) - r).max() <= 1e-12 * np.abs(r).max()


@pytest.mark.parametrize("m, block, chunk", [(1, 4, 3), (2, 1, 1), (13, 4, 5), (40, 7, 64),
                                            (40, 256, 1 << 16)])
def test_symmetric_in_place_is_the_reversed_symmetric_matrix(m, block, chunk):
    """symmetric_in_place(U) = J (U + U^T - diag U) J (J the reversal) bit for bit, C order,
    in U's memory: blocks and chunks that do and do not divide m, odd and even m^2."""
    from vpcontact.solvers.schur import symmetric_in_place
    rng = np.random.default_rng(m)
    U = np.asfortranarray(np.triu(rng.standard_normal((m, m))))
    expected = (U + U.T - np.diag(np.diag(U)))[::-1, ::-1]
    S = symmetric_in_place(U, block, chunk)
    assert S.flags.c_contiguous and np.shares_memory(S, U)
    assert np.array_equal(S, expected)


@pytest.mark.parametrize("m, block", [(1, 4), (2, 1), (13, 4), (40, 7), (40, 256)])
def test_schur_from_buffer_is_the_symmetric_lower_triangle(m, block, monkeypatch):
    """mumps.schur_from_buffer: S = L + L^T - diag L from the buffer's lower triangle L, bit
    for bit, in the buffer's memory, whatever MUMPS left in the strict upper part."""
    from vpcontact.solvers import mumps, schur
    monkeypatch.setattr(schur.mirror_upper, "__defaults__", (block,))
    rng = np.random.default_rng(m)
    buffer = rng.standard_normal((m, m))
    L = np.tril(buffer)
    S = mumps.schur_from_buffer(buffer)
    assert S is buffer and np.array_equal(S, L + L.T - np.diag(np.diag(L)))


def test_g_last_factors_reproduce_the_matrix():
    A = _spd(40, seed=1)
    G = np.array([5, 6, 70])
    f = GLastLU(_csr(A), G)
    assert list(f.perm[-3:]) == list(G)
    assert sorted(f.perm) == list(range(A.shape[0]))
    Ap = A[f.perm][:, f.perm].toarray()
    assert np.abs((f.L @ f.U).toarray() - Ap).max() <= 1e-13 * np.abs(Ap).max()


def _factor(kind, A, G, bs):
    if kind == "superlu":
        return GLastLU(_csr(A), G, bs)
    module = ldl.load()
    if module is None:
        pytest.skip("CHOLMOD not available")
    return GLastLDL(_csr(A), G, bs, module)


def _dense_L(f):
    """L (unit lower, dense) from a GLastLDL's interior blocks and L_GG."""
    bs, nbc, Bp, Bi, Bx, Ld = f.blocks
    n, k = f.n, f.n - f.m
    L = np.eye(n)
    for J in range(nbc):
        for a in range(bs):
            for b in range(a + 1, bs):
                L[bs * J + b, bs * J + a] = Ld[J * bs * bs + a * bs + b]
        for q in range(Bp[J], Bp[J + 1]):
            for a in range(bs):
                for b in range(bs):
                    if bs * Bi[q] + b < n:
                        L[bs * Bi[q] + b, bs * J + a] = Bx[q * bs * bs + a * bs + b]
    L[k:, k:] = f.trailing()[0]
    return L


@pytest.mark.parametrize("bs", [1, 2])
def test_cholmod_ldl_reproduces_the_matrix_in_the_given_order(bs):
    A = _spd(40, seed=1)
    G = np.array([4, 5, 70, 71])                  # whole nodes
    f = _factor("cholmod", A, G, bs)
    assert f.blocks[0] == bs
    lu = GLastLU(_csr(A), G, bs)
    assert np.array_equal(f.perm, lu.perm)
    Ap = A[f.perm][:, f.perm].toarray()
    assert f._factor.in_place                        # the factor's blocks over CHOLMOD's x
    L = _dense_L(f)
    assert np.array_equal(np.diag(L), np.ones(A.shape[0]))
    LDLt = L @ np.diag(f.D) @ L.T
    assert np.abs(LDLt - Ap).max() <= 1e-13 * np.abs(Ap).max()
    assert np.abs(f.D - lu.D).max() <= 1e-13 * np.abs(lu.D).max()     # SuperLU's pivots


def test_cholmod_refuses_an_indefinite_matrix():
    module = ldl.load()
    if module is None:
        pytest.skip("CHOLMOD not available")
    A = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]]))
    with pytest.raises(ldl.NotPositiveDefinite):
        ldl.Factor(module, A.indptr, A.indices, A.data, np.arange(2), 0)


@pytest.mark.parametrize("kind", ["superlu", "cholmod"])
@pytest.mark.parametrize("bs", [1, 2])
def test_split_solve_with_given_gamma3_values(bs, kind):
    """kernels.GLastSolve: forward, y0 = S^-1 r, backward with u_G = y solves the interior
    equations exactly, and u_G = y0 is the unconstrained solution K^-1 b; with scalar and
    2 x 2 block storage of L (G is two whole nodes, so the nodal ordering applies)."""
    from vpcontact import kernels
    from vpcontact.solvers.dense import cholesky_solve
    from vpcontact.solvers.schur import schur_pair
    module = kernels.load()
    if module is None:
        pytest.skip("no C compiler")
    A = _spd(50, seed=2)
    G = np.array([99, 98, 10, 11])
    f = _factor(kind, A, G, bs)
    if bs == 2:                                    # a node's dofs stay consecutive
        head = f.perm[:-4]
        assert np.all(head[::2] % 2 == 0) and np.array_equal(head[::2] + 1, head[1::2])
    split = kernels.GLastSolve(f, module, bs)
    assert split.bs == bs
    rng = np.random.default_rng(3)
    b = rng.normal(size=A.shape[0])
    Ad = A.toarray()
    r = split.forward(b).copy()
    y0 = cholesky_solve(schur_pair(f)[1], r)
    u = np.empty_like(b)
    split.backward(y0, u)
    assert np.abs(u - np.linalg.solve(Ad, b)).max() <= 1e-12 * np.abs(u).max()
    r2 = split.forward(b).copy()
    y = rng.normal(size=len(G))                       # any Gamma3 values
    split.backward(y, u)
    interior = np.setdiff1d(np.arange(A.shape[0]), G)
    assert np.array_equal(u[G], y)
    res = (Ad @ u - b)[interior]
    assert np.abs(res).max() <= 1e-12 * (np.abs(Ad).max() * np.abs(u).max())
    assert np.array_equal(r, r2)


@pytest.mark.parametrize("bs", [1, 2])
def test_interior_graph_is_the_nonzero_pattern(bs):
    """schur._interior_graph (numpy) against scipy: the pattern of the nonzero entries of
    A_II, of its nodes for bs = 2 (a node pair is an edge if any entry of the block is
    nonzero); stored zeros (Dirichlet rows) are no edges."""
    from vpcontact.solvers.schur import _interior_graph
    A = _spd(30, seed=4)
    row = slice(A.indptr[8], A.indptr[9])           # a Dirichlet-like row: stored zeros
    A.data[row] = np.where(A.indices[row] == 8, 1.0, 0.0)
    assert np.count_nonzero(A.data == 0.0) > 0
    G = np.array([0, 1, 40, 41])
    I = np.setdiff1d(np.arange(A.shape[0]), G)
    indptr, indices = _interior_graph(_csr(A), I, bs)
    P = sp.csr_matrix((np.ones(len(I)), (np.arange(len(I)), np.arange(len(I)) // bs)))
    ref = (P.T @ abs(A[I][:, I]) @ P).tocsr()
    ref.eliminate_zeros()
    ref.sort_indices()
    assert np.array_equal(indptr, ref.indptr) and np.array_equal(indices, ref.indices)


@pytest.mark.parametrize("bs", [1, 2])
def test_cholmod_blocks_in_place_equal_a_copy(bs):
    """ldl.Factor writes the blocks over CHOLMOD's values; forced to copy them into a new
    array (and free CHOLMOD's factor) it gives the same blocks, D and L_GG bit for bit."""
    from vpcontact.solvers.schur import interior_last_ordering
    module = ldl.load()
    if module is None:
        pytest.skip("CHOLMOD not available")
    A = _spd(60, seed=5)
    G = np.array([10, 11, 100, 101])
    perm = interior_last_ordering(_csr(A), G, bs)
    f1 = ldl.Factor(module, A.indptr, A.indices, A.data, perm, len(G), bs)
    f2 = ldl.Factor(module, A.indptr, A.indices, A.data, perm, len(G), bs, in_place=False)
    assert f1.in_place and not f2.in_place and f2._handle is None
    for a, b in zip(f1.blocks, f2.blocks):
        assert np.array_equal(a, b)
    assert np.array_equal(f1.D, f2.D) and np.array_equal(f1.L_GG, f2.L_GG)


def test_mumps_schur_variables_give_the_pair_and_the_split_solve():
    """MUMPS with G as Schur variables (app/solvers/mumps.py, one rank here; the fast solver's
    mpirun tests run it on two): S and its Cholesky factor as the dense reference, and the
    condensation / expansion cycle r = b_G - K_GI K_II^-1 b_I, u = K^-1 (b + E_G lambda) with
    u_G = y."""
    from vpcontact.solvers import mumps
    from vpcontact.solvers.dense import cholesky_solve
    module = mumps.load()
    if module is None:
        pytest.skip("the MUMPS wrapper cannot be built here")
    A = _spd(60, seed=5)
    G = np.array([7, 3, 50, 51, 119, 0])
    K = PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                            A.indices.astype(PETSc.IntType), A.data),
                              comm=MPI.COMM_SELF)
    M = mumps.SchurMumps(module, K, G, 1, MPI.COMM_SELF)
    Ad = A.toarray()
    Zd = np.linalg.inv(Ad)[np.ix_(G, G)]
    assert np.abs(M.S @ Zd - np.eye(len(G))).max() <= 1e-12
    _check_cholesky(M.C, M.S)
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    r = M.forward(b)
    y0 = cholesky_solve(M.C, r)
    assert np.abs(y0 - np.linalg.solve(Ad, b)[G]).max() <= 1e-12 * np.abs(r).max()
    y = y0 + 0.1
    x = np.zeros(A.shape[0])                      # the owned entries (all, one rank)
    M.backward(y, x)
    lam = np.zeros(A.shape[0])
    lam[G] = M.S @ (y - y0)
    assert np.abs(x - np.linalg.solve(Ad, b + lam)).max() <= 1e-11 * np.abs(x).max()
    M.destroy()


class _SmallWorkspace:
    """The MUMPS wrapper with ICNTL(14) = -50 % set after the analysis: the workspace
    estimate of the factorisation is too small (INFOG(1) = -9) on the first attempt."""

    def __init__(self, lib):
        self._lib, self.factorisations = lib, []

    def __getattr__(self, name):
        return getattr(self._lib, name)

    def ms_analyse(self, h, *args):
        status = self._lib.ms_analyse(h, *args)
        self._lib.ms_set_icntl(h, 14, -50)
        return status

    def ms_factor(self, h, S):
        status = self._lib.ms_factor(h, S)
        self.factorisations.append((status, self._lib.ms_icntl(h, 14)))
        return status


def test_mumps_workspace_too_small_is_factorised_again(caplog):
    """MUMPS's workspace estimate too small (-9, met under mpirun as the partition varies):
    the factorisation is repeated with ICNTL(14) raised, logged, and gives S = (K^-1)_GG^-1;
    MUMPS's own messages are restored afterwards (ICNTL(1) = 6)."""
    from types import SimpleNamespace

    from vpcontact.solvers import mumps
    module = mumps.load()
    if module is None:
        pytest.skip("the MUMPS wrapper cannot be built here")
    A = _spd(400, seed=5)
    G = np.arange(0, 800, 7)
    K = PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                            A.indices.astype(PETSc.IntType), A.data),
                              comm=MPI.COMM_SELF)
    lib = _SmallWorkspace(module.lib)
    with caplog.at_level("INFO", logger="vpcontact"):
        M = mumps.SchurMumps(SimpleNamespace(ffi=module.ffi, lib=lib), K, G, 2, MPI.COMM_SELF)
    assert lib.factorisations == [(-9, -50), (0, 20)]
    assert "INFOG(1) = -9" in caplog.text and "ICNTL(14) = 20 %" in caplog.text
    assert module.lib.ms_icntl(M._h, 1) == 6
    Zd = np.linalg.inv(A.toarray())[np.ix_(G, G)]
    assert np.abs(M.S @ Zd - np.eye(len(G))).max() <= 1e-10
    M.destroy()


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_cholesky_solve_compiled_equals_scipy(monkeypatch, dtype):
    """S^-1 r by the compiled trsv pair and by scipy's, in either precision; only C's lower
    triangle is read (the upper holds garbage, as the kept factor's may)."""
    from vpcontact.solvers import dense
    if dense.load() is None:
        pytest.skip("no compiled kernels")
    rng = np.random.default_rng(5)
    m = 40
    L = np.tril(rng.random((m, m))) + m * np.eye(m)
    S = L @ L.T
    C = np.asfortranarray(L + np.triu(rng.random((m, m)) * 1e30, 1), dtype=dtype)
    r = rng.random(m)
    compiled = dense.cholesky_solve(C, r)
    monkeypatch.setattr(dense, "load", lambda: None)
    reference = dense.cholesky_solve(C, r)
    assert compiled.dtype == reference.dtype == dtype
    tol = 1e-12 if dtype == np.float64 else 1e-5
    assert np.abs(compiled - reference).max() <= tol * np.abs(reference).max()
    assert np.abs(S @ compiled - r).max() <= tol * np.abs(r).max() * m
