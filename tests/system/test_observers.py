"""The Simulation's observer interface: every observer sees start, each step and end in
order; an observer raising StopRun ends the run with that status; the state() interface
undoes a step exactly."""
import numpy as np
import pytest
from mpi4py import MPI

from conftest import make_case
from vpcontact.observers import Observer, StopRun
from vpcontact.records import StepFailure
from vpcontact.simulation import Simulation, run

TINY = dict(mesh={"n": 4}, time={"T": 1.0, "N": 3})


class Recorder(Observer):
    def __init__(self):
        self.calls = []

    def start(self, sim):
        self.calls.append(("start", sim.n, sim.t))

    def check(self, sim, record):
        self.calls.append(("check", record["n"], len(sim.steps)))

    def step(self, sim, record):
        assert sim.steps[-1] is record
        self.calls.append(("step", sim.n, record["t"]))

    def end(self, sim, summary):
        self.calls.append(("end", summary.status, summary.last_good_step))


def test_a_recording_observer_sees_start_every_step_and_end():
    rec = Recorder()
    res = run(make_case(**TINY), MPI.COMM_WORLD, [rec])
    assert res.status == "completed"
    assert rec.calls == [("start", 0, 0.0),
                         ("check", 1, 0), ("step", 1, pytest.approx(1 / 3)),
                         ("check", 2, 1), ("step", 2, pytest.approx(2 / 3)),
                         ("check", 3, 2), ("step", 3, 1.0),
                         ("end", "completed", 3)]


class StopAt(Observer):
    def __init__(self, n, hook):
        self.n, self.hook = n, hook

    def _stop(self, sim):
        if sim.n == self.n:
            raise StopRun("diverged", StepFailure(sim.n, sim.t, "stopped by a test",
                                                  hint="none"))

    def check(self, sim, record):
        if self.hook == "check":
            self._stop(sim)

    def step(self, sim, record):
        if self.hook == "step":
            self._stop(sim)


@pytest.mark.parametrize("hook, last_good", [("check", 1), ("step", 2)])
def test_stop_run_ends_the_run_with_its_status(hook, last_good):
    """StopRun from check refuses step 2 (the last good step is 1); from step it stops
    after step 2 was accepted."""
    rec = Recorder()
    res = run(make_case(**TINY), MPI.COMM_WORLD, [StopAt(2, hook), rec])
    s = res.summary
    assert res.status == s["status"] == "diverged"
    assert s["failure"] == {"step": 2, "t": pytest.approx(2 / 3), "reason": "stopped by a test",
                            "snes_reason": None, "hint": "none"}
    assert s["last_good_step"] == last_good == len(s["steps"]) == s["time"]["N"]
    assert rec.calls[-1] == ("end", "diverged", last_good)


def test_step_by_step_and_state_round_trip():
    """setup(), then step() by hand; load_state(state()) of step 1 and advancing again
    reproduces step 2 exactly."""
    sim = Simulation(make_case(**TINY, contact={"memory": {"b0": 50.0, "beta": 1.0}}),
                     MPI.COMM_WORLD)
    sim.setup()
    assert sim.gamma3_history is not None and sim.history is not None
    first = sim.step()
    assert first["n"] == sim.n == 1 and sim.steps == [first]
    saved, u1 = sim.state(), sim.problem.u.x.array.copy()
    second = sim.step()
    u2, sigma2 = sim.problem.u.x.array.copy(), sim.problem.sigma.x.array.copy()
    sim.load_state(saved)
    sim.problem.u.x.array[:] = u1
    sim.n, sim.t = 1, first["t"]
    sim.stepper.load_state({**sim.stepper.state(), "n": 1})
    sim.advance(second["k"], second["t"])
    np.testing.assert_allclose(sim.problem.u.x.array, u2, rtol=0, atol=1e-14)
    np.testing.assert_allclose(sim.problem.sigma.x.array, sigma2, rtol=0, atol=1e-12)
    sim.solver.destroy()
