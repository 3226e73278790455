"""The Gamma3 part of the error estimate's time part (app/post/gamma3error.py): on elastic
bodies, whose time error comes from the memory and slip sums alone, the estimate of a run
is within [0.5, 2] of its true error against a finer-k reference on the same mesh (the
error measure max_n ||sigma_n - sigma(t_n)||_Q + ||u_n - u(t_n)||_V); the direct memory sum
and the exponential kernel's recursion give the same term."""
import copy

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from conftest import ROOT
from vpcontact.case import validate
from vpcontact.observers import Observer
from vpcontact.post.quantities import norm
from vpcontact.simulation import Simulation


class _Fields(Observer):
    """u_n and sigma_n of every accepted step."""

    def __init__(self):
        self.t, self.fields = [], []

    def step(self, sim, record):
        self.t.append(sim.t)
        self.fields.append((sim.problem.u.x.array.copy(), sim.problem.sigma.x.array.copy()))


def _elastic(name: str, N: int, **contact) -> dict:
    raw = yaml.safe_load((ROOT / "cases" / f"{name}.yaml").read_text())
    raw["material"].pop("viscoplastic")
    raw["mesh"]["n"], raw["time"]["N"] = 8, N
    for key, value in contact.items():
        raw["contact"][key].update(value)
    return raw


def _run(raw: dict):
    sim = Simulation(validate(copy.deepcopy(raw), "test-case"), MPI.COMM_WORLD)
    fields = _Fields()
    sim.add(fields)
    sim.run()
    assert sim.status == "completed"
    return sim, fields


def _true_error(ref_sim, ref, run) -> float:
    """max_n of the measure between a run and the reference at the run's times."""
    p, out = ref_sim.problem, []
    for t, (u, s) in zip(run.t, run.fields, strict=True):
        j = int(np.argmin(np.abs(np.asarray(ref.t) - t)))
        assert ref.t[j] == pytest.approx(t, rel=1e-12)
        p.u.x.array[:] = u - ref.fields[j][0]
        p.sigma.x.array[:] = s - ref.fields[j][1]
        out.append(norm(p, "V") + norm(p, "Q"))
    return max(out)


@pytest.mark.parametrize("name", ["memory", "slip_weakening"])
def test_gamma3_time_estimate_effectivity(name):
    """Measured (h = 1/8, N = 16 against N = 256): memory 1.55, slip weakening 0.71 (the
    slip sum's first step, s_1 = 0, dominates; N = 8: 1.81 and 0.71)."""
    ref_sim, ref = _run(_elastic(name, 256))
    sim, run = _run(_elastic(name, 16))
    estimate = max(r["est_time"] for r in sim.steps)
    assert all(r["est_time"] == r["est_time_gamma3"] for r in sim.steps)   # elastic
    effectivity = estimate / _true_error(ref_sim, ref, run)
    assert 0.5 <= effectivity <= 2.0, effectivity


def test_direct_memory_sum_gives_the_recursion_term():
    """The right sum T_n by the stored history (direct) equals its recursion."""
    est = {}
    for how in ("recursion", "direct"):
        sim, _ = _run(_elastic("memory", 8, memory={"sum": how}))
        est[how] = [r["est_time_gamma3"] for r in sim.steps]
    assert max(est["recursion"]) > 0
    np.testing.assert_allclose(est["direct"], est["recursion"], rtol=1e-8)
