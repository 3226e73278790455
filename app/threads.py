"""BLAS threads for the few large dense operations of a run, and the cores they run on.

The environment keeps OpenBLAS single-threaded (small dense solves slow down with more
threads: docs/performance.md, section 5).  A serial run of a large 3D scene has cores idle
during its BLAS-bound kernels, the G-last CHOLMOD factorisation and the dense work of the
Gamma3 problem: ``blas_threads`` lets exactly those use the cores this process may run on.

Under mpirun the condensed solver's Gamma3 problem is solved on one rank (GAMMA3_ROOT), while the
others wait asleep in ``idle_bcast`` (spinning in MPI would keep their cores busy).  That
rank's large operations use the cores of every rank on its node: mpirun binds each rank to
one core, so ``blas_threads`` widens the root's affinity to theirs for the operation and
restores it after.  Every other rank keeps one thread.  Without threadpoolctl (the Debian
package python3-threadpoolctl), or where the affinity cannot be widened, everything stays
single-threaded.
"""
from __future__ import annotations

import contextlib
import os
import time

try:
    from threadpoolctl import ThreadpoolController
except ImportError:                                   # pragma: no cover - optional
    ThreadpoolController = None

GAMMA3_ROOT = 0     # the rank that solves the Gamma3 problem under mpirun
IDLE_POLL_S = 2e-4  # how often a waiting rank looks whether the root is done

# set by the run (app/simulation.py): the threads of the large operations of this rank
_cores = 1
_lent: set[int] | None = None          # mpirun, on GAMMA3_ROOT: its node's ranks' cores
_requested: int | None = None          # `vpcontact run --threads N`
_controller = None                     # the loaded BLAS libraries, found once (_blas)


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


def configure(comm, threads: int | None = None) -> int:
    """Set the threads of the large operations of this rank for a run (collective).

    Args:
        comm: the run's communicator (mpi4py).
        threads: the threads asked for (None: ``request``'s, else the available cores;
            under mpirun, on GAMMA3_ROOT, the cores of the ranks on its node).

    Returns:
        The threads this rank's large operations will use.
    """
    global _cores, _lent
    threads = threads if threads is not None else _requested
    _lent = None
    if comm.size == 1:
        _cores = 1 if ThreadpoolController is None else \
            max(1, threads if threads is not None else available_cores())
        return _cores
    lent = _node_cores(comm)
    _cores = 1
    if lent is not None and ThreadpoolController is not None and _can_widen(lent):
        _cores, _lent = max(1, min(threads or len(lent), len(lent))), lent
    return _cores


def _node_cores(comm) -> set[int] | None:
    """On GAMMA3_ROOT, the cores of the ranks on its node (collective); None elsewhere."""
    from mpi4py import MPI
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        parts = node.allgather((comm.rank, sorted(os.sched_getaffinity(0))))
    finally:
        node.Free()
    if comm.rank != GAMMA3_ROOT:
        return None
    return {core for _, cores in parts for core in cores}


def _can_widen(cores: set[int]) -> bool:
    """Whether this process may run on ``cores`` (a cpuset may forbid it)."""
    own = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, cores)
    except OSError:
        return False
    os.sched_setaffinity(0, own)
    return True


def cores() -> int:
    """The threads of this rank's large operations.

    Returns:
        What ``configure`` set (1 before it is called).
    """
    return _cores


def own_cores() -> int:
    """The threads of this rank's work while every rank computes: ``cores()`` of a serial
    run, 1 under mpirun (the cores GAMMA3_ROOT borrows are its sleeping neighbours').

    Returns:
        The number of threads.
    """
    return _cores if _lent is None else 1


def blas_threads(large: bool):
    """A context in which BLAS may use the run's cores (``configure``) if ``large``.

    Args:
        large: whether the operation inside is large enough to gain from threads (a dense
            factorisation of order >= 1000, a 3D sparse factorisation).

    Returns:
        A context manager.
    """
    if not large or _cores <= 1 or ThreadpoolController is None:
        return contextlib.nullcontext()
    return _threads(_cores, _lent)


@contextlib.contextmanager
def _threads(n: int, lent: set[int] | None):
    """n BLAS threads; on the cores ``lent`` (then restored) if given.  (OpenBLAS starts its
    threads on the caller's cores, so they keep them.)"""
    own = os.sched_getaffinity(0) if lent else None
    if lent:
        os.sched_setaffinity(0, lent)
    try:
        with _blas().limit(limits=n, user_api="blas"):
            yield
    finally:
        if own is not None:
            os.sched_setaffinity(0, own)


def _blas():
    """threadpoolctl's controller of the BLAS libraries loaded (numpy's, which CHOLMOD and
    LAPACK share), found at the first use: a new search of the process's libraries at every
    ``blas_threads`` was slow, and there are many (docs/performance.md, section 9)."""
    global _controller
    if _controller is None:
        _controller = ThreadpoolController()
    return _controller


def idle_bcast(comm, obj=None):
    """``comm.bcast(obj, root=GAMMA3_ROOT)`` for ranks with nothing to do until the root
    is done: they sleep between polls of a non-blocking barrier instead of spinning in MPI,
    so the root's threads have their cores (collective).

    Args:
        comm: the communicator (mpi4py).
        obj: what the root sends (ignored elsewhere).

    Returns:
        The root's ``obj`` on every rank.
    """
    if comm.size == 1:
        return obj
    request = comm.Ibarrier()
    if comm.rank != GAMMA3_ROOT:
        while not request.Test():
            time.sleep(IDLE_POLL_S)
    else:
        request.Wait()
    return comm.bcast(obj, root=GAMMA3_ROOT)


def root_call(comm, work):
    """``work()`` on GAMMA3_ROOT while the other ranks wait asleep (``idle_bcast``); its
    result, or the exception it raised, on every rank (collective).

    Args:
        comm: the communicator (mpi4py).
        work: called on the root only; its result must pickle (it is broadcast).

    Returns:
        ``work()``'s result, on every rank.

    Raises:
        The exception ``work()`` raised (a copy on the other ranks), on every rank.
    """
    result, failure = None, None
    if comm.rank == GAMMA3_ROOT:
        try:
            result = work()
        except Exception as exc:             # every rank raises it, none waits for ever
            failure = exc
    result, failure = idle_bcast(comm, (result, failure))
    if failure is not None:
        raise failure
    return result
