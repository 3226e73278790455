"""A posteriori estimate of the paper's error measure in every run (docs/model.md, "Error
estimates"): max_n (||sigma_n - sigma(t_n)||_Q + ||u_n - u(t_n)||_V + ||kappa_n -
kappa(t_n)||_Y), split into a time part and a space part.

- Space, per step: (eta_Q^2 + eta_C^2)^(1/2) + eta_V + eta_Y, the recovery indicators of
  app/post/recovery.py summed over the cells (each a global L2 norm, as the error
  measure's three norms; eta_C, the contact boundary's, is part of the stress error).
- Time: the error of the history update, embedded and propagated.  The explicit sums
  (3.2)-(3.3) take G at the left end point; the trapezoidal (second order) update differs
  from them by the local error l_n = (k_n / 2) (G_n - G_{n-1}), G_j = G(sigma_j, kappa_j)
  (Gk likewise for kappa), known after the step; the implicit scheme's backward-Euler
  update differs from the trapezoidal one by -l_n.  The error fields (delta H, delta kappa)
  per cell are carried through the scheme by the law itself, with the stress error taken
  as the error of H (exact under held displacements):
      explicit: delta_n = delta_{n-1} + k_n (G(s_{n-1}) - G(s_{n-1} - delta_{n-1})) - l_n,
      implicit: delta_n = delta_{n-1} + k_n (G(s_n) - G(s_n - delta_{n-1})) + l_n,
  s_j = (sigma_j, kappa_j); the time estimate of step n is ||delta H_n||_Q + ||delta
  kappa_n||_Y.  So a relaxing history damps its early errors as the scheme does (the sum of
  the ||l_n|| would keep them).  It costs two more evaluations of the law's explicit update
  per step, on copies of the state.  The memory and slip sums of Gamma3 add
  ``est_time_gamma3`` (app/post/gamma3error.py), their error's effect on u and sigma.
  The error fields are in the checkpoint (``TimeError.state``), so a restarted run goes on
  with them and reports the uninterrupted run's estimate.

Each step record gets est_time, est_space, est_total (their sum), est_max (the running max
of est_total, the measure's max_n), est_space's four parts, est_time's Gamma3 part and
est_time_local, the error made in step n alone (||l_n|| plus the rise of the Gamma3 part:
what ``run --tol`` grades the time steps by); summary.json gets ``error_estimate``.
"""
from __future__ import annotations

import logging

import numpy as np

from vpcontact.model.history import UPDATE_ERRORS, first_failure
from vpcontact.observers import Observer
from vpcontact.post.gamma3error import Gamma3TimeError
from vpcontact.post.recovery import space_indicators

log = logging.getLogger("vpcontact")

PARTS = ("est_space_sigma_Q", "est_space_u_V", "est_space_kappa_Y", "est_space_contact")
COLUMNS = ("est_time", "est_space", "est_total", "est_max") + PARTS + ("est_time_gamma3",
                                                                       "est_time_local")
NORMS = ("norm_sigma_Q", "norm_u_V", "norm_kappa_Y")


class HistoryRates:
    """G(sigma, kappa) and Gk(sigma, kappa) per cell by the law's explicit update on copies
    (the State is untouched).

    Args:
        problem: the ContactProblem (its law, sigma and State).
    """

    def __init__(self, problem):
        self.problem = problem
        self.update = problem.law.explicit()

    def __call__(self, k: float, sigma: np.ndarray | None = None,
                 kappa: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(G, Gk) at (sigma, kappa), by default the current state.

        Args:
            k: the step of the update (the scheme's there, so that a safeguard of the law
                acts as in the run).
            sigma: sigma per local cell, flat, or None.
            kappa: kappa (cells, m), or None.

        Returns:
            (G, Gk) per local cell, (cells, d*d) and (cells, m).
        """
        p, st = self.problem, self.problem.state
        sigma = p.sigma.x.array if sigma is None else sigma
        kappa0 = st.kappa_cells if kappa is None else kappa
        H, kap = st.H.x.array.copy(), kappa0.copy()
        self.update(sigma.copy(), H, kap, k)
        return ((H - st.H.x.array).reshape(len(kap), -1) / k, (kap - kappa0) / k)


class TimeError:
    """The propagated error (delta H, delta kappa) of the history update (module
    docstring); collective.

    Args:
        problem: the ContactProblem with a viscoplastic law.
        k: the first step (for G at the initial or restored state).
    """

    def __init__(self, problem, k: float):
        self.problem, self.rates = problem, HistoryRates(problem)
        self.implicit = bool(problem.implicit)
        self.previous = self._state_rates(k)
        self.delta = None
        self.local = 0.0          # ||l_n||_Q + ||l_kappa,n||_Y of the last step

    def _state_rates(self, k: float):
        """(sigma, kappa, G, Gk) of the current state; None if the law fails on a rank."""
        p = self.problem
        out = _collective(p.disc.comm, self.rates, k)
        if out is None:
            return None
        return (p.sigma.x.array.copy(), p.state.kappa_cells.copy()) + out

    def step(self, k: float) -> float:
        """delta_n from delta_{n-1} and the step just solved.

        Args:
            k: the step k_n.

        Returns:
            ||delta H_n||_Q + ||delta kappa_n||_Y (NaN once the law's update failed).
        """
        now, before = self._state_rates(k), self.previous
        self.previous = now
        if now is None or before is None:
            self.delta, self.local = None, float("nan")
            return float("nan")
        local = [0.5 * k * (a - b) for a, b in zip(now[2:], before[2:])]
        self.local = self._norm(local)
        if self.delta is None:                    # the first step: no error before it
            self.delta = [-x if not self.implicit else x for x in local]
            return self._norm(self.delta)
        at = now if self.implicit else before
        sig = at[0] - self.delta[0].reshape(-1)
        moved = _collective(self.problem.disc.comm, self.rates, k, sig, at[1] - self.delta[1])
        if moved is None:
            self.delta = None
            return float("nan")
        sign = 1.0 if self.implicit else -1.0
        self.delta = [d + k * (g - gm) + sign * x
                      for d, g, gm, x in zip(self.delta, at[2:], moved, local)]
        return self._norm(self.delta)

    def state(self) -> dict | None:
        """delta_n for a checkpoint.

        Returns:
            {"dH": (cells, d*d), "dkappa": (cells, m)} per local cell (owned rows first), or
            None (no step yet, or the law's update failed).
        """
        return None if self.delta is None else {"dH": self.delta[0], "dkappa": self.delta[1]}

    def load_state(self, state: dict | None) -> None:
        """delta_n from a checkpoint.

        Args:
            state: ``state()`` of the checkpointed run (None: no error before).
        """
        self.delta = None if state is None else [np.array(state["dH"], dtype=float),
                                                 np.array(state["dkappa"], dtype=float)]

    def _norm(self, fields: list) -> float:
        """||H-like field||_Q + ||kappa-like field||_Y over the owned cells of all ranks."""
        p = self.problem
        disc = p.disc
        n = disc.num_owned_cells
        vol = disc.cell_volumes()[:n]
        return float(sum(np.sqrt(disc.reduce(float(vol @ np.einsum("ij,ij->i", d[:n], d[:n])),
                                          "SUM")) for d in fields))


def _collective(comm, call, *args):
    """call(*args), or None on every rank if it failed on some rank (collective)."""
    out, error = None, None
    try:
        out = call(*args)
    except UPDATE_ERRORS as exc:
        error = exc
    return None if first_failure(comm, error) is not None else out


class ErrorEstimate(Observer):
    """The estimate of every step (module docstring); collective."""

    def __init__(self):
        self.space = self.time = self.gamma3 = None
        self.best = None
        self.gamma3_before = 0.0      # est_time_gamma3 of the step before

    def start(self, sim) -> None:
        """The indicators, and G at the initial (or restored) state, with the restored
        error fields and Gamma3 sums (the step of the last restored record is the one G was
        taken with).

        Args:
            sim: the Simulation, set up.
        """
        p, restart = sim.problem, getattr(sim, "restart", None)
        self.space = space_indicators(p)
        if p.law is not None and p.state.H is not None:
            times = sim.case.time.times
            k = sim.steps[-1]["k"] if sim.steps else float(times[1] - times[0])
            self.time = TimeError(p, float(k))
            if restart is not None:
                self.time.load_state(restart.time_error)
        g3 = p.state.gamma3
        if g3 is not None and (g3.memory is not None or g3.slip is not None) \
                and p.disc.pairs is None:
            self.gamma3 = Gamma3TimeError(p)
            if restart is not None and restart.gamma3_error is not None:
                self.gamma3.load_state(restart.gamma3_error)
        for rec in sim.steps:                 # restored steps: their running max goes on
            if "est_total" in rec:
                self._keep(rec)
                self.gamma3_before = rec.get("est_time_gamma3") or 0.0

    def check(self, sim, record: dict) -> None:
        """Add the estimates of step n to its record.

        Args:
            sim: the Simulation with step n solved.
            record: the step's record.
        """
        if self.space is None:     # a loop driven by ``step`` without ``start``: the time
            return                 # part would miss G at the initial state: no estimate
        parts = self.space.norms(self.space.update())
        est = dict(zip(PARTS, map(float, parts)),
                   est_space=float(np.hypot(parts[0], parts[3]) + parts[1] + parts[2]))
        est["est_time"] = self.time.step(record["k"]) if self.time is not None else 0.0
        est["est_time_gamma3"] = self.gamma3.step(record["k"], record["t"]) \
            if self.gamma3 is not None else 0.0
        est["est_time"] += est["est_time_gamma3"]
        est["est_time_local"] = (self.time.local if self.time is not None else 0.0) + max(
            est["est_time_gamma3"] - self.gamma3_before, 0.0)
        self.gamma3_before = est["est_time_gamma3"]
        est["est_total"] = est["est_time"] + est["est_space"]
        # an estimate that is not finite (rates that overflow) is absent, never a reason
        # for the blow-up monitor to stop the run
        record.update({k: v if np.isfinite(v) else None for k, v in est.items()})
        self._keep(record)
        record["est_max"] = None if self.best is None else self.best["estimate"]

    def _keep(self, record: dict) -> None:
        """The running max of est_total with its step and split."""
        if record["est_total"] is None:
            return
        if self.best is None or record["est_total"] > self.best["estimate"]:
            self.best = {"estimate": record["est_total"], "time": record["est_time"],
                         "space": record["est_space"], "n_max": record["n"],
                         "t_max": record["t"],
                         "space_parts": {k: record.get(k) for k in PARTS}}

    def end(self, sim, summary) -> None:
        """summary.json's ``error_estimate`` and the log line.

        Args:
            sim: the Simulation at its end.
            summary: the RunSummary.
        """
        if self.best is None:
            return
        b = dict(self.best)
        b["scale"] = scale_of(sim.steps)
        b["relative"] = b["estimate"] / b["scale"] if b["scale"] > 0 else None
        summary.error_estimate = b
        relative = f": {100 * b['relative']:.3g} % of the solution's scale {b['scale']:.4g}" \
            if b["relative"] is not None else ""
        log.info("error estimate: %.4g (time %.4g, space %.4g) at step %d (t = %g)%s",
                 b["estimate"], b["time"], b["space"], b["n_max"], b["t_max"], relative)


def scale_of(steps: list[dict]) -> float:
    """The solution's scale, against which an estimate is relative (``run --tol`` too).

    Args:
        steps: the run's step records.

    Returns:
        max_n (||sigma_n||_Q + ||u_n||_V + ||kappa_n||_Y) over them (0 without steps).
    """
    return max((sum(r.get(k) or 0.0 for k in NORMS) for r in steps), default=0.0)
