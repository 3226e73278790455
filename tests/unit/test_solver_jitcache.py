"""A damaged FFCx JIT cache entry (app/io/cachedirs.py, repairing): truncated, empty, garbage
or unfinished entries are compiled again with one warning line, never loaded (a truncated
library loads and dies with SIGBUS) and never an internal error.  Each test compiles a small
form into a temporary cache (XDG_CACHE_HOME, which app/io/cachedirs.py and dolfinx read)."""
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import MPI_ENV, ROOT
from vpcontact.io import cachedirs

# a small form of its own (the constant makes its hash differ from the application's forms)
SCRIPT = """
from vpcontact.cli.entry import prepare_process
prepare_process()   # as the command line does: the JIT cache's repair installed
import ufl
from vpcontact.cli.logs import quiet_jit_log
quiet_jit_log()   # as the command line does: cffi's compiler lines out of stderr
from dolfinx import fem, mesh
from mpi4py import MPI
m = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
V = fem.FunctionSpace(m, ("CG", 1))
u = fem.Function(V)
u.interpolate(lambda x: 1 + x[0])
a = fem.form(u * u * 0.123456789 * ufl.dx)
value = MPI.COMM_WORLD.allreduce(fem.assemble_scalar(a), op=MPI.SUM)
if MPI.COMM_WORLD.rank == 0:   # one line: two ranks' prints may interleave
    print("VALUE", value)
"""
VALUE = 0.123456789 * 7 / 3        # integral of (1 + x)^2 over the unit square


def _run(cache: Path, nprocs: int = 1) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-c", SCRIPT]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    env = {**os.environ, **MPI_ENV, "XDG_CACHE_HOME": str(cache), "PYTHONPATH": str(ROOT)}
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)


def _value(out: subprocess.CompletedProcess) -> float:
    assert out.returncode == 0, out.stderr[-3000:]
    return float(out.stdout.split("VALUE")[-1])


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    """A cache with the small form compiled once (its files kept as bytes)."""
    cache = tmp_path_factory.mktemp("xdg")
    assert _value(_run(cache)) == pytest.approx(VALUE, rel=1e-12)
    files = {p.name: p.read_bytes() for p in (cache / "fenics").iterdir()}
    return files


def _fresh(tmp_path: Path, files: dict) -> Path:
    (tmp_path / "fenics").mkdir()
    for name, data in files.items():
        (tmp_path / "fenics" / name).write_bytes(data)
    return tmp_path


def _form_library(cache: Path) -> Path:
    [lib] = list((cache / "fenics").glob("libffcx_forms_*.so"))
    return lib


DAMAGE = {
    "truncated": lambda data: data[:len(data) // 3],    # SIGBUS when loaded
    "header only": lambda data: data[:40],              # ImportError: file too short
    "empty": lambda data: b"",
    "garbage": lambda data: os.urandom(len(data)),      # invalid ELF header
}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_a_damaged_library_is_compiled_again(tmp_path, compiled, damage):
    cache = _fresh(tmp_path, compiled)
    lib = _form_library(cache)
    lib.write_bytes(DAMAGE[damage](lib.read_bytes()))
    out = _run(cache)
    assert _value(out) == pytest.approx(VALUE, rel=1e-12)
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("vpcontact: warning: damaged FFCx JIT "
                                                   "cache entry "), out.stderr
    assert str(lib.with_name(lib.name.split(".")[0])) in lines[0]
    assert cachedirs.elf_damage(_form_library(cache)) is None     # the repaired library
    again = _run(cache)                                            # and no warning after
    assert _value(again) == pytest.approx(VALUE, rel=1e-12) and again.stderr == ""


def test_a_compilation_that_never_finished_is_done_again(tmp_path, compiled):
    """A killed compilation: the .c without its ready mark, an object file, no library."""
    cache = _fresh(tmp_path, compiled)
    lib = _form_library(cache)
    stem = lib.name.split(".")[0]
    lib.unlink()
    (cache / "fenics" / f"{stem}.c.cached").unlink()
    old = time.time() - 2 * cachedirs.JIT_STALE_SECONDS
    for p in (cache / "fenics").glob(f"{stem}.*"):
        os.utime(p, (old, old))
    start = time.monotonic()
    out = _run(cache)
    assert _value(out) == pytest.approx(VALUE, rel=1e-12)
    assert "compilation never finished" in out.stderr and out.stderr.count("\n") == 1
    assert time.monotonic() - start < 60        # not FFCx's 10 s wait for the ready mark


def test_a_library_missing_behind_its_ready_mark_is_compiled_again(tmp_path, compiled):
    cache = _fresh(tmp_path, compiled)
    _form_library(cache).unlink()
    out = _run(cache)
    assert _value(out) == pytest.approx(VALUE, rel=1e-12)
    assert "the compiled library is missing" in out.stderr


def test_under_mpirun_rank_0_compiles_again_and_the_others_load_it(tmp_path, compiled):
    cache = _fresh(tmp_path, compiled)
    lib = _form_library(cache)
    lib.write_bytes(lib.read_bytes()[:5000])
    out = _run(cache, nprocs=2)
    assert _value(out) == pytest.approx(VALUE, rel=1e-12)
    assert out.stderr.count("damaged FFCx JIT cache entry") == 1, out.stderr


def test_an_entry_that_cannot_be_removed_is_one_line_naming_the_directory(tmp_path,
                                                                         monkeypatch):
    (tmp_path / "libffcx_forms_x.c").write_text("")
    (tmp_path / "libffcx_forms_x.c.cached").write_text("")

    def refuse(self, missing_ok=False):
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr(Path, "unlink", refuse)
    with pytest.raises(cachedirs.JitCacheError) as err:
        cachedirs.discard_jit_entry(tmp_path, "libffcx_forms_x")
    text = str(err.value)
    assert "\n" not in text and f"delete the directory {tmp_path} " in text


def test_an_unfinished_entry_is_left_to_its_compilation_while_young(tmp_path):
    (tmp_path / "libffcx_forms_y.c").write_text("")
    now = time.time()
    assert cachedirs.jit_entry_damage(tmp_path, "libffcx_forms_y", now) is None
    later = now + 2 * cachedirs.JIT_STALE_SECONDS
    assert "never finished" in cachedirs.jit_entry_damage(tmp_path, "libffcx_forms_y", later)
    assert cachedirs.jit_entry_damage(tmp_path, "libffcx_forms_absent", later) is None


def test_elf_damage_accepts_the_libraries_python_loads():
    import _ctypes
    assert cachedirs.elf_damage(Path(_ctypes.__file__)) is None


KERNEL = """
from vpcontact.kernels import build
module = build.compiled("_vpcontact_test_truncated", "int plus_one(int);",
                        "int plus_one(int x) { return x + 1; }", "a test module")
print("VALUE", module.lib.plus_one(41))
"""


def test_a_truncated_kernel_library_is_built_again(tmp_path):
    """The same damage in the compiled kernels' cache (app/kernels/build.py): found
    from the ELF headers, not by loading the library (SIGBUS)."""
    env = {**os.environ, "VPCONTACT_CACHE": str(tmp_path), "PYTHONPATH": str(ROOT)}

    def run():
        return subprocess.run([sys.executable, "-c", KERNEL], env=env, capture_output=True,
                              text=True, timeout=300)
    assert _value(run()) == 42
    [lib] = list((tmp_path / "kernels").glob("_vpcontact_test_truncated_*.so"))
    lib.write_bytes(lib.read_bytes()[:3000])
    assert _value(run()) == 42
    assert cachedirs.elf_damage(lib) is None


UNFINISHED = """
import sys
from pathlib import Path
from vpcontact.cli.entry import prepare_process
prepare_process()   # as the command line does: the JIT cache's repair installed
from mpi4py import MPI
import ufl
from dolfinx import fem, mesh
from vpcontact.io.cachedirs import JitCacheError
m = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
V = fem.FunctionSpace(m, ("CG", 1))
u = fem.Function(V)
try:
    fem.form(u * u * 0.123456789 * ufl.dx, jit_params={"timeout": 2})
    what = "compiled"
except JitCacheError as exc:
    what = "JitCacheError: " + str(exc)
except Exception as exc:
    what = type(exc).__name__ + ": " + str(exc)
Path(sys.argv[1], f"rank{MPI.COMM_WORLD.rank}.txt").write_text(what)
"""


@pytest.mark.parametrize("nprocs", [1, 2])
def test_a_compilation_still_running_is_one_error_on_every_rank(tmp_path, compiled, nprocs):
    """An unfinished entry younger than JIT_STALE_SECONDS may be another process's
    compilation: it is not removed; FFCx's wait ends in one line naming the files to
    delete (JitCacheError, an OSError: the command line prints it, exit 1), on every rank
    (dolfinx turns rank 0's error into 'Compilation failed on root node.' on the others)."""
    (tmp_path / "cache").mkdir()
    cache = _fresh(tmp_path / "cache", compiled)
    lib = _form_library(cache)
    stem = lib.name.split(".")[0]
    lib.unlink()
    (cache / "fenics" / f"{stem}.c.cached").unlink()
    cmd = [sys.executable, "-c", UNFINISHED, str(tmp_path)]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    env = {**os.environ, **MPI_ENV, "XDG_CACHE_HOME": str(cache), "PYTHONPATH": str(ROOT)}
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    for rank in range(nprocs):
        text = (tmp_path / f"rank{rank}.txt").read_text()
        assert text.startswith("JitCacheError: the FFCx JIT cache entry "), text
        assert f"delete {cache / 'fenics' / stem}.* or the directory" in text
    assert (cache / "fenics" / f"{stem}.c").exists()       # not removed


def test_the_command_line_prints_a_damaged_cache_as_one_line(monkeypatch, capsys):
    from vpcontact.cli import main
    damaged = cachedirs.JitCacheError("the FFCx JIT cache entry x is damaged and cannot be "
                                        "removed; delete the directory /c")

    def fail(args, petsc):
        raise damaged
    monkeypatch.setattr(main, "dispatch", fail)
    assert main.main(["info"]) == 1
    err = capsys.readouterr().err
    assert err == "vpcontact: error: " + str(damaged) + "\n"


def test_an_unreadable_library_is_compiled_again(tmp_path, compiled):
    """A library that cannot be read (here a directory in its place; permissions do not
    stop root) is removed and compiled again."""
    cache = _fresh(tmp_path, compiled)
    lib = _form_library(cache)
    lib.unlink()
    (lib / "inside").mkdir(parents=True)
    assert "unreadable" in cachedirs.elf_damage(lib)
    out = _run(cache)
    assert _value(out) == pytest.approx(VALUE, rel=1e-12)
    assert "unreadable" in out.stderr and out.stderr.count("\n") == 1
    assert lib.is_file() and cachedirs.elf_damage(lib) is None


@pytest.mark.parametrize("nprocs", [1, 2])
def test_a_compilation_that_fails_is_one_line_on_every_rank(tmp_path, nprocs):
    """The C compiler fails (as on a full disk; here CC names no program): one line naming
    the FFCx cache, exit 1, no internal error (under mpirun dolfinx turned rank 0's error
    into a RuntimeError on every rank: an internal error and MPI_Abort)."""
    cmd = [sys.executable, "-m", "vpcontact", "run", str(ROOT / "cases" / "wang_cheng_2021.yaml"),
           "--out", str(tmp_path / "out"), "--no-plots", "--set", "mesh.n=2",
           "--set", "time.N=1"]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    env = {**os.environ, **MPI_ENV, "XDG_CACHE_HOME": str(tmp_path / "xdg"),
           "VPCONTACT_CACHE": str(tmp_path / "vpc"), "CC": str(tmp_path / "no-compiler"),
           "PYTHONPATH": str(ROOT)}
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 1, out.stderr[-3000:]
    ours = [ln for ln in out.stderr.splitlines() if ln.startswith("vpcontact:")]
    assert ours == [f"vpcontact: error: compiling a form into the FFCx JIT cache "
                    f"{tmp_path / 'xdg' / 'fenics'} failed " + ours[0].split(" failed ", 1)[1]]
    assert "internal error" not in out.stderr and "Traceback" not in out.stderr
