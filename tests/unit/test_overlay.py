"""app/studies/overlay.py: the Error on the overlay of two triangle meshes against the
exact prolongation of the nested grids (app/studies/grid.py, convergence.run_error) on
random fields, both diagonals; the overlay's areas; triangle intersections in closed form."""
import types

import numpy as np
import pytest

from vpcontact.studies.convergence import RunRecord, run_error
from vpcontact.studies.grid import Grid, cell_strains, cell_vertices
from vpcontact.studies.overlay import clip_area, overlay, overlay_error, triangle_strains


def test_triangle_intersections_in_closed_form():
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert clip_area(unit, unit) == pytest.approx(0.5, abs=1e-15)
    assert clip_area(unit, unit[::-1]) == pytest.approx(0.5, abs=1e-15)     # orientation
    assert clip_area(unit, 0.5 * unit) == pytest.approx(0.125, abs=1e-15)
    assert clip_area(unit, np.array([[1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])) == 0.0
    # touching the hypotenuse at one point only: no area; shifted by (1/4, 1/4): the
    # triangle (1/4, 1/4), (3/4, 1/4), (1/4, 3/4) of legs 1/2
    other = np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5]])
    assert clip_area(unit, other) == pytest.approx(0.0, abs=1e-15)
    shifted = np.array([[0.25, 0.25], [1.25, 0.25], [0.25, 1.25]])
    assert clip_area(unit, shifted) == pytest.approx(0.5 * 0.5 ** 2, abs=1e-15)


@pytest.mark.parametrize("diagonal", ["right", "left"])
def test_overlay_areas_cover_every_cell(diagonal):
    coarse, fine = Grid(3, 2.0, 1.0, diagonal), Grid(5, 2.0, 1.0, "right")   # not nested
    cells = cell_vertices(coarse).reshape(-1, 3, 2)
    P, R, A = overlay(cells, fine)
    assert A.sum() == pytest.approx(2.0, rel=1e-13)
    per_cell = np.bincount(P, weights=A, minlength=len(cells))
    assert np.allclose(per_cell, coarse.hx * coarse.hy / 2, rtol=1e-13)
    per_ref = np.bincount(R, weights=A, minlength=fine.n * fine.n * 2)
    assert np.allclose(per_ref, fine.hx * fine.hy / 2, rtol=1e-13)


@pytest.mark.parametrize("diagonal", ["right", "left"])
def test_overlay_error_equals_the_nested_prolongation(diagonal):
    """Random fields on n = 4 against n = 12 at three common time points: the overlay's
    Error equals run_error's (exact prolongation on the nested grids) to round-off."""
    rng = np.random.default_rng(1)
    coarse, ref_grid = Grid(4, 1.0, 1.0, diagonal), Grid(12, 1.0, 1.0, diagonal)

    def snaps(g, count):
        return [{"u": rng.normal(size=(g.n + 1, g.n + 1, 2)),
                 "sigma": rng.normal(size=(g.n, g.n, 2, 2, 2)),
                 "kappa": rng.normal(size=(g.n, g.n, 2))} for _ in range(count)]

    level = RunRecord(4, 2, 1e-7, coarse, 0, np.array([0.0, 0.5, 1.0]), 0, 0, 0, False,
                      snaps(coarse, 3))
    ref = RunRecord(12, 4, 1e-7, ref_grid, 0, np.array([0.0, 0.25, 0.5, 0.75, 1.0]), 0, 0,
                    0, False, snaps(ref_grid, 5))
    expected = run_error(level, ref)
    cells = cell_vertices(coarse).reshape(-1, 3, 2)
    samples = types.SimpleNamespace(cells=cells, times=list(level.times), snaps=[
        {"eps": cell_strains(s["u"], coarse).reshape(-1, 3),
         "sigma": s["sigma"].reshape(-1, 2, 2), "kappa": s["kappa"].reshape(-1)}
        for s in level.snaps])
    got = overlay_error(samples, ref, ref_grid)
    for key in ("error", "e_sigma", "e_u", "e_kappa"):
        assert got[key] == pytest.approx(expected[key], rel=1e-12)
    assert got["n_max"] == expected["n_max"]
    samples.times[1] = 0.4                       # not a reference time point: no Error
    assert overlay_error(samples, ref, ref_grid) is None


def test_triangle_strains_of_a_linear_field():
    """u = B x on any triangles: eps = sym(B)."""
    rng = np.random.default_rng(2)
    x = rng.random((20, 3, 2))
    B = np.array([[0.3, -0.7], [1.1, 0.2]])
    eps = triangle_strains(x, x @ B.T)
    sym = 0.5 * (B + B.T)
    assert np.allclose(eps, [sym[0, 0], sym[1, 1], sym[0, 1]], atol=1e-10)
