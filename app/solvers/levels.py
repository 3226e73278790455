"""GAMG's multigrid levels kept between Newton iterations, with the finest level applied in
PETSc's symmetric block format.

``InactiveSetAMG`` (app/solvers/amg.py) lets GAMG build its interpolation once per step.  The
later set-ups of the step only recompute the coarse operators A_{l-1} = P_l^T A_l P_l
(Galerkin) and the smoothers; ``GalerkinLevels`` does that itself (MatPtAP into the kept
products, then every level's smoother handed its operator again: Chebyshev re-estimates its
eigenvalues, Jacobi takes the new diagonal, the coarse LU refactors) instead of GAMG's
set-up, which resets the finest smoother to Jt.  So the finest smoother and residual can
apply ``SymmetricCopy``, Jt in the SBAIJ format (3 x 3 blocks, upper triangle), whose
product costs well under half the AIJ one (docs/performance.md, section 7): the smoother's
four products and the residual's one per V-cycle are most of the Krylov time.  GAMG itself
needs AIJ (its graph), so Jt stays AIJ for the set-ups and the
copy's values are gathered from it (one numpy take per set-up).  Serial only: under MPI the
finest level applies Jt (AIJ) as before.
"""
from __future__ import annotations

import ctypes
from contextlib import contextmanager

import numpy as np
from petsc4py import PETSc

from vpcontact.native import loaded_libraries

_LIB = None


def libpetsc() -> ctypes.CDLL:
    """The PETSc library petsc4py runs on (found in this process's memory map).

    Returns:
        The library for the few calls petsc4py 3.18 does not wrap (array access of the
        SeqAIJ and SeqSBAIJ formats, PCMGSetResidual).
    """
    global _LIB
    if _LIB is None:
        paths = loaded_libraries("libpetsc")
        if not paths:
            raise RuntimeError("the PETSc library is not in this process's memory map")
        _LIB = ctypes.CDLL(paths[0])
    return _LIB


def _array(mat: PETSc.Mat, n: int, get: str) -> tuple[np.ndarray, ctypes.c_void_p]:
    """A numpy view of a sequential matrix's value array (PETSc's <get> function)."""
    ptr = ctypes.POINTER(ctypes.c_double)()
    handle = ctypes.c_void_p(mat.handle)
    if getattr(libpetsc(), get)(handle, ctypes.byref(ptr)) != 0:
        raise PETSc.Error(f"{get} failed")
    return np.ctypeslib.as_array(ptr, shape=(n,)), ptr


@contextmanager
def _row_ij(mat: PETSc.Mat):
    """A sequential AIJ matrix's row pointers and column indices, not copied (MatGetRowIJ;
    petsc4py's getRowIJ copies them, a large transient at 3D sizes: docs/performance.md,
    section 9)."""
    lib = libpetsc()
    cint = np.ctypeslib.as_ctypes_type(PETSc.IntType)
    n, done = cint(), ctypes.c_int()
    ia, ja = ctypes.POINTER(cint)(), ctypes.POINTER(cint)()
    args = (ctypes.c_void_p(mat.handle), cint(0), ctypes.c_int(0), ctypes.c_int(0),
            ctypes.byref(n), ctypes.byref(ia), ctypes.byref(ja), ctypes.byref(done))
    if lib.MatGetRowIJ(*args) != 0 or not done.value:
        raise PETSc.Error("MatGetRowIJ failed")
    try:
        indptr = np.ctypeslib.as_array(ia, shape=(n.value + 1,))
        yield indptr, np.ctypeslib.as_array(ja, shape=(int(indptr[-1]),))
    finally:
        lib.MatRestoreRowIJ(*args)


# a matrix A counts as symmetric (an SBAIJ copy may apply it) when |A - A^T| <= this times |A|
SYMMETRY_RTOL = 1e-12


def is_symmetric(A: PETSc.Mat) -> bool:
    """Whether |A - A^T| <= SYMMETRY_RTOL |A| (infinity norms; PETSc's MatIsSymmetric).

    Args:
        A: the matrix.

    Returns:
        True where A counts as symmetric.
    """
    return A.isSymmetric(SYMMETRY_RTOL * A.norm(PETSc.NormType.INFINITY))


class SymmetricCopy:
    """Jt in the SBAIJ format with d x d blocks, its values gathered from the AIJ Jt.

    The AIJ pattern (dolfinx's, with whole d x d blocks: the d rows of a node have the same
    columns) gives, once, for every block of the upper block triangle the AIJ position of
    its first value and its block row's row length; ``update`` gathers the values by
    chunks of CHUNK blocks (two integers per block are kept, not one per value).

    Args:
        Jt: the sequential AIJ matrix, symmetric, with block size d and whole blocks.
        absolute: hold the absolute values of Jt's entries (|Jt|, app/solvers/snesvi.py's
            round-off floor) instead of the values.
    """

    CHUNK = 1 << 16

    def __init__(self, Jt: PETSc.Mat, absolute: bool = False):
        self.absolute = absolute
        self.bs = bs = Jt.getBlockSize()
        t = np.arange(bs * bs)
        self.row, self.col = t % bs, t // bs             # SBAIJ blocks are column-major
        with _row_ij(Jt) as (indptr, indices):
            lengths = np.diff(indptr).reshape(-1, bs)
            if np.any(lengths % bs) or np.any(lengths != lengths[:, :1]):
                raise ValueError("the AIJ pattern is not made of whole blocks")
            self.nnz = indices.size
            mbs = lengths.shape[0]
            parts = [self._blocks(indptr, indices, r, min(r + self.CHUNK, mbs))
                     for r in range(0, mbs, self.CHUNK)]
        self.start = np.concatenate([p[0] for p in parts])
        self.length = np.concatenate([p[1] for p in parts])
        counts = np.concatenate([p[2] for p in parts])
        csr = (np.concatenate([[0], np.cumsum(counts)]).astype(PETSc.IntType),
               np.concatenate([p[3] for p in parts]).astype(PETSc.IntType))
        del parts
        self.mat = PETSc.Mat().createSBAIJ(Jt.getSizes(), bs, csr=csr, comm=Jt.getComm())
        self.mat.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        self.update(Jt)

    def _blocks(self, indptr, indices, first_row: int, end_row: int):
        """Block rows first_row..end_row: their upper blocks' first AIJ positions and row
        lengths, the blocks per block row and the block columns (checked against the AIJ
        columns)."""
        bs = self.bs
        first = indptr[bs * first_row:bs * end_row:bs].astype(np.int64)
        nb = (indptr[bs * first_row + 1:bs * end_row + 1:bs] - first) // bs
        brow = np.repeat(np.arange(end_row - first_row), nb)
        p = np.arange(brow.size) - np.repeat(np.cumsum(nb) - nb, nb)
        bcol = indices[first[brow] + bs * p] // bs
        keep = bcol >= brow + first_row
        brow, bcol, p = brow[keep], bcol[keep], p[keep]
        start, length = first[brow] + bs * p, bs * nb[brow]
        pos = start[:, None] + length[:, None] * self.row + self.col
        if not np.array_equal(indices[pos], bs * bcol[:, None] + self.col):
            raise ValueError("the AIJ pattern is not made of whole blocks")
        dtype = np.int32 if self.nnz < 2**31 else np.int64
        return (start.astype(dtype), length.astype(dtype), np.bincount(brow, minlength=nb.size),
                bcol)

    def update(self, Jt: PETSc.Mat) -> None:
        """Copy Jt's values (its pattern the one of the construction).

        Args:
            Jt: the AIJ matrix.
        """
        lib = libpetsc()
        d = self.bs * self.bs
        a, aptr = _array(Jt, self.nnz, "MatSeqAIJGetArrayRead")
        s, sptr = _array(self.mat, d * self.start.size, "MatSeqSBAIJGetArray")
        try:
            for c in range(0, self.start.size, self.CHUNK):
                start = self.start[c:c + self.CHUNK, None].astype(np.int64)
                pos = start + self.length[c:c + self.CHUNK, None] * self.row + self.col
                chunk = s[d * c:d * (c + pos.shape[0])].reshape(pos.shape)
                np.take(a, pos, out=chunk)
                if self.absolute:
                    np.abs(chunk, out=chunk)
        finally:
            lib.MatSeqSBAIJRestoreArray(ctypes.c_void_p(self.mat.handle), ctypes.byref(sptr))
            lib.MatSeqAIJRestoreArrayRead(ctypes.c_void_p(Jt.handle), ctypes.byref(aptr))
        self.mat.assemble()                          # a new state: the smoother sets up again

    def destroy(self) -> None:
        """Free the SBAIJ matrix."""
        self.mat.destroy()


class FineProduct:
    """The finest Galerkin product A_c = P^T Jt P for a Jt that changes only in the rows of
    ``changing`` and their columns (the Gamma3 dofs: contact terms, the active set) and in
    the rows R that couple to them: A_c = C0 + P_R^T (Jt_R P), with Jt_R = Jt's rows R
    (all columns), P_R = P's rows R and C0 = P^T Jt P - P_R^T (Jt_R P) of the first Jt,
    kept; R is a small part of the rows (docs/performance.md, section 7).
    C0 carries the rounding error of A_c's largest entry; so the first A_c must not exceed
    C0 by more than MAX_RANGE (a stiff compliance: B ~ 1e16 K would leave K's digits in
    it), or ``usable`` is false and the full product is used.

    Args:
        Jt: the embedded Jacobian (AIJ) of the first set-up.
        P: the finest interpolation.
        A_c: the coarse operator GAMG formed from them.
        changing: local rows of Jt whose entries (and columns) may change.
    """

    MAX_RANGE = 1e6

    def __init__(self, Jt: PETSc.Mat, P: PETSc.Mat, A_c: PETSc.Mat, changing: np.ndarray):
        comm = Jt.getComm()
        lo = Jt.getOwnershipRange()[0]
        rows = PETSc.IS().createGeneral(np.asarray(lo + changing, PETSc.IntType), comm=comm)
        every = PETSc.IS().createStride(Jt.getSize()[1], 0, 1, comm=comm)
        coupled = Jt.createSubMatrix(rows, every).getRowIJ()[1]
        R = np.union1d(lo + changing, coupled).astype(PETSc.IntType)
        self.rows = PETSc.IS().createGeneral(R, comm=comm)
        self.every = every
        self.coarse = PETSc.IS().createStride(P.getSize()[1], 0, 1, comm=comm)
        self.P, self.P_R = P, P.createSubMatrix(self.rows, self.coarse)
        self.Jt_R = Jt.createSubMatrix(self.rows, every)
        self.W = self.Jt_R.matMult(P)
        self.G = self.P_R.transposeMatMult(self.W)
        self.C0 = A_c.duplicate(copy=True)
        self.C0.axpy(-1.0, self.G, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        self.usable = A_c.norm(PETSc.NormType.INFINITY) \
            <= self.MAX_RANGE * self.C0.norm(PETSc.NormType.INFINITY)

    def form(self, Jt: PETSc.Mat, A_c: PETSc.Mat) -> None:
        """A_c = C0 + P_R^T (Jt_R P) for this Jt (A_c's pattern is the first one's).

        Args:
            Jt: the embedded Jacobian, changed only in the rows and columns of ``changing``.
            A_c: the coarse operator, overwritten.
        """
        Jt.createSubMatrix(self.rows, self.every, submat=self.Jt_R)
        self.Jt_R.matMult(self.P, result=self.W)
        self.P_R.transposeMatMult(self.W, result=self.G)
        self.C0.copy(A_c, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        A_c.axpy(1.0, self.G, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)

    def destroy(self) -> None:
        """Free the kept matrices and index sets."""
        for obj in (self.rows, self.every, self.coarse, self.P_R, self.Jt_R, self.W, self.G,
                    self.C0):
            obj.destroy()


class GalerkinLevels:
    """The levels of a set-up GAMG PC, recomputed from a new Jt of the same pattern without
    GAMG's set-up (whose interpolation is kept).

    Args:
        inner: the GAMG PC, set up on Jt (AIJ).
        fine: the operator its finest smoother and residual apply (Jt, or its SBAIJ copy).
        changing: local rows of Jt whose entries may change before the next interpolation
            (then the finest product is formed incrementally: ``FineProduct``), or None.
    """

    def __init__(self, inner: PETSc.PC, fine: PETSc.Mat, changing: np.ndarray | None = None):
        self.inner, self.fine = inner, fine
        self.n = inner.getMGLevels()
        self.event = PETSc.Log.Event("vpcontact Galerkin")
        inner.setReusePreconditioner(True)          # GAMG's own set-up never runs again
        top = inner.getMGSmoother(self.n - 1)
        Jt = top.getOperators()[1]
        self.product = None
        if changing is not None and self.n > 1:
            product = FineProduct(Jt, inner.getMGInterpolation(self.n - 1),
                                  inner.getMGSmoother(self.n - 2).getOperators()[1], changing)
            self.product = product if product.usable else product.destroy()
        if fine.handle != Jt.handle:
            if self.n > 1:
                lib = libpetsc()
                level = np.ctypeslib.as_ctypes_type(PETSc.IntType)(self.n - 1)
                if lib.PCMGSetResidual(ctypes.c_void_p(inner.handle), level,
                                       lib.PCMGResidualDefault, ctypes.c_void_p(fine.handle)):
                    raise PETSc.Error("PCMGSetResidual failed")
            top.setOperators(fine, Jt)
            top.setUp()

    def update(self, Jt: PETSc.Mat) -> None:
        """A_{L-1} = Jt, A_{l-1} = P_l^T A_l P_l into the kept matrices, and every level's
        smoother set up for its new operator.

        Args:
            Jt: the embedded Jacobian (AIJ), the pattern of the first set-up.
        """
        self.event.begin()
        A = Jt
        for level in range(self.n - 1, 0, -1):
            B = self.inner.getMGSmoother(level - 1).getOperators()[1]
            if level == self.n - 1 and self.product is not None:
                self.product.form(Jt, B)
            else:
                A.PtAP(self.inner.getMGInterpolation(level), result=B)
            A = B
        self.event.end()
        for level in range(self.n - 1, -1, -1):
            ksp = self.inner.getMGSmoother(level)
            if level == self.n - 1:
                ksp.setOperators(self.fine, Jt)
            else:
                B = ksp.getOperators()[1]
                ksp.setOperators(B, B)
            ksp.setUp()

    def forget_product(self) -> None:
        """From now on form the finest product in full."""
        self.destroy()
        self.product = None

    def destroy(self) -> None:
        """Free the incremental product's matrices."""
        if self.product is not None:
            self.product.destroy()
