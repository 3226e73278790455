"""Time step control: the case's fixed grid, or adaptive steps.

Adaptive: start with the grid's first step; before a step, halve k while the explicit
scheme's stability indicator k r_max exceeds ``max_indicator``; when SNES fails, the step is
rejected (all history restored by the caller) and k halved; after a step with at most
``fast_newton`` Newton iterations k grows by ``grow`` (up to ``k_max``).  Every attempt is
recorded for summary.json.
"""
from __future__ import annotations


class StepTooSmall(RuntimeError):
    pass


class FixedSteps:
    """The case's time grid t_0 < ... < t_N."""

    adaptive = False

    def __init__(self, times):
        self.times = list(times)
        self.n = 0
        self.history: list[dict] = []

    @property
    def total(self) -> int | None:
        return len(self.times) - 1

    def finished(self, t: float) -> bool:
        return self.n >= len(self.times) - 1

    def next_k(self, t: float) -> float | None:
        if self.finished(t):
            return None
        return self.times[self.n + 1] - self.times[self.n]

    def next_t(self, t: float, k: float) -> float:
        return self.times[self.n + 1]

    def accept(self, k: float, its: int) -> None:
        self.n += 1

    def reject(self, k: float, reason: str) -> bool:
        return False


class AdaptiveSteps:
    adaptive = True

    def __init__(self, T: float, k0: float, rate: float | None, scheme: str, k_min=None,
                 k_max=None, grow=1.5, fast_newton=4, max_indicator=1.0):
        self.T, self.k = T, k0
        self.k_min = k_min if k_min is not None else k0 / 1024
        self.k_max = k_max if k_max is not None else T
        self.grow, self.fast = grow, fast_newton
        self.limit = max_indicator / rate if (rate and scheme == "explicit") else None
        self.history: list[dict] = []
        self.total = None

    def finished(self, t: float) -> bool:
        return t >= self.T * (1 - 1e-12)

    def next_k(self, t: float) -> float | None:
        if self.finished(t):
            return None
        k = min(self.k, self.k_max)
        if self.limit is not None and self.limit < self.k_min:
            raise StepTooSmall(f"the stability indicator needs k <= {self.limit:g}, below "
                               f"time.adaptive.k_min = {self.k_min:g}")
        while self.limit is not None and k > self.limit:
            self.history.append({"t": t, "k": k, "accepted": False,
                                 "reason": "stability indicator"})
            k *= 0.5
        if k < self.k_min:
            raise StepTooSmall(f"the step k = {k:g} needed by the stability indicator is below "
                               f"time.adaptive.k_min = {self.k_min:g}")
        self.k = k
        rest = self.T - t
        return rest if k >= rest * (1 - 1e-9) else k   # land exactly on T

    def next_t(self, t: float, k: float) -> float:
        return self.T if abs(t + k - self.T) <= 1e-12 * self.T else t + k

    def accept(self, k: float, its: int) -> None:
        self.history.append({"k": k, "accepted": True, "newton": its})
        if its <= self.fast:   # grow, but not past the stability limit (no reject loop)
            self.k = min(self.k * self.grow, self.k_max,
                         self.limit if self.limit is not None else float("inf"))

    def reject(self, k: float, reason: str) -> bool:
        self.history.append({"k": k, "accepted": False, "reason": reason})
        self.k = 0.5 * k
        return self.k >= self.k_min


def make_stepper(case, rate: float | None):
    a = case.time.adaptive
    if a is None:
        return FixedSteps(case.time.times)
    k0 = case.time.times[1] - case.time.times[0]
    return AdaptiveSteps(case.time.T, k0, rate, case.time.scheme, a.get("k_min"),
                         a.get("k_max"), a["grow"], a["fast_newton"], a["max_indicator"])
