"""The condensed Gamma3 problem of one step, the same whatever the back end condensed K with.

With the nodal (vertex) Gamma3 rule, condensing (3.4) onto the Gamma3 dofs leaves
    min_y  1/2 (y - y0)^T S (y - y0) + sum_i w_i phi_i(y_i),   y_nu <= g,
with S the Schur complement, y0 the Gamma3 values without contact forces and phi_i the nodal
contact energy (NodalContact: normal compliance (4.1), memory xi_n, friction (4.2) times
theta(s_n)).  ``Gamma3Problem`` solves it by a projected Newton method with an Armijo line
search on this energy (convex under (2.6)), in the coordinates of ``WorkFrames``, started from
the extrapolation of the last two steps' solutions.  Under mpirun it lives on GAMMA3_ROOT
(S, its Newton matrices: dense, O(m^2) memory), which uses the cores of its node's ranks while
they wait asleep (threads.root_call); only y0 and y pass between the ranks.
"""
from __future__ import annotations

import numpy as np

from vpcontact import kernels, threads
from vpcontact.io.errors import StepSolveError
from vpcontact.model.contact_laws import ContactLaw
from vpcontact.solvers import dense
from vpcontact.solvers.nodal import NodalContact

_EPS = np.finfo(float).eps
MAX_ITERATIONS = 200        # of the projected Newton method, per step


def _projected(y, g, lo, hi) -> float:
    """The largest projected gradient component: g where no bound holds y back."""
    binding = ((y <= lo) & (g > 0)) | ((y >= hi) & (g < 0))
    return float(np.abs(np.where(binding, 0.0, g)).max(initial=0.0))


class Gamma3Problem:
    """The Gamma3 problem of every step (collective to build; S is read on GAMMA3_ROOT).

    Args:
        comm: the run's communicator.
        S: the Schur complement in the global coordinates, on GAMMA3_ROOT (None elsewhere).
        frames: the WorkFrames of the problem.
        w: the nodal weights of the Gamma3 rule, in G order.
        law: the contact laws with numbers as parameters (``ContactProblem.contact_law``,
            a parameter that varies in space (c_nu(x)) evaluated at the Gamma3 nodes in G
            order).
        rtol: relative tolerance of the projected gradient.
        coupling: two bodies: the PairCoupling (app/solvers/condensed/pairs.py): the
            nodal energy acts on w = C_G y at the surface nodes (``w`` their weights), y
            the values of G; None: on y itself (one body).
    """

    def __init__(self, comm, S, frames, w, law: ContactLaw, rtol: float = 1e-13,
                 coupling=None, reduced: bool = False):
        self.comm, self.frames, self.w, self.rtol = comm, frames, w, rtol
        self.d = len(frames.normal)
        self.m = len(w) * self.d if coupling is None else coupling.m
        self.reduced = coupling is not None or reduced   # solve() takes r = S y0 for y0
        self._y_prev = []               # (t, y) of the last two steps (_start)
        self._direction = None

        def direction():                # the dense Newton matrices, on the root
            self._direction = dense.NewtonDirection(frames.work_matrix(S), self.d, dense.load()) \
                if coupling is None else coupling.direction(S)
            return self._local_counts()
        self._counts = threads.root_call(comm, direction)
        self.contact = NodalContact(w, frames.normal, law, kernels.load()) if coupling is None \
            else coupling.contact(w, frames.normal, law)

    def set_data(self, xi: np.ndarray | None, theta: np.ndarray | None) -> None:
        """The step's memory term and slip factor at the Gamma3 nodes (G order).

        Args:
            xi: xi_n, or None to keep the last (absent term: stays None).
            theta: theta(s_n), or None to keep the last.
        """
        if xi is not None:
            self.contact.xi = xi
        if theta is not None:
            self.contact.theta = theta

    def solve_on_root(self, y0: np.ndarray | None, t: float) -> tuple[np.ndarray, int]:
        """Solve on GAMMA3_ROOT while the other ranks wait asleep (collective).

        Args:
            y0: the Gamma3 values without contact forces (global coordinates, G order),
                read on the root only.
            t: the step's time t_n (for the start's extrapolation).

        Returns:
            (y, iterations), y in the global coordinates, on every rank.

        Raises:
            StepSolveError: on every rank, if the root's iteration failed.
        """
        def solve():
            y, its = self.solve(y0, t)
            return y, its, self._local_counts()
        y, its, self._counts = threads.root_call(self.comm, solve)
        return y, its

    def solve(self, y0_global: np.ndarray, t: float) -> tuple[np.ndarray, int]:
        """The Gamma3 problem in its coordinates, on this rank.

        Args:
            y0_global: y0 in the global coordinates (``reduced``: r = S y0; its values at
                the prescribed dofs are theirs, S being the identity there).
            t: the step's time t_n.

        Returns:
            (y, iterations), y in the global coordinates.

        Raises:
            StepSolveError: the iteration did not converge.
        """
        fr = self.frames
        y0 = fr.to_work(y0_global)
        lb, ub = fr.lb.ravel().copy(), fr.ub.ravel().copy()
        lb[fr.fixed] = ub[fr.fixed] = y0[fr.fixed]      # prescribed components
        y, its = self._projected_newton(y0, lb, ub, t)
        return fr.from_work(y), its

    def _projected_newton(self, y0, lb, ub, t) -> tuple[np.ndarray, int]:
        """Projected Newton for min 1/2 (y-y0)^T S (y-y0) + sum w phi(y_i), lb <= y <= ub
        (two bodies: y0 is r = S y0, ``reduced``)."""
        S, d = self._direction.product, self.d
        y = np.clip(self._start(y0, t), lb, ub)
        if self.reduced:      # the start: the solver's warm start, never r itself
            y = y if self._y_prev else np.clip(np.zeros_like(y0), lb, ub)
            return self._iterate(self._reduced_energy(y0), y, lb, ub, t,
                                 max(np.abs(y0).max(), np.abs(self.w).max(), 1e-300))
        scale = max(np.abs(S(y0)).max(), np.abs(self.w).max(), 1e-300)

        def energy_grad(yv, hess=True):
            e, g, H = self.contact.evaluate(yv.reshape(-1, d), hess)
            dy = yv - y0
            Sdy = S(dy)
            return 0.5 * dy @ Sdy + e, Sdy + g.ravel(), H
        return self._iterate(energy_grad, y, lb, ub, t, scale)

    def _reduced_energy(self, r):
        """1/2 y^T S y - r^T y + sum w phi, its gradient and nodal Hessians: the energy of
        the reduced right-hand side r, which needs no S^-1 (S only semidefinite where the
        contact holds a body's rigid motion)."""
        S, d = self._direction.product, self.d

        def energy_grad(yv, hess=True):
            e, g, H = self.contact.evaluate(yv.reshape(-1, d), hess)
            Sy = S(yv)
            return 0.5 * yv @ Sy - r @ yv + e, Sy - r + g.ravel(), H
        return energy_grad

    def _iterate(self, energy_grad, y, lb, ub, t, scale) -> tuple[np.ndarray, int]:
        """The projected Newton iteration from y with the energy ``energy_grad``."""
        E, g, Hn = energy_grad(y)
        lo, hi = lb + 1e-14 * scale, ub - 1e-14 * scale
        for it in range(1, MAX_ITERATIONS):
            binding = ((y <= lo) & (g > 0)) | ((y >= hi) & (g < 0))
            pg = np.where(binding, 0.0, g)
            if np.abs(pg).max() <= self.rtol * scale:
                self._remember(y, t)
                return y, it - 1
            p = self._newton_step(Hn, g, pg, binding, scale)
            y, E, g, Hn = self._line_search(energy_grad, y, E, g, pg, p, lb, ub, lo, hi,
                                            scale)
        if np.abs(pg).max() <= 1e-9 * scale:   # converged to round-off, not to rtol
            self._remember(y, t)
            return y, it
        raise StepSolveError("condensed solver: the Gamma3 problem did not converge in "
                             f"{MAX_ITERATIONS} iterations")

    def _newton_step(self, Hn, g, pg, binding, scale) -> np.ndarray:
        """The projected Newton direction: Cholesky (or CG with a kept factor), else LU on
        the free dofs, else -g; steepest descent where it does not descend."""
        p = self._direction(Hn, g, binding, rtol=self._forcing(np.abs(pg).max(), scale))
        if p is None:                 # not positive definite here: LU, else -pg
            H = self._direction.matrix(Hn)
            f = np.flatnonzero(~binding)
            p = np.zeros_like(g)
            try:
                p[f] = np.linalg.solve(H[np.ix_(f, f)], -g[f])
            except np.linalg.LinAlgError:
                p[f] = -g[f]
        if pg @ p >= 0:               # not a descent direction: steepest descent
            p = -pg
        return p

    @staticmethod
    def _line_search(energy_grad, y, E, g, pg, p, lb, ub, lo, hi, scale):
        """The projected Armijo backtracking along p; returns (y, E, g, H) at the step."""
        alpha = 1.0
        for _ in range(60):
            yt = np.minimum(np.maximum(y + alpha * p, lb), ub)
            Et, gt, Ht = energy_grad(yt)
            # Armijo, or a step so small that the energy cannot resolve it any more.
            # (Accepting steps up to the round-off of E instead let the iteration zig-zag:
            # docs/performance.md, section 2.)
            if Et <= E + 1e-4 * g @ (yt - y) or np.abs(yt - y).max() <= 1e-16 * scale:
                break
            # Where the predicted decrease is below the round-off of E, the energy cannot
            # judge the step: the projected gradient does (else steps stall in 3D;
            # docs/performance.md, section 9).
            if abs(g @ (yt - y)) <= 1e3 * _EPS * max(abs(E), abs(Et)) and \
                    _projected(yt, gt, lo, hi) < 0.5 * np.abs(pg).max():
                break
            alpha *= 0.5
        return yt, Et, gt, Ht

    def _forcing(self, pg_max: float, scale: float) -> float:
        """The relative residual an inexact Newton direction needs: |pg| / scale (quadratic
        convergence), but no smaller than what brings the projected gradient below the
        tolerance in one more iteration (|r|_2 <= 0.1 rtol scale / sqrt(m)), at most 1e-2."""
        final = 0.1 * self.rtol * scale / (pg_max * np.sqrt(max(self.m, 1)))
        return min(1e-2, max(pg_max / scale, final))

    def _start(self, y0: np.ndarray, t: float) -> np.ndarray:
        """The iteration's start: the linear extrapolation in time of the last two steps'
        solutions (the step problems change smoothly, so Newton needs fewer iterations:
        docs/performance.md, section 2), the last solution after one step or a restart, y0
        (the free solution) at the first step."""
        if len(self._y_prev) == 2:
            (t0, y_0), (t1, y_1) = self._y_prev
            if t0 is not None and t > t1 > t0:
                return y_1 + (t - t1) / (t1 - t0) * (y_1 - y_0)
        return self._y_prev[-1][1].copy() if self._y_prev else y0.copy()

    def _remember(self, y: np.ndarray, t: float) -> None:
        """Keep this step's solution (and its time) for the next start."""
        self._y_prev = [*self._y_prev[-1:], (t, y)]

    def warm_start(self, y_global: np.ndarray) -> None:
        """Start the next problem from y (after a restart from a checkpoint).

        Args:
            y_global: the Gamma3 values of the current u, global coordinates (every rank).
        """
        y = self.frames.to_work(y_global)
        self._y_prev = [(None, y)] if self.comm.rank == threads.GAMMA3_ROOT else []

    def stats(self) -> dict:
        """The linear algebra so far, the same on every rank.

        Returns:
            {"factorisations": dense Cholesky factorisations of the Newton matrix,
            "cg_iterations": CG iterations with a kept factor, "threads": BLAS threads of its
            large operations}.
        """
        return self._local_counts() or self._counts

    def _local_counts(self) -> dict | None:
        """The counts of ``stats`` on GAMMA3_ROOT, as they are; None elsewhere (which keep
        the root's of the last problem)."""
        if self._direction is None:
            return None
        return {"factorisations": self._direction.factorisations,
                "cg_iterations": self._direction.cg_iterations, "threads": threads.cores()}
