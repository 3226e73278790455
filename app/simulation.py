"""The time loop of scheme (3.2)-(3.4) as an object: :class:`Simulation`.

For n = 1..N (steps k_n = t_n - t_{n-1} may vary, or adapt):

1. H_n, kappa_n from sigma_{n-1}, kappa_{n-1} (3.2)-(3.3) (explicit scheme; the implicit
   variant updates them with u_n during the solve), xi_n and s_n on Gamma3 from u_{n-1};
2. the loads f_n at t_n;
3. u_n from the step inequality (3.4) (the StepSolver);
4. sigma_n = E eps(u_n) + H_n (3.2); the step is recorded, checked and observed.

``setup()`` builds the mesh, the problem, the history terms, the step solver, the step
control and the diagnostics (and restores a checkpoint); ``step()`` does one step (an
adaptive step rejected by the solver is undone by the State's ``restore()``,
app/model/state.py, and retried with k/2); ``run()`` steps to T and returns the
RunSummary.  Outputs, checkpoints, progress and samplers are observers (app/observers.py)
added with ``add()``.
"""
from __future__ import annotations

import logging
import os
import time
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from vpcontact import threads
from vpcontact.case import Case, CaseError, rescale_for_length
from vpcontact.case.meshrules import MAX_VERTICES
from vpcontact.io.errors import StepSolveError
from vpcontact.io.output import OutputError
from vpcontact.meshes import build_box, build_rectangle
from vpcontact.meshes.gmshfile import MeshFileError, load_mesh_file
from vpcontact.model.datapoints import check_data_on_mesh
from vpcontact.model.gamma3 import Gamma3History, build_gamma3_history
from vpcontact.model.history import ViscoplasticHistory
from vpcontact.model.problem import ContactProblem
from vpcontact.model.stepping import StepTooSmall, make_stepper
from vpcontact.observers import Observer, StopRun
from vpcontact.post import quantities
from vpcontact.post.diagnostics import diagnose
from vpcontact.post.divergence import stress_scale
from vpcontact.post.estimators import ErrorEstimate
from vpcontact.post.lawreport import law_report
from vpcontact.post.pairreport import pair_lines
from vpcontact.post.phases import PhaseClock
from vpcontact.post.ratewatch import RateWatch, needs_watch
from vpcontact.records import HINT_SOLVER, HINT_STEP_TOO_SMALL, RunSummary, StepFailure
from vpcontact.solvers import select_solver
from vpcontact.solvers.coulomb import CoulombFixedPoint
from vpcontact.solvers.snesvi import describe_petsc_error

log = logging.getLogger("vpcontact")


def build_mesh(case: Case, comm):
    """The body's mesh with its named boundary groups (meshes/).

    Args:
        case: the validated Case (mesh section).
        comm: the MPI communicator.

    Returns:
        A meshes.FileMesh (mesh.file), else a meshes.RectangleMesh (2D) or BoxMesh (3D).

    Raises:
        CaseError: if the mesh file cannot be used (naming mesh.file and why).
    """
    m = case.mesh
    if m.file is not None:
        try:
            return load_mesh_file(comm, m.file, m.dim, m.size, max_vertices=MAX_VERTICES)
        except MeshFileError as exc:
            raise CaseError(f"{case.source}: mesh.file: {exc}") from None
    size = {"n": m.n} if m.kind == "structured" else {"h": m.h}
    if m.dim == 3:
        return build_box(comm, m.L1, m.L2, m.L3, engine=m.engine, **size)
    return build_rectangle(comm, m.L1, m.L2, diagonal=m.diagonal, engine=m.engine, **size)


def build_history(case: Case, problem):
    """The viscoplastic history H_n, kappa_n of (3.2)-(3.3), if the case has a viscoplastic
    law (app/model/viscoplastic.py).

    Args:
        case: the validated Case.
        problem: the ContactProblem.

    Returns:
        A ViscoplasticHistory (explicit scheme), an ImplicitViscoplasticHistory, or None.
    """
    if problem.law is None:
        return None
    if problem.implicit:
        return problem.implicit_update        # the step problem's residual hook runs it
    return ViscoplasticHistory(problem, problem.law)


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
        _unblock_std_streams()

    def __exit__(self, *exc):
        import signal
        for sig, old in self._old.items():
            signal.signal(sig, old)
        return False


def _unblock_std_streams() -> None:
    """Under mpirun, make the rank's stdout and stderr non-blocking once a signal asked to
    stop: mpirun sends SIGTERM when it aborts the job (Ctrl-C, or a log reader that quit:
    Open MPI aborts after about ten writes to the closed pipe) and then stops reading the
    ranks' output, so a rank writing its log would block until Open MPI kills it (1 s later
    by default) and leave no summary.  A write that would block now fails, and the
    std streams' SafeStream (app/cli/streams.py) drops the output from there on.  Serially
    the descriptors may be a terminal shared with the shell: left as they are."""
    if "OMPI_COMM_WORLD_SIZE" not in os.environ and "PMI_SIZE" not in os.environ:
        return
    for fd in (1, 2):
        try:
            os.set_blocking(fd, False)
        except OSError:
            pass


class Simulation:
    """A run of scheme (3.2)-(3.4) for one case (see the module docstring).

    Args:
        case: the validated Case.
        comm: the MPI communicator.
        outdir: the directory the output observers write to (None: a run in memory).
        restart: an vpcontact.io.checkpoint.Checkpoint to continue from (None: start at t = 0).
        law: a viscoplastic law that replaces the case's: a law written by the user (the
            protocol of app/model/laws.py) as a class or callable taking the case's
            Elasticity, or a law object; None: the case's law.
        contact_laws: contact laws that replace parts of the case's: {"normal": P,
            "friction": psi}, each a ScalarLaw written with ``backend(r)`` of
            app/model/primitives.py (app/model/contact_laws.py: ``replace_laws``; the case
            keeps the section of the part replaced); None: the case's laws.
        mesh: the body's mesh, built already (a RectangleMesh or BoxMesh of the case's
            built-in mesh, e.g. refined locally by meshes/adapt.py), or None: built from
            the case.

    Attributes:
        problem: the ContactProblem (u, sigma, forms, norms).
        history: the viscoplastic history H_n, kappa_n (None for an elastic body).
        gamma3_history: the Gamma3 history xi_n, s_n (None without memory and slip terms).
        solver: the StepSolver of (3.4).
        stepper: the step control (FixedSteps or AdaptiveSteps).
        diagnostics: the case's diagnostics (stability indicator, well-posedness).
        n, t: the last accepted step and its time t_n.
        steps: the step records of the accepted steps (app/records.py).
        status, failure: "completed" or how and why the run stopped (a StepFailure).
        interrupted: a signal asked to stop after the current step.
        last_checkpoint: the checkpoint written last (set by the Checkpointer).
        estimate: the ErrorEstimate observer (app/post/estimators.py; its time error goes
            into checkpoints).
    """

    def __init__(self, case: Case, comm, outdir: Path | None = None, restart=None, law=None,
                 contact_laws=None, mesh=None):
        self.case, self.comm, self.outdir, self.restart = case, comm, outdir, restart
        self.law, self.contact_laws = law, contact_laws
        self.observers: list[Observer] = []
        self.domain, self.problem, self.history, self.gamma3_history = mesh, None, None, None
        self.clock = None                       # the loop's PhaseClock, from ``start``
        self.solver = self.stepper = self.diagnostics = self.estimate = None
        self.n, self.t, self.steps = 0, 0.0, []
        self.status, self.failure = "completed", None
        self.interrupted, self.last_checkpoint = False, None
        self.boundary_residual = None      # the last step's nodal boundary forces (forces())
        self._signals = None
        self._clock = {}

    @property
    def stop_signal(self) -> str | None:
        """The signal (e.g. "SIGINT") that asked this run, on this rank, to stop after its
        current step; None if none did or the run is not stepping (read-only).

        Returns:
            The signal's name, or None.
        """
        return self._signals.signal if self._signals is not None else None

    def add(self, observer: Observer) -> Simulation:
        """Register an observer (called in the order added).

        Args:
            observer: an app.observers.Observer.

        Returns:
            The simulation itself.
        """
        self.observers.append(observer)
        return self

    # ------------------------------------------------------------------ set-up
    def setup(self) -> None:
        """Mesh, problem, history terms (initial values), step solver, diagnostics, step
        control, and the state of the checkpoint to continue from (else sigma_0)."""
        self._clock["start"] = time.perf_counter()
        case = self.case
        if self.domain is None:
            self.domain = build_mesh(case, self.comm)
        if case.mesh.file is not None:          # the tolerances' scale: the body's size
            lo, hi = self.domain.bbox
            self.case = case = rescale_for_length(case, float(np.max(hi - lo)),
                                                  check_data_on_mesh(case, self.domain))
        self.problem = problem = ContactProblem(case, self.domain, self.law,
                                                self.contact_laws)
        self.history = build_history(case, problem)
        problem.set_initial_values()
        self.gamma3_history = g3 = build_gamma3_history(case, problem)
        problem.state.attach_gamma3(g3)
        coulomb = g3 is not None and g3.coulomb is not None
        scale = stress_scale(problem.case, problem) if coulomb else None     # collective
        threads.configure(self.comm)
        self.solver = select_solver(case, problem)
        if coulomb:         # Coulomb friction: the fixed point on p_n around the step solver
            self.solver = CoulombFixedPoint(self.solver, g3, scale)
        self._clock["setup"] = time.perf_counter() - self._clock["start"]
        self._log_case()
        self.diagnostics = diagnose(problem, self.solver)
        for level, text in self.diagnostics.messages():
            getattr(log, level)(text)
        log.info("step solver: %s, set-up (mesh, JIT, matrices) %.2f s", self.solver.describe(),
                 self._clock["setup"])
        self.stepper = make_stepper(case, self.diagnostics.relaxation_rate)
        if needs_watch(self):       # no rate bound: k r estimated at every step, first
            self.observers.insert(0, RateWatch())
        self.estimate = ErrorEstimate()             # the a posteriori estimate, every run
        self.observers.insert(0, self.estimate)
        if self.restart is not None:
            self.steps = self.restart.restore(self)
            self.n, self.t = self.restart.n, self.restart.t
            self.solver.warm_start()
            log.info("restarted from %s at step %d (t = %g)", self.restart.path, self.n, self.t)
        else:
            self.problem.update_sigma()                 # sigma_0
        self.problem.state.commit()

    def _log_case(self) -> None:
        """The run's first lines: mesh, dofs, steps, adaptive steps, active terms."""
        case, disc = self.case, self.problem.disc
        ks = [b - a for a, b in zip(case.time.times, case.time.times[1:])]
        log.info("case %s (%dD): %d cells, %d vertices, %d dofs, %d steps (k = %s)", case.name,
                 disc.dim, disc.num_cells, disc.num_vertices, disc.num_dofs, case.time.N,
                 f"{ks[0]:g}" if case.time.uniform else f"{min(ks):g}..{max(ks):g}")
        if case.time.adaptive is not None:
            log.info("adaptive time steps: starting from k = %g to T = %g", ks[0], case.time.T)
        log.info("active terms: %s", ", ".join(case.active_terms()))
        if case.contact.pairs:       # two bodies: each pair (app/post/pairreport.py)
            for line in pair_lines(disc):
                log.info("%s", line)
        elif disc.frames is not None:
            d = case.contact.direction
            log.info("Gamma3 (%s): %d nodes, normal %s%s",
                     ", ".join(map(str, case.boundaries.contact)), disc.num_gamma3_nodes,
                     f"the fixed direction {tuple(round(x, 6) for x in d)}" if d is not None
                     else "nodal (the mesh's outward normals)",
                     "; SNES VI and the fast solver in rotated nodal frames"
                     if disc.frames.rotated else "")

    # ------------------------------------------------------------------ the loop
    @property
    def finished(self) -> bool:
        """True once the step control reached T."""
        return self.stepper.finished(self.t)

    def run(self) -> RunSummary:
        """Step from the initial (or restarted) state to T, or until a step fails, an
        observer stops the run, or SIGINT/SIGTERM asks to stop (after the current step).

        Returns:
            The RunSummary (its status says how the run ended).
        """
        if self.problem is None:
            self.setup()
        with _StopRequest() as self._signals:   # also shields the final writes
            try:
                self.start()
                while not self.finished:
                    self.step()                  # n-1 -> n: (3.2)-(3.4), observed
            except StopRun as stop:
                self.status, self.failure = stop.status, stop.failure
            summary = self.finish()
        self._signals = None
        return summary

    def step(self) -> dict | None:
        """One step n-1 -> n of scheme (3.2)-(3.4) (see ``advance``), recorded, checked by
        the observers and accepted; an adaptive step whose solve fails is undone and
        retried with k/2.

        Returns:
            The step's record (app/records.py), or None if the run is at T already.

        Raises:
            StopRun: the step failed (or an observer refused it, or a signal stopped the
                run after it); ``n`` is the last good step.
        """
        if self.finished:
            return None
        before = self.problem.u.x.array.copy() if self.stepper.adaptive else None
        k, t_new, its, norms, t_g3, t0 = self._solve_step()
        wall = time.perf_counter() - t0
        self.n, self.t = self.n + 1, t_new
        self.stepper.accept(k, self._relative_change(before))
        with self._stage("records"):
            record = self._record(its, wall, norms, k, t_g3)
        self._accept(record)
        return record

    def _stage(self, name: str):
        """The PhaseClock's timer of the loop's stage ``name`` (none before ``start``)."""
        return self.clock.stage(name) if self.clock is not None else nullcontext()

    def _start_in_contact(self) -> None:
        """The first step of a body held only by contact (app/model/semicoercive.py): from
        the body translated into contact, and with SNES VI from one Newton step with its
        contact nodes held (``press_next``)."""
        p = self.problem
        if p.hold.close_gap(p.u):
            self.solver.warm_start()
        if hasattr(self.solver, "press_next"):
            self.solver.press_next(p.hold.pinned_slots())

    def advance(self, k: float, t_new: float):
        """The scheme's step from t_{n-1} = ``self.t`` to t_n = ``t_new``: H_n, kappa_n
        (explicit: from step n-1) (3.2)-(3.3), xi_n, s_n, the loads f_n, u_n from the step
        inequality (3.4), then sigma_n (3.2).  ``n`` and ``t`` are not changed.

        Args:
            k: the step k_n.
            t_new: t_n.

        Returns:
            (iterations, (||u||_V, ||sigma||_Q) or None, wall time of the Gamma3 history).

        Raises:
            StepSolveError: the step solve or a local (cell) update failed; a numerical
                error of the history update (von Mises projection, implicit Perzyna update)
                is reported alike.
        """
        p, history, g3, stage = self.problem, self.history, self.gamma3_history, self._stage
        try:
            if history:
                with stage("viscoplastic history"):
                    history.before_solve(p, k)      # explicit: H_n, kappa_n from step n-1
            t_g3 = time.perf_counter()
            if g3:
                with stage("contact history"):
                    g3.advance(self.t, t_new)       # xi_n, s_n from u_{n-1}
            t_g3 = time.perf_counter() - t_g3
            p.set_time(t_new, k)                    # f_n, prescribed displacements, k_n
            if p.hold is not None and self.n == 0:  # held only by contact: the first step
                self._start_in_contact()
            # u_n in U^h, (3.4); with Coulomb friction a fixed point on p_n (CoulombFixedPoint)
            with stage("solve"):
                its = self.solver.solve()
            # sigma_n (explicit: E eps(u_n) + H_n, (3.2))
            with stage("stress update"):
                norms = history.after_solve(p, k) if history else p.update_sigma()
        except StepSolveError:
            raise
        except PETSc.Error as exc:                  # e.g. -ksp_error_if_not_converged
            raise StepSolveError(describe_petsc_error(exc)) from exc
        except (ArithmeticError, RuntimeError, np.linalg.LinAlgError) as exc:
            raise StepSolveError(f"{exc}") from exc
        return its, norms, t_g3

    def state(self) -> dict:
        """A copy of the scheme's state (app/model/state.py): u_n, sigma_n, H_n, kappa_n and
        the Gamma3 history (xi_n, s_n).

        Returns:
            The State's snapshot().
        """
        return self.problem.state.snapshot()

    def load_state(self, state: dict) -> None:
        """Set the scheme's state from ``state()`` of this run.

        Args:
            state: as returned by ``state()``.
        """
        self.problem.state.load(state)

    # ------------------------------------------------------------------ step internals
    def _next_k(self) -> float:
        """The step control's next k; StopRun if it cannot give one above k_min."""
        try:
            return self.stepper.next_k(self.t)
        except StepTooSmall as exc:
            log.error("step %d (t = %g) failed: %s", self.n + 1, self.t, exc)
            raise StopRun("failed", StepFailure(self.n + 1, self.t, str(exc),
                                                hint=HINT_STEP_TOO_SMALL)) from None

    def _solve_step(self):
        """``advance`` with the adaptive retries.  Returns (k, t_n, iterations, norms,
        Gamma3 history time, start time of the successful attempt)."""
        while True:
            k = self._next_k()
            t_new = self.stepper.next_t(self.t, k)
            t0 = time.perf_counter()
            try:
                result = (k, t_new, *self.advance(k, t_new), t0)
                self.problem.state.commit()         # trial -> committed (adaptive: a copy)
                return result
            except StepSolveError as exc:
                if self.stepper.adaptive:           # undo the step's trial state, retry k/2
                    self.problem.state.restore()
                    if self.stepper.reject(k, str(exc)):
                        log.warning("step at t = %g with k = %g rejected (%s); retrying with "
                                    "k = %g", self.t, k, exc.args[0].split(";")[0],
                                    self.stepper.k)
                        continue
                failure = StepFailure(self.n + 1, t_new, str(exc), getattr(exc, "reason", None),
                                      HINT_SOLVER)
                log.error("step %d (t = %g) failed: %s; the last good state is step %d",
                          self.n + 1, t_new, exc, self.n)
                raise StopRun("failed", failure) from None

    def _relative_change(self, before) -> float:
        """The step's relative change of the solution, max|u_n - u_{n-1}| / max|u_n| over
        the owned dofs of all ranks (collective), for the adaptive step control: a property
        of the converged solution, not of the step solver.  0 without ``before`` (a fixed
        grid) or for u_n = 0."""
        if before is None:
            return 0.0
        u = self.problem.u
        owned = u.function_space.dofmap.index_map.size_local * \
            u.function_space.dofmap.index_map_bs
        now = u.x.array[:owned]
        change = self.comm.allreduce(float(np.abs(now - before[:owned]).max(initial=0.0)),
                                     op=MPI.MAX)
        scale = self.comm.allreduce(float(np.abs(now).max(initial=0.0)), op=MPI.MAX)
        return change / scale if scale > 0 else 0.0

    def _record(self, its: int, wall: float, norms, k: float, t_g3: float) -> dict:
        """The step's record (app/records.py); ``norms`` = (||u||_V, ||sigma||_Q) if the
        stress update computed them already, else they are computed here (collective)."""
        p = self.problem
        kappa = p.state.kappa
        norm_u, norm_sigma = norms or (quantities.norm(p, "V"), quantities.norm(p, "Q"))
        record = {
            "n": self.n, "t": self.t,
            "norm_u_V": norm_u,
            "norm_sigma_Q": norm_sigma,
            "norm_kappa_Y": quantities.cell_norm(p, kappa) if kappa is not None else 0.0,
            "max_vm": quantities.cell_max(p, p.sigma_vm),
            "max_kappa": quantities.cell_max(p, kappa) if kappa is not None else 0.0,
            "newton_iterations": its,
            "linear_iterations": getattr(self.solver, "linear_iterations", None),
            "wall_s": wall,
            "k": k,
        }
        # the nodal forces of the boundary layer: the forces and the contact table
        self.boundary_residual = quantities.bulk_residual(p)
        forces = quantities.forces(p, self.boundary_residual)   # on the body: supports, ...
        record["reactions"] = forces["reactions"]
        if forces["contact_force"] is not None:
            record["contact_force"] = forces["contact_force"]
        if forces["pair_forces"] is not None:
            record["pair_forces"] = forces["pair_forces"]
        caps = p.disc.caps
        if caps is not None:                  # the rigid caps' motion and resultant
            owned = p.disc.V.dofmap.index_map.size_local * p.disc.dim
            record["rigid"] = caps.report(p.u.x.array[:owned], self.boundary_residual.ravel())
        if self.gamma3_history:
            record["gamma3_history_s"] = t_g3       # memory term / slip update of this step
        if self.solver.fallback:
            record["fallback"] = self.solver.fallback
            if self.solver.continuation_stages:
                record["delta_continuation_stages"] = self.solver.continuation_stages
        return record

    def _accept(self, record: dict) -> None:
        """Check step n with the observers, accept it (record, observers' ``step``), and
        stop after it if a signal asked to (StopRun in each case that ends the run)."""
        try:
            for obs in self.observers:
                obs.check(self, record)
        except StopRun:
            self.n -= 1                             # refused: the last good state is n - 1
            raise
        if self.solver.fallback:
            log.warning("step %d: the basic Newton iteration failed; solved with %s (%d Newton "
                        "iterations in all)%s", self.n, self.solver.fallback,
                        record["newton_iterations"], "; later steps start with backtracking"
                        if self.solver.sticky_robust else "")
        self.steps.append(record)
        signalled = self.stop_signal is not None
        self.interrupted = self.comm.allreduce(signalled, op=MPI.LOR)   # all ranks agree
        try:
            with self._stage("outputs"):
                for obs in self.observers:
                    obs.step(self, record)
        except OutputError as exc:
            # step n was computed but not (fully) written: the last good step is n - 1
            record["written"] = False
            failure = StepFailure.output(self.n, self.t, exc)
            log.error("step %d (t = %g): %s; stopping", self.n, self.t, failure.reason)
            raise StopRun("failed", failure) from None
        if self.interrupted:
            raise self._interrupt()

    def _interrupt(self) -> StopRun:
        """The stop after a signal: outputs are complete up to step n."""
        signal = self.stop_signal
        failure = StepFailure(self.n, self.t,
                              f"interrupted by {signal or 'a signal on another rank'}",
                              hint=f"continue with: ./vpcontact run CASE --restart "
                                   f"{self.outdir} --out NEW_DIR")
        log.warning("interrupted (%s) after step %d (t = %g); outputs are complete up to "
                    "this step, checkpoint %s", signal or "another rank", self.n, self.t,
                    self.last_checkpoint or "-")
        return StopRun("interrupted", failure)

    # ------------------------------------------------------------------ start and end
    def start(self) -> None:
        """Start the observers (``run`` does; call it yourself when you drive the loop
        with ``step``).

        Raises:
            StopRun: an output could not be written (the run has failed at step n).
        """
        try:
            for obs in self.observers:
                obs.start(self)
        except OutputError as exc:
            raise StopRun("failed", StepFailure.output(self.n, self.t, exc)) from None
        finally:
            self._clock["loop_start"] = time.perf_counter()
            self.clock = PhaseClock(self.comm)

    def finish(self) -> RunSummary:
        """End the run: the RunSummary, the observers' ``end`` (which may amend it and
        write the final files), then free the step solver.  ``run`` calls it; call it
        yourself after the last ``step`` when you drive the loop.

        Returns:
            The RunSummary.
        """
        self._clock["loop"] = time.perf_counter() - self._clock["loop_start"]
        summary = self.summary()
        for obs in self.observers:
            obs.end(self, summary)
        self.solver.destroy()
        return summary

    def _mesh_kind(self) -> dict:
        """summary.json's mesh kind and n: "adapted" (n None) for a built-in structured mesh
        refined locally (meshes/adapt.py), else the case's."""
        if self.case.mesh.kind == "structured" and getattr(self.domain, "n", 0) is None:
            return {"kind": "adapted", "n": None}
        return {"kind": self.case.mesh.kind, "n": self.case.mesh.n}

    def summary(self) -> RunSummary:
        """Returns: the RunSummary of the run so far (summary.json without contact_states)."""
        case, p, stepper = self.case, self.problem, self.stepper
        disc = p.disc
        return RunSummary(
            case=case.name, source=case.source, case_data=case.raw, status=self.status,
            mesh={"cells": disc.num_cells, "vertices": disc.num_vertices, "dofs": disc.num_dofs,
                  **self._mesh_kind(), "h": self.domain.h,
                  "diagonal": self.domain.diagonal},
            time={"T": case.time.T, "N": self.n, "uniform": case.time.uniform,
                  "scheme": case.time.scheme, "adaptive": stepper.adaptive},
            mpi_ranks=self.comm.size, active_terms=case.active_terms(),
            diagnostics=self.diagnostics.as_dict(),
            solver={"method": case.numerics.method, "used": self.solver.name,
                    "factorisations": self.solver.factorisations,
                    "gamma3": getattr(self.solver, "gamma3_stats", lambda: None)(),
                    "amg": getattr(self.solver, "amg_stats", lambda: None)(),
                    "linear": getattr(self.solver, "linear", None),
                    "delta": case.numerics.delta, "quadrature": case.numerics.quadrature,
                    "petsc_options": dict(getattr(self.solver, "options", case.petsc))},
            steps=self.steps, setup_s=self._clock["setup"],
            loop_s=self._clock.get("loop", 0.0),
            wall_s=time.perf_counter() - self._clock["start"],
            step_history=stepper.decisions if stepper.adaptive else None,
            failure=self.failure, laws=law_report(p, self.gamma3_history),
            phases=self.clock.report() if self.clock is not None else None)


@dataclass
class RunResult:
    """What ``run`` returns.

    Attributes:
        status: the run's status.
        summary: the content of summary.json (a dict).
        problem: the ContactProblem at the end of the run.
        history: the viscoplastic history (None for an elastic body).
        gamma3_history: the Gamma3 history (None without memory and slip terms).
    """

    status: str
    summary: dict
    problem: ContactProblem = field(repr=False)
    history: ViscoplasticHistory | None = field(repr=False, default=None)
    gamma3_history: Gamma3History | None = field(repr=False, default=None)


def run(case: Case, comm, observers=(), *, outdir: Path | None = None, restart=None,
        monitor: bool = True, law=None, contact_laws=None, mesh=None) -> RunResult:
    """Run a case: a Simulation with the blow-up monitor (unless ``monitor`` is False) and
    the given observers.  Writes nothing unless an observer does.

    Args:
        case: the validated Case.
        comm: the MPI communicator.
        observers: app.observers.Observer instances, called in this order.
        outdir: the directory the output observers write to.
        restart: an vpcontact.io.checkpoint.Checkpoint to continue from.
        monitor: stop a run whose norms blow up as "diverged" (app/post/divergence.py).
        law: a viscoplastic law that replaces the case's (see Simulation), or None.
        contact_laws: contact laws that replace parts of the case's (see Simulation), or
            None.
        mesh: the body's mesh, built already (see Simulation), or None.

    Returns:
        The RunResult (status, summary dict, and the problem and histories at the end).
    """
    from vpcontact.post.divergence import BlowUpMonitor

    sim = Simulation(case, comm, outdir=outdir, restart=restart, law=law,
                     contact_laws=contact_laws, mesh=mesh)
    if monitor:
        sim.add(BlowUpMonitor())
    for obs in observers:
        sim.add(obs)
    summary = sim.run()
    return RunResult(summary.status, summary.as_dict(), sim.problem, sim.history,
                     sim.gamma3_history)
