"""The case's elasticity tensor E(x) (hypothesis H(E)): isotropic with numbers (the paper's
Elasticity, unchanged), isotropic with E, nu expressions of x, y, z taken per cell (at the
cell's midpoint: E in L-infinity, DG0), orthotropic from engineering constants and material
axes, or a Voigt matrix; and its UFL operator for the forms.

Matrices here are in t-coordinates (app/model/material.py): (E tau)_t = C t(tau), t =
(t11, t22, t12) in 2D, (t11, t22, t33, t23, t13, t12) in 3D.  A Voigt matrix D of the case
file acts on engineering strains (shears 2 eps_ij): C = D diag(1, .., 2, ..).

Orthotropic: in the material axes a1, a2, a3 (a3 = a1 x a2 in 3D; in 2D a2 is a1 turned by
+90 degrees and a3 = z) the compliance in engineering Voigt order is
    S = [[1/E1, -nu12/E1, -nu13/E1], [-nu12/E1, 1/E2, -nu23/E2], [-nu13/E1, -nu23/E2, 1/E3]]
on the normal block and diag(1/G23, 1/G13, 1/G12) on the shears (nu_ij = -eps_j / eps_i
under a uniaxial stress along a_i; nu21 = nu12 E2/E1).  In 2D plane stress takes the
in-plane block of S (E1, E2, nu12, G12 suffice), D = S_p^-1 with p = (11, 22, 12); plane
strain needs the 3D data (E: [E1, E2, E3], nu: [nu12, nu13, nu23], G: [G12, G13, G23]) and
takes D = (S^-1)_pp, the reduced compliance S_pp - S_p3 S_3p / S_33.  The matrix in the
global axes is T^-1 C_local T, T the change of t-coordinates to the material axes.  The axes
must be nonzero and orthogonal (refused otherwise: a silent orthonormalisation would change
the material the user meant); their lengths do not matter.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.case.datacheck import evaluate
from vpcontact.forms.elasticity import (
    elasticity_operator,
    lame_constants,
    plane_strain_moduli,
    voigt_operator,
)
from vpcontact.model.material import (
    CellElasticity,
    Elasticity,
    ElasticityForms,
    MatrixElasticity,
    from_voigt,
    to_voigt,
)

_SHEARS = {2: [2], 3: [3, 4, 5]}
_PLANE = [0, 1, 5]                     # (11, 22, 12) in the 3D engineering Voigt order


def _weights(dim: int) -> np.ndarray:
    """The Frobenius weights of the t-coordinates (2 on the shears)."""
    return np.array([1.0] * dim + [2.0] * (3 * dim - 3 - dim))


def voigt_matrix(D, dim: int) -> np.ndarray:
    """C in t-coordinates from a Voigt matrix on engineering strains.

    Args:
        D: the (m, m) matrix: stresses (11, 22, 12) / (11, 22, 33, 23, 13, 12) from the
            engineering strains in the same order.
        dim: space dimension d.

    Returns:
        C = D diag(weights).
    """
    return np.asarray(D, dtype=float) * _weights(dim)[None, :]


def isotropic_matrices(E, nu, dim: int, plane: str | None = "stress") -> np.ndarray:
    """Isotropic C per cell, (E tau) = lmbda tr(tau) I + two_mu tau.

    Args:
        E: Young's moduli (n,).
        nu: Poisson's ratios (n,).
        dim: space dimension d.
        plane: in 2D "stress" or "strain" (plane_strain_moduli).

    Returns:
        (n, m, m) matrices.
    """
    E, nu = np.asarray(E, dtype=float), np.asarray(nu, dtype=float)
    if dim == 2 and plane == "strain":
        E, nu = plane_strain_moduli(E, nu)
    lmbda, two_mu = lame_constants(E, nu, dim)
    m = 3 * dim - 3
    C = two_mu[:, None, None] * np.eye(m)[None]
    C[:, :dim, :dim] += lmbda[:, None, None]
    return C


def material_axes(axes, dim: int) -> np.ndarray:
    """The rotation R whose rows are the unit material axes.

    Args:
        axes: [a1] in 2D, [a1, a2] in 3D.
        dim: space dimension d.

    Returns:
        R (d x d), orthogonal with det 1.

    Raises:
        ValueError: an axis is zero or the axes are not orthogonal (|cos| > 1e-8).
    """
    a = [np.asarray(v, dtype=float) for v in axes]
    if len(a) != dim - 1 or any(v.shape != (dim,) for v in a):
        raise ValueError(f"axes: {dim - 1} vector(s) of {dim} components expected")
    norms = [float(np.linalg.norm(v)) for v in a]
    if not all(np.isfinite(norms)) or min(norms) == 0.0:
        raise ValueError("axes: an axis is zero (or not finite)")
    a = [v / n for v, n in zip(a, norms)]
    if dim == 2:
        return np.array([a[0], [-a[0][1], a[0][0]]])
    if abs(a[0] @ a[1]) > 1e-8:
        raise ValueError(f"axes: a1 and a2 are not orthogonal (cos = {a[0] @ a[1]:.3g})")
    a2 = a[1] - (a[0] @ a[1]) * a[0]
    a2 /= np.linalg.norm(a2)
    return np.array([a[0], a2, np.cross(a[0], a2)])


def rotation_matrix(R: np.ndarray) -> np.ndarray:
    """T: t(R tau R^T) = T t(tau), the t-coordinates of tau in the axes of R's rows.

    Args:
        R: d x d orthogonal, rows the new axes.

    Returns:
        T (m x m).
    """
    dim = R.shape[0]
    m = 3 * dim - 3
    tau = from_voigt(np.eye(m), dim)                         # the basis tensors
    return to_voigt(R[None] @ tau @ R.T[None], dim).T


def orthotropic_compliance(E, nu, G) -> np.ndarray:
    """S (engineering Voigt order) in the material axes, 3D data (or 2D: E1, E2, nu12,
    G12 give the in-plane block (11, 22, 12)).

    Args:
        E: [E1, E2, E3] or [E1, E2].
        nu: [nu12, nu13, nu23] or [nu12].
        G: [G12, G13, G23] or [G12].

    Returns:
        S (6 x 6, or 3 x 3 for 2D data).
    """
    if len(E) == 2:
        E1, E2 = E
        return np.array([[1 / E1, -nu[0] / E1, 0.0], [-nu[0] / E1, 1 / E2, 0.0],
                         [0.0, 0.0, 1 / G[0]]])
    (E1, E2, E3), (n12, n13, n23), (G12, G13, G23) = E, nu, G
    S = np.zeros((6, 6))
    S[:3, :3] = [[1 / E1, -n12 / E1, -n13 / E1], [-n12 / E1, 1 / E2, -n23 / E2],
                 [-n13 / E1, -n23 / E2, 1 / E3]]
    S[3:, 3:] = np.diag([1 / G23, 1 / G13, 1 / G12])
    return S


def orthotropic_matrix(E, nu, G, axes, dim: int, plane: str | None = "stress") -> np.ndarray:
    """C of an orthotropic material in the global axes (module docstring).

    Args:
        E, nu, G: the engineering constants (orthotropic_compliance).
        axes: the material axes (material_axes).
        dim: space dimension d.
        plane: in 2D "stress" or "strain" (strain needs the 3D data).

    Returns:
        C (m x m) in t-coordinates.

    Raises:
        ValueError: plane strain with 2D data, a modulus <= 0, a compliance that is not
            positive definite, or bad axes.
    """
    if min(list(E) + list(G)) <= 0:
        raise ValueError("the moduli E and G must be > 0")
    S = orthotropic_compliance(E, nu, G)
    if np.linalg.eigvalsh(S).min() <= 0:
        raise ValueError("the compliance is not positive definite")
    if dim == 3:
        D = np.linalg.inv(S)
    elif len(S) == 3:
        if plane == "strain":
            raise ValueError("plane strain needs E3, nu13, nu23 (E, nu, G with 3 entries)")
        D = np.linalg.inv(S)
    else:
        D = np.linalg.inv(S[np.ix_(_PLANE, _PLANE)]) if plane != "strain" else \
            np.linalg.inv(S)[np.ix_(_PLANE, _PLANE)]
    T = rotation_matrix(material_axes(axes, dim))
    return np.linalg.solve(T, voigt_matrix(0.5 * (D + D.T), dim) @ T)


def spd_check(C: np.ndarray, dim: int) -> float:
    """The smallest eigenvalue of E on symmetric tensors (Frobenius inner product), after
    checking that A = diag(weights) C is symmetric.

    Args:
        C: (m, m) or (n, m, m) matrices in t-coordinates.
        dim: space dimension d.

    Returns:
        m_E (<= 0: not positive definite).

    Raises:
        ValueError: A is not symmetric (relative 1e-12).
    """
    A = _weights(dim)[:, None] * np.asarray(C, dtype=float)
    At = np.swapaxes(A, -1, -2)
    if np.abs(A - At).max() > 1e-12 * np.abs(A).max():
        raise ValueError("the matrix is not symmetric")
    # generalised eigenvalues of (A, W): those of W^-1/2 A W^-1/2, symmetric
    s = 1.0 / np.sqrt(_weights(dim))
    return float(np.linalg.eigvalsh(0.5 * (A + At) * s[:, None] * s[None, :]).min())


def cell_rows(Q) -> np.ndarray:
    """The row (DG0 block of Q) of each local cell (owned and ghost).

    Args:
        Q: a DG0 space.

    Returns:
        (ncells,) row indices.
    """
    return np.asarray(Q.dofmap.list.array).reshape(-1)


def cell_values(component, msh, n: int) -> np.ndarray:
    """A number or expression of x, y, z at the midpoints of the local cells 0..n-1.

    Args:
        component: a number or an expression string.
        msh: the mesh.
        n: the number of local cells (owned and ghost).

    Returns:
        (n,) values.
    """
    tdim = msh.topology.dim
    mid = dmesh.compute_midpoints(msh, tdim, np.arange(n, dtype=np.int32))
    values, _ = evaluate(component, mid[:, :msh.geometry.dim], np.zeros(1))
    return np.broadcast_to(values[0], (n,)).astype(float)


def case_elasticity(material, dim: int, Q) -> ElasticityForms | None:
    """The case's E when it is not the paper's homogeneous isotropic one; collective.

    Args:
        material: the case's Material (E, nu, elasticity, plane).
        dim: space dimension d.
        Q: the DG0 tensor space (its rows are the CellElasticity's).

    Returns:
        A MatrixElasticity (orthotropic, voigt), a CellElasticity (E or nu an expression),
        or None (numbers E, nu: the caller's Elasticity).

    Raises:
        ValueError: E <= 0 or nu out of range in a cell, or bad orthotropic data.
    """
    plane = material.plane if dim == 2 else None
    spec = getattr(material, "elasticity", None)
    if spec is not None:
        if "voigt" in spec:
            return MatrixElasticity(voigt_matrix(spec["voigt"], dim), dim)
        o = spec["orthotropic"]
        return MatrixElasticity(orthotropic_matrix(o["E"], o["nu"], o["G"], o["axes"], dim,
                                                   plane), dim)
    if isinstance(material.E, (int, float)) and isinstance(material.nu, (int, float)):
        return None
    msh = Q.mesh
    n = len(cell_rows(Q))
    E, nu = cell_values(material.E, msh, n), cell_values(material.nu, msh, n)
    top = 1.0 if dim == 2 and plane != "strain" else 0.5
    bad = not (np.all(E > 0) and np.all(nu >= 0) and np.all(nu < top))
    if msh.comm.allreduce(bool(bad), op=MPI.LOR):
        raise ValueError(f"material.E must be > 0 and material.nu in [0, {top}) in every "
                         "cell of the mesh")
    Cmats = np.empty((n, 3 * dim - 3, 3 * dim - 3))
    Cmats[cell_rows(Q)] = isotropic_matrices(E, nu, dim, plane)
    return cell_elasticity(Cmats, dim, msh.comm)


def cell_elasticity(Cmats: np.ndarray, dim: int, comm) -> CellElasticity:
    """A CellElasticity from one matrix per row, its bounds (m_E, M_E) reduced over the
    ranks; collective.  (For materials per group: CellElasticity.from_pieces, with
    ``global_bounds`` of the pieces.)

    Args:
        Cmats: (n, m, m) matrices in t-coordinates, rows in the DG0 order (cell_rows).
        dim: space dimension d.
        comm: the mesh's communicator.

    Returns:
        The CellElasticity.
    """
    el = CellElasticity.from_rows(Cmats, dim)
    return CellElasticity(el.mats, el.index, dim, global_bounds(el, comm))


def global_bounds(el: ElasticityForms, comm) -> tuple[float, float]:
    """(m_E, M_E) of an elasticity over every rank's cells; collective.

    Args:
        el: the elasticity (its ``bounds`` on this rank).
        comm: the communicator.

    Returns:
        (m_E, M_E).
    """
    lo, hi = el.bounds()
    return comm.allreduce(lo, op=MPI.MIN), comm.allreduce(hi, op=MPI.MAX)


def tensor_field(el: CellElasticity, Q) -> fem.Function:
    """The DG0 (m, m) Function of the matrices per cell (for the forms).

    Args:
        el: the CellElasticity (rows in Q's DG0 order).
        Q: the DG0 tensor space.

    Returns:
        The Function C(x).
    """
    m = el.m
    F = fem.Function(fem.TensorFunctionSpace(Q.mesh, ("DG", 0), shape=(m, m)), name="E")
    with el.rows():
        Cmats = el.Cmat
    F.x.array.reshape(-1, m * m)[cell_rows(F.function_space)] = \
        Cmats[cell_rows(Q)].reshape(-1, m * m)
    return F


def stress_operator(el: ElasticityForms, Q, E=None, nu=None):
    """The UFL operator tau -> E tau of the forms.

    Args:
        el: the elasticity.
        Q: the DG0 tensor space.
        E: for an isotropic homogeneous E, its Young's modulus (a Constant of the forms).
        nu: likewise its Poisson's ratio.

    Returns:
        The operator: the paper's elasticity_operator(E, nu) for Elasticity, else
        voigt_operator of a Constant matrix or of the DG0 field.
    """
    if isinstance(el, Elasticity):
        return elasticity_operator(E, nu, el.dim)
    if el.homogeneous:
        return voigt_operator(fem.Constant(Q.mesh, PETSc.ScalarType(el.Cmat)), el.dim)
    return voigt_operator(tensor_field(el, Q), el.dim)
