"""Checks of a case's data values before anything is built or compiled.

Every expression-valued input (loads.f0, loads.traction / pressure / displacement of a
group, initial.u0, initial.sigma0, material.viscoplastic.kappa0, contact.g) is evaluated with
numpy at sample points covering the closed body (or the side it acts on) and at the times of
the time grid (a dense sample of [0, T] with adaptive steps).  A value that is not a finite
real number is refused, naming the key and the point (x, t); so are data outside the model's
set: g >= 0 on Gamma3, kappa0 >= 0, sigma0 symmetric, and (for the built-in mesh with its
default boundaries) u0 vanishing on Gamma1 {x = 0} and u_nu <= g on Gamma3 (the bottom side).

The sample points are a tensor grid with the vertices and the midpoints of a structured
grid of m cells per side of the built-in rectangle / box: the mesh's own cells (m = mesh.n,
or L / h for unstructured meshes) up to MAX_CELLS[dim] per side.  The body of a mesh.file is
not known before it is loaded (``Samples.unknown``): only the values that do not depend on
the position are sampled then; once it is loaded, the same checks run on its own points
(``PointSamples``: the nodes and cell midpoints of the body, the nodes and facet midpoints of
each group; app/model/datapoints.py) before anything is computed.
"""
from __future__ import annotations

import math

import numpy as np

from vpcontact.case import anisotropy, expressions

MAX_MAGNITUDE = 1e100            # as app/case/reading.py's limit for the numbers of a case
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

    side_word = "side"               # what ``points(side)`` samples, for messages

    def __init__(self, lengths, cells, times, adaptive: bool):
        self.known = True            # the body's geometry is known (see ``unknown``)
        self.dim = len(lengths)
        self.lengths = [float(L) for L in lengths]
        self.axes = [np.linspace(0.0, L, 2 * int(min(max(m, 1), MAX_CELLS[self.dim])) + 1)
                     for L, m in zip(self.lengths, cells)]
        t = np.asarray(times, dtype=float)
        if adaptive:
            t = np.union1d(t, np.linspace(0.0, t[-1], ADAPTIVE_TIMES))
        self.times = t

    @classmethod
    def unknown(cls, dim: int, times, adaptive: bool) -> Samples:
        """Samples of a body whose geometry is not known yet (a mesh.file): the sample times,
        and one placeholder point for the values that do not depend on the position.

        Args:
            dim: the space dimension.
            times: the time grid t_0..t_N.
            adaptive: the steps are adaptive.

        Returns:
            The Samples (``known`` False).
        """
        self = cls([1.0] * dim, [1] * dim, times, adaptive)
        self.known = False
        self.axes = [np.zeros(1)] * dim
        return self

    def points(self, side=None) -> np.ndarray:
        """The sample points.

        Args:
            side: a side's name, or None for the whole closed body (ignored for an unknown
                geometry: one placeholder point).

        Returns:
            (P, dim) points.
        """
        if not self.known:
            return np.zeros((1, self.dim))
        axes = list(self.axes)
        if side is not None:
            axis, end = SIDE_AXIS[self.dim][side]
            axes[axis] = np.array([self.lengths[axis] * end])
        grid = np.meshgrid(*axes, indexing="ij")
        return np.stack([g.ravel() for g in grid], axis=1)


class PointSamples(Samples):
    """Sample points of a body known by its mesh (a mesh.file once loaded): the nodes and cell
    midpoints of the body, the nodes and facet midpoints of each group, and the sample times.

    Args:
        body: (P, dim) points of the whole body.
        groups: group (a name or physical tag, as the case gives it) -> (P_g, dim) points.
        lengths: the extents of the body's bounding box.
        times: the time grid t_0..t_N.
        adaptive: the steps are adaptive: ADAPTIVE_TIMES more times in [0, T].
    """

    side_word = "group"

    def __init__(self, body: np.ndarray, groups: dict, lengths, times, adaptive: bool):
        super().__init__(lengths, [1] * len(lengths), times, adaptive)
        self.body = np.asarray(body, dtype=float).reshape(-1, self.dim)
        self.groups = {k: np.asarray(v, dtype=float).reshape(-1, self.dim)
                       for k, v in groups.items()}

    def points(self, side=None) -> np.ndarray:
        """The sample points.

        Args:
            side: a group (name or tag), or None for the whole body.

        Returns:
            (P, dim) points; none for a group the mesh does not have (refused elsewhere).
        """
        if side is None:
            return self.body
        return self.groups.get(side, np.zeros((0, self.dim)))


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


def _check_u0_on_the_boundary(u0, g, direction, scale: float, samples: Samples) -> None:
    """u0 = 0 on Gamma1 (the left side) and u_nu <= g on Gamma3 (the bottom side)."""
    d = samples.dim
    for i, c in enumerate(u0):
        v = finite_values(c, f"initial.u0[{i}]", samples, "left", with_t=False)
        if np.abs(v).max(initial=0.0) > 1e-12 * scale:
            raise DataError(f"initial.u0: must vanish on Gamma1 (x = 0), got u0[{i}] = "
                            f"{v.flat[np.argmax(np.abs(v))]:.6g}")
    if g is None:
        return
    if direction is None:                       # u_nu = -u_d on the bottom side
        direction = [0.0] * (d - 1) + [-1.0]
    norm = math.hypot(*direction)
    v = sum(float(di) / norm * finite_values(c, f"initial.u0[{i}]", samples, "bottom",
                                              with_t=False)
            for i, (di, c) in enumerate(zip(direction, u0)) if di != 0)
    gv = finite_values(g, "contact.g", samples, "bottom", with_t=False) \
        if isinstance(g, str) else np.asarray(float(g))
    v, gv = np.broadcast_arrays(np.asarray(v, dtype=float), gv)
    excess = v - gv * (1 + 1e-12)
    if excess.max(initial=-math.inf) > 0:
        k = np.unravel_index(np.argmax(excess), excess.shape)
        shown = f"{g:g}" if not isinstance(g, str) else f"{gv[k]:.6g}"
        raise DataError(f"initial.u0: violates u_nu <= g on Gamma3 ({AXES[d - 1]} = 0): "
                        f"u_nu = {v[k]:.6g} > g = {shown}")


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
        The values (M, P); none (P = 0) for a component that depends on the position of a
        body not known yet.

    Raises:
        DataError: if a value is not a finite number of at most MAX_MAGNITUDE.
    """
    points = samples.points(side)
    try:
        if not samples.known and isinstance(component, str) and \
                expressions.names(expressions.parse(component)) & set(AXES):
            return np.zeros((1, 0))             # depends on the position: not known yet
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
                        f"{samples.side_word if side is not None else 'whole body'}"
                        f"{' at every time in [0, T]' if with_t else ''})")
    return values


def check_loads(loads: dict, samples: Samples) -> float:
    """Loads finite on the body (f0) and on their groups (tractions, pressures; a group of
    a known body is one of its sides).

    Args:
        loads: the case's ``loads`` section.
        samples: the sample points and times.

    Returns:
        The largest stress they apply: max |f2|, max |p| and max |f0| L.

    Raises:
        DataError: for a value that is not finite or out of range.
    """
    scale = 0.0
    for side, comps in loads.get("traction", {}).items():
        for i, c in enumerate(comps):
            values = finite_values(c, f"loads.traction.{side}[{i}]", samples, side)
            scale = max(scale, float(np.abs(values).max(initial=0.0)))
    for side, c in loads.get("pressure", {}).items():
        values = finite_values(c, f"loads.pressure.{side}", samples, side)
        scale = max(scale, float(np.abs(values).max(initial=0.0)))
    for i, c in enumerate(loads.get("f0", ())):
        values = finite_values(c, f"loads.f0[{i}]", samples)
        scale = max(scale, float(np.abs(values).max(initial=0.0)) * max(samples.lengths))
    return scale


def check_displacement(displacement: dict, samples: Samples) -> float:
    """Prescribed displacements finite on their groups at every time.

    Args:
        displacement: the case's ``loads.displacement`` (group -> components, None where
            free).
        samples: the sample points and times.

    Returns:
        Their largest magnitude max |u_D| (0 without any).

    Raises:
        DataError: for a value that is not finite or out of range.
    """
    scale = 0.0
    for side, comps in displacement.items():
        for i, c in enumerate(comps):
            if c is not None:
                values = finite_values(c, f"loads.displacement.{side}[{i}]", samples, side)
                scale = max(scale, float(np.abs(values).max(initial=0.0)))
    return scale


def check_gap(g, sides, samples: Samples, path: str = "contact.g",
              what: str = "the gap to the foundation") -> None:
    """The gap g (an expression) finite and >= 0 on Gamma3 (the contact sides of a known
    body; for a mesh.file only an expression without x, y, z is sampled here).

    Args:
        g: contact.g: a number, an expression in x, y, z, or None.
        sides: boundaries.contact (side names of the built-in mesh).
        samples: the sample points.
        path: the key (also contact.normal_compliance.c_nu, contact.memory.b0: fields of
            x, y, z >= 0 on Gamma3).
        what: its meaning, for the message.

    Raises:
        DataError: for a value that is not finite, or negative.
    """
    if not isinstance(g, str):
        return                                  # a number >= 0 (schema) or no bound
    for side in sides if samples.known else [None]:
        v = finite_values(g, path, samples, side, with_t=False)
        if v.size and v.min() < 0:
            points = samples.points(side)
            where = _where(points if v.shape[1] == len(points) else points[:1], samples.times,
                           (0, int(np.argmin(v[0]))), samples.dim, False)
            raise DataError(f"{path}: must be >= 0 on Gamma3 ({what}), "
                            f"got {v.min():.6g} at {where}")


def check_initial(initial: dict, kappa0, g, samples: Samples, direction=None,
                  geometric: bool = True) -> tuple[float, float]:
    """u0, sigma0 and kappa0 finite and in the model's set.

    Args:
        initial: the case's ``initial`` section.
        kappa0: material.viscoplastic.kappa0 (a number or expression), or None.
        g: the gap (a number or an expression in x, y, z), or None.
        samples: the sample points.
        direction: contact.direction (u_nu = u . d), or None: the bottom side's outward
            normal.
        geometric: Gamma1 is the left side and Gamma3 the bottom side of a known body:
            check u0 = 0 on Gamma1 and u_nu <= g on Gamma3 (else the mesh's nodes are
            checked when it is loaded).

    Returns:
        (max |u0|, max |sigma0|).

    Raises:
        DataError: for a value that is not finite, u0 not 0 on Gamma1 or beyond g on
            Gamma3, sigma0 not symmetric, or kappa0 < 0.
    """
    scale = 0.0
    if "u0" in initial:
        u0 = initial["u0"]
        body = [finite_values(c, f"initial.u0[{i}]", samples, with_t=False)
                for i, c in enumerate(u0)]
        scale = max(float(np.abs(v).max(initial=0.0)) for v in body)
        if geometric and samples.known:
            _check_u0_on_the_boundary(u0, g, direction, scale, samples)
    stress = 0.0
    if "sigma0" in initial:
        rows = initial["sigma0"]
        s = [[finite_values(c, f"initial.sigma0[{i}][{j}]", samples, with_t=False)
              for j, c in enumerate(r)] for i, r in enumerate(rows)]
        stress = max(float(np.abs(v).max(initial=0.0)) for r in s for v in r)
        for i in range(samples.dim):
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


def check_elasticity(material: dict, samples: Samples) -> float:
    """A material section's elasticity at the sample points: E > 0 and 0 <= nu < 0.5 where
    they are expressions (per cell on the mesh: app/model/stiffness.py).

    Args:
        material: the section (its E, nu, or elasticity: app/case/anisotropy.py).
        samples: the sample points.

    Returns:
        Its modulus scale: E (its largest sampled value), or the largest eigenvalue of an
        anisotropic E.

    Raises:
        DataError: E <= 0 or nu outside [0, 0.5) at a sample point, or a value not finite.
    """
    spec = material.get("elasticity")
    if spec is not None:
        return anisotropy.largest_modulus(
            anisotropy.elasticity_matrix(spec, samples.dim, material.get("plane", "stress")),
            samples.dim)
    E = finite_values(material["E"], "material.E", samples, with_t=False)
    nu = finite_values(material["nu"], "material.nu", samples, with_t=False)
    if E.size and E.min() <= 0:
        raise DataError(f"material.E: must be > 0 everywhere, got {E.min():.6g}")
    if nu.size and (nu.min() < 0 or nu.max() >= 0.5):
        raise DataError(f"material.nu: must be in [0, 0.5) everywhere, got values in "
                        f"[{nu.min():.6g}, {nu.max():.6g}]")
    return float(E.max(initial=0.0))
