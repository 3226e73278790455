"""The explicit Perzyna update (3.2)-(3.3) compiled (perzyna.c).

The explicit Perzyna update in numpy (whole-array Newton iterations on the secular equation,
temporaries) took more than the two back-substitutions of the fast solver.  The same algorithm
as material.VonMisesProjection, one cell at a time in C, is several times faster
(docs/performance.md, section 4).  The law's numpy update (app/model/laws.py: ExplicitUpdate
from Perzyna.rates) stays the reference (tests/unit/test_kernels.py compares them) and the
fallback when no C compiler is available.
The kernel knows no law object: its data (E, the von Mises form, the projection's
eigenbasis, the coordinates' positions in the tensor) are passed in.  It takes one E for
every cell (isotropic or any homogeneous matrix: Elasticity, MatrixElasticity); for E per
cell (CellElasticity) Perzyna's law uses the numpy update (ExplicitUpdate, with the batched
CellProjection).
"""
from __future__ import annotations

import numpy as np

from vpcontact.kernels.build import buf
from vpcontact.kernels.cells import split_threads


class PerzynaKernel:
    """perzyna_advance for one Perzyna law, on flat DG0 arrays.  Each cell's
    secular-equation root is kept between calls as the next call's start (``mu``): the
    roots change little from step to step (docs/performance.md, section 4).

    Args:
        law: the elasticity: its ``dim``, ``m``, ``Cmat`` and von Mises form ``M``.
        projection: its von Mises projection: ``AV``, ``V``, ``lam`` and the ``groups`` of
            equal eigenvalues.
        lambda1: the viscosity lambda1 of the Perzyna law.
        lambda2: the hardening parameter lambda2 of the Perzyna law.
        module: the compiled kernels (kernels.load()).
        flat: the flat (row-major d x d) positions of the t-coordinates.
        from_: for each tensor entry, its t-coordinate.
        rtol: the relative tolerance of the secular equation's root.
        max_iter: the most Newton sweeps over the cells.
    """

    def __init__(self, law, projection, lambda1: float, lambda2: float, module, flat, from_,
                 rtol: float = 1e-14, max_iter: int = 100):
        d = law.dim
        self.mod, self.d, self.m = module, d, law.m
        self.l1, self.l2, self.rtol, self.max_iter = lambda1, lambda2, rtol, max_iter
        c = np.ascontiguousarray
        self.C, self.M = c(law.Cmat, dtype=float), c(law.M, dtype=float)
        self.AV, self.V = c(projection.AV, dtype=float), c(projection.V, dtype=float)
        self.lam = c(projection.lam, dtype=float)
        self.flat = c(flat, dtype=np.intc)
        self.from_ = c(from_, dtype=np.intc)
        self.glam = c([projection.lam[g[0]] for g in projection.groups], dtype=float)
        self.GM = np.zeros((len(self.glam), self.m))       # GM[g, j] = 1: lam_j in group g
        for i, g in enumerate(projection.groups):
            self.GM[i, g] = 1.0
        self._work = None
        self.mu = None

    def advance(self, sigma: np.ndarray, H: np.ndarray, kappa: np.ndarray, k: float,
                threads: int = 1) -> int:
        """H += k Gfun(sigma, kappa), kappa += k Gk(sigma, kappa) in place: one explicit step
        of (3.2)-(3.3) (numpy reference: the law's ExplicitUpdate).

        Args:
            sigma: sigma per cell, flat contiguous float64 (ncells * d * d).
            H: the history tensor per cell, same layout, updated.
            kappa: the hardening variable per cell (ncells), updated.
            k: the time step.
            threads: 2 splits the cells between two threads (``split_threads``; the
                same results: a cell's update does not depend on the others).

        Returns:
            The number of cells whose root search did not converge (then H and kappa are
            left as they were), else 0.

        Raises:
            TypeError: if an array is not contiguous float64.
            ValueError: if the sizes do not match.
        """
        ffi, lib = self.mod.ffi, self.mod.lib
        for a in (sigma, H, kappa):
            if a.dtype != np.float64 or not a.flags.c_contiguous:
                raise TypeError("kernel arrays must be contiguous float64")
        n = len(kappa)
        if sigma.size != n * self.d ** 2 or H.size != n * self.d ** 2:
            raise ValueError("sigma, H and kappa sizes do not match")
        if self._work is None or len(self.mu) != n:
            self._work = np.empty(max(n, 1) * (self.m + 6 + len(self.glam)))
            self.mu = np.zeros(n)
        return lib.perzyna_advance(
            n, self.d ** 2, self.m, buf(ffi, sigma), buf(ffi, H), buf(ffi, kappa), k, self.l1,
            self.l2, buf(ffi, self.C), buf(ffi, self.M), buf(ffi, self.AV), buf(ffi, self.V),
            buf(ffi, self.lam), buf(ffi, self.flat), buf(ffi, self.from_), self.rtol,
            self.max_iter, len(self.glam), buf(ffi, self.glam), buf(ffi, self.GM),
            buf(ffi, self._work), buf(ffi, self.mu), split_threads(threads, n))
