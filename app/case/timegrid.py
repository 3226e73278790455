"""The ``time`` section's rules: the time points t_0..t_N of T with N or k (uniform), T with
N and a geometric grading, or the explicit times; the adaptive steps' bounds."""
from __future__ import annotations

import math

from vpcontact.case.model import TimeGrid
from vpcontact.io.errors import CaseError

MAX_STEPS = 1_000_000       # time steps (as time.N allows)
K_MIN_DIVISOR = 1024        # the default time.adaptive.k_min: the first step / K_MIN_DIVISOR


def default_k_min(k0: float) -> float:
    """The smallest adaptive step when time.adaptive.k_min is not given.

    Args:
        k0: the first step of the time grid.

    Returns:
        k0 / K_MIN_DIVISOR.
    """
    return k0 / K_MIN_DIVISOR


def time_grid(t: dict, source: str) -> TimeGrid:
    """The time points of the ``time`` section.

    Args:
        t: the default-filled ``time`` section.
        source: the case file, for messages.

    Returns:
        The TimeGrid (explicit scheme, no adaptivity: validation sets those).

    Raises:
        CaseError: for times that do not start at 0 and increase, keys that do not go
            together, a step that does not divide T, or too many steps.
    """
    if "times" in t:
        extra = [k for k in ("N", "k", "grading") if k in t]
        if extra:
            raise CaseError(f"{source}: time.{extra[0]}: not allowed together with time.times")
        ts = [float(x) for x in t["times"]]
        if ts[0] != 0.0 or any(b <= a for a, b in zip(ts, ts[1:])):
            raise CaseError(f"{source}: time.times: must start at 0 and increase strictly")
        if "T" in t and abs(t["T"] - ts[-1]) > 1e-12 * ts[-1]:
            raise CaseError(f"{source}: time.T: {t['T']} differs from the last of time.times "
                            f"({ts[-1]})")
        k = [b - a for a, b in zip(ts, ts[1:])]
        return TimeGrid(tuple(ts), max(k) - min(k) <= 1e-12 * ts[-1])
    if "T" not in t:
        raise CaseError(f"{source}: time.T: required (or give time.times)")
    T = float(t["T"])
    if ("N" in t) == ("k" in t):
        raise CaseError(f"{source}: time: give exactly one of time.N and time.k")
    if "k" in t:
        if "grading" in t:
            raise CaseError(f"{source}: time.grading: needs time.N, not time.k")
        steps = T / t["k"]
        if not steps <= MAX_STEPS + 0.5:
            raise CaseError(f"{source}: time.k: {t['k']} gives {steps:.3g} steps of T = {T:g} "
                            f"(limit {MAX_STEPS})")
        N = round(steps)
        if N < 1 or abs(N * t["k"] - T) > 1e-9 * T:
            raise CaseError(f"{source}: time.k: {t['k']} does not divide T = {T} into whole steps")
        return TimeGrid(tuple(T * n / N for n in range(N + 1)), True)
    N = int(t["N"])
    r = float(t.get("grading", 1.0))
    if r == 1.0:
        return TimeGrid(tuple(T * n / N for n in range(N + 1)), True)
    try:
        k1 = T * (1.0 - r) / (1.0 - r**N)
        ts = [0.0] + [k1 * (1.0 - r**n) / (1.0 - r) for n in range(1, N + 1)]
    except (OverflowError, ZeroDivisionError):
        ts = [0.0, math.nan, T]
    ts[-1] = T
    if not all(math.isfinite(x) for x in ts) or any(b <= a for a, b in zip(ts, ts[1:])):
        raise CaseError(f"{source}: time.grading: {r} with N = {N} gives steps that underflow "
                        "or overflow")
    return TimeGrid(tuple(ts), False)


def check_adaptive(a: dict | None, times: tuple, source: str) -> None:
    """The adaptive steps' bounds: k_min <= first step, k_min <= k_max (the stepper could
    not take a single step); T / k_max within MAX_STEPS (the stepper takes at least that
    many steps).

    Args:
        a: the ``time.adaptive`` section, or None (fixed grid: nothing to check).
        times: the time grid t_0..t_N.
        source: the case file, for messages.

    Raises:
        CaseError: for bounds the stepper cannot keep.
    """
    if a is None:
        return
    k0 = times[1] - times[0]
    k_min, k_max = a.get("k_min"), a.get("k_max", times[-1])
    if not times[-1] / k_max <= MAX_STEPS + 0.5:
        raise CaseError(f"{source}: time.adaptive.k_max: {k_max:g} gives at least "
                        f"{times[-1] / k_max:.3g} steps of T = {times[-1]:g} (limit {MAX_STEPS})")
    if k_min is not None and k_min > k_max:
        raise CaseError(f"{source}: time.adaptive.k_min: {k_min:g} is larger than "
                        f"time.adaptive.k_max = {k_max:g} (allowed: k_min <= k_max)")
    if k_min is None and default_k_min(k0) > k_max:
        raise CaseError(f"{source}: time.adaptive.k_max: {k_max:g} is smaller than the default "
                        f"time.adaptive.k_min = first step / {K_MIN_DIVISOR} = "
                        f"{default_k_min(k0):g} (allowed: k_max >= k_min; give a smaller "
                        "time.adaptive.k_min)")
    if k_min is not None and k_min > k0:
        raise CaseError(f"{source}: time.adaptive.k_min: {k_min:g} is larger than the first "
                        f"step of the time grid, {k0:g}, where adaptive steps start "
                        "(allowed: k_min <= first step)")

