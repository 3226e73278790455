"""The user's gmsh files: every refusal, groups and tags, .geo sizes, the shipped .geo files,
the rotated test meshes, and two ranks agreeing."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from conftest import MPI_ENV, ROOT
from meshtools import rotation_2d, rotation_3d, write_rotated_box, write_rotated_square
from vpcontact.meshes import MeshFileError, build_box, build_rectangle, gmshfile, load_mesh_file

SQUARE = """Point(1) = {0, 0, 0, 0.3}; Point(2) = {1, 0, 0, 0.3};
Point(3) = {1, 1, 0, 0.3}; Point(4) = {0, 1, 0, 0.3};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
"""
GOOD = SQUARE + """Physical Curve("contact", 7) = {1}; Physical Curve(9) = {2, 3};
Physical Surface("body", 3) = {1};
"""
BOX = """SetFactory("OpenCASCADE"); Box(1) = {0, 0, 0, 1, 1, 1}; Mesh.MeshSizeMax = 0.5;
Physical Volume("body") = {1}; Physical Surface("bottom") = {5};
"""


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text if text.endswith("\n") else text + "\n")
    return path


def _gmsh_box(path, generate=3, version=4.1, groups=(("bottom", 1, [5]),), binary=False):
    """A .msh of the unit box, meshed up to dimension ``generate`` (0: not at all)."""
    import gmsh

    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], 10)
        gmsh.model.setPhysicalName(3, 10, "body")
        for name, tag, faces in groups:
            gmsh.model.addPhysicalGroup(2, faces, tag)
            gmsh.model.setPhysicalName(2, tag, name)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.4)
        if generate:
            gmsh.model.mesh.generate(generate)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", int(binary))
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def _load(path, dim=2, size=1.0):
    return load_mesh_file(MPI.COMM_SELF, path, dim, size)


def _vertices(m):
    return m.mesh.topology.index_map(0).size_global


def _measure_body(m):
    return fem.assemble_scalar(fem.form(fem.Constant(m.mesh, 1.0) * ufl.dx))


BAD_GEO = [
    ("nophys.geo", SQUARE, 2, r"no physical group of dimension 2.*add a Physical Surface"),
    ("nobody.geo", SQUARE + 'Physical Curve("bottom") = {1};', 2,
     r"add a Physical Surface for the body"),
    ("syntax.geo", SQUARE + "Foo bar;", 2, r"gmsh cannot read .*line 5: Unknown variable"),
    ("quads.geo", GOOD + "Recombine Surface{1};", 2,
     r"'body'\) has Quadrilateral 4 elements; vpcontact needs linear triangles"),
    ("order2.geo", GOOD + "Mesh.ElementOrder = 2;", 2,
     r"'body'\) has Triangle 6 elements; vpcontact needs linear triangles"),
    ("order2box.geo", BOX + "Mesh.ElementOrder = 2;", 3,
     r"'body'\) has Tetrahedron 10 elements; vpcontact needs linear tetrahedra"),
    ("share.geo", SQUARE + 'Physical Curve("a") = {1}; Physical Curve("b") = {1, 2};'
     'Physical Surface("body") = {1};', 2,
     r"Physical Curve 1 \('a'\) and Physical Curve 2 \('b'\) share elements"),
    ("tilted.geo", SQUARE.replace("{1, 0, 0,", "{1, 0, 0.5,").replace("{1, 1, 0,", "{1, 1, 0.5,")
     + 'Physical Surface("body") = {1};', 2, r"not planar \(z from 0 to 0.5\).*plane z = 0"),
    ("raised.geo", SQUARE.replace(", 0, 0.3}", ", 1.5, 0.3}") + 'Physical Surface("body") = {1};',
     2, r"the 2D mesh lies in the plane z = 1\.5, not z = 0; move it to z = 0"),
    ("box.geo", BOX, 2, r"the geometry is 3D .*set mesh.dim: 3"),
    ("square.geo", GOOD, 3, r"holds no 3D elements .*set mesh.dim: 2"),
    ("points.geo", "Point(1) = {0, 0, 0, 1}; Physical Point(1) = {1};", 2,
     r"holds no 2D elements \(it is a 0D mesh\)"),
]


@pytest.mark.parametrize("name, text, dim, message", BAD_GEO, ids=[b[0] for b in BAD_GEO])
def test_bad_geo_is_refused(tmp_path, name, text, dim, message):
    with pytest.raises(MeshFileError, match=message) as err:
        _load(_write(tmp_path, name, text), dim)
    assert "\n" not in str(err.value)


def test_unterminated_last_line_is_refused(tmp_path):
    """gmsh 4.8 drops the second statement of an unterminated last line: refused, not lost."""
    path = tmp_path / "last.geo"
    path.write_text(GOOD.replace('Physical Curve("contact", 7) = {1}; Physical Curve(9) = '
                                 '{2, 3};\n', "") + 'Physical Curve("contact", 7) = {1}; '
                    'Physical Curve(9) = {2, 3};')
    with pytest.raises(MeshFileError, match=r"last line has no line break.*end the file with"):
        _load(path)
    path.write_text(path.read_text() + "\n")
    assert _load(path).tags == (7, 9)


def test_bad_paths_are_refused(tmp_path, monkeypatch):
    with pytest.raises(MeshFileError, match=r"none\.msh: no such file"):
        _load(tmp_path / "none.msh")
    (tmp_path / "dir.msh").mkdir()
    with pytest.raises(MeshFileError, match=r"dir\.msh is not a file"):
        _load(tmp_path / "dir.msh")
    with pytest.raises(MeshFileError, match=r"unknown suffix '\.stl'.*\.msh.*\.geo"):
        _load(_write(tmp_path, "part.stl", "solid x\n"))
    with pytest.raises(MeshFileError, match=r"gmsh cannot read .*garbage\.msh: "):
        _load(_write(tmp_path, "garbage.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
                                              "$Nodes\n1 2 3\n"))

    def unreadable(*args, **kwargs):
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr(gmshfile, "open", unreadable, raising=False)
    with pytest.raises(MeshFileError, match=r"cannot read .*: Permission denied; check its"):
        _load(_write(tmp_path, "locked.geo", GOOD))


def test_bad_msh_is_refused(tmp_path):
    with pytest.raises(MeshFileError, match=r"no mesh elements \(save a \.msh after meshing"):
        _load(_gmsh_box(tmp_path / "unmeshed.msh", generate=0), 3)
    with pytest.raises(MeshFileError, match=r"holds a 3D mesh \(Tetrahedron 4\).*mesh.dim: 3"):
        _load(_gmsh_box(tmp_path / "box.msh"), 2)
    surf = _gmsh_box(tmp_path / "surface.msh", generate=2)
    with pytest.raises(MeshFileError, match=r"volumes have no elements.*mesh them in 3D"):
        _load(surf, 3)
    with pytest.raises(MeshFileError, match=r"Physical Volume 10 \('body'\) holds volume 1, "
                                            r"which has no elements"):
        _load(surf, 2)
    # gmsh keeps one name per group, but a .msh written by hand can name two groups alike
    twice = _gmsh_box(tmp_path / "twice.msh", groups=(("a", 1, [5]), ("b", 2, [6])))
    twice.write_text(twice.read_text().replace('2 2 "b"', '2 2 "a"'))
    with pytest.raises(MeshFileError, match=r"two Physical Surfaces are named 'a' \(tags 1 "
                                            r"and 2\); rename one"):
        _load(twice, 3)
    with pytest.raises(ValueError, match="dim must be 2 or 3"):
        _load(twice, 1)


def test_groups_and_tags(tmp_path):
    m = _load(_write(tmp_path, "good.geo", GOOD))
    assert m.groups == {"contact": 7} and m.tags == (7, 9) and m.dim == 2
    assert sorted(set(m.facet_tags.values)) == [7, 9]
    assert set(m.cell_tags.values) == {3}
    assert (m.structured, m.n, m.diagonal, m.normal) == (False, None, None, None)
    np.testing.assert_array_equal(m.bbox[0], [0, 0])
    np.testing.assert_array_equal(m.bbox[1], [1, 1])
    assert (m.L1, m.L2, m.L3) == (1.0, 1.0, 0.0)
    assert 0 < m.h_min <= m.h < 0.6
    # the facets of each group lie where the .geo put them, all their length is there
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)
    one = fem.Constant(m.mesh, 1.0)
    assert fem.assemble_scalar(fem.form(one * ds(7))) == pytest.approx(1.0)
    assert fem.assemble_scalar(fem.form(one * ds(9))) == pytest.approx(2.0)


@pytest.mark.parametrize("version, binary", [(2.2, False), (2.2, True), (4.1, True)])
def test_msh_formats(tmp_path, version, binary):
    """The formats the docs name (MSH_FORMATS in tests/unit/test_doc_facts.py): 4.1 and
    2.2, ASCII and binary, load as the same mesh as 4.1 ASCII."""
    a = _load(_gmsh_box(tmp_path / "box41.msh"), 3)
    b = _load(_gmsh_box(tmp_path / "other.msh", version=version, binary=binary), 3)
    assert a.groups == b.groups == {"bottom": 1}
    assert _vertices(a) == _vertices(b) > 8


def test_sparse_node_tags(tmp_path):
    """A .msh whose node tags are not 1..N (dolfinx's reader needs them so): renumbered."""
    import gmsh

    path = tmp_path / "sparse.msh"
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.addDiscreteEntity(2, 1)
        gmsh.model.mesh.addNodes(2, 1, [10, 20, 30, 40],
                                 [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0])
        gmsh.model.mesh.addElementsByType(1, 2, [], [10, 20, 30, 10, 30, 40])
        gmsh.model.addPhysicalGroup(2, [1], 5)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    assert "\n40\n" in path.read_text()
    m = _load(path)
    assert _vertices(m) == 4 and m.mesh.topology.index_map(2).size_global == 2
    assert m.tags == () and m.groups == {}
    assert _measure_body(m) == pytest.approx(1.0)


def test_geo_size_scales_the_mesh(tmp_path):
    path = _write(tmp_path, "good.geo", GOOD)
    coarse, fine = _load(path, size=1.0), _load(path, size=0.5)
    assert _vertices(fine) > 2 * _vertices(coarse)
    assert fine.h < coarse.h
    with pytest.raises(ValueError, match="size must be > 0"):
        _load(path, size=0.0)


SHIPPED = {
    # file: dim, groups, measure of each group, body measure, vertex range at size 1
    "hertz_cylinder.geo": (2, {"arc": np.pi / 2, "top": 1.0, "sym": 1.0}, np.pi / 4,
                           (1000, 3000)),
    "punch_relaxation.geo": (2, {"base": 0.4 + np.pi * 0.1 / 2, "top": 0.5, "sym": 0.5,
                                 "side": 0.4}, 0.25 - (1 - np.pi / 4) * 0.01, (3000, 6000)),
    "sphere3d.geo": (3, {"surface": np.pi / 2, "top": np.pi / 4, "symx": np.pi / 4,
                         "symy": np.pi / 4}, np.pi / 6, (1000, 15000)),
}


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_geo_files(name):
    dim, measures, body, (lo, hi) = SHIPPED[name]
    m = _load(ROOT / "cases" / name, dim)
    assert set(m.groups) == set(measures) and m.tags == tuple(sorted(m.groups.values()))
    assert lo <= _vertices(m) <= hi
    ds = ufl.Measure("ds", domain=m.mesh, subdomain_data=m.facet_tags)
    one = fem.Constant(m.mesh, 1.0)
    rel = 1e-3 if dim == 2 else 1e-2       # polygonal / polyhedral approximations of arcs
    for group, value in measures.items():
        got = fem.assemble_scalar(fem.form(one * ds(m.groups[group])))
        assert got == pytest.approx(value, rel=rel), group
    assert fem.assemble_scalar(fem.form(one * ufl.dx)) == pytest.approx(body, rel=rel)
    # every exterior facet is in a group
    assert fem.assemble_scalar(fem.form(one * ds)) == pytest.approx(
        sum(fem.assemble_scalar(fem.form(one * ds(t))) for t in m.tags), rel=1e-12)


def _cells(msh):
    tdim = msh.topology.dim
    x = msh.geometry.x
    n = msh.topology.index_map(tdim).size_local
    cells = msh.geometry.dofmap.array.reshape(-1, tdim + 1)[:n]
    return x[cells]


def _cell_set(points):
    return sorted(tuple(sorted(map(tuple, np.round(c, 9) + 0.0))) for c in points)


@pytest.mark.parametrize("diagonal", ["right", "left"])
def test_rotated_square_rotated_back_is_the_built_in_mesh(tmp_path, diagonal):
    path = write_rotated_square(tmp_path / "square.msh", 5, 30.0, diagonal)
    m = _load(path)
    R = rotation_2d(30.0)
    back = _cells(m.mesh)[:, :, :2] @ R          # R^T x, row-wise
    ref = build_rectangle(MPI.COMM_SELF, n=5, diagonal=diagonal)
    assert np.abs(np.sort(back.reshape(-1, 2), axis=0)
                  - np.sort(_cells(ref.mesh)[:, :, :2].reshape(-1, 2), axis=0)).max() < 1e-14
    assert _cell_set(back) == _cell_set(_cells(ref.mesh)[:, :, :2])
    assert m.groups == ref.groups
    _check_sides(m, R, {"left": (0, 0.0), "right": (0, 1.0), "bottom": (1, 0.0),
                        "top": (1, 1.0)}, 5)


def test_rotated_box_rotated_back_is_the_built_in_mesh(tmp_path):
    path = write_rotated_box(tmp_path / "box.msh", 3, (30.0, 20.0))
    m = _load(path, 3)
    R = rotation_3d((30.0, 20.0))
    back = _cells(m.mesh) @ R
    ref = build_box(MPI.COMM_SELF, n=3)
    assert _cell_set(back) == _cell_set(_cells(ref.mesh))
    assert m.groups == ref.groups
    _check_sides(m, R, {"left": (0, 0.0), "right": (0, 1.0), "front": (1, 0.0),
                        "back": (1, 1.0), "bottom": (2, 0.0), "top": (2, 1.0)}, 3)


def _check_sides(m, R, sides, n):
    """Each named group's facets, rotated back, lie on their side; n^(dim-1) squares each."""
    msh, ft, d = m.mesh, m.facet_tags, m.dim
    msh.topology.create_connectivity(d - 1, 0)
    f2v = msh.topology.connectivity(d - 1, 0)
    x = msh.geometry.x[:, :d] @ R
    for name, (axis, value) in sides.items():
        facets = ft.indices[ft.values == m.groups[name]]
        assert len(facets) == (n if d == 2 else 2 * n * n), name
        pts = x[np.concatenate([f2v.links(f) for f in facets])]
        np.testing.assert_allclose(pts[:, axis], value, atol=1e-14)


TWO_RANKS = """
import json, pathlib, sys
from mpi4py import MPI
from vpcontact.meshes import MeshFileError, load_mesh_file
comm = MPI.COMM_WORLD
m = load_mesh_file(comm, sys.argv[1], int(sys.argv[2]))
try:
    load_mesh_file(comm, sys.argv[3], 2)
    bad = None
except MeshFileError as err:
    bad = str(err)
out = pathlib.Path(sys.argv[4]) / f"rank{comm.rank}.json"
out.write_text(json.dumps({"rank": comm.rank,
                           "vertices": m.mesh.topology.index_map(0).size_global,
                           "local": m.mesh.topology.index_map(0).size_local,
                           "groups": m.groups,
                           "tags": list(m.tags), "h": m.h, "h_min": m.h_min, "bad": bad,
                           "bbox": [list(m.bbox[0]), list(m.bbox[1])]}))
"""


@pytest.mark.mpi
@pytest.mark.parametrize("name, dim", [("hertz_cylinder.geo", 2), ("sphere3d.geo", 3)])
def test_two_ranks(tmp_path, name, dim):
    """Both ranks see the same mesh and groups; a bad file raises on both (no hang)."""
    bad = _write(tmp_path, "nobody.geo", SQUARE)
    cmd = ["mpirun", "-n", "2", sys.executable, "-c", TWO_RANKS, str(ROOT / "cases" / name),
           str(dim), str(bad), str(tmp_path)]
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = [json.loads((tmp_path / f"rank{r}.json").read_text()) for r in (0, 1)]
    assert sorted(o["rank"] for o in out) == [0, 1]
    serial = _load(ROOT / "cases" / name, dim)
    for o in out:
        assert o["vertices"] == _vertices(serial) and o["groups"] == serial.groups
        assert o["tags"] == list(serial.tags)
        assert (o["h"], o["h_min"]) == pytest.approx((serial.h, serial.h_min), rel=1e-14)
        np.testing.assert_allclose(o["bbox"], [serial.bbox[0], serial.bbox[1]], atol=1e-14)
        assert "add a Physical Surface for the body" in o["bad"]
    assert all(o["local"] < _vertices(serial) for o in out)     # really distributed
