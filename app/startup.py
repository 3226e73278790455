"""Process start-up and exit costs that are not the computation's (the reference run
is timed as a whole process, so they count).

- ufl and ffcx 2022.2 (Debian bookworm) import ``pkg_resources`` only to read their own
  version, ``pkg_resources.get_distribution(name).version``; importing it scans every
  installed distribution.  ``install_pkg_resources_stand_in`` puts a stand-in module in its
  place that answers that call from importlib.metadata; any other use of it loads the real
  module and forwards to it.
- Python's cyclic garbage collector scans every tracked object of the start-up's imports
  (dolfinx, ufl, numpy, ...) again and again while they load.
  ``pause_collector`` turns it off for the start-up and the set-up, ``resume_collector``
  moves what exists then into the permanent generation (``gc.freeze``: never scanned
  again) and turns it back on.  The cycles made meanwhile (some 40,000 objects, a few MB)
  stay until the process ends.
- The interpreter's teardown of a finished run (clearing the modules of dolfinx, ufl, numpy,
  ... one by one) is slow.  ``quick_exit`` does what that teardown does
  that matters (flush the streams, run the atexit handlers, finalise PETSc and MPI) and
  ends the process without the rest.

What each costs, and what each saves of the commands' wall time: docs/performance.md
section 5.
"""
from __future__ import annotations

import gc
import importlib
import os
import re
import sys
import time
import types

# the command's start (imported first by the command line, app/cli/entry.py console): the
# run log's start-up time under mpirun (app/cli/ranknote.py)
STARTED = time.perf_counter()


class _PkgResourcesStandIn(types.ModuleType):
    """``get_distribution(name).version`` from importlib.metadata; everything else from the
    real pkg_resources, imported on first use."""

    def get_distribution(self, name):
        found = installed_version(name)
        if found is None:
            from importlib.metadata import PackageNotFoundError, version
            try:
                found = version(name)
            except PackageNotFoundError:
                return self._real().get_distribution(name)
        return types.SimpleNamespace(project_name=name, version=found)

    def __getattr__(self, attr):
        return getattr(self._real(), attr)

    def _real(self):
        if sys.modules.get(self.__name__) is self:
            del sys.modules[self.__name__]
        return importlib.import_module(self.__name__)


def _normalised(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


def installed_version(name: str) -> str | None:
    """The version of an installed distribution from the first metadata of that name on
    sys.path (a .dist-info's METADATA, an .egg-info's PKG-INFO), read as a file:
    importlib.metadata and the email parser it imports cost more (docs/performance.md,
    section 3).

    Args:
        name: the distribution's name (any spelling PEP 503 normalises alike).

    Returns:
        Its "Version:", or None if none is found (importlib.metadata then decides).
    """
    want = _normalised(name)
    for entry in sys.path:
        try:
            names = os.listdir(entry or ".")
        except OSError:
            continue
        for item in names:
            stem, _, kind = item.rpartition(".")
            if kind not in ("dist-info", "egg-info") or _normalised(stem.split("-")[0]) != want:
                continue
            path = os.path.join(entry, item)
            if os.path.isdir(path):
                path = os.path.join(path, "METADATA" if kind == "dist-info" else "PKG-INFO")
            try:
                with open(path, encoding="utf-8") as f:
                    for line in f:
                        if line.startswith("Version:"):
                            return line.split(":", 1)[1].strip()
                        if not line.strip():            # the headers end at a blank line
                            break
            except OSError:
                continue
    return None


def install_pkg_resources_stand_in() -> None:
    """Before ufl/ffcx are imported; nothing is done if pkg_resources is imported already."""
    if "pkg_resources" not in sys.modules:
        sys.modules["pkg_resources"] = _PkgResourcesStandIn("pkg_resources")


_paused = False


def pause_collector() -> None:
    """Turn the cyclic garbage collector off for the start-up (see the module docstring);
    the command line's process only, which calls ``resume_collector`` once set up."""
    global _paused
    if gc.isenabled():
        gc.disable()
        _paused = True


def resume_collector() -> None:
    """Freeze what the start-up made and turn the collector back on, if ``pause_collector``
    turned it off (else nothing: a program that imports vpcontact keeps its own settings)."""
    global _paused
    if _paused:
        gc.freeze()
        gc.enable()
        _paused = False


def quick_exit(code: int, last=None, after_petsc=None):
    """Exit with ``code`` after what the interpreter's teardown would do that matters: flush
    sys.stdout/stderr, run the atexit handlers (logging's among them), finalise PETSc (its
    -log_view report) and MPI (mpirun expects every rank to), flush C's stdio buffers.

    Args:
        code: the exit status.
        last: called with ``code`` after the finalisation, returns the exit status (e.g.
            app/cli/ending.py ``signal_at_exit``); None: ``code``.
        after_petsc: called right after PETSc's finalisation (which puts the signals'
            default actions back: app/cli/ending.py ``hold_signals``), or None.
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
        if after_petsc is not None:
            after_petsc()
    mpi = sys.modules.get("mpi4py.MPI")
    if mpi is not None and mpi.Is_initialized() and not mpi.Is_finalized():
        mpi.Finalize()
    if last is not None:
        code = last(code)
        sys.stderr.flush()
    ctypes.CDLL(None).fflush(None)
    os._exit(code)
