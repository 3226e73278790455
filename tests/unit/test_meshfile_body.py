"""The body's cells and groups in a gmsh file: degenerate cells are refused
at load naming their vertices (they were blamed on sigma_0), groups off the body are refused
(dolfinx died with a segmentation fault), groups inside the body are recorded, and a .geo's
mesh is bounded in memory."""
import subprocess
import sys

import numpy as np
import pytest
from mpi4py import MPI

from conftest import ROOT
from vpcontact.meshes import MeshFileError, gmshfile, load_mesh_file
from vpcontact.meshes.bodycheck import interior_role

SQUARE = """Point(1) = {0, 0, 0, 0.25}; Point(2) = {1, 0, 0, 0.25};
Point(3) = {1, 1, 0, 0.25}; Point(4) = {0, 1, 0, 0.25};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom", 1) = {1}; Physical Surface("body", 10) = {1};
"""


def _triangles(path, xyz, triangles, dim=2):
    """A .msh of the given triangles (node tags 1..n) in one physical group of dimension 2."""
    import gmsh
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.addDiscreteEntity(2, 1)
        gmsh.model.mesh.addNodes(2, 1, np.arange(1, len(xyz) + 1), np.ravel(xyz))
        gmsh.model.mesh.addElementsByType(1, 2, [], np.ravel(triangles))
        gmsh.model.addPhysicalGroup(2, [1], 5)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


@pytest.mark.parametrize("apex", [(2.0, 0.0), (0.5, 1e-12)], ids=["collinear", "near-zero"])
def test_a_degenerate_cell_is_refused_naming_its_vertices(tmp_path, apex):
    xyz = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (*apex, 0)]
    path = _triangles(tmp_path / "flat.msh", xyz, [[1, 2, 3], [1, 3, 4], [1, 2, 5]])
    with pytest.raises(MeshFileError, match=r"flat\.msh: 1 cell\(s\) have zero area, e\.g\. "
                                            r"the cell with vertices \(0, 0\), \(1, 0\), "
                                            rf"\({apex[0]:g}, {apex[1]:g}\)"):
        load_mesh_file(MPI.COMM_SELF, path, 2)
    good = _triangles(tmp_path / "good.msh", xyz[:4], [[1, 2, 3], [1, 3, 4]])
    assert load_mesh_file(MPI.COMM_SELF, good, 2).mesh.topology.index_map(2).size_global == 2


def test_a_degenerate_tetrahedron_is_refused(tmp_path):
    import gmsh
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    path = tmp_path / "flat3d.msh"
    try:
        gmsh.model.addDiscreteEntity(3, 1)
        xyz = [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 0]
        gmsh.model.mesh.addNodes(3, 1, [1, 2, 3, 4, 5], xyz)
        gmsh.model.mesh.addElementsByType(1, 4, [], [1, 2, 3, 4, 1, 2, 3, 5])
        gmsh.model.addPhysicalGroup(3, [1], 5)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    with pytest.raises(MeshFileError, match=r"1 cell\(s\) have zero volume.*\(1, 1, 0\)"):
        load_mesh_file(MPI.COMM_SELF, path, 3)


def _load_in_child(path, dim):
    """load_mesh_file in a separate process: a segmentation fault must not end pytest."""
    code = ("import sys; from mpi4py import MPI; from vpcontact.meshes import MeshFileError, "
            "load_mesh_file\ntry:\n    load_mesh_file(MPI.COMM_SELF, sys.argv[1], "
            "int(sys.argv[2])); print('LOADED')\nexcept MeshFileError as e:\n    print(e)")
    return subprocess.run([sys.executable, "-c", code, str(path), str(dim)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


def test_a_surface_group_off_the_volume_is_refused(tmp_path):
    """3D: a Physical Surface of a face of a second box that is not in the body."""
    geo = tmp_path / "two.geo"
    geo.write_text('SetFactory("OpenCASCADE"); Box(1) = {0, 0, 0, 1, 1, 1}; '
                   "Box(2) = {2, 0, 0, 1, 1, 1}; Mesh.MeshSizeMax = 0.5;\n"
                   'Physical Volume("body") = {1}; Physical Surface("far") = {7};\n')
    proc = _load_in_child(geo, 3)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Physical Surface 2 ('far') has" in proc.stdout and "outside the body" in proc.stdout


@pytest.mark.parametrize("extra, message", [
    ('Point(9) = {5, 5, 0, 1}; Physical Point("far", 4) = {9};',
     "Physical Point 4 ('far') has 1 of its 1 nodes off the body"),
    ('Point(9) = {0.5, 0, 0, 1}; Physical Point(4) = {9};',       # on a curve, not a vertex
     "Physical Point 4 has 1 of its 1 nodes off the body"),
])
def test_a_point_group_off_the_body_is_refused(tmp_path, extra, message):
    geo = tmp_path / "point.geo"
    geo.write_text(SQUARE + extra + "\n")
    proc = _load_in_child(geo, 2)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert message in proc.stdout, proc.stdout
    geo.write_text(SQUARE + 'Physical Point("corner", 4) = {3};\n')      # on the body
    assert "LOADED" in _load_in_child(geo, 2).stdout


def test_an_embedded_curve_is_a_group_inside_the_body(tmp_path):
    geo = tmp_path / "inner.geo"
    geo.write_text(SQUARE + "Point(5) = {0.3, 0.5, 0, 0.25}; Point(6) = {0.7, 0.5, 0, 0.25}; "
                   'Line(5) = {5, 6};\nCurve{5} In Surface{1};\nPhysical Curve("inner", 7) '
                   "= {5};\n")
    m = load_mesh_file(MPI.COMM_SELF, geo, 2)
    assert m.interior == {7: (2, 2)}
    assert interior_role(m, "loads.traction.inner", "inner", 7).startswith(
        "loads.traction.inner: group 'inner' has 2 of its 2 facets inside the body")
    assert interior_role(m, "boundaries.clamped", "bottom", 1) is None


def test_the_meshing_child_is_bounded_in_memory(tmp_path):
    """~3e7 nodes pass the estimate; 64 MB more than gmsh itself end the child, one line."""
    geo = tmp_path / "fine.geo"
    geo.write_text(SQUARE + "Mesh.MeshSizeMax = 2e-4;\n")
    gmsh = gmshfile.import_gmsh()
    gmsh.initialize(readConfigFiles=False)
    try:
        with pytest.raises(MeshFileError, match=r"gmsh ran out of memory meshing .*fine\.geo "
                                                r"\(limit 0\.1 GB more than gmsh itself\)"):
            gmshfile._mesh_geo(gmsh, str(geo), 2, 1.0, 1e8, memory=64 * 2**20)
    finally:
        gmsh.finalize()


@pytest.mark.parametrize("name, dim", [("hertz_cylinder.geo", 2), ("sphere3d.geo", 3)])
def test_tiny_point_sizes_are_refused_before_gmsh_meshes(name, dim):
    """mesh.size 1e-6 on the shipped .geo files: every point size is tiny, the mesh would
    have ~1e10 nodes (gmsh took all the machine's memory); refused in seconds."""
    import time
    start = time.monotonic()
    with pytest.raises(MeshFileError, match=rf"{name}: its mesh sizes \(about .* on the "
                                            r"curves or less\) ask for about .* nodes "
                                            r"\(limit 1e\+08\)"):
        load_mesh_file(MPI.COMM_SELF, ROOT / "cases" / name, dim, size=1e-6)
    assert time.monotonic() - start < 30


def test_a_msh_larger_than_half_the_memory_is_refused(tmp_path, monkeypatch):
    path = _triangles(tmp_path / "big.msh", [(0, 0, 0), (1, 0, 0), (1, 1, 0)], [[1, 2, 3]])
    monkeypatch.setattr(gmshfile, "_memory_budget", lambda: 100)
    with pytest.raises(MeshFileError, match=r"big\.msh is 0\.0 GB, more than half this "
                                            r"machine's memory .*gmsh could not hold"):
        load_mesh_file(MPI.COMM_SELF, path, 2)


def test_a_long_gmsh_call_is_interruptible():
    """Reading a large .msh runs in a thread: SIGINT reaches the main thread at once (a
    20 GB file was read for 10 minutes with SIGTERM ignored)."""
    import os
    import signal
    import threading
    import time
    release = threading.Event()
    threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        gmshfile._interruptible(release.wait, 30)
    assert time.monotonic() - start < 5
    release.set()
    gmshfile._busy.clear()
    assert gmshfile._interruptible(lambda a, b: a + b, 1, 2) == 3
    with pytest.raises(ValueError, match="x"):
        gmshfile._interruptible(int, "x")
