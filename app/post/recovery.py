"""Recovery of nodal fields and the space error indicators of Zienkiewicz-Zhu type
(docs/model.md, "Error estimates").

The recovered field f* of a cellwise field f_h is its L2 projection onto P1 with the lumped
(row-sum) mass: f*_i = (f_h, phi_i) / (1, phi_i), the volume-weighted mean of the cells
around node i; a uniform field is reproduced exactly.  ``sigma_nodal`` of solution.xdmf is
this projection of sigma (app/post/outputfields.py), and the space indicators compare the
three fields of the paper's error measure with theirs, cell by cell:

    eta_Q,K = ||sigma* - sigma_h||_L2(K)          (Frobenius, the norm ||.||_Q)
    eta_V,K = ||eps(u_h)* - eps(u_h)||_L2(K)     (the recovered gradient, ||.||_V)
    eta_Y,K = ||kappa* - kappa_h||_L2(K)          (Euclidean over kappa's m components)

integrated exactly (f* is P1, f_h constant on K: quadrature of degree 2).  The recovered
strain is the projection of eps(u_h) itself, not E^-1 (sigma* - H): the latter would only
rescale eta_Q and carry the jumps of the cellwise H; the former measures ||.||_V's own
discretisation error.  The contact boundary gives the cells at Gamma3 a fourth indicator
(``ContactJump``), eta_C,K^2 = h_K ||sigma* nu - t_h||^2 over their Gamma3 facets, t_h the
discrete contact traction, as the boundary jumps of residual estimators; a part of the
stress error, it enters the estimate as (eta_Q^2 + eta_C^2)^(1/2).

A problem has one SpaceIndicators (``space_indicators``), shared by the estimate of every
step and the ``eta`` output; it recomputes only when u, sigma or kappa changed, so an
output step projects once.
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.la import ScatterMode
from mpi4py import MPI

from vpcontact.post.quantities import contact_table

_ADD = ScatterMode.add


def _space(msh, family: str, shape: tuple):
    """A P1 or DG0 space of scalars (shape ()), vectors (m,) or tensors (d, d)."""
    if not shape:
        return fem.FunctionSpace(msh, (family, (1 if family == "CG" else 0)))
    if len(shape) == 1:
        return fem.VectorFunctionSpace(msh, (family, (1 if family == "CG" else 0)),
                                       dim=shape[0])
    return fem.TensorFunctionSpace(msh, (family, (1 if family == "CG" else 0)), shape=shape)


class LumpedProjection:
    """The lumped-mass L2 projection onto P1 of a cellwise UFL expression f_h:
    f*_i = (f_h, phi_i) / (1, phi_i) (collective).

    Args:
        msh: the mesh.
        expr: the UFL expression of f_h (constant on each cell).
        shape: its value shape: () a scalar, (m,) a vector, (d, d) a tensor.
        name: the name of the P1 Function f*.
    """

    def __init__(self, msh, expr, shape: tuple, name: str = "recovered"):
        T = _space(msh, "CG", shape)
        self.nodal = fem.Function(T, name=name)
        self.expr = expr
        self.rhs = fem.form(ufl.inner(expr, ufl.TestFunction(T)) * ufl.dx)
        W = fem.FunctionSpace(msh, ("CG", 1))
        mass = fem.assemble_vector(fem.form(ufl.TestFunction(W) * ufl.dx))
        mass.scatter_reverse(_ADD)
        mass.scatter_forward()
        self.mass = np.repeat(mass.array, int(np.prod(shape, dtype=int)))

    def update(self) -> None:
        """f* from the current f_h, ghosts included (collective)."""
        b = fem.assemble_vector(self.rhs)
        b.scatter_reverse(_ADD)
        b.scatter_forward()
        self.nodal.x.array[:] = b.array / self.mass


class SpaceIndicators:
    """The indicators eta_Q,K, eta_V,K, eta_Y,K of a problem's state (module docstring).

    Args:
        problem: the ContactProblem (its u, sigma and State's kappa).
    """

    def __init__(self, problem):
        disc = problem.disc
        d, msh = disc.dim, disc.mesh
        self.comm, self.owned = disc.comm, disc.num_owned_cells
        kappa = problem.state.kappa
        fields = [(problem.sigma, (d, d)), (ufl.sym(ufl.grad(problem.u)), (d, d))]
        if kappa is not None:
            fields.append((kappa, tuple(kappa.ufl_shape)))
        self.projections = [LumpedProjection(msh, f, s) for f, s in fields]
        E = fem.VectorFunctionSpace(msh, ("DG", 0), dim=4)
        w = ufl.TestFunction(E)
        form = sum(ufl.inner(pr.nodal - pr.expr, pr.nodal - pr.expr) * w[i]
                   for i, pr in enumerate(self.projections))
        self.contact = ContactJump(problem, self.projections[0].nodal)
        if self.contact.active:
            form = form * ufl.dx(metadata={"quadrature_degree": 2}) + self.contact.form(w[3])
        else:
            form = form * ufl.dx(metadata={"quadrature_degree": 2})
        self.form = fem.form(form)
        self.rows = np.asarray(E.dofmap.list.array)[:self.owned]
        self.inputs = [problem.u, problem.sigma] + ([kappa] if kappa is not None else [])
        self.seen, self.eta2 = None, None

    def update(self) -> np.ndarray:
        """The squared indicators of the owned cells, recomputed only if u, sigma or kappa
        changed since the last call on some rank (collective).

        Returns:
            (owned cells, 4): eta_Q,K^2, eta_V,K^2, eta_Y,K^2 (0 without kappa), eta_C,K^2
            (the contact boundary's, ``ContactJump``; 0 without Gamma3), in local
            cell order (a copy).
        """
        now = [f.x.array for f in self.inputs]
        same = self.seen is not None and all(np.array_equal(a, b)
                                             for a, b in zip(now, self.seen))
        if not self.comm.allreduce(same, op=MPI.LAND):
            for pr in self.projections:
                pr.update()
            self.contact.update()
            b = fem.assemble_vector(self.form)        # cell integrals: the owned cells
            self.eta2 = b.array.reshape(-1, 4)[self.rows]
            self.seen = [a.copy() for a in now]
        return self.eta2.copy()

    def norms(self, eta2: np.ndarray) -> np.ndarray:
        """The global estimates (sum over the cells of all ranks; collective).

        Args:
            eta2: ``update()``'s squared indicators.

        Returns:
            (4,): eta_Q, eta_V, eta_Y, eta_C.
        """
        return np.sqrt(self.comm.allreduce(eta2.sum(axis=0), op=MPI.SUM))


class ContactJump:
    """The contact boundary's indicator eta_C,K^2 = h_K ||sigma* nu - t_h||^2_L2(F) over the Gamma3
    facets F of cell K, the recovered stress's traction against the discrete contact
    traction t_h = r_i / w_i at the Gamma3 nodes (the bulk residual over the nodal rule's
    weight: p_n nu + sigma_tau of the laws, or the bound's multiplier), P1 on Gamma3.  One
    body only (pairs: none).  (The contact table's sign: -sigma_nu, -sigma_tau.)

    Args:
        problem: the ContactProblem.
        recovered: sigma*, the P1 tensor of the recovery.
    """

    def __init__(self, problem, recovered):
        self.problem, self.recovered = problem, recovered
        disc = problem.disc
        self.active = disc.gamma3 is not None and disc.pairs is None
        if self.active:
            self.traction = fem.Function(disc.V, name="contact_traction")

    def form(self, w):
        """The facet integral of the contact boundary term.

        Args:
            w: a DG0 test function.

        Returns:
            The UFL form h (sigma* nu - t_h)^2 w ds over Gamma3.
        """
        p, msh = self.problem, self.problem.disc.mesh
        nu, h = ufl.FacetNormal(msh), ufl.CellDiameter(msh)
        jump = ufl.dot(self.recovered, nu) - self.traction
        ds = ufl.Measure("ds", domain=msh, subdomain_data=p.disc.body.facet_tags,
                         metadata={"quadrature_degree": 2})
        return h * ufl.inner(jump, jump) * w * ds(p.disc.gamma3_tags)

    def update(self) -> None:
        """t_h from the current state: -(neg_sigma_nu nu + neg_sigma_tau tau) of the contact
        table (app/post/quantities.py: at a node a Dirichlet condition holds, the laws'
        friction, not the support's reaction); collective."""
        if not self.active:
            return
        p = self.problem
        disc = p.disc
        gm, fr = disc.gamma3, disc.frames
        table = contact_table(p)
        pos = np.searchsorted(fr.nodes, gm.nodes)
        sfx = [""] if disc.dim == 2 else ["1", "2"]
        t = -table["neg_sigma_nu"][:, None] * fr.normal[pos] - sum(
            table[f"neg_sigma_tau{x}"][:, None] * fr.tangents[pos][:, k]
            for k, x in enumerate(sfx))
        values = self.traction.x.array.reshape(-1, disc.dim)
        values[:] = 0.0
        values[gm.nodes] = t
        self.traction.x.scatter_forward()


def space_indicators(problem) -> SpaceIndicators:
    """The problem's one SpaceIndicators, built on first use (collective then).

    Args:
        problem: the ContactProblem.

    Returns:
        The SpaceIndicators the estimate and the ``eta`` output share.
    """
    found = getattr(problem, "space_indicators", None)
    if found is None:
        found = problem.space_indicators = SpaceIndicators(problem)
    return found
