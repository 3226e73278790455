"""The rigid-motion check part by part: a body in disconnected pieces (cells connected through
shared vertices) needs enough prescribed displacements on every piece; one line naming the
piece (its cells and a point in it), before any computation, serially and on two ranks."""
import subprocess
import sys

import numpy as np
import pytest
import yaml
from dolfinx import fem
from mpi4py import MPI

from conftest import MPI_ENV, ROOT, run_cli, validate_raw
from vpcontact.case import CaseError
from vpcontact.meshes import build_box, build_rectangle
from vpcontact.model.dirichlet import body_parts
from vpcontact.model.problem import ContactProblem
from vpcontact.simulation import build_mesh

TWO_SQUARES = """lc = 0.5;
Point(1) = {0, 0, 0, lc}; Point(2) = {1, 0, 0, lc}; Point(3) = {1, 1, 0, lc};
Point(4) = {0, 1, 0, lc}; Point(5) = {2, 0, 0, lc}; Point(6) = {3, 0, 0, lc};
Point(7) = {3, 1, 0, lc}; Point(8) = {2, 1, 0, lc};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Line(5) = {5, 6}; Line(6) = {6, 7}; Line(7) = {7, 8}; Line(8) = {8, 5};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Curve Loop(2) = {5, 6, 7, 8}; Plane Surface(2) = {2};
Physical Curve("left") = {4};
Physical Curve("left2") = {8};
Physical Curve("top") = {3, 7};
Physical Surface("body") = {1, 2};
"""
# the second square [1, 2] x [1, 2] touches the first at its corner (1, 1): one part
TOUCHING = """lc = 0.5;
Point(1) = {0, 0, 0, lc}; Point(2) = {1, 0, 0, lc}; Point(3) = {1, 1, 0, lc};
Point(4) = {0, 1, 0, lc}; Point(6) = {2, 1, 0, lc}; Point(7) = {2, 2, 0, lc};
Point(8) = {1, 2, 0, lc};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Line(5) = {3, 6}; Line(6) = {6, 7}; Line(7) = {7, 8}; Line(8) = {8, 3};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Curve Loop(2) = {5, 6, 7, 8}; Plane Surface(2) = {2};
Physical Curve("left") = {4};
Physical Curve("top") = {3, 7};
Physical Surface("body") = {1, 2};
"""


def _raw(geo, clamped, displacement=None) -> dict:
    raw = {"mesh": {"file": str(geo)}, "boundaries": {"clamped": clamped},
           "material": {"E": 1000.0, "nu": 0.3},
           "loads": {"traction": {"top": [0.0, -1.0]}}, "time": {"T": 1.0, "N": 2}}
    if displacement:
        raw["loads"]["displacement"] = displacement
    return raw


@pytest.fixture(scope="module")
def two_squares(tmp_path_factory):
    path = tmp_path_factory.mktemp("parts") / "two.geo"
    path.write_text(TWO_SQUARES)
    return path


def _problem(raw):
    case = validate_raw(raw)
    return ContactProblem(case, build_mesh(case, MPI.COMM_SELF))


@pytest.mark.parametrize("clamped, part, point", [
    (["left"], 2, "(3, 0)"), (["left2"], 1, "(1, 0.5)"), ([], 1, "(1, 0.5)")],
    ids=["first-held", "second-held", "none-held"])
def test_an_unsupported_part_is_refused(two_squares, clamped, part, point):
    with pytest.raises(CaseError) as err:
        _problem(_raw(two_squares, clamped))
    text = str(err.value)
    assert "boundaries.clamped / loads.displacement: the prescribed displacements leave 3 " \
        f"rigid motion(s) of part {part} of the body's 2 disconnected parts (14 cells, " \
        f"through the point {point}) free" in text, text


def test_a_part_held_by_one_component_is_refused(two_squares):
    """Part 2 with only u_x prescribed on its left side: u_y and the rotation are free."""
    with pytest.raises(CaseError) as err:
        _problem(_raw(two_squares, ["left"], {"left2": [0.0, None]}))
    assert "leave 1 rigid motion(s) of part 2" in str(err.value)
    assert "like translation y" in str(err.value)


def test_both_parts_held_pass(two_squares):
    problem = _problem(_raw(two_squares, ["left", "left2"]))
    parts = body_parts(problem.disc.V)
    assert list(parts.cells) == [14, 14]
    x = problem.disc.V.tabulate_dof_coordinates()[:, 0]
    assert set(parts.label[x < 1.5]) == {0} and set(parts.label[x > 1.5]) == {1}
    np.testing.assert_allclose(parts.lo, [[0, 0], [2, 0]], atol=1e-12)
    np.testing.assert_allclose(parts.hi, [[1, 1], [3, 1]], atol=1e-12)


def test_parts_touching_at_a_vertex_are_one_part(tmp_path):
    """Cells that share only a vertex connect their parts (the check's definition)."""
    geo = tmp_path / "touching.geo"
    geo.write_text(TOUCHING)
    problem = _problem(_raw(geo, ["left"]))
    assert list(body_parts(problem.disc.V).cells) == [28]


@pytest.mark.parametrize("build, cells", [
    (lambda: build_rectangle(MPI.COMM_SELF, 2.0, 1.0, n=4), 32),
    (lambda: build_box(MPI.COMM_SELF, 1.0, 1.0, 1.0, n=2), 48)], ids=["2d", "3d"])
def test_a_connected_body_is_one_part(build, cells):
    V = fem.VectorFunctionSpace(build().mesh, ("CG", 1))
    parts = body_parts(V)
    assert list(parts.cells) == [cells] and np.all(parts.label == 0)


BODY_PARTS_SCRIPT = """
import json, sys
from mpi4py import MPI
from dolfinx import fem
from vpcontact.meshes import build_rectangle
from vpcontact.model.dirichlet import body_parts
V = fem.VectorFunctionSpace(build_rectangle(MPI.COMM_WORLD, 1.0, 1.0, n=8).mesh, ("CG", 1))
p = body_parts(V)
with open(f"{sys.argv[1]}.{MPI.COMM_WORLD.rank}", "w") as fh:
    json.dump({"cells": p.cells.tolist(), "labels": sorted(set(p.label.tolist()))}, fh)
"""


@pytest.mark.mpi
def test_a_connected_body_is_one_part_on_two_ranks(tmp_path):
    """The parts of the ranks are merged through the shared nodes (each rank writes its own
    file: no parsing of mpirun's merged output)."""
    out = tmp_path / "parts"
    subprocess.run(["mpirun", "-n", "2", sys.executable, "-c", BODY_PARTS_SCRIPT, str(out)],
                   cwd=ROOT, env={**MPI_ENV, **_env()}, check=True, timeout=300)
    for rank in (0, 1):
        found = yaml.safe_load((tmp_path / f"parts.{rank}").read_text())
        assert found == {"cells": [128], "labels": [0]}


def _env():
    import os
    return {**os.environ, "PYTHONPATH": str(ROOT)}


@pytest.mark.mpi
def test_two_ranks_refuse_the_unsupported_part(two_squares, tmp_path):
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(_raw(two_squares, ["left"])))
    proc = run_cli(["run", path, "--out", tmp_path / "out"], nprocs=2, timeout=300)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "Traceback" not in proc.stdout + proc.stderr
    assert "internal error" not in proc.stdout + proc.stderr
    assert "of the body's 2 disconnected parts (14 cells, through the point (3, 0)) free" \
        in proc.stderr
    assert not (tmp_path / "out").exists()


TWO_BOXES = """SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Box(2) = {2, 0, 0, 1, 1, 1};
Mesh.MeshSizeMax = 0.6;
Physical Surface("left") = {1};
Physical Surface("left2") = {7};
Physical Volume("body") = {1, 2};
"""


def test_a_3d_body_in_two_parts(tmp_path):
    geo = tmp_path / "boxes.geo"
    geo.write_text(TWO_BOXES)
    raw = _raw(geo, ["left"])
    raw["loads"] = {"f0": [0.0, 0.0, -1.0]}
    with pytest.raises(CaseError) as err:
        _problem(raw)
    assert "leave 6 rigid motion(s) of part 2 of the body's 2 disconnected parts (" \
        in str(err.value), err.value
    raw["boundaries"]["clamped"] = ["left", "left2"]
    problem = _problem(raw)
    parts = body_parts(problem.disc.V)
    assert len(parts.cells) == 2 and parts.cells.sum() == problem.disc.num_cells
    np.testing.assert_allclose(parts.lo, [[0, 0, 0], [2, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(parts.hi, [[1, 1, 1], [3, 1, 1]], atol=1e-12)
