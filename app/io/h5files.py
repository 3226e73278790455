"""HDF5 files written with h5py (contact.h5, solution.h5's groups) whose failure is an
OSError and does not crash the process afterwards.

On a full disk, h5py raises a RuntimeError from the write or from closing the file, or
closes it without an error while the ids it frees fail to flush ("file write failed",
printed as "Exception ignored"), and the half-closed file then crashes the process when it
ends (segmentation fault: H5Idec_ref on the file's id at interpreter exit, then serial
HDF5's own termination in H5D_close; exit 139 before or after the run recorded its
failure; observed with a 64 kB tmpfs and Debian's libhdf5_serial 1.10).  ``open_h5``
therefore keeps a failed file's id alive for good (one more reference, never released),
does not print h5py's tracebacks and raises one OSError naming the file and the errno
HDF5 reports; ``h5py_module`` imports h5py with serial HDF5's termination at exit turned
off (H5dont_atexit, before the library starts; files are closed by ``open_h5``, the OS
closes the rest).  The parallel HDF5 of dolfinx's files is app/io/output.py's write_xdmf.
"""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import gc
import io
import os
import re
import sys
from pathlib import Path


def h5py_module():
    """h5py, imported after serial HDF5's termination at exit is turned off (once; if h5py
    was imported before, HDF5 has started and this changes nothing).

    Returns:
        The h5py module.
    """
    if "h5py" not in sys.modules:
        name = ctypes.util.find_library("hdf5_serial")
        try:
            ctypes.CDLL(name).H5dont_atexit()
        except (OSError, AttributeError, TypeError):
            pass
    import h5py
    return h5py


def h5_write_error(path: Path, exc: Exception) -> OSError:
    """The OSError of an HDF5 write that h5py reports as a RuntimeError.

    Args:
        path: the HDF5 file.
        exc: h5py's error (HDF5's message holds the errno, e.g. 'errno = 28').

    Returns:
        OSError(errno, strerror, path): ENOSPC, EFBIG, ... as HDF5 names it, else EIO.
    """
    found = re.search(r"errno = (\d+)", str(exc))
    code = int(found.group(1)) if found else errno.EIO
    return OSError(code, os.strerror(code), str(path))


@contextlib.contextmanager
def open_h5(path: Path, mode: str):
    """An h5py File, closed after; a failed write or close is an OSError and the file's id
    is never released (see the module's docstring).

    Args:
        path: the HDF5 file.
        mode: h5py's mode ("w", "a", "r").

    Yields:
        The open h5py File.

    Raises:
        OSError: the file could not be written or closed.
    """
    h5py = h5py_module()
    f, error, printed = None, None, io.StringIO()   # h5py's tracebacks of ids failing to close
    with contextlib.redirect_stderr(printed):
        try:
            f = h5py.File(path, mode)
            with f:
                yield f
        except RuntimeError as exc:
            if f is not None:
                ctypes.pythonapi.Py_IncRef(ctypes.py_object(f.id))
            error = h5_write_error(path, exc)
        if error is not None:     # the failed write's h5py objects freed (and printing) here
            gc.collect()
    text = printed.getvalue()
    if error is None and "file write failed" in text:    # h5py freed ids that failed to flush
        error = h5_write_error(path, RuntimeError(text))
    if error is not None:
        raise error
    sys.stderr.write(text)
