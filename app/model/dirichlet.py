"""The Dirichlet data of a scene: Gamma1 (u = 0 on the clamped groups) and the prescribed
displacement components of ``loads.displacement`` (numbers, expressions of x, y, z, t or
tables in t; ``null`` leaves a component free).

Each prescribed component of a group is one dolfinx condition on the collapsed component
space, its values interpolated at every step's t_n (``set_time``).  A vertex shared by a
clamped and a displaced group is clamped (the clamped conditions come last and win).
Before any solve, ``check_rigid_motions`` refuses data that leave a rigid motion of the body
free: the step matrix would be singular.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from app.io.errors import CaseError


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


def build_dirichlet(V, facets: dict, clamped: list, displacement: dict, time_data) -> DirichletData:
    """The Dirichlet conditions of the clamped groups and of ``loads.displacement``.

    Args:
        V: the P1 vector space V^h.
        facets: group name -> the local facet indices of that group.
        clamped: the clamped group names (Gamma1).
        displacement: group name -> components (number, expression, table or None: free).
        time_data: the TimeData of the run (UFL of expressions, time Constants).

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


def check_rigid_motions(V, fixed: np.ndarray, bbox, source: str) -> None:
    """Refuse Dirichlet data that leave a rigid motion free (collective).

    A rigid motion r is blocked when it does not vanish on the prescribed components:
    the Gram matrix M = sum over prescribed (node, component) of r_a r_b must be positive
    definite (its smallest eigenvalue above 1e-10 of its largest, coordinates centred and
    scaled by the body's size).

    Args:
        V: the P1 vector space.
        fixed: bool (local nodes, d): prescribed components.
        bbox: (lo, hi), the body's bounding box over all ranks (the mesh's ``bbox``).
        source: the case file, for the message.

    Raises:
        CaseError: naming boundaries.clamped / loads.displacement and the free motions.
    """
    comm = V.mesh.comm
    d = V.dofmap.index_map_bs
    owned = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:owned, :d]
    lo, hi = (np.asarray(b, dtype=float)[:d] for b in bbox)
    scale = max(float(np.max(hi - lo)), 1e-300)
    modes = rigid_modes((x - 0.5 * (lo + hi)) / scale)          # (n, d, r)
    mask = fixed[:owned]
    rows = modes[mask]                                           # (prescribed, r)
    M = comm.allreduce(rows.T @ rows, op=MPI.SUM)
    w, vecs = np.linalg.eigh(M)
    free = w <= 1e-10 * max(w[-1], 1e-300)
    if free.any():
        names = ["translation x", "translation y", "translation z"][:d] + \
            (["rotation"] if d == 2 else ["rotation about z", "rotation about x",
                                           "rotation about y"])
        what = ", ".join(names[int(np.argmax(np.abs(v)))] for v in vecs[:, free].T)
        raise CaseError(f"{source}: boundaries.clamped / loads.displacement: the prescribed "
                        f"displacements leave {int(free.sum())} rigid motion(s) of the body "
                        f"free (like {what}); clamp a group or prescribe more components")
