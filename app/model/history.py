"""History terms of scheme (3.2)-(3.3), explicit (left end point) as in the paper.

H_n     = sum_{j=1..n} k_j G(sigma_{j-1}, kappa_{j-1}) + sigma0 - E eps(u0)   (DG0 tensor)
kappa_n = sum_{j=1..n} k_j Gk(sigma_{j-1}, kappa_{j-1}) + kappa0     (DG0, m components)
so H_n = H_{n-1} + k_n G(sigma_{n-1}, kappa_{n-1}) with H_0 = sigma0 - E eps(u0), and
likewise for kappa; G and Gk are the law's (app/model/viscoplastic.py).  Only a case with a
viscoplastic law has this history; an elastic case creates no history object at all.  The
fields live in the State (app/model/state.py); the
history objects here are the stages of a step that update them, with the law's updates
(app/model/viscoplastic.py) and no state of their own.

Under MPI a law may fail in the cells of one rank only: the explicit update then fails on
every rank alike (``collective_update``: one allreduce of a flag per step, the state
unchanged on every rank), as the implicit update's trial does (problem.before_residual), so
that no rank goes on into the collective solve.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from vpcontact.model.implicit import LocalFailure
from vpcontact.model.laws import ViscoplasticLaw

# the numerical errors of a law's update that fail a step (as in Simulation.advance)
UPDATE_ERRORS = (ArithmeticError, RuntimeError, np.linalg.LinAlgError)


class HistoryUpdateFailure(RuntimeError):
    """The explicit history update failed on some rank (raised on every rank)."""


def collective_update(comm, update, sigma, H, kappa, k: float) -> None:
    """The explicit update (3.2)-(3.3) on every rank, failing on all ranks if it fails on one.

    Each rank runs ``update`` on its cells; one allreduce tells every rank the lowest rank
    whose update failed; only then its message is broadcast and the ranks whose update
    succeeded put their H_{n-1}, kappa_{n-1} back (the failing rank wrote nothing), so the
    state is unchanged on every rank.

    Args:
        comm: the MPI communicator of the mesh (more than one rank).
        update: the law's explicit update (``law.explicit()``).
        sigma: sigma_{n-1} per cell, flat.
        H: H_{n-1} per cell, flat; becomes H_n.
        kappa: kappa_{n-1}, (ncells, m); becomes kappa_n.
        k: the step k_n.

    Raises:
        HistoryUpdateFailure: the update failed on some rank; the message is that rank's,
            with the rank named.
    """
    saved, error = (H.copy(), kappa.copy()), None
    try:
        update(sigma, H, kappa, k)
    except UPDATE_ERRORS as exc:
        error = exc
    reason = first_failure(comm, error)
    if reason is None:
        return
    if error is None:
        H[:], kappa[:] = saved
    raise HistoryUpdateFailure(reason) from error


def first_failure(comm, error: BaseException | None) -> str | None:
    """Whether a local computation failed on some rank, known on every rank: one allreduce
    of the lowest failing rank, then that rank's message broadcast; collective.

    Args:
        comm: the MPI communicator.
        error: this rank's exception, or None (it succeeded).

    Returns:
        None if no rank failed, else the lowest failing rank's message, with the rank
        named under MPI ("... (on rank r of size)").
    """
    first = comm.allreduce(comm.rank if error is not None else comm.size, op=MPI.MIN)
    if first == comm.size:
        return None
    if comm.size == 1:
        return str(error)
    reason = comm.bcast(str(error) if comm.rank == first else None, root=first)
    return f"{reason} (on rank {first} of {comm.size})"


class ViscoplasticHistory:
    """The explicit stage of a step: H_n, kappa_n from sigma_{n-1}, kappa_{n-1} by the law's
    sums (3.2)-(3.3) before the solve, sigma_n = E eps(u_n) + H_n after it.  H_0 =
    sigma0 - E eps(u0) and kappa_0 are set by ``problem.set_initial_values``.

    Args:
        problem: the ContactProblem (its State holds H and kappa).
        law: the viscoplastic law (app/model/viscoplastic.py).
    """

    def __init__(self, problem, law: ViscoplasticLaw):
        self.law = law
        self.state = problem.state
        self.comm = problem.disc.comm
        self.update = law.explicit()         # compiled for Perzyna where it can be

    @property
    def kappa(self):
        """The State's kappa (read-only access for callers of the history)."""
        return self.state.kappa

    def before_solve(self, problem, k: float) -> None:
        """H_n, kappa_n from sigma_{n-1}, kappa_{n-1} (explicit: known before the solve).

        Args:
            problem: the ContactProblem (its sigma holds sigma_{n-1}).
            k: the step k_n.
        """
        self.advance(problem.sigma, k)

    def after_solve(self, problem, k: float | None = None) -> tuple[float, float] | None:
        """sigma_n = E eps(u_n) + H_n (3.2).

        Args:
            problem: the ContactProblem (its u holds u_n).
            k: the step k_n (not needed by the explicit scheme).

        Returns:
            problem.update_sigma's norms (||u||_V, ||sigma||_Q), or None.
        """
        return problem.update_sigma()

    def advance(self, sigma_prev, k: float) -> None:
        """H_n = H_{n-1} + k_n G(sigma_{n-1}, kappa_{n-1}), same for kappa (3.2)-(3.3).

        The State's kappa holds kappa_{n-1} on entry and kappa_n on exit.  All local cells
        (owned and ghost) are updated with the same data, so ghosts stay consistent without
        communication; under MPI a failure on one rank fails the step on all ranks
        (``collective_update``).

        Args:
            sigma_prev: the DG0 function holding sigma_{n-1}.
            k: the step k_n.

        Raises:
            RuntimeError: the law's update failed (on some rank; the state is unchanged on
                every rank).
        """
        args = (sigma_prev.x.array, self.state.H.x.array, self.state.kappa_cells, k)
        if self.comm.size == 1:
            self.update(*args)
        else:
            collective_update(self.comm, self.update, *args)


class ImplicitViscoplasticHistory:
    """The right-end-point variant (app/model/implicit.py): the State's H and kappa hold the
    committed H_{n-1} = sigma_{n-1} - E eps(u_{n-1}) and kappa_{n-1} during the solve of
    step n; every residual evaluation computes the trial sigma (and the tangent) from the
    current u (``trial``, the step problem's residual hook); after the solve the state at
    u_n is written to H and kappa.

    Args:
        problem: the ContactProblem (its elasticity and State).
        law: the viscoplastic law (app/model/viscoplastic.py).
    """

    def __init__(self, problem, law: ViscoplasticLaw):
        self.elasticity = problem.elasticity
        self.law = law
        self.local = law.implicit()
        self.state = problem.state
        self._trial = None

    @property
    def kappa(self):
        """The State's kappa (read-only access for callers of the history)."""
        return self.state.kappa

    def before_solve(self, problem, k: float) -> None:
        """Nothing: the update runs at every residual (``trial``) with the step's k_n.

        Args:
            problem: the ContactProblem.
            k: the step k_n.
        """

    def trial(self, problem, k: float) -> bool:
        """The trial state at the current u: sigma, kappa and the algorithmic tangent by the
        backward-Euler update of the law from the committed H_{n-1}, kappa_{n-1}.

        Args:
            problem: the ContactProblem (its u, sigma and C_alg).
            k: the step k_n.

        Returns:
            False if the local update failed in some cell (nothing is committed).
        """
        law = self.elasticity
        eps_t = problem.strain_voigt()
        s_tr = law.apply(eps_t) + law.to_voigt(self.state.H.x.array)
        try:
            sigma, kappa, C = self.local.solve(s_tr, self.state.kappa_cells, k,
                                               eps_t if self.law.uses_eps else None)
        except LocalFailure:
            return False
        problem.sigma.x.array[:] = law.from_voigt(sigma).reshape(-1)
        problem.C_alg.x.array[:] = C.reshape(-1)
        self._trial = (eps_t, sigma, kappa)
        return True

    def after_solve(self, problem, k: float) -> None:
        """The state at the converged u_n: sigma_n, kappa_n, H_n = sigma_n - E eps(u_n).

        Args:
            problem: the ContactProblem (its u holds u_n).
            k: the step k_n.

        Raises:
            LocalFailure: the local update failed at u_n (on some rank: on every rank, and
                nothing is committed on any).
        """
        ok = self.trial(problem, k)      # at the converged u_n
        comm = problem.disc.comm
        if comm.size > 1:
            ok = comm.allreduce(ok, op=MPI.LAND)
        if not ok:
            raise LocalFailure("implicit Perzyna update failed at the converged step")
        law = self.elasticity
        eps_t, sigma_t, kappa_t = self._trial
        self.state.kappa.x.array[:] = kappa_t.reshape(-1)
        self.state.H.x.array[:] = law.from_voigt(sigma_t - law.apply(eps_t)).reshape(-1)
        problem.update_vm()
