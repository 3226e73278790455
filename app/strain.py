"""The cell-strain operator of P1 displacements: eps(u) per cell as one sparse matrix.

For P1 elements eps(u) is constant on each cell, so with the DG0 tensor space Q
    D[q, j] = int_Omega eps(phi_j) : tau_q dx     (phi_j in V^h, tau_q in Q^h)
gives (D u)_c = |c| eps_c(u) exactly, and D^T H = int H : eps(v) dx for H in Q^h; likewise
D_sigma[q, j] = int E eps(phi_j) : tau_q / |c| dx gives (D_sigma u)_c = E eps_c(u).  One
matrix-vector product thus replaces an interpolation of sigma_n = E eps(u_n) + H_n (3.2) and
one an assembly of the pre-stress load (H_n, eps(v)) of (3.4) in every step, and the norms
||u||_V = ||eps(u)||_L2 and ||sigma||_Q are exact cell sums.

With the compiled kernels (kernels.cell_pass, cell_load) the same operator D is applied cell
by cell from |c| grad phi_a of the cell's d + 1 vertex functions, read off D's rows (a quarter
of their data): sigma, its von Mises norm and the squared norms ||eps(u)||^2, ||sigma||_Q^2 in
one pass, D^T H in another.  At h = 1/128 they take about 1.0 and 0.4 ms per step (from D's
rows 1.0-1.6 and 0.5-1.1 ms; the PETSc products, the numpy von Mises norm and the A-norm
about 6 ms).  The PETSc products stay the reference (tests/unit/test_strain.py) and the
fallback.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from forms.elasticity import elasticity_operator, eps, lame_constants

from . import kernels


class StrainOperator:
    """sigma = E eps(u) + H per cell, the pre-stress load D^T H, and the norms."""

    def __init__(self, V, Q, E: float, nu: float):
        self.d = d = V.mesh.geometry.dim
        du, tau = ufl.TrialFunction(V), ufl.TestFunction(Q)
        self.D = fem.petsc.assemble_matrix(fem.form(ufl.inner(eps(du), tau) * ufl.dx))
        self.D.assemble()
        self._V, self._Q, self._E, self._nu = V, Q, E, nu
        vol = fem.petsc.assemble_vector(fem.form(tau[0, 0] * ufl.dx))
        self.n_owned = Q.dofmap.index_map.size_local
        self.vol = vol.array_r.reshape(-1, d * d)[:, 0].copy()      # owned cells, Q order
        vol.destroy()
        self._b = self.D.createVecRight()
        self.comm = V.mesh.comm
        self.lmbda, self.two_mu = lame_constants(E, nu, d)
        self.mod = kernels.load()
        cells = self._cell_rows(V) if self.mod is not None else None
        # one path on every rank (the PETSc products and the lazy assembly are collective)
        self._cells = cells if self.comm.allreduce(cells is not None, op=MPI.LAND) else None
        self._work = fem.Function(V) if self._cells is not None else None   # ghosted

    @cached_property
    def D_sigma(self) -> PETSc.Mat:
        """(D_sigma u)_c = E eps_c(u); assembled when first used (not by the compiled
        path)."""
        du, tau = ufl.TrialFunction(self._V), ufl.TestFunction(self._Q)
        C = elasticity_operator(self._E, self._nu, self.d)
        M = fem.petsc.assemble_matrix(fem.form(
            ufl.inner(C(eps(du)), tau) / ufl.CellVolume(self._V.mesh) * ufl.dx))
        M.assemble()
        return M

    @cached_property
    def A(self) -> PETSc.Mat:
        """||eps(u)||^2 = u . A u; assembled when first used (not by the compiled path)."""
        du, v = ufl.TrialFunction(self._V), ufl.TestFunction(self._V)
        M = fem.petsc.assemble_matrix(fem.form(ufl.inner(eps(du), eps(v)) * ufl.dx))
        M.assemble()
        return M

    def _cell_rows(self, V):
        """(nodes, G): per owned cell its d + 1 vertices (local node numbers) and the rows
        G_a = |c| grad phi_a, read off the assembled D (D_c[(i,j), (a,k)] =
        (delta_ik G_aj + delta_jk G_ai) / 2) and checked against all of D_c; None if D does
        not have this structure."""
        d = self.d
        dd, nd = d * d, (d + 1) * d
        indptr, indices, data = self.D.getValuesCSR()
        if (len(indptr) - 1) != self.n_owned * dd or not np.all(np.diff(indptr) == nd):
            return None
        cols = indices.reshape(-1, dd, nd)
        if not np.all(cols == cols[:, :1, :]):
            return None
        imap, bs = V.dofmap.index_map, V.dofmap.index_map_bs
        nodes = imap.local_to_global(np.arange(imap.size_local + imap.num_ghosts,
                                               dtype=np.int32))
        l2g = (np.asarray(nodes, dtype=np.int64)[:, None] * bs + np.arange(bs)).ravel()
        order = np.argsort(l2g)
        glob = cols[:, 0, :].astype(np.int64)
        local = order[np.minimum(np.searchsorted(l2g, glob, sorter=order), len(l2g) - 1)]
        if bs != d or not np.array_equal(l2g[local], glob):
            return None
        vertices = local[:, ::d] // d                     # the dofs are node * d + k, by node
        if not np.array_equal(local, (vertices[:, :, None] * d + np.arange(d)).reshape(-1, nd)):
            return None
        Dx = data.reshape(-1, dd, d + 1, d)                # [cell, (i, j), a, k]
        G = np.stack([Dx[:, j * d + j, :, j] for j in range(d)], axis=2)  # |c| grad phi_a
        tol, eye = 1e-13 * np.abs(data).max(initial=0.0), np.eye(d)
        for i in range(d):
            for j in range(d):
                rebuilt = 0.5 * (G[:, :, j, None] * eye[i] + G[:, :, i, None] * eye[j])
                if np.abs(Dx[:, i * d + j] - rebuilt).max(initial=0.0) > tol:
                    return None
        return (np.ascontiguousarray(vertices, dtype=np.intc),
                np.ascontiguousarray(G, dtype=float))

    def _cell_pass(self, u, H=None, sigma=None, vm=None) -> tuple[float, float]:
        """kernels.cell_pass on the owned cells; returns this rank's ||eps(u)||^2 and (with
        sigma) ||sigma||_Q^2 (else 0)."""
        ffi, n, dd = self.mod.ffi, self.n_owned, self.d * self.d
        vertices, G = self._cells
        ss = ffi.new("double *")
        e2 = self.mod.lib.cell_pass(
            n, self.d, kernels.buf(ffi, vertices), kernels.buf(ffi, G), kernels.buf(ffi, self.vol),
            self.lmbda, self.two_mu, kernels.buf(ffi, u.x.array),
            kernels.buf(ffi, None if H is None else H.x.array[:n * dd]),
            kernels.buf(ffi, None if sigma is None else sigma.x.array[:n * dd]),
            kernels.buf(ffi, None if vm is None else vm.x.array[:n]), ss)
        return e2, ss[0]

    def update_sigma(self, u, H, sigma, vm=None) -> tuple[float, float] | None:
        """sigma = E eps(u) + H on the owned cells, ghosts by scatter.  With the compiled
        kernel also vm = ||sigma||_VM (a DG0 function), and the pass's global sums
        (||eps(u)||_L2^2, ||sigma||_Q^2) are returned (else None)."""
        if self._cells is not None and vm is not None:
            sums = self.comm.allreduce(np.array(self._cell_pass(u, H, sigma, vm)), op=MPI.SUM)
            sigma.x.scatter_forward()
            vm.x.scatter_forward()
            return float(sums[0]), float(sums[1])
        if H is None:
            self.D_sigma.mult(u.vector, sigma.vector)
        else:
            self.D_sigma.multAdd(u.vector, H.vector, sigma.vector)
        sigma.x.scatter_forward()
        return None

    def strain_norm2(self, u) -> float:
        """||eps(u)||_L2^2 (global: reduced over the ranks)."""
        if self._cells is not None:
            return self.comm.allreduce(self._cell_pass(u)[0], op=MPI.SUM)
        self.A.mult(u.vector, self._b)
        return self._b.dot(u.vector)

    def energy_norm2(self, cell_tensors: np.ndarray) -> float:
        """sum_c |c| t_c : t_c over the owned cells (this rank's part of ||t||_L2^2)."""
        flat = cell_tensors.reshape(len(self.vol), -1)
        return float(self.vol @ np.einsum("ij,ij->i", flat, flat))

    def pre_stress_load(self, H, b: PETSc.Vec) -> None:
        """b -= D^T H = (H, eps(v)) for all v (the pre-stress term of the step's load)."""
        if self._cells is not None:
            ffi, w = self.mod.ffi, self._work
            vertices, G = self._cells
            w.x.array[:] = 0.0
            n, dd = self.n_owned, self.d * self.d
            self.mod.lib.cell_load(n, self.d, kernels.buf(ffi, vertices), kernels.buf(ffi, G),
                                   kernels.buf(ffi, H.x.array[:n * dd]),
                                   kernels.buf(ffi, w.x.array))
            w.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            b.axpy(-1.0, w.vector)
            return
        self.D.multTranspose(H.vector, self._b)
        b.axpy(-1.0, self._b)

    def destroy(self):
        for obj in (self.D, self._b, self.__dict__.get("D_sigma"), self.__dict__.get("A")):
            if obj is not None:
                obj.destroy()
