"""Process start-up and exit costs that are not the computation's (the reference run
is timed as a whole process, about 3 s).

- ufl and ffcx 2022.2 (Debian bookworm) import ``pkg_resources`` only to read their own
  version, ``pkg_resources.get_distribution(name).version``; importing it scans every
  installed distribution: 0.09-0.17 s per run (measured, python -X importtime).
  ``install_pkg_resources_stand_in`` puts a stand-in module in its place that answers that
  call from importlib.metadata; any other use of it loads the real module and forwards to it.
- The interpreter's teardown of a finished run (clearing the modules of dolfinx, ufl, numpy,
  ... one by one) takes 0.12-0.15 s (measured).  ``quick_exit`` does what that teardown does
  that matters (flush the streams, run the atexit handlers, finalise PETSc and MPI) and
  ends the process without the rest.
"""
from __future__ import annotations

import importlib
import os
import sys
import types


class _PkgResourcesStandIn(types.ModuleType):
    """``get_distribution(name).version`` from importlib.metadata; everything else from the
    real pkg_resources, imported on first use."""

    def get_distribution(self, name):
        from importlib.metadata import PackageNotFoundError, version
        try:
            return types.SimpleNamespace(project_name=name, version=version(name))
        except PackageNotFoundError:
            return self._real().get_distribution(name)

    def __getattr__(self, attr):
        return getattr(self._real(), attr)

    def _real(self):
        if sys.modules.get(self.__name__) is self:
            del sys.modules[self.__name__]
        return importlib.import_module(self.__name__)


def install_pkg_resources_stand_in() -> None:
    """Before ufl/ffcx are imported; nothing is done if pkg_resources is imported already."""
    if "pkg_resources" not in sys.modules:
        sys.modules["pkg_resources"] = _PkgResourcesStandIn("pkg_resources")


def quick_exit(code: int):
    """Exit with ``code`` after what the interpreter's teardown would do that matters: flush
    sys.stdout/stderr, run the atexit handlers (logging's among them), finalise PETSc (its
    -log_view report) and MPI (mpirun expects every rank to), flush C's stdio buffers.

    Args:
        code: the exit status.
    """
    import atexit
    import ctypes
    for stream in (sys.stdout, sys.stderr):
        if stream is not None:
            stream.flush()
    atexit._run_exitfuncs()
    petsc = sys.modules.get("petsc4py.PETSc")
    if petsc is not None:
        petsc._finalize()
    mpi = sys.modules.get("mpi4py.MPI")
    if mpi is not None and mpi.Is_initialized() and not mpi.Is_finalized():
        mpi.Finalize()
    ctypes.CDLL(None).fflush(None)
    os._exit(code)
