# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: light
#       format_version: '1.5'
# ---

# # A stiff viscosity: explicit, implicit and adaptive history updates
#
# This demo (`demo_stiff_viscosity.py`) takes the paper's example with a ten times smaller
# viscosity $\lambda_1$ and runs it three ways. It illustrates how to:
#
# - load a case file and change keys the way `--set` does on the command line;
# - read the stability indicator of the explicit scheme (3.2)-(3.3) before a run;
# - let an observer stop a run: the blow-up monitor ends an unstable run as "diverged";
# - use the implicit (backward Euler) history update, or adaptive time steps, instead.
#
# Run it from the repository root, serially or on two MPI ranks:
#
#     .venv/bin/python demos/demo_stiff_viscosity.py
#     mpirun -n 2 .venv/bin/python demos/demo_stiff_viscosity.py
#
# As in `demo_wang_cheng.py`, run it with `OPENBLAS_NUM_THREADS=1`.

# +
import logging
import sys
from pathlib import Path

from mpi4py import MPI

from vpcontact import Simulation, validate
from vpcontact.case import load_raw
from vpcontact.post.divergence import BlowUpMonitor

# -

comm = MPI.COMM_WORLD

# Only the application's warnings and errors are shown (on rank 0): the stability warning
# and the divergence are the interesting ones here.

log = logging.getLogger("vpcontact")
handler = logging.StreamHandler(sys.stdout)
handler.setFormatter(logging.Formatter("[vpcontact] %(message)s"))
log.handlers[:] = [handler]
log.setLevel(logging.WARNING if comm.rank == 0 else logging.CRITICAL)
log.propagate = False

# ## The case
#
# The case file of the paper's example, read with `load_raw`, which also applies overrides
# written as on the command line (`section.key=value`). We coarsen the mesh to $h = 1/8$,
# keep $k = 1/16$, and take $\lambda_1 = 10$ instead of 100: the stress relaxes towards the
# yield set ten times faster.

CASE_FILE = Path(__file__).resolve().parents[1] / "cases" / "wang_cheng_2021.yaml"
BASE = ["mesh.n=8", "time.N=16", "material.viscoplastic.lambda1=10"]


# +
def simulate(*changes: str):
    """Run the case with ``changes`` on top of BASE, with the blow-up monitor.

    Args:
        changes: more overrides, e.g. "time.scheme=implicit".

    Returns:
        (the Simulation, its RunSummary).
    """
    case = validate(load_raw(CASE_FILE, [*BASE, *changes]), str(CASE_FILE))
    sim = Simulation(case, comm)
    sim.add(BlowUpMonitor())
    return sim, sim.run()


# -

# ## Explicit history update: unstable at this step
#
# The explicit update $H_n = H_{n-1} + k_n \mathcal G(\sigma_{n-1}, \kappa_{n-1})$ relaxes
# the overstress by a factor $1 - k r$ per step, with rates $r$ up to
# $r_{\max} = \lambda_{\max}(\mathcal E)/(2\lambda_1)$. Beyond $k r_{\max} = 2$ the factor
# is below $-1$ and the overstress grows, alternating in sign. `setup()` computes the
# indicator $k_{\max} r_{\max}$ (`sim.diagnostics`) and warns.
#
# `run()` is the whole loop of `demo_wang_cheng.py` in one call. Every step passes through the
# observers' `check`; the `BlowUpMonitor` compares the largest von Mises stress with a bound
# set by the data and raises `StopRun` when it is exceeded. The run ends as "diverged", its
# summary names the step and the reason, and the state of the last good step is kept.

sim, explicit = simulate()
indicator = sim.diagnostics.as_dict()["stability_indicator"]
rate = sim.diagnostics.relaxation_rate
if comm.rank == 0:
    print(f"explicit, k = 1/16: k r_max = {indicator:.3g} -> {explicit.status} at step "
          f"{explicit.failure.step} ({explicit.failure.reason})")

# ## Implicit history update
#
# `time.scheme: implicit` evaluates $\mathcal G$ and $G$ at the right end point,
# $(\sigma_n, \kappa_n)$: a backward Euler step, stable for any $k$. The stress update is
# then a local nonlinear problem per cell, solved inside every Newton iteration of the step
# problem (with its algorithmic tangent), so a step costs more. Only the SNES VI step solver
# handles it.

_, implicit = simulate("time.scheme=implicit")
last_implicit = implicit.steps[-1]
if comm.rank == 0:
    print(f"implicit, k = 1/16: {implicit.status}, {len(implicit.steps)} steps, "
          f"|u|_V = {last_implicit['norm_u_V']:.6g}, |sigma|_Q = "
          f"{last_implicit['norm_sigma_Q']:.6g}")

# ## Explicit update with adaptive steps
#
# Alternatively the explicit scheme keeps its stability with smaller steps. With
# `time.adaptive` the step control starts from the grid's first step, halves it while
# $k r_{\max}$ exceeds `max_indicator` (default 1: no overshoot) or the step solver fails,
# and grows it after steps that converged in a few Newton iterations; setting any of its
# keys switches it on. Its decisions are in the summary (`step_history`).

sim_adaptive, adaptive = simulate("time.adaptive.max_indicator=1")
ks = [s["k"] for s in adaptive.steps]
last_adaptive = adaptive.steps[-1]
if comm.rank == 0:
    rejected = sum(not d["accepted"] for d in adaptive.step_history)
    print(f"explicit, adaptive: {adaptive.status}, {len(ks)} steps (k = {min(ks):.4g} .. "
          f"{max(ks):.4g}, {rejected} rejected), |u|_V = {last_adaptive['norm_u_V']:.6g}, "
          f"|sigma|_Q = {last_adaptive['norm_sigma_Q']:.6g}")

# ## Checks
#
# The explicit run diverged after its first steps, the two stable runs completed, the
# adaptive steps respect the indicator, and both stable runs approximate the same solution:
# they differ by the time discretisation error, $O(k)$, here well below 2 %.

# +
failures = []


def check(ok: bool, what: str) -> None:
    """Record ``what`` as failed unless ``ok`` holds on every rank."""
    if not comm.allreduce(bool(ok), op=MPI.LAND):
        failures.append(what)


# -

check(indicator > 2 and explicit.status == "diverged" and explicit.failure.step > 1,
      "the explicit run at k = 1/16 diverged")
check(implicit.status == "completed" and len(implicit.steps) == 16, "the implicit run completed")
check(adaptive.status == "completed" and abs(sim_adaptive.t - 1.0) < 1e-12,
      "the adaptive run completed")
check(max(ks) * rate <= 1.0 + 1e-12, "adaptive steps keep k r_max <= 1")
for key in ("norm_u_V", "norm_sigma_Q"):
    a, b = last_implicit[key], last_adaptive[key]
    check(abs(a - b) <= 0.02 * abs(b), f"implicit and adaptive agree ({key})")

# The implicit run's norms at $t_N$, as `./vpcontact run cases/wang_cheng_2021.yaml` with
# the same `--set` options computes them:

if comm.rank == 0:
    print(f"final norm_u_V = {last_implicit['norm_u_V']!r} "
          f"norm_sigma_Q = {last_implicit['norm_sigma_Q']!r}")
    print("checks:", "all passed" if not failures else "FAILED: " + "; ".join(failures))
if failures:
    sys.exit(1)
