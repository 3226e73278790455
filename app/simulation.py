"""The time loop of scheme (3.2)-(3.4): for n = 1..N build H_n, kappa_n, xi_n, s_n from step
n-1, set the loads f_n, solve the step inequality for u_n (SNES VI), set
sigma_n = E eps(u_n) + H_n, record, write.  Steps k_n = t_n - t_{n-1} may vary.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from meshes import build_box, build_rectangle

from app.io import checkpoint
from app.io.case import Case
from app.post.diagnostics import diagnose
from app.model.gamma3 import Gamma3History, Kernel
from app.model.history import ImplicitViscoplasticHistory, ViscoplasticHistory
from app.cli.progress import Progress
from app.post.divergence import BlowUpMonitor
from app.io.output import FieldWriter, OutputError, write_contact_csv, write_json
from app.model.problem import ContactProblem
from app.solvers.snesvi import SNESVISolver, StepFailure, describe_petsc_error
from app.model.stepping import StepTooSmall, make_stepper

log = logging.getLogger("vpcontact")


@dataclass
class RunResult:
    status: str
    summary: dict
    problem: ContactProblem = field(repr=False)
    history: ViscoplasticHistory | None = field(repr=False, default=None)
    gamma3_history: Gamma3History | None = field(repr=False, default=None)


def build_mesh(case: Case, comm):
    m = case.mesh
    size = {"n": m.n} if m.kind == "structured" else {"h": m.h}
    if m.dim == 3:
        return build_box(comm, m.L1, m.L2, m.L3, **size)
    return build_rectangle(comm, m.L1, m.L2, diagonal=m.diagonal, **size)


def build_gamma3_history(case: Case, problem) -> Gamma3History | None:
    """The memory term and accumulated slip, only if the case enables them."""
    c = case.contact
    memory = slip = None
    if c.memory is not None:
        mk = c.memory
        kernel = Kernel(mk.kernel, mk.b0, beta=mk.beta, alpha=mk.alpha or 1.0,
                        tau=mk.tau or 1.0, table=mk.table)
        memory = {"kernel": kernel,
                  "recursion": None if mk.sum == "auto" else mk.sum == "recursion"}
    if c.friction is not None and c.friction.slip is not None:
        slip = {"theta_inf": c.friction.slip.theta_inf, "s0": c.friction.slip.s0}
    if memory is None and slip is None:
        return None
    return Gamma3History(problem, memory=memory, slip=slip)


AUTO_FAST_MAX_GAMMA3_DOFS = 3000


def make_solver(case: Case, problem):
    """The step solver the case asks for (solver.method); auto picks the fast one where it
    applies and the Gamma3 problem is small enough for dense algebra."""
    from app.io.case import CaseError
    from app.solvers.fast import FastStepSolver, eligible

    method = case.numerics.method
    ok, why = eligible(case)
    if method == "fast" and not ok:
        raise CaseError(f"{case.source}: solver.method: 'fast' is not possible here: {why} "
                        "(allowed: snes_vi, auto)")
    if method == "auto":
        n_g = problem.comm.allreduce(len(problem.gamma3.nodes) if problem.gamma3 else 0)
        method = "fast" if ok and n_g * problem.dim <= AUTO_FAST_MAX_GAMMA3_DOFS else "snes_vi"
    if method == "fast":
        return FastStepSolver(problem, case.petsc)
    return SNESVISolver(problem, case.petsc)


def _step_record(problem, history, n, t, its, wall, norms=None):
    """The step's line of summary.json; ``norms`` = (||u||_V, ||sigma||_Q) if the stress
    update computed them already (problem.update_sigma), else they are computed here."""
    kappa = history.kappa if history else None
    norm_u, norm_sigma = norms or (problem.norm("V"), problem.norm("Q"))
    return {
        "n": n, "t": t,
        "norm_u_V": norm_u,
        "norm_sigma_Q": norm_sigma,
        "norm_kappa_Y": problem.cell_norm(kappa) if kappa else 0.0,
        "max_vm": problem.cell_max(problem.sigma_vm),
        "max_kappa": problem.cell_max(kappa) if kappa else 0.0,
        "newton_iterations": its,
        "wall_s": wall,
    }


class _StopRequest:
    """SIGINT / SIGTERM set a flag; the time loop ends after the current step."""

    def __init__(self):
        self.signal = None
        self._old = {}

    def __enter__(self):
        import signal
        import threading
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def _handler(self, signum, frame):
        import signal
        self.signal = signal.Signals(signum).name

    def __exit__(self, *exc):
        import signal
        for sig, old in self._old.items():
            signal.signal(sig, old)
        return False


def run(case: Case, outdir: Path | None, comm, write_outputs: bool = True,
        on_step=None, restart=None, progress: bool = False) -> RunResult:
    """Run the case; write outputs to ``outdir`` (created by the caller) if asked.

    ``on_step(n, t, problem, history)`` is called for n = 0 (initial state) and after every
    converged step.  ``restart`` (app/io/checkpoint.Checkpoint) continues from its step n;
    ``progress`` shows the progress bar (rank 0).  A step's ``wall_s`` covers the history
    update, the step solve and the stress update only: not mesh generation, JIT
    compilation, outputs or ``on_step``.
    """
    t_start = time.perf_counter()
    rect = build_mesh(case, comm)
    problem = ContactProblem(case, rect)
    vp = case.material.viscoplastic
    history = None
    if vp:
        cls = ImplicitViscoplasticHistory if problem.implicit else ViscoplasticHistory
        history = cls(problem, vp.lambda1, vp.lambda2)
    problem.set_initial_values(history.kappa if history else None)
    g3 = build_gamma3_history(case, problem)
    solver = make_solver(case, problem)
    t_setup = time.perf_counter() - t_start
    ks = [b - a for a, b in zip(case.time.times, case.time.times[1:])]
    log.info("case %s (%dD): %d cells, %d vertices, %d dofs, %d steps (k = %s)", case.name,
             problem.dim, problem.num_cells, problem.num_vertices, problem.num_dofs,
             case.time.N, f"{ks[0]:g}" if case.time.uniform else f"{min(ks):g}..{max(ks):g}")
    if case.time.adaptive is not None:
        log.info("adaptive time steps: starting from k = %g to T = %g", ks[0], case.time.T)
    log.info("active terms: %s", ", ".join(case.active_terms()))
    diag = diagnose(problem, solver)
    for level, text in diag.messages():
        getattr(log, level)(text)
    log.info("step solver: %s, set-up (mesh, JIT, matrices) %.2f s",
             f"SNES {solver.snes.getType()}" if hasattr(solver, "snes") else
             f"fast (one factorisation, {solver.m} Gamma3 dofs condensed)"
             if getattr(solver, "gamma3", False) else "fast (one factorisation)", t_setup)

    stepper = make_stepper(case, diag.relaxation_rate)
    N = stepper.total
    steps, status, failure = [], "completed", None
    t, n = 0.0, 0
    if restart is not None:
        steps = restart.restore(problem, history, g3, stepper)
        n, t = restart.n, restart.t
        if hasattr(solver, "warm_start"):
            solver.warm_start()
        log.info("restarted from %s at step %d (t = %g)", restart.path, n, t)
    else:
        problem.update_sigma()

    monitor = BlowUpMonitor(case, problem, problem.cell_max(history.kappa) if history else 0.0)
    writer = None
    checkpoint_every = case.output.checkpoint_every if write_outputs else None
    bar = Progress(case.time.T, N, t, enabled=progress and comm.rank == 0)
    with _StopRequest() as stop:        # also shields the final writes from SIGINT/SIGTERM
        try:
            if write_outputs:
                fields = [problem.u, problem.sigma, problem.sigma_vm]
                if history:
                    fields.append(history.kappa)
                writer = FieldWriter(comm, outdir / "solution.xdmf", problem.mesh, fields)
                writer.write(t)
        except OutputError as exc:
            status, failure = "failed", _failure(n, t, f"cannot write the outputs: {exc}",
                                                 HINT_OUTPUT)
        if on_step and failure is None:
            on_step(n, t, problem, history)
        loop_start = time.perf_counter()
        while failure is None:
            try:
                k = stepper.next_k(t)
            except StepTooSmall as exc:
                status, failure = "failed", _failure(n + 1, t, str(exc), "lower time.adaptive."
                                                     "k_min or use time.scheme: implicit")
                log.error("step %d (t = %g) failed: %s", n + 1, t, exc)
                break
            if k is None:
                break
            t_new = stepper.next_t(t, k)
            t0 = time.perf_counter()
            saved = (history.snapshot() if history else None, g3.snapshot() if g3 else None,
                     problem.sigma.x.array.copy()) if stepper.adaptive else None
            try:
                its, norms, t_g3 = _advance(problem, history, g3, solver, t, t_new, k)
            except StepFailure as exc:
                if saved is not None:               # adaptive: undo the history, retry k/2
                    _restore(problem, history, g3, saved)
                    if stepper.reject(k, str(exc)):
                        log.warning("step at t = %g with k = %g rejected (%s); retrying with "
                                    "k = %g", t, k, exc.args[0].split(";")[0], stepper.k)
                        continue
                status, failure = "failed", _failure(n + 1, t_new, str(exc), HINT_SOLVER,
                                                     getattr(exc, "reason", None))
                log.error("step %d (t = %g) failed: %s; the last good state is step %d",
                          n + 1, t_new, exc, n)
                break
            n, t = n + 1, t_new
            stepper.accept(k, its)
            rec = _step_record(problem, history, n, t, its, time.perf_counter() - t0, norms)
            rec["k"] = k
            if g3:
                rec["gamma3_history_s"] = t_g3      # memory term / slip update of this step
            blow_up = monitor.check(rec)
            if blow_up:
                status, failure = "diverged", _failure(n, t, blow_up, HINT_DIVERGED)
                log.error("step %d (t = %g) diverged: %s; stopping, the last good state is "
                          "step %d", n, t, blow_up, n - 1)
                n -= 1
                break
            if solver.fallback:
                rec["fallback"] = solver.fallback
                if solver.continuation_stages:
                    rec["delta_continuation_stages"] = solver.continuation_stages
                log.warning("step %d: the basic Newton iteration failed; solved with %s (%d Newton "
                            "iterations in all)%s", n, solver.fallback, its,
                            "; later steps start with backtracking" if solver.sticky_robust else "")
            steps.append(rec)
            if on_step:
                on_step(n, t, problem, history)
            interrupted = comm.allreduce(stop.signal is not None, op=MPI.LOR)  # all ranks agree
            try:
                if writer and (n % case.output.every == 0 or stepper.finished(t) or interrupted):
                    writer.write(t)
                if checkpoint_every and n % checkpoint_every == 0 and not interrupted:
                    checkpoint.save(outdir, comm, case, problem, history, g3, stepper, n, t, steps)
            except OutputError as exc:
                status, failure = "failed", _failure(n, t, f"cannot write the outputs: {exc}",
                                                     HINT_OUTPUT)
                log.error("step %d (t = %g): %s; stopping", n, t, failure["reason"])
                break
            bar.update(n, t, its)
            log.debug("step %3d/%s  t = %-8.5g newton %2d  |u|_V = %.6e  |sigma|_Q = %.6e  "
                      "max vm = %.5g  max kappa = %.5g  (%.3f s)", n, N or "?", t, its,
                      rec["norm_u_V"], rec["norm_sigma_Q"], rec["max_vm"], rec["max_kappa"],
                      rec["wall_s"])
            if interrupted:
                status = "interrupted"
                by = stop.signal or "a signal on another rank"
                failure = _failure(n, t, f"interrupted by {by}", "continue with: ./vpcontact run "
                                   f"CASE --restart {outdir} --out NEW_DIR")
                saved_to = None
                if write_outputs:
                    saved_to = _try_checkpoint(outdir, comm, case, problem, history, g3,
                                               stepper, n, t, steps)
                log.warning("interrupted (%s) after step %d (t = %g); outputs are complete up to "
                            "this step, checkpoint %s", stop.signal or "another rank", n, t,
                            saved_to or "-")
                break
        bar.close()
        t_loop = time.perf_counter() - loop_start
        if writer:
            writer.close()
        summary = _summary(case, comm, problem, rect, diag, solver, stepper, status, failure,
                           steps, n, t_setup, t_loop, t_start)
        if write_outputs:
            _write_final(comm, outdir, case, problem, summary, steps)
    solver.destroy()
    return RunResult(summary["status"], summary, problem, history, g3)


HINT_SOLVER = ("try a smaller time step (time.N), time.adaptive, time.scheme: implicit, a larger "
               "solver.delta, or other PETSc options (-snes_monitor to see the iterations)")
HINT_DIVERGED = ("the explicit scheme is unstable at this time step (see the stability "
                 "indicator): use time.scheme: implicit or a smaller time step (time.N, "
                 "time.adaptive)")
HINT_OUTPUT = ("free space on the output file system or choose another --out; the files of "
               "the steps written before are intact")


def _failure(step: int, t: float, reason: str, hint: str, snes_reason=None) -> dict:
    """The ``failure`` entry of summary.json (the reason on one line)."""
    reason = "; ".join(x.strip() for x in str(reason).splitlines() if x.strip())
    return {"step": step, "t": t, "reason": reason, "snes_reason": snes_reason, "hint": hint}


def _advance(problem, history, g3, solver, t: float, t_new: float, k: float):
    """One step of scheme (3.2)-(3.4) from t to t_new: H_n, kappa_n (explicit: from step
    n-1), xi_n, s_n, the loads f_n, u_n from the step inequality (3.4), then sigma_n.

    Returns:
        (Newton iterations, (||u||_V, ||sigma||_Q) or None, wall time of the Gamma3 history).
    Raises:
        StepFailure: the step solve or a local (cell) update failed; a numerical error of the
        history update (von Mises projection, implicit Perzyna update) is reported alike.
    """
    try:
        if history:
            history.before_solve(problem, k)        # explicit: H_n, kappa_n from step n-1
        t_g3 = time.perf_counter()
        if g3:
            g3.advance(t, t_new)                    # xi_n, s_n from u_{n-1}
        t_g3 = time.perf_counter() - t_g3
        problem.time_data.set_time(t_new)           # f_n
        its = solver.solve()                        # u_n in U^h, (3.4)
        # sigma_n (explicit: E eps(u_n) + H_n, (3.2))
        norms = history.after_solve(problem) if history else problem.update_sigma()
    except StepFailure:
        raise
    except PETSc.Error as exc:                      # e.g. -ksp_error_if_not_converged
        raise StepFailure(describe_petsc_error(exc)) from exc
    except (ArithmeticError, RuntimeError, np.linalg.LinAlgError) as exc:
        raise StepFailure(f"{exc}") from exc
    return its, norms, t_g3


def _restore(problem, history, g3, saved) -> None:
    """Undo a rejected adaptive step: the history, the Gamma3 history and sigma of n-1."""
    if history:
        history.restore(saved[0])
    if g3:
        g3.restore(saved[1])
    problem.sigma.x.array[:] = saved[2]


def _try_checkpoint(outdir, comm, *state) -> Path | None:
    """The checkpoint of an interrupted run; None (with a warning) if it cannot be written."""
    try:
        return checkpoint.save(outdir, comm, *state)
    except OutputError as exc:
        log.warning("no checkpoint written: %s", exc)
        return None


def _write_final(comm, outdir: Path, case: Case, problem, summary: dict, steps: list) -> None:
    """contact.csv and summary.json; if contact.csv cannot be written the summary records
    the failure; if summary.json cannot be written either, the error is logged."""
    try:
        if problem.gamma3 is not None and steps:
            summary["contact_states"] = write_contact_csv(
                comm, outdir / "contact.csv", problem.contact_table(), case.contact.g)
    except OutputError as exc:
        if summary["status"] == "completed":
            summary["status"] = "failed"
            summary["failure"] = _failure(summary["last_good_step"], steps[-1]["t"],
                                          f"cannot write the outputs: {exc}", HINT_OUTPUT)
    try:
        write_json(comm, outdir / "summary.json", summary)
    except OutputError as exc:
        log.error("summary.json not written: %s", exc)
        summary["summary_error"] = str(exc)
        if summary["status"] == "completed":
            summary["status"] = "failed"
            summary["failure"] = _failure(summary["last_good_step"],
                                          steps[-1]["t"] if steps else 0.0,
                                          f"cannot write summary.json: {exc}", HINT_OUTPUT)


def _summary(case, comm, problem, rect, diag, solver, stepper, status, failure, steps, n,
             t_setup, t_loop, t_start) -> dict:
    """The content of summary.json (without contact_states, added by _write_final)."""
    summary = {
        "case": case.name,
        "source": case.source,
        "case_data": case.raw,
        "status": status,
        "mesh": {"cells": problem.num_cells, "vertices": problem.num_vertices,
                 "dofs": problem.num_dofs, "kind": case.mesh.kind, "n": case.mesh.n,
                 "h": rect.h, "diagonal": rect.diagonal},
        "time": {"T": case.time.T, "N": n, "uniform": case.time.uniform,
                 "scheme": case.time.scheme, "adaptive": stepper.adaptive},
        "mpi_ranks": comm.size,
        "active_terms": case.active_terms(),
        "diagnostics": diag.as_dict(),
        "solver": {"method": case.numerics.method,
                   "used": "snes_vi" if hasattr(solver, "snes") else "fast",
                   "factorisations": getattr(solver, "factorisations", None),
                   "delta": case.numerics.delta,
                   "quadrature": case.numerics.quadrature,
                   "petsc_options": {k: v for k, v in case.petsc.items()}},
        "last_good_step": steps[-1]["n"] if steps else 0,
        "steps": steps,
        "newton_iterations_total": sum(s["newton_iterations"] for s in steps),
        "solve_s": sum(s["wall_s"] for s in steps),
        "setup_s": t_setup,
        "loop_s": t_loop,
        "wall_s": time.perf_counter() - t_start,
    }
    if stepper.adaptive:
        summary["step_history"] = stepper.history
    if failure:
        summary["failure"] = failure
    return summary
