"""Which step solver and which linear solver a case runs with.  Light: no dolfinx or PETSc
at import time, so case validation can ask ``condensed_eligible``.

``condensed_eligible`` is the rule of the condensed solver (app/solvers/condensed/): the bulk
problem of a step must be linear (explicit history scheme) and every Gamma3 term a sum of
nodal energies (vertex quadrature).  ``choose_method`` resolves ``solver.method`` (the Case
holds ``condensed`` where a file gives ``fast``, its former name: app/case/model.py),
``choose_linear`` SNES VI's ``solver.linear``.
"""
from __future__ import annotations

# auto: the condensed solver while its Gamma3 problem (dense m x m algebra) is small.
# box3d n = 32 (m = 3267), 8 steps: condensed 25.9 s whole process, 2.4 GB; SNES VI (fresh LU
# every Newton iteration) 622 s (measured); m = 6000 keeps the dense matrices near 1.5 GB.
AUTO_FAST_MAX_GAMMA3_DOFS = 6000
# auto: SNES VI's Newton systems by CG + GAMG (app/solvers/amg.py) in 3D above this many dofs
# (LU's fill grows like dofs^(4/3) in 3D).  box3d, 8 steps, whole process: n = 16 (14,739
# dofs) LU 15.3 s, CG + GAMG 7.2 s; n = 24 (46,875) 130 s against 40 s (docs/performance.md).
# Below, LU costs seconds and takes indefinite Jacobians (beyond (2.6)) as they come.
AUTO_AMG_MIN_DOFS = 20_000


def condensed_eligible(case) -> tuple[bool, str]:
    """Can the condensed step solver solve this case?

    Args:
        case: the case.

    Returns:
        (eligible, why not: "" when eligible).
    """
    if case.time.scheme != "explicit" and any(m.viscoplastic for m in case.all_materials):
        return False, "the implicit history variant makes the bulk problem nonlinear"
    if case.numerics.quadrature != "vertex" and case.contact.active:
        return False, "the condensed solver needs the nodal (vertex) Gamma3 quadrature"
    if case.contact.pairs:
        return False, "contact.pairs (two bodies) are solved by SNES VI only, so far"
    return True, ""


def choose_method(case, n_gamma3_dofs: int) -> str:
    """The step solver a case runs with: ``solver.method``, and for ``auto`` the condensed
    solver where it applies (``condensed_eligible``) and its Gamma3 problem has at most
    AUTO_FAST_MAX_GAMMA3_DOFS dofs, else SNES VI.  (``condensed`` where it does not apply
    is refused when the case is validated.)

    Args:
        case: the validated Case.
        n_gamma3_dofs: the global number of Gamma3 dofs (nodes times dimension).

    Returns:
        "condensed" or "snes_vi".
    """
    method = case.numerics.method
    if method != "auto":
        return method
    ok, _ = condensed_eligible(case)
    return "condensed" if ok and n_gamma3_dofs <= AUTO_FAST_MAX_GAMMA3_DOFS else "snes_vi"


def choose_linear(case, n_dofs: int) -> str:
    """The linear solver of SNES VI's Newton systems: ``solver.linear``, and for ``auto``
    algebraic multigrid in 3D with more than AUTO_AMG_MIN_DOFS dofs, else LU.

    Args:
        case: the validated Case.
        n_dofs: the global number of dofs of u.

    Returns:
        "direct" or "amg".
    """
    linear = case.numerics.linear
    if linear != "auto":
        return linear
    return "amg" if case.dim == 3 and n_dofs > AUTO_AMG_MIN_DOFS else "direct"


def gamma3_dofs(problem) -> int:
    """The global number of Gamma3 dofs of ``problem`` (collective).

    Args:
        problem: the ContactProblem.

    Returns:
        Gamma3 nodes (over all ranks) times the dimension; 0 without Gamma3.
    """
    nodes = problem.comm.allreduce(len(problem.gamma3.nodes) if problem.gamma3 else 0)
    return nodes * problem.dim
