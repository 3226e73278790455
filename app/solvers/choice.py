"""Which step solver and which linear solver a case runs with.  Light: no dolfinx or PETSc
at import time, so case validation can ask ``condensed_eligible``.

``condensed_eligible`` is the rule of the condensed solver (app/solvers/condensed/): the bulk
problem of a step must be linear (explicit history scheme), every Gamma3 term a sum of
nodal energies (vertex quadrature), and a rigid motion held only by contact (a pair's or the
foundation's: the bulk stiffness it factorises, without the contact, is singular in it)
only with its compiled back end (serially) or MUMPS (under mpirun).
``choose_method`` resolves ``solver.method`` (the Case holds ``condensed`` where a file gives
``fast``, its former name: app/case/model.py), ``choose_linear`` SNES VI's ``solver.linear``.
"""
from __future__ import annotations

# auto: the condensed solver while its Gamma3 problem (dense m x m algebra) is small, where it
# is much faster than SNES VI; m = 6000 keeps the dense matrices near 1.5 GB
# (docs/performance.md, section 9).
AUTO_FAST_MAX_GAMMA3_DOFS = 6000
# bytes per entry of m x m that the condensed solver's Gamma3 problem holds at once on the
# rank that solves it (S, its Cholesky factor, the Newton matrix's work, the kept factor in
# single precision): an upper estimate, which also counted the (2.6) diagnostic's dense
# Gamma3 mass matrix and its symmetric part (16 bytes, now sparse) and keeps that margin.
# A solver whose dense matrices would not fit in the memory available is not chosen by
# auto, and refused when asked for (``dense_fits``).
DENSE_BYTES_PER_ENTRY = 48
# auto: SNES VI's Newton systems by CG + GAMG (app/solvers/amg.py) in 3D above this many dofs
# (LU's fill grows like dofs^(4/3) in 3D; docs/performance.md, section 9).
# Below, a direct solve (the Gamma3 Schur complement, LU where it does not apply) costs
# seconds and takes indefinite Jacobians (beyond (2.6)) as they come.
AUTO_AMG_MIN_DOFS = 20_000


def condensed_eligible(case, disc=None) -> tuple[bool, str]:
    """Can the condensed step solver solve this case?

    Args:
        case: the case.
        disc: its Discretisation (app/model/discretisation.py), or None: the case's rules
            only.  With it, also the rule of the mesh: a body whose rigid motion only contact holds
            (``held_by_contact``) is refused with fast_* PETSc options.

    Returns:
        (eligible, why not: "" when eligible).
    """
    if case.time.scheme != "explicit" and any(m.viscoplastic for m in case.all_materials):
        return False, "the implicit history variant makes the bulk problem nonlinear"
    if case.numerics.quadrature != "vertex" and case.contact.active:
        return False, "the condensed solver needs the nodal (vertex) Gamma3 quadrature"
    if disc is not None and \
            any(str(k).startswith("fast_") for k in case.petsc) and held_by_contact(disc):
        return False, ("a body's rigid motion is held only by a contact pair or the "
                       "foundation: the condensed solver takes it with its compiled back end "
                       "(serially) or MUMPS (under mpirun) only, not with fast_* PETSc "
                       "options")
    return True, ""


def held_by_contact(disc) -> bool:
    """Whether the Dirichlet data leave a rigid motion of a part of the body free (held
    only by contact, a pair's or the foundation's: app/model/dirichlet.py
    ``check_rigid_motions``); collective.

    Args:
        disc: the Discretisation.

    Returns:
        True if some part has a free rigid motion.
    """
    from vpcontact.model.dirichlet import body_parts, free_motions
    free = free_motions(disc.V, disc.dirichlet.fixed, body_parts(disc.V), disc.caps)
    return any(f.shape[1] > 0 for f in free)


def choose_method(case, n_gamma3_dofs: int, disc=None) -> str:
    """The step solver a case runs with: ``solver.method``, and for ``auto`` the condensed
    solver where it applies (``condensed_eligible``) and its Gamma3 problem has at most
    AUTO_FAST_MAX_GAMMA3_DOFS dofs (two bodies: those of G, ``condensed_dofs``) and its
    dense matrices fit in the memory available (``dense_fits``), else SNES VI.
    (``condensed`` where the case's rules refuse it is refused when the case is validated;
    where the mesh's rule or the memory does, here.)

    Args:
        case: the validated Case.
        n_gamma3_dofs: the global number of Gamma3 dofs (nodes times dimension).
        disc: the case's Discretisation (collective then), or None: the case's rules only.

    Returns:
        "condensed" or "snes_vi".

    Raises:
        CaseError: ``condensed`` given for a case whose mesh rule refuses it, or whose
            dense Gamma3 matrices do not fit in the memory available.
    """
    method = case.numerics.method
    if method == "snes_vi":
        return method
    ok, why = condensed_eligible(case, disc)
    if ok and disc is not None:
        if case.contact.pairs:
            n_gamma3_dofs = condensed_dofs(disc)
        ok, why = dense_fits(n_gamma3_dofs, disc.comm)
    if method == "condensed":
        if not ok:
            from vpcontact.io.errors import CaseError
            raise CaseError(f"{case.source}: solver.method: 'condensed' is not possible here: "
                            f"{why} (allowed: snes_vi, auto)")
        return method
    return "condensed" if ok and n_gamma3_dofs <= AUTO_FAST_MAX_GAMMA3_DOFS else "snes_vi"


def dense_fits(m: int, comm, memory: float | None = None) -> tuple[bool, str]:
    """Whether the condensed solver's dense m x m Gamma3 matrices fit in the memory the
    machine still has (MemAvailable on the rank that solves the Gamma3 problem, rank 0);
    collective.

    Args:
        m: the dofs of the Gamma3 problem.
        comm: the run's communicator (mpi4py).
        memory: the available memory in bytes (None: read on rank 0).

    Returns:
        (True, "") or (False, the reason, with the sizes).
    """
    from vpcontact.meshes.refine import available_memory
    if memory is None:
        memory = comm.bcast(available_memory() if comm.rank == 0 else None, root=0)
    need = DENSE_BYTES_PER_ENTRY * float(m) ** 2
    if memory is None or need <= memory:
        return True, ""
    return False, (f"its Gamma3 problem ({m} dofs) needs about {need / 1e9:.1f} GB of dense "
                   f"matrices on one rank, more than the {memory / 1e9:.1f} GB available")


def condensed_dofs(disc) -> int:
    """The dofs of the condensed solver's G (collective): the Gamma3 dofs, and with two
    bodies also those of the target nodes coupled to the surface nodes.

    Args:
        disc: the Discretisation.

    Returns:
        The global number of G's nodes times the dimension.
    """
    import numpy as np
    if disc.pairs is None:
        return gamma3_dofs(disc)
    imap = disc.V.dofmap.index_map
    mine = np.concatenate([imap.local_to_global(disc.gamma3.nodes.astype(np.int32)),
                           disc.pairs.cols]).astype(np.int64)
    nodes = np.unique(np.concatenate(disc.comm.allgather(np.unique(mine))))
    return len(nodes) * disc.dim


def choose_linear(case, n_dofs: int) -> str:
    """The linear solver of SNES VI's Newton systems: ``solver.linear``, and for ``auto``
    algebraic multigrid in 3D with more than AUTO_AMG_MIN_DOFS dofs, else the Gamma3 Schur
    complement on one factorisation of K (app/solvers/inactiveschur.py; SNES VI takes LU
    where it does not apply, and logs why).

    Args:
        case: the validated Case.
        n_dofs: the global number of dofs of u.

    Returns:
        "direct" (LU of every Newton system), "schur" or "amg".
    """
    linear = case.numerics.linear
    if linear != "auto":
        return linear
    return "amg" if case.dim == 3 and n_dofs > AUTO_AMG_MIN_DOFS else "schur"


def gamma3_dofs(disc) -> int:
    """The global number of Gamma3 dofs of a Discretisation (collective).

    Args:
        disc: the Discretisation.

    Returns:
        Gamma3 nodes (over all ranks) times the dimension; 0 without Gamma3.
    """
    return disc.num_gamma3_nodes * disc.dim
