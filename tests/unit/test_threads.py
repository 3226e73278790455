"""threads.py: BLAS threads for the large dense operations, in a serial run and on the rank
that solves the Gamma3 problem under mpirun (with the cores of its node's ranks)."""
import os

import pytest
from mpi4py import MPI

from vpcontact import threads

threadpoolctl = pytest.importorskip("threadpoolctl")


def _blas_threads():
    return [p["num_threads"] for p in threadpoolctl.threadpool_info() if p["user_api"] == "blas"]


class _Node:
    """A node communicator of two ranks bound to cores 0 and 1 (as mpirun binds them)."""

    def allgather(self, item):
        return [(0, [0]), (1, [1])]

    def Free(self):
        pass


class _World:
    def __init__(self, rank):
        self.rank, self.size = rank, 2

    def Split_type(self, kind):
        assert kind == MPI.COMM_TYPE_SHARED
        return _Node()


def test_threads_only_for_large_operations_of_a_serial_run(monkeypatch):
    import numpy  # noqa: F401  (loads BLAS)
    monkeypatch.setattr(threads, "_cores", 1)
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    before = _blas_threads()
    assert threads.configure(MPI.COMM_SELF) == 2 == threads.cores()
    with threads.blas_threads(large=False):
        assert _blas_threads() == before
    with threads.blas_threads(large=True):
        assert set(_blas_threads()) == {2}
    assert _blas_threads() == before                            # restored on exit
    assert threads.configure(MPI.COMM_SELF, threads=1) == 1


def test_under_mpirun_the_gamma3_rank_borrows_its_node_cores(monkeypatch):
    monkeypatch.setattr(threads, "_can_widen", lambda cores: True)
    assert threads.configure(_World(rank=1)) == 1               # waits for the root
    with threads.blas_threads(large=True):
        assert threads._lent is None
    assert threads.configure(_World(rank=threads.GAMMA3_ROOT)) == 2
    assert threads._lent == {0, 1}
    assert threads.configure(_World(rank=threads.GAMMA3_ROOT), threads=1) == 1
    monkeypatch.setattr(threads, "_can_widen", lambda cores: False)   # a cpuset forbids it
    assert threads.configure(_World(rank=threads.GAMMA3_ROOT)) == 1
    threads.configure(MPI.COMM_SELF)


def test_borrowed_cores_only_inside_the_operation(monkeypatch):
    import numpy  # noqa: F401  (loads BLAS)
    own = os.sched_getaffinity(0)
    if len(own) < 2:
        pytest.skip("one core")
    first = {min(own)}
    os.sched_setaffinity(0, first)                  # bound to one core, as under mpirun
    try:
        monkeypatch.setattr(threads, "_cores", 2)
        monkeypatch.setattr(threads, "_lent", set(own))
        with threads.blas_threads(large=True):
            assert os.sched_getaffinity(0) == own and set(_blas_threads()) == {2}
        assert os.sched_getaffinity(0) == first
    finally:
        os.sched_setaffinity(0, own)


def test_idle_bcast_on_one_rank_returns_the_object():
    assert threads.idle_bcast(MPI.COMM_SELF, (3, None)) == (3, None)
