"""Rigid caps (``loads.rigid``): a boundary group that moves rigidly, its amplitudes loaded
by a resultant force and moment or prescribed (Abaqus's rigid body with a reference node,
Code_Aster's LIAISON_SOLIDE).

On the cap the displacement is a small rigid motion about the reference point X_ref,

    u(X) = U + theta x (X - X_ref)   (2D: theta a scalar about z),

that is u_cap = Phi a with the d(d+1)/2 amplitudes a = (U, theta) and Phi the rigid modes at
the cap's dofs.  The solvers eliminate the cap's dofs by a change of variables u = T z
(master-slave elimination): r chosen "master" dofs of the cap (Phi's rows of a pivoted QR,
so that Phi restricted to them is well conditioned) hold the amplitudes, z_master = a; every
other cap dof is a slave, u_slave = (Phi a)_slave + z_slave with z_slave held at 0; every
other dof keeps z = u.  T is invertible; its inverse on u of a rigid cap motion is
T^+ u: a = (Phi^T Phi)^-1 Phi^T u_cap, z_slave = 0.  The Newton matrix T^T K T keeps K's
symmetry; its rows and columns at the slaves and at the prescribed amplitudes are the
identity with a zero residual (like Dirichlet rows), and a loaded amplitude receives its
generalised force in the residual: the virtual work of the resultant (F, M) is F . U + M . theta
(2D: M theta), so the residual at the amplitude a_k is (T^T F_bulk)_k - L_k(t).  The step
solvers (app/solvers/pairmap.py for two bodies, app/solvers/rotation.py for one) compose T
with their own change of variables; the cap's nodes are neither contact nor Dirichlet nodes,
so T commutes with the nodal frames and the pairs' lift.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.case.caprules import component_value
from vpcontact.io.errors import CaseError
from vpcontact.model.dirichlet import rigid_modes

log = logging.getLogger("vpcontact")

# rigid_modes' 3D rotation order is (about z, about x, about y): the amplitudes are
# (U, theta_x, theta_y, theta_z)
_ORDER = {2: [0, 1, 2], 3: [0, 1, 2, 4, 5, 3]}


def cap_modes(x: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Phi: the rigid modes about X_ref at points, amplitudes (U, theta).

    Args:
        x: (n, d) coordinates.
        reference: X_ref (d,).

    Returns:
        (n, d, r) with r = 3 in 2D, 6 in 3D.
    """
    return rigid_modes(x - reference)[:, :, _ORDER[x.shape[1]]]


@dataclass
class RigidCap:
    """One cap on this rank.

    Attributes:
        name: the group as the case names it.
        spec: the case's RigidCap (load, prescribed, reference).
        nodes: the local (owned and ghost) nodes of the group.
        dofs: the owned dofs of the cap (local, unrolled node * d + a).
        phi: (len(dofs), r) Phi at those dofs.
        reference: X_ref.
        masters: (r,) the global dofs holding the amplitudes.
        gram_inv: (Phi^T Phi)^-1 over the whole cap (r, r).
    """

    name: str
    spec: object
    nodes: np.ndarray
    dofs: np.ndarray
    phi: np.ndarray
    reference: np.ndarray
    masters: np.ndarray
    gram_inv: np.ndarray

    def amplitudes(self, comm, values: np.ndarray) -> np.ndarray:
        """The least-squares amplitudes of a displacement on the cap (collective):
        a = (Phi^T Phi)^-1 Phi^T u_cap (exact for a rigid motion).

        Args:
            comm: the communicator.
            values: the owned dofs' values (unrolled).

        Returns:
            (r,) (U, theta).
        """
        return self.gram_inv @ self.resultant(comm, values)

    def resultant(self, comm, forces: np.ndarray) -> np.ndarray:
        """The generalised force Phi^T f of nodal forces on the cap: the resultant force
        and its moment about X_ref (collective).

        Args:
            comm: the communicator.
            forces: the owned dofs' nodal forces (unrolled).

        Returns:
            (r,) (F, M).
        """
        out = self.phi.T @ forces[self.dofs]
        comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        return out


def _centroid(V, facets: np.ndarray) -> np.ndarray:
    """The group's centroid, int X ds / int ds (collective)."""
    msh = V.mesh
    d, fdim = msh.topology.dim, msh.topology.dim - 1
    order = np.unique(facets).astype(np.int32)
    tags = dmesh.meshtags(msh, fdim, order, np.ones(len(order), dtype=np.int32))
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)(1)
    x = ufl.SpatialCoordinate(msh)
    area = msh.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * ds)), op=MPI.SUM)
    moments = [msh.comm.allreduce(fem.assemble_scalar(fem.form(x[a] * ds)), op=MPI.SUM)
               for a in range(d)]
    return np.asarray(moments) / area


def _masters(V, nodes: np.ndarray, reference: np.ndarray, where: str) -> np.ndarray:
    """The global dofs of the amplitudes: the rows of Phi over the whole cap that a pivoted
    QR of Phi^T takes first (rotations scaled by the cap's size), the same on every rank
    (collective).

    Raises:
        CaseError: if the cap's nodes do not determine a rigid motion."""
    from scipy.linalg import qr
    imap, d = V.dofmap.index_map, V.dofmap.index_map_bs
    owned = nodes[nodes < imap.size_local]
    gid = imap.local_to_global(owned.astype(np.int32)).astype(np.int64)
    x = V.tabulate_dof_coordinates()[owned, :d]
    parts = V.mesh.comm.allgather((gid, x))
    gid = np.concatenate([p[0] for p in parts])
    x = np.concatenate([p[1] for p in parts]).reshape(-1, d)
    order = np.argsort(gid)
    gid, x = gid[order], x[order]
    phi = cap_modes(x, reference).reshape(len(x) * d, len(_ORDER[d]))
    size = max(np.ptp(x, axis=0).max(initial=0.0), 1e-300)
    phi[:, d:] /= size
    r = phi.shape[1]
    if len(phi) >= r:
        _, R, piv = qr(phi.T, pivoting=True, mode="economic")
        rank_ok = abs(R[r - 1, r - 1]) > 1e-8 * abs(R[0, 0])
    if len(phi) < r or not rank_ok:
        need = "2 nodes" if d == 2 else "3 nodes not on one line"
        raise CaseError(f"{where}: the group's {len(x)} node(s) do not determine a rigid "
                        f"motion (at least {need})")
    return np.sort(gid[piv[:r] // d] * d + piv[:r] % d)


def _build_cap(V, name: str, spec, facets: np.ndarray, source: str) -> RigidCap:
    """One cap (collective)."""
    d, fdim = V.dofmap.index_map_bs, V.mesh.topology.dim - 1
    imap = V.dofmap.index_map
    where = f"{source}: loads.rigid.{name}"
    nodes = fem.locate_dofs_topological(V, fdim, facets)
    reference = np.asarray(spec.reference, dtype=float) if spec.reference is not None \
        else _centroid(V, facets)
    masters = _masters(V, nodes, reference, where)
    owned = np.sort(nodes[nodes < imap.size_local])
    x = V.tabulate_dof_coordinates()[owned, :d]
    phi = cap_modes(x, reference).reshape(len(owned) * d, len(_ORDER[d]))
    gram = phi.T @ phi
    V.mesh.comm.Allreduce(MPI.IN_PLACE, gram, op=MPI.SUM)
    dofs = (owned[:, None] * d + np.arange(d)).ravel()
    return RigidCap(name, spec, nodes, dofs, phi, reference, masters, np.linalg.inv(gram))


class RigidCaps:
    """The rigid caps of a body and the elimination u = T z (module docstring).

    Args:
        V: the P1 vector space.
        caps: the RigidCap of every ``loads.rigid`` group.
        source: the case file, for messages.

    Attributes:
        caps: the caps.
        nodes: the local (owned and ghost) nodes of every cap.
        fixed: the owned dofs of z held fixed (local): the slaves and the prescribed
            amplitudes.
    """

    def __init__(self, V, caps: list[RigidCap], source: str = "case"):
        self.V, self.caps, self.comm, self.source = V, caps, V.mesh.comm, source
        self.d = V.dofmap.index_map_bs
        self.start = V.dofmap.index_map.local_range[0] * self.d
        self.n = V.dofmap.index_map.size_local * self.d
        self.nodes = np.unique(np.concatenate([c.nodes for c in caps]))
        slaves = [np.setdiff1d(c.dofs, self._local(c.masters)) for c in caps]
        held = [self._local(c.masters[k:k + 1]) for c in caps
                for k, v in enumerate(c.spec.prescribed) if v is not None]
        self.fixed = np.unique(np.concatenate(slaves + held)).astype(PETSc.IntType)

    def _local(self, dofs: np.ndarray) -> np.ndarray:
        """The owned ones of global dofs, as local indices."""
        dofs = np.asarray(dofs, dtype=np.int64)
        return (dofs[(dofs >= self.start) & (dofs < self.start + self.n)] - self.start)

    def _amplitude_dofs(self, t: float, which: str) -> tuple[np.ndarray, np.ndarray]:
        """(owned local dofs, values at t) of the amplitudes given by ``which`` ("load" or
        "prescribed") on this rank."""
        at, values = [], []
        for c in self.caps:
            for k, comp in enumerate(getattr(c.spec, which)):
                mine = self._local(c.masters[k:k + 1])
                if comp is not None and len(mine):
                    at.append(mine[0])
                    values.append(component_value(comp, t))
        return np.asarray(at, dtype=np.int64), np.asarray(values, dtype=float)

    def fix(self, z: PETSc.Vec, t: float) -> None:
        """z at the fixed dofs: 0 at the slaves, the prescribed amplitudes at t.

        Args:
            z: a vector of z's layout.
            t: the time t_n.
        """
        z.array[self.fixed] = 0.0
        at, values = self._amplitude_dofs(t, "prescribed")
        z.array[at] = values

    def add_loads(self, b: PETSc.Vec, t: float, scale: float) -> None:
        """b += scale L(t) at the loaded amplitudes (L: the force and moment components).

        Args:
            b: a vector of z's layout.
            t: the time t_n.
            scale: -1 for a residual (internal - external), +1 for a right-hand side.
        """
        at, values = self._amplitude_dofs(t, "load")
        b.array[at] += scale * values

    def matrices(self) -> tuple[PETSc.Mat, PETSc.Mat]:
        """(T, T^+) as AIJ matrices of u's layout (collective).

        Returns:
            T (u = T z) and T^+ (z = T^+ u on a rigid cap motion, 0 at the slaves).
        """
        rows, cols, vals = [np.arange(self.n)], [np.arange(self.n) + self.start], \
            [np.ones(self.n)]
        inv_rows, inv_cols, inv_vals = [], [], []
        cap_dofs = np.concatenate([c.dofs for c in self.caps])
        keep = np.ones(self.n, dtype=bool)
        for c in self.caps:
            masters = self._local(c.masters)
            keep[masters] = False
            rows.append(np.repeat(c.dofs, len(c.masters)))
            cols.append(np.tile(c.masters, len(c.dofs)))
            vals.append(c.phi.ravel())
            # T^+'s master rows: (Phi^T Phi)^-1 Phi^T over the whole cap
            parts = self.comm.allgather((c.dofs + self.start, c.phi))
            every = np.concatenate([p[0] for p in parts])
            pinv = c.gram_inv @ np.concatenate([p[1] for p in parts]).T
            for k, g in enumerate(c.masters):
                if self.start <= g < self.start + self.n:
                    inv_rows.append(np.full(len(every), g - self.start))
                    inv_cols.append(every)
                    inv_vals.append(pinv[k])
        rows[0], cols[0], vals[0] = rows[0][keep], cols[0][keep], vals[0][keep]
        other = np.ones(self.n, dtype=bool)
        other[cap_dofs] = False
        inv = (np.concatenate([np.flatnonzero(other)] + inv_rows),
               np.concatenate([np.flatnonzero(other) + self.start] + inv_cols),
               np.concatenate([np.ones(other.sum())] + inv_vals))
        return (self._aij(np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)),
                self._aij(*inv))

    def _aij(self, rows, cols, vals) -> PETSc.Mat:
        """An AIJ matrix of u's layout from owned (local row, global column, value)."""
        from scipy.sparse import coo_matrix
        total = self.comm.allreduce(self.n)
        m = coo_matrix((vals, (rows, cols)), shape=(self.n, total)).tocsr()
        m.sum_duplicates()
        m.sort_indices()
        A = PETSc.Mat().createAIJ(size=((self.n, total), (self.n, total)),
                                  csr=(m.indptr.astype(PETSc.IntType),
                                       m.indices.astype(PETSc.IntType), m.data),
                                  comm=self.comm)
        A.assemble()
        return A

    def blocked(self, labels: np.ndarray, centre: np.ndarray, scale: np.ndarray) -> list:
        """The rigid motions of the body's parts that the prescribed amplitudes block, as
        rows in the basis of app/model/dirichlet.py's rigid_modes at the part's centred and
        scaled coordinates (collective): a translation component of the cap is the part's
        motion at X_ref, a rotation component its rotation (times the part's size).

        Args:
            labels: the part of each local node.
            centre, scale: each part's centre and size.

        Returns:
            [(part, rows (k, r))] per cap with prescribed amplitudes.

        Raises:
            CaseError: a cap on several disconnected parts (it would tie them; the check
                is part by part).
        """
        out = []
        for c in self.caps:
            mine = labels[c.nodes[c.nodes < self.V.dofmap.index_map.size_local]]
            k = self.comm.allreduce(int(mine.max(initial=-1)), op=MPI.MAX)
            low = self.comm.allreduce(int(mine.min(initial=len(centre))), op=MPI.MIN)
            if low != k:
                raise CaseError(f"{self.source}: loads.rigid.{c.name}: the cap spans "
                                "disconnected parts of the body (a cap is on one part: split "
                                "it into one cap per part)")
            given = [i for i, v in enumerate(c.spec.prescribed) if v is not None]
            if not given:
                continue
            at = rigid_modes(((c.reference - centre[k]) / scale[k])[None, :])[0]   # (d, r)
            rows = np.vstack([at, np.eye(at.shape[1])[_ORDER[self.d][self.d:]]])
            out.append((k, rows[given]))
        return out

    def report(self, u: np.ndarray, r: np.ndarray) -> dict:
        """The caps' amplitudes and their generalised reactions (collective).

        Args:
            u: the owned dofs of u_n (unrolled).
            r: the owned dofs of the bulk residual at u_n (the nodal forces on the body).

        Returns:
            {group: {"displacement": U, "rotation": theta, "force": F, "moment": M}}, the
            rotation and moment a number in 2D; F and M the resultant of the cap on the
            body (= the applied load at a loaded amplitude, at convergence).
        """
        out = {}
        for c in self.caps:
            a, f = c.amplitudes(self.comm, u), c.resultant(self.comm, r)
            turn = (lambda v: float(v[0])) if self.d == 2 else (lambda v: v.tolist())
            out[str(c.name)] = {"displacement": a[:self.d].tolist(),
                                "rotation": turn(a[self.d:]),
                                "force": f[:self.d].tolist(), "moment": turn(f[self.d:])}
        return out


def _shared(V, cap: RigidCap, nodes: np.ndarray) -> int:
    """The number of the cap's nodes among ``nodes`` (local), over the ranks."""
    mine = cap.nodes[cap.nodes < V.dofmap.index_map.size_local]
    return V.mesh.comm.allreduce(len(np.intersect1d(mine, nodes)))


def build_caps(V, facets: dict, rigid: dict, source: str, taken: dict,
               yielding: dict | None = None) -> RigidCaps | None:
    """The rigid caps of ``loads.rigid`` (collective).

    Args:
        V: the P1 vector space.
        facets: group name -> the local facets of that group.
        rigid: the case's loads.rigid (group -> RigidCap spec).
        source: the case file, for messages.
        taken: role (a case key) -> local nodes that a cap may not share (the clamped
            groups', the contact groups').
        yielding: role -> local nodes where the cap's motion wins (loads.displacement's
            groups: the shared nodes are logged at INFO), or None.

    Returns:
        The RigidCaps, or None without caps.

    Raises:
        CaseError: a cap sharing nodes with another cap or a role in ``taken``; a cap that
            does not determine a rigid motion.
    """
    if not rigid:
        return None
    caps = [_build_cap(V, name, spec, facets[name], source) for name, spec in rigid.items()]
    for i, c in enumerate(caps):
        others = {f"loads.rigid.{o.name}": o.nodes for o in caps[:i]}
        for key, nodes in {**taken, **others}.items():
            if n := _shared(V, c, nodes):
                raise CaseError(f"{source}: loads.rigid.{c.name}: the cap shares {n} node(s) "
                                f"with {key} (a node is on one rigid cap, and never also "
                                "clamped or in contact)")
        for key, nodes in (yielding or {}).items():
            if n := _shared(V, c, nodes):
                log.info("%s: loads.rigid.%s: %d node(s) shared with %s follow the cap (its "
                         "motion wins there)", source, c.name, n, key)
    return RigidCaps(V, caps, source)
