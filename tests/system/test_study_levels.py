"""Studies on a user's mesh: the refined levels are refused before any refinement or run
when the finest would exceed the built-in meshes' vertex limit or the memory (one line, exit
2, no output directory), and a signal while gmsh meshes the .geo ends the study with exit 3
and one line (gmsh's module set SIGINT to its default action: the process died)."""
import os
import subprocess
import sys

import pytest

from conftest import MPI_ENV, ROOT, run_cli

HERTZ = ROOT / "cases" / "hertz_cylinder.yaml"
PUNCH = ROOT / "cases" / "punch_relaxation.yaml"


@pytest.mark.parametrize("geo, dim, size", [("hertz_cylinder.geo", 2, 4.0),
                                            ("sphere3d.geo", 3, 1.0)])
def test_level_vertices_are_the_refined_meshes(geo, dim, size):
    """The vertex counts computed without refining equal those of the refined meshes."""
    import gmsh

    from vpcontact.meshes.refine import level_vertices, read_level, refine
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        levels = [read_level(gmsh, ROOT / "cases" / geo, dim, size)]
    finally:
        gmsh.finalize()
    for _ in range(2 if dim == 2 else 1):
        levels.append(refine(levels[-1]))
    assert level_vertices(levels[0], len(levels) - 1) == [len(m.x) for m in levels]


def test_refine_file_refuses_before_refining(tmp_path, monkeypatch):
    """The vertex limit was checked after each refinement, so the level over the limit was
    built first (minutes and gigabytes for a large reference); now nothing is refined."""
    from mpi4py import MPI

    from vpcontact.meshes import MeshFileError
    from vpcontact.meshes import refine as rf
    calls = []
    monkeypatch.setattr(rf, "refine", lambda level: calls.append(level) or 1 / 0)
    with pytest.raises(MeshFileError, match="refined 4 times would have 2.9"):
        rf.refine_file(MPI.COMM_WORLD, ROOT / "cases" / "hertz_cylinder.geo", 2, 4.0, 6,
                       tmp_path, max_vertices=10000)
    assert calls == [] and not any(tmp_path.iterdir())


def test_too_large_names_the_first_level_over_either_limit():
    """Vertex limit (the built-in meshes', 1e8) and memory (700 B per vertex in 2D)."""
    from vpcontact.meshes.refine import too_large
    sizes = [10 ** 6, 4 * 10 ** 6, 16 * 10 ** 6, 64 * 10 ** 6, 256 * 10 ** 6]
    assert too_large(sizes, 2, 1e8, None) == (4, "would have 2.56e+08 vertices (limit 1e+08)")
    assert too_large(sizes, 2, 1e8, 5e9) == (
        2, "would need about 11.2 GB of memory to refine (5 GB available)")
    assert too_large(sizes[:2], 3, 1e8, 1e10) is None


@pytest.mark.parametrize("args, option, memory", [
    (["convergence", HERTZ, "--levels", "0", "--reference", "12"], "--reference", False),
    (["convergence", HERTZ, "--levels", "3", "5", "--reference", "1000"], "--reference",
     False),
    (["stability", PUNCH, "--refine", "7"], "--refine", False),
    (["stability", PUNCH, "--refine", "6"], "--refine", True),
])
def test_too_many_refinements_are_refused_before_any_computation(tmp_path, args, option,
                                                                  memory):
    """hertz refined 9 times has 3.35e8 vertices (the built-in meshes' limit is 1e8), punch
    refined 7 times 5e7 (30 GB to refine): one line naming the option and the values
    allowed, exit 2, no output directory, in seconds (before: the study refined the mesh
    for minutes; punch --refine 6 was killed for want of memory, exit 137)."""
    from vpcontact.meshes.refine import available_memory
    if memory and (available_memory() is None or available_memory() > 30e9):
        pytest.skip("refused for want of memory only below 30 GB available")
    out = tmp_path / "o"
    proc = run_cli([*args, "--out", out], timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stdout, proc.stderr
    assert " vertices (limit 1e+08)" in lines[0] or " GB of memory to refine (" in lines[0]
    assert f"; allowed: {option} up to " in lines[0]
    assert not out.exists()


# the process sends itself SIGINT as gmsh starts to mesh the .geo (the n-th time)
SIGNAL_WHILE_MESHING = """
import os, signal, sys
from vpcontact.meshes import gmshfile
count, real = [0], gmshfile._mesh_geo
def mesh_geo(*args):
    count[0] += 1
    if count[0] == int(sys.argv[1]):
        os.kill(os.getpid(), signal.SIGINT)
    return real(*args)
gmshfile._mesh_geo = mesh_geo
from vpcontact.cli.main import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("nth, line", [
    (1, "vpcontact: interrupted before the time loop started"),
    (2, "vpcontact: convergence study interrupted by SIGINT during the refinement of "
        f"{ROOT / 'cases' / 'hertz_cylinder.geo'}; 0 run(s) had finished (not kept: "
        "--no-cache); no report was written to "),
])
def test_signal_while_gmsh_meshes_ends_the_study(tmp_path, nth, line):
    """The .geo is meshed twice: for the size check (before anything else) and for the
    levels.  Either time: exit 3, one line, no temporary level files left (the process
    was killed by SIGINT before, exit -2, without a word)."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    cmd = [sys.executable, "-c", SIGNAL_WHILE_MESHING, str(nth), "convergence", str(HERTZ),
           "--levels", "0", "--reference", "1", "--out", str(tmp_path / "o"), "--no-cache"]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT),
                               "TMPDIR": str(tmp)})
    assert proc.returncode == 3, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(line), proc.stderr
    assert not list(tmp.glob("vpcontact-levels-*"))


# (a built-in --reference over mesh.n's 4096 is refused by the parser first:
# tests/unit/test_loose_cli_ints.py)
@pytest.mark.parametrize("args, start", [
    (["convergence", HERTZ, "--levels", "0", "--reference", "2", "--set", "time.N=400000"],
     "--reference 2: "),
])
def test_a_level_the_case_refuses_names_the_study_option(tmp_path, args, start):
    """A level's case too large for the case's limits (mesh.n <= 4096, time.N <= 1e6) named
    mesh.n or time.N only, which the command line did not set; now the option first."""
    proc = run_cli([*args, "--out", tmp_path / "o", "--no-cache"])
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith(f"vpcontact: error: {start}"), proc.stderr
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "o").exists()


def test_signal_while_gmsh_meshes_ends_the_stability_sweep(tmp_path):
    """The sweep's levels of a .geo (the second meshing): exit 3, one line, no report."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    cmd = [sys.executable, "-c", SIGNAL_WHILE_MESHING, "2", "stability", str(HERTZ),
           "--out", str(tmp_path / "o")]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT),
                               "TMPDIR": str(tmp)})
    assert proc.returncode == 3, proc.stderr
    assert proc.stderr == ("vpcontact: stability sweep interrupted by SIGINT during the "
                           f"refinement of {ROOT / 'cases' / 'hertz_cylinder.geo'}; no variant "
                           "had finished, no report written\n")
    assert not list(tmp.glob("vpcontact-levels-*"))
    assert not (tmp_path / "o" / "stability.csv").exists()
