"""Gamma3 found by the probe of the newer surface: a Gamma3 whose every node is fully
prescribed is a Gamma3 problem of size 0 (the fast solver equals SNES VI there, serially and
under mpirun -n 2; it ended in an internal error), and a contact.direction tangent to Gamma3
or pointing into the body is refused in one line, exit 2 (it ran as "no contact")."""
import json

import pytest

from conftest import run_cli

# a rectangle whose bottom is three curves: the middle one is a single element between two
# clamped curves, so both of its nodes (all of Gamma3) are clamped; the top is loaded
MID_GEO = """lc = 0.1;
Point(1) = {0, 0, 0, lc}; Point(2) = {0.4, 0, 0, lc}; Point(3) = {0.6, 0, 0, lc};
Point(4) = {1, 0, 0, lc}; Point(5) = {1, 0.5, 0, lc}; Point(6) = {0, 0.5, 0, lc};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 6};
Line(6) = {6, 1};
Transfinite Curve {2} = 2;
Curve Loop(1) = {1, 2, 3, 4, 5, 6};
Plane Surface(1) = {1};
Physical Curve("b1") = {1}; Physical Curve("mid") = {2}; Physical Curve("b3") = {3};
Physical Curve("top") = {5};
Physical Surface("body") = {1};
"""

MID_CASE = """mesh: {file: mid.geo}
material: {E: 1000.0, nu: 0.3}
boundaries: {clamped: [b1, b3], contact: [mid]}
contact:
  g: 0.01
  normal_compliance: {c_nu: 100.0}
loads:
  traction: {top: [1.0, -5.0]}
time: {T: 1.0, N: 2}
"""

BOX_CASE = """mesh: {n: 4, L2: 0.5}
material: {E: 1000.0, nu: 0.3}
boundaries: {clamped: [left], contact: [bottom]}
contact:
  g: 0.01
  normal_compliance: {c_nu: 100.0}
  direction: DIRECTION
loads:
  traction: {top: [0.0, -5.0]}
time: {T: 1.0, N: 2}
"""


def _summary(out):
    return json.loads((out / "summary.json").read_text())


def _mid_case(tmp_path):
    (tmp_path / "mid.geo").write_text(MID_GEO)
    case = tmp_path / "mid.yaml"
    case.write_text(MID_CASE)
    return case


def _norms(summary):
    return [x for s in summary["steps"] for x in (s["norm_u_V"], s["norm_sigma_Q"], s["max_vm"])]


def _run(tmp_path, case, name, *extra, nprocs=1):
    out = tmp_path / name
    proc = run_cli(["run", case, "--out", out, "--quiet", *extra], nprocs=nprocs, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "internal error" not in proc.stderr and "Traceback" not in proc.stderr
    return _summary(out)


def test_gamma3_with_every_node_clamped_fast_equals_snes_vi(tmp_path):
    case = _mid_case(tmp_path)
    fast = _run(tmp_path, case, "fast")
    snes = _run(tmp_path, case, "snes", "--set", "solver.method=snes_vi")
    assert fast["solver"]["used"] == "condensed" and fast["status"] == "completed"
    assert all(s.get("fallback") is None for s in fast["steps"])
    assert fast["steps"][-1]["norm_u_V"] > 1e-3            # the body does move
    assert _norms(fast) == pytest.approx(_norms(snes), rel=1e-8)


@pytest.mark.mpi
def test_gamma3_with_every_node_clamped_on_two_ranks(tmp_path):
    case = _mid_case(tmp_path)
    serial = _run(tmp_path, case, "serial")
    mpi = _run(tmp_path, case, "mpi", nprocs=2)
    assert mpi["solver"]["used"] == "condensed" and mpi["mpi_ranks"] == 2
    assert _norms(mpi) == pytest.approx(_norms(serial), rel=1e-8)


def _direction_case(tmp_path, direction):
    case = tmp_path / "box.yaml"
    case.write_text(BOX_CASE.replace("DIRECTION", direction))
    return case


@pytest.mark.parametrize("direction, angle", [("[1.0, 0.0]", "90.0"), ("[0.0, 1.0]", "180.0"),
                                              ("[-1.0, 0.2]", "101.3")])
def test_direction_tangent_or_into_the_body_is_refused(tmp_path, direction, angle):
    proc = run_cli(["run", _direction_case(tmp_path, direction), "--out", tmp_path / "out"],
                   timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "box.yaml: contact.direction:" in lines[0]
    assert f"makes {angle} degrees with the outward normal of Gamma3 at the node (0.25, 0.0)" \
        in lines[0]
    assert not (tmp_path / "out" / "summary.json").exists()


@pytest.mark.mpi
def test_direction_into_the_body_is_refused_on_two_ranks(tmp_path):
    proc = run_cli(["run", _direction_case(tmp_path, "[0.0, 1.0]"), "--out", tmp_path / "out"],
                   nprocs=2, timeout=300)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "makes 180.0 degrees with the outward normal of Gamma3 at the node (0.25, 0.0)" \
        in proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr


def test_grazing_direction_is_warned_of_and_runs(tmp_path):
    """d = (1, -0.1) / |.|: 84.3 degrees from the bottom's normal (0, -1), under 90: accepted,
    with a warning; the paper's direction (0, -1) gives none."""
    out = tmp_path / "out"
    proc = run_cli(["run", _direction_case(tmp_path, "[1.0, -0.1]"), "--out", out], timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "makes 84.3 degrees on average with the outward normal of Gamma3" in \
        proc.stdout + proc.stderr
    proc = run_cli(["run", _direction_case(tmp_path, "[0.0, -1.0]"), "--out", out,
                    "--overwrite"], timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "degrees" not in proc.stdout + proc.stderr
