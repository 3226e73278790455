"""Grid sampling, exact prolongation between nested meshes, and the grid error norms."""
import numpy as np
import pytest
from dolfinx import geometry
from mpi4py import MPI

from conftest import make_case
from vpcontact.meshes import build_rectangle
from vpcontact.model.problem import ContactProblem
from vpcontact.post.quantities import norm
from vpcontact.studies.grid import (
    Grid,
    GridSampler,
    cell_centroids,
    cell_l2_norm,
    prolong_dg0,
    prolong_p1,
    strain_norm,
)


def _problem(n, diagonal, L1=1.0, L2=1.0):
    case = make_case(mesh={"n": n, "diagonal": diagonal, "L1": L1, "L2": L2})
    rect = build_rectangle(MPI.COMM_SELF, L1, L2, n=n, diagonal=diagonal)
    return ContactProblem(case, rect), Grid(n, L1, L2, diagonal)


def _eval(f, points):
    """Evaluate a dolfinx Function at points with its own mesh (independent of app.studies.grid)."""
    msh = f.function_space.mesh
    tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
    cand = geometry.compute_collisions(tree, points)
    cells = geometry.compute_colliding_cells(msh, cand, points)
    return f.eval(points, np.array([cells.links(i)[0] for i in range(len(points))]))


@pytest.mark.parametrize("diagonal", ["right", "left"])
def test_prolongation_is_exact(diagonal):
    """A random coarse P1 / DG0 field prolonged to the fine grid equals the coarse function
    evaluated (by dolfinx, on the coarse mesh) at the fine vertices / cell centroids."""
    L1, L2 = 2.0, 1.0
    pc, gc = _problem(4, diagonal, L1, L2)
    gf = Grid(16, L1, L2, diagonal)
    rng = np.random.default_rng(5)
    pc.u.x.array[:] = rng.normal(size=pc.u.x.array.size)
    pc.sigma.x.array[:] = rng.normal(size=pc.sigma.x.array.size)
    coarse = GridSampler(pc, gc).sample(pc, None)

    I, J = np.meshgrid(np.arange(17), np.arange(17), indexing="ij")
    pts = np.column_stack([I.ravel() * gf.hx, J.ravel() * gf.hy, np.zeros(I.size)])
    expected = _eval(pc.u, pts).reshape(17, 17, 2)
    np.testing.assert_allclose(prolong_p1(coarse["u"], gc, gf), expected, atol=1e-13)

    cent = cell_centroids(gf).reshape(-1, 2)
    expected = _eval(pc.sigma, np.column_stack([cent, np.zeros(len(cent))]))
    got = prolong_dg0(coarse["sigma"], gc, gf).reshape(-1, 4)
    np.testing.assert_allclose(got, expected, atol=1e-13)


def test_non_nested_is_refused():
    with pytest.raises(ValueError, match="not nested"):
        prolong_p1(np.zeros((5, 5, 2)), Grid(4, 1, 1, "right"), Grid(6, 1, 1, "right"))
    with pytest.raises(ValueError, match="not nested"):
        prolong_dg0(np.zeros((4, 4, 2)), Grid(4, 1, 1, "right"), Grid(8, 1, 1, "left"))


@pytest.mark.parametrize("diagonal", ["right", "left"])
def test_grid_norms_match_dolfinx(diagonal):
    p, g = _problem(6, diagonal, 1.5, 1.0)
    rng = np.random.default_rng(6)
    p.u.x.array[:] = rng.normal(size=p.u.x.array.size)
    p.update_sigma()
    snap = GridSampler(p, g).sample(p, None)
    assert strain_norm(snap["u"], g) == pytest.approx(norm(p, "V"), rel=1e-12)
    assert cell_l2_norm(snap["sigma"], g) == pytest.approx(norm(p, "Q"), rel=1e-12)


def test_prolonged_field_has_the_same_norm():
    """Prolongation changes the representation, not the function: norms are preserved."""
    p, gc = _problem(4, "right")
    rng = np.random.default_rng(7)
    p.u.x.array[:] = rng.normal(size=p.u.x.array.size)
    p.update_sigma()
    snap = GridSampler(p, gc).sample(p, None)
    gf = Grid(32, 1.0, 1.0, "right")
    assert strain_norm(prolong_p1(snap["u"], gc, gf), gf) == pytest.approx(
        strain_norm(snap["u"], gc), rel=1e-12)
    assert cell_l2_norm(prolong_dg0(snap["sigma"], gc, gf), gf) == pytest.approx(
        cell_l2_norm(snap["sigma"], gc), rel=1e-12)
