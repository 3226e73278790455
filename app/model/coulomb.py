"""Coulomb friction on Gamma3 against the rigid foundation: the friction term of (3.4) is
theta_i psi(|u_tau|_delta) with psi(rho) = rho and the nodal factor

    theta_i = mu p_n,i (times theta(s_n) of the slip dependence, if any),

p_n,i the contact pressure at node i (normal compliance, memory term and the bound's
reaction: -sigma_nu of the bulk residual, as in contact.csv).  The bound mu p_n depends on
the solution: the step problem is quasi-variational.  ``CoulombPressure.solve`` solves it by
a fixed point on p_n inside each step: start from the previous step's p_n, solve the step
(either step solver: the factor is the nodal field theta they both read), recompute p_n,
repeat until max|p^(i+1) - p^(i)| <= max(TOL max p^(i+1), ROUNDOFF S), at most
``MAX_ITERATIONS`` solves. S is the data's stress scale (``divergence.stress_scale``: the
loads and initial data, E_max times the prescribed displacements over L, the contact laws'
levels, the initial stress), the scale in which the bulk residual, and so p_n, is measured:
p_n is a nodal residual divided by its weight, summed from stress terms of that size, so its
round-off is a few eps S. Without the floor ROUNDOFF S a step in which every node separates
(p_n = 0 up to round-off, ~1e-14 at S = 30) could never converge (the relative test compares
that noise with max p_n ~ 1e-21); the floor is some 5000 eps S, far above that noise and far
below the pressures of nodes in contact (a floor of TOL S stopped the fixed point of a stiff
foundation body, whose E enters S, long before its pressures were resolved).
A converged fixed point says so on a --verbose line (DEBUG: at the default level the progress
bar and the closing lines suffice); one that does not converge fails the step
(StepSolveError: the run's warning of a rejected adaptive step, or its error line).
The static/kinetic law mu(s) = mu_s - (mu_s - mu_k) min(s_n / L, 1) is mu = mu_s times the
slip dependence theta(s_n) = 1 - (1 - mu_k / mu_s) min(s_n / L, 1)
(``contact_laws.StaticKineticSlip``, summed by the Gamma3 slip machinery).  p_n is part of
the state a checkpoint stores: a restarted step starts its fixed point where the
uninterrupted run's does.
"""
from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from vpcontact.post.divergence import stress_scale
from vpcontact.post.quantities import bulk_residual
from vpcontact.solvers.snesvi import StepSolveError

log = logging.getLogger("vpcontact")

# the fixed point's relative tolerance on p_n and its largest number of step solves
TOL = 1e-8
ROUNDOFF = 1e-12   # the floor of the fixed point's test, relative to the data's stresses
MAX_ITERATIONS = 30


def pressure_floor(problem) -> float:
    """The pressure below which p_n is round-off: ROUNDOFF times the data's stress scale S
    (``divergence.stress_scale``, see the module docstring); collective.

    Args:
        problem: the ContactProblem (its case, elasticity, length and gap scales).

    Returns:
        ROUNDOFF S [Pa] (0 for data without any stress: u = 0 and p_n = 0 exactly).
    """
    return ROUNDOFF * stress_scale(problem.case, problem)


class CoulombPressure:
    """The contact pressure p_n at the local Gamma3 nodes (owned and ghost) and the fixed
    point of the Coulomb bound mu p_n.

    Args:
        problem: the ContactProblem (u, the Gamma3 nodes, frames and weights).
        mu: the friction coefficient (mu_s of the static/kinetic law); with laws per pair,
            its value at each local Gamma3 node (0 at the nodes of pairs without Coulomb).
        field: a NodalField of the Gamma3 nodes (scratch: p_n's ghost values).
        hold: the ContactHold of a body held only by contact
            (app/model/semicoercive.py: each step's fixed point starts from the pressure of
            its normal load), or None.
    """

    hold = None

    def __init__(self, problem, mu: float, field, hold=None):
        self.problem, self.mu, self.field, self.hold = problem, mu, field, hold
        self.p = np.zeros(len(problem.gamma3_local_nodes))
        self.owned = np.searchsorted(problem.gamma3_local_nodes, problem.gamma3.nodes)
        self.iterations = 0
        self.floor = pressure_floor(problem)

    def measure(self) -> np.ndarray:
        """p_n = (-sigma_nu)^+ at the current u: minus the normal component of the bulk
        residual divided by the node's weight (0 where u_nu is prescribed); collective.

        Returns:
            p_n at the local Gamma3 nodes (owned and ghost), shape (m,).
        """
        p, gm, fr = self.problem, self.problem.gamma3, self.problem.frames
        pos = np.searchsorted(fr.nodes, gm.nodes)
        p.current_stress()
        r = bulk_residual(p)[gm.nodes]
        pn = -np.einsum("ij,ij->i", r, fr.normal[pos]) / gm.weight
        local = np.zeros(len(self.p))
        local[self.owned] = np.where(fr.bounded[pos], np.maximum(pn, 0.0), 0.0)
        self.field.set(local)
        self.field.function.x.scatter_forward()
        return self.field.function.x.array[self.field.dofs].copy()

    def solve(self, solver, set_factor) -> int:
        """The fixed point on p_n of one step: solve with mu p^(i), p^(i+1) from u; collective.

        Args:
            solver: the step solver (``solve()`` -> iterations).
            set_factor: mu p -> None, sets the friction factor of the forms' nodal field.

        Returns:
            The step solver's iterations summed over the fixed point.

        Raises:
            StepSolveError: no convergence in MAX_ITERATIONS solves (p_n and u are the last
                iterate's; the step is not accepted).
        """
        comm, its, change, scale = self.problem.comm, 0, np.inf, 0.0
        if self.hold is not None:   # a body held only by the contact: p_n of the step's load
            self.p = self._spread(self.hold.pressure_start(self._loads(), self.p[self.owned]))
        for i in range(1, MAX_ITERATIONS + 1):
            set_factor(self.mu * self.p)
            its += solver.solve()
            new = self.measure()
            change = comm.allreduce(float(np.abs(new - self.p).max(initial=0.0)), op=MPI.MAX)
            scale = comm.allreduce(float(new.max(initial=0.0)), op=MPI.MAX)
            self.p = new
            if change <= max(TOL * scale, self.floor):
                self.iterations = i
                log.debug("Coulomb friction: the fixed point on p_n converged in %d "
                          "iteration(s) (max change %.2e, max p_n %.4g)", i, change, scale)
                return its
        raise StepSolveError(
            f"Coulomb friction: the fixed point on the contact pressure p_n did not converge "
            f"in {MAX_ITERATIONS} iterations (max|p^(i+1) - p^(i)| = {change:.3e} > "
            f"max({TOL:g} max p_n, round-off floor) = {max(TOL * scale, self.floor):.3e}; "
            f"mu = {np.max(self.mu):g} may be too large for the fixed point)")

    def _loads(self) -> np.ndarray:
        """The step's owned nodal loads f_n, (owned nodes, d)."""
        p = self.problem
        owned = p.V.dofmap.index_map.size_local
        if p.load_vector is None:
            return np.zeros((owned, p.dim))
        return p.load_vector.at_current_time().array_r.reshape(-1, p.dim)[:owned]

    def _spread(self, owned: np.ndarray) -> np.ndarray:
        """p at the local Gamma3 nodes (owned and ghost) from its owned values."""
        local = np.zeros(len(self.p))
        local[self.owned] = owned
        self.field.set(local)
        self.field.function.x.scatter_forward()
        return self.field.function.x.array[self.field.dofs].copy()

    def state(self) -> dict:
        """Returns: {"p": a copy of p_n (m,)}."""
        return {"p": self.p.copy()}

    def load_state(self, state: dict | None) -> None:
        """Set p_n from ``state()`` or a checkpoint's copy of it (None: start from 0).

        Args:
            state: {"p": array (m,)} or None.
        """
        self.p = np.zeros(len(self.p)) if state is None else np.array(state["p"], dtype=float)
