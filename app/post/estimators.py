"""A posteriori estimate of the paper's error measure in every run (docs/model.md, "Error
estimates"): max_n (||sigma_n - sigma(t_n)||_Q + ||u_n - u(t_n)||_V + ||kappa_n -
kappa(t_n)||_Y), split into a time part and a space part.

- Space, per step: eta_Q + eta_V + eta_Y, the recovery indicators of app/model/recovery.py
  summed over the cells (each a global L2 norm, as the error measure's three norms).
- Time: the local error of the history update, embedded.  The explicit sums (3.2)-(3.3)
  take G at the left end point; the trapezoidal (second order) update differs from them by
  e_n = (k_n / 2) (||G(sigma_n, kappa_n) - G(sigma_{n-1}, kappa_{n-1})||_Q + ||Gk(sigma_n,
  kappa_n) - Gk(sigma_{n-1}, kappa_{n-1})||_Y), known after the step; the implicit scheme's
  backward-Euler update differs from the trapezoidal one by the same amount.  The
  estimate of step n is the sum E_n = e_1 + ... + e_n (the stability factor of the scheme
  taken as 1: the errors of a relaxing history are not amplified).  G is the law's own
  update evaluated once more per step (its explicit update with the step k_n on a copy of
  the state).  The memory and slip sums of Gamma3 add no term yet.

Each step record gets est_time (E_n), est_space, est_total (their sum), est_max (the
running max of est_total, the measure's max_n) and est_space's three parts; summary.json
gets ``error_estimate``.
"""
from __future__ import annotations

import logging

import numpy as np

from vpcontact.model.history import UPDATE_ERRORS, first_failure
from vpcontact.model.recovery import SpaceIndicators
from vpcontact.observers import Observer

log = logging.getLogger("vpcontact")

PARTS = ("est_space_sigma_Q", "est_space_u_V", "est_space_kappa_Y")
COLUMNS = ("est_time", "est_space", "est_total", "est_max") + PARTS


class HistoryRates:
    """k G(sigma, kappa) and k Gk(sigma, kappa) of the current state by the law's explicit
    update on a copy (the State is untouched).

    Args:
        problem: the ContactProblem (its law, sigma and State).
    """

    def __init__(self, problem):
        self.problem = problem
        self.update = problem.law.explicit()

    def __call__(self, k: float) -> tuple[np.ndarray, np.ndarray]:
        """Returns: (G, Gk) per local cell, (cells, d*d) and (cells, m), from the update
        with the step k (the one the scheme takes there, so no safeguard of the law acts
        otherwise than in the run)."""
        p, st = self.problem, self.problem.state
        H, kappa = st.H.x.array.copy(), st.kappa_cells.copy()
        self.update(p.sigma.x.array.copy(), H, kappa, k)
        return ((H - st.H.x.array).reshape(len(kappa), -1) / k, (kappa - st.kappa_cells) / k)


class ErrorEstimate(Observer):
    """The estimate of every step (module docstring); collective."""

    def __init__(self):
        self.space = self.rates = self.previous = None
        self.time_sum, self.best = 0.0, None

    def start(self, sim) -> None:
        """The indicators, and G at the initial (or restored) state.

        Args:
            sim: the Simulation, set up.
        """
        p = sim.problem
        self.space = SpaceIndicators(p)
        if p.law is not None and p.state.H is not None:
            self.rates = HistoryRates(p)
            times = sim.case.time.times
            self.previous = self._rates(float(times[1] - times[0]))
        for rec in sim.steps:                 # restored steps: their estimates go on
            if "est_total" in rec:
                self.time_sum = rec["est_time"]
                self._keep(rec)

    def _rates(self, k: float):
        """(G, Gk) at the current state, None if the law's update fails on some rank
        (collective: then None on every rank)."""
        now, error = None, None
        try:
            now = self.rates(k)
        except UPDATE_ERRORS as exc:
            error = exc
        return None if first_failure(self.rates.problem.comm, error) is not None else now

    def check(self, sim, record: dict) -> None:
        """Add the estimates of step n to its record.

        Args:
            sim: the Simulation with step n solved.
            record: the step's record.
        """
        p = sim.problem
        parts = self.space.norms(self.space.update())
        record["est_space"] = float(parts.sum())
        record.update(zip(PARTS, map(float, parts)))
        self.time_sum += self._local_time_error(p, record["k"])
        record["est_time"] = self.time_sum
        record["est_total"] = record["est_time"] + record["est_space"]
        self._keep(record)
        record["est_max"] = self.best["estimate"]

    def _local_time_error(self, p, k: float) -> float:
        """e_n = (k_n / 2) (||G_n - G_{n-1}||_Q + ||Gk_n - Gk_{n-1}||_Y); G_n kept."""
        if self.rates is None:
            return 0.0
        now = self._rates(k)
        if now is None or self.previous is None:
            self.previous = now
            return float("nan")
        n, vol = p.num_owned_cells, p.cell_volumes()[:p.num_owned_cells]
        e = 0.0
        for a, b in zip(now, self.previous):
            d = (a - b)[:n]
            e += np.sqrt(p.reduce(float(vol @ np.einsum("ij,ij->i", d, d)), "SUM"))
        self.previous = now
        return 0.5 * k * e

    def _keep(self, record: dict) -> None:
        """The running max of est_total with its step and split."""
        if self.best is None or not record["est_total"] <= self.best["estimate"]:
            self.best = {"estimate": record["est_total"], "time": record["est_time"],
                         "space": record["est_space"], "n_max": record["n"],
                         "t_max": record["t"],
                         "space_parts": {k: record[k] for k in PARTS}}

    def end(self, sim, summary) -> None:
        """summary.json's ``error_estimate`` and the log line.

        Args:
            sim: the Simulation at its end.
            summary: the RunSummary.
        """
        if self.best is None:
            return
        summary.error_estimate = dict(self.best)
        b = self.best
        log.info("error estimate: %.4g (time %.4g, space %.4g) at step %d (t = %g)",
                 b["estimate"], b["time"], b["space"], b["n_max"], b["t_max"])
