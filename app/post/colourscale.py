"""The colour scale of a picture's field (app/post/pictures.py): the field's whole range,
from its smallest to its largest value, as ParaView shows it (no value beyond the bar's
ends, so no clipping to state); a field that is uniform (its spread within rounding) is one
colour whose value the picture states; the bar's title names the quantity and its unit.

Units: a case's numbers are used as given, in SI units (docs/model.md, Units; the case
reference states each key's unit): stresses and kappa in N/m^2, displacements in m, the
accumulated strain p of the laws norton and chaboche dimensionless.  numpy only (the
tests check the scale without pyvista).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the fields the pictures colour by: (name in the titles, unit)
QUANTITIES = {"sigma_vm": ("von Mises stress", "N/m^2"),
              "kappa": ("kappa", "N/m^2"),
              "p": ("accumulated viscoplastic strain p", "-"),
              "neg_sigma_nu": ("contact pressure -sigma_nu", "N/m^2")}

UNIFORM_RTOL = 1e-9     # a spread below this fraction of the largest |value|: rounding


@dataclass(frozen=True)
class ColourScale:
    """A field's colour scale.

    Attributes:
        low, high: the smallest and largest finite value (0, 0 without any).
        uniform: the spread is within rounding: the field is drawn in one colour.
    """

    low: float
    high: float
    uniform: bool

    @property
    def clim(self) -> tuple[float, float]:
        """The range given to the colour map: (low, high), widened when uniform so that
        high > low (VTK needs it; a uniform field takes no colour map)."""
        if not self.uniform:
            return self.low, self.high
        return self.low, self.low + max(abs(self.low), 1.0)


def colour_scale(values) -> ColourScale:
    """The colour scale of a field: its whole finite range.

    Args:
        values: the field's values (cells or points; NaN and inf are left out).

    Returns:
        ColourScale(min, max, uniform): uniform when max - min <= UNIFORM_RTOL max|value|
        (or no finite value).
    """
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    if not v.size:
        return ColourScale(0.0, 0.0, True)
    lo, hi = float(v.min()), float(v.max())
    return ColourScale(lo, hi, hi - lo <= UNIFORM_RTOL * max(abs(lo), abs(hi)))


def bar_title(name: str) -> str:
    """The colour bar's title of a field: its quantity and unit.

    Args:
        name: a key of QUANTITIES.

    Returns:
        E.g. "von Mises stress [N/m^2]".
    """
    quantity, unit = QUANTITIES[name]
    return f"{quantity} [{unit}]"


def uniform_note(name: str, scale: ColourScale) -> str:
    """What a picture of a uniform field says instead of a colour bar.

    Args:
        name: a key of QUANTITIES.
        scale: the field's ColourScale (uniform).

    Returns:
        E.g. "von Mises stress uniform: 40 N/m^2".
    """
    quantity, unit = QUANTITIES[name]
    value = 0.5 * (scale.low + scale.high)
    return f"{quantity} uniform: {value:.4g}" + ("" if unit == "-" else f" {unit}")
