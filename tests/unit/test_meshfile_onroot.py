"""meshes.gmshfile.on_root, the one definition of "gmsh work on rank 0, its verdict broadcast"
used by load_mesh_file, the built-in meshes (rectangle.gmsh_mesh) and the refined levels
(refine.read_sizes, refine.refine_file): the error each raises, on one rank and on two."""
import json
import os
import subprocess
import sys

import pytest
from mpi4py import MPI

from conftest import MPI_ENV, ROOT
from vpcontact.meshes import MeshFileError, gmshfile, load_mesh_file
from vpcontact.meshes.gmshfile import file_failure, on_root
from vpcontact.meshes.rectangle import gmsh_mesh

COMM = MPI.COMM_WORLD


def _stopped(*_):
    raise KeyboardInterrupt("SIGTERM")


def test_a_signal_while_loading_a_file_keeps_its_name(monkeypatch, tmp_path):
    """The signal's name reaches the CLI's message (app.studies.interrupts.signal_name)."""
    monkeypatch.setattr(gmshfile, "_read", _stopped)
    with pytest.raises(KeyboardInterrupt) as caught:
        load_mesh_file(COMM, tmp_path / "part.msh", 2)
    assert caught.value.args == ("SIGTERM",)


def test_a_signal_while_building_a_mesh_keeps_its_name():
    with pytest.raises(KeyboardInterrupt) as caught:
        gmsh_mesh(COMM, 2, _stopped, 1.0)
    assert caught.value.args == ("SIGTERM",)


def test_a_file_failure_is_one_line_naming_the_file():
    def work(gmsh):
        raise OSError("first\nsecond")
    with pytest.raises(MeshFileError) as caught:
        on_root(COMM, work, file_failure("part.msh", "read"))
    assert str(caught.value) == "cannot read part.msh: OSError: first second"

    def refused(gmsh):
        raise MeshFileError("part.msh: no cells")
    with pytest.raises(MeshFileError, match=r"^part\.msh: no cells$"):
        on_root(COMM, refused, file_failure("part.msh", "read"))


def test_a_built_in_mesh_raises_its_own_error_on_rank_0():
    error = ValueError("bad size")

    def build():
        raise error
    with pytest.raises(ValueError) as caught:
        gmsh_mesh(COMM, 2, build, 1.0)
    assert caught.value is error


def test_the_result_is_shared_or_kept_on_rank_0():
    assert on_root(COMM, lambda g: g.option.getNumber("General.Terminal"),
                   file_failure("x", "read")) == 0
    assert on_root(COMM, lambda g: [1, 2], file_failure("x", "read"), share=False) == [1, 2]


TWO_RANKS = """
import json, sys
from mpi4py import MPI
from vpcontact.meshes.gmshfile import file_failure, on_root
from vpcontact.meshes.rectangle import gmsh_mesh
comm = MPI.COMM_WORLD
out = {}
def build():
    raise ValueError("bad size")
def failing(gmsh):
    raise OSError("gone")
try:
    gmsh_mesh(comm, 2, build, 1.0)
except Exception as err:
    out["built_in"] = [type(err).__name__, str(err)]
try:
    on_root(comm, failing, file_failure("part.msh", "refine"), share=False)
except Exception as err:
    out["file"] = [type(err).__name__, str(err)]
out["shared"] = on_root(comm, lambda g: [comm.rank, 7], file_failure("x", "read"))
out["kept"] = on_root(comm, lambda g: 5, file_failure("x", "read"), share=False)
with open(f"{sys.argv[1]}/rank{comm.rank}.json", "w") as f:
    json.dump(out, f)
"""


def test_two_ranks_raise_the_same_verdict(tmp_path):
    cmd = ["mpirun", "-n", "2", sys.executable, "-c", TWO_RANKS, str(tmp_path)]
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    r0, r1 = (json.loads((tmp_path / f"rank{r}.json").read_text()) for r in (0, 1))
    assert r0["built_in"] == ["ValueError", "bad size"]
    assert r1["built_in"] == ["RuntimeError",
                              "rank 0 could not build the mesh: ValueError: bad size"]
    assert r0["file"] == r1["file"] == ["MeshFileError",
                                        "cannot refine part.msh: OSError: gone"]
    assert r0["shared"] == r1["shared"] == [0, 7]
    assert (r0["kept"], r1["kept"]) == (5, None)
