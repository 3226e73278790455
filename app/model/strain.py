"""The cell-strain operator of P1 displacements: eps(u) per cell as one sparse matrix.

For P1 elements eps(u) is constant on each cell, so with the DG0 tensor space Q
    D[q, j] = int_Omega eps(phi_j) : tau_q dx     (phi_j in V^h, tau_q in Q^h)
gives (D u)_c = |c| eps_c(u) exactly, and D^T H = int H : eps(v) dx for H in Q^h; likewise
D_sigma[q, j] = int E eps(phi_j) : tau_q / |c| dx gives (D_sigma u)_c = E eps_c(u).  One
matrix-vector product thus replaces an interpolation of sigma_n = E eps(u_n) + H_n (3.2) and
one an assembly of the pre-stress load (H_n, eps(v)) of (3.4) in every step, and the norms
||u||_V = ||eps(u)||_L2 and ||sigma||_Q are exact cell sums.

With the compiled kernels (kernels.cell_pass, cell_load) the same operator D is applied cell by
cell from |c| grad phi_a of the cell's d + 1 vertex functions (from the cell geometry: a quarter
of the data of D's rows, and D itself is then never assembled, which shortens the set-up):
sigma, its von Mises norm and the squared norms ||eps(u)||^2, ||sigma||_Q^2 in one pass, D^T H
in another, faster than from D's rows and much faster than the PETSc products
(docs/performance.md, sections 3, 4 and 9).  The PETSc products of the assembled D stay the
reference (tests/unit/test_strain.py) and the fallback.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact import kernels, threads
from vpcontact.forms.elasticity import elasticity_operator, eps, lame_constants


def _inverse(J: np.ndarray) -> np.ndarray:
    """The inverses of a stack of 2 x 2 or 3 x 3 matrices by their adjugates (np.linalg.inv
    calls LAPACK once per matrix, several times slower: docs/performance.md, section 3).
    For columns c0, c1(, c2) of J the rows of J^-1 are orthogonal to the other
    columns: (c1 x c2, c2 x c0, c0 x c1) / det in 3D."""
    if J.shape[-1] == 2:
        a, b, c, e = J[:, 0, 0], J[:, 0, 1], J[:, 1, 0], J[:, 1, 1]
        rows = np.stack([np.stack([e, -b], -1), np.stack([-c, a], -1)], 1)
        det = a * e - b * c
    else:
        c0, c1, c2 = J[:, :, 0], J[:, :, 1], J[:, :, 2]
        rows = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], 1)
        det = np.einsum("ij,ij->i", c0, rows[:, 0])
    return rows / det[:, None, None]


@dataclass
class CellSubset:
    """Some owned cells for a StrainOperator pass.

    Attributes:
        rows: the cells, rows of Q's owned blocks.
        vertices: their vertices (the compiled pass's), or None.
        G: their |c| grad phi_a (the compiled pass's), or None.
    """

    rows: np.ndarray
    vertices: np.ndarray | None
    G: np.ndarray | None


class StrainOperator:
    """sigma = E eps(u) + H per cell (3.2), the pre-stress load D^T H of (3.4), the norms.

    An E other than the isotropic (E, nu) one (anisotropic, or per cell) is given as its UFL
    operator ``C``: sigma is then the product of the assembled D_sigma (the compiled cell
    pass knows only lmbda and two_mu); the norms and D^T H stay compiled.

    Args:
        V: the P1 displacement space V^h.
        Q: the DG0 tensor space Q^h.
        E: Young's modulus (isotropic E; None with ``C``).
        nu: Poisson's ratio (isotropic E; None with ``C``).
        C: the operator tau -> E tau (forms.elasticity.voigt_operator), or None.
    """

    def __init__(self, V, Q, E: float | None, nu: float | None, C=None):
        self.d = d = V.mesh.geometry.dim
        tau = ufl.TestFunction(Q)
        self._V, self._Q, self._E, self._nu, self._C = V, Q, E, nu, C
        vol = fem.petsc.assemble_vector(fem.form(tau[0, 0] * ufl.dx))
        self.n_owned = Q.dofmap.index_map.size_local
        self.vol = vol.array_r.reshape(-1, d * d)[:, 0].copy()      # owned cells, Q order
        vol.destroy()
        self.comm = V.mesh.comm
        # with C the cell pass computes only the norms (lmbda, two_mu unused there)
        self.lmbda, self.two_mu = lame_constants(E, nu, d) if C is None else (0.0, 0.0)
        self.mod = kernels.load()
        cells = self._cell_gradients(V, Q) if self.mod is not None else None
        # one path on every rank (the PETSc products and the lazy assembly are collective)
        self._cells = cells if self.comm.allreduce(cells is not None, op=MPI.LAND) else None
        self._work = fem.Function(V) if self._cells is not None else None   # ghosted

    @staticmethod
    def _assembled(a) -> PETSc.Mat:
        M = fem.petsc.assemble_matrix(fem.form(a))
        M.assemble()
        return M

    @cached_property
    def D(self) -> PETSc.Mat:
        """D[q, j] = int eps(phi_j) : tau_q dx; assembled when first used (not by the
        compiled path)."""
        du, tau = ufl.TrialFunction(self._V), ufl.TestFunction(self._Q)
        return self._assembled(ufl.inner(eps(du), tau) * ufl.dx)

    @cached_property
    def _b(self) -> PETSc.Vec:
        return self.D.createVecRight()

    @cached_property
    def D_sigma(self) -> PETSc.Mat:
        """(D_sigma u)_c = E eps_c(u); assembled when first used (not by the compiled
        path)."""
        du, tau = ufl.TrialFunction(self._V), ufl.TestFunction(self._Q)
        C = elasticity_operator(self._E, self._nu, self.d) if self._C is None else self._C
        return self._assembled(ufl.inner(C(eps(du)), tau) / ufl.CellVolume(self._V.mesh)
                               * ufl.dx)

    @cached_property
    def A(self) -> PETSc.Mat:
        """||eps(u)||^2 = u . A u; assembled when first used (not by the compiled path)."""
        du, v = ufl.TrialFunction(self._V), ufl.TestFunction(self._V)
        return self._assembled(ufl.inner(eps(du), eps(v)) * ufl.dx)

    def _cell_gradients(self, V, Q):
        """(vertices, G): per owned cell (in Q's dof order, the rows of D) its d + 1 vertices
        (local node numbers of V: dofs node * d + k) and G_a = |c| grad phi_a, from the cell
        geometry (affine P1 cells: grad phi_a = rows of J^-1 for a >= 1, minus their sum for
        a = 0).  Then D_c[(i,j), (a,k)] = (delta_ik G_aj + delta_jk G_ai) / 2; the tests
        compare the cell passes with the assembled D.  None if the spaces are not P1
        displacements on an affine simplex mesh with DG0 cell data."""
        d, msh = self.d, V.mesh
        geometry = msh.geometry.dofmap.array
        nv = d + 1
        if (V.dofmap.index_map_bs != d or V.dofmap.dof_layout.num_dofs != nv
                or Q.dofmap.dof_layout.num_dofs != 1 or len(geometry) % nv
                or msh.geometry.cmap.degree != 1):
            return None
        qdof = Q.dofmap.list.array                        # one DG0 block per cell
        cell = np.empty(len(qdof), dtype=np.int64)
        cell[qdof] = np.arange(len(qdof))
        cell = cell[:self.n_owned]                        # the owned rows of D, in order
        vertices = V.dofmap.list.array.reshape(-1, nv)[cell]
        X = msh.geometry.x[geometry.reshape(-1, nv)[cell], :d]            # (cells, d + 1, d)
        J = (X[:, 1:, :] - X[:, :1, :]).transpose(0, 2, 1)              # columns X_a - X_0
        Jinv = _inverse(J)                                # rows: grad phi_1 .. grad phi_d
        grads = np.concatenate([-Jinv.sum(axis=1, keepdims=True), Jinv], axis=1)
        return (np.ascontiguousarray(vertices, dtype=np.intc),
                np.ascontiguousarray(self.vol[:, None, None] * grads, dtype=float))

    def _cell_pass(self, u, H=None, sigma=None, vm=None) -> tuple[float, float]:
        """kernels.cell_pass on the owned cells; returns this rank's ||eps(u)||^2 and (with
        sigma) ||sigma||_Q^2 (else 0)."""
        n, dd = self.n_owned, self.d * self.d
        vertices, G = self._cells
        return kernels.cell_pass(
            self.mod, vertices, G, self.vol, self.lmbda, self.two_mu, u.x.array,
            None if H is None else H.x.array[:n * dd],
            None if sigma is None else sigma.x.array[:n * dd],
            None if vm is None else vm.x.array[:n], threads.own_cores())

    def update_sigma(self, u, H, sigma, vm=None) -> tuple[float, float] | None:
        """sigma = E eps(u) + H (3.2) on the owned cells, ghosts by scatter; collective.

        Args:
            u: the displacement (P1 Function).
            H: the pre-stress (DG0 tensor Function) or None.
            sigma: the DG0 tensor Function to fill.
            vm: a DG0 scalar Function for ||sigma||_VM, filled by the compiled kernel only.

        Returns:
            With the compiled kernel and ``vm``, the pass's global sums
            (||eps(u)||_L2^2, ||sigma||_Q^2); else None.
        """
        if self._cells is not None and vm is not None and self._C is None:
            sums = np.array(self._cell_pass(u, H, sigma, vm))
            self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)   # buffer: no pickling
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
        """||eps(u)||_L2^2, reduced over the ranks; collective.

        Args:
            u: the displacement (P1 Function).

        Returns:
            The squared norm.
        """
        if self._cells is not None:
            return self.comm.allreduce(self._cell_pass(u)[0], op=MPI.SUM)
        self.A.mult(u.vector, self._b)
        return self._b.dot(u.vector)

    def energy_norm2(self, cell_tensors: np.ndarray) -> float:
        """sum_c |c| t_c : t_c over the owned cells.

        Args:
            cell_tensors: the owned cells' d x d tensors (flat or shaped).

        Returns:
            This rank's part of ||t||_L2^2.
        """
        flat = cell_tensors.reshape(len(self.vol), -1)
        return float(self.vol @ np.einsum("ij,ij->i", flat, flat))

    def subset(self, rows: np.ndarray) -> CellSubset:
        """The owned cells ``rows`` (Q's order) with their compiled pass's data.

        Args:
            rows: owned cells.

        Returns:
            The CellSubset (without the compiled data where the assembled D serves).
        """
        if self._cells is None:
            return CellSubset(rows, None, None)
        vertices, G = self._cells
        return CellSubset(rows, np.ascontiguousarray(vertices[rows]), np.ascontiguousarray(G[rows]))

    def stress_load(self, sigma, cells: CellSubset | None = None) -> PETSc.Vec:
        """D^T sigma = (sigma, eps(v)) for all v, from the owned cells of ``cells`` (None:
        all): exact at the nodes whose cells are all among them; collective.

        Args:
            sigma: a DG0 tensor Function (a stress).
            cells: a ``subset`` of the owned cells, or None for every cell.

        Returns:
            A work vector of V (owned entries valid; overwritten by the next call).
        """
        if self._cells is None:                   # the assembled D: every cell
            self.D.multTranspose(sigma.vector, self._b)
            return self._b
        ffi, w, dd = self.mod.ffi, self._work, self.d * self.d
        if cells is None:
            (vertices, G), values = self._cells, sigma.x.array[:self.n_owned * dd]
        else:
            vertices, G = cells.vertices, cells.G
            values = np.ascontiguousarray(sigma.x.array.reshape(-1, dd)[cells.rows])
        w.x.array[:] = 0.0
        self.mod.lib.cell_load(len(vertices), self.d, kernels.buf(ffi, vertices),
                               kernels.buf(ffi, G), kernels.buf(ffi, values),
                               kernels.buf(ffi, w.x.array))
        w.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return w.vector

    def pre_stress_load(self, H, b: PETSc.Vec) -> None:
        """b -= D^T H = (H, eps(v)) for all v, the pre-stress term of the load of (3.4).

        Args:
            H: the pre-stress H_n (DG0 tensor Function).
            b: the load vector, updated in place.
        """
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
