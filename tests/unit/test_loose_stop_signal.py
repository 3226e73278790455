"""Simulation.stop_signal, the public read-only view of "a signal asked the run to stop",
and the study's SignalWatch, which reads it (not the simulation's private state) at the end
of each run."""
import os
import signal
import types

import pytest
from mpi4py import MPI

from vpcontact.simulation import Simulation, _StopRequest
from vpcontact.studies.interrupts import SignalWatch


def test_stop_signal_is_none_outside_a_run_and_read_only():
    sim = Simulation(None, MPI.COMM_SELF)
    assert sim.stop_signal is None
    with pytest.raises(AttributeError):
        sim.stop_signal = "SIGINT"


def test_stop_signal_names_the_signal_taken_while_the_run_steps():
    sim = Simulation(None, MPI.COMM_SELF)
    with _StopRequest() as sim._signals:      # what Simulation.run holds while stepping
        assert sim.stop_signal is None
        os.kill(os.getpid(), signal.SIGTERM)
        assert sim.stop_signal == "SIGTERM"


@pytest.mark.parametrize("name", [None, "SIGINT", "SIGTERM"])
def test_signal_watch_takes_the_signal_from_the_public_property(name):
    sim = types.SimpleNamespace(comm=MPI.COMM_SELF, stop_signal=name)   # no private state
    watch = SignalWatch()
    watch.end(sim, None)
    assert watch.signal == name
