"""Time step control: the case's fixed grid, or adaptive steps k_n = t_n - t_{n-1}.

Adaptive: start with the grid's first step; before a step, halve k while the explicit
scheme's stability indicator k r_max exceeds ``max_indicator``; when the step solve fails,
the step is rejected (the history terms restored by the caller) and k halved; after a step
whose converged solution changed by at most ``max_change`` (relative, max norm:
max|u_n - u_{n-1}| <= max_change max|u_n|) k grows by ``grow`` (up to ``k_max``).  The rule
reads the solution only, never the step solver's iterations: the fast solver and SNES VI,
which solve the same discrete problem to round-off, take the same time grid.  Every decision
(accepted or rejected step) is kept in ``decisions`` for summary.json ("step_history").
"""
from __future__ import annotations

from vpcontact.case.timegrid import default_k_min


class StepTooSmall(RuntimeError):
    """The adaptive step would have to fall below time.adaptive.k_min."""


class FixedSteps:
    """The case's time grid t_0 < ... < t_N.

    Args:
        times: t_0, ..., t_N.
    """

    adaptive = False

    def __init__(self, times):
        self.times = list(times)
        self.n = 0
        self.decisions: list[dict] = []

    @property
    def total(self) -> int | None:
        """The number of steps N."""
        return len(self.times) - 1

    def finished(self, t: float) -> bool:
        """Whether the last step of the grid was accepted.

        Args:
            t: the current time t_n (unused: the grid counts its steps).

        Returns:
            True once n = N.
        """
        return self.n >= len(self.times) - 1

    def next_k(self, t: float) -> float | None:
        """The grid's next step k_{n+1} = t_{n+1} - t_n.

        Args:
            t: the current time t_n (unused).

        Returns:
            k_{n+1}, or None when finished.
        """
        if self.finished(t):
            return None
        return self.times[self.n + 1] - self.times[self.n]

    def next_t(self, t: float, k: float) -> float:
        """The grid's next time, exactly t_{n+1} (not t + k, which may round).

        Args:
            t: the current time t_n (unused).
            k: the step from ``next_k`` (unused).

        Returns:
            t_{n+1}.
        """
        return self.times[self.n + 1]

    def accept(self, k: float, change: float) -> None:
        """The step was accepted: move to the next grid point.

        Args:
            k: the accepted step (unused).
            change: the solution's relative change over the step (unused).
        """
        self.n += 1

    def reject(self, k: float, reason: str) -> bool:
        """A fixed grid never retries a step.

        Args:
            k: the failed step (unused).
            reason: why it failed (unused).

        Returns:
            False.
        """
        return False

    def state(self) -> dict:
        """Returns: {"adaptive": False, "n": steps taken, "k": None, "decisions": [...]}."""
        return {"adaptive": False, "n": self.n, "k": None, "decisions": list(self.decisions)}

    def load_state(self, state: dict) -> None:
        """Continue from ``state()`` (of a checkpoint).

        Args:
            state: {"n": steps taken, "decisions": [...]} (other keys are ignored).
        """
        self.n = state["n"]
        self.decisions = list(state["decisions"])


class AdaptiveSteps:
    """Adaptive steps on [0, T] (see the module docstring).

    Args:
        T: the final time.
        k0: the first step tried.
        rate: the relaxation rate r_max of the explicit scheme (None: no stability limit).
        scheme: "explicit" or "implicit" (only the explicit scheme has the limit).
        k_min: the smallest step (default: app/case/timegrid.py default_k_min).
        k_max: the largest step (default T).
        grow: the factor k grows by after a step that changed the solution little.
        max_change: the largest relative change max|u_n - u_{n-1}| / max|u_n| of a step
            after which k grows.
        max_indicator: the largest stability indicator k r_max allowed.
    """

    adaptive = True

    def __init__(self, T: float, k0: float, rate: float | None, scheme: str, k_min=None,
                 k_max=None, grow=1.5, max_change=0.2, max_indicator=1.0):
        self.T, self.k = T, k0
        self.k_min = k_min if k_min is not None else default_k_min(k0)
        self.k_max = k_max if k_max is not None else T
        self.grow, self.max_change = grow, max_change
        self.limit = max_indicator / rate if (rate and scheme == "explicit") else None
        self.decisions: list[dict] = []
        self.total = None

    def finished(self, t: float) -> bool:
        """Whether the run reached T.

        Args:
            t: the current time t_n.

        Returns:
            True once t >= T (up to a relative 1e-12).
        """
        return t >= self.T * (1 - 1e-12)

    def next_k(self, t: float) -> float | None:
        """The next step from t, within the stability limit.

        Halves k while the explicit scheme's indicator k r_max exceeds ``max_indicator``
        (each halving is recorded in ``decisions``); the last step is stretched or shortened
        to land exactly on T.

        Args:
            t: the current time t_n.

        Returns:
            k_{n+1}, or None when finished.

        Raises:
            StepTooSmall: the stability limit needs a step below k_min.
        """
        if self.finished(t):
            return None
        k = min(self.k, self.k_max)
        if self.limit is not None and self.limit < self.k_min:
            raise StepTooSmall(f"the stability indicator needs k <= {self.limit:g}, below "
                               f"time.adaptive.k_min = {self.k_min:g}")
        while self.limit is not None and k > self.limit:
            self.decisions.append({"t": t, "k": k, "accepted": False,
                                   "reason": "stability indicator"})
            k *= 0.5
        if k < self.k_min:
            raise StepTooSmall(f"the step k = {k:g} needed by the stability indicator is below "
                               f"time.adaptive.k_min = {self.k_min:g}")
        self.k = k
        rest = self.T - t
        return rest if k >= rest * (1 - 1e-9) else k   # land exactly on T

    def next_t(self, t: float, k: float) -> float:
        """The time after a step of k from t.

        Args:
            t: the current time t_n.
            k: the step from ``next_k``.

        Returns:
            t + k, exactly T when it is within 1e-12 T of T.
        """
        return self.T if abs(t + k - self.T) <= 1e-12 * self.T else t + k

    def accept(self, k: float, change: float) -> None:
        """The step was accepted: record it and grow k if the solution changed little.

        Args:
            k: the accepted step.
            change: the converged solution's relative change over the step,
                max|u_n - u_{n-1}| / max|u_n| (0 for u_n = u_{n-1} = 0); at most
                ``max_change`` makes k grow by ``grow`` (up to k_max and the stability
                limit).  A property of the solution of the discrete problem, the same
                for every step solver.
        """
        self.decisions.append({"k": k, "accepted": True, "change": change})
        if change <= self.max_change:   # grow, not past the stability limit (no reject loop)
            self.k = min(self.k * self.grow, self.k_max,
                         self.limit if self.limit is not None else float("inf"))

    def reject(self, k: float, reason: str) -> bool:
        """The step k failed: record it and halve k.

        Args:
            k: the failed step.
            reason: why it failed (kept in ``decisions``).

        Returns:
            Whether the halved step is at least k_min (may be tried).
        """
        self.decisions.append({"k": k, "accepted": False, "reason": reason})
        self.k = 0.5 * k
        return self.k >= self.k_min

    def state(self) -> dict:
        """Returns: {"adaptive": True, "n": None, "k": the next step, "decisions": [...]}."""
        return {"adaptive": True, "n": None, "k": self.k, "decisions": list(self.decisions)}

    def load_state(self, state: dict) -> None:
        """Continue from ``state()`` (of a checkpoint).

        Args:
            state: {"k": the next step, "decisions": [...]} (other keys are ignored).
        """
        self.k = state["k"]
        self.decisions = list(state["decisions"])


def make_stepper(case, rate: float | None) -> FixedSteps | AdaptiveSteps:
    """The step control of a case: its fixed grid, or adaptive steps (time.adaptive).

    Args:
        case: the validated Case.
        rate: the relaxation rate r_max (diagnostics), for the explicit stability limit.

    Returns:
        A FixedSteps or an AdaptiveSteps.
    """
    a = case.time.adaptive
    if a is None:
        return FixedSteps(case.time.times)
    k0 = case.time.times[1] - case.time.times[0]
    return AdaptiveSteps(case.time.T, k0, rate, case.time.scheme, a.get("k_min"),
                         a.get("k_max"), a["grow"], a["max_change"], a["max_indicator"])
