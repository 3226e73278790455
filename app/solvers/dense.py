"""The projected Newton direction of the condensed solver's Gamma3 problem
(app/solvers/condensed/problem.py).

Each Newton iteration of the step problem on Gamma3 solves
    (S + W)_ff p_f = -g_f,   p = 0 on the binding dofs,
with S the (dense, m x m) Schur complement, W the nodal d x d Hessian blocks of the contact
energy and f the free dofs (not held at the bound u_nu <= g).  The matrix is positive
definite where the step energy is strictly convex ((2.6)), so it is factorised by Cholesky.

The compiled version (kernels/dense.c with cffi, LAPACK's dpotrf/dpotrs) gathers the free
block straight from S and the nodal blocks, so only the nf x nf block is built and
factorised: a fraction of the flops of factorising the whole m x m matrix with the binding
rows replaced by the identity (docs/performance.md, section 4), and no copy of S per
iteration.
Without a C compiler or LAPACK the same direction is computed with numpy
(``NewtonDirection._numpy``, the tests' reference).

Large Gamma3 problems (m >= PCG_MIN, 3D) keep the last factor: the Newton matrix of the next
iteration (or step) differs from it by the change of the nodal blocks W and of a few binding
dofs, so preconditioned CG with the kept factor solves it in a few matrix-vector products
(O(m^2) each) instead of a new O(m^3) factorisation (docs/performance.md, section 7).  The
Newton iteration asks for the accuracy it needs (an inexact Newton method: relative residual
``rtol``, down to its own convergence); where CG needs more than PCG_MAX_ITERATIONS, or too many
dofs changed their binding state, the matrix is factorised afresh.
"""
from __future__ import annotations

import numpy as np

from vpcontact import kernels
from vpcontact.threads import blas_threads

PCG_MIN = 1000              # Gamma3 dofs from which the factor is kept and reused by CG
PCG_MAX_ITERATIONS = 15     # CG iterations worth about one factorisation (m ~ 3000)
PCG_MAX_CHANGED = 60        # dofs whose binding state changed since the factorisation

DENSE = kernels.Library("_vpcontact_dense", ("dense",), "compiled Newton direction (using numpy)",
                        libraries=("lapack", "blas"))


def load():
    """The compiled Newton direction (kernels/dense.c, linked to LAPACK).

    Returns:
        The cffi module (``.lib``, ``.ffi``), or None (numpy is used then).
    """
    return DENSE.load()


def cholesky_solve(C: np.ndarray, r: np.ndarray) -> np.ndarray:
    """S^-1 r from S's Cholesky factor C: two triangular solves by BLAS trsv in C's precision,
    through the compiled library where it is built (no scipy import in a 2D run), else
    scipy's.  LAPACK's potrs goes through the matrix-matrix trsm, about twice as slow in
    double and four times in single precision (docs/performance.md, section 9).

    Args:
        C: lower triangular (m, m), Fortran order, float64 or float32 (only the lower
            triangle is read).
        r: the right-hand side (m,).

    Returns:
        S^-1 r (a new array, C's dtype).
    """
    x = np.array(r, dtype=C.dtype)
    mod = load()
    if mod is not None and C.flags.f_contiguous:
        solve = mod.lib.cholesky_solve_d if C.dtype == np.float64 else mod.lib.cholesky_solve_s
        solve(len(C), kernels.buf(mod.ffi, C.T), kernels.buf(mod.ffi, x))   # C.T: C order
        return x
    from scipy.linalg.blas import get_blas_funcs
    trsv = get_blas_funcs("trsv", (C,))
    y = trsv(C, x, lower=1, overwrite_x=1)                         # C y = r
    return trsv(C, y, lower=1, trans=1, overwrite_x=1)             # C^T x = y


def symmetric_product(S: np.ndarray):
    """x -> S x for a symmetric S: from PCG_MIN dofs by BLAS dsymv, which reads one triangle
    (the product is bound by memory traffic; docs/performance.md, section 7), else numpy's
    product.

    Args:
        S: dense (m, m), symmetric, C order (exactly symmetric: one triangle is read).

    Returns:
        The product, a function of x (m,).
    """
    if len(S) < PCG_MIN:
        return S.__matmul__
    from scipy.linalg.blas import dsymv
    St = S.T                          # Fortran order, no copy
    return lambda x: dsymv(1.0, St, x, lower=1)


class _Kept:
    """The kept Cholesky factor of (S + W)_ff, in single precision: L (nf x nf, lower,
    Fortran order), the free dofs f and every dof's position in f (-1 if binding).  It only
    preconditions CG, and its triangular solves are bound by memory traffic: in single
    precision they take half the time, and by BLAS strsv (cholesky_solve) rather than
    LAPACK's spotrs a quarter (docs/performance.md, sections 7 and 9)."""

    def __init__(self, L: np.ndarray, free: np.ndarray, m: int):
        # only the lower triangle is L (cholesky_solve reads no other); the compiled
        # kernel leaves its work in the strict upper one, whose values may not fit a float32
        with np.errstate(over="ignore"):
            self.L = np.asfortranarray(L, dtype=np.float32)
        self.free = free
        self.pos = np.full(m, -1, dtype=np.intp)
        self.pos[free] = np.arange(len(free))


class ProjectedDirection:
    """p = -(S + the contact Hessian)_ff^-1 g_f on the free dofs, 0 on the binding ones, for
    a fixed S: a new factorisation (``_factorise``, the subclass's), and from PCG_MIN dofs CG
    preconditioned by the kept factor while it converges within PCG_MAX_ITERATIONS and few
    dofs changed their binding state.  A subclass gives ``_factorise`` and the contact
    Hessian's diagonal and product (``_contact``); it sets S, m, product (x -> S x), _kept
    and the counts ``factorisations`` and ``cg_iterations``.
    """

    def __call__(self, W: np.ndarray, g: np.ndarray, binding: np.ndarray,
                 rtol: float = 0.0) -> np.ndarray | None:
        """The projected Newton direction.

        Args:
            W: the nodal Hessian blocks of the contact energy (nodes, d, d).
            g: the gradient (m).
            binding: True at the dofs held at their bound (p = 0 there).
            rtol: the relative residual the direction needs (0: exact, by a factorisation);
                with m >= PCG_MIN, CG with the kept factor is tried first.

        Returns:
            The direction (a new array), or None if the free block of the Newton matrix is
            not positive definite.
        """
        free = np.flatnonzero(~binding).astype(np.intc)
        with blas_threads(large=len(free) >= PCG_MIN):
            if rtol > 0 and self._kept is not None:
                p = self._pcg(W, g, free, rtol)
                if p is not None:
                    return p
            return self._factorise(W, g, free)

    def _pcg(self, W, g, free, rtol):
        """CG on the free block p_f = -g_f preconditioned by the kept factor (on the dofs
        free then and now; the diagonal on those free only now); None where it does not
        converge within PCG_MAX_ITERATIONS or the matrix is not positive definite there."""
        kept, m = self._kept, self.m
        pos = kept.pos[free]
        both = pos >= 0
        if (len(free) - both.sum()) + (len(kept.free) - both.sum()) > PCG_MAX_CHANGED:
            return None
        w_diagonal, w_product = self._contact(W)
        diag = self.S[free, free] + w_diagonal(free)
        q = np.zeros(len(kept.free), dtype=np.float32)

        def precondition(r):
            q[:] = 0.0
            q[pos[both]] = r[both]
            z = r / diag
            z[both] = cholesky_solve(kept.L, q)[pos[both]]
            return z

        def product(x):
            xm = np.zeros(m)
            xm[free] = x
            y = self.product(xm) + w_product(xm)
            return y[free]
        x, its = _cg(product, precondition, -g[free], rtol, PCG_MAX_ITERATIONS)
        self.cg_iterations += abs(its)
        if its < 0:
            return None
        out = np.zeros(m)
        out[free] = x
        return out


class NewtonDirection(ProjectedDirection):
    """p = -(S + W)_ff^-1 g_f on the free dofs, 0 on the binding ones, for a fixed S.

    Args:
        S: the Schur complement (m x m, symmetric).
        d: the dofs per node (W's blocks are d x d).
        module: the compiled Newton direction (``load()``), or None: numpy
            (``_numpy``).

    Counts ``factorisations`` and ``cg_iterations`` (with the kept factor, m >= PCG_MIN).
    """

    def __init__(self, S: np.ndarray, d: int, module=None):
        self.S, self.d, self.m = np.ascontiguousarray(S, dtype=float), d, S.shape[0]
        self.mod = module
        self.p = np.empty(self.m)
        self.work = np.empty(self.m * (self.m + 1))
        n = self.m // d
        node = np.repeat(np.arange(n), d * d)         # numpy: (row, column) of every W entry
        a, b = np.tile(np.repeat(np.arange(d), d), n), np.tile(np.arange(d), d * n)
        self._rows, self._cols = node * d + a, node * d + b
        self.product = symmetric_product(self.S)    # x -> S x
        self._kept: _Kept | None = None
        self.factorisations = self.cg_iterations = 0
        if module is not None:
            self._S, self._p, self._work = (kernels.buf(module.ffi, x)
                                            for x in (self.S, self.p, self.work))

    def _factorise(self, W, g, free):
        """The direction by a new Cholesky factorisation (kept where m >= PCG_MIN)."""
        self.factorisations += 1
        self._kept = None
        if self.mod is None:
            return self._numpy(W, g, free)
        ffi, buf = self.mod.ffi, kernels.buf
        info = self.mod.lib.newton_direction(
            self.m, self.d, self._S, buf(ffi, np.ascontiguousarray(W, dtype=float)),
            buf(ffi, free), len(free), buf(ffi, np.ascontiguousarray(g, dtype=float)),
            self._p, self._work)
        if info != 0:
            return None
        if self.m >= PCG_MIN:            # work holds L column by column: a Fortran view
            nf = len(free)
            self._kept = _Kept(self.work[:nf * nf].reshape(nf, nf).T, free, self.m)
        return self.p.copy()

    def _contact(self, W):
        """(free -> W's diagonal there, x -> W x) of the nodal blocks W."""
        Wd = np.asarray(W, dtype=float)
        return (lambda free: Wd.reshape(-1, self.d * self.d)[
            free // self.d, (free % self.d) * (self.d + 1)],
            lambda x: np.einsum("nij,nj->ni", Wd, x.reshape(-1, self.d)).ravel())

    def matrix(self, W: np.ndarray) -> np.ndarray:
        """S + W.

        Args:
            W: the nodal Hessian blocks (m / d, d, d).

        Returns:
            S + W (a new m x m array).
        """
        H = self.S.copy()
        H[self._rows, self._cols] += np.asarray(W).ravel()
        return H

    def _numpy(self, W, g, free):
        """The direction by numpy's Cholesky factorisation (the compiled kernel's reference)."""
        H = self.matrix(W)
        Hff = H[np.ix_(free, free)]
        try:
            L = np.linalg.cholesky(Hff)
        except np.linalg.LinAlgError:
            return None
        p = np.zeros(self.m)
        p[free] = -np.linalg.solve(L.T, np.linalg.solve(L, g[free]))
        if self.m >= PCG_MIN:
            self._kept = _Kept(np.asfortranarray(L), free, self.m)
        return p


def _cg(product, precondition, b, rtol, max_iterations):
    """Preconditioned conjugate gradients for A x = b from x = 0.

    Args:
        product: x -> A x (symmetric).
        precondition: r -> M^-1 r (symmetric positive definite).
        b: the right-hand side.
        rtol: stop at |r| <= rtol |b| (2-norms).
        max_iterations: the iteration limit.

    Returns:
        (x, iterations), iterations negated if the limit was reached or A is not positive
        definite on the Krylov space.
    """
    x, r = np.zeros_like(b), b.copy()
    tol = rtol * np.linalg.norm(b)
    if np.linalg.norm(r) <= tol:
        return x, 0
    z = precondition(r)
    p, rz = z.copy(), r @ z
    for it in range(1, max_iterations + 1):
        Ap = product(p)
        pAp = p @ Ap
        if not pAp > 0:
            return x, -it
        alpha = rz / pAp
        x += alpha * p
        r -= alpha * Ap
        if np.linalg.norm(r) <= tol:
            return x, it
        z = precondition(r)
        rz, rz_old = r @ z, rz
        p = z + (rz / rz_old) * p
    return x, -max_iterations
