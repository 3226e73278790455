"""Step solvers of the discrete inequality (3.4), and the one place that chooses between them.

Two solvers implement :class:`StepSolver`: ``SNESVISolver`` (app/solvers/snesvi.py, PETSc
SNES VI on the whole of U^h, any case) and ``FastStepSolver`` (app/solvers/fast.py, one
factorisation per run and a small problem on the Gamma3 dofs per step; explicit history
scheme and the nodal Gamma3 rule only).  ``select_solver`` builds the one a case asks for
(``solver.method``); ``choose_method`` is its rule for ``auto``.  The solver modules are
imported only when a solver is built, so that importing a submodule (the compiled kernels,
the Schur complement helpers) stays cheap.
"""
from __future__ import annotations

from typing import Protocol

# auto: the fast solver while the condensed Gamma3 problem (dense m x m algebra) is small.
# box3d n = 32 (m = 3267), 8 steps: fast 25.9 s whole process, 2.4 GB; SNES VI (fresh LU every
# Newton iteration) 622 s (measured); m = 6000 keeps the dense matrices near 1.5 GB.
AUTO_FAST_MAX_GAMMA3_DOFS = 6000
# auto: SNES VI's Newton systems by CG + GAMG (app/solvers/amg.py) in 3D above this many dofs
# (LU's fill grows like dofs^(4/3) in 3D).  box3d, 8 steps, whole process: n = 16 (14,739
# dofs) LU 15.3 s, CG + GAMG 7.2 s; n = 24 (46,875) 130 s against 40 s (docs/performance.md).
# Below, LU costs seconds and takes indefinite Jacobians (beyond (2.6)) as they come.
AUTO_AMG_MIN_DOFS = 20_000


class StepSolver(Protocol):
    """What the time loop needs of a step solver: solve (3.4) for u_n from u_{n-1}.

    Attributes:
        name: "snes_vi" or "fast" (summary.json: solver.used).
        fallback: None if the step was solved by the solver's basic method, else what
            solved it ("backtracking", "delta continuation", "snes_vi").
        continuation_stages: the delta continuation's stages of the last step (0: none).
        sticky_robust: later steps start with the fallback (SNES VI: backtracking).
        factorisations: matrix factorisations per run (None: refactorised per iteration).
    """

    name: str
    fallback: str | None
    continuation_stages: int
    sticky_robust: bool
    factorisations: int | None

    def solve(self) -> int:
        """Solve step (3.4) from the current u (u_{n-1}); on return u holds u_n.

        Returns:
            The (Newton) iterations of the step.

        Raises:
            StepSolveError: the step could not be solved; u holds u_{n-1}.
        """

    def describe(self) -> str:
        """The solver as the run's log line 'step solver: ...' names it."""

    def warm_start(self) -> None:
        """Prepare the next solve from the current u (after a restart from a checkpoint)."""

    def destroy(self) -> None:
        """Free the PETSc objects."""


def choose_method(case, n_gamma3_dofs: int) -> str:
    """The step solver a case runs with: ``solver.method``, and for ``auto`` the fast solver
    where it applies (app/io/case.fast_eligible) and the condensed Gamma3 problem has at
    most AUTO_FAST_MAX_GAMMA3_DOFS dofs, else SNES VI.  (``fast`` where it does not apply
    is refused when the case is validated.)

    Args:
        case: the validated Case.
        n_gamma3_dofs: the global number of Gamma3 dofs (nodes times dimension).

    Returns:
        "fast" or "snes_vi".
    """
    from vpcontact.io.case import fast_eligible

    method = case.numerics.method
    if method != "auto":
        return method
    ok, _ = fast_eligible(case)
    return "fast" if ok and n_gamma3_dofs <= AUTO_FAST_MAX_GAMMA3_DOFS else "snes_vi"


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


def snes_vi_options(case, linear: str) -> dict:
    """SNES VI's PETSc options: the case's, and for ``amg`` the iterative defaults
    (app/solvers/amg.AMG_PETSC) in place of the direct solver's defaults.

    Args:
        case: the validated Case (its petsc options).
        linear: "direct" or "amg".

    Returns:
        Option name (without '-') -> value.
    """
    if linear != "amg":
        return dict(case.petsc)
    from vpcontact.io.schema import DEFAULT_PETSC
    from vpcontact.solvers.amg import AMG_PETSC, DIRECT_KEYS

    given = {k: v for k, v in case.petsc.items()
             if not (k in DIRECT_KEYS and DEFAULT_PETSC.get(k) == v)}
    return {**AMG_PETSC, **given}


def gamma3_dofs(problem) -> int:
    """The global number of Gamma3 dofs of ``problem`` (collective).

    Args:
        problem: the ContactProblem.

    Returns:
        Gamma3 nodes (over all ranks) times the dimension; 0 without Gamma3.
    """
    nodes = problem.comm.allreduce(len(problem.gamma3.nodes) if problem.gamma3 else 0)
    return nodes * problem.dim


def select_solver(case, problem) -> StepSolver:
    """Build the step solver of (3.4) that ``choose_method`` picks (collective).

    Args:
        case: the validated Case (solver.method, PETSc options).
        problem: the ContactProblem to solve.

    Returns:
        A FastStepSolver or an SNESVISolver.
    """
    # the default snes_atol is raised to the residual's round-off floor; a given one is kept
    default_atol = case.petsc.get("snes_atol") == case.petsc_defaults.get("snes_atol")
    if choose_method(case, gamma3_dofs(problem)) == "fast":
        from vpcontact.solvers.fast import FastStepSolver
        return FastStepSolver(problem, case.petsc, roundoff_floor=default_atol)
    from vpcontact.solvers.snesvi import SNESVISolver
    linear = choose_linear(case, problem.V.dofmap.index_map.size_global * problem.dim)
    return SNESVISolver(problem, snes_vi_options(case, linear), linear=linear,
                        roundoff_floor=default_atol)
