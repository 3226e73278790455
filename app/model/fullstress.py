"""The full stress of a 2D state: sigma_33 and the 3D von Mises norm that every output shows
(solution.xdmf's sigma and sigma_vm, history.csv's max_vm, summary.json, the figures).

- 3D: sigma is the full tensor already.
- 2D plane stress (a thin plate): sigma_33 = 0 by definition; the paper's 2D norm is the 3D
  one of (sigma_11, sigma_22, 0, sigma_12).
- 2D plane strain (a long body, eps_33 = eps_13 = eps_23 = 0): sigma_33 follows from the 3D
  law at eps_33 = 0.  The 2D model's E is the in-plane block of the 3D C3 at eps_33 = 0
  (forms.elasticity.plane_strain_moduli, app/case/anisotropy.py) and sigma_n = E eps(u_n) +
  H_n (3.2) with H_n in-plane, so sigma = C3 (eps - eps_vp) restricted to the plane with the
  in-plane eps_vp = -E^-1 H_n and eps_vp33 = 0 is the only 3D state that gives the model's
  in-plane stress, unless the law carries its own eps_vp33 (then H_n holds its -lambda
  eps_vp33 I, app/model/planestrain.py).  Hence, per cell:
    isotropic E (its own nu in each cell):  sigma_33 = nu (sigma_11 + sigma_22) - E eps_vp33
      (eps_vp33: the kappa component of laws norton and chaboche; 0 for an elastic cell and
      for perzyna, power and python laws, whose creep strain is in-plane);
    orthotropic E with 3D data:  sigma_33 = r . t(sigma), r = C3[33, p] (C3[p, p])^-1 in
      the global axes (app/case/anisotropy.out_of_plane_row, p = (11, 22, 12));
    a 2D Voigt matrix (the in-plane law alone): no out-of-plane data, sigma_33 is unknown:
      NaN, and sigma_vm is the in-plane norm there (the log says so once).
  The von Mises norm is the 3D one of (sigma_11, sigma_22, sigma_33, sigma_12).
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from vpcontact.model.material import _von_mises_matrix
from vpcontact.model.planestrain import PlaneStrain, isotropic_rows, matrices

log = logging.getLogger("vpcontact")
M3 = _von_mises_matrix(3)[np.ix_([0, 1, 2, 5], [0, 1, 2, 5])]   # on (11, 22, 33, 12)


def eps_vp33_column(law) -> int | None:
    """The column of eps_vp33 in a law's kappa (laws norton, chaboche in plane strain).

    Args:
        law: a ViscoplasticLaw, or None.

    Returns:
        The column, or None if the law carries no eps_vp33.
    """
    if law is None or getattr(law, "plane_strain", None) is None:
        return None
    start = 0
    for name, size in getattr(law, "fields", ()):
        if name == "eps_vp33":
            return start
        start += size
    return None


class FullStress:
    """sigma_33 and the 3D von Mises norm of a 2D plane-strain state, per cell (the module
    docstring), over the rows of the DG0 fields (owned and ghost cells).

    Args:
        elasticity: the 2D model's E (Elasticity, MatrixElasticity or CellElasticity over
            every row); an orthotropic one carries ``out_of_plane`` (its row r).
        n: the number of rows.
        creep: [(rows, E, column)]: the rows whose law carries eps_vp33 in kappa's
            ``column``, E their 3D Young's modulus (a number or one per row).

    Attributes:
        r: (n, 3) sigma_33 = r . t(sigma) + creep terms; NaN rows: sigma_33 unknown.
        unknown: whether some row has no sigma_33 (a 2D Voigt matrix).
    """

    def __init__(self, elasticity, n: int, creep=()):
        self.r = np.full((n, 3), np.nan)
        C = np.broadcast_to(matrices(elasticity), (n, 3, 3)) if elasticity.homogeneous \
            else matrices(elasticity)[elasticity.index]
        iso = isotropic_rows(C)
        lmbda, two_mu = C[:, 0, 1], C[:, 2, 2]
        nu = lmbda / (2.0 * lmbda + two_mu)         # lambda / (2 (lambda + mu))
        self.r[iso, 0] = self.r[iso, 1] = nu[iso]
        self.r[iso, 2] = 0.0
        self.creep = list(creep)
        self.unknown = bool(np.isnan(self.r[:, 0]).any())

    def set_rows(self, rows: np.ndarray, r: np.ndarray) -> None:
        """Set the out-of-plane row of some cells (an orthotropic material's).

        Args:
            rows: row indices.
            r: (3,) sigma_33 = r . t(sigma) there.
        """
        self.r[rows] = r
        self.unknown = bool(np.isnan(self.r[:, 0]).any())

    def sigma_33(self, t: np.ndarray, kappa: np.ndarray | None) -> np.ndarray:
        """sigma_33 per row.

        Args:
            t: rows (n, 3) of the in-plane sigma in t-coordinates (11, 22, 12).
            kappa: (n, m) internal variables, or None without a law.

        Returns:
            (n,) sigma_33 (NaN where unknown).
        """
        s33 = np.einsum("ni,ni->n", self.r, t)
        for rows, E, col in self.creep:
            E_rows = E if np.ndim(E) == 0 else np.asarray(E)[rows]
            s33[rows] -= E_rows * kappa[rows, col]
        return s33

    def von_mises(self, t: np.ndarray, s33: np.ndarray) -> np.ndarray:
        """The 3D von Mises norm of (sigma_11, sigma_22, sigma_33, sigma_12) per row (the
        in-plane one, sigma_33 = 0, where sigma_33 is unknown).

        Args:
            t: rows (n, 3) of the in-plane sigma (11, 22, 12).
            s33: (n,) sigma_33.

        Returns:
            (n,) ||sigma||_VM.
        """
        s = np.column_stack([t[:, 0], t[:, 1], np.nan_to_num(s33, nan=0.0), t[:, 2]])
        return np.sqrt(np.maximum(np.einsum("ni,ij,nj->n", s, M3, s), 0.0))


def full_stress(problem) -> FullStress | None:
    """The FullStress of a 2D plane-strain problem (None in 3D and plane stress).

    Args:
        problem: the ContactProblem (its elasticity, law, materials and case).

    Returns:
        A FullStress over the rows of the DG0 fields, or None.
    """
    case = problem.case
    if problem.disc.dim != 2 or case.all_materials[0].plane != "strain":
        return None
    n = len(problem.disc.Y.dofmap.list.array)
    groups = problem.materials.groups if problem.materials else None
    pieces = [(g.rows, g.law, g.elasticity) for g in groups] if groups else \
        [(np.arange(n), problem.law, problem.elasticity)]
    creep = []
    for rows, law, _ in pieces:
        col = eps_vp33_column(law)
        if col is not None:
            creep.append((rows, _young(law.plane_strain), col))
    fs = FullStress(problem.elasticity, n, creep)
    for rows, _, el in pieces:
        r = getattr(el, "out_of_plane", None)
        if r is not None:
            fs.set_rows(rows, r)
    comm = problem.disc.comm
    unknown = comm.allreduce(fs.unknown, op=MPI.LOR)
    if unknown and comm.rank == 0:
        log.warning("plane strain with a 2D Voigt matrix (material.elasticity.voigt): no "
                    "out-of-plane data, so sigma_33 is written NaN and sigma_vm is the "
                    "in-plane norm (sigma_33 = 0) in its cells")
    return fs


def _young(plane_strain: PlaneStrain):
    """The 3D Young's modulus of a law's PlaneStrain (a number, or one per row)."""
    return plane_strain.young_poisson()[0]
