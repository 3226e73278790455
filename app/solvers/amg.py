"""Iterative Newton systems for SNES VI: Krylov (CG) preconditioned by algebraic multigrid
(PETSc GAMG) that knows the rigid body motions of the body.

SNES vinewtonrsls solves, in every Newton iteration, the system on the inactive dofs only: it
extracts the submatrix J_II of the Jacobian (MatCreateSubMatrix) and hands it to the KSP.  The
submatrix carries neither the block size nor the near-nullspace of J, so GAMG would see one
scalar unknown per dof and only the constant vector, and its size changes with the inactive
set, so GAMG would start anew at every change.  ``InactiveSetAMG`` is a PETSc python PC
around a GAMG PC on J's own layout: J with the active rows and columns replaced by the
identity, the rigid body modes Z (in the dofs SNES solves for: R^T Z in the nodal frames on a
curved Gamma3) as near-nullspace, the interpolation built once per step and kept; on one
rank the levels are then kept by app/solvers/levels.py (the finest product formed from the
rows that change, the finest level applied in the SBAIJ format).
The options of the inner PC have the prefix ``<prefix>amg_`` (e.g.
-vpcontact_amg_pc_gamg_threshold 0.02; -vpcontact_amg_pc_type hypre works too, but BoomerAMG
sees no modes and is much slower; docs/performance.md, section 9).
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from vpcontact.solvers.levels import GalerkinLevels, SymmetricCopy, is_symmetric
from vpcontact.solvers.matrices import share_pattern

AMG_PREFIX = "amg_"

# The iterative path's PETSc options (under the solver's prefix); the case's petsc section
# overrides them.  The KSP tolerance is relative to the true residual of the Newton system
# (Newton then contracts at least by ksp_rtol per iteration near the solution).  Unsmoothed
# aggregation (agg_nsmooths 0): the set-up, repeated whenever the inactive set changes,
# costs a third of the smoothed one, for more CG iterations and less time in all.
# Inexact Newton (Eisenstat-Walker forcing, snes_ksp_ew): the Krylov tolerance follows
# Newton's progress, loose far from the solution; SNES's own tolerances decide the
# solution.  Its version 3 (Eisenstat-Walker's choice 2 with two safeguards: the tolerance
# falls no faster than gamma rtol_last^alpha, and it is never tighter than what reaches
# SNES's relative tolerance, snes_rtol ||F_0|| / ||F_k||, so that the last solve does not
# over-solve) takes fewer CG iterations than the default 2.  Aggregation keeps every nonzero
# of the graph (threshold 0, was 0.01) and stops coarsening below 2000 equations
# (coarse_eq_limit, PETSc's default 50), whose LU is cheap: fewer CG iterations.  The
# measurements behind each choice: docs/performance.md, section 7 ("SNES VI with CG + GAMG").
AMG_PETSC = {
    "snes_ksp_ew": True,
    "snes_ksp_ew_version": 3,
    "ksp_type": "cg",
    "ksp_norm_type": "unpreconditioned",
    "ksp_rtol": 1.0e-8,
    "ksp_atol": 0.0,
    "ksp_max_it": 2000,
    "amg_pc_type": "gamg",
    "amg_pc_gamg_type": "agg",
    "amg_pc_gamg_agg_nsmooths": 0,
    "amg_pc_gamg_threshold": 0.0,
    "amg_pc_gamg_square_graph": 1,
    "amg_pc_gamg_coarse_eq_limit": 2000,
    "amg_pc_gamg_reuse_interpolation": True,
    "amg_mg_levels_ksp_type": "chebyshev",
    "amg_mg_levels_pc_type": "jacobi",
    "amg_mg_levels_ksp_max_it": 2,
}

# Options of the direct default (app/solvers/options.DEFAULT_PETSC) that the iterative path drops
# unless the case gives them with other values.
DIRECT_KEYS = ("ksp_type", "pc_type", "pc_factor_mat_solver_type")


def rigid_body_modes(V) -> np.ndarray:
    """The rigid body motions of the P1 vector space V at its owned dofs.

    Args:
        V: the P1 vector FunctionSpace (block size d = 2 or 3).

    Returns:
        (owned dofs, 3 or 6) array: translations, then rotations about the centroid
        (2D: one, 3D: three).
    """
    d = V.dofmap.index_map_bs
    n = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:n, :d]
    x = x - V.mesh.comm.allreduce(x.sum(axis=0)) / max(V.mesh.comm.allreduce(n), 1)
    rotations = [(0, 1)] if d == 2 else [(0, 1), (1, 2), (2, 0)]
    Z = np.zeros((n, d, d + len(rotations)))
    for i in range(d):
        Z[:, i, i] = 1.0
    for k, (i, j) in enumerate(rotations):
        Z[:, i, d + k] = -x[:, j]
        Z[:, j, d + k] = x[:, i]
    return Z.reshape(n * d, -1)


def orthonormal_columns(Z: np.ndarray, comm) -> np.ndarray:
    """Orthonormalise the columns of a row-distributed matrix (by the eigenvectors of the
    Gram matrix).

    Args:
        Z: this rank's rows.
        comm: the communicator the rows are distributed over.

    Returns:
        Z Q W^-1/2 with Z^T Z = Q W Q^T (summed over ranks); directions whose eigenvalue is
        below 1e-12 times the largest (columns dependent on the row restriction) are
        dropped.
    """
    G = comm.allreduce(Z.T @ Z)
    w, Q = np.linalg.eigh(G)
    keep = w > 1e-12 * w.max()
    return Z @ (Q[:, keep] / np.sqrt(w[keep]))


def near_nullspace(Z: np.ndarray, P: PETSc.Mat) -> PETSc.NullSpace:
    """The columns of Z (P's owned rows), orthonormalised, as a PETSc near-nullspace of P.

    Args:
        Z: (owned rows of P, modes) array, e.g. ``rigid_body_modes``.
        P: the operator (its layout and communicator).

    Returns:
        The NullSpace (to set with P.setNearNullSpace).
    """
    Z = orthonormal_columns(Z, P.getComm().tompi4py())
    vectors = []
    for j in range(Z.shape[1]):
        vectors.append(P.createVecLeft())
        vectors[-1].array[:] = Z[:, j]
    return PETSc.NullSpace().create(vectors=vectors, comm=P.getComm())


class InactiveSetAMG:
    """A PETSc python PC for the Newton systems J_II of SNES VI: GAMG on the embedded
    operator Jt = J with the rows and columns of the active dofs replaced by the identity
    (Jt = J_II plus the identity, J's size and block size, the rigid body modes Z of all
    dofs as near-nullspace), applied to the residual extended by zeros.

    GAMG's interpolation is built at the first Newton iteration of a step (from that
    Jacobian, with the contact terms of the last step) and kept for the step
    (``pc_gamg_reuse_interpolation``): Jt keeps its size and nonzero pattern whatever the
    inactive set, so a later set-up only copies J, replaces the active rows and recomputes
    the Galerkin products and smoothers (GAMG's re-set-up under MPI; on one rank
    ``GalerkinLevels``: the finest product from the rows that change only, unless
    ``<prefix>amg_incremental`` is false, and the finest level applied by Jt's SBAIJ copy
    when Jt is symmetric, unless ``<prefix>amg_fine_sbaij`` is false).  Against GAMG on
    J_II built anew at every change of the inactive set the set-ups are far cheaper for
    the same Krylov iterations; one interpolation for the whole run (from the first
    Jacobian, without contact) costs more Krylov iterations (docs/performance.md, section 7,
    "SNES VI with CG + GAMG").

    When the inactive set is the one of the previous set-up, the PC is kept (built on an
    earlier Jacobian: they differ by the Gamma3 terms only) while the Krylov iterations of
    the last solve stay within REUSE_GROWTH times those of the first solve with it (the
    Gamma3 terms can change much: contact and friction forces appear), unless the option
    ``<prefix>amg_reuse`` is false.

    Args:
        snes: the SNES whose KSP uses this PC (its Jacobian and inactive set are read in
            setUp).
        Z: (owned dofs, modes) array: the rigid body modes in the dofs SNES solves for.
        prefix: the SNES's options prefix; the inner PC reads ``<prefix>amg_``.
        changing: returns the local rows of J that may change between the Newton
            iterations of a step, every active dof among them
            (app/solvers/levels.FineProduct), or None (asked at GAMG's first set-up).
    """

    REUSE_GROWTH = 1.5

    def __init__(self, snes: PETSc.SNES, Z: np.ndarray, prefix: str,
                 changing=None):
        self.snes, self.Z, self.prefix = snes, Z, prefix
        self.changing_rows, self.changing = changing, None
        self.inner = self.Jt = self.xt = self.yt = None
        self.levels = self.copy = None
        self.rows = None
        self.setups = self.reuses = self.interpolations = 0
        self.fresh_its = None           # Krylov iterations of the first solve with the PC

    def _rows(self, P: PETSc.Mat) -> np.ndarray | None:
        """P's rows as local dofs of SNES's unknowns: the inactive set, None for all."""
        x = self.snes.getSolution()
        if P.getSize()[0] == x.getSize():
            return None
        return self.snes.getVIInactiveSet().getIndices() - x.getOwnershipRange()[0]

    def _same_rows(self, rows, comm) -> bool:
        """Whether the rows are those of the previous set-up on every rank."""
        same = self.inner is not None and (
            (rows is None and self.rows is None)
            or (rows is not None and self.rows is not None and np.array_equal(rows, self.rows)))
        return comm.tompi4py().allreduce(same, op=_land())

    def setUp(self, pc: PETSc.PC) -> None:
        """Set up GAMG on Jt for this Newton iteration's Jacobian and inactive set (or keep
        it for the same inactive set).

        Args:
            pc: the python PC (its operators: J_II of this Newton iteration, or J).
        """
        _, P = pc.getOperators()
        rows = self._rows(P)
        last_its = self.snes.getKSP().getIterationNumber()
        if self.fresh_its is None:
            self.fresh_its = last_its
        reuse = PETSc.Options(self.prefix + AMG_PREFIX).getBool("reuse", True) \
            and last_its <= self.REUSE_GROWTH * self.fresh_its
        if reuse and self._same_rows(rows, pc.getComm()):
            self.reuses += 1
            return
        self.fresh_its = None
        if self.snes.getIterationNumber() == 0 and self.inner is not None:
            self._drop_inner()                      # a new step: a new interpolation
        active = self._embed(self.snes.getJacobian()[0], rows)
        if self.inner is None:
            self._build(pc.getComm())
        elif self.levels is None:
            self.inner.setUp()                      # GAMG's own re-set-up (under MPI)
        else:
            if self.levels.product is not None and not np.all(np.isin(active, self.changing)):
                self.levels.forget_product()        # (not expected: a changing row missed)
            if self.levels.fine.handle != self.Jt.handle:
                self.copy.update(self.Jt)
            self.levels.update(self.Jt)
        self.rows = rows
        self.setups += 1

    def _build(self, comm: PETSc.Comm) -> None:
        """GAMG set up on Jt (a new interpolation); on one rank its levels kept by
        GalerkinLevels, with the finest level in SBAIJ and its product incremental where
        they apply (app/solvers/levels.py)."""
        self.interpolations += 1
        self.inner = PETSc.PC().create(comm)
        self.inner.setOptionsPrefix(self.prefix + AMG_PREFIX)
        self.inner.setType("gamg")
        self.inner.setFromOptions()
        self.inner.setOperators(self.Jt, self.Jt)
        self.inner.setUp()
        if comm.getSize() == 1 and self._option("keep_levels"):
            if self.changing is None and self.changing_rows is not None:
                self.changing = self.changing_rows()
            incremental = self._option("incremental") and self.changing is not None
            self.levels = GalerkinLevels(self.inner, self._fine(),
                                         self.changing if incremental else None)

    def _drop_inner(self) -> None:
        """Free GAMG and its kept levels."""
        if self.levels is not None:
            self.levels.destroy()
        if self.inner is not None:
            self.inner.destroy()
        self.inner = self.levels = None

    def _fine(self) -> PETSc.Mat:
        """The operator of the finest smoother and residual for this step (one rank): Jt's
        SBAIJ copy (app/solvers/levels.py) when Jt is symmetric, else Jt."""
        if not self._option("fine_sbaij"):
            return self.Jt
        if not is_symmetric(self.Jt):
            return self.Jt
        if self.copy is None:
            try:
                self.copy = SymmetricCopy(self.Jt)
            except ValueError:                      # a pattern without whole blocks
                self.copy = False
        elif self.copy:
            self.copy.update(self.Jt)
        return self.copy.mat if self.copy else self.Jt

    def _option(self, name: str) -> bool:
        """``<prefix>amg_<name>`` (default true): ``keep_levels`` false lets GAMG set
        itself up again between its interpolations as under MPI (neither of the next two
        then), ``fine_sbaij`` false keeps the finest level in AIJ, ``incremental`` false
        forms the finest Galerkin product in full."""
        return PETSc.Options(self.prefix + AMG_PREFIX).getBool(name, True)

    def _embed(self, J: PETSc.Mat, rows: np.ndarray | None) -> np.ndarray:
        """Jt = J with the rows and columns of the dofs not in ``rows`` (the active set)
        set to those of the identity (the first time: Jt created, with the modes); returns
        the active set (local rows)."""
        if self.Jt is None:
            self.Jt = J.duplicate(copy=share_pattern(J))
            self.Jt.setNearNullSpace(near_nullspace(self.Z, self.Jt))
            self.xt, self.yt = self.Jt.createVecs()
        J.copy(self.Jt, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        lo, hi = J.getOwnershipRange()
        active = np.zeros(hi - lo, dtype=bool)
        if rows is not None:
            active[:] = True
            active[rows] = False
        active = np.flatnonzero(active)
        self.Jt.zeroRowsColumns((lo + active).astype(PETSc.IntType), 1.0)
        return active

    def apply(self, pc: PETSc.PC, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """One multigrid cycle on Jt, for the residual on the inactive dofs.

        Args:
            pc: the python PC.
            x: the residual (inactive dofs).
            y: output, the preconditioned residual.
        """
        if self.rows is None:
            self.inner.apply(x, y)
            return
        self.xt.set(0.0)
        self.xt.array[self.rows] = x.array_r
        self.inner.apply(self.xt, self.yt)
        y.array[:] = self.yt.array_r[self.rows]

    def view(self, pc: PETSc.PC, viewer: PETSc.Viewer) -> None:
        """Show the inner PC (-ksp_view).

        Args:
            pc: the python PC.
            viewer: where to show it.
        """
        if self.inner is not None:
            self.inner.view(viewer)

    def destroy(self, pc: PETSc.PC) -> None:
        """Free the inner PC and Jt.

        Args:
            pc: the python PC (unused).
        """
        self._drop_inner()
        for obj in (self.Jt, self.copy, self.xt, self.yt):
            if obj:
                obj.destroy()
        self.inner = self.Jt = self.copy = self.xt = self.yt = None


def _land():
    """MPI's logical and (mpi4py imported when first needed)."""
    from mpi4py import MPI
    return MPI.LAND
