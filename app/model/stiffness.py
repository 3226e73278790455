"""The case's elasticity tensor E(x) (hypothesis H(E)) on the mesh: isotropic with numbers
(the paper's Elasticity, built by the step problem as before), isotropic with E, nu
expressions of x, y, z taken per cell (at the cell's midpoint: E in L-infinity, DG0),
orthotropic or a Voigt matrix (``material.elasticity``: the matrices of
app/case/anisotropy.py); and its UFL operator tau -> E tau for the forms.
"""
from __future__ import annotations

import logging
from dataclasses import asdict

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.case.anisotropy import elasticity_matrix, out_of_plane_row
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
)

log = logging.getLogger("vpcontact")


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
        ValueError: E <= 0 or nu out of range in a cell, or bad material.elasticity data
            (the message starts with the key).
    """
    plane = material.plane if dim == 2 else None
    state = f", plane {plane}" if dim == 2 else " (3D)"
    spec = getattr(material, "elasticity", None)
    if spec is not None:
        try:
            el = MatrixElasticity(elasticity_matrix(asdict(spec), dim, plane), dim)
        except ValueError as e:
            raise ValueError(f"material.elasticity.{e}") from None
        if plane == "strain" and spec.orthotropic is not None:    # sigma_33 of the outputs
            el.out_of_plane = out_of_plane_row(asdict(spec)["orthotropic"])
        return el.describe_as(*_described(spec, state))
    if isinstance(material.E, (int, float)) and isinstance(material.nu, (int, float)):
        return None
    msh = Q.mesh
    n = len(cell_rows(Q))
    E, nu = cell_values(material.E, msh, n), cell_values(material.nu, msh, n)
    for key, bad, why in (("E", ~(E > 0), "> 0"), ("nu", ~((nu >= 0) & (nu < 0.5)),
                                                        "in [0, 0.5)")):
        if msh.comm.allreduce(bool(bad.any()), op=MPI.LOR):
            raise ValueError(f"material.{key}: must be {why} in every cell of the mesh "
                             "(at the cells' midpoints)")
    Cmats = np.empty((n, 3 * dim - 3, 3 * dim - 3))
    Cmats[cell_rows(Q)] = isotropic_matrices(E, nu, dim, plane)
    return cell_elasticity(Cmats, dim, msh.comm).describe_as(
        f"isotropic per cell{state}", {"E": (material.E, "N/m^2"), "nu": (material.nu, "-")})


def _described(spec, state: str) -> tuple[str, dict]:
    """The name and constants of a material.elasticity section (the law report's)."""
    o = spec.orthotropic
    if o is None:
        return f"anisotropic (Voigt matrix){state}", {"voigt": (str(spec.voigt), "N/m^2")}
    consts = {}
    for key, names, unit in (("E", ("E1", "E2", "E3"), "N/m^2"),
                             ("nu", ("nu12", "nu13", "nu23"), "-"),
                             ("G", ("G12", "G13", "G23"), "N/m^2")):
        consts.update({k: (v, unit) for k, v in zip(names, getattr(o, key))})
    consts.update({f"a{i + 1}": (str(list(a)), "-") for i, a in enumerate(o.axes)})
    return f"orthotropic{state}", consts


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
    log.info("E per cell (%d distinct matrices on this rank's cells): sigma by the assembled "
             "D_sigma, Perzyna's explicit update in numpy (the compiled kernels take one E)",
             len(el.mats))
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
    Cmats = el.mats[el.index]
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
