"""The Dirichlet data of a scene: Gamma1 (u = 0 on the clamped groups) and the prescribed
displacement components of ``loads.displacement`` (numbers, expressions of x, y, z, t or
tables in t; ``null`` leaves a component free).

Each prescribed component of a group is one dolfinx condition on the collapsed component
space, its values interpolated at every step's t_n (``set_time``).  A vertex shared by a
clamped and a displaced group is clamped (the clamped conditions come last and win).
Before any solve, ``check_rigid_motions`` refuses data that leave a rigid motion of the body
free, or of any of its connected parts (``body_parts``: a body in two pieces with one of them
held would otherwise pass): the step matrix would be singular.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact import kernels
from vpcontact.io.errors import CaseError

log = logging.getLogger("vpcontact")


@dataclass
class DirichletGroup:
    """The constrained dofs of one group, for its reaction force.

    Attributes:
        name: the group as the case names it (clamped or loads.displacement key).
        dofs: the owned constrained dofs (unrolled: node * d + component) of this group
            that no earlier group constrains.
    """

    name: str
    dofs: np.ndarray


@dataclass
class DirichletData:
    """The Dirichlet conditions of a scene.

    Attributes:
        bcs: the dolfinx conditions (displacement components first, clamped last).
        fixed: bool (nodes, d) over the local (owned and ghost) nodes: the component is
            prescribed.
        groups: one DirichletGroup per clamped or displaced group, in the case's order.
        homogeneous: every prescribed value is 0 at all times (clamping only).
        clamped_nodes: the local (owned and ghost) nodes of the clamped groups.
    """

    bcs: list
    fixed: np.ndarray
    groups: list = field(default_factory=list)
    homogeneous: bool = True
    clamped_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int32))
    _updates: list = field(default_factory=list, repr=False)

    def set_time(self) -> None:
        """Interpolate the time-dependent prescribed values at the current t (the time
        Constants of TimeData are set first)."""
        for fn, expr in self._updates:
            fn.interpolate(expr)
            fn.x.scatter_forward()


def build_dirichlet(V, facets: dict, clamped: list, displacement: dict, time_data,
                    exclude: np.ndarray | None = None) -> DirichletData:
    """The Dirichlet conditions of the clamped groups and of ``loads.displacement``.

    Args:
        V: the P1 vector space V^h.
        facets: group name -> the local facet indices of that group.
        clamped: the clamped group names (Gamma1).
        displacement: group name -> components (number, expression, table or None: free).
        time_data: the TimeData of the run (UFL of expressions, time Constants).
        exclude: local nodes that ``loads.displacement`` does not prescribe (a rigid cap's:
            the cap's motion wins where a displaced group meets it), or None.

    Returns:
        The DirichletData.
    """
    d = V.dofmap.index_map_bs
    fdim = V.mesh.topology.dim - 1
    n_local = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    fixed = np.zeros((n_local, d), dtype=bool)
    bcs, updates, named, homogeneous = [], [], [], True
    for name, comps in displacement.items():
        dofs_all = []
        for i, comp in enumerate(comps):
            if comp is None:
                continue
            Vi, _ = V.sub(i).collapse()
            dofs = fem.locate_dofs_topological((V.sub(i), Vi), fdim, facets[name])
            if exclude is not None:
                keep = ~np.isin(dofs[1], exclude)
                dofs = [dofs[0][keep], dofs[1][keep]]
            value = fem.Function(Vi)
            if isinstance(comp, (int, float)):
                value.x.array[:] = float(comp)
                homogeneous &= float(comp) == 0.0
            else:
                expr = fem.Expression(time_data.scalar(comp),
                                      Vi.element.interpolation_points())
                updates.append((value, expr))
                homogeneous = False
            bcs.append(fem.dirichletbc(value, dofs, V.sub(i)))
            dofs_all.append(dofs[0])
        named.append((name, np.concatenate(dofs_all) if dofs_all else np.zeros(0, np.int32)))
    clamped_nodes = [np.zeros(0, dtype=np.int32)]
    for name in clamped:
        nodes = fem.locate_dofs_topological(V, fdim, facets[name])
        bcs.append(fem.dirichletbc(np.zeros(d, dtype=PETSc.ScalarType), nodes, V))
        named.append((name, (nodes[:, None] * d + np.arange(d)).ravel()))
        clamped_nodes.append(nodes)
    # clamped groups are listed last in bcs but their reactions come first in the case's
    # order: clamped, then displacement
    named = named[len(displacement):] + named[:len(displacement)]
    owned = V.dofmap.index_map.size_local * d
    groups, taken = [], np.zeros(n_local * d, dtype=bool)
    for name, dofs in named:
        fixed.ravel()[dofs] = True
        mine = np.unique(dofs[(dofs < owned) & ~taken[dofs]])
        taken[mine] = True
        groups.append(DirichletGroup(name, mine))
    data = DirichletData(bcs, fixed, groups, homogeneous,
                         np.unique(np.concatenate(clamped_nodes)), updates)
    data.set_time()
    return data


def rigid_modes(x: np.ndarray) -> np.ndarray:
    """The rigid motions of a body evaluated at points.

    Args:
        x: (n, d) coordinates (centred and scaled by the caller).

    Returns:
        (n, d, r) modes: r = 3 in 2D (two translations, one rotation), 6 in 3D.
    """
    n, d = x.shape
    modes = [np.broadcast_to(np.eye(d)[a], (n, d)) for a in range(d)]
    if d == 2:
        modes.append(np.stack([-x[:, 1], x[:, 0]], axis=1))
    else:
        for a, b in ((0, 1), (1, 2), (2, 0)):
            r = np.zeros((n, d))
            r[:, a], r[:, b] = -x[:, b], x[:, a]
            modes.append(r)
    return np.stack(modes, axis=2)


@dataclass
class HeldPart:
    """A part of the body whose rigid motions only its contact (with the foundation, or a
    contact pair's) holds.

    Attributes:
        nodes: bool (local nodes,): the part's local (owned and ghost) nodes.
        free: (r, free) the free motions in the basis of ``rigid_modes``, at coordinates
            centred at ``centre`` and divided by ``scale``.
        centre: (d,) the centre of the part's bounding box.
        scale: the part's size.
        surface_of: the contact pairs whose surface the part carries (none: the
            foundation's contact holds it).
        target_of: the contact pairs whose target the part carries.
    """

    nodes: np.ndarray
    free: np.ndarray
    centre: np.ndarray
    scale: float
    surface_of: tuple = ()
    target_of: tuple = ()

    def modes(self, x: np.ndarray) -> np.ndarray:
        """The free motions at points.

        Args:
            x: (n, d) coordinates.

        Returns:
            (n, d, free).
        """
        return rigid_modes((x - self.centre) / self.scale) @ self.free


@dataclass
class BodyParts:
    """The connected components of the body (cells connected through shared vertices), on
    every rank alike.

    Attributes:
        label: (local nodes,) the part of each local (owned and ghost) node: an index into
            the arrays below.
        cells: (parts,) the number of cells of each part (all ranks).
        point: (parts, d) a vertex of each part (its lowest global node).
        lo, hi: (parts, d) the corners of each part's bounding box.
    """

    label: np.ndarray
    cells: np.ndarray
    point: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def _local_components(V) -> tuple[np.ndarray, np.ndarray]:
    """(the local component of each local node, the cell-node table of the local cells):
    the compiled union-find (kernels/cells.c), else scipy's connected_components (whose
    import the compiled kernel spares a run; docs/performance.md, section 9)."""
    imap = V.dofmap.index_map
    n = imap.size_local + imap.num_ghosts
    cells = V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)
    mod = kernels.load()
    if mod is not None:
        label = np.empty(n, dtype=np.intc)
        nodes = np.ascontiguousarray(cells, dtype=np.intc)
        mod.lib.cell_components(n, len(cells), cells.shape[1], kernels.buf(mod.ffi, nodes),
                                kernels.buf(mod.ffi, label))
        return label, cells
    return components_scipy(n, cells), cells


def components_scipy(n: int, cells: np.ndarray) -> np.ndarray:
    """The component of each of n nodes joined by the cells (rows of node numbers), by
    scipy's connected_components (the compiled kernel's fallback and reference).

    Args:
        n: the number of nodes.
        cells: (cells, nodes per cell) node numbers.

    Returns:
        (n,) component labels.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    rows = np.repeat(cells[:, :1], cells.shape[1] - 1, axis=1).ravel()
    cols = cells[:, 1:].ravel()
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def body_parts(V) -> BodyParts:
    """The connected components of the body (collective).

    A part is first found on each rank (scipy's connected_components on the local cells);
    the parts of different ranks that share a node are merged by giving every node the
    lowest global node index of its part, exchanged with the ghosts until no label changes.

    Args:
        V: the P1 vector space.

    Returns:
        The BodyParts.
    """
    comm, imap = V.mesh.comm, V.dofmap.index_map
    owned, n = imap.size_local, imap.size_local + imap.num_ghosts
    local, cells = _local_components(V)
    gid = imap.local_to_global(np.arange(n, dtype=np.int32)).astype(np.int64)
    label = np.full(local.max(initial=-1) + 1, np.iinfo(np.int64).max)
    np.minimum.at(label, local, gid)
    vec = PETSc.Vec().createGhost(imap.ghosts.astype(PETSc.IntType), size=(owned, PETSc.DECIDE),
                                  comm=comm)
    while True:      # labels as -gid, so that MAX_VALUES takes the lowest global index
        with vec.localForm() as lf:
            lf.array[:] = -label[local].astype(float)
        vec.ghostUpdate(addv=PETSc.InsertMode.MAX_VALUES, mode=PETSc.ScatterMode.REVERSE)
        vec.ghostUpdate(addv=PETSc.InsertMode.INSERT_VALUES, mode=PETSc.ScatterMode.FORWARD)
        with vec.localForm() as lf:
            seen = (-lf.array).astype(np.int64)
        new = label.copy()
        np.minimum.at(new, local, seen)
        changed = comm.allreduce(bool((new != label).any()), op=MPI.LOR)
        label = new
        if not changed:
            break
    vec.destroy()
    return _gather_parts(V, label[local], gid, cells)


def _gather_parts(V, node_label: np.ndarray, gid: np.ndarray, cells: np.ndarray) -> BodyParts:
    """The parts' cell counts, points and boxes over all ranks, from each node's label."""
    comm, d = V.mesh.comm, V.dofmap.index_map_bs
    owned = V.dofmap.index_map.size_local
    names = np.unique(np.concatenate(comm.allgather(np.unique(node_label))))
    part = np.searchsorted(names, node_label)
    x = V.tabulate_dof_coordinates()[:, :d]
    owned_cells = cells[:V.mesh.topology.index_map(V.mesh.topology.dim).size_local]
    count = np.bincount(part[owned_cells[:, 0]], minlength=len(names)).astype(float)
    point = np.zeros((len(names), d))
    first = np.flatnonzero(gid[:owned] == node_label[:owned])
    point[part[first]] = x[first]
    lo = np.full((len(names), d), np.inf)
    hi = np.full((len(names), d), -np.inf)
    np.minimum.at(lo, part, x)
    np.maximum.at(hi, part, x)
    for array, op in ((count, MPI.SUM), (point, MPI.SUM), (lo, MPI.MIN), (hi, MPI.MAX)):
        comm.Allreduce(MPI.IN_PLACE, array, op=op)
    return BodyParts(part, count.astype(int), point, lo, hi)


def free_motions(V, fixed: np.ndarray, parts: BodyParts, caps=None) -> list[np.ndarray]:
    """The rigid motions that the prescribed components leave free, part by part
    (collective).

    A rigid motion r of a part is blocked when it does not vanish on the part's prescribed
    components: the Gram matrix M = sum over prescribed (node, component) of r_a r_b must be
    positive definite (its smallest eigenvalue above 1e-10 of its largest, coordinates
    centred and scaled by the part's size).

    Args:
        V: the P1 vector space.
        fixed: bool (local nodes, d): prescribed components.
        parts: the body's connected components.
        caps: the rigid caps (app/model/rigidcap.py), whose prescribed amplitudes block
            motions too (their free amplitudes and their slave dofs block none), or None.

    Returns:
        For each part, the free motions as columns (r, free) in the basis of rigid_modes.
    """
    d = V.dofmap.index_map_bs
    owned = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:owned, :d]
    part = parts.label[:owned]
    centre = 0.5 * (parts.lo + parts.hi)
    scale = np.maximum(np.max(parts.hi - parts.lo, axis=1), 1e-300)
    modes = rigid_modes((x - centre[part]) / scale[part, None])          # (n, d, r)
    node, comp = np.nonzero(fixed[:owned])
    order = np.argsort(part[node], kind="stable")
    node, comp = node[order], comp[order]
    rows = modes[node, comp, :]                            # (prescribed, r), part by part
    M = np.zeros((len(parts.cells), rows.shape[1], rows.shape[1]))
    ends = np.searchsorted(part[node], np.arange(len(parts.cells) + 1))
    for k in np.flatnonzero(np.diff(ends)):
        R = rows[ends[k]:ends[k + 1]]
        M[k] = R.T @ R
    V.mesh.comm.Allreduce(MPI.IN_PLACE, M, op=MPI.SUM)
    for k, R in caps.blocked(parts.label, centre, scale) if caps is not None else ():
        M[k] += R.T @ R
    free = []
    for Mk in M:
        w, vecs = np.linalg.eigh(Mk)
        free.append(vecs[:, w <= 1e-10 * max(w[-1], 1e-300)])
    return free


def _pair_parts(V, parts: BodyParts, pairs: list) -> list[tuple[set, set]]:
    """(the parts carrying the surface, the parts carrying the target) of each pair, on
    every rank alike (collective)."""
    fdim = V.mesh.topology.dim - 1
    out = []
    for groups in pairs:
        sides = []
        for facets in groups:
            nodes = fem.locate_dofs_topological(V, fdim, np.asarray(facets, dtype=np.int32))
            mine = np.unique(parts.label[nodes]).tolist()
            sides.append(set().union(*V.mesh.comm.allgather(mine)))
        out.append(tuple(sides))
    return out


def _held_by_pairs(free: list, links: list) -> dict:
    """part -> the pair (0-based) through which a chain of pairs ties it to a part that the
    Dirichlet data hold, for the parts with free motions that have such a chain."""
    held = {k for k, f in enumerate(free) if f.shape[1] == 0}
    via, grown = {}, True
    while grown:
        grown = False
        for i, (surface, target) in enumerate(links):
            for mine, other in ((surface, target), (target, surface)):
                if other & held:
                    for k in mine - held:
                        held.add(k)
                        via[k] = i
                        grown = True
    return via


def check_rigid_motions(V, fixed: np.ndarray, source: str, pairs: list = (),
                        caps=None, foundation=None) -> list:
    """Refuse Dirichlet data that leave a rigid motion of the body, or of one of its
    connected parts, free (collective): the step matrix would be singular.

    A part carrying a contact pair's surface or target group may leave rigid motions free
    when the pair ties it to a part that the Dirichlet data hold (directly, or through a
    chain of pairs and such parts): the contact holds them (a punch loaded by a pressure on
    its top, pressed onto a clamped substrate).  This is logged at INFO, naming the part, the
    free motions and the pair; the motions are then held only where the contact is active
    (a free normal motion needs the bound or the compliance active somewhere, a free
    tangential one friction with p_n > 0): otherwise the step's Newton matrix is singular.

    Args:
        V: the P1 vector space.
        fixed: bool (local nodes, d): prescribed components.
        source: the case file, for the message.
        pairs: for each contact pair, (its surface's local facets, its target's local
            facets); none for a case without pairs.
        caps: the rigid caps, or None (free_motions).
        foundation: the local facets of Gamma3 on the rigid foundation
            (boundaries.contact), or None: a part carrying them may leave rigid motions free,
            held by the contact with the foundation where the load presses the part onto it
            (app/model/semicoercive.py checks the loads before the first step).

    Returns:
        The HeldPart of each part whose free motions only the contact (the foundation's or
        a pair's) holds (empty: the Dirichlet data hold the body).

    Raises:
        CaseError: naming boundaries.clamped / loads.displacement, the free motions and, for
            a body in several parts, the part (its number of cells and a point in it).
    """
    d = V.dofmap.index_map_bs
    parts = body_parts(V)
    free = free_motions(V, fixed, parts, caps)
    links = _pair_parts(V, parts, list(pairs)) if len(pairs) else []
    via = _held_by_pairs(free, links) if links else {}
    on_foundation = set() if foundation is None else \
        _pair_parts(V, parts, [(foundation, foundation)])[0][0]
    held = []
    rigid = " / loads.rigid" if caps is not None else ""
    for k, f in enumerate(free):
        if f.shape[1] == 0:
            continue
        what = motion_names(f, d)
        where = "the body"
        if len(free) > 1:
            size = np.max(parts.hi[k] - parts.lo[k])
            point = ", ".join(f"{c:.6g}" if abs(c) > 1e-12 * size else "0"
                              for c in parts.point[k])
            where = (f"part {k + 1} of the body's {len(free)} disconnected parts "
                     f"({parts.cells[k]} cells, through the point ({point}))")
        if k in via:
            log.info("%s: %d rigid motion(s) of %s (like %s) held only by contact pair %d "
                     "(contact.pairs[%d])", source, f.shape[1], where, what, via[k], via[k])
        elif k in on_foundation:
            log.info("%s: %d rigid motion(s) of %s (like %s) held only by the contact with the "
                     "foundation (boundaries.contact)", source, f.shape[1], where, what)
        else:
            raise CaseError(f"{source}: boundaries.clamped / loads.displacement{rigid}: the "
                            f"prescribed displacements leave {f.shape[1]} rigid motion(s) of "
                            f"{where} free (like {what}); clamp a group "
                            f"{'on that part ' if len(free) > 1 else ''}"
                            "or prescribe more components")
        held.append(_held_part(parts, k, f, links))
    return held


def motion_names(free: np.ndarray, d: int) -> str:
    """The free motions in words ('translation x, rotation'): each column named by its
    largest component in the basis of ``rigid_modes``.

    Args:
        free: (r, free) the motions.
        d: the dimension.

    Returns:
        The names, comma separated.
    """
    names = ["translation x", "translation y", "translation z"][:d] + \
        (["rotation"] if d == 2 else ["rotation about z", "rotation about x",
                                       "rotation about y"])
    return ", ".join(names[int(np.argmax(np.abs(v)))] for v in free.T)


def _held_part(parts: BodyParts, k: int, free: np.ndarray, links: list) -> HeldPart:
    """The HeldPart of part k with its free motions (links: the pairs' parts)."""
    return HeldPart(parts.label == k, free, 0.5 * (parts.lo[k] + parts.hi[k]),
                    max(float(np.max(parts.hi[k] - parts.lo[k])), 1e-300),
                    tuple(i for i, (sf, _) in enumerate(links) if k in sf),
                    tuple(i for i, (sf, tg) in enumerate(links) if k in tg and k not in sf))
