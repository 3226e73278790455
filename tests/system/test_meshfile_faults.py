"""User meshes under the command line: a group off the body is
one line and exit 2 (it was a segmentation fault), serially and under mpirun -n 2; a
boundary role on an embedded curve is refused (its traction was silently ignored); SIGINT and
SIGTERM while gmsh meshes a .geo end the run at once with exit 3 (they waited for the mesh);
a .geo asking for a huge mesh is refused before gmsh makes it."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import MPI_ENV, ROOT, run_cli

SQUARE = """Point(1) = {0, 0, 0, 0.25}; Point(2) = {1, 0, 0, 0.25};
Point(3) = {1, 1, 0, 0.25}; Point(4) = {0, 1, 0, 0.25};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("bottom") = {1}; Physical Surface("body") = {1};
"""
# a curve beside the body, and one embedded in it
AWAY = 'Point(5) = {2, 0, 0, 0.5}; Point(6) = {3, 0, 0, 0.5}; Line(5) = {5, 6};\n' \
       'Physical Curve("away") = {5};\n'
INNER = 'Point(5) = {0.3, 0.5, 0, 0.25}; Point(6) = {0.7, 0.5, 0, 0.25}; Line(5) = {5, 6};\n' \
        'Curve{5} In Surface{1};\nPhysical Curve("inner") = {5};\n'


def _case(tmp_path, geo: str, loads: str = "{}", name="part.geo") -> Path:
    (tmp_path / name).write_text(geo)
    case = tmp_path / "case.yaml"
    case.write_text(f"mesh: {{file: {name}, dim: 2}}\n"
                    "material: {E: 1000.0, nu: 0.3, plane: strain}\n"
                    f"boundaries: {{clamped: [bottom]}}\nloads: {loads}\ntime: {{T: 1.0, N: 1}}\n")
    return case


def _save_msh(geo: Path) -> Path:
    code = ("import sys, gmsh; gmsh.initialize(readConfigFiles=False); "
            "gmsh.option.setNumber('General.Terminal', 0); gmsh.open(sys.argv[1]); "
            "gmsh.model.mesh.generate(2); gmsh.write(sys.argv[2]); gmsh.finalize()")
    msh = geo.with_suffix(".msh")
    subprocess.run([sys.executable, "-c", code, str(geo), str(msh)], check=True, timeout=120)
    return msh


def _one_line_error(proc, *words):
    err = [line for line in proc.stderr.splitlines() if "error:" in line]
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert len(err) == 1 and all(w in err[0] for w in words), proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr


@pytest.mark.parametrize("suffix", [".geo", ".msh"])
def test_a_group_off_the_body_is_refused(tmp_path, suffix):
    case = _case(tmp_path, SQUARE + AWAY, "{traction: {away: [0.0, 1.0]}}")
    if suffix == ".msh":
        _save_msh(tmp_path / "part.geo")
        case.write_text(case.read_text().replace("part.geo", "part.msh"))
    proc = run_cli(["run", case, "--out", tmp_path / "out"], timeout=300)
    _one_line_error(proc, f"part{suffix}: Physical Curve 3 ('away') has 2 of its 2 elements "
                          "outside the body", "a boundary group must lie on the body")


@pytest.mark.mpi
def test_a_group_off_the_body_is_refused_on_two_ranks(tmp_path):
    case = _case(tmp_path, SQUARE + AWAY)
    proc = run_cli(["run", case, "--out", tmp_path / "out"], nprocs=2, timeout=300)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "('away') has 2 of its 2 elements outside the body" in proc.stderr
    assert "Segmentation" not in proc.stderr and "Traceback" not in proc.stderr


def test_a_boundary_role_on_an_embedded_curve_is_refused(tmp_path):
    case = _case(tmp_path, SQUARE + INNER, "{traction: {inner: [0.0, 1.0]}}")
    proc = run_cli(["run", case, "--out", tmp_path / "out"], timeout=300)
    _one_line_error(proc, "loads.traction.inner: group 'inner' has 2 of its 2 facets inside "
                          "the body")
    case.write_text(case.read_text().replace("clamped: [bottom]", "clamped: [bottom, inner]")
                    .replace("{traction: {inner: [0.0, 1.0]}}", "{}"))
    proc = run_cli(["run", case, "--out", tmp_path / "out2"], timeout=300)
    _one_line_error(proc, "boundaries.clamped: group 'inner' has 2 of its 2 facets inside")


def _child_of(pid: int, needle: str) -> int | None:
    """A child process of ``pid`` whose command line holds ``needle``."""
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid and needle in cmdline:
            return int(entry.name)
    return None


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_while_gmsh_meshes_ends_the_run_at_once(tmp_path, sig):
    """A mesh of ~3e7 nodes takes gmsh minutes; the signal ends the run within seconds."""
    case = _case(tmp_path, SQUARE + "Mesh.MeshSizeMax = 2e-4;\n")
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "vpcontact", "run", str(case), "--out",
                             str(tmp_path / "out"), "--no-plots"], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30             # (or gmsh meshes in this process)
        while (child := _child_of(proc.pid, "geomesh.py")) is None and \
                time.monotonic() < deadline:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.05)
        time.sleep(1.0)                             # gmsh is meshing now
        start = time.monotonic()
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
        waited = time.monotonic() - start
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 3, out + err
    assert "interrupted" in err and "Traceback" not in err
    assert waited < 20, waited
    assert child is None or not Path(f"/proc/{child}").exists() or \
        Path(f"/proc/{child}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"


@pytest.mark.parametrize("geo, words", [
    (SQUARE + "Mesh.MeshSizeMax = 1e-9;\n", "at most 1e-09 on a body 1 long"),
    (SQUARE.replace("0.25}", "1e-5}") + "\n", "on the curves or less"),
], ids=["MeshSizeMax", "point sizes"])
def test_a_geo_asking_for_a_huge_mesh_is_refused_before_meshing(tmp_path, geo, words):
    case = _case(tmp_path, geo)
    start = time.monotonic()
    proc = run_cli(["run", case, "--out", tmp_path / "out"], timeout=300)
    _one_line_error(proc, "part.geo: its mesh sizes", words, "(limit 1e+08)")
    assert time.monotonic() - start < 60


PLATE = """Point(1) = {0, 0, 0, 0.25}; Point(2) = {1, 0, 0, 0.25};
Point(3) = {1, 1, 0, 0.25}; Point(4) = {0, 1, 0, 0.25};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Curve("base") = {1}; Physical Curve("lid") = {3}; Physical Curve("wall") = {4};
Physical Surface("plate") = {1};
"""


def _save_partitioned(geo: Path, name: str, version: float, old_style: int) -> Path:
    """The .geo meshed, partitioned in 2 (as gmsh -part 2) and saved in MSH ``version``."""
    code = ("import sys, gmsh; gmsh.initialize(readConfigFiles=False); "
            "gmsh.option.setNumber('General.Terminal', 0); gmsh.open(sys.argv[1]); "
            "gmsh.model.mesh.generate(2); gmsh.model.mesh.partition(2); "
            f"gmsh.option.setNumber('Mesh.MshFileVersion', {version}); "
            f"gmsh.option.setNumber('Mesh.PartitionOldStyleMsh2', {old_style}); "
            "gmsh.write(sys.argv[2]); gmsh.finalize()")
    msh = geo.with_name(name)
    subprocess.run([sys.executable, "-c", code, str(geo), str(msh)], check=True, timeout=120)
    return msh


@pytest.mark.parametrize("version,old_style", [(4.1, 0), (2.2, 0), (2.2, 1)])
def test_a_mesh_saved_partitioned_is_read_as_one_mesh(tmp_path, version, old_style):
    """gmsh -part 2 puts the elements into partition entities; the file was refused ('...
    holds surface 1, which has no elements'): it is the same mesh as saved unpartitioned,
    its groups holding their elements (lc = 0.25: 4 facets on each side of the square)."""
    from mpi4py import MPI

    from vpcontact.meshes.gmshfile import load_mesh_file
    geo = tmp_path / "plate.geo"
    geo.write_text(PLATE)
    whole = load_mesh_file(MPI.COMM_WORLD, _save_msh(geo), 2)
    parted = load_mesh_file(MPI.COMM_WORLD, _save_partitioned(
        geo, f"parted_{version}_{old_style}.msh", version, old_style), 2)
    assert parted.groups == whole.groups == {"base": 1, "lid": 2, "wall": 3}
    for m in (whole, parted):
        assert m.mesh.topology.index_map(2).size_global == 42
        assert m.mesh.geometry.index_map().size_global == 30
        assert m.h == pytest.approx(whole.h) and m.h_min == pytest.approx(whole.h_min)
        for tag in (1, 2, 3):
            assert int((m.facet_tags.values == tag).sum()) == 4, tag
