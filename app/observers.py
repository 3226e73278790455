"""Everything that watches a run: one small interface (:class:`Observer`) and the observers
of the command line's ``run``.

A Simulation calls, in the order the observers were added (``sim.add``):

- ``start(sim)`` once, before the first step (the state t_0, or the restart's step);
- ``check(sim, record)`` after each step n of scheme (3.2)-(3.4) was solved, before it is
  accepted: raising :class:`StopRun` refuses it (the last good state is then step n - 1);
- ``step(sim, record)`` after step n was accepted (``sim.steps`` ends with ``record``);
- ``end(sim, summary)`` once after the loop, also after a failure (a run summary exists then).
- ``written()`` after the run: the files the observer wrote and left in the output directory
  (``written_files``: the command line's closing ``outputs:`` line).

An observer stops a run by raising StopRun (status and StepFailure); an OutputError raised
by ``start`` or ``step`` ends the run as "failed" (the files written before stay intact).
The command line registers CollectorAfterSetUp, FieldOutput, ContactOutput, HistoryOutput,
Checkpointer, StepLog, RunFiles and its progress bar (ProgressBar, app/cli/progress.py) in
app/cli/commands.py; every run has the blow-up monitor
(app/post/divergence.py); the convergence study adds its sampler (app/studies/convergence.py).
"""
from __future__ import annotations

import logging
from pathlib import Path

from vpcontact.io import checkpoint, reserve
from vpcontact.io.contact_xdmf import ContactWriter
from vpcontact.io.history import HistoryWriter, history_columns
from vpcontact.io.output import (
    FieldWriter,
    OutputError,
    gather_contact_table,
    state_counts,
    write_contact_csv,
    write_json,
)
from vpcontact.model.state import KappaOutput
from vpcontact.post import quantities
from vpcontact.post.outputfields import derived_outputs, law_rows
from vpcontact.records import HINT_OUTPUT, StepFailure
from vpcontact.startup import resume_collector

log = logging.getLogger("vpcontact")


class StopRun(Exception):
    """Raised by an observer (or the step itself) to end a run early.

    Args:
        status: the run's status ("failed", "diverged", "interrupted").
        failure: why, for summary.json.
    """

    def __init__(self, status: str, failure: StepFailure):
        super().__init__(failure.reason)
        self.status, self.failure = status, failure


class Observer:
    """Watches a Simulation (see the module docstring); every hook does nothing by default."""

    def start(self, sim) -> None:
        """Before the first step.

        Args:
            sim: the Simulation, set up (sim.n, sim.t: the initial or restarted state).
        """

    def check(self, sim, record: dict) -> None:
        """Step n is solved but not yet accepted; raise StopRun to refuse it.

        Args:
            sim: the Simulation (sim.n, sim.t: the new step).
            record: the step's record (app/records.py).
        """

    def step(self, sim, record: dict) -> None:
        """Step n was accepted.

        Args:
            sim: the Simulation (sim.interrupted: a signal asked to stop after this step).
            record: the step's record, the last of sim.steps.
        """

    def end(self, sim, summary) -> None:
        """After the loop (completed or not).

        Args:
            sim: the Simulation.
            summary: the RunSummary (an observer may amend it, e.g. a failed final write).
        """

    def written(self) -> list[Path]:
        """The files this observer wrote into the output directory and left there (the
        run's closing ``outputs:`` line, ``written_files``).

        Returns:
            The paths, in the order written; none by default.
        """
        return []


def written_files(observers) -> list[Path]:
    """Every file the observers of a run wrote and left in its output directory: the one
    list the run's closing ``outputs:`` line names.

    Args:
        observers: the run's Observers.

    Returns:
        The paths, observer by observer in their order.
    """
    return [f for o in observers for f in o.written()]


class CollectorAfterSetUp(Observer):
    """Turns Python's garbage collector back on once the run is set up, where the command
    line turned it off for the start-up (app/startup.py); the first of its observers."""

    def start(self, sim) -> None:
        """Resume the collector (nothing if it was not paused).

        Args:
            sim: the Simulation, set up.
        """
        resume_collector()


def is_output_step(sim) -> bool:
    """Whether the fields of step n are written.

    Args:
        sim: the Simulation after step n was accepted.

    Returns:
        True for every output.every-th step, the last one, and the one a signal stopped
        the run at.
    """
    return (sim.n % sim.case.output.every == 0 or sim.stepper.finished(sim.t)
            or sim.interrupted)


class FieldOutput(Observer):
    """solution.xdmf in ``sim.outdir``: u, sigma (2D plane strain: with sigma_33), the
    3D von Mises norm sigma_vm (and kappa, or the law's named
    internal variables: p for Norton's, X, R, p for Chaboche's) at the start, every
    output.every-th step, the last step and the step a signal stopped at."""

    def __init__(self):
        self.writer = self.kappa = None
        self.derived = []

    def start(self, sim) -> None:
        """Open solution.xdmf, write the mesh and the fields at the start time.

        Args:
            sim: the Simulation, set up (sim.t: t_0 or the restarted time).

        Raises:
            OutputError: solution.xdmf cannot be written.
        """
        p = sim.problem
        kappa = p.state.kappa
        self.kappa = KappaOutput(kappa, getattr(p.law, "fields", None), law_rows(p)) \
            if kappa is not None else None       # kappa, or the law's named variables
        # sigma_33 in sigma (plane strain), material id, eps, eps_vp, sigma_nodal, eta
        self.derived = derived_outputs(p)
        fields = [p.u, p.sigma, p.sigma_vm] + (
            self.kappa.functions if kappa is not None else []) + [
            f for out in self.derived for f in out.functions]
        self.writer = FieldWriter(sim.comm, Path(sim.outdir) / "solution.xdmf", p.disc.mesh,
                                  fields)
        self._write(sim.t)

    def _write(self, t: float) -> None:
        """The fields at time t (the law's named internal variables copied from kappa, the
        derived fields of app/post/outputfields.py computed)."""
        if self.kappa is not None:
            self.kappa.update()
        columns = {}
        for out in self.derived:
            out.update()
            columns.update(out.columns())
        self.writer.write(t, columns)

    def step(self, sim, record: dict) -> None:
        """Write the fields at sim.t if step n is an output step (every output.every-th,
        the last, or the one a signal stopped at).

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record (unused).

        Raises:
            OutputError: the write failed.
        """
        if is_output_step(sim):
            self._write(sim.t)

    def end(self, sim, summary) -> None:
        """Close solution.xdmf (if it was opened).

        Args:
            sim: the Simulation (unused).
            summary: the RunSummary (unused).
        """
        if self.writer is not None:
            self.writer.close()

    def written(self) -> list[Path]:
        """Returns: solution.xdmf and its solution.h5 (none if never opened)."""
        return [] if self.writer is None else [self.writer.path, self.writer.h5]


class ContactOutput(Observer):
    """contact.xdmf in ``sim.outdir`` (app/io/contact_xdmf.py): the Gamma3 facet mesh with
    the contact table at the output times of solution.xdmf; and the Gamma3 node counts of
    every step in its record (``contact_states``: history.csv, summary.json).  Nothing
    without Gamma3."""

    def __init__(self):
        self.writer = None

    def _table(self, sim) -> dict | None:
        c = sim.case.contact
        table = quantities.contact_table(sim.problem, sim.boundary_residual)   # None: assembled
        return gather_contact_table(sim.comm, table, c.g, compliance=c.compliances,
                                    length=sim.problem.disc.length_scale)

    def start(self, sim) -> None:
        """Write the facet mesh and the table at the start time.

        Args:
            sim: the Simulation, set up.

        Raises:
            OutputError: contact.xdmf cannot be written.
        """
        disc = sim.problem.disc
        if disc.gamma3 is None:
            return
        self.writer = ContactWriter(sim.comm, Path(sim.outdir) / "contact.xdmf",
                                    disc.gamma3_facet_coordinates(), disc.dim)
        self.writer.write(sim.t, self._table(sim))

    def step(self, sim, record: dict) -> None:
        """Count the node states of step n; write the table if n is an output step.

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record; gets ``contact_states``.

        Raises:
            OutputError: the write failed.
        """
        if self.writer is None:
            return
        data = self._table(sim)
        counts = state_counts(data) if sim.comm.rank == 0 else None
        record["contact_states"] = sim.comm.bcast(counts, root=0) if sim.comm.size > 1 \
            else counts
        if is_output_step(sim):
            self.writer.write(sim.t, data)

    def written(self) -> list[Path]:
        """Returns: contact.xdmf and its contact.h5 (none without Gamma3)."""
        return [] if self.writer is None else [self.writer.path, self.writer.h5]


class HistoryOutput(Observer):
    """history.csv in ``sim.outdir`` (app/io/history.py): a row per accepted step, appended
    as the run goes (after ContactOutput, whose node counts it shows)."""

    def __init__(self):
        self.writer = None

    def start(self, sim) -> None:
        """Write the header and the rows of restored steps.

        Args:
            sim: the Simulation, set up.

        Raises:
            OutputError: history.csv cannot be written.
        """
        disc = sim.problem.disc
        groups = [str(g.name) for g in disc.dirichlet.groups]
        columns = history_columns(disc.dim, groups, disc.gamma3 is not None,
                                  [(str(q.surface), str(q.target)) for q in sim.case.contact.pairs],
                                  [str(g) for g in sim.case.loads.rigid])
        self.writer = HistoryWriter(sim.comm, Path(sim.outdir) / "history.csv", columns,
                                    disc.dim, sim.steps)

    def step(self, sim, record: dict) -> None:
        """Append the row of step n.

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record.

        Raises:
            OutputError: the write failed.
        """
        self.writer.append(record)

    def written(self) -> list[Path]:
        """Returns: history.csv (none if the run stopped before its start)."""
        return [] if self.writer is None else [self.writer.path]


class Checkpointer(Observer):
    """checkpoint_<n>.npz in ``sim.outdir`` (app/io/checkpoint.py): every
    output.checkpoint_every-th step, and at the step a signal stopped the run at (then a
    failed write is a warning, not a failure).  Sets ``sim.last_checkpoint``."""

    def __init__(self):
        self.saved = []

    def step(self, sim, record: dict) -> None:
        """Save checkpoint_<n>.npz if step n is a checkpoint step or a signal stopped the run.

        Args:
            sim: the Simulation after step n was accepted; ``sim.last_checkpoint`` is set
                to the file written (None if a write at a signal failed).
            record: the step's record (unused).

        Raises:
            OutputError: a regular (not signal-triggered) checkpoint cannot be written.
        """
        every = sim.case.output.checkpoint_every
        if sim.interrupted:
            try:
                sim.last_checkpoint = checkpoint.save(sim.outdir, sim)
            except OutputError as exc:
                log.warning("no checkpoint written: %s", exc)
                sim.last_checkpoint = None
                return
        elif every and sim.n % every == 0:
            sim.last_checkpoint = checkpoint.save(sim.outdir, sim)
        else:
            return
        self.saved = [*self.saved, sim.last_checkpoint][-checkpoint.KEEP:]

    def written(self) -> list[Path]:
        """Returns: the checkpoints kept (``checkpoint.save`` removes all but the newest
        KEEP)."""
        return list(self.saved)


class StepLog(Observer):
    """One debug line per step (shown with --verbose)."""

    def step(self, sim, record: dict) -> None:
        """Log step n: t, Newton iterations, |u|_V, |sigma|_Q, max von Mises, max kappa.

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record (app/records.py).
        """
        log.debug("step %3d/%s  t = %-8.5g newton %2d  |u|_V = %.6e  |sigma|_Q = %.6e  "
                  "max vm = %.5g  max kappa = %.5g  (%.3f s)", sim.n, sim.stepper.total or "?",
                  sim.t, record["newton_iterations"], record["norm_u_V"],
                  record["norm_sigma_Q"], record["max_vm"], record["max_kappa"],
                  record["wall_s"])
        for cap, q in record.get("rigid", {}).items():
            log.debug("         rigid cap %s: u = %s  theta = %s  F = %s  M = %s", cap,
                      *(" ".join(f"{v:.6g}" for v in (q[k] if isinstance(q[k], list)
                                                       else [q[k]]))
                        for k in ("displacement", "rotation", "force", "moment")))


class RunFiles(Observer):
    """contact.csv and summary.json in ``sim.outdir``, written once at the end.  A completed
    run whose contact.csv cannot be written is "failed"; if summary.json cannot be written
    either (a full disk), the run is "failed", the error is kept in the summary
    (summary_error) and the summary written into the space kept for it since the start
    (app/io/reserve.py); if even that fails, the log says so."""

    def __init__(self):
        self.files = []

    def start(self, sim) -> None:
        """Keep space on the output file system for summary.json (app/io/reserve.py).

        Args:
            sim: the Simulation before its first step.
        """
        reserve.reserve(sim.comm, Path(sim.outdir) / "summary.json")

    def written(self) -> list[Path]:
        """Returns: contact.csv and summary.json, those written."""
        return list(self.files)

    def end(self, sim, summary) -> None:
        """Write contact.csv (if the case has Gamma3 and a step was taken) and summary.json.

        Args:
            sim: the Simulation after the loop.
            summary: the RunSummary; a write failure marks it failed (StepFailure with
                HINT_OUTPUT), and a summary.json failure also sets ``summary_error``.
        """
        outdir, steps = Path(sim.outdir), sim.steps
        try:
            if sim.problem.disc.gamma3 is not None and steps:
                summary.contact_states = write_contact_csv(
                    sim.comm, outdir / "contact.csv", quantities.contact_table(sim.problem),
                    sim.case.contact.g, compliance=sim.case.contact.compliances,
                    length=sim.problem.disc.length_scale)
                self.files.append(outdir / "contact.csv")
        except OutputError as exc:
            summary.fail(StepFailure.output(summary.last_good_step, steps[-1]["t"], exc))
        path = outdir / "summary.json"
        try:
            write_json(sim.comm, path, summary.as_dict())
            self.files.append(path)
        except OutputError as exc:
            summary.summary_error = str(exc)
            summary.fail(StepFailure(summary.last_good_step, steps[-1]["t"] if steps else 0.0,
                                     f"cannot write summary.json: {exc}", hint=HINT_OUTPUT))
            self._write_reserved(sim.comm, path, summary, exc)
        finally:
            reserve.release(sim.comm, path)

    @staticmethod
    def _write_reserved(comm, path, summary, exc) -> None:
        """summary.json (status failed) into the space kept at the start, or the log says
        that it is not written."""
        try:
            written = reserve.write_reserved(comm, path, summary.reduced_dicts())
        except OutputError:
            written = False
        if written:
            log.error("summary.json written into the space kept for it (status %s): %s",
                      summary.status, exc)
        else:
            log.error("summary.json not written: %s", exc)
