"""SIGINT/SIGTERM while gmsh works for the run: gmsh is imported only through
meshes.gmshfile.import_gmsh, which keeps the process's SIGINT handler (gmsh's module sets
SIGINT to its default action when first imported, so a Ctrl-C killed the process: no line,
no exit code 3), and a signal on rank 0 while it builds the built-in mesh or reads and refines
a mesh.file for a study is a KeyboardInterrupt on every rank (the other ranks waited for
rank 0 in a collective until mpirun tore the job down).

The signals are real: the process sends one to itself at a chosen moment (a patched
function: deterministic), then gmsh's work goes on for longer than the test waits."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import MPI_ENV, ROOT

BOX3D = str(ROOT / "cases" / "box3d.yaml")
HERTZ = str(ROOT / "cases" / "hertz_cylinder.yaml")

# run the CLI after wrapping ``module.name`` so that rank 0 signals itself (and then works
# 30 s more: gmsh "meshing") when it is called; each rank writes its exit code to a file
PATCHED = """
import os, signal, sys, time, importlib
from mpi4py import MPI
module, name, sig, out = sys.argv[1:5]
mod = importlib.import_module(module)
real = getattr(mod, name)
def patched(*args, **kwargs):
    if MPI.COMM_WORLD.rank == 0:
        os.kill(os.getpid(), getattr(signal, sig))
        time.sleep(30)
    return real(*args, **kwargs)
setattr(mod, name, patched)
from vpcontact.cli.main import main
code = main(sys.argv[5:])
with open(f"{out}.rank{MPI.COMM_WORLD.rank}", "w") as f:
    f.write(str(code))
sys.exit(code)
"""


def _run_patched(tmp_path, target: str, sig: str, args: list[str], nprocs: int = 1):
    module, name = target.rsplit(".", 1)
    cmd = [sys.executable, "-c", PATCHED, module, name, sig, str(tmp_path / "code"), *args]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    # an empty mesh cache: the built-in mesh is built by gmsh (meshes/meshcache.py)
    env = {**__import__("os").environ, **MPI_ENV, "PYTHONPATH": str(ROOT),
           "VPCONTACT_CACHE": str(tmp_path / "cache")}
    try:
        return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                              timeout=25)      # gmsh "works" 30 s after the signal
    except subprocess.TimeoutExpired:
        pytest.fail(f"{target}: not interrupted within 25 s of {sig}")


def _codes(tmp_path, nprocs: int) -> list[str]:
    return [Path(f"{tmp_path / 'code'}.rank{r}").read_text()
            if Path(f"{tmp_path / 'code'}.rank{r}").exists() else None for r in range(nprocs)]


@pytest.mark.parametrize("target", ["vpcontact.meshes.box._gmsh_model",            # gmsh meshes
                                    "vpcontact.meshes.meshcache.model_arrays"])  # model read
@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_while_the_builtin_mesh_is_built_ends_the_run_with_exit_3(tmp_path, target,
                                                                          sig):
    proc = _run_patched(tmp_path, target, sig, ["run", BOX3D, "--set", "mesh.n=2", "--set",
                                                "time.N=1", "--out", str(tmp_path / "o"),
                                                "--no-plots"])
    assert proc.returncode == 3, (proc.returncode, proc.stderr[-2000:])
    lines = proc.stderr.strip().splitlines()
    assert lines == ["vpcontact: interrupted before the time loop started"], proc.stderr


def test_a_signal_on_rank_0_while_it_builds_the_mesh_stops_every_rank(tmp_path):
    proc = _run_patched(tmp_path, "vpcontact.meshes.box._gmsh_model", "SIGINT",
                        ["run", BOX3D, "--set", "mesh.n=2", "--set", "time.N=1", "--out",
                         str(tmp_path / "o"), "--no-plots"], nprocs=2)
    assert _codes(tmp_path, 2) == ["3", "3"], (proc.returncode, proc.stderr[-2000:])
    assert proc.returncode == 3
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr


@pytest.mark.parametrize("nprocs", [1, 2])
def test_a_signal_on_rank_0_while_it_reads_the_mesh_of_a_study_stops_every_rank(tmp_path,
                                                                                nprocs):
    proc = _run_patched(tmp_path, "vpcontact.meshes.refine.read_level", "SIGTERM",
                        ["convergence", HERTZ, "--set", "mesh.size=4", "--levels", "0",
                         "--reference", "1", "--no-cache", "--out", str(tmp_path / "o")],
                        nprocs=nprocs)
    assert _codes(tmp_path, nprocs) == ["3"] * nprocs, (proc.returncode, proc.stderr[-2000:])
    assert proc.returncode == 3
    assert re.search(r"interrupted", proc.stderr), proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
