"""History terms of scheme (3.2)-(3.3), explicit (left end point) as in the paper.

H_n     = sum_{j=1..n} k_j G(sigma_{j-1}, kappa_{j-1}) + sigma0 - E eps(u0)   (DG0 tensor)
kappa_n = sum_{j=1..n} k_j Gk(sigma_{j-1}, kappa_{j-1}) + kappa0     (DG0, m components)
so H_n = H_{n-1} + k_n G(sigma_{n-1}, kappa_{n-1}) with H_0 = sigma0 - E eps(u0), and
likewise for kappa; G and Gk are the law's (app/model/viscoplastic.py).  Only a case with a
viscoplastic law has this history; an elastic case
creates no history object at all.  The state is committed only through ``advance`` (after
the previous step converged), so a failed step leaves it untouched.
"""
from __future__ import annotations

from dolfinx import fem

from vpcontact.model.implicit import LocalFailure
from vpcontact.model.viscoplastic import ViscoplasticLaw


def kappa_function(Y, m: int) -> fem.Function:
    """The internal variables kappa in R^m per cell: a DG0 scalar Function for m = 1 (the
    paper's Perzyna law), else DG0 with m components.

    Args:
        Y: the DG0 scalar space Y^h.
        m: the law's number of internal variables.

    Returns:
        The Function "kappa" (zero).
    """
    space = Y if m == 1 else fem.VectorFunctionSpace(Y.mesh, ("DG", 0), dim=m)
    return fem.Function(space, name="kappa")


class _CommittedHistory:
    """The committed state of a viscoplastic history: H (the problem's DG0 tensor function)
    and kappa (DG0, m components); what adaptive rollback and checkpoints save and restore."""

    H: fem.Function
    kappa: fem.Function

    def state(self) -> dict:
        """The committed history (H_n, kappa_n of (3.2)-(3.3)) as copies of the local arrays.

        Returns:
            {"H": H values, "kappa": kappa values} (owned and ghost cells).
        """
        return {"H": self.H.x.array.copy(), "kappa": self.kappa.x.array.copy()}

    def load_state(self, state: dict) -> None:
        """Set the committed history from ``state()`` of the same run (e.g. to undo a
        rejected step).

        Args:
            state: {"H": ..., "kappa": ...} as returned by ``state()``.
        """
        self.H.x.array[:], self.kappa.x.array[:] = state["H"], state["kappa"]


class ViscoplasticHistory(_CommittedHistory):
    """Holds H_n (the problem's DG0 function ``H``) and kappa_n, and advances them by the
    explicit sums (3.2)-(3.3) of the law.  H_0 = sigma0 - E eps(u0) and kappa_0 are set by
    ``problem.set_initial_values``.

    Args:
        problem: the ContactProblem (its elasticity law, H, and the DG0 space Y).
        law: the viscoplastic law (app/model/viscoplastic.py).
    """

    def __init__(self, problem, law: ViscoplasticLaw):
        self.law = law
        self.H = problem.H
        self.kappa = kappa_function(problem.Y, law.m)
        self.update = law.explicit()         # compiled for Perzyna where it can be

    def before_solve(self, problem, k: float) -> None:
        """H_n, kappa_n from sigma_{n-1}, kappa_{n-1} (explicit: known before the solve).

        Args:
            problem: the ContactProblem (its sigma holds sigma_{n-1}).
            k: the step k_n.
        """
        self.advance(problem.sigma, k)

    def after_solve(self, problem) -> tuple[float, float] | None:
        """sigma_n = E eps(u_n) + H_n (3.2).

        Args:
            problem: the ContactProblem (its u holds u_n).

        Returns:
            problem.update_sigma's norms (||u||_V, ||sigma||_Q), or None.
        """
        return problem.update_sigma()

    def advance(self, sigma_prev, k: float) -> None:
        """H_n = H_{n-1} + k_n G(sigma_{n-1}, kappa_{n-1}), same for kappa (3.2)-(3.3).

        ``self.kappa`` holds kappa_{n-1} on entry and kappa_n on exit.  All local cells (owned
        and ghost) are updated with the same data, so ghosts stay consistent without
        communication.

        Args:
            sigma_prev: the DG0 function holding sigma_{n-1}.
            k: the step k_n.

        Raises:
            RuntimeError: the law's update failed (the state is unchanged).
        """
        self.update(sigma_prev.x.array, self.H.x.array,
                    self.kappa.x.array.reshape(-1, self.law.m), k)


class ImplicitViscoplasticHistory(_CommittedHistory):
    """The right-end-point variant (app/model/implicit.py): H and kappa hold the committed state
    H_{n-1} = sigma_{n-1} - E eps(u_{n-1}) and kappa_{n-1}; during the solve of step n every
    residual evaluation updates sigma (and the tangent) from the current u (the trial state);
    after the solve the state at u_n is committed.

    Args:
        problem: the ContactProblem (becomes its ``constitutive`` update).
        law: the viscoplastic law (app/model/viscoplastic.py).
    """

    def __init__(self, problem, law: ViscoplasticLaw):
        self.elasticity = problem.elasticity
        self.law = law
        self.local = law.implicit()
        self.H = problem.H
        self.kappa = kappa_function(problem.Y, law.m)
        self._kappa_trial = None
        self.k = None
        problem.constitutive = self

    def before_solve(self, problem, k: float) -> None:
        """Keep k_n for the local updates of step n's residual evaluations.

        Args:
            problem: the ContactProblem.
            k: the step k_n.
        """
        self.k = k

    def update(self, problem) -> bool:
        """The trial state at the current u: sigma, kappa and the algorithmic tangent by the
        backward-Euler update of the law from the committed H_{n-1}, kappa_{n-1}.

        Args:
            problem: the ContactProblem (its u, sigma and C_alg).

        Returns:
            False if the local update failed in some cell (nothing is committed).
        """
        law = self.elasticity
        eps_t = problem.strain_voigt()
        s_tr = law.apply(eps_t) + law.to_voigt(self.H.x.array)
        try:
            sigma, kappa, C = self.local.solve(s_tr, self.kappa.x.array.reshape(-1, self.law.m),
                                               self.k)
        except LocalFailure:
            return False
        problem.sigma.x.array[:] = law.from_voigt(sigma).reshape(-1)
        problem.C_alg.x.array[:] = C.reshape(-1)
        self._kappa_trial = kappa
        self._eps_t = eps_t
        self._sigma_t = sigma
        return True

    def after_solve(self, problem) -> None:
        """Commit the state at the converged u_n: sigma_n, kappa_n, H_n = sigma_n - E eps(u_n).

        Args:
            problem: the ContactProblem (its u holds u_n).

        Raises:
            LocalFailure: the local update failed at u_n.
        """
        if not self.update(problem):   # at the converged u_n
            raise LocalFailure("implicit Perzyna update failed at the converged step")
        law = self.elasticity
        self.kappa.x.array[:] = self._kappa_trial.reshape(-1)
        self.H.x.array[:] = law.from_voigt(self._sigma_t - law.apply(self._eps_t)).reshape(-1)
        problem.update_vm()
