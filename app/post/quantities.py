"""Quantities derived from the state of a run: the step record's norms (||u||_V,
||sigma||_Q, ||kappa||_Y, the largest cell values), the bulk residual at the nodes and from
it the reactions on the Dirichlet groups, the contact force and the contact table of the
Gamma3 nodes.  Functions of the ContactProblem (its discretisation, State and forms);
collective where they reduce over ranks, as their docstrings say.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI


def norm(problem, which: str) -> float:
    """A norm of the step record, reduced over ranks; collective.

    Exact cell sums (eps(u) and sigma are constant on cells).

    Args:
        problem: the ContactProblem.
        which: "V" for ||u||_V = ||eps(u)||_L2, "Q" for ||sigma||_Q.

    Returns:
        The norm.
    """
    op = problem.strain_operator
    if which == "V":
        return float(np.sqrt(max(op.strain_norm2(problem.u), 0.0)))
    local = op.energy_norm2(problem.sigma.x.array[:op.n_owned * problem.dim**2])
    return float(np.sqrt(problem.reduce(local, "SUM")))


def cell_norm(problem, f) -> float:
    """L2 norm of a DG0 function (||kappa||_Y), reduced over ranks; collective.

    Args:
        problem: the ContactProblem.
        f: a DG0 Function on the mesh (scalar, or m components: the Euclidean norm per cell).

    Returns:
        The norm.
    """
    n = problem.num_owned_cells
    vol = problem.cell_volumes()[:n]
    bs = f.function_space.dofmap.index_map_bs
    a = f.x.array[:n * bs].reshape(n, bs)
    local = float(vol @ np.einsum("ij,ij->i", a, a))
    return float(np.sqrt(problem.reduce(local, "SUM")))


def cell_max(problem, f) -> float:
    """The largest cell value of a DG0 function (of any of its components), over ranks;
    collective.

    Args:
        problem: the ContactProblem.
        f: a DG0 Function on the mesh.

    Returns:
        The maximum (-inf without cells).
    """
    n = problem.num_owned_cells * f.function_space.dofmap.index_map_bs
    local = float(np.max(f.x.array[:n])) if n else -np.inf
    return float(problem.reduce(local, "MAX"))


def bulk_residual(problem) -> np.ndarray:
    """The bulk residual r = (sigma_n, eps(phi_i)) - f_n(phi_i) at the owned nodes, exact at
    the nodes of the Dirichlet groups, of Gamma3 and of the pairs' targets: the force the
    boundary (supports, contact) exerts on the body there (app/model/layer.py; the problem's
    sigma must be the stress of its u); collective.

    Args:
        problem: the ContactProblem.

    Returns:
        (owned nodes, d) nodal forces.
    """
    return problem.boundary_layer.residual()


# Coulomb friction: a node slips where |sigma_tau| >= (1 - SLIP_RATIO) mu p_n
SLIP_RATIO = 1e-6


def contact_table(problem, r: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Per owned Gamma3 node: coordinates, displacement, u_nu, tangential components in
    the nodal frame, and the contact force densities -sigma_nu, -sigma_tau (and xi,
    theta(s), the gap where it varies; with Coulomb friction the bound mu p_n
    (friction_bound) and slip_state: 1 slip, 0 stick).

    The force at node i is the bulk residual r_i = (sigma_n, eps(phi_i)) - f(phi_i)
    divided by the node's weight w_i = int phi_i ds: with the nodal rule this is exactly
    p(u_nu) + memory force + (bound multiplier)/w_i in the normal direction and the
    friction force in the tangential ones.

    Args:
        problem: the ContactProblem.
        r: the bulk residual (bulk_residual()), or None to assemble it.

    Returns:
        Column name -> values of the owned Gamma3 nodes (sorted by coordinates).
    """
    gm, d, fr = problem.gamma3, problem.dim, problem.frames
    rr = (bulk_residual(problem) if r is None else r)[gm.nodes]
    uu = problem.u.x.array.reshape(-1, d)[gm.nodes]
    pos = np.searchsorted(fr.nodes, gm.nodes)
    ww = uu if problem.pairs is None else problem.contact_u()[pos]   # two bodies: [u] - d nu
    nu, tau = fr.normal[pos], fr.tangents[pos]
    axes = "xyz"[:d]
    table = {a: gm.x[:, i] for i, a in enumerate(axes)}
    table.update({f"u_{a}": uu[:, i] for i, a in enumerate(axes)})
    table["u_nu"] = np.einsum("ij,ij->i", ww, nu)
    u_tau = np.einsum("ij,ikj->ik", ww, tau)
    f_tau = -np.einsum("ij,ikj->ik", rr, tau) / gm.weight[:, None]
    suffix = [""] if d == 2 else ["1", "2"]
    for k, sfx in enumerate(suffix):
        table[f"u_tau{sfx}"] = u_tau[:, k]
    if d == 3:
        table["u_tau"] = np.linalg.norm(u_tau, axis=1)
    table["neg_sigma_nu"] = -np.einsum("ij,ij->i", rr, nu) / gm.weight
    for k, sfx in enumerate(suffix):
        table[f"neg_sigma_tau{sfx}"] = f_tau[:, k]
    if problem.xi is not None:
        table["xi"] = problem.xi.function.x.array[problem.xi.dofs[pos]]
    # the columns by the case's laws (the same on every rank), the values node by node
    has = coulomb_sections(problem)
    coulomb = coulomb_nodes(problem, pos)
    theta = None if problem.theta is None else \
        problem.theta.function.x.array[problem.theta.dofs[pos]]
    if theta is not None and not all(has):     # (laws per pair: not at Coulomb's nodes)
        table["theta"] = np.where(coulomb, np.nan, theta)
    if any(has):  # theta holds the bound mu p_n (theta(s_n)): slip where it is reached
        table["friction_bound"] = np.where(coulomb, theta, np.nan)
        slip = np.linalg.norm(f_tau, axis=1) >= (1 - SLIP_RATIO) * theta
        table["slip_state"] = np.where(coulomb, slip.astype(float), np.nan)
    if isinstance(problem.case.contact.g, str) or problem.pairs is not None:
        table["g"] = fr.g[pos]
    if problem.pairs is not None:      # two bodies: the pair and the initial distance d
        table["pair"] = problem.pairs.pair[pos].astype(float)
        table["d"] = problem.pairs.distance[pos]
    # hidden (not a CSV column): the Dirichlet data prescribe u_nu here, so the force is
    # a support's reaction, not a contact pressure
    table["_prescribed"] = ~fr.bounded[pos]
    return table


def coulomb_sections(problem) -> list[bool]:
    """Which sets of laws (``Contact.sections``: one, or one per pair) have Coulomb friction.

    Args:
        problem: the ContactProblem.

    Returns:
        One bool per set of laws.
    """
    return [c.friction is not None and c.friction.coulomb is not None
            for c in problem.case.contact.sections]


def coulomb_nodes(problem, pos: np.ndarray) -> np.ndarray:
    """Which Gamma3 nodes have Coulomb friction (every node or none, but with laws per
    pair: the nodes of the pairs whose laws have it).

    Args:
        problem: the ContactProblem.
        pos: the nodes' positions in the frames' order.

    Returns:
        A boolean mask, shape (len(pos),).
    """
    has = coulomb_sections(problem)
    if len(has) == 1:
        return np.full(len(pos), has[0])
    return np.asarray(has)[problem.pairs.pair[pos]]


def summed(comm, local: np.ndarray) -> np.ndarray:
    """The sum over the ranks of a float array, by a buffer reduction (no pickling; none
    in a serial run); collective.

    Args:
        comm: the communicator.
        local: this rank's part.

    Returns:
        A new array of the sums.
    """
    out = np.array(local, dtype=float)
    if comm.size > 1:
        comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
    return out


def forces(problem, r: np.ndarray | None = None) -> dict:
    """The reaction force resultant on each Dirichlet group and the total contact
    force, both exerted on the body (collective).  With the loads they sum to zero
    (equilibrium, up to the solver's tolerance).

    Args:
        problem: the ContactProblem.
        r: the bulk residual (bulk_residual()), or None to assemble it.

    Returns:
        {"reactions": {group: [F_x, F_y(, F_z)]}, "contact_force": [...] (Gamma3 dofs
        that no Dirichlet condition prescribes) or None without contact, "pair_forces":
        pair_forces() or None without contact pairs}.
    """
    r = (bulk_residual(problem) if r is None else r).ravel()
    d, groups = problem.dim, problem.dirichlet.groups
    rows = [np.bincount(grp.dofs % d, weights=r[grp.dofs], minlength=d) for grp in groups]
    if problem.gamma3 is not None:
        nodes = problem.gamma3.nodes
        free = ~problem.dirichlet.fixed[nodes]
        rows.append((r.reshape(-1, d)[nodes] * free).sum(axis=0))
    total = summed(problem.comm, np.reshape(rows, (-1, d))).tolist()   # one reduction
    reactions = {str(grp.name): total[i] for i, grp in enumerate(groups)}
    contact = total[-1] if problem.gamma3 is not None else None
    return {"reactions": reactions, "contact_force": contact,
            "pair_forces": pair_forces(problem, r) if problem.pairs is not None else None}


def pair_forces(problem, r: np.ndarray) -> list[dict]:
    """The contact force resultant on each body of each pair (collective): the sum of the
    bulk residual r_i = (sigma_n, eps(phi_i)) - f_n(phi_i) over the dofs of the pair's
    surface nodes and over those of its target nodes that no Dirichlet condition
    prescribes (at a prescribed dof r_i is in that group's reaction).  r_i at a free dof
    is the force the other body exerts there (loads are in f_n), so each body's reactions,
    its contact force and its loads sum to zero up to the solver's tolerance.  The
    coupling's rows sum to 1, so on_target = -on_surface but for the contact force at the
    target's prescribed dofs (e.g. a symmetry roller's), which is in that group's reaction.

    Args:
        problem: the ContactProblem with contact pairs.
        r: the bulk residual (bulk_residual(), the layer's is exact at the surface and
            target nodes).

    Returns:
        Per pair {"surface": group, "target": group, "on_surface": [F_x, ...],
        "on_target": [...]}.
    """
    from vpcontact.model.pairs import surface_nodes
    d = problem.dim
    r = r.reshape(-1, d)
    fixed = problem.dirichlet.fixed
    n_owned = problem.V.dofmap.index_map.size_local
    pos = np.searchsorted(problem.frames.nodes, problem.gamma3.nodes)
    out = []
    for i, p in enumerate(problem.case.contact.pairs):
        surface = problem.gamma3.nodes[problem.pairs.pair[pos] == i]
        target = surface_nodes(problem.disc, p.target)
        target = target[target < n_owned]
        local = [(r[nodes] * ~fixed[nodes]).sum(axis=0) for nodes in (surface, target)]
        on_surface, on_target = summed(problem.comm, np.array(local))
        out.append({"surface": str(p.surface), "target": str(p.target),
                    "on_surface": [float(v) for v in on_surface],
                    "on_target": [float(v) for v in on_target]})
    return out
