"""The cell-strain operator of P1 displacements: eps(u) per cell as one sparse matrix.

For P1 elements eps(u) is constant on each cell, so with the DG0 tensor space Q
    D[q, j] = int_Omega eps(phi_j) : tau_q dx     (phi_j in V^h, tau_q in Q^h)
gives (D u)_c = |c| eps_c(u) exactly, and D^T H = int H : eps(v) dx for H in Q^h; likewise
D_sigma[q, j] = int E eps(phi_j) : tau_q / |c| dx gives (D_sigma u)_c = E eps_c(u).  One
matrix-vector product thus replaces an interpolation of sigma_n = E eps(u_n) + H_n (3.2) and
one an assembly of the pre-stress load (H_n, eps(v)) of (3.4) in every step, and the norms
||u||_V = ||eps(u)||_L2 and ||sigma||_Q are exact cell sums.
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from forms.elasticity import elasticity_operator, eps


class StrainOperator:
    """sigma = E eps(u) + H per cell, the pre-stress load D^T H, and the norms."""

    def __init__(self, V, Q, E: float, nu: float):
        self.d = d = V.mesh.geometry.dim
        du, tau = ufl.TrialFunction(V), ufl.TestFunction(Q)
        self.D = fem.petsc.assemble_matrix(fem.form(ufl.inner(eps(du), tau) * ufl.dx))
        self.D.assemble()
        C = elasticity_operator(E, nu, d)
        self.D_sigma = fem.petsc.assemble_matrix(fem.form(
            ufl.inner(C(eps(du)), tau) / ufl.CellVolume(V.mesh) * ufl.dx))
        self.D_sigma.assemble()
        v = ufl.TestFunction(V)
        self.A = fem.petsc.assemble_matrix(fem.form(ufl.inner(eps(du), eps(v)) * ufl.dx))
        self.A.assemble()                     # ||eps(u)||^2 = u . A u
        vol = fem.petsc.assemble_vector(fem.form(tau[0, 0] * ufl.dx))
        self.n_owned = Q.dofmap.index_map.size_local
        self.vol = vol.array_r.reshape(-1, d * d)[:, 0].copy()      # owned cells, Q order
        vol.destroy()
        self._b = self.D.createVecRight()

    def update_sigma(self, u, H, sigma) -> None:
        """sigma = E eps(u) + H on the owned cells, ghosts by scatter."""
        if H is None:
            self.D_sigma.mult(u.vector, sigma.vector)
        else:
            self.D_sigma.multAdd(u.vector, H.vector, sigma.vector)
        sigma.x.scatter_forward()

    def strain_norm2(self, u) -> float:
        """||eps(u)||_L2^2 (global: PETSc reduces the dot product)."""
        self.A.mult(u.vector, self._b)
        return self._b.dot(u.vector)

    def energy_norm2(self, cell_tensors: np.ndarray) -> float:
        """sum_c |c| t_c : t_c over the owned cells (this rank's part of ||t||_L2^2)."""
        flat = cell_tensors.reshape(len(self.vol), -1)
        return float(self.vol @ np.einsum("ij,ij->i", flat, flat))

    def pre_stress_load(self, H, b: PETSc.Vec) -> None:
        """b -= D^T H = (H, eps(v)) for all v (the pre-stress term of the step's load)."""
        self.D.multTranspose(H.vector, self._b)
        b.axpy(-1.0, self._b)

    def destroy(self):
        for obj in (self.D, self.D_sigma, self.A, self._b):
            obj.destroy()
