"""threads.py: BLAS threads for the large factorisations of a serial run only."""
import pytest

from app.solvers import threads

threadpoolctl = pytest.importorskip("threadpoolctl")


def _blas_threads():
    return [p["num_threads"] for p in threadpoolctl.threadpool_info() if p["user_api"] == "blas"]


def test_threads_only_for_large_operations_of_a_serial_run(monkeypatch):
    import numpy  # noqa: F401  (loads BLAS)
    monkeypatch.setattr(threads, "_cores", 1)
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    before = _blas_threads()
    assert threads.configure(comm_size=2) == 1                 # mpirun: one per rank
    with threads.blas_threads(large=True):
        assert _blas_threads() == before
    assert threads.configure(comm_size=1) == 2 == threads.cores()
    with threads.blas_threads(large=False):
        assert _blas_threads() == before
    with threads.blas_threads(large=True):
        assert set(_blas_threads()) == {2}
    assert _blas_threads() == before                            # restored on exit
    assert threads.configure(comm_size=1, threads=1) == 1
