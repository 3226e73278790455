"""The pictures' colour scale (app/post/colourscale.py) and the round numbers of the figures'
scales (results.round_125), against values written out by hand."""
import numpy as np
import pytest

from vpcontact.post.colourscale import ColourScale, bar_title, colour_scale, uniform_note
from vpcontact.post.results import round_125


def test_the_scale_is_the_whole_finite_range():
    values = np.r_[np.linspace(2.0, 12.0, 1000), 23.2, np.nan, np.inf]   # one corner value
    assert colour_scale(values) == ColourScale(2.0, 23.2, False)
    assert colour_scale(values).clim == (2.0, 23.2)


@pytest.mark.parametrize("values, value", [([4.573123347813151, 4.573123347813152], 4.573),
                                           ([0.0, 0.0], 0.0), ([-3.0, -3.0 + 1e-15], -3.0)])
def test_a_spread_of_rounding_is_uniform(values, value):
    scale = colour_scale(values)
    assert scale.uniform and scale.clim[1] > scale.clim[0]
    assert uniform_note("sigma_vm", scale) == f"von Mises stress uniform: {value:.4g} N/m^2"


def test_a_small_real_spread_is_not_uniform():
    assert not colour_scale([100.0, 100.0 + 1e-6]).uniform          # 1e-8 relative
    assert colour_scale([]).uniform and colour_scale([np.nan]).uniform


def test_titles_have_units():
    assert bar_title("sigma_vm") == "von Mises stress [N/m^2]"
    assert bar_title("kappa") == "kappa [N/m^2]"
    assert bar_title("p") == "accumulated viscoplastic strain p [-]"
    assert uniform_note("p", ColourScale(0.5, 0.5, True)).endswith("uniform: 0.5")


@pytest.mark.parametrize("value, expected", [(0.073, 0.05), (23.2, 20.0), (1.0, 1.0),
                                             (2.0, 2.0), (4.99, 2.0), (5.0, 5.0),
                                             (9.99, 5.0), (10.0, 10.0), (3e-7, 2e-7)])
def test_round_125(value, expected):
    assert round_125(value) == pytest.approx(expected, rel=1e-15)
