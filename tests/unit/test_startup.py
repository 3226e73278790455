"""The command line's process set-up (app/cli/entry.py prepare_process): its singleton MPI
settings must not leak into child processes (an inherited OMPI_MCA_btl=self breaks
`mpirun -n 2` started from a serial run)."""
import os
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
