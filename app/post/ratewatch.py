"""The estimated stability indicator of a law without a rate bound, watched during a run.

A law that states neither a relaxation rate nor a Lipschitz constant L_G (app/model/laws.py:
Norton, Chaboche, the power law with n > 1, most laws of users) has no stability indicator
k r_max <= 2 that holds at every stress before the run (app/post/diagnostics.py: Norton's
and Chaboche's at the data's stress scale, which the run's stresses may exceed; others'
estimated at the initial state, where a body at rest gives none).  ``RateWatch`` estimates
it at every accepted state of the explicit scheme (3.2)-(3.3), k_n times the spectral
radius of dG/dsigma at the cell of largest ||sigma||_VM (``diagnostics.state_rate``), warns
once when it exceeds the limit, and records the largest and the last values in
summary.json's "diagnostics" (``estimated_indicator_max``, ``estimated_indicator_last``,
``estimated_indicator_step``).  Where the law raises (or fails numerically) at the state
the watch differences, the estimate of that step is unknown: one warning; the scheme's next
explicit update evaluates G at the same sigma_n and fails the step cleanly (summary.json
status "failed") if the law raises there too, while a run already at T is complete.
"""
from __future__ import annotations

import logging

from vpcontact.observers import Observer
from vpcontact.post.diagnostics import STABILITY_LIMIT, RateEstimateError, state_rate

log = logging.getLogger("vpcontact")


def needs_watch(sim) -> bool:
    """A run whose explicit stability is not known from its law (the watch's runs).

    Args:
        sim: the Simulation, set up (its diagnostics and case).

    Returns:
        True for the explicit scheme with a law that states no rate bound.
    """
    d = sim.diagnostics
    return d is not None and d.indicator_source in ("estimated", "stress_scale", "unknown") \
        and sim.case.time.scheme == "explicit"


class RateWatch(Observer):
    """Estimates k_n r at every accepted step (see the module docstring); collective."""

    def __init__(self):
        self.largest = self.last = None
        self.step_of_largest = None
        self.warned = self.failed = False

    def step(self, sim, record: dict) -> None:
        """Estimate the indicator at the accepted state sigma_n, kappa_n with k_n.

        Args:
            sim: the Simulation.
            record: the step's record (its k and n).
        """
        p = sim.problem
        try:
            rate = state_rate(p, p.elasticity.to_voigt(p.sigma.x.array))
        except RateEstimateError as exc:          # raised on every rank alike
            if not self.failed:
                self.failed = True
                log.warning("estimated stability indicator not computed at step %d (t = %g): "
                            "%s", record["n"], sim.t, exc)
            return
        if rate is None:
            return
        self.last = record["k"] * rate
        if self.largest is None or self.last > self.largest:
            self.largest, self.step_of_largest = self.last, record["n"]
        if self.last > STABILITY_LIMIT and not self.warned:
            self.warned = True
            log.warning("estimated stability indicator k r = %g x %.4g = %.3g at step %d "
                        "(t = %g) exceeds the explicit limit %g (the law states no rate "
                        "bound; dG/dsigma at the largest ||sigma||_VM): the explicit scheme "
                        "may be unstable here; use time.scheme: implicit or a smaller time "
                        "step", record["k"], rate, self.last, record["n"], sim.t,
                        STABILITY_LIMIT)

    def end(self, sim, summary) -> None:
        """Record the estimates in summary.json's "diagnostics".

        Args:
            sim: the Simulation.
            summary: the RunSummary.
        """
        summary.diagnostics.update(estimated_indicator_max=self.largest,
                                   estimated_indicator_last=self.last,
                                   estimated_indicator_step=self.step_of_largest)
