"""The Coulomb fixed point of a step: a step solver around SNES VI or the condensed solver.

With Coulomb friction the bound mu p_n of (3.4) depends on the solution (the step problem
is quasi-variational; p_n is held and measured by ``CoulombPressure``,
app/model/coulomb.py).  ``CoulombFixedPoint.solve`` solves it by a fixed point on p_n inside
each step: start from the previous step's p_n, solve the step (either step solver: the
factor is the nodal field theta they both read), recompute p_n, repeat until
max|p^(i+1) - p^(i)| <= max(TOL max p^(i+1), ROUNDOFF S), at most ``MAX_ITERATIONS`` solves.
S is the data's stress scale (``stress_scale`` of app/post/divergence.py: the loads and
initial data, E_max times the prescribed displacements over L, the contact laws' levels, the
initial stress; the time loop passes it in), the scale in which the bulk residual, and so
p_n, is measured: p_n is a nodal residual divided by its weight, summed from stress terms of
that size, so its round-off is a few eps S. Without the floor ROUNDOFF S a step in which
every node separates (p_n = 0 up to round-off, ~1e-14 at S = 30) could never converge (the
relative test compares that noise with max p_n ~ 1e-21); the floor is some 5000 eps S, far
above that noise and far below the pressures of nodes in contact (a floor of TOL S stopped
the fixed point of a stiff foundation body, whose E enters S, long before its pressures were
resolved).
A converged fixed point says so on a --verbose line (DEBUG: at the default level the progress
bar and the closing lines suffice); one that does not converge fails the step
(StepSolveError: the run's warning of a rejected adaptive step, or its error line).
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from vpcontact.io.errors import StepSolveError

log = logging.getLogger("vpcontact")

# the fixed point's relative tolerance on p_n and its largest number of step solves
TOL = 1e-8
ROUNDOFF = 1e-12   # the floor of the fixed point's test, relative to the data's stresses
MAX_ITERATIONS = 30


class CoulombFixedPoint:
    """A StepSolver that solves a step with Coulomb friction by the fixed point on p_n (the
    module docstring) with the step solver it wraps; every other attribute (name, fallback,
    describe, warm_start, destroy, ...) is the wrapped solver's.

    Args:
        solver: the step solver of (3.4) (SNES VI or the condensed solver).
        history: the Gamma3History: its CoulombPressure ``coulomb`` (p_n, mu, ``measure``,
            ``start_step``) and ``set_coulomb_bound`` (the forms' nodal factor theta).
        stress_scale: the data's stress scale S (app/post/divergence.py); the test's floor
            is ROUNDOFF S [Pa] (0 for data without any stress: u = 0 and p_n = 0 exactly).
    """

    def __init__(self, solver, history, stress_scale: float):
        self.solver, self.history = solver, history
        self.floor = ROUNDOFF * stress_scale
        self.iterations = 0          # the step solves of the last converged fixed point

    def __getattr__(self, name: str):
        """The wrapped solver's attribute (only called for names this object lacks).

        Args:
            name: the attribute's name.

        Returns:
            ``getattr(solver, name)``.
        """
        if name in ("solver", "history"):        # not yet set (a copy being built)
            raise AttributeError(name)
        return getattr(self.solver, name)

    def solve(self) -> int:
        """The fixed point on p_n of one step: solve with mu p^(i), p^(i+1) from u; collective.

        Returns:
            The step solver's iterations summed over the fixed point.

        Raises:
            StepSolveError: no convergence in MAX_ITERATIONS solves (p_n and u are the last
                iterate's; the step is not accepted).
        """
        pressure = self.history.coulomb
        comm, its, change, scale = pressure.problem.disc.comm, 0, np.inf, 0.0
        pressure.start_step()
        for i in range(1, MAX_ITERATIONS + 1):
            self.history.set_coulomb_bound(pressure.mu * pressure.p)
            its += self.solver.solve()
            new = pressure.measure()
            change = comm.allreduce(float(np.abs(new - pressure.p).max(initial=0.0)),
                                    op=MPI.MAX)
            scale = comm.allreduce(float(new.max(initial=0.0)), op=MPI.MAX)
            pressure.p = new
            if change <= max(TOL * scale, self.floor):
                self.iterations = i
                log.debug("Coulomb friction: the fixed point on p_n converged in %d "
                          "iteration(s) (max change %.2e, max p_n %.4g)", i, change, scale)
                return its
        raise StepSolveError(
            f"Coulomb friction: the fixed point on the contact pressure p_n did not converge "
            f"in {MAX_ITERATIONS} iterations (max|p^(i+1) - p^(i)| = {change:.3e} > "
            f"max({TOL:g} max p_n, round-off floor) = {max(TOL * scale, self.floor):.3e}; "
            f"mu = {np.max(pressure.mu):g} may be too large for the fixed point)")
