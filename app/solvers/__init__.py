"""Step solvers of the discrete inequality (3.4), and the one place that builds them.

Two solvers implement :class:`StepSolver`: ``SNESVISolver`` (app/solvers/snesvi.py, PETSc
SNES VI on the whole of U^h, any case) and ``CondensedStepSolver`` (app/solvers/condensed/,
one factorisation per run and a small problem on the Gamma3 dofs per step; explicit history
scheme and the nodal Gamma3 rule only).  ``select_solver`` builds the one a case asks for
(``solver.method``) by the rules of app/solvers/choice.py (``choose_method``,
``choose_linear``).  The solver modules are imported only when a solver is built, so that
importing a submodule (the choice, the compiled kernels, the Schur complement helpers) stays
cheap.
"""
from __future__ import annotations

from typing import Protocol

from vpcontact.solvers.choice import (
    AUTO_AMG_MIN_DOFS,
    AUTO_FAST_MAX_GAMMA3_DOFS,
    choose_linear,
    choose_method,
    condensed_eligible,
    gamma3_dofs,
)

__all__ = ["AUTO_AMG_MIN_DOFS", "AUTO_FAST_MAX_GAMMA3_DOFS", "StepSolver", "choose_linear",
           "choose_method", "condensed_eligible", "gamma3_dofs", "select_solver"]


class StepSolver(Protocol):
    """What the time loop needs of a step solver: solve (3.4) for u_n from u_{n-1}.

    Attributes:
        name: "snes_vi" or "condensed" (summary.json: solver.used).
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


def select_solver(case, problem) -> StepSolver:
    """Build the step solver of (3.4) that ``choose_method`` picks (collective).

    Args:
        case: the validated Case (solver.method, PETSc options).
        problem: the ContactProblem to solve.

    Returns:
        A CondensedStepSolver or an SNESVISolver.
    """
    # the default snes_atol is raised to the residual's round-off floor; a given one is kept
    default_atol = case.petsc.get("snes_atol") == case.petsc_defaults.get("snes_atol")
    disc = problem.disc
    if choose_method(case, gamma3_dofs(disc), disc) == "condensed":
        from vpcontact.solvers.condensed import CondensedStepSolver
        return CondensedStepSolver(problem, case.petsc, roundoff_floor=default_atol)
    from vpcontact.solvers.options import snes_vi_options
    from vpcontact.solvers.snesvi import SNESVISolver
    linear = choose_linear(case, disc.num_dofs)
    return SNESVISolver(problem, snes_vi_options(case, linear), linear=linear,
                        roundoff_floor=default_atol)
