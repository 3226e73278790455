"""The condensed solver for two bodies in contact (``contact.pairs``): (3.4) condensed in the
unknown x of app/solvers/pairmap.py, in which the pairs' bound is a box.

With u = P x + c and w = C x (``PairVariables``), the step problem of the explicit scheme is
    min_x  1/2 x^T K_x x - F_x^T x + sum_i w_i phi_i((C x)_i),   sign_i x_slot,i <= g_i,
K_x = P^T K P (the Dirichlet rows and columns the identity, as in SNES VI's Newton matrix),
F_x = P^T (F_n - K (c + P x_D)) with x_D the prescribed values (the lifting; F_x = x_D at
those dofs): ``PairRightHandSide``.  The contact energy reads w at the surface nodes only,
and C couples them to the target nodes of their projections, so the problem condenses onto
G = the surface nodes and the target nodes C couples them to (``PairLayout``): with S the
Schur complement of K_x on G and y0 = (K_x^-1 F_x)_G,
    min_y  1/2 (y - y0)^T S (y - y0) + sum_i w_i phi_i((C_G y)_i),   the box on the slots,
C_G the rows of C at the surface nodes restricted to G (``PairCoupling``: sparse, rotated
into the frames T_i = (nu_i, the tangents) so that the nodal energy sees the normal e_0).
Its gradient is C_G^T grad and its Hessian S + C_G^T W C_G (``PairNewtonDirection``: dense,
like S).  The surface node's non-slot components in x are not relative (they stay u,
rotated), which is why C_G is needed: a prescribed component there stays a fixed dof of y.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from petsc4py import PETSc

from vpcontact.solvers.condensed.frames import WorkFrames, normal_first
from vpcontact.solvers.condensed.layout import Gamma3Layout
from vpcontact.solvers.dense import (  # the one-body direction's kept factor and CG
    PCG_MIN,
    ProjectedDirection,
    _Kept,
    cholesky_solve,
    symmetric_product,
)
from vpcontact.solvers.nodal import NodalContact
from vpcontact.threads import GAMMA3_ROOT


class PairRightHandSide:
    """F_x = -P^T F_bulk(P x_D + c), F_x = x_D at the Dirichlet dofs (collective): the bulk
    residual of SNES VI's PairMap at x = x_D, whose negative is F_n - K (c + P x_D).

    Args:
        problem: the ContactProblem (u, forms.bulk_residual, bcs).
        pv: the PairVariables.
    """

    def __init__(self, problem, pv):
        self.problem, self.pv = problem, pv
        self.F_bulk = fem.form(problem.forms.bulk_residual)
        self.b_u = fem.petsc.create_vector(self.F_bulk)
        self.z, self.saved = pv.c.duplicate(), problem.u.vector.copy()

    def assemble(self, b: PETSc.Vec) -> None:
        """b = F_x for the current time data and history (u is left as it was).

        Args:
            b: a vector of x's layout, overwritten.
        """
        p, pv, z = self.problem, self.pv, self.z
        p.u.vector.copy(self.saved)
        z.set(0.0)
        pv.fix(z)                                   # x_D (and the caps' fixed values)
        pv.to_u(z, p.u)
        with self.b_u.localForm() as loc:
            loc.set(0.0)
        fem.petsc.assemble_vector(self.b_u, self.F_bulk)
        self.b_u.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self.saved.copy(p.u.vector)
        p.u.x.scatter_forward()
        pv.P.multTranspose(self.b_u, b)
        b.scale(-1.0)
        if pv.caps is not None:                     # the caps' loads at their amplitudes
            pv.caps.add_loads(b, pv.time, 1.0)
        b.array[pv.dirichlet] = z.array_r[pv.dirichlet]

    def destroy(self) -> None:
        """Free the PETSc vectors."""
        for obj in (self.b_u, self.z, self.saved):
            obj.destroy()


def pair_stiffness(pv) -> PETSc.Mat:
    """K_x = P^T K P with the Dirichlet rows and columns the identity (collective).

    Args:
        pv: the PairVariables.

    Returns:
        The assembled AIJ matrix.
    """
    K = pv.bulk_stiffness()
    K.zeroRowsColumns(pv.dirichlet_global, diag=1.0)
    return K


def _surface_rows(disc, pv) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """C's rows at this rank's owned surface nodes as (local row, global column, value),
    the rows numbered d i + a for the i-th owned surface node (``disc``: the
    Discretisation)."""
    d = disc.dim
    indptr, indices, data = pv.C.getValuesCSR()
    rows = (disc.gamma3.nodes[:, None] * d + np.arange(d)).ravel()
    counts = indptr[rows + 1] - indptr[rows]
    at = np.concatenate([np.arange(indptr[r], indptr[r + 1]) for r in rows] or
                        [np.zeros(0, np.int64)]).astype(np.int64)
    return np.repeat(np.arange(len(rows)), counts), indices[at].astype(np.int64), data[at]


class PairLayout(Gamma3Layout):
    """G of two bodies: the surface nodes and the target nodes that C couples them to, in
    the order of their global numbers (collective).

    Attributes:
        surface: the Gamma3Layout of the surface nodes alone (their weights, the nodal
            fields xi and theta, the order of the nodal energy).
        coupling: the PairCoupling (C_G in the work frames, on GAMMA3_ROOT).

    Args:
        disc: the Discretisation with pairs.
        pv: the PairVariables.
        row_start: the first global row of K_x this rank owns.
    """

    def __init__(self, disc, pv, row_start: int):
        d, imap = disc.dim, disc.V.dofmap.index_map
        self.surface = Gamma3Layout(disc, row_start)
        rows, cols, vals = _surface_rows(disc, pv)
        glob = np.unique(np.concatenate(disc.comm.allgather(np.unique(np.concatenate(
            [cols // d, self.surface.g_nodes])))))
        lo, hi = imap.local_range
        mine = glob[(glob >= lo) & (glob < hi)] - lo
        super().__init__(disc, row_start, nodes=mine.astype(np.int32),
                         weight=np.zeros(len(mine)))
        # C_G rotated: rows T_i^T C_i of the owned surface nodes, columns at G positions
        fr = disc.frames
        T, _ = normal_first(fr, np.searchsorted(fr.nodes, disc.gamma3.nodes))
        node, comp = rows // d, rows % d
        col = np.searchsorted(self.g_nodes, cols // d) * d + cols % d
        # (T_i^T C_i)[b, :] = sum_a T_i[a, b] C_i[a, :]
        r_w = (node[:, None] * d + np.arange(d)).ravel()
        v_w = (T[node, comp, :] * vals[:, None]).ravel()
        c_w = np.repeat(col, d)
        surf_rows = self.surface.owned_positions[r_w]
        self.coupling = PairCoupling.gather(self.comm, surf_rows, c_w, v_w,
                                            self.surface.m, self.m, d)


class PairCoupling:
    """C_G in the work frames (sparse, n_s d x m) on GAMMA3_ROOT (None elsewhere): the
    map from y to the nodal w of the surface nodes, w_i = T_i^T (C_G y)_i.

    Args:
        Cw: the scipy CSR matrix, or None off the root.
        m: the dofs of G.
        d: the dofs per node.
    """

    def __init__(self, Cw, m: int, d: int):
        self.Cw, self.m, self.d = Cw, m, d

    @classmethod
    def gather(cls, comm, rows, cols, vals, n_rows: int, m: int, d: int) -> PairCoupling:
        """Assemble C_G on GAMMA3_ROOT from the ranks' triplets (duplicates summed;
        collective).

        Args:
            comm: the communicator.
            rows, cols, vals: this rank's entries (surface rows, G columns).
            n_rows: n_s d.
            m: the dofs of G.
            d: the dofs per node.

        Returns:
            The PairCoupling.
        """
        from scipy.sparse import coo_matrix
        parts = comm.gather((rows, cols, vals), root=GAMMA3_ROOT)
        if parts is None:
            return cls(None, m, d)
        r, c, v = (np.concatenate([p[k] for p in parts]) for k in range(3))
        Cw = coo_matrix((v, (r, c)), shape=(n_rows, m)).tocsr()
        Cw.sum_duplicates()
        return cls(Cw, m, d)

    def direction(self, S: np.ndarray) -> PairNewtonDirection:
        """The Newton direction of the Gamma3 problem with this coupling (on the root).

        Args:
            S: the Schur complement (m, m).

        Returns:
            The PairNewtonDirection.
        """
        return PairNewtonDirection(S, self.Cw, self.d)

    def contact(self, w: np.ndarray, normal: np.ndarray, law) -> PairContact:
        """The contact energy of y.

        Args:
            w: the surface nodes' weights (surface order).
            normal: the normal of the work frames, e_0.
            law: the ContactLaw of every surface node, or with laws per pair the
                ``PairSection`` list (``pair_sections``).

        Returns:
            The PairContact.
        """
        from vpcontact import kernels
        sections = law if isinstance(law, list) else [PairSection(None, law)]
        return PairContact(sections, w, normal, self.Cw, self.d, kernels.load())


@dataclass
class PairSection:
    """The surface nodes of one set of laws (``Contact.sections``) and the laws.

    Attributes:
        nodes: their positions in the surface order (None: all).
        law: their ContactLaw.
        xi, theta: whether the laws take the memory term and the slip factor.
    """

    nodes: np.ndarray | None
    law: object
    xi: bool = True
    theta: bool = True


def pair_sections(problem, surface) -> list[PairSection] | None:
    """The laws per pair (``ContactProblem.section_laws``) at their surface nodes, or None
    where one set of laws serves every pair (collective).

    Args:
        problem: the ContactProblem with pairs.
        surface: the surface nodes' Gamma3Layout.

    Returns:
        A PairSection per pair in the pairs' order, or None.
    """
    sections = problem.case.contact.sections
    if len(sections) == 1:
        return None
    disc = problem.disc
    d, n = disc.dim, len(surface.g_nodes)
    owned = np.searchsorted(disc.gamma3_local_nodes, disc.gamma3.nodes)
    pair = surface.place_on_all(surface.local_owned_g, disc.pairs.pair[owned], n,
                                dtype=np.int64)
    x = surface.place_on_all(surface.local_owned_g, disc.gamma3.x, (n, d))
    out = []
    for k, section in enumerate(sections):
        nodes = np.flatnonzero(pair == k)
        fr = section.friction
        out.append(PairSection(nodes, problem.section_laws(x=x[nodes])[k],
                               section.memory is not None,
                               fr is not None and (fr.slip is not None
                                                   or fr.coulomb is not None)))
    return out


class PairContact:
    """sum_i w_i phi_i(w_i) with w = C_G y in the work frames, its gradient C_G^T grad and
    the nodal Hessian blocks W of the surface nodes (the Newton matrix is S + C_G^T W C_G),
    each node with its pair's laws.  ``xi`` and ``theta`` are set in the surface order.

    Args:
        sections: the PairSections.
        w: the surface nodes' weights.
        normal: the normal of the work frames, e_0.
        Cw: C_G (scipy CSR, n_s d x m), or None off the root (never evaluated there).
        d: the dofs per node.
        module: the compiled kernels, or None.
    """

    def __init__(self, sections, w, normal, Cw, d: int, module):
        self.Cw, self.d, self.sections = Cw, d, sections
        self.nodal = [NodalContact(w if s.nodes is None else w[s.nodes], normal, s.law,
                                   module) for s in sections]
        self._xi = self._theta = None

    @property
    def xi(self):
        """The memory term xi_n at the surface nodes."""
        return self._xi

    @xi.setter
    def xi(self, value):
        self._xi = value
        for s, nodal in zip(self.sections, self.nodal):
            nodal.xi = None if not s.xi else value if s.nodes is None else value[s.nodes]

    @property
    def theta(self):
        """The slip factor theta(s_n) (times mu p_n with Coulomb) at the surface nodes."""
        return self._theta

    @theta.setter
    def theta(self, value):
        self._theta = value
        for s, nodal in zip(self.sections, self.nodal):
            nodal.theta = None if not s.theta else value if s.nodes is None \
                else value[s.nodes]

    def evaluate(self, y, need_hessian=True):
        """The energy and its derivatives at y.

        Args:
            y: the values of G, shape (m / d, d).
            need_hessian: whether to compute the Hessian blocks.

        Returns:
            (energy, gradient (m / d, d), the surface nodes' Hessian blocks (n_s, d, d) or
            None).
        """
        w = (self.Cw @ y.ravel()).reshape(-1, self.d)
        if len(self.nodal) == 1:
            e, g, H = self.nodal[0].evaluate(w, need_hessian)
        else:
            e, g = 0.0, np.zeros_like(w)
            H = np.zeros((len(w), self.d, self.d)) if need_hessian else None
            for s, nodal in zip(self.sections, self.nodal):
                e_s, g[s.nodes], H_s = nodal.evaluate(w[s.nodes], need_hessian)
                e += e_s
                if need_hessian:
                    H[s.nodes] = H_s
        return e, (self.Cw.T @ g.ravel()).reshape(-1, self.d), H


class PairNewtonDirection(ProjectedDirection):
    """p = -(S + C_G^T W C_G)_ff^-1 g_f on the free dofs, 0 on the binding ones, for a fixed
    S: dense Cholesky (LAPACK), and from PCG_MIN dofs CG preconditioned by the kept factor
    (dense.ProjectedDirection, as the one-body dense.NewtonDirection).

    Args:
        S: the Schur complement (m x m, symmetric).
        Cw: C_G (scipy CSR, n_s d x m).
        d: the dofs per node.
    """

    def __init__(self, S: np.ndarray, Cw, d: int):
        from scipy.sparse import bsr_matrix
        self.S, self.Cw, self.d = np.ascontiguousarray(S, dtype=float), Cw, d
        self.m = S.shape[0]
        self.product = symmetric_product(self.S)
        n = Cw.shape[0] // d
        self._blocks = lambda W: bsr_matrix((np.asarray(W, dtype=float), np.arange(n),
                                             np.arange(n + 1)), shape=(n * d, n * d))
        self._kept = None
        self.factorisations = self.cg_iterations = 0

    def _coupled(self, W: np.ndarray):
        """C_G^T W C_G (scipy sparse, m x m)."""
        return (self.Cw.T @ (self._blocks(W) @ self.Cw)).tocsr()

    def matrix(self, W: np.ndarray) -> np.ndarray:
        """S + C_G^T W C_G.

        Args:
            W: the surface nodes' Hessian blocks (n_s, d, d).

        Returns:
            The Newton matrix (a new m x m array).
        """
        CWC = self._coupled(W).tocoo()
        H = self.S.copy()
        np.add.at(H, (CWC.row, CWC.col), CWC.data)
        return H

    def _factorise(self, W, g, free):
        """The direction by a new Cholesky factorisation (kept where m >= PCG_MIN)."""
        from scipy.linalg.lapack import dpotrf
        self.factorisations += 1
        self._kept = None
        L, info = dpotrf(self.matrix(W)[np.ix_(free, free)], lower=1, clean=1)
        if info != 0:
            return None
        p = np.zeros(self.m)
        p[free] = -cholesky_solve(L, g[free])
        if self.m >= PCG_MIN:
            self._kept = _Kept(L, free, self.m)
        return p

    def _contact(self, W):
        """(free -> C_G^T W C_G's diagonal there, x -> C_G^T W C_G x)."""
        CWC = self._coupled(W)
        return (lambda free: CWC.diagonal()[free], lambda x: CWC @ x)


def pair_frames(disc, layout: PairLayout) -> WorkFrames:
    """The Gamma3 problem's coordinates of two bodies: x itself (T = None), the box
    sign_i y_slot <= g at the surface nodes that carry the bound, the Dirichlet dofs of G
    fixed, the normal e_0 of the work frames of PairCoupling (collective).

    Args:
        disc: the Discretisation with pairs.
        layout: the PairLayout.

    Returns:
        The WorkFrames.
    """
    d, fr, n = disc.dim, disc.frames, len(layout.g_nodes)
    imap = disc.V.dofmap.index_map
    owned = (layout.owned_dofs_local[::d] // d).astype(np.int64)
    fixed = layout.place_on_all(layout.local_owned_g, disc.dirichlet.fixed[owned],
                                (n, d), dtype=bool).ravel()
    pos = np.searchsorted(fr.nodes, disc.gamma3.nodes)
    on = fr.bounded[pos]
    nodes = imap.local_to_global(disc.gamma3.nodes[on].astype(np.int32))
    at = np.searchsorted(layout.g_nodes, nodes) * d + fr.slot[pos][on]
    g, plus = fr.g[pos][on], fr.sign[pos][on] > 0
    lb, ub = np.full(n * d, -np.inf), np.full(n * d, np.inf)
    for side, where, values in ((ub, at[plus], g[plus]), (lb, at[~plus], -g[~plus])):
        for where_r, values_r in disc.comm.allgather((where, values)):
            side[where_r] = values_r
    return WorkFrames(None, fixed, lb.reshape(n, d), ub.reshape(n, d), np.eye(d)[0])
