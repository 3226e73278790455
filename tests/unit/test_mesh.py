"""The built-in rectangle and box: boundary tags and named groups, diagonal direction, both
engines, nesting, unstructured meshes."""
import inspect

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from vpcontact.meshes import BOUNDARY_TAGS, SIDES, build_box, build_rectangle


def _cells(rect):
    x = rect.mesh.geometry.x[:, :2]
    dm = rect.mesh.geometry.dofmap
    n = rect.mesh.topology.index_map(2).size_local
    return np.array([x[dm.links(c)] for c in range(n)])


@pytest.mark.parametrize("engine", ["dolfinx", "gmsh"])
@pytest.mark.parametrize("diagonal", ["right", "left"])
def test_structured_diagonal(diagonal, engine):
    rect = build_rectangle(MPI.COMM_SELF, 2.0, 1.0, n=4, diagonal=diagonal, engine=engine)
    cells = _cells(rect)
    assert len(cells) == 2 * 4 * 4
    hx, hy = 0.5, 0.25
    for tri in cells:
        lo = tri.min(axis=0)
        corners = {tuple(np.round((p - lo) / (hx, hy)).astype(int)) for p in tri}
        # "right": the diagonal joins (x0,y0)-(x1,y1); "left": (x0,y1)-(x1,y0)
        diag = {(0, 0), (1, 1)} if diagonal == "right" else {(0, 1), (1, 0)}
        assert diag <= corners, (diagonal, tri)


@pytest.mark.parametrize("engine", ["dolfinx", "gmsh"])
def test_boundary_tags(engine):
    rect = build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=8, engine=engine)
    ft = rect.facet_tags
    msh = rect.mesh
    msh.topology.create_connectivity(1, 0)
    f2v = msh.topology.connectivity(1, 0)
    x = msh.geometry.x
    for name in SIDES[2]:
        facets = ft.indices[ft.values == BOUNDARY_TAGS[name]]
        assert len(facets) == 8, name
        pts = np.array([x[f2v.links(f)] for f in facets]).reshape(-1, 3)
        sides = {"left": (0, 0.0), "right": (0, 1.0), "bottom": (1, 0.0), "top": (1, 1.0)}
        coord, val = sides[name]
        np.testing.assert_allclose(pts[:, coord], val, atol=1e-12)


@pytest.mark.parametrize("diagonal", ["right", "left"])
def test_engines_build_the_same_triangulation(diagonal):
    """dolfinx's create_rectangle and gmsh's transfinite mesh: the same set of triangles."""
    def key(rect):
        return sorted(tuple(sorted(map(tuple, np.round(c, 9)))) for c in _cells(rect))
    a = build_rectangle(MPI.COMM_SELF, 2.0, 1.0, n=6, diagonal=diagonal, engine="dolfinx")
    b = build_rectangle(MPI.COMM_SELF, 2.0, 1.0, n=6, diagonal=diagonal, engine="gmsh")
    assert key(a) == key(b)


def test_gmsh_is_the_default_engine_and_its_vertices_are_exact():
    """gmsh builds by default; its transfinite vertices are put on the grid (L / n) i, so both
    engines give bitwise the same coordinates."""
    for build in (build_rectangle, build_box):
        assert inspect.signature(build).parameters["engine"].default == "gmsh"
    a = build_rectangle(MPI.COMM_SELF, 2.0, 0.7, n=6, engine="dolfinx").mesh.geometry.x
    b = build_rectangle(MPI.COMM_SELF, 2.0, 0.7, n=6).mesh.geometry.x
    assert len(a) == len(b) == 49
    np.testing.assert_array_equal(np.unique(a, axis=0), np.unique(b, axis=0))


def _measure(m, tag=None):
    one = fem.Constant(m.mesh, 1.0)
    if tag is None:
        return fem.assemble_scalar(fem.form(one * ufl.dx))
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)
    return fem.assemble_scalar(fem.form(one * ds(tag)))


def test_box_engines():
    """dolfinx's create_box and gmsh's transfinite box: the same vertices (bitwise), cell
    count, volume and face areas per tag (the tetrahedra themselves may differ)."""
    L = (2.0, 1.0, 0.5)
    a = build_box(MPI.COMM_SELF, *L, n=3, engine="dolfinx")
    b = build_box(MPI.COMM_SELF, *L, n=3, engine="gmsh")
    xa, xb = a.mesh.geometry.x, b.mesh.geometry.x
    np.testing.assert_array_equal(np.unique(xa, axis=0), np.unique(xb, axis=0))
    for m in (a, b):
        assert m.mesh.topology.index_map(3).size_local == 6 * 27
        assert _measure(m) == pytest.approx(1.0, rel=1e-13)
    areas = {"left": 0.5, "right": 0.5, "front": 1.0, "back": 1.0, "bottom": 2.0, "top": 2.0}
    for name, area in areas.items():
        for m in (a, b):
            assert _measure(m, m.groups[name]) == pytest.approx(area, rel=1e-13), name
    with pytest.raises(ValueError, match="engine"):
        build_box(MPI.COMM_SELF, n=2, engine="cgal")


def test_groups_sizes_and_bounding_box():
    rect = build_rectangle(MPI.COMM_SELF, 2.0, 1.0, n=4)
    assert rect.groups == {"left": 1, "bottom": 2, "right": 3, "top": 4}
    assert rect.tags == (1, 2, 3, 4) and rect.L3 == 0.0
    assert rect.h == 0.5 and rect.h_min == pytest.approx(np.hypot(0.5, 0.25))
    np.testing.assert_array_equal(rect.bbox[0], [0.0, 0.0])
    np.testing.assert_array_equal(rect.bbox[1], [2.0, 1.0])
    box = build_box(MPI.COMM_SELF, 2.0, 1.0, 0.5, h=0.3)
    assert box.groups == {"left": 1, "bottom": 2, "right": 3, "top": 4, "front": 5, "back": 6}
    assert box.tags == (1, 2, 3, 4, 5, 6) and (box.L1, box.L2, box.L3) == (2.0, 1.0, 0.5)
    assert 0 < box.h_min < 0.3
    np.testing.assert_allclose(box.bbox[0], [0.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(box.bbox[1], [2.0, 1.0, 0.5], rtol=1e-15)


def test_refined_structured_mesh_is_nested():
    """Every fine cell lies inside one coarse cell (barycentric coordinates in [0, 1])."""
    coarse = _cells(build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=4))
    fine = _cells(build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=8))
    for tri in fine:
        inside = False
        for c in coarse:
            T = np.column_stack([c[1] - c[0], c[2] - c[0]])
            lam = np.linalg.solve(T, (tri - c[0]).T)
            bary = np.vstack([1 - lam.sum(axis=0), lam])
            if np.all(bary > -1e-9):
                inside = True
                break
        assert inside


def test_unstructured_mesh():
    rect = build_rectangle(MPI.COMM_SELF, 1.0, 1.0, h=0.1)
    assert not rect.structured and rect.h == 0.1
    ncell = rect.mesh.topology.index_map(2).size_local
    assert 150 < ncell < 600
    ft = rect.facet_tags
    assert set(np.unique(ft.values)) == {BOUNDARY_TAGS[s] for s in SIDES[2]}


def test_bad_arguments():
    with pytest.raises(ValueError, match="exactly one"):
        build_rectangle(MPI.COMM_SELF, 1.0, 1.0)
    with pytest.raises(ValueError, match="diagonal"):
        build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=2, diagonal="up")
    with pytest.raises(ValueError, match="engine"):
        build_rectangle(MPI.COMM_SELF, 1.0, 1.0, n=2, engine="cgal")


@pytest.mark.parametrize("size", [{"n": 3}, {"h": 0.4}, {"n": 3, "engine": "dolfinx"}])
def test_box_faces(size):
    box = build_box(MPI.COMM_SELF, 2.0, 1.0, 0.5, **size)
    assert box.dim == 3 and box.normal == (0.0, 0.0, -1.0)
    msh, ft = box.mesh, box.facet_tags
    msh.topology.create_connectivity(2, 0)
    f2v = msh.topology.connectivity(2, 0)
    x = msh.geometry.x
    where = {"left": (0, 0.0), "right": (0, 2.0), "front": (1, 0.0), "back": (1, 1.0),
             "bottom": (2, 0.0), "top": (2, 0.5)}
    for name in SIDES[3]:
        facets = ft.indices[ft.values == BOUNDARY_TAGS[name]]
        assert len(facets) > 0, name
        pts = x[np.concatenate([f2v.links(f) for f in facets])]
        axis, value = where[name]
        np.testing.assert_allclose(pts[:, axis], value, atol=1e-12)
    if "n" in size:
        assert msh.topology.index_map(3).size_local == 6 * 27   # 6 tets per hex
