"""Derived fields that solution.xdmf writes beside the State's own (the user guide's
outputs section lists them with units): the full stress sigma (in 2D plane strain with
sigma_33 of app/model/fullstress.py), the body's material id, the strain eps(u), the
viscoplastic strain eps_vp and the nodal averaged stress sigma_nodal.  A scene writes only
what it has: no material id for a body of one physical group, no eps_vp without a law;
cells without a law (an elastic material of several) carry NaN in eps_vp and kappa, which
ParaView shows as absent.

dolfinx 0.5 writes a 2D DG0 d x d tensor per cell as 9 components (row-major 3 x 3) with
the out-of-plane ones 0, and a 3 x 3 tensor on a 2D mesh not per cell at all; so in plane
strain ``sigma`` and ``eps_vp`` are written by dolfinx and their component 8 (the 33 one)
replaced after (FieldWriter.write's ``columns``): the files keep their size and layout.
"""
from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from vpcontact.post.recovery import LumpedProjection, space_indicators


def owned_rows(disc) -> np.ndarray:
    """The rows of the DG0 fields of the owned cells, in local cell order (the file's).

    Args:
        disc: the Discretisation.

    Returns:
        (owned cells,) row indices.
    """
    return np.asarray(disc.Y.dofmap.list.array)[:disc.num_owned_cells]


class StressOutput:
    """The columns of the written ``sigma`` to replace: none in 3D (the full tensor) and 2D
    plane stress (sigma_33 = 0 by definition); in 2D plane strain sigma_33 (component 8).

    Args:
        problem: the ContactProblem (its sigma, sigma_33 and owned cells).
    """

    def __init__(self, problem):
        self.problem = problem
        self.functions = []

    def update(self) -> None:
        """Nothing to copy: dolfinx writes the State's sigma."""

    def columns(self) -> dict:
        """The replaced components, for FieldWriter.write.

        Returns:
            {("sigma", 8): sigma_33 of the owned cells in local cell order}, or {}.
        """
        p = self.problem
        if p.sigma_33 is None:
            return {}
        return {("sigma", 8): p.sigma_33.x.array[owned_rows(p.disc)]}


def law_rows(problem) -> np.ndarray | None:
    """Which rows of the DG0 fields have which internal variables (collective: the answer
    None is the same on every rank, so that every rank builds the same output Functions).

    Args:
        problem: the ContactProblem.

    Returns:
        (rows, m) booleans (a material's law has the first m_g of kappa's m components; an
        elastic material none), or None: every row of every rank has all (one law for the
        body, or materials whose laws all have m variables).
    """
    groups = problem.materials.groups if problem.materials else None
    if problem.law is None or not groups:
        return None
    has = np.zeros((len(problem.disc.Y.dofmap.list.array), problem.law.m), dtype=bool)
    for g in groups:
        if g.law is not None:
            has[g.rows, :g.law.m] = True
    every = problem.disc.comm.allreduce(bool(has.all()), op=MPI.LAND)
    return None if every else has


class MaterialOutput:
    """``material``: the physical tag of each cell's group (DG0 scalar; NaN for a cell
    without one), written only if the body has several physical groups of cells (two
    bodies, several materials): threshold one body or material in ParaView.

    Args:
        problem: the ContactProblem (its body's cell tags).
    """

    def __init__(self, problem):
        self.functions = []
        disc = problem.disc
        ct = getattr(disc.body, "cell_tags", None)
        if ct is None:
            return
        tags = np.unique(np.asarray(ct.values))
        every = set().union(*disc.comm.allgather(set(tags.tolist())))
        if len(every) < 2:
            return
        f = fem.Function(disc.Y, name="material")
        f.x.array[:] = np.nan
        f.x.array[np.asarray(disc.Y.dofmap.list.array)[ct.indices]] = ct.values
        self.functions = [f]

    def update(self) -> None:
        """Nothing changes with time."""

    def columns(self) -> dict:
        """Returns: {} (nothing replaced)."""
        return {}


class StrainOutput:
    """``eps``: the strain eps(u) per cell (DG0 d x d tensor, dimensionless); ``eps_vp``
    with a viscoplastic law: the inelastic strain eps(u) - E^-1 sigma per cell, in 2D plane
    strain eps(u) - E^-1 (sigma + lambda eps_vp33 I) with eps_vp33 of laws norton and
    chaboche (0 for the others) in its component 33 (app/model/fullstress.py); NaN in cells
    without a law.  In 2D plane strain eps_33 = 0; in plane stress the 33 components are
    not computed (written 0).

    Args:
        problem: the ContactProblem.
    """

    def __init__(self, problem):
        self.problem = problem
        disc = problem.disc
        self.eps = fem.Function(disc.Q, name="eps")
        self.functions = [self.eps]
        self.eps_vp = None
        if problem.law is not None:
            self.eps_vp = fem.Function(disc.Q, name="eps_vp")
            self.functions.append(self.eps_vp)
            has = law_rows(problem)
            self.absent = None if has is None else ~has[:, 0]
            self.compliance = _compliances(problem.elasticity)
            self.eps_vp33 = np.zeros(len(disc.Y.dofmap.list.array))

    def update(self) -> None:
        """eps(u), eps_vp from u, sigma and kappa (owned and ghost cells)."""
        p = self.problem
        el = p.elasticity
        t_eps = p.strain_voigt()
        self.eps.x.array[:] = el.from_voigt(t_eps).reshape(-1)
        if self.eps_vp is None:
            return
        t_sig = el.to_voigt(p.sigma.x.array).copy()
        self.eps_vp33[:] = 0.0
        fs = p.full_stress
        for rows, _, col in (fs.creep if fs is not None else ()):
            e33 = p.state.kappa_cells[rows, col]
            lmbda = _lame_lambda(el, rows)
            t_sig[rows, :2] += (lmbda * e33)[:, None]
            self.eps_vp33[rows] = e33
        vp = t_eps - np.einsum("nij,nj->ni", self.compliance, t_sig)
        if self.absent is not None:
            vp[self.absent] = np.nan
            self.eps_vp33[self.absent] = np.nan
        self.eps_vp.x.array[:] = el.from_voigt(vp).reshape(-1)

    def columns(self) -> dict:
        """The replaced components, for FieldWriter.write.

        Returns:
            In 2D plane strain {("eps_vp", 8): eps_vp33 of the owned cells}, else {}.
        """
        p = self.problem
        if self.eps_vp is None or p.sigma_33 is None:
            return {}
        return {("eps_vp", 8): self.eps_vp33[owned_rows(p.disc)]}


def _compliances(elasticity) -> np.ndarray:
    """E^-1 of every row in t-coordinates, (rows, m, m) (a view for a homogeneous E)."""
    if elasticity.homogeneous:
        return np.linalg.inv(np.asarray(elasticity.Cmat, dtype=float))[None]
    return np.linalg.inv(np.asarray(elasticity.mats, dtype=float))[elasticity.index]


def _lame_lambda(elasticity, rows: np.ndarray) -> np.ndarray:
    """The 3D Lame lambda of a 2D plane-strain isotropic E in some rows (its C[0, 1])."""
    if elasticity.homogeneous:
        return np.full(len(rows), float(elasticity.Cmat[0, 1]))
    return np.asarray(elasticity.mats)[elasticity.index[rows], 0, 1]


class NodalStressOutput:
    """``sigma_nodal``: the stress averaged at the nodes (P1 tensor, N/m^2), the L2
    projection of the DG0 sigma onto P1 with the lumped (row-sum) mass: sigma_i = (sigma,
    phi_i) / (1, phi_i), the volume-weighted mean of the cells around node i (a uniform
    stress is reproduced exactly; app/post/recovery.py: LumpedProjection).  In 2D plane
    strain a 3 x 3 tensor with sigma_33; in 2D plane stress the 2 x 2 one (sigma_33 = 0).

    Args:
        problem: the ContactProblem.
    """

    def __init__(self, problem):
        self.problem = problem
        d, full = problem.disc.dim, problem.sigma_33 is not None
        shape = (3, 3) if full else (d, d)
        msh = problem.disc.mesh
        self.cells = fem.Function(fem.TensorFunctionSpace(msh, ("DG", 0), shape=shape))
        self.projection = LumpedProjection(msh, self.cells, shape, name="sigma_nodal")
        self.nodal = self.projection.nodal
        self.functions = [self.nodal]

    def update(self) -> None:
        """Project the current sigma (with sigma_33 in plane strain) onto P1 (collective)."""
        p = self.problem
        d = p.disc.dim
        if p.sigma_33 is None:
            self.cells.x.array[:] = p.sigma.x.array
        else:
            c = self.cells.x.array.reshape(-1, 3, 3)
            c[:, :d, :d] = p.sigma.x.array.reshape(-1, d, d)
            c[:, 2, 2] = p.sigma_33.x.array
        self.projection.update()

    def columns(self) -> dict:
        """Returns: {} (nothing replaced)."""
        return {}


class EtaOutput:
    """``eta``: the space error indicator per cell (DG0 scalar), (eta_Q,K^2 + eta_V,K^2 +
    eta_Y,K^2)^(1/2) of app/post/recovery.py (the stress, strain and kappa parts of the
    paper's error measure, each against its recovered nodal field).

    Args:
        problem: the ContactProblem.
    """

    def __init__(self, problem):
        self.problem = problem
        self.indicators = space_indicators(problem)   # the estimate's: computed once a step
        self.eta = fem.Function(problem.disc.Y, name="eta")
        self.functions = [self.eta]

    def update(self) -> None:
        """eta of the owned cells from the current state (collective)."""
        eta2 = self.indicators.update()
        self.eta.x.array[owned_rows(self.problem.disc)] = np.sqrt(eta2.sum(axis=1))

    def columns(self) -> dict:
        """Returns: {} (nothing replaced)."""
        return {}


def derived_outputs(problem) -> list:
    """The derived fields of a problem's solution.xdmf, in the written order.

    Args:
        problem: the ContactProblem.

    Returns:
        [StressOutput, MaterialOutput, StrainOutput, NodalStressOutput, EtaOutput]: each with
        ``functions`` (what it writes, possibly none), ``update()`` and ``columns()``.
    """
    return [StressOutput(problem), MaterialOutput(problem), StrainOutput(problem),
            NodalStressOutput(problem), EtaOutput(problem)]
