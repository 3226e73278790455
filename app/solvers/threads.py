"""BLAS threads for the few large factorisations of a serial run.

The environment keeps OpenBLAS single-threaded (small dense solves slow down 30-100x with more
threads); a serial run of a large 3D scene has cores idle during its two BLAS-bound kernels,
the G-last CHOLMOD factorisation and the dense Cholesky factorisations of the Gamma3 problem.
``blas_threads`` lets exactly those use the cores this process may run on, and only in a
serial run: under mpirun every rank keeps one thread.  Without threadpoolctl (the Debian
package python3-threadpoolctl) everything stays single-threaded.
"""
from __future__ import annotations

import contextlib
import os

try:
    from threadpoolctl import threadpool_limits
except ImportError:                                   # pragma: no cover - optional
    threadpool_limits = None

# set by the run (app/simulation.py): the cores one serial process may use, 1 under mpirun
_cores = 1
_requested: int | None = None          # `vpcontact run --threads N`


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity).

    Returns:
        At least 1.
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:                            # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def request(threads: int | None) -> None:
    """Ask for a number of threads for the next runs of this process (``run --threads``).

    Args:
        threads: the threads (None: the available cores).
    """
    global _requested
    _requested = threads


def configure(comm_size: int, threads: int | None = None) -> int:
    """Set the threads of the large factorisations for this run.

    Args:
        comm_size: the number of MPI ranks (> 1: one thread per rank).
        threads: the threads asked for (None: ``request``'s, else the available cores).

    Returns:
        The threads the large factorisations will use.
    """
    global _cores
    threads = threads if threads is not None else _requested
    if comm_size > 1 or threadpool_limits is None:
        _cores = 1
    else:
        _cores = max(1, threads if threads is not None else available_cores())
    return _cores


def cores() -> int:
    """The threads of the large factorisations.

    Returns:
        What ``configure`` set (1 before it is called).
    """
    return _cores


def blas_threads(large: bool):
    """A context in which BLAS may use the run's cores (``configure``) if ``large``.

    Args:
        large: whether the operation inside is large enough to gain from threads (a dense
            factorisation of order >= 1000, a 3D sparse factorisation).

    Returns:
        A context manager.
    """
    if not large or _cores <= 1 or threadpool_limits is None:
        return contextlib.nullcontext()
    return threadpool_limits(limits=_cores, user_api="blas")
