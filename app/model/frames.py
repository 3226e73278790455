"""Nodal contact frames on Gamma3: the normal nu_i, tangents and gap g_i at every node.

The normal at a Gamma3 node is either the case's fixed approach direction
(``contact.direction``: a flat rigid obstacle) or the outward unit normal of Gamma3 at the
node, the facet normals weighted by int_f phi_i ds (area-weighted, assembled over ranks).  At
a node where the Dirichlet data prescribe some components (a symmetry roller), the normal is
projected onto the free components and normalised (the normal of the symmetric body); a node
whose normal lies in the prescribed components takes no bound.

Every node gets an orthonormal frame Q_i (its columns) in which the bound u_nu <= g is one
dof: column ``slot_i`` is ``sign_i`` nu_i.  Prescribed axes keep their own column (e_a in slot
a), so a Dirichlet condition stays a condition on that dof.  Where the normal is +-e_k the
frame is the identity (the paper's flat bottom: no rotation at all); otherwise nu_i takes the
first free slot and the tangents complete the frame.  ``tangents`` are the frame's other
columns, in 2D oriented as tau = (-nu_y, nu_x).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact.case import expressions
from vpcontact.io.errors import CaseError

log = logging.getLogger("vpcontact")

AXIS_TOL = 1e-12      # a normal within this of +-e_k is that axis (no rotated frame)
# contact.direction d against the outward normal n of Gamma3: refused where d.n <= DIRECTION_MIN
# at some node (d tangent to Gamma3 or pointing into the body: u_nu = u.d is then no normal
# displacement and the contact laws act on a tangential or inward one).  The nodal normal
# averages the node's facet normals, so a flat side tangent to d gives d.n = 0 up to the
# round-off of the coordinates (~1e-16 relative), and the end node of a curved Gamma3 that
# turns tangent to d (the quarter cylinder of hertz_cylinder at (1, 1)) gives
# d.n = sin(h / 2R) > 0: 1e-8 (90 - 6e-7 degrees) separates the two.  A direction grazing
# Gamma3 as a whole (the mean of d.n over its nodes below cos 80 degrees) is only warned of.
DIRECTION_MIN = 1e-8
DIRECTION_GRAZING_DEG = 80.0


@dataclass
class ContactFrames:
    """The nodal data of Gamma3 (owned and ghost nodes).

    Attributes:
        nodes: local node indices, sorted.
        normal: (m, d) unit normals nu_i.
        tangents: (m, d - 1, d) unit tangents.
        Q: (m, d, d) orthonormal frames (columns).
        slot: (m,) the column of Q along the normal.
        sign: (m,) +-1: nu_i = sign_i Q_i[:, slot_i].
        bounded: (m,) the node carries the bound u_nu <= g (the normal is not prescribed).
        g: (m,) the gap, or None without the bound.
        rotated: some frame (on some rank) is not the identity.
    """

    nodes: np.ndarray
    normal: np.ndarray
    tangents: np.ndarray
    Q: np.ndarray
    slot: np.ndarray
    sign: np.ndarray
    bounded: np.ndarray
    g: np.ndarray | None
    rotated: bool


def facet_normals(V, ds_contact) -> np.ndarray:
    """Area-weighted outward unit normals at all local nodes (zero off Gamma3).

    Args:
        V: the P1 vector space.
        ds_contact: the measure of Gamma3 (any exact rule for P1 times a facet constant).

    Returns:
        (local nodes, d) normals, owned and ghost values consistent over ranks.
    """
    d = V.dofmap.index_map_bs
    v = ufl.TestFunction(V)
    n = ufl.FacetNormal(V.mesh)
    vec = fem.petsc.assemble_vector(fem.form(ufl.dot(n, v) * ds_contact))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    vec.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    with vec.localForm() as loc:
        out = loc.array.reshape(-1, d).copy()
    vec.destroy()
    norm = np.linalg.norm(out, axis=1)
    nz = norm > 0
    out[nz] /= norm[nz, None]
    return out


def _frame(nu: np.ndarray, fixed: np.ndarray):
    """(Q, slot, sign) of one node: prescribed axes in their own columns, nu in a free one."""
    d = len(nu)
    k = int(np.argmax(np.abs(nu)))
    if abs(abs(nu[k]) - 1.0) <= AXIS_TOL and not fixed[k]:
        return np.eye(d), k, (1 if nu[k] > 0 else -1)
    Q = np.eye(d)
    free = [a for a in range(d) if not fixed[a]]
    slot = free[0]
    Q[:, slot] = nu
    others = free[1:]
    if d == 2 and others:
        Q[:, others[0]] = (-nu[1], nu[0])
    else:
        basis = [Q[:, a] for a in range(d) if fixed[a]] + [nu]
        for a in others:
            t = np.eye(d)[a] - sum((b @ np.eye(d)[a]) * b for b in basis)
            if np.linalg.norm(t) < 1e-6:                 # e_a nearly along nu: another axis
                t = np.eye(d)[(a + 1) % d] - sum((b @ np.eye(d)[(a + 1) % d]) * b
                                                 for b in basis)
            t /= np.linalg.norm(t)
            Q[:, a] = t
            basis.append(t)
    return Q, slot, 1


def build_frames(V, nodes: np.ndarray, raw_normal: np.ndarray, fixed: np.ndarray,
                 direction, source: str) -> ContactFrames:
    """Frames at the Gamma3 nodes.

    Args:
        V: the P1 vector space.
        nodes: local Gamma3 node indices (owned and ghost, sorted).
        raw_normal: (nodes, d) the facet normals at these nodes (ignored with a direction).
        fixed: bool (nodes, d): the components the Dirichlet data prescribe at these nodes.
        direction: the case's contact.direction (unit) or None.
        source: the case file, for messages.

    Returns:
        The ContactFrames (g not yet set).

    Raises:
        CaseError: a fixed direction not orthogonal to a prescribed component of a node,
            or tangent to Gamma3 or pointing into the body at a node (check_direction).
    """
    m, d = len(nodes), V.dofmap.index_map_bs
    nu = np.broadcast_to(np.asarray(direction, float), (m, d)).copy() if direction is not None \
        else raw_normal.copy()
    projected = np.where(fixed, 0.0, nu)
    size = np.linalg.norm(projected, axis=1)
    if direction is not None:
        bad = (size > 1e-6) & (np.abs(size - 1.0) > 1e-8)
        if V.mesh.comm.allreduce(bool(bad.any()), op=MPI.LOR):
            raise CaseError(f"{source}: contact.direction: not orthogonal to the prescribed "
                            "components of loads.displacement at a Gamma3 node; prescribe "
                            "components orthogonal to the direction there")
    bounded = size > 1e-6
    if direction is not None:
        check_direction(V, nodes[bounded], raw_normal[bounded], direction, source)
    nu = np.where(bounded[:, None], projected / np.where(bounded, size, 1.0)[:, None], nu)
    Q, slot, sign = np.empty((m, d, d)), np.empty(m, dtype=np.int32), np.empty(m, dtype=np.int32)
    tangents = np.zeros((m, d - 1, d))
    for i in range(m):
        Qi, slot[i], sign[i] = _frame(nu[i], fixed[i] if bounded[i] else np.zeros(d, bool))
        tangents[i] = np.delete(Qi, slot[i], axis=1).T
        # a node without the bound (its normal is prescribed) needs no rotated dof
        Q[i] = Qi if bounded[i] else np.eye(d)
        if not bounded[i]:
            slot[i] = int(np.argmax(np.abs(nu[i])))
            sign[i] = 1 if nu[i, slot[i]] > 0 else -1
    rotated = bool(V.mesh.comm.allreduce(bool(np.any(Q != np.eye(d))), op=MPI.LOR))
    return ContactFrames(nodes, nu, tangents, Q, slot, sign, bounded, None, rotated)


def check_direction(V, nodes: np.ndarray, normal: np.ndarray, direction, source: str) -> None:
    """Refuse a contact.direction d tangent to Gamma3 or pointing into the body: d.n <=
    DIRECTION_MIN at some node (n the outward nodal normal); warn where d grazes Gamma3 as a
    whole (see DIRECTION_MIN).  Collective: every rank raises.

    Args:
        V: the P1 vector space.
        nodes: the local Gamma3 nodes that carry the bound u.d <= g.
        normal: (nodes, d) their outward unit normals (facet_normals).
        direction: the case's contact.direction (unit).
        source: the case file, for messages.

    Raises:
        CaseError: naming the node of the smallest d.n and its angle, on every rank.
    """
    comm, d = V.mesh.comm, V.dofmap.index_map_bs
    dn = normal @ np.asarray(direction, float)
    x = V.tabulate_dof_coordinates()[nodes, :d]
    # the smallest d.n, ties to the lowest coordinates: the same node on any rank count
    worst = int(np.lexsort((*x.T[::-1], dn))[0]) if len(dn) else None
    mine = (float(dn[worst]), tuple(float(v) + 0.0 for v in np.round(x[worst], 6))) \
        if worst is not None else (np.inf, None)
    value, point = min(comm.allgather(mine), key=lambda item: (item[0], item[1] or ()))
    show = [float(v) for v in np.round(np.asarray(direction, float), 6)]
    if value <= DIRECTION_MIN:
        angle = np.degrees(np.arccos(np.clip(value, -1.0, 1.0)))
        raise CaseError(f"{source}: contact.direction: {show} makes {angle:.1f} degrees with "
                        f"the outward normal of Gamma3 at the node {point}: it is tangent to "
                        "Gamma3 or points into the body there (it must point from the body "
                        "toward the obstacle, under 90 degrees to the outward normal at every "
                        "Gamma3 node)")
    owned = nodes < V.dofmap.index_map.size_local
    total = comm.allreduce(float(dn[owned].sum()), op=MPI.SUM)
    count = comm.allreduce(int(owned.sum()), op=MPI.SUM)
    mean = np.degrees(np.arccos(np.clip(total / max(count, 1), -1.0, 1.0)))
    if count and mean > DIRECTION_GRAZING_DEG and comm.rank == 0:
        log.warning("%s: contact.direction: %s makes %.1f degrees on average with the outward "
                    "normal of Gamma3: u_nu = u.d is nearly tangential there", source, show,
                    mean)


def gap_values(g, x: np.ndarray, source: str, comm) -> np.ndarray:
    """The gap g at Gamma3 nodes: a number, or an expression of x, y, z.

    Args:
        g: contact.g (float or expression string).
        x: (m, d) node coordinates.
        source: the case file, for messages.
        comm: the communicator (the check is collective).

    Returns:
        (m,) gap values.

    Raises:
        CaseError: if g is not finite or is negative at some Gamma3 node beyond the
            round-off of the coordinates (on every rank); round-off is clipped to 0.
    """
    if isinstance(g, str):
        tree = expressions.parse(g, ("x", "y", "z"))
        sym = {a: x[:, i] for i, a in enumerate("xyz"[:x.shape[1]])}
        sym.setdefault("z", np.zeros(len(x)))
        with np.errstate(all="ignore"):
            values = np.broadcast_to(np.asarray(expressions.evaluate(tree, sym), float),
                                     (len(x),)).copy()
    else:
        values = np.full(len(x), float(g))
    # node coordinates carry round-off (gmsh puts a point of y = 0 at y = -1e-17)
    scale = comm.allreduce(float(np.abs(x).max(initial=0.0)), op=MPI.MAX)
    bad = ~np.isfinite(values) | (values < -1e-12 * scale)
    values = np.maximum(values, 0.0)
    where = x[bad][0] if bad.any() else None
    if comm.allreduce(bool(bad.any()), op=MPI.LOR):
        found = comm.allgather(None if where is None else tuple(np.round(where, 6)))
        point = next(p for p in found if p is not None)
        raise CaseError(f"{source}: contact.g: {g!r} is negative or not finite at the Gamma3 "
                        f"node {point} (the gap must be >= 0 on Gamma3)")
    return values
