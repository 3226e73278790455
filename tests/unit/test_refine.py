"""Uniform refinement of a gmsh mesh (meshes/refine.py) and the study's fields on its levels
(app/studies/nested.py): nested cells, boundary groups carried over, exact prolongation,
the .msh files as dolfinx reads them, and the error norms against dolfinx's."""
import math

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from conftest import ROOT
from vpcontact.meshes import load_mesh_file
from vpcontact.meshes.refine import MeshLevel, prolong_dg0, prolong_p1, refine, refine_file
from vpcontact.post.quantities import norm

HERTZ_GEO = ROOT / "cases" / "hertz_cylinder.geo"
SPHERE_GEO = ROOT / "cases" / "sphere3d.geo"


@pytest.fixture(scope="module")
def hertz_levels(tmp_path_factory):
    out = tmp_path_factory.mktemp("levels2d")
    return refine_file(MPI.COMM_WORLD, HERTZ_GEO, 2, 8.0, 2, out)


@pytest.fixture(scope="module")
def sphere_levels(tmp_path_factory):
    out = tmp_path_factory.mktemp("levels3d")
    return refine_file(MPI.COMM_WORLD, SPHERE_GEO, 3, 6.0, 1, out)


def _volumes(level: MeshLevel) -> np.ndarray:
    p = level.x[level.cells]
    J = p[:, 1:] - p[:, :1]
    return np.abs(np.linalg.det(J)) / math.factorial(level.dim)


def _barycentric(points: np.ndarray, simplex: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of points (m, d) in simplices (m, d + 1, d)."""
    J = np.swapaxes(simplex[:, 1:] - simplex[:, :1], 1, 2)
    lam = np.linalg.solve(J, (points - simplex[:, 0])[..., None])[..., 0]
    return np.column_stack([1 - lam.sum(axis=1), lam])


@pytest.mark.parametrize("which", ["hertz_levels", "sphere_levels"])
def test_children_tile_their_parent(which, request):
    """Each cell's k children lie inside it (barycentric coordinates >= 0 at their
    vertices) and their volumes add up to its volume; no child is degenerate."""
    _, levels = request.getfixturevalue(which)
    for coarse, fine in zip(levels, levels[1:]):
        k = coarse.children
        assert len(fine.cells) == k * len(coarse.cells)
        parent = np.repeat(np.arange(len(coarse.cells)), k)
        vf, vc = _volumes(fine), _volumes(coarse)
        np.testing.assert_allclose(np.bincount(parent, vf), vc, rtol=1e-12)
        assert vf.min() > 0.05 * vc.min() / k
        for j in range(coarse.dim + 1):
            lam = _barycentric(fine.x[fine.cells[:, j]], coarse.x[coarse.cells[parent]])
            assert lam.min() > -1e-12
        assert fine.diameter() == pytest.approx(coarse.diameter() / 2, rel=0.3)


@pytest.mark.parametrize("which", ["hertz_levels", "sphere_levels"])
def test_prolongation_is_the_same_function(which, request):
    """A random coarse P1 field prolonged over two refinements equals the coarse function
    evaluated at the fine vertices (barycentric formula in the ancestor cell); DG0 values
    are the ancestor's."""
    _, levels = request.getfixturevalue(which)
    R = len(levels) - 1
    coarse, fine = levels[0], levels[R]
    k = coarse.children ** R
    rng = np.random.default_rng(3)
    u = rng.normal(size=(len(coarse.x), coarse.dim))
    got = prolong_p1(u, levels, 0, R)
    ancestor = np.arange(len(fine.cells)) // k
    for j in range(coarse.dim + 1):
        v = fine.cells[:, j]
        lam = _barycentric(fine.x[v], coarse.x[coarse.cells[ancestor]])
        expected = np.einsum("mi,mid->md", lam, u[coarse.cells[ancestor]])
        np.testing.assert_allclose(got[v], expected, atol=1e-12)
    f = rng.normal(size=(len(coarse.cells), 2, 2))
    np.testing.assert_array_equal(prolong_dg0(f, levels, 0, R), f[ancestor])


@pytest.mark.parametrize("which", ["hertz_levels", "sphere_levels"])
def test_boundary_groups_are_carried_over(which, request):
    """Each group keeps its name, its measure, and its facets lie on its parent facets."""
    paths, levels = request.getfixturevalue(which)
    coarse, fine = levels[0], levels[1]
    d = coarse.dim
    assert fine.names == coarse.names and set(coarse.names.values()) >= {"top"}

    def measure(level, tag):
        p = level.x[level.facets[level.facet_tags == tag]]
        if d == 2:
            return np.linalg.norm(p[:, 1] - p[:, 0], axis=1).sum()
        return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()

    for tag in np.unique(coarse.facet_tags):
        assert np.sum(fine.facet_tags == tag) == (2 if d == 2 else 4) * np.sum(
            coarse.facet_tags == tag)
        assert measure(fine, tag) == pytest.approx(measure(coarse, tag), rel=1e-12)
    # the files as dolfinx reads them: the same groups, facet counts and vertex numbering
    for path, level in zip(paths, levels):
        fm = load_mesh_file(MPI.COMM_WORLD, path, d)
        names = {n: t for (dd, t), n in level.names.items() if dd == d - 1}
        assert fm.groups == names
        tags, counts = np.unique(fm.facet_tags.values, return_counts=True)
        expected = np.unique(level.facet_tags, return_counts=True)
        np.testing.assert_array_equal(tags, expected[0])
        np.testing.assert_array_equal(counts, expected[1])
        index = fm.mesh.geometry.input_global_indices
        np.testing.assert_array_equal(fm.mesh.geometry.x[:, :d], level.x[index])


def test_refined_msh_files_are_reproducible(hertz_levels, tmp_path):
    """Meshing the .geo again and refining gives byte-identical files (the run cache keys
    a level by its content)."""
    paths, _ = hertz_levels
    again, _ = refine_file(MPI.COMM_WORLD, HERTZ_GEO, 2, 8.0, 2, tmp_path)
    for a, b in zip(paths, again, strict=True):
        assert a.read_bytes() == b.read_bytes()


def test_refine_refuses_facets_off_the_cells():
    level = MeshLevel(np.array([[0.0, 0], [1, 0], [0, 1], [1, 1]]), np.array([[0, 1, 2]]),
                      np.array([1]), np.array([[1, 3]]), np.array([2]))
    from vpcontact.meshes import MeshFileError
    with pytest.raises(MeshFileError, match="tagged facet"):
        refine(level)


def test_level_norms_and_sampling_match_dolfinx(hertz_levels, tmp_path):
    """On a refined level read by a run: the sampler puts every value at its level index,
    and the level's norms equal the problem's own ||u||_V and ||sigma||_Q."""
    from vpcontact.case import validate
    from vpcontact.model.problem import ContactProblem
    from vpcontact.studies.nested import LevelSampler, NestedLevel, row_positions

    paths, levels = hertz_levels
    raw = yaml.safe_load((ROOT / "cases" / "hertz_cylinder.yaml").read_text())
    raw["mesh"] = {"file": str(paths[1]), "dim": 2}
    case = validate(raw, str(tmp_path / "case.yaml"))
    fm = load_mesh_file(MPI.COMM_WORLD, paths[1], 2)
    p = ContactProblem(case, fm)
    rng = np.random.default_rng(8)
    p.u.x.array[:] = rng.normal(size=p.u.x.array.size)
    p.update_sigma()
    level = NestedLevel(1, paths[1], 0.1, levels)
    snap = LevelSampler(p, level).sample(p, None)
    assert level.strain_norm(snap["u"]) == pytest.approx(norm(p, "V"), rel=1e-12)
    assert level.cell_l2_norm(snap["sigma"]) == pytest.approx(norm(p, "Q"), rel=1e-12)
    xv = p.disc.V.tabulate_dof_coordinates()[:, :2]
    nv = p.disc.V.dofmap.index_map.size_local
    where = {tuple(np.round(x, 12)): i for i, x in enumerate(levels[1].x)}
    order = [where[tuple(np.round(x, 12))] for x in xv[:nv]]
    np.testing.assert_array_equal(snap["u"][order], p.u.x.array.reshape(-1, 2)[:nv])
    np.testing.assert_array_equal(row_positions(np.array([[1, 2, 3], [4, 5, 6]]),
                                                np.array([[6, 4, 5], [3, 1, 2]])), [1, 0])
    with pytest.raises(ValueError, match="not in the reference"):
        row_positions(np.array([[1, 2, 3]]), np.array([[1, 2, 4]]))
