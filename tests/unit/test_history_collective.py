"""The explicit history update under MPI (collective_update): a law that fails in the cells
of one rank fails the step on every rank with that rank's message and leaves H, kappa
unchanged on every rank; the ranks are played by a stand-in communicator (two ranks seen
from one), the whole run under mpirun is tests/system/test_collective_failure.py."""
import numpy as np
import pytest
from mpi4py import MPI

from vpcontact.model.history import HistoryUpdateFailure, collective_update


class TwoRanks:
    """Rank ``rank`` of two; the other rank's update failed with ``peer_error`` (or not)."""

    size = 2

    def __init__(self, rank: int, peer_error: str | None):
        self.rank, self.peer_error, self.bcasts = rank, peer_error, 0

    def allreduce(self, value, op):
        assert op == MPI.MIN
        peer = 1 - self.rank if self.peer_error is not None else self.size
        return min(value, peer)

    def bcast(self, obj, root):
        self.bcasts += 1
        return obj if root == self.rank else self.peer_error


def _update(fail: bool):
    """An update that adds k to H and 2 k to kappa in place, or raises before writing."""
    def update(sigma, H, kappa, k):
        if fail:
            raise RuntimeError("von Mises projection: secular equation did not converge")
        H += k
        kappa += 2 * k
    return update


def _state():
    return np.zeros(8), np.array(3.0), np.ones((2, 1))   # H, sigma, kappa


def test_no_failure_updates_and_sends_no_message():
    H, sigma, kappa = _state()
    comm = TwoRanks(0, None)
    collective_update(comm, _update(False), sigma, H, kappa, 0.25)
    assert np.all(H == 0.25) and np.all(kappa == 1.5) and comm.bcasts == 0


def test_a_failure_on_the_other_rank_undoes_this_ranks_update():
    H, sigma, kappa = _state()
    comm = TwoRanks(0, "G or Gk returned non-finite values (NaN/Inf) at 3 cell(s)")
    with pytest.raises(HistoryUpdateFailure) as info:
        collective_update(comm, _update(False), sigma, H, kappa, 0.25)
    assert str(info.value) == ("G or Gk returned non-finite values (NaN/Inf) at 3 cell(s) "
                               "(on rank 1 of 2)")
    assert np.all(H == 0.0) and np.all(kappa == 1.0)      # H_{n-1}, kappa_{n-1} again


def test_a_failure_on_this_rank_is_raised_with_its_message():
    H, sigma, kappa = _state()
    with pytest.raises(HistoryUpdateFailure, match=r"did not converge \(on rank 1 of 2\)$"):
        collective_update(TwoRanks(1, None), _update(True), sigma, H, kappa, 0.25)
    assert np.all(H == 0.0) and np.all(kappa == 1.0)


def test_the_lowest_failing_rank_names_the_failure():
    H, sigma, kappa = _state()
    with pytest.raises(HistoryUpdateFailure, match=r"did not converge \(on rank 0 of 2\)$"):
        collective_update(TwoRanks(0, "the other message"), _update(True), sigma, H, kappa,
                          0.25)


def test_a_bug_is_not_a_failed_step():
    """Only the numerical errors of a step fail it (as in Simulation.advance); a bug in a law
    stays an error of its own."""
    def update(sigma, H, kappa, k):
        raise TypeError("a bug")
    H, sigma, kappa = _state()
    with pytest.raises(TypeError):
        collective_update(TwoRanks(0, None), update, sigma, H, kappa, 0.25)
