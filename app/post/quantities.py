"""Quantities derived from the state of a run: the step record's norms (||u||_V,
||sigma||_Q, ||kappa||_Y, the largest cell values), the bulk residual at the nodes and from
it the reactions on the Dirichlet groups, the contact force and the contact table of the
Gamma3 nodes.  Functions of the ContactProblem (its discretisation, State and forms);
collective where they reduce over ranks, as their docstrings say.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from vpcontact.io.output import SEPARATED_RATIO, U_ROUNDOFF


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
    local = op.energy_norm2(problem.sigma.x.array[:op.n_owned * problem.disc.dim**2])
    return float(np.sqrt(problem.disc.reduce(local, "SUM")))


def cell_norm(problem, f) -> float:
    """L2 norm of a DG0 function (||kappa||_Y), reduced over ranks; collective.

    Args:
        problem: the ContactProblem.
        f: a DG0 Function on the mesh (scalar, or m components: the Euclidean norm per cell).

    Returns:
        The norm.
    """
    disc = problem.disc
    n = disc.num_owned_cells
    vol = disc.cell_volumes()[:n]
    bs = f.function_space.dofmap.index_map_bs
    a = f.x.array[:n * bs].reshape(n, bs)
    local = float(vol @ np.einsum("ij,ij->i", a, a))
    return float(np.sqrt(disc.reduce(local, "SUM")))


def cell_max(problem, f) -> float:
    """The largest cell value of a DG0 function (of any of its components), over ranks;
    collective.

    Args:
        problem: the ContactProblem.
        f: a DG0 Function on the mesh.

    Returns:
        The maximum (-inf without cells).
    """
    n = problem.disc.num_owned_cells * f.function_space.dofmap.index_map_bs
    local = float(np.max(f.x.array[:n])) if n else -np.inf
    return float(problem.disc.reduce(local, "MAX"))


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


# slip_state (Coulomb friction) of a Gamma3 node in contact.csv and contact.xdmf
SLIP_CODES = {"separated": -1, "stick": 0, "slip": 1}
# slip in step n: a slip increment beyond SLIP_DELTAS delta (slip_threshold)
SLIP_DELTAS = 10.0


def slip_threshold(delta: float, u_scale: float) -> float:
    """The slip increment above which a node slips in a step: max(SLIP_DELTAS delta,
    U_ROUNDOFF u_scale).

    The friction term is regularised as theta psi(|u_tau|_delta), |x|_delta =
    sqrt(|x|^2 + delta^2): with Coulomb's psi(rho) = rho the friction stress is
    q = theta rho / sqrt(rho^2 + delta^2), rho = |u_tau|.  A node that sticks with
    q = s theta (s < 1) sits at rho = delta s / sqrt(1 - s^2): below 0.6 delta for
    s <= 1/2, 7 delta at s = 0.99, 10 delta at s = 0.995.  A node that moves by more
    than 10 delta in one step has left the regularisation's stick branch (its friction
    is within 0.5 % of the bound, and within delta^2 / (2 rho^2) of it); a sliding node
    moves by far more (the slip displacement, e.g. 1e3 - 1e5 delta in the shipped cases).
    The bound |q| >= (1 - 1e-6) theta misreads as stuck every node that has slid less than
    delta / sqrt(2e-6) ~ 700 delta.  The second term keeps the test above the round-off
    of the displacements (1e-9 of their largest value on Gamma3) when delta is tiny
    against them.

    Args:
        delta: the friction regularisation (solver.delta).
        u_scale: the largest displacement on Gamma3 (over all ranks).

    Returns:
        The threshold (m).
    """
    return max(SLIP_DELTAS * delta, U_ROUNDOFF * u_scale)


def slip_states(p_n: np.ndarray, increment: np.ndarray, threshold: float,
                p_scale: float) -> np.ndarray:
    """The slip_state code of each node (SLIP_CODES): -1 separated (p_n <= SEPARATED_RATIO
    p_scale: no friction bound), else 1 slip (the slip increment of the step above
    threshold) or 0 stick.  Every scale is of the whole Gamma3 (over all ranks), so a state
    is the same on any number of ranks.

    Args:
        p_n: the contact pressure -sigma_nu at the nodes (0 where u_nu is prescribed).
        increment: the slip increment |u_{n,tau} - u_{n-1,tau}| at the nodes.
        threshold: slip_threshold().
        p_scale: the largest p_n on Gamma3 (over all ranks).

    Returns:
        The codes, float (NaN-able as the table's columns).
    """
    state = np.where(increment > threshold, SLIP_CODES["slip"], SLIP_CODES["stick"])
    return np.where(p_n <= SEPARATED_RATIO * p_scale, SLIP_CODES["separated"],
                    state).astype(float)


def held_nodes(disc) -> np.ndarray:
    """The owned Gamma3 nodes where a Dirichlet condition prescribes a component of u (a
    pushed side's corner, a roller's end): their residual holds the support's reaction.

    Args:
        disc: the Discretisation.

    Returns:
        A boolean mask over disc.gamma3.nodes.
    """
    return disc.dirichlet.fixed[disc.gamma3.nodes].any(axis=1)


def law_friction(problem, pos: np.ndarray, u_tau: np.ndarray) -> np.ndarray:
    """The friction stress of the laws at Gamma3 nodes: the gradient in u_tau of the
    friction term theta_i psi(|u_tau|_delta) of (3.4), theta_i psi'(rho) u_tau / rho with
    rho = |u_tau|_delta (Coulomb: theta_i = mu p_n(,i) theta(s_n)), the force density the
    body exerts on the foundation (minus the foundation's on the body).  Local.

    Args:
        problem: the ContactProblem.
        pos: the nodes' positions in the frames' order.
        u_tau: their tangential displacements (vectors, (len(pos), d)).

    Returns:
        (len(pos), d) stress vectors (zero without friction).
    """
    out = np.zeros_like(u_tau, dtype=float)
    theta = np.ones(len(pos)) if problem.theta is None else \
        problem.theta.function.x.array[problem.theta.dofs[pos]]
    pairs = problem.disc.pairs
    section = np.zeros(len(pos), int) if pairs is None else pairs.pair[pos]
    for k, law in enumerate(problem.section_laws()):
        rows = section == k
        if law.friction is None or not rows.any():
            continue
        rho = law.norm.value(u_tau[rows])
        out[rows] = (theta[rows] * law.friction.derivative(rho) / rho)[:, None] * u_tau[rows]
    return out


def _global_max(comm, values: list[float]) -> list[float]:
    """The maxima over the ranks of a few numbers (one buffer reduction); collective."""
    out = np.array(values, dtype=float)
    if comm.size > 1:
        comm.Allreduce(MPI.IN_PLACE, out, op=MPI.MAX)
    return out.tolist()


def contact_table(problem, r: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Per owned Gamma3 node: coordinates, displacement, u_nu, tangential components in
    the nodal frame, and the contact force densities -sigma_nu, -sigma_tau (and xi,
    theta(s), the gap where it varies; with Coulomb friction the bound mu p_n
    (friction_bound) and slip_state (SLIP_CODES: -1 separated, 0 stick, 1 slip); with
    Coulomb friction or a slip law the slip increment of the step and the accumulated slip
    (slip_increment, slip_accumulated: app/model/gamma3.py SlipPath); where some node of
    Gamma3 is held by a Dirichlet condition, held (1 there, else 0)).  Collective (the
    scales of slip_state and the presence of held nodes are reduced over the ranks).

    The force at node i is the bulk residual r_i = (sigma_n, eps(phi_i)) - f(phi_i)
    divided by the node's weight w_i = int phi_i ds: with the nodal rule this is exactly
    p(u_nu) + memory force + (bound multiplier)/w_i in the normal direction and the
    friction force in the tangential ones.  At a node where a Dirichlet condition
    prescribes a component (held_nodes) the residual also holds the support's reaction:
    -sigma_tau there is the laws' friction (law_friction), as in forces().

    Args:
        problem: the ContactProblem.
        r: the bulk residual (bulk_residual()), or None to assemble it.

    Returns:
        Column name -> values of the owned Gamma3 nodes (sorted by coordinates).
    """
    disc = problem.disc
    gm, d, fr = disc.gamma3, disc.dim, disc.frames
    rr = (bulk_residual(problem) if r is None else r)[gm.nodes]
    uu = problem.u.x.array.reshape(-1, d)[gm.nodes]
    pos = np.searchsorted(fr.nodes, gm.nodes)
    ww = uu if disc.pairs is None else problem.contact_u()[pos]   # two bodies: [u] - d nu
    nu, tau = fr.normal[pos], fr.tangents[pos]
    axes = "xyz"[:d]
    table = {a: gm.x[:, i] for i, a in enumerate(axes)}
    table.update({f"u_{a}": uu[:, i] for i, a in enumerate(axes)})
    table["u_nu"] = np.einsum("ij,ij->i", ww, nu)
    u_tau = np.einsum("ij,ikj->ik", ww, tau)
    f_tau = -np.einsum("ij,ikj->ik", rr, tau) / gm.weight[:, None]
    held = held_nodes(disc)
    u_tau_vec = ww - table["u_nu"][:, None] * nu
    if held.any():                       # the support's reaction: the laws' friction instead
        f_tau[held] = np.einsum("ij,ikj->ik", law_friction(problem, pos[held],
                                                           u_tau_vec[held]), tau[held])
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
    _friction_columns(problem, table, pos, u_tau_vec)
    if disc.comm.allreduce(bool(held.any()), op=MPI.LOR):
        table["held"] = held.astype(float)
    if isinstance(problem.case.contact.g, str) or disc.pairs is not None:
        table["g"] = fr.g[pos]
    if disc.pairs is not None:      # two bodies: the pair and the initial distance d
        table["pair"] = disc.pairs.pair[pos].astype(float)
        table["d"] = disc.pairs.distance[pos]
    # hidden (not a CSV column): the Dirichlet data prescribe u_nu here, so the force is
    # a support's reaction, not a contact pressure
    table["_prescribed"] = ~fr.bounded[pos]
    return table


def _friction_columns(problem, table: dict, pos: np.ndarray, u_tau: np.ndarray) -> None:
    """theta, friction_bound, slip_state, slip_increment, slip_accumulated (where the case
    has them) into the table; collective (slip_state's scales)."""
    has = coulomb_sections(problem)       # the columns by the case's laws (every rank)
    coulomb = coulomb_nodes(problem, pos)
    theta = None if problem.theta is None else \
        problem.theta.function.x.array[problem.theta.dofs[pos]]
    if theta is not None and not all(has):     # (laws per pair: not at Coulomb's nodes)
        table["theta"] = np.where(coulomb, np.nan, theta)
    g3 = problem.state.gamma3
    path = None if g3 is None else g3.path
    increment = np.zeros(len(pos)) if path is None else path.increment(u_tau, pos)
    if any(has):  # theta holds the bound mu p_n (theta(s_n)): slip where the node moves
        table["friction_bound"] = np.where(coulomb, theta, np.nan)
        p_n = np.where(problem.disc.frames.bounded[pos], table["neg_sigma_nu"], 0.0)
        u_scale, p_scale = _global_max(problem.disc.comm, [
            float(np.abs(u_tau).max(initial=0.0)), float(p_n.max(initial=0.0))])
        state = slip_states(p_n, increment,
                            slip_threshold(problem.case.numerics.delta, u_scale), p_scale)
        table["slip_state"] = np.where(coulomb, state, np.nan)
    if path is not None:
        table["slip_increment"] = increment
        table["slip_accumulated"] = path.accumulated(u_tau, pos)


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
    return np.asarray(has)[problem.disc.pairs.pair[pos]]


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

    At a Gamma3 node where a Dirichlet condition prescribes a component (held_nodes: a
    pushed side's corner) the residual of that component is the support's reaction plus
    the friction of the laws there (law_friction): the friction is counted in the contact
    force with the node's pressure, and only the rest in the group's reaction (the sum is
    unchanged).

    Args:
        problem: the ContactProblem.
        r: the bulk residual (bulk_residual()), or None to assemble it.

    Returns:
        {"reactions": {group: [F_x, F_y(, F_z)]}, "contact_force": [...] (Gamma3 dofs
        that no Dirichlet condition prescribes, and the friction at those it does) or None
        without contact, "pair_forces": pair_forces() or None without contact pairs}.
    """
    r = (bulk_residual(problem) if r is None else r).ravel()
    disc = problem.disc
    d, groups = disc.dim, disc.dirichlet.groups
    moved = np.zeros_like(r)                    # the friction at held Gamma3 dofs
    if disc.gamma3 is not None:
        nodes = disc.gamma3.nodes
        fixed = disc.dirichlet.fixed[nodes]
        moved.reshape(-1, d)[nodes] = held_friction(problem) * fixed
    rows = [np.bincount(grp.dofs % d, weights=(r - moved)[grp.dofs], minlength=d)
            for grp in groups]
    if disc.gamma3 is not None:
        rows.append((r.reshape(-1, d)[nodes] * ~fixed).sum(axis=0)
                    + moved.reshape(-1, d)[nodes].sum(axis=0))
    total = summed(disc.comm, np.reshape(rows, (-1, d))).tolist()   # one reduction
    reactions = {str(grp.name): total[i] for i, grp in enumerate(groups)}
    contact = total[-1] if disc.gamma3 is not None else None
    return {"reactions": reactions, "contact_force": contact,
            "pair_forces": pair_forces(problem, r, moved) if disc.pairs is not None
            else None}


def held_friction(problem) -> np.ndarray:
    """The friction force of the laws on the body at the owned Gamma3 nodes that a
    Dirichlet condition holds (held_nodes), -w_i law_friction, zero elsewhere; collective
    (two bodies' relative displacement).

    Args:
        problem: the ContactProblem with Gamma3.

    Returns:
        (owned Gamma3 nodes, d) nodal forces.
    """
    disc = problem.disc
    gm, fr = disc.gamma3, disc.frames
    held = held_nodes(disc)
    out = np.zeros((len(gm.nodes), disc.dim))
    if not disc.comm.allreduce(bool(held.any()), op=MPI.LOR):
        return out
    pos = np.searchsorted(fr.nodes, gm.nodes)
    w = problem.u.x.array.reshape(-1, disc.dim)[gm.nodes] if disc.pairs is None \
        else problem.contact_u()[pos]
    nu = fr.normal[pos]
    u_tau = w - np.einsum("ij,ij->i", w, nu)[:, None] * nu
    out[held] = -gm.weight[held, None] * law_friction(problem, pos[held], u_tau[held])
    return out


def pair_forces(problem, r: np.ndarray, moved: np.ndarray | None = None) -> list[dict]:
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
    disc = problem.disc
    d = disc.dim
    r = r.reshape(-1, d)
    fixed = disc.dirichlet.fixed
    n_owned = disc.V.dofmap.index_map.size_local
    pos = np.searchsorted(disc.frames.nodes, disc.gamma3.nodes)
    out = []
    for i, p in enumerate(problem.case.contact.pairs):
        surface = disc.gamma3.nodes[disc.pairs.pair[pos] == i]
        target = surface_nodes(disc, p.target)
        target = target[target < n_owned]
        local = [(r[nodes] * ~fixed[nodes]).sum(axis=0) for nodes in (surface, target)]
        if moved is not None:
            local[0] = local[0] + moved.reshape(-1, d)[surface].sum(axis=0)
        on_surface, on_target = summed(disc.comm, np.array(local))
        out.append({"surface": str(p.surface), "target": str(p.target),
                    "on_surface": [float(v) for v in on_surface],
                    "on_target": [float(v) for v in on_target]})
    return out
