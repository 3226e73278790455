"""The Gamma3 Schur complement S of the condensed solver and its Cholesky factor, from one sparse
factorisation with the Gamma3 dofs ordered last.

If the rows and columns of K are ordered so that the Gamma3 dofs G come last and K = L U
(no pivoting: K is symmetric positive definite, so U = D L^T), the trailing blocks satisfy
    S = K_GG - K_GI K_II^-1 K_IG = L_GG U_GG = C C^T,      C = L_GG D_G^1/2,
so the Schur complement costs one factorisation and a product of two m x m triangles instead of
m back-substitutions, which cost far more with every back end (docs/performance.md, section 3).
The interior is ordered by CHOLMOD's fill-reducing order (AMD or METIS; PETSc's nested
dissection where CHOLMOD is missing) of the node graph, so a node's dofs stay together,
the factorisation is CHOLMOD's L D L^T (app/solvers/ldl.py) or, without it, SuperLU's L U (scipy),
on rank 0 with the matrix gathered there (the condensed solver is for problems whose Gamma3 is
small; the matrix itself is a few MB at the sizes it is chosen for).  The CHOLMOD path needs
numpy and PETSc only: importing scipy.sparse pulls in scipy.linalg and scipy.sparse.csgraph
(start-up time: docs/performance.md, section 3), so scipy is imported for the SuperLU
fallback alone.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

log = logging.getLogger("vpcontact")


@dataclass
class CSR:
    """A square sparse matrix as CSR arrays.

    Args:
        indptr: row pointers, shape (n + 1,).
        indices: column indices, shape (nnz,).
        data: values, shape (nnz,).
    """
    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray

    @property
    def n(self) -> int:
        """The number of rows (and columns)."""
        return len(self.indptr) - 1

    def without_zeros(self) -> CSR:
        """The same matrix without its stored zeros (the couplings dolfinx zeroes in the
        Dirichlet rows and columns).

        Returns:
            A new CSR (the arrays are copies).
        """
        keep = self.data != 0
        rows = np.repeat(np.arange(self.n), np.diff(self.indptr))[keep]
        indptr = np.zeros(self.n + 1, dtype=self.indptr.dtype)
        np.cumsum(np.bincount(rows, minlength=self.n), out=indptr[1:])
        return CSR(indptr, self.indices[keep], self.data[keep])

    def scipy(self):
        """The same matrix for scipy (imports scipy).

        Returns:
            A scipy.sparse.csr_matrix of shape (n, n) sharing these arrays.
        """
        import scipy.sparse as sp
        return sp.csr_matrix((self.data, self.indices, self.indptr), shape=(self.n, self.n))


def gather_csr(K: PETSc.Mat, comm) -> CSR | None:
    """The global matrix K as CSR arrays on rank 0 (collective).

    Args:
        K: a distributed PETSc AIJ matrix (each rank owns a contiguous block of rows).
        comm: K's MPI communicator.

    Returns:
        On rank 0, the CSR of the whole matrix (rows in global order); None elsewhere.
    """
    indptr, indices, data = K.getValuesCSR()
    # one rank: no gather, which pickles the arrays (docs/performance.md, section 3)
    if comm.size == 1:
        return CSR(indptr, indices, data)
    parts = comm.gather((indptr, indices, data), root=0)
    if comm.rank != 0:
        return None
    ptr = [np.zeros(1, dtype=np.int64)]
    offset = 0
    for p, _, _ in parts:
        ptr.append(np.asarray(p[1:], dtype=np.int64) + offset)
        offset += int(p[-1])
    return CSR(np.concatenate(ptr), np.concatenate([i for _, i, _ in parts]),
               np.concatenate([d for _, _, d in parts]))


def _interior_graph(A: CSR, I: np.ndarray, bs: int) -> tuple[np.ndarray, np.ndarray]:
    """The graph (CSR indptr, indices) of the nonzero entries of A_II (stored zeros, e.g.
    the couplings of Dirichlet rows, left out), or with bs > 1 of its nodes (the bs x bs
    blocks of I = whole nodes, in order)."""
    n = A.n
    pos = np.full(n, -1, dtype=np.int64)
    pos[I] = np.arange(len(I))
    rows = np.repeat(pos, np.diff(A.indptr))
    cols = pos[A.indices]
    keep = (rows >= 0) & (cols >= 0) & (A.data != 0)
    rows, cols = rows[keep] // bs, cols[keep] // bs
    nn = len(I) // bs
    if bs > 1:                  # a node pair once (sorted); bs = 1: A's rows are sorted already
        key = rows * nn + cols
        key = key[np.r_[True, key[1:] != key[:-1]]]      # the runs within a dof row first
        key = np.unique(key)
        rows, cols = key // nn, key % nn
    indptr = np.zeros(nn + 1, dtype=PETSc.IntType)
    np.cumsum(np.bincount(rows, minlength=nn), out=indptr[1:])
    return indptr, cols.astype(PETSc.IntType)


def _metis_order(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray | None:
    """CHOLMOD's fill-reducing order of a symmetric graph (AMD or METIS, postordered:
    kernels/cholmod_ldl.c), or None where CHOLMOD is not available or fails.  Vertices with
    no neighbour (the Dirichlet dofs, whose couplings are stored zeros) come first: they
    cause no fill.  This order of the nodal graph costs about what CHOLMOD's own order of the
    dof matrix does, a fraction of PETSc's nested dissection (docs/performance.md, section
    9)."""
    from vpcontact.solvers import ldl
    module = ldl.load()
    if module is None:
        return None
    n = len(indptr) - 1
    rows = np.repeat(np.arange(n), np.diff(indptr))
    linked = np.zeros(n, dtype=bool)
    linked[rows[rows != indices]] = True
    keep = np.flatnonzero(linked)
    pos = np.full(n, -1, dtype=np.int64)
    pos[keep] = np.arange(len(keep))
    sel = linked[rows]
    sub_rows, sub_cols = pos[rows[sel]], pos[indices[sel]]
    ptr = np.zeros(len(keep) + 1, dtype=np.intc)
    np.cumsum(np.bincount(sub_rows, minlength=len(keep)), out=ptr[1:])
    ind = np.ascontiguousarray(sub_cols, dtype=np.intc)
    perm = np.empty(len(keep), dtype=np.intc)
    ffi = module.ffi
    if module.lib.metis_order(len(keep), ffi.from_buffer("int[]", ptr),
                              ffi.from_buffer("int[]", ind), ffi.from_buffer("int[]", perm)):
        return None
    return np.concatenate([np.flatnonzero(~linked), keep[perm]]).astype(PETSc.IntType)


def interior_last_ordering(A: CSR, G: np.ndarray, bs: int = 1) -> np.ndarray:
    """A fill-reducing order of the dofs with G (in the given order) last: CHOLMOD's order
    (AMD or METIS, postordered; PETSc's nested dissection without CHOLMOD) of the interior
    block K_II, then G.  With bs > 1 and an interior made of whole
    nodes (dofs bs i .. bs i + bs - 1), the dissection is of the node graph and a node's dofs
    stay consecutive (the blocks of kernels.GLastSolve).

    Args:
        A: the matrix K (its nonzero pattern is used).
        G: the Gamma3 dofs, shape (m,), in the order they get at the end.
        bs: the block size (dofs per node).

    Returns:
        The permutation: position i holds dof ``order[i]``, shape (n,), G last.
    """
    n = A.n
    interior = np.ones(n, dtype=bool)
    interior[G] = False
    I = np.flatnonzero(interior)
    nodal = bs > 1 and n % bs == 0 and len(I) % bs == 0 and np.array_equal(
        I.reshape(-1, bs), I[::bs, None] + np.arange(bs))
    indptr, indices = _interior_graph(A, I, bs if nodal else 1)
    order = _metis_order(indptr, indices)
    if order is None:
        M = PETSc.Mat().createAIJ((len(indptr) - 1,) * 2,
                                  csr=(indptr, indices, np.ones(len(indices))),
                                  comm=PETSc.COMM_SELF)
        rperm, cperm = M.getOrdering("nd")
        order = rperm.getIndices()
        for obj in (M, rperm, cperm):
            obj.destroy()
    if nodal:
        order = (order[:, None] * bs + np.arange(bs)).ravel()
    return np.concatenate([I[order], np.asarray(G)])


class GLastLU:
    """K = L U with the dofs ordered interior first (fill-reducing), G last (serial,
    SuperLU on the CSR arrays).  ``perm[i]`` is the dof at position i; ``L``, ``U`` are scipy
    CSC matrices; ``Lp``, ``Li``, ``Lx`` the arrays of L and ``D`` = diag(U).

    Args:
        A: the symmetric positive definite matrix K.
        G: the Gamma3 dofs, shape (m,), ordered last.
        bs: the block size (dofs per node), for the interior ordering.

    Raises:
        RuntimeError: SuperLU permuted rows or columns (the trailing blocks would not be G's).
    """

    def __init__(self, A: CSR, G: np.ndarray, bs: int = 1):
        import scipy.sparse.linalg as sla
        self.n, self.m = A.n, len(G)
        self.perm = interior_last_ordering(A, G, bs)
        Ap = A.without_zeros().scipy()[self.perm][:, self.perm].tocsc()
        # diag_pivot_thresh = 0: the diagonal pivots of the symmetric positive definite K in
        # the given order (no row interchanges, so the trailing blocks are those of G)
        lu = sla.splu(Ap, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                      options=dict(SymmetricMode=True))
        if not (np.array_equal(lu.perm_r, np.arange(self.n))
                and np.array_equal(lu.perm_c, np.arange(self.n))):
            raise RuntimeError("SuperLU permuted the G-last ordering")
        self.L, self.U = lu.L.tocsc(), lu.U.tocsc()
        self.L.sort_indices()
        self.Lp, self.Li, self.Lx = self.L.indptr, self.L.indices, self.L.data
        self.D = self.U.diagonal()        # U = D L^T to round-off (K symmetric, no pivoting)

    def trailing(self) -> tuple[np.ndarray, np.ndarray]:
        """The trailing blocks of the factors, whose product is the Schur complement S.

        Returns:
            (L_GG, U_GG): dense (m, m), unit lower and upper triangular, S = L_GG U_GG.
        """
        k = self.n - self.m
        return self.L[k:, k:].toarray(), self.U[k:, k:].toarray()


class GLastLDL:
    """K = L D L^T by CHOLMOD (app/solvers/ldl.py) in the same order as GLastLU (interior by nested
    dissection, G last): half the work of an L U factorisation (docs/performance.md,
    section 3).  ``D``: the pivots; ``blocks``: the interior columns of L in blocks, ready
    for kernels.GLastSolve (ldl.Factor); U = D L^T.

    Args:
        A: the symmetric positive definite matrix K.
        G: the Gamma3 dofs, shape (m,), ordered last.
        bs: the block size (dofs per node).
        module: the CHOLMOD wrapper module (``ldl.load()``).
        blocks: whether to prepare the interior blocks for the split solve.

    Raises:
        RuntimeError: CHOLMOD failed.
    """

    def __init__(self, A: CSR, G: np.ndarray, bs: int, module, blocks: bool = True):
        from vpcontact.solvers.ldl import Factor
        self.n, self.m = A.n, len(G)
        self.perm = interior_last_ordering(A, G, bs)
        # the factor's pattern is the ordering's graph: no stored zeros (with them, the
        # Dirichlet dofs' couplings fill; docs/performance.md, section 9)
        A = A.without_zeros()
        self._factor = Factor(module, A.indptr, A.indices, A.data, self.perm, self.m, bs,
                              blocks=blocks)
        self.D, self.blocks = self._factor.D, self._factor.blocks

    @property
    def L_GG(self) -> np.ndarray:
        """The trailing block of L: dense (m, m), unit lower triangular."""
        return self._factor.L_GG

    def trailing(self) -> tuple[np.ndarray, np.ndarray]:
        """The trailing blocks of the factors, as GLastLU.trailing gives them.

        Returns:
            (L_GG, U_GG = D_G L_GG^T): dense (m, m), S = L_GG U_GG.
        """
        return self.L_GG, self.D[self.n - self.m:, None] * self.L_GG.T

    def release_L_GG(self) -> np.ndarray:
        """L_GG's memory for the caller to overwrite (the Schur pair's work array: pages
        touched already, where a fresh m x m array costs its page faults; docs/performance.md,
        section 7); L_GG and ``trailing`` are gone afterwards.

        Returns:
            L_GG, dense (m, m), Fortran order.
        """
        L, self._factor.L_GG = self._factor.L_GG, None
        return L


def g_last_factor(A: CSR, G: np.ndarray, bs: int = 1, blocks: bool = True):
    """Factorise K with G last: CHOLMOD's L D L^T if it is available here (and succeeds),
    else SuperLU's L U (same order).

    Args:
        A: the symmetric positive definite matrix K (on one rank).
        G: the Gamma3 dofs, shape (m,), ordered last.
        bs: the block size (dofs per node).
        blocks: False: only for the Schur complement (no blocks for the split solve).

    Returns:
        A GLastLDL or a GLastLU.
    """
    from vpcontact.solvers import ldl
    module = ldl.load()
    if module is not None:
        try:
            return GLastLDL(A, G, bs, module, blocks)
        except RuntimeError as exc:
            log.warning("CHOLMOD failed (%s); factorising with SuperLU", exc)
    return GLastLU(A, G, bs)


LAPACK_MIN = 600    # Gamma3 dofs above which scipy's LAPACK (slow to import) pays off


def schur_pair(factor: GLastLU | GLastLDL) -> tuple[np.ndarray, np.ndarray]:
    """The Schur complement S = L_GG U_GG and its Cholesky factor C (S = C C^T) from a
    G-last factorisation.

    Args:
        factor: a GLastLU or GLastLDL of K.

    Returns:
        (S, C): S dense (m, m), symmetric; C lower triangular, Fortran order.

    Raises:
        np.linalg.LinAlgError: S is not positive definite.
    """
    if isinstance(factor, GLastLDL) and factor.m > LAPACK_MIN:
        pair = _schur_pair_cholesky(factor)
        if pair is not None:
            return pair
    L_GG, U_GG = factor.trailing()
    S = L_GG @ U_GG
    S = 0.5 * (S + S.T)
    return S, np.asfortranarray(np.linalg.cholesky(S))


def _schur_pair_cholesky(factor: GLastLDL) -> tuple[np.ndarray, np.ndarray] | None:
    """C = L_GG D_G^1/2 is S's Cholesky factor, and S = C C^T by LAPACK's triangular
    product (dlauum: m^3/3 flops, against 2 m^3 for a general product; docs/performance.md,
    section 9).

    Returns:
        (S, C), or None if a pivot of D_G is not positive (K not positive definite there;
        the factor's L_GG is then untouched, else it is consumed).
    """
    from scipy.linalg.lapack import dlauum

    from vpcontact.threads import blas_threads
    D_G = factor.D[factor.n - factor.m:]
    if not np.all(D_G > 0):
        return None
    C = np.multiply(factor.L_GG, np.sqrt(D_G)[None, :], order="F")     # L_GG: Fortran
    # C C^T = J (U U^T) J with U = J C J upper triangular, J the reversal, written over
    # L_GG (no longer needed); LAPACK writes one triangle and leaves the other as given
    # (zero here)
    U = factor.release_L_GG()
    np.copyto(U, C[::-1, ::-1])
    with blas_threads(large=True):
        U, info = dlauum(U, lower=0, overwrite_c=1)
    if info != 0:                   # an illegal argument: LAPACK's only failure here
        raise RuntimeError(f"LAPACK dlauum: info {info}")
    return symmetric_in_place(U), C


def spd_cholesky(S: np.ndarray) -> np.ndarray | None:
    """The Cholesky factor C of a symmetric positive definite S (S = C C^T), by LAPACK's
    dpotrf (with the run's BLAS threads for the large ones).

    Args:
        S: dense (m, m), symmetric.

    Returns:
        C, lower triangular, Fortran order; None if S is not positive definite.
    """
    from scipy.linalg.lapack import dpotrf

    from vpcontact.threads import blas_threads
    with blas_threads(large=len(S) > LAPACK_MIN):
        C, info = dpotrf(S, lower=1, clean=1)
    return C if info == 0 else None


def mirror_upper(U: np.ndarray, block: int = 256) -> None:
    """Set U's strict lower triangle to the transpose of its upper one, in place, block by
    block (each block transposed in cache): U becomes symmetric.

    Args:
        U: (m, m), any memory order (a view of it is written).
        block: the order of the transposed blocks.
    """
    m = len(U)
    for i in range(0, m, block):
        diag = U[i:i + block, i:i + block]
        lower = np.tril_indices(len(diag), -1)
        diag[lower] = diag.T[lower]
        for j in range(i + block, m, block):
            U[j:j + block, i:i + block] = U[i:i + block, j:j + block].T


def symmetric_in_place(U: np.ndarray, block: int = 256, chunk: int = 1 << 16) -> np.ndarray:
    """J (U + U^T - diag U) J, J the reversal, in U's own memory: the S of
    ``_schur_pair_cholesky`` from dlauum's upper triangle without a new m x m array (whose
    first touch costs page faults; docs/performance.md, section 7).

    U's lower triangle is filled from its upper one (``mirror_upper``), and then the
    reversed matrix is U's memory read backwards: for a symmetric A in Fortran order,
    (J A J)[i, j] = A[m-1-j, m-1-i] lies at position m^2 - 1 - (i m + j), so reversing the
    m^2 values in place, chunk by chunk, gives J A J in C order.

    Args:
        U: (m, m), Fortran order, the upper triangle given (the lower one is overwritten).
        block: the order of the transposed blocks.
        chunk: the values swapped per step of the reversal.

    Returns:
        The symmetric matrix, C order, a view of U's memory (U is consumed).
    """
    m = len(U)
    mirror_upper(U, block)
    flat = U.reshape(-1, order="F")                   # a view: U is Fortran-contiguous
    n, tmp = len(flat), np.empty(min(chunk, len(flat) // 2 + 1))
    for i in range(0, n // 2, chunk):
        k = min(chunk, n // 2 - i)
        t = tmp[:k]
        t[:] = flat[i:i + k]
        flat[i:i + k] = flat[n - i - k:n - i][::-1]
        flat[n - i - k:n - i] = t[::-1]
    return flat.reshape(m, m)


def gamma3_schur_pair(K: PETSc.Mat, G_rows: np.ndarray, comm) -> tuple | None:
    """The Gamma3 Schur complement S and its Cholesky factor C (collective; factorised on
    rank 0).

    Args:
        K: the assembled stiffness matrix (PETSc, distributed).
        G_rows: the global matrix rows of the Gamma3 dofs, shape (m,).
        comm: K's MPI communicator.

    Returns:
        (S, C) as ``schur_pair``'s, rows/columns in the order of ``G_rows``, on rank 0
        (None on the others: the Gamma3 problem is solved there).
    """
    A = gather_csr(K, comm)
    return schur_pair(g_last_factor(A, np.asarray(G_rows), blocks=False)) \
        if comm.rank == 0 else None
