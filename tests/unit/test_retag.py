"""meshes/retag.py: the physical groups of a gmsh mesh on a locally refined copy, checked
against the geometry of cases/bimaterial_punch.geo (foot y < 0.25, cap above; base y = 0 and
the fillet; sym x = 0; top y = 0.5; side x = 0.5) and against measures the refinement keeps
(each group's area or length), not against the lookup itself."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT
from vpcontact.meshes import load_mesh_file
from vpcontact.meshes.adapt import refine_cells
from vpcontact.meshes.retag import entity_points, in_simplices

NAMES = {"foot": 10, "cap": 11, "base": 1, "top": 2, "sym": 3, "side": 4}


def _measure(msh, tags, dim):
    """Per tag, the sum of the entities' areas (dim 2) or lengths (dim 1)."""
    pts = entity_points(msh, dim, tags.indices)
    e1, e2 = pts[:, 1] - pts[:, 0], pts[:, -1] - pts[:, 0]
    size = np.abs(np.cross(e1, e2)) / 2 if dim == 2 else np.linalg.norm(e1, axis=1)
    return {int(t): float(size[tags.values == t].sum()) for t in np.unique(tags.values)}


def _refined():
    body = load_mesh_file(MPI.COMM_SELF, ROOT / "cases" / "bimaterial_punch.geo", 2, 4.0)
    mid = entity_points(body.mesh, 2, np.arange(body.mesh.topology.index_map(2).size_local,
                                                dtype=np.int32)).mean(axis=1)
    # the cells near the interface and the right half: both materials, base, side, fillet
    marked = np.flatnonzero((np.abs(mid[:, 1] - 0.25) < 0.1) | (mid[:, 0] > 0.3))
    return body, refine_cells(body, marked.astype(np.int32))


def test_refined_cells_keep_their_material():
    """Every refined cell is tagged foot below y = 0.25 and cap above, the areas of the two
    materials are those of the mesh refined, and there are more cells than before."""
    body, fine = _refined()
    ct = fine.cell_tags
    ncell = fine.mesh.topology.index_map(2).size_local
    assert np.array_equal(np.sort(ct.indices), np.arange(ncell))
    assert ncell > 1.3 * body.mesh.topology.index_map(2).size_local
    y = entity_points(fine.mesh, 2, ct.indices).mean(axis=1)[:, 1]
    assert np.array_equal(ct.values == NAMES["foot"], y < 0.25)
    before, after = _measure(body.mesh, body.cell_tags, 2), _measure(fine.mesh, ct, 2)
    assert before.keys() == after.keys() == {10, 11}
    for t in before:
        assert after[t] == pytest.approx(before[t], rel=1e-12)
    assert fine.cell_groups == body.cell_groups


def test_refined_facets_keep_their_group():
    """Each group's facets lie on its lines (sym x = 0, top y = 0.5, side x = 0.5, base y = 0
    or the fillet's chords), each group keeps its length, every boundary facet of the refined
    mesh is in a group, and the split facets are more than the mesh read had."""
    body, fine = _refined()
    ft = fine.facet_tags
    pts = entity_points(fine.mesh, 1, ft.indices)
    for name, axis, value in (("sym", 0, 0.0), ("top", 1, 0.5), ("side", 0, 0.5)):
        sel = ft.values == NAMES[name]
        assert sel.any() and np.allclose(pts[sel][:, :, axis], value, atol=1e-12), name
    base = pts[ft.values == NAMES["base"]]
    flat = np.all(np.abs(base[:, :, 1]) < 1e-12, axis=1)
    assert flat.any() and (~flat).any()              # the bottom and the fillet
    before, after = _measure(body.mesh, body.facet_tags, 1), _measure(fine.mesh, ft, 1)
    assert before.keys() == after.keys()
    for t in before:
        assert after[t] == pytest.approx(before[t], rel=1e-12)
    assert len(ft.indices) > len(body.facet_tags.indices)
    fine.mesh.topology.create_connectivity(1, 2)
    f2c = fine.mesh.topology.connectivity(1, 2)
    exterior = [f for f in range(fine.mesh.topology.index_map(1).size_local)
                if len(f2c.links(f)) == 1]
    assert set(exterior) <= set(ft.indices.tolist())


def test_in_simplices_against_hand_cases():
    """Points on, beside and beyond a segment and a triangle."""
    seg = np.array([[[0.0, 0.0], [2.0, 0.0]]] * 3)
    pts = np.array([[[0.5, 0.0], [2.0, 0.0]], [[0.5, 1e-6], [1.0, 0.0]],
                    [[1.0, 0.0], [2.1, 0.0]]])
    assert in_simplices(pts, seg).tolist() == [True, False, False]
    tri = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]] * 2)
    pts = np.array([[[0.5, 0.5, 1.0], [0.1, 0.2, 1.0]], [[0.6, 0.6, 1.0], [0.1, 0.2, 1.0]]])
    assert in_simplices(pts, tri).tolist() == [True, False]
    tet = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]] * 2)
    pts = np.array([[[0.2, 0.2, 0.2], [0.0, 0.0, 1.0]], [[0.2, 0.2, 0.2], [0.4, 0.4, 0.4]]])
    assert in_simplices(pts, tet).tolist() == [True, False]


def _simplex_measure(pts):
    """Lengths, areas or volumes of simplices (n, m, gdim), any m <= gdim + 1."""
    e = pts[:, 1:] - pts[:, :1]
    return np.sqrt(np.abs(np.linalg.det(e @ np.transpose(e, (0, 2, 1))))) / np.prod(
        np.arange(1, e.shape[1] + 1))


def test_3d_groups_keep_their_measure():
    """cases/sphere3d.geo refined in its lower half: every facet group keeps its area and every
    cell group its volume (a facet or cell missed or mistagged would change them), and the
    refined mesh has more tagged facets."""
    body = load_mesh_file(MPI.COMM_SELF, ROOT / "cases" / "sphere3d.geo", 3, 4.0)
    n = body.mesh.topology.index_map(3).size_local
    mid = entity_points(body.mesh, 3, np.arange(n, dtype=np.int32)).mean(axis=1)
    fine = refine_cells(body, np.flatnonzero(mid[:, 2] < np.median(mid[:, 2])).astype(np.int32))
    assert fine.mesh.topology.index_map(3).size_local > 1.5 * n
    for d, a, b in ((2, body.facet_tags, fine.facet_tags), (3, body.cell_tags, fine.cell_tags)):
        ma = _simplex_measure(entity_points(body.mesh, d, a.indices))
        mb = _simplex_measure(entity_points(fine.mesh, d, b.indices))
        assert set(a.values) == set(b.values)
        for t in set(a.values):
            assert mb[b.values == t].sum() == pytest.approx(ma[a.values == t].sum(), rel=1e-12)
    assert len(fine.facet_tags.indices) > len(body.facet_tags.indices)
