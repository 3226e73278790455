"""The projected Newton direction of the fast solver's Gamma3 problem (app/solvers/fast.py).

Each Newton iteration of the step problem on Gamma3 solves
    (S + W)_ff p_f = -g_f,   p = 0 on the binding dofs,
with S the (dense, m x m) Schur complement, W the nodal d x d Hessian blocks of the contact
energy and f the free dofs (not held at the bound u_nu <= g).  The matrix is positive
definite where the step energy is strictly convex ((2.6)), so it is factorised by Cholesky.

The compiled version (kernels/dense.c with cffi, LAPACK's dpotrf/dpotrs) gathers the free
block straight from S and the nodal blocks, so only the nf x nf block is built and
factorised; at h = 1/128 (m = 256, about 180 free dofs) that is a third of the flops of
factorising the whole m x m matrix with the binding rows replaced by the identity, and no
copy of S per iteration.
Without a C compiler or LAPACK the same direction is computed with numpy
(``newton_direction_numpy``, the tests' reference).
"""
from __future__ import annotations

import numpy as np

from app.solvers import kernels

DENSE = kernels.Library("_vpcontact_dense", ("dense",), "compiled Newton direction (using numpy)",
                        libraries=("lapack",))


def load():
    """The compiled Newton direction (kernels/dense.c, linked to LAPACK).

    Returns:
        The cffi module (``.lib``, ``.ffi``), or None (numpy is used then).
    """
    return DENSE.load()


def newton_direction_numpy(H: np.ndarray, g: np.ndarray, free: np.ndarray) -> np.ndarray | None:
    """p_f = -H_ff^-1 g_f by numpy's Cholesky factorisation, p = 0 elsewhere (the reference
    of the C newton_direction).

    Args:
        H: S + W, the Hessian of the Gamma3 problem (m x m).
        g: the gradient (m).
        free: the free dofs (ascending).

    Returns:
        p (a new array), or None if H_ff is not positive definite.
    """
    Hff = H[np.ix_(free, free)]
    p = np.zeros(len(g))
    try:
        L = np.linalg.cholesky(Hff)
    except np.linalg.LinAlgError:
        return None
    p[free] = -np.linalg.solve(L.T, np.linalg.solve(L, g[free]))
    return p


class NewtonDirection:
    """p = -(S + W)_ff^-1 g_f on the free dofs, 0 on the binding ones, for a fixed S.

    Args:
        S: the Schur complement (m x m, symmetric).
        d: the dofs per node (W's blocks are d x d).
        module: the compiled Newton direction (``load()``), or None: numpy
            (``newton_direction_numpy``).
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
        if module is not None:
            self._S, self._p, self._work = (kernels.buf(module.ffi, x)
                                            for x in (self.S, self.p, self.work))

    def __call__(self, W: np.ndarray, g: np.ndarray, binding: np.ndarray) -> np.ndarray | None:
        """The projected Newton direction.

        Args:
            W: the nodal Hessian blocks of the contact energy (m / d, d, d).
            g: the gradient (m).
            binding: True at the dofs held at their bound (p = 0 there).

        Returns:
            The direction (a new array), or None if (S + W)_ff is not positive definite.
        """
        free = np.flatnonzero(~binding).astype(np.intc)
        if self.mod is not None:
            ffi, buf = self.mod.ffi, kernels.buf
            info = self.mod.lib.newton_direction(
                self.m, self.d, self._S, buf(ffi, np.ascontiguousarray(W, dtype=float)),
                buf(ffi, free), len(free), buf(ffi, np.ascontiguousarray(g, dtype=float)),
                self._p, self._work)
            return None if info != 0 else self.p.copy()
        return self._numpy(W, g, free)

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
        return newton_direction_numpy(self.matrix(W), g, free)
