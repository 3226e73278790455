"""The mesh cache of the built-in geometries (meshes/meshcache.py): a mesh from the cache is
the mesh gmsh's model gives (the same coordinates, cells and tags, bit for bit, serially),
a run with a cached mesh does not import gmsh, a damaged entry is built anew and replaced,
and the key changes with the parameters, the builder's source and nothing else."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from vpcontact.meshes import meshcache
from vpcontact.meshes.box import build_box
from vpcontact.meshes.rectangle import build_rectangle

ROOT = Path(__file__).resolve().parents[2]


def _arrays(body) -> list[np.ndarray]:
    m = body.mesh
    return [m.geometry.x, m.geometry.dofmap.array, body.cell_tags.indices,
            body.cell_tags.values, body.facet_tags.indices, body.facet_tags.values]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache directory of this test."""
    monkeypatch.setattr(meshcache, "_directory", lambda: tmp_path / "meshes")
    return tmp_path / "meshes"


@pytest.mark.parametrize("build", [
    lambda: build_rectangle(MPI.COMM_WORLD, 2.0, 1.0, n=8, diagonal="left"),
    lambda: build_rectangle(MPI.COMM_WORLD, 1.0, 0.5, h=0.1),
    lambda: build_box(MPI.COMM_WORLD, 1.0, 0.5, 0.5, n=2)])
def test_a_cached_mesh_is_the_mesh_gmsh_gives(cache, build):
    built = _arrays(build())                       # gmsh's model, stored
    assert len(list(cache.glob("*.npz"))) == 1
    again = _arrays(build())                       # from the cache
    assert all(np.array_equal(a, b) for a, b in zip(built, again))


def test_a_damaged_entry_is_built_anew(cache):
    first = _arrays(build_rectangle(MPI.COMM_WORLD, n=4))
    entry = next(cache.glob("*.npz"))
    entry.write_bytes(b"not a numpy archive")
    again = _arrays(build_rectangle(MPI.COMM_WORLD, n=4))
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert np.load(entry)["x"].shape == (25, 3)     # replaced by a readable entry


def test_an_unwritable_cache_is_skipped(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the directory would be")
    monkeypatch.setattr(meshcache, "_directory", lambda: blocker / "meshes")
    assert build_rectangle(MPI.COMM_WORLD, n=2).mesh.topology.index_map(2).size_local == 8


def test_the_key_follows_parameters_and_source(tmp_path):
    source = tmp_path / "builder.py"
    source.write_text("def build(): pass\n")
    key = meshcache.cache_key("rectangle", [1.0, 0.5, 8, None, "left"], source)
    assert key == meshcache.cache_key("rectangle", [1.0, 0.5, 8, None, "left"], source)
    assert key != meshcache.cache_key("rectangle", [1.0, 0.5, 8, None, "right"], source)
    assert key != meshcache.cache_key("box", [1.0, 0.5, 8, None, "left"], source)
    source.write_text("def build(): return 1\n")
    assert key != meshcache.cache_key("rectangle", [1.0, 0.5, 8, None, "left"], source)
    assert meshcache.gmsh_version() not in ("", "unknown")


def test_a_run_with_a_cached_mesh_does_not_import_gmsh(tmp_path):
    script = ("import sys\nfrom mpi4py import MPI\n"
              "from vpcontact.meshes.rectangle import build_rectangle\n"
              "build_rectangle(MPI.COMM_WORLD, n=6)\nprint('gmsh' in sys.modules)")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "VPCONTACT_CACHE": str(tmp_path)}
    seen = [subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, text=True,
                           capture_output=True, timeout=120).stdout.strip() for _ in range(2)]
    assert seen == ["True", "False"]


@pytest.mark.parametrize("build", [
    lambda: build_rectangle(MPI.COMM_WORLD, 2.0, 1.0, n=8, diagonal="left"),
    lambda: build_box(MPI.COMM_WORLD, 1.0, 0.5, 0.5, n=3)])
def test_one_volume_tags_every_cell_as_the_distributed_data_does(build):
    """The cell tags of a one-volume mesh (every local cell, without distributing the cells'
    data) equal those that distributing gmsh's cell data gives."""
    body = build()
    mesh, tdim = body.mesh, body.mesh.topology.dim
    value = int(body.cell_tags.values[0])
    cells = mesh.geometry.dofmap.array.reshape(-1, tdim + 1)
    original = np.asarray(mesh.geometry.input_global_indices, dtype=np.int64)[cells]
    everywhere = meshcache._distributed_tags(mesh, tdim, original,
                                             np.full(len(cells), value, dtype=np.int32))
    imap = mesh.topology.index_map(tdim)
    assert len(body.cell_tags.indices) == imap.size_local + imap.num_ghosts
    assert np.array_equal(body.cell_tags.indices, everywhere.indices)
    assert np.array_equal(body.cell_tags.values, everywhere.values)
