"""Checks of a case's data values before anything is built or compiled.

Every expression-valued input (loads.f0, loads.traction.<side>, initial.u0, initial.sigma0,
material.viscoplastic.kappa0) is evaluated with numpy at sample points covering the closed
body (or the side it acts on) and at the times of the time grid (a dense sample of [0, T]
with adaptive steps).  A value that is not a finite real number is refused, naming the key
and the point (x, t); so are initial data outside the model's set: u0 must vanish on Gamma1
{x = 0} and satisfy u_nu <= g on Gamma3 (the bottom side), kappa0 >= 0, sigma0 symmetric.

The sample points are a tensor grid with the vertices and the midpoints of a structured
grid of m cells per side: the mesh's own cells (m = mesh.n, or L / h for unstructured
meshes) up to MAX_CELLS[dim] per side.  The same checks on the mesh nodes are repeated in
app/model/problem.py, where u0 and kappa0 are set.
"""
from __future__ import annotations

import math

import numpy as np

from app.io import expressions

MAX_MAGNITUDE = 1e100                # as app/io/case.py's limit for the numbers of a case
MAX_CELLS = {2: 128, 3: 16}        # sample grid: at most this many cells per side
MAX_EVALUATIONS = 1_000_000        # points x times per component
ADAPTIVE_TIMES = 1025              # times sampled in [0, T] when the steps are adaptive
AXES = "xyz"
# the coordinate fixed on each side: (axis, 0 for the lower end or 1 for the upper end)
SIDE_AXIS = {2: {"left": (0, 0), "right": (0, 1), "bottom": (1, 0), "top": (1, 1)},
             3: {"left": (0, 0), "right": (0, 1), "front": (1, 0), "back": (1, 1),
                 "bottom": (2, 0), "top": (2, 1)}}


class DataError(ValueError):
    """A data value outside the allowed set; the message starts with the key path."""


class Samples:
    """Sample points of the body and its sides, and sample times of [0, T].

    Args:
        lengths: the body's sides (L1, L2[, L3]).
        cells: the mesh's cells per side (the sample grid has twice as many, at most
            MAX_CELLS).
        times: the time grid t_0..t_N.
        adaptive: the steps are adaptive: ADAPTIVE_TIMES more times in [0, T].
    """

    def __init__(self, lengths, cells, times, adaptive: bool):
        self.dim = len(lengths)
        self.lengths = [float(L) for L in lengths]
        self.axes = [np.linspace(0.0, L, 2 * int(min(max(m, 1), MAX_CELLS[self.dim])) + 1)
                     for L, m in zip(self.lengths, cells)]
        t = np.asarray(times, dtype=float)
        if adaptive:
            t = np.union1d(t, np.linspace(0.0, t[-1], ADAPTIVE_TIMES))
        self.times = t

    def points(self, side: str | None = None) -> np.ndarray:
        """The sample points.

        Args:
            side: a side's name, or None for the whole closed body.

        Returns:
            (P, dim) points.
        """
        axes = list(self.axes)
        if side is not None:
            axis, end = SIDE_AXIS[self.dim][side]
            axes[axis] = np.array([self.lengths[axis] * end])
        grid = np.meshgrid(*axes, indexing="ij")
        return np.stack([g.ravel() for g in grid], axis=1)


def evaluate(component, points: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values of a data component at sample points and times.

    Values that are not real numbers (e.g. (-1)**0.5) are NaN.

    Args:
        component: a number, {"table": ...} or an expression string.
        points: (P, dim) points.
        times: sample times.

    Returns:
        (values (M, P), the M times used): all the times unless that exceeds
        MAX_EVALUATIONS (one time or point when the component does not depend on it).

    Raises:
        ExpressionError: for an expression that does not parse.
    """
    if isinstance(component, (int, float)):
        return np.full((1, len(points)), float(component)), times[:1]
    if isinstance(component, dict):
        table = np.asarray(component["table"], dtype=float)
        values = np.interp(times, table[:, 0], table[:, 1])
        return np.repeat(values[:, None], len(points), axis=1), times
    tree = expressions.parse(component)
    names = expressions.names(tree)
    if not names & set(AXES):
        points = points[:1]
    if "t" not in names:
        times = times[:1]
    elif len(times) * len(points) > MAX_EVALUATIONS:
        keep = max(MAX_EVALUATIONS // len(points), 2)
        times = times[np.linspace(0, len(times) - 1, keep).round().astype(int)]
    symbols = {"t": times[:, None]}
    for i, a in enumerate(AXES):
        symbols[a] = points[None, :, i] if i < points.shape[1] else 0.0
    values = expressions.evaluate(tree, symbols)
    return np.broadcast_to(values, (len(times), len(points))), times


def _where(points, times, index, dim: int, with_t: bool) -> str:
    m, p = index
    parts = [f"{a} = {points[p, i]:.6g}" for i, a in enumerate(AXES[:dim])]
    if with_t:
        parts.append(f"t = {times[m]:.6g}")
    return ", ".join(parts)


def finite_values(component, path: str, samples: Samples, side: str | None = None,
                  with_t: bool = True) -> np.ndarray:
    """The component's sample values, all finite.

    Args:
        component: a number, table or expression string.
        path: its key path, for messages.
        samples: the sample points and times.
        side: a side's name, or None for the whole body.
        with_t: the component depends on time (loads; initial values do not).

    Returns:
        The values (M, P).

    Raises:
        DataError: if a value is not a finite number of at most MAX_MAGNITUDE.
    """
    points = samples.points(side)
    try:
        values, times = evaluate(component, points, samples.times)
    except expressions.ExpressionError as exc:
        raise DataError(f"{path}: {exc}") from None
    bad = ~(np.abs(values) <= MAX_MAGNITUDE)
    if bad.any():
        index = np.unravel_index(np.argmax(bad), bad.shape)
        if values.shape[1] < len(points):                 # no x, y, z in the expression
            points = points[:1]
        value = values[index]
        what = f"{value:g} is out of range" if np.isfinite(value) else \
            f"{value} is not a finite number"
        raise DataError(f"{path}: {what} at {_where(points, times, index, samples.dim, with_t)}"
                        f" (allowed: finite values up to {MAX_MAGNITUDE:g} in magnitude on the "
                        f"{'side' if side else 'whole body'}"
                        f"{' at every time in [0, T]' if with_t else ''})")
    return values


def check_loads(loads: dict, samples: Samples) -> float:
    """Loads finite on the body (f0) and on their sides (tractions).

    Args:
        loads: the case's ``loads`` section.
        samples: the sample points and times.

    Returns:
        The largest stress they apply: max |f2| and max |f0| L.

    Raises:
        DataError: for a value that is not finite or out of range.
    """
    scale = 0.0
    for side, comps in loads.get("traction", {}).items():
        for i, c in enumerate(comps):
            values = finite_values(c, f"loads.traction.{side}[{i}]", samples, side)
            scale = max(scale, float(np.abs(values).max(initial=0.0)))
    for i, c in enumerate(loads.get("f0", ())):
        values = finite_values(c, f"loads.f0[{i}]", samples)
        scale = max(scale, float(np.abs(values).max(initial=0.0)) * max(samples.lengths))
    return scale


def check_initial(initial: dict, kappa0, g: float | None,
                  samples: Samples) -> tuple[float, float]:
    """u0, sigma0 and kappa0 finite and in the model's set.

    Args:
        initial: the case's ``initial`` section.
        kappa0: material.viscoplastic.kappa0 (a number or expression), or None.
        g: the gap, or None.
        samples: the sample points.

    Returns:
        (max |u0|, max |sigma0|).

    Raises:
        DataError: for a value that is not finite, u0 not 0 on Gamma1 or beyond g on
            Gamma3, sigma0 not symmetric, or kappa0 < 0.
    """
    d = samples.dim
    scale = 0.0
    if "u0" in initial:
        u0 = initial["u0"]
        body = [finite_values(c, f"initial.u0[{i}]", samples, with_t=False)
                for i, c in enumerate(u0)]
        scale = max(float(np.abs(v).max(initial=0.0)) for v in body)
        for i, c in enumerate(u0):              # u0 = 0 on Gamma1
            v = finite_values(c, f"initial.u0[{i}]", samples, "left", with_t=False)
            if np.abs(v).max(initial=0.0) > 1e-12 * scale:
                raise DataError(f"initial.u0: must vanish on Gamma1 (x = 0), got u0[{i}] = "
                                f"{v.flat[np.argmax(np.abs(v))]:.6g}")
        if g is not None:                       # u_nu = -u_d on the bottom side
            v = -finite_values(u0[d - 1], f"initial.u0[{d - 1}]", samples, "bottom",
                               with_t=False)
            if v.max(initial=-math.inf) > g * (1 + 1e-12):
                raise DataError(f"initial.u0: violates u_nu <= g on Gamma3 "
                                f"({AXES[d - 1]} = 0): u_nu = {v.max():.6g} > g = {g:g}")
    stress = 0.0
    if "sigma0" in initial:
        rows = initial["sigma0"]
        s = [[finite_values(c, f"initial.sigma0[{i}][{j}]", samples, with_t=False)
              for j, c in enumerate(r)] for i, r in enumerate(rows)]
        stress = max(float(np.abs(v).max(initial=0.0)) for r in s for v in r)
        for i in range(d):
            for j in range(i):
                if np.abs(s[i][j] - s[j][i]).max(initial=0.0) > 1e-12 * stress:
                    raise DataError(f"initial.sigma0: must be symmetric ([{i}][{j}] != "
                                    f"[{j}][{i}])")
    if isinstance(kappa0, str):
        v = finite_values(kappa0, "material.viscoplastic.kappa0", samples, with_t=False)
        if v.min(initial=0.0) < -1e-12 * np.abs(v).max(initial=0.0):
            raise DataError(f"material.viscoplastic.kappa0: must be >= 0 everywhere, got "
                            f"{v.min():.6g}")
    return scale, stress
