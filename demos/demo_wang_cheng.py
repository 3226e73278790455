# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: light
#       format_version: '1.5'
# ---

# # A viscoplastic body pressed onto a foundation (Wang & Cheng 2021, Section 4)
#
# This demo (`demo_wang_cheng.py`) runs the paper's numerical example through the
# Python API of vpcontact, step by step. It illustrates how to:
#
# - write a case in Python, one model term at a time, and validate it;
# - set up a `Simulation` (`app/simulation.py`) and drive the time loop of
#   scheme (3.2)-(3.4) yourself with `step()`;
# - watch a run with an observer of your own, next to the stock `FieldOutput` observer that
#   writes `solution.xdmf`;
# - check the discrete contact laws (4.1)-(4.2) at every $\Gamma_3$ node, in parallel.
#
# Run it from the repository root, serially or on two MPI ranks:
#
#     .venv/bin/python demos/demo_wang_cheng.py
#     mpirun -n 2 .venv/bin/python demos/demo_wang_cheng.py
#
# (as root, mpirun needs `OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1`).
# The fields go to `$VPCONTACT_DEMO_OUT`, else to `vpcontact-demos/wang_cheng` under the
# system's temporary directory.
#
# Importing `vpcontact` changes nothing in the process. Multithreaded OpenBLAS makes the small
# per-cell algebra much slower: run with `OPENBLAS_NUM_THREADS=1` (the command line sets it
# itself).

# +
import logging
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
from mpi4py import MPI

from vpcontact import FieldOutput, Observer, Simulation, validate
from vpcontact.model.contact_laws import PiecewiseLinearFriction
from vpcontact.post.quantities import contact_table

# -

# The application reports through the `vpcontact` logger (mesh size, stability indicator,
# step solver); the messages are collective, so rank 0 shows them.

comm = MPI.COMM_WORLD
log = logging.getLogger("vpcontact")
handler = logging.StreamHandler(sys.stdout)
handler.setFormatter(logging.Formatter("[vpcontact] %(message)s"))
log.handlers[:] = [handler]
log.setLevel(logging.INFO if comm.rank == 0 else logging.CRITICAL)
log.propagate = False

# ## The case
#
# A case is a dictionary of sections, exactly as a YAML case file reads (the file
# `cases/wang_cheng_2021.yaml` holds this one). We build it section by section.
#
# The body $\Omega = (0, L_1) \times (0, L_2)$ is the unit square, meshed with $n \times n$
# squares cut along one diagonal. Its left side $\Gamma_1$ is clamped, the right side and the
# top form $\Gamma_2$ (tractions), and the bottom $\Gamma_3$ touches the foundation. The
# resolution $h = k = 1/16$ is that of the case file; the run takes about a second.

n = N = 16
case_data = {"name": "wang_cheng_2021",
             "mesh": {"L1": 1.0, "L2": 1.0, "kind": "structured", "n": n, "diagonal": "right"}}

# The material: plane-stress elasticity $\mathcal E$ with Young's modulus $E$ and Poisson's
# ratio $\nu$, and the Perzyna viscoplastic law of the paper's Section 4,
#
# $$\mathcal G(\sigma, \kappa) = -\frac{1}{2\lambda_1}\,\mathcal E\bigl(\sigma -
# P_{K(\kappa)}\sigma\bigr), \qquad G(\sigma, \kappa) = \frac{2}{3\lambda_2}
# \Vert \sigma - P_{K(\kappa)}\sigma\Vert_{VM},$$
#
# where $P_{K(\kappa)}$ projects onto the von Mises ball $K(\kappa)$ of radius $\kappa$ (in
# the energy inner product) and $\kappa_0 = 0$ is the initial hardening. Only the stress
# outside the ball relaxes, with the viscosities $\lambda_1$ and $\lambda_2$. These two rates
# drive the history terms $H_n$ and $\kappa_n$ of (3.2)-(3.3).

case_data["material"] = {"E": 1000.0, "nu": 0.4,
                         "viscoplastic": {"lambda1": 100.0, "lambda2": 100.0, "kappa0": 0.0}}

# The contact on $\Gamma_3$ has three parts (law (4.1) and (4.2)):
#
# - normal compliance $-\sigma_\nu = p(u_\nu) = c_\nu u_\nu^+$ for a penetration
#   $u_\nu$ below the bound $g$,
# - the unilateral constraint $u_\nu \le g$: the penetration stops at $g$, where the
#   contact pressure may exceed $c_\nu g$,
# - nonmonotone friction: $|\sigma_\tau| = \psi'(|u_\tau|)$ while slipping, with
#   $\psi'(r) = b - c_1 r$ for $r \le u_1$ (softening) and $c_2 (r - u_1) + b - c_1 u_1$
#   beyond (hardening).

case_data["contact"] = {"g": 0.012,
                        "normal_compliance": {"c_nu": 100.0},
                        "friction": {"b": 1.0, "c1": 60.0, "c2": 60.0, "u1": 0.01}}

# The loads: no body force, a downward traction on the top and a leftward one on the right
# side, constant in time (a value may also be an expression of x, y, t or a table in t).

case_data["loads"] = {"f0": [0.0, 0.0],
                      "traction": {"top": [0.0, -8.0], "right": [-3.2, 0.0]}}

# Time: $N$ uniform steps $k = T/N$ on $[0, T]$. The step problem (3.4) is solved by PETSc's
# SNES VI (a semismooth Newton method for the bound $u_\nu \le g$) with the nodal (vertex)
# quadrature on $\Gamma_3$, which makes the contact laws hold node by node. `every: 1` writes
# the fields at every step.

case_data["time"] = {"T": 1.0, "N": N}
case_data["solver"] = {"method": "snes_vi", "quadrature": "vertex"}
case_data["output"] = {"every": 1}

# `validate` checks the dictionary against the schema (the same one the command line uses)
# and returns a `Case`: typed sections with the defaults filled in. A bad value raises
# `CaseError` with one line naming the key.

case = validate(case_data, "demo_wang_cheng")

# ## Setting up the simulation
#
# `Simulation(case, comm, outdir)` holds one run. `setup()` builds, collectively over the
# ranks of `comm`:
#
# - the mesh with its boundary tags (`sim.domain`),
# - the discrete problem `sim.problem`: the spaces $V^h$ (P1), $Q^h$ (DG0 tensors for
#   $\sigma$, $H_n$), $Y^h$ (DG0 for $\kappa$), the compiled forms of the step functional
#   $J_n$, the Dirichlet condition on $\Gamma_1$ and the bound $u_\nu \le g$,
# - the viscoplastic history `sim.history` ($H_0 = 0$, $\kappa_0$) and, for cases with the
#   memory or slip terms, their history on $\Gamma_3$ (`sim.gamma3_history`, None here),
# - the step solver `sim.solver` (here SNES VI; `select_solver` makes the choice),
# - the step control `sim.stepper` and the diagnostics (stability indicator of the explicit
#   scheme, well-posedness condition (2.6)), logged above the first step.

out_default = Path(tempfile.gettempdir()) / "vpcontact-demos" / "wang_cheng"
outdir = Path(os.environ.get("VPCONTACT_DEMO_OUT", out_default))
if comm.rank == 0:
    outdir.mkdir(parents=True, exist_ok=True)
comm.barrier()

sim = Simulation(case, comm, outdir=outdir)
sim.setup()
problem = sim.problem

# ## An observer of our own
#
# Everything that watches a run is an `Observer` (`app/observers.py`) with
# four hooks: `start` (before the first step), `check` (a step is solved: raise `StopRun` to
# refuse it), `step` (the step was accepted) and `end`. This one keeps, per step, the state
# of the $\Gamma_3$ nodes and the largest contact pressure, from the problem's contact table
# (per owned node: $u_\nu$, $u_\tau$, $-\sigma_\nu$, $-\sigma_\tau$). Each rank owns some of
# the nodes, so the counts are summed and the maximum is taken over the ranks.


# +
class ContactWatch(Observer):
    """Per accepted step: Gamma3 nodes at the bound, in compliance and separated, and the
    largest contact pressure -sigma_nu (the same numbers on every rank)."""

    def __init__(self):
        self.rows = []

    def step(self, sim, record):
        table = contact_table(sim.problem)
        g = sim.case.contact.g
        u_nu = table["u_nu"]
        at_bound = u_nu >= g * (1 - 1e-9)
        local = np.array([at_bound.sum(), (~at_bound & (u_nu > 0)).sum(), (u_nu <= 0).sum()])
        counts = sim.comm.allreduce(local, op=MPI.SUM)
        pressure = sim.comm.allreduce(float(np.max(table["neg_sigma_nu"], initial=-np.inf)),
                                      op=MPI.MAX)
        self.rows.append({"n": sim.n, "bound": int(counts[0]), "compliance": int(counts[1]),
                          "separated": int(counts[2]), "max_pressure": pressure})


# -

# The stock `FieldOutput` observer writes $u$, $\sigma$, $\Vert\sigma\Vert_{VM}$ and
# $\kappa$ to `solution.xdmf` in `sim.outdir` (every `output.every` steps and the last).
# Observers are called in the order they are added.

watch = ContactWatch()
sim.add(FieldOutput()).add(watch)

# ## The time loop
#
# `sim.run()` does all of this in one call (and lets Ctrl-C end a run after a step, as the
# command line does). Here we drive the loop ourselves: `start()` (the observers' `start`),
# `step()` until the step control reaches $T$, then `finish()` (the run summary, the
# observers' `end`, and the step solver's PETSc objects freed).
#
# One call of `step()` takes the state from $t_{n-1}$ to $t_n$ (`Simulation.advance`):
#
# 1. $H_n = H_{n-1} + k_n \mathcal G(\sigma_{n-1}, \kappa_{n-1})$ and
#    $\kappa_n = \kappa_{n-1} + k_n G(\sigma_{n-1}, \kappa_{n-1})$ (3.2)-(3.3), from the
#    previous step: the scheme is explicit in the history;
# 2. the memory term $\xi_n$ and the accumulated slip $s_n$ on $\Gamma_3$ from $u_{n-1}$
#    (not in this case);
# 3. the loads $f_n$ at $t_n$;
# 4. $u_n \in U^h = \{v : v_\nu \le g \text{ at the } \Gamma_3 \text{ nodes}\}$ from the
#    step inequality (3.4), i.e. the minimiser of
#    $J_n(v) = \tfrac12 (\mathcal E\varepsilon(v), \varepsilon(v)) + (H_n, \varepsilon(v))
#    - f_n(v) + \int_{\Gamma_3} P(v_\nu) + j_\tau(v_\tau)$ (plus the memory and slip terms
#    when the case has them; the step solver);
# 5. $\sigma_n = \mathcal E \varepsilon(u_n) + H_n$ (3.2).
#
# The step is then recorded (norms $\Vert u_n\Vert_V$, $\Vert\sigma_n\Vert_Q$, Newton
# iterations, ...), checked and accepted by the observers. `step()` returns the record.
#
# We take the first step on its own and look at its record. Because $\sigma_0 = 0$ lies in
# the yield set $K(\kappa_0)$, $\mathcal G(\sigma_0, \kappa_0) = 0$ and $H_1 = H_0 = 0$: the
# first step is purely elastic, the viscoplastic flow enters from step 2 on.

sim.start()
record = sim.step()
H1 = comm.allreduce(float(np.max(np.abs(problem.H.x.array), initial=0.0)), op=MPI.MAX)
if comm.rank == 0:
    print("step 1:", {key: record[key] for key in ("t", "k", "norm_u_V", "norm_sigma_Q",
                                                    "newton_iterations")}, "max |H_1| =", H1)

# The remaining steps, until the step control reaches $T$; then `finish()`: the run's
# summary (the content of a command line run's `summary.json`) and the observers' `end`,
# which closes the XDMF file.

while not sim.finished:
    sim.step()
summary = sim.finish()

# ## Results
#
# Rank 0 prints one line per step: the norms of the step record (reduced over the ranks),
# the largest von Mises stress, the Newton iterations and the observer's $\Gamma_3$ states.

if comm.rank == 0:
    print(f"\n{'n':>3} {'t':>7} {'|u|_V':>12} {'|sigma|_Q':>12} {'max vm':>9} {'its':>4} "
          f"{'bound':>6} {'compl':>6} {'sep':>4} {'max p':>8}")
    for rec, row in zip(sim.steps, watch.rows):
        print(f"{rec['n']:3d} {rec['t']:7.4f} {rec['norm_u_V']:12.6e} "
              f"{rec['norm_sigma_Q']:12.6e} {rec['max_vm']:9.4f} {rec['newton_iterations']:4d} "
              f"{row['bound']:6d} {row['compliance']:6d} {row['separated']:4d} "
              f"{row['max_pressure']:8.4f}")

# ## Checks
#
# The demo ends by checking what can go wrong. Every test is decided on all ranks alike
# (a logical AND over the ranks), so that either every rank passes or every rank fails.

# +
failures = []


def check(ok: bool, what: str) -> None:
    """Record ``what`` as failed unless ``ok`` holds on every rank."""
    if not comm.allreduce(bool(ok), op=MPI.LAND):
        failures.append(what)


# -

# The run reached $T$ in $N$ steps, and the first step was elastic.

check(summary.status == "completed" and sim.n == N and abs(sim.t - case.time.T) < 1e-12,
      "the run completed all steps")
check(H1 == 0.0, "H_1 = 0 (the explicit history lags one step)")

# The contact laws at $t_N$, node by node (tolerances relative to the force scale
# $c_\nu g$): the constraint $u_\nu \le g$ holds; the contact pressure is never negative;
# law (4.1) gives no force on separated nodes, $c_\nu u_\nu$ in compliance and at least
# $c_\nu g$ at the bound; law (4.2) gives $|\sigma_\tau| = \psi'(|u_\tau|)$ where the node
# slips. The friction term is regularised as $\sqrt{|u_\tau|^2 + \delta^2}$, which changes
# the force by $O(\delta^2/|u_\tau|^2)$.

c = case.contact
fr = c.friction
table = contact_table(problem)
u_nu, p_nu = table["u_nu"], table["neg_sigma_nu"]
u_tau, p_tau = table["u_tau"], table["neg_sigma_tau"]
tol = 1e-7 * c.c_nu * c.g
at_bound, separated = u_nu >= c.g * (1 - 1e-9), u_nu <= 0
inside = ~at_bound & ~separated
slip = np.abs(u_tau) > 1e-5
check(np.all(u_nu <= c.g * (1 + 1e-12)), "u_nu <= g on Gamma3")
check(np.all(p_nu >= -tol), "contact pressure -sigma_nu >= 0")
check(np.all(np.abs(p_nu[separated]) <= tol), "(4.1): no force where separated")
check(np.allclose(p_nu[inside], c.c_nu * u_nu[inside], rtol=0.0, atol=tol),
      "(4.1): -sigma_nu = c_nu u_nu in compliance")
check(np.all(p_nu[at_bound] >= c.c_nu * c.g - tol), "(4.1): -sigma_nu >= c_nu g at the bound")
psi = PiecewiseLinearFriction(fr.b, fr.c1, fr.c2, fr.u1)
expected = psi.derivative(np.abs(u_tau[slip])) * np.sign(u_tau[slip])
check(np.allclose(p_tau[slip], expected, rtol=1e-6, atol=tol), "(4.2): friction on slip")

# The paper's picture at $T$: part of $\Gamma_3$ at the bound, part in compliance, and every
# node slipping (so none of the checks above was vacuous).

nodes = comm.allreduce(len(u_nu), op=MPI.SUM)
check(comm.allreduce(int(at_bound.sum())) > 0 and comm.allreduce(int(inside.sum())) > 0
      and comm.allreduce(int(slip.sum())) == nodes, "bound, compliance and slip at T")

# The demo's own counts agree with the contact table, and the norms of the records are
# global: every rank holds the same values (a norm summed over the local cells only would
# differ between ranks).

last = watch.rows[-1]
check(last["bound"] + last["compliance"] + last["separated"] == nodes, "node counts")
norms = (summary.steps[-1]["norm_u_V"], summary.steps[-1]["norm_sigma_Q"])
check(all(x == norms for x in comm.allgather(norms)), "norms equal on every rank")
check(len(watch.rows) == len(sim.steps) == N, "the observer saw every step")

# The field output exists (written by rank 0, collectively).

check(comm.rank != 0 or (outdir / "solution.xdmf").is_file()
      and (outdir / "solution.h5").is_file(), "solution.xdmf and solution.h5 written")

# Finally the two norms at $t_N$ with all their digits: the same on any number of ranks
# (to round-off), and the same as `./vpcontact run cases/wang_cheng_2021.yaml` computes.

if comm.rank == 0:
    print(f"\nGamma3 nodes at T: {last['bound']} at the bound, {last['compliance']} in "
          f"compliance, {last['separated']} separated; fields in {outdir / 'solution.xdmf'}")
    print(f"final norm_u_V = {norms[0]!r} norm_sigma_Q = {norms[1]!r}")
    print("checks:", "all passed" if not failures else "FAILED: " + "; ".join(failures))
if failures:
    sys.exit(1)
