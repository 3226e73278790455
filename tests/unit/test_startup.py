"""The command line's process set-up (app/cli/entry.py prepare_process): its singleton MPI
settings must not leak into child processes (an inherited OMPI_MCA_btl=self breaks
`mpirun -n 2` started from a serial run)."""
import os
import shutil
import subprocess
import sys

import pytest

PREP = "from vpcontact.cli.entry import prepare_process; prepare_process(); "


def test_singleton_settings_are_not_inherited():
    env = {k: v for k, v in os.environ.items() if not k.startswith("OMPI_MCA_")}
    code = ("import os; " + PREP + "from mpi4py import MPI; "
            "print(MPI.COMM_WORLD.size, "
            "sorted(k for k in os.environ if k.startswith('OMPI_MCA_')))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split(None, 1)
    assert out == ["1", "[]\n"]


def test_user_settings_win():
    env = {**os.environ, "OMPI_MCA_btl": "self,vader"}
    code = "import os; " + PREP + "print(os.environ['OMPI_MCA_btl'])"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert out == "self,vader"


def test_mpi_settings_of_a_launch():
    """Without a launcher: the light singleton; under Open MPI's mpirun with every rank on
    this node: the ob1 layer named (no other layer opened first); across nodes or under
    another launcher: nothing (the launcher's settings)."""
    from vpcontact.cli.entry import mpi_settings
    assert dict(mpi_settings({}))["OMPI_MCA_btl"] == "self"
    one_node = {"OMPI_COMM_WORLD_SIZE": "2", "OMPI_COMM_WORLD_LOCAL_SIZE": "2"}
    assert dict(mpi_settings(one_node)) == {"OMPI_MCA_pml": "ob1"}
    assert mpi_settings({**one_node, "OMPI_COMM_WORLD_LOCAL_SIZE": "1"}) == ()
    assert mpi_settings({"PMI_RANK": "0", "PMI_SIZE": "2"}) == ()


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_one_node_mpirun_settings_are_not_inherited():
    """Two ranks on this node start with the ob1 layer named and pass none of it on."""
    code = ("import os; " + PREP + "from mpi4py import MPI; c = MPI.COMM_WORLD; "
            "s = c.allreduce(c.rank); "
            "found = c.gather([k for k in ('OMPI_MCA_pml',) if k in os.environ]); "
            "c.rank or print(c.size, s, found)")
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("OMPI_MCA_")},
           "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}
    out = subprocess.run(["mpirun", "-n", "2", sys.executable, "-c", code], env=env,
                         capture_output=True, text=True, timeout=120, check=True).stdout
    assert out.strip() == "2 1 [[], []]"


def test_openblas_thread_timeout_default_and_user_value():
    """OpenBLAS's idle threads sleep after 2^20 cycles unless the user says otherwise."""
    code = "import os; " + PREP + "print(os.environ['OPENBLAS_THREAD_TIMEOUT'])"
    for given, expected in ((None, "20"), ("28", "28")):
        env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
        if given is not None:
            env["OPENBLAS_THREAD_TIMEOUT"] = given
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, check=True).stdout.strip()
        assert out == expected


def test_pkg_resources_stand_in():
    """ufl/ffcx get their versions without the real pkg_resources; any other use of it
    loads the real module (app/startup.py)."""
    code = ("import sys; " + PREP + "import ufl, ffcx; from importlib.metadata import version; "
            "s = sys.modules['pkg_resources']; "
            "print(ufl.__version__ == version('fenics-ufl'), "
            "ffcx.__version__ == version('fenics-ffcx'), type(s).__name__); "
            "import pkg_resources; "
            "print(pkg_resources.parse_version('1.2') < pkg_resources.parse_version('1.10'), "
            "type(sys.modules['pkg_resources']).__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split("\n")
    assert out[0] == "True True _PkgResourcesStandIn"
    assert out[1] == "True module"


def test_quick_exit_flushes_and_finalises(tmp_path):
    """quick_exit: the exit status, Python's buffered output, atexit handlers, and PETSc's
    -log_view report (printed at PetscFinalize through C's stdio) all survive."""
    code = ("import atexit, sys; " + PREP + "import petsc4py; petsc4py.init(['x', '-log_view']); "
            "from petsc4py import PETSc; "
            "atexit.register(lambda: print('atexit ran')); print('buffered', end=''); "
            "from vpcontact.startup import quick_exit; quick_exit(3)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode == 3, p.stderr
    assert p.stdout.startswith("buffered") and "atexit ran" in p.stdout
    assert "PETSc Performance Summary" in p.stdout


@pytest.mark.parametrize("name", ["fenics-ufl", "fenics_ffcx", "numpy", "PyYAML", "jsonschema",
                                  "no-such-distribution-x"])
def test_installed_version_reads_the_metadata_importlib_reads(name):
    """The stand-in's own reader gives importlib.metadata's answer (None where it finds
    nothing: importlib.metadata answers then)."""
    from importlib.metadata import PackageNotFoundError, version

    from vpcontact.startup import installed_version
    try:
        expected = version(name)
    except PackageNotFoundError:
        expected = None
    assert installed_version(name) == expected


@pytest.fixture
def collector():
    """The collector as the test found it, afterwards."""
    import gc
    enabled = gc.isenabled()
    yield gc
    from vpcontact import startup
    startup._paused = False
    (gc.enable if enabled else gc.disable)()


def test_collector_paused_for_the_start_up_and_frozen_after(collector):
    from vpcontact import startup
    collector.enable()
    startup.pause_collector()
    assert not collector.isenabled()
    frozen = collector.get_freeze_count()
    startup.resume_collector()
    assert collector.isenabled() and collector.get_freeze_count() > frozen


def test_a_program_that_turned_the_collector_off_keeps_it_off(collector):
    from vpcontact import startup
    collector.disable()
    startup.resume_collector()                  # vpcontact did not pause it: not its to resume
    assert not collector.isenabled()
    startup.pause_collector()
    startup.resume_collector()
    assert not collector.isenabled()


@pytest.mark.parametrize("command", ["run", "check"])
def test_the_command_line_resumes_the_collector(collector, command, tmp_path, monkeypatch):
    """A run collects garbage from its first step on; the other commands from their start."""
    from conftest import PAPER_CASE
    from vpcontact import observers, startup
    from vpcontact.cli import main
    seen = []
    monkeypatch.setattr(observers.FieldOutput, "step",
                        lambda self, sim, record: seen.append(collector.isenabled()))
    collector.enable()
    startup.pause_collector()
    argv = [command, str(PAPER_CASE)]
    if command == "run":
        argv += ["--out", str(tmp_path / "out"), "--quiet", "--no-plots",
                 "--set", "mesh.n=4", "--set", "time.N=3"]
    assert main.main(argv) == 0
    assert collector.isenabled()
    assert seen == ([True] * 3 if command == "run" else [])


FACTOR_THREADS = """
import os
import numpy as np
import scipy.sparse as sp
from vpcontact.solvers import ldl
module = ldl.load()
if module is None:
    print("skip")
else:
    n = 160                                  # a grid Laplacian: supernodes of > 128 rows
    T = sp.diags([-1.0, 4.0, -1.0], [-1, 0, 1], shape=(n, n))
    A = sp.csr_matrix(sp.kron(sp.eye(n), T) + sp.kron(sp.diags([-1.0, -1.0], [-1, 1],
                                                              shape=(n, n)), sp.eye(n)))
    before = len(os.listdir("/proc/self/task"))
    ldl.Factor(module, A.indptr, A.indices, A.data, np.arange(n * n), 0, blocks=False)
    print(len(os.listdir("/proc/self/task")) - before)
"""


def test_cholmod_factorisation_starts_no_openmp_threads():
    """CHOLMOD's supernodal factorisation asks for 4 OpenMP threads in its scatter loops
    (a compiled-in constant) whatever OMP_NUM_THREADS says; on two cores they cost the 2D
    reference ~0.07 s of its set-up (measured), so the command line limits OpenMP to one
    thread (OMP_THREAD_LIMIT) unless the user sets it.  A CHOLMOD factorisation must then
    leave no OpenMP worker threads behind; with the user's limit it may."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_THREAD_LIMIT"}
    code = PREP + FACTOR_THREADS
    for given, check in ((None, lambda extra: extra == 0), ("4", lambda extra: extra > 0)):
        if given is not None:
            env["OMP_THREAD_LIMIT"] = given
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, check=True).stdout.strip()
        if out == "skip":
            pytest.skip("CHOLMOD not available")
        assert check(int(out)), (given, out)
