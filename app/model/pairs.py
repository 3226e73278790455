"""Two bodies in contact (``contact.pairs``): the node-to-segment kinematics of small sliding.

Each local node x_i of a pair's ``surface`` (Gamma3 of the pair) is coupled once, in the
reference configuration, to a point pi(x_i) = sum_k N_ik x_k of one of the pair's ``target``
facets (app/model/pairnormal.py): the point met along the pair's normal

    nu_i = (n_s(x_i) - n_t(pi(x_i))) / |n_s(x_i) - n_t(pi(x_i))|,

the average of the surface's outward normal n_s and the target's inward one -n_t (each body's
area-weighted vertex normals, n_t interpolated on the facet; Code_Aster's NORMALE='MAIT_ESCL'),
so that two mirror-image bodies pressed together have a purely normal jump.  The measured
initial distance is d_i = (pi(x_i) - x_i) . nu_i >= 0 (with either rule).  The relative
displacement

    [u]_i = u(x_i) - u(pi(x_i)) = u_i - sum_k N_ik u_k

is a fixed linear combination of dofs (the rows of the jump matrix B).  With a fixed approach
direction e (``contact.direction``, from the surfaces toward the targets: the gap of linear
contact theory, Johnson ch. 4) pi(x_i) is instead the point of the target on the line through
x_i along e (a ray cast), nu_i = e and d_i the distance along e.  The contact laws
of the rigid-foundation case act on

    w_i = [u]_i - d_i nu_i:    w_i . nu_i = [u]_nu - d_i  (the interpenetration when > 0),
                               w_i - (w_i . nu_i) nu_i = [u]_tau,

with the bound w_i . nu_i <= g (the pair's g).  So the forms of the Gamma3 terms (4.1)-(4.2),
the memory and slip sums and the Coulomb pressure are those of one body against the
foundation, evaluated on w (a P1 Function whose values at the Gamma3 nodes are w_i); the step
solver maps them back to u (app/solvers/pairmap.py).  Small sliding: nu_i and the coupling
are those of the reference configuration, and the friction's slip is [u]_tau, the total
tangential jump along them (zero under a pure normal approach of mirror-image bodies).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import cpp as dcpp
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.io.errors import CaseError

# a node with the surface's outward normal under FACING_MIN to the pair's normal is refused
# (the surfaces do not face each other there); an initial overlap beyond PENETRATION_TOL
# times the body's size is refused, below it is round-off (clipped to 0)
FACING_MIN = 0.0
PENETRATION_TOL = 1e-8


@dataclass
class PairGeometry:
    """The projection of the local Gamma3 nodes (owned and ghost, in
    ``gamma3_local_nodes`` order) onto their pairs' targets, and the coupling of the owned
    ones.

    Attributes:
        pair: (m,) the index of each node's pair in contact.pairs.
        normal: (m, d) nu_i, the pair's unit normal (the average of the surface's outward
            and the target's inward normals, app/model/pairnormal.py).
        distance: (m,) d_i >= 0, the initial distance (pi(x_i) - x_i) . nu_i along nu_i
            (both rules: of the node's own point; app/model/mortar.py says why).
        g: (m,) the pair's extra gap g at each node.
        rows, cols, coef: the coupling [u]_i = u_i - sum_k c_ik u_k of the owned nodes:
            the node's position in ``gamma3_local_nodes``, the target's global node k,
            c_ik (each row sums to 1).
    """

    pair: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    g: np.ndarray
    rows: np.ndarray = None
    cols: np.ndarray = None
    coef: np.ndarray = None


def vertex_nodes(V) -> np.ndarray:
    """The node (block dof) of V at each local vertex of the mesh (P1 on simplices: a
    cell's dofs follow its vertices).

    Args:
        V: the P1 vector space.

    Returns:
        (vertices,) node indices.
    """
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    c2v = msh.topology.connectivity(tdim, 0).array
    out = np.empty(msh.topology.index_map(0).size_local
                   + msh.topology.index_map(0).num_ghosts, dtype=np.int64)
    out[c2v] = V.dofmap.list.array
    return out


def local_facets(disc, ref, owned: bool = False) -> tuple:
    """This rank's facets of a group: vertex coordinates, a point inside the adjacent cell
    and the vertices' global nodes.

    Args:
        disc: the Discretisation (its mesh, V and ``facets`` of the group).
        ref: the group.
        owned: only the facets this rank owns (each facet on one rank).

    Returns:
        (coordinates (nf, nv, d), interior points (nf, d), global nodes (nf, nv)).
    """
    msh, V, d = disc.mesh, disc.V, disc.dim
    fdim = d - 1
    facets = np.asarray(disc.facets[ref], dtype=np.int32)
    msh.topology.create_connectivity(fdim, 0)
    msh.topology.create_connectivity(fdim, d)
    if owned:
        facets = facets[facets < msh.topology.index_map(fdim).size_local]
    f2v, f2c = msh.topology.connectivity(fdim, 0), msh.topology.connectivity(fdim, d)
    verts = np.array([f2v.links(f) for f in facets], dtype=np.int64).reshape(len(facets), d)
    local = vertex_nodes(V)[verts]
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    cpp_mesh = getattr(msh, "_mesh", msh)
    geo = dcpp.mesh.entities_to_geometry(cpp_mesh, d, cells, False)
    interior = msh.geometry.x[geo][:, :, :d].mean(axis=1) if len(cells) else np.zeros((0, d))
    glob = np.asarray(V.dofmap.index_map.local_to_global(local.reshape(-1).astype(np.int32)),
                      dtype=np.int64).reshape(local.shape)
    return V.tabulate_dof_coordinates()[local][:, :, :d], interior, glob


def gathered_facets(disc, ref) -> tuple:
    """The facets of a group over all ranks, each once: their vertex coordinates, the body's
    outward normals, the vertices' global nodes and the vertex normals there.

    Args:
        disc: the Discretisation.
        ref: the group (a pair's target or surface).

    Returns:
        (coordinates (nf, nv, d), outward normals (nf, d), global nodes (nf, nv), vertex
        normals (nf, nv, d): pairnormal.vertex_normals).
    """
    from vpcontact.model.pairgeometry import facet_normals  # scipy: only with pairs
    from vpcontact.model.pairnormal import vertex_normals

    d = disc.dim
    parts = disc.comm.allgather(local_facets(disc, ref))
    coords = np.concatenate([p[0] for p in parts]).reshape(-1, d, d)
    inner = np.concatenate([p[1] for p in parts]).reshape(-1, d)
    glob = np.concatenate([p[2] for p in parts]).reshape(-1, d)
    _, first = np.unique(np.sort(glob, axis=1), axis=0, return_index=True)
    first = np.sort(first)
    coords, glob = coords[first], glob[first]
    normals = facet_normals(coords, inner[first])
    return coords, normals, glob, vertex_normals(coords, normals, glob)


def _at_nodes(facets: tuple, nodes: np.ndarray) -> np.ndarray:
    """The vertex normals of gathered_facets at some of their global nodes.

    Args:
        facets: gathered_facets of a group.
        nodes: global nodes of that group's vertices (any shape).

    Returns:
        (nodes.shape, d) normals.
    """
    glob, vertex = facets[2].ravel(), facets[3].reshape(facets[2].size, -1)
    order = np.argsort(glob, kind="stable")
    at = order[np.searchsorted(glob[order], np.asarray(nodes).ravel())]
    return vertex[at].reshape(*np.shape(nodes), vertex.shape[1])


def project_pairs(disc, nodes: np.ndarray, outward: np.ndarray) -> PairGeometry:
    """Project the local Gamma3 nodes onto their pairs' targets, check the pairs and
    couple the owned nodes to the targets (each pair's ``rule``).

    Args:
        disc: the Discretisation (case, V, facets of the groups).
        nodes: the local Gamma3 nodes (owned and ghost, sorted).
        outward: (m, d) the surface's outward unit normals at those nodes.

    Returns:
        The PairGeometry.

    Raises:
        CaseError: a node in two pairs' surfaces, a node projecting outside its target,
            surfaces that do not face each other, an initial interpenetration (on every
            rank).
    """
    case, d = disc.case, disc.dim
    x = disc.V.tabulate_dof_coordinates()[nodes, :d]
    m = len(nodes)
    pair = np.full(m, -1)
    for i, p in enumerate(case.contact.pairs):
        mine = np.isin(nodes, surface_nodes(disc, p.surface))
        disc.refuse((mine & (pair >= 0)).any(), f"contact.pairs[{i}].surface",
                    "shares a node with another pair's surface")
        pair[mine] = i
    geo = PairGeometry(pair, np.zeros((m, d)), np.zeros(m), np.zeros(m))
    couplings = []
    for i, p in enumerate(case.contact.pairs):
        sel = pair == i
        target, surface = gathered_facets(disc, p.target), gathered_facets(disc, p.surface)
        disc.refuse(sel.any() and len(target[0]) == 0, f"contact.pairs[{i}].target",
                    f"the group {p.target!r} has no facets")
        if case.contact.direction is not None:                        # collective
            _check_direction(disc, p, outward[sel], x[sel])
        project = projector(case.contact.direction, target)
        n_s = _at_nodes(surface, _global(disc, nodes[sel]))
        proj, nu = project(x[sel], n_s) if sel.any() else (None, None)
        inside = proj.inside if proj is not None else np.ones(0, bool)
        _refuse_count(disc, ~inside, x[sel], f"contact.pairs[{i}]",
                      f"node(s) of {p.surface!r} project outside the target {p.target!r} "
                      "(past its free edge): make the surface group cover only the part "
                      "that faces the target, or the target larger")
        if proj is not None:
            geo.normal[sel] = nu
            geo.distance[sel] = np.einsum("ij,ij->i", proj.closest - x[sel], nu)
            geo.g[sel] = p.g
        _check_facing(disc, i, p, outward[sel], geo.normal[sel], x[sel])   # collective
        couplings.append(_coupling(disc, p, nodes, np.flatnonzero(sel), proj,
                                   (surface, target), project))
    geo.rows, geo.cols, geo.coef = (np.concatenate([c[k] for c in couplings])
                                    for k in range(3))
    for i, p in enumerate(case.contact.pairs):
        _check_distance(disc, i, p, geo, pair == i, x[pair == i])
    return geo


def _global(disc, nodes: np.ndarray) -> np.ndarray:
    """The global indices of local nodes of V."""
    return np.asarray(disc.V.dofmap.index_map.local_to_global(
        np.asarray(nodes, dtype=np.int32)), dtype=np.int64)


def projector(direction, target: tuple):
    """pi and nu of the pairs onto one target: along the pair's averaged normal, or along
    a fixed direction.

    Args:
        direction: contact.direction (unit), or None.
        target: gathered_facets of the target.

    Returns:
        f(points, n_s) -> (Projection, nu (m, d)), n_s the surface's outward normals at
        the points: ``pairnormal.pair_projection`` without a direction (nu the average of
        the two bodies' normals), else ``cast_points`` along it (the gap of linear contact
        theory, measured along one approach direction; nu = the direction).
    """
    from vpcontact.model import pairgeometry, pairnormal  # scipy: only with pairs
    coords, normals, _, vertex = target
    if direction is None:
        return lambda points, n_s: pairnormal.pair_projection(points, n_s, coords, normals,
                                                              vertex)
    e = np.asarray(direction, float)
    return lambda points, n_s: (pairgeometry.cast_points(points, coords, normals, e),
                                np.broadcast_to(e, np.shape(points)).copy())


def _coupling(disc, p, nodes, sel, proj, facets, project) -> tuple:
    """(rows, cols, coef) of one pair's owned nodes (positions ``sel`` in ``nodes``),
    ``facets`` the pair's (surface, target) gathered_facets, ``project`` its projector."""
    from vpcontact.model.mortar import mortar_triplets
    surface, target = facets
    owned = nodes[sel] < disc.V.dofmap.index_map.size_local
    if p.rule == "node_to_segment":
        if proj is None:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        nv = proj.weights.shape[1]
        return (np.repeat(sel[owned], nv), target[2][proj.facet[owned]].ravel(),
                proj.weights[owned].ravel())
    coords, _, glob = local_facets(disc, p.surface, owned=True)
    return _owned_rows(disc, nodes, sel, mortar_triplets(coords, glob, _at_nodes(surface, glob),
                                                         target[2], project))


def _owned_rows(disc, nodes, sel, triplets) -> tuple:
    """The rows of M (mortar_triplets: global row, global column, value, from all ranks)
    at this rank's owned nodes at positions ``sel`` in ``nodes``, duplicates summed, each
    row divided by its sum: (positions in nodes, global columns, c_ik) (collective)."""
    from scipy.sparse import coo_matrix

    parts = disc.comm.allgather(triplets)
    rows, cols, vals = (np.concatenate([q[k] for q in parts]) for k in range(3))
    start = disc.V.dofmap.index_map.local_range[0]
    mine = (rows >= start) & (rows < start + disc.V.dofmap.index_map.size_local)
    local = rows[mine] - start
    at = np.searchsorted(nodes, local)
    ok = (at < len(nodes)) & (nodes[np.minimum(at, len(nodes) - 1)] == local)
    ok &= np.isin(at, sel)                          # another pair's node: not this one
    rows, cols, vals = at[ok], cols[mine][ok], vals[mine][ok]
    # sum the quadrature points' contributions to each (node, target node) entry
    M = coo_matrix((vals, (rows, cols)), shape=(len(nodes), int(cols.max(initial=-1)) + 1))
    M = M.tocsr()
    M.sum_duplicates()
    rows = np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))
    total = np.bincount(rows, weights=M.data, minlength=len(nodes))
    return rows, M.indices.astype(np.int64), M.data / total[rows]


def surface_nodes(disc, ref) -> np.ndarray:
    """The local nodes on the facets of a group (dolfinx's locate_dofs_topological, as
    Gamma3's nodes are found: also a node whose facet of the group is on another rank);
    collective.

    Args:
        disc: the Discretisation.
        ref: the group.

    Returns:
        Sorted local node indices.
    """
    from dolfinx import fem

    facets = np.asarray(disc.facets[ref], dtype=np.int32)
    return np.sort(fem.locate_dofs_topological(disc.V, disc.dim - 1, facets))


def node_labels(disc) -> np.ndarray:
    """Which pair group each local node of V lies on: 1 a pair's surface, 2 its target, 0
    neither (2 where both), the same on every rank and for every partition (the largest
    over the group's facets on all ranks).  Two bodies touching at the start have
    coincident interface nodes; the label tells them apart (checkpoints).

    Args:
        disc: the Discretisation with contact pairs.

    Returns:
        (local nodes,) labels, owned and ghost.
    """
    from dolfinx import fem

    V = disc.V
    W, parent = V.sub(0).collapse()
    bs = V.dofmap.index_map_bs
    node_to_w = np.empty(len(parent), dtype=np.int64)
    node_to_w[np.asarray(parent) // bs] = np.arange(len(parent))
    f = fem.Function(W)
    for p in disc.case.contact.pairs:
        for label, ref in ((1.0, p.surface), (2.0, p.target)):
            at = node_to_w[surface_nodes(disc, ref)]
            f.x.array[at] = np.maximum(f.x.array[at], label)
    f.vector.ghostUpdate(addv=PETSc.InsertMode.MAX_VALUES, mode=PETSc.ScatterMode.REVERSE)
    f.x.scatter_forward()
    return f.x.array[node_to_w].copy()


def _check_facing(disc, i, p, outward, nu, x) -> None:
    """Refuse a pair whose surface does not face its target at some node."""
    cos = np.einsum("ij,ij->i", outward, nu)
    _refuse_count(disc, cos <= FACING_MIN, x, f"contact.pairs[{i}]",
                  f"node(s) of {p.surface!r} whose outward normal points away from the "
                  f"target {p.target!r} (the surfaces do not face each other there)")


def _check_direction(disc, p, outward, x) -> None:
    """Refuse a contact.direction that does not point from a pair's surface toward its
    target: under 90 degrees to the surface's outward normal at every node."""
    cos = outward @ np.asarray(disc.case.contact.direction, float)
    _refuse_count(disc, cos <= FACING_MIN, x, "contact.direction",
                  f"node(s) of {p.surface!r} whose outward normal makes 90 degrees or more "
                  "with the direction (it must point from each pair's surface toward its "
                  f"target, here {p.target!r})")


def _check_distance(disc, i, p, geo, sel, x) -> None:
    """Refuse an initial interpenetration beyond round-off; clip the round-off to 0."""
    tol = PENETRATION_TOL * disc.length_scale
    d = geo.distance[sel]
    _refuse_count(disc, d < -tol, x, f"contact.pairs[{i}]",
                  f"node(s) of {p.surface!r} start inside the target body {p.target!r} "
                  f"(initial interpenetration, largest {-d.min(initial=0.0):.3g} m)")
    geo.distance[sel] = np.maximum(d, 0.0)


def _refuse_count(disc, bad: np.ndarray, x: np.ndarray, key: str, what: str) -> None:
    """Raise CaseError on every rank naming how many nodes are ``bad`` and the first."""
    count = disc.comm.allreduce(int(bad.sum()), op=MPI.SUM)
    if not count:
        return
    found = [pt for pt in disc.comm.allgather(
        tuple(float(v) + 0.0 for v in np.round(x[bad][0], 6)) if bad.any() else None) if pt]
    raise CaseError(f"{disc.case.source}: {key}: {count} {what} (e.g. at {found[0]})")


def csr_matrix(comm, n_local: int, rows: np.ndarray, cols: np.ndarray,
               vals: np.ndarray) -> PETSc.Mat:
    """A square AIJ matrix with ``n_local`` owned rows from (local row, global column, value)
    triplets (duplicates summed).

    Args:
        comm: the communicator.
        n_local: the owned rows (and columns) on this rank.
        rows: local row indices.
        cols: global column indices.
        vals: the values.

    Returns:
        The assembled matrix.
    """
    order = np.lexsort((cols, rows))
    rows, cols, vals = rows[order], cols[order], vals[order]
    key = np.stack([rows, cols])
    keep = np.ones(len(rows), bool)
    keep[1:] = (np.diff(key, axis=1) != 0).any(axis=0)
    starts = np.flatnonzero(keep)
    vals = np.add.reduceat(vals, starts) if len(vals) else vals
    rows, cols = rows[starts], cols[starts]
    indptr = np.zeros(n_local + 1, dtype=PETSc.IntType)
    np.add.at(indptr, rows + 1, 1)
    indptr = np.cumsum(indptr).astype(PETSc.IntType)
    A = PETSc.Mat().createAIJ(size=((n_local, PETSc.DECIDE), (n_local, PETSc.DECIDE)),
                              csr=(indptr, cols.astype(PETSc.IntType), vals), comm=comm)
    A.assemble()
    return A


def _joined(*parts) -> tuple:
    """(rows, cols, vals) of several triplet lists, concatenated."""
    return tuple(np.concatenate([np.asarray(p[k]) for p in parts]) for k in range(3))


class PairOperators:
    """The linear maps of the pairs on V's dofs (owned rows, PETSc):

    - B, the jump: (B u)_i = u_i - sum_k N_ik u_k at the Gamma3 nodes, u elsewhere;
    - I + S (``lift``) and its inverse I - S (``unlift``; S S = 0: S maps target dofs to
      Gamma3 slot dofs): row (i, slot_i) of S holds sign_i N_ik nu_i[a] at column (k, a),
      so that in the nodal frames the slot dof of node i becomes sign_i ([u]_nu - d_i)
      (app/solvers/pairmap.py);
    - c_w = d_i nu_i at the Gamma3 nodes: w = B u - c_w.

    Args:
        disc: the Discretisation (V, frames, pairs' geometry, Gamma3 nodes).
    """

    def __init__(self, disc):
        V, d, fr, geo = disc.V, disc.dim, disc.frames, disc.pairs
        self.comm = disc.comm
        imap = V.dofmap.index_map
        n = imap.size_local
        self.n_local = n * d
        start = imap.local_range[0] * d
        dofs = np.arange(n * d)
        ident = (dofs, dofs + start, np.ones(n * d))
        comp = np.arange(d)
        # B = I - c at the Gamma3 rows (each component against the same component)
        node = fr.nodes[geo.rows]
        b = ((d * node[:, None] + comp).ravel(), (d * geo.cols[:, None] + comp).ravel(),
             np.repeat(-geo.coef, d))
        self.B = csr_matrix(self.comm, self.n_local, *_joined(ident, b))
        # S: the slot rows of the bounded nodes
        on = fr.bounded[geo.rows]
        r = geo.rows[on]
        srow = np.repeat(d * fr.nodes[r] + fr.slot[r], d)
        scol = (d * geo.cols[on][:, None] + comp).ravel()
        sval = ((fr.sign[r] * geo.coef[on])[:, None] * fr.normal[r]).ravel()
        self.lift = csr_matrix(self.comm, self.n_local, *_joined(ident, (srow, scol, sval)))
        self.unlift = csr_matrix(self.comm, self.n_local,
                                 *_joined(ident, (srow, scol, -sval)))
        owned = np.flatnonzero(fr.nodes < n)
        self.c_w = self.B.createVecLeft()
        self.c_w.array[(d * fr.nodes[owned][:, None] + comp).ravel()] = \
            (geo.distance[owned][:, None] * fr.normal[owned]).ravel()
        # the affine part of u = P x + c: d_i nu_i at the bounded nodes
        self.c = self.B.createVecLeft()
        bnd = owned[fr.bounded[owned]]
        self.c.array[(d * fr.nodes[bnd][:, None] + comp).ravel()] = \
            (geo.distance[bnd][:, None] * fr.normal[bnd]).ravel()

    def jump(self, u: PETSc.Vec, w: PETSc.Vec) -> None:
        """w = B u - c_w (owned entries; the caller updates the ghosts).

        Args:
            u: the displacement.
            w: output.
        """
        self.B.mult(u, w)
        w.axpy(-1.0, self.c_w)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self.B, self.lift, self.unlift, self.c_w, self.c):
            obj.destroy()
