"""The singleton MPI settings of app/__init__.py must not leak into child processes (an
inherited OMPI_MCA_btl=self breaks `mpirun -n 2` started from a serial run)."""
import os
import subprocess
import sys


def test_singleton_settings_are_not_inherited():
    env = {k: v for k, v in os.environ.items() if not k.startswith("OMPI_MCA_")}
    code = ("import os, app; from mpi4py import MPI; "
            "print(MPI.COMM_WORLD.size, sorted(k for k in os.environ if k.startswith('OMPI_MCA_')))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split(None, 1)
    assert out == ["1", "[]\n"]


def test_user_settings_win():
    env = {**os.environ, "OMPI_MCA_btl": "self,vader"}
    code = "import os, app; print(os.environ['OMPI_MCA_btl'])"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert out == "self,vader"
