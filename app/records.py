"""What a run records: why it stopped early (StepFailure) and its summary (RunSummary, the
content of summary.json).

A step record (one entry of summary.json's "steps", built by Simulation.step) is a plain dict:
n, t (t_n), norm_u_V, norm_sigma_Q, norm_kappa_Y (the norms of u_n, sigma_n, kappa_n),
max_vm, max_kappa, newton_iterations, wall_s (history update, step solve and stress update
of scheme (3.2)-(3.4)), k (k_n), and where they apply gamma3_history_s (the update of
xi_n, s_n), fallback and delta_continuation_stages (how the step solver got there); and
``written: false`` on a step that was computed but whose outputs could not be written (an
output fault stops the run there: ``last_good_step`` is the step before).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

HINT_SOLVER = ("try a smaller time step (time.N), time.adaptive, time.scheme: implicit, a larger "
               "solver.delta, or other PETSc options (-snes_monitor to see the iterations)")
HINT_DIVERGED = ("the explicit scheme is unstable at this time step (see the stability "
                 "indicator): use time.scheme: implicit or a smaller time step (time.N, "
                 "time.adaptive)")
HINT_OUTPUT = ("free space on the output file system or choose another --out; the files of "
               "the steps written before are intact")
HINT_STEP_TOO_SMALL = "lower time.adaptive.k_min or use time.scheme: implicit"


@dataclass
class StepFailure:
    """Why a run stopped before T (summary.json: "failure").

    Args:
        step: the step that failed (for an interrupt: the last completed step).
        t: its time.
        reason: what happened; kept on one line (lines joined by '; ').
        snes_reason: SNES's converged reason, if SNES failed.
        hint: what the user can do about it.
    """

    step: int
    t: float
    reason: str
    snes_reason: int | None = None
    hint: str = ""

    def __post_init__(self):
        self.reason = "; ".join(x.strip() for x in str(self.reason).splitlines() if x.strip())

    @classmethod
    def output(cls, step: int, t: float, exc: Exception) -> StepFailure:
        """The failure of an output that cannot be written (the earlier files stay intact).

        Args:
            step: the step the run stops at.
            t: its time.
            exc: the OutputError.

        Returns:
            The StepFailure with HINT_OUTPUT.
        """
        return cls(step, t, f"cannot write the outputs: {exc}", hint=HINT_OUTPUT)

    def as_dict(self) -> dict:
        """Returns: {"step", "t", "reason", "snes_reason", "hint"} (summary.json)."""
        return dataclasses.asdict(self)


@dataclass
class RunSummary:
    """The summary of a run: summary.json is ``as_dict()``.

    Args:
        case: the case's name.
        source: the case file.
        case_data: the case as read (after --set overrides).
        status: "completed", "failed", "diverged" or "interrupted".
        mesh: cells, vertices, dofs, kind, n, h, diagonal.
        time: T, N (steps done), uniform, scheme, adaptive.
        mpi_ranks: the number of MPI ranks.
        active_terms: the model's terms the case switches on.
        diagnostics: the diagnostics (stability indicator, well-posedness, ...).
        solver: method asked for, solver used, factorisations, delta, quadrature, PETSc
            options.
        steps: the step records (see the module docstring), restored ones included.
        setup_s: wall time of the set-up (mesh, JIT, matrices).
        loop_s: wall time of the time loop.
        wall_s: wall time of the run until the summary.
        step_history: the adaptive stepper's decisions (None: fixed steps).
        failure: why the run stopped early (None: it did not).
        contact_states: the Gamma3 node counts of contact.csv (None: not written).
        summary_error: why summary.json could not be written (None: it was).
        laws: the case's laws and materials with their constants and units
            (app/post/lawreport.py: elasticity, viscoplastic law, contact laws; None: not
            recorded).
        phases: where the loop's time went (app/post/phases.py: the stages of the steps and
            PETSc's events in the solves; None: not timed).
        error_estimate: the a posteriori estimate's max over the steps with its time and
            space parts (app/post/estimators.py; None: no step).
    """

    case: str
    source: str
    case_data: dict
    status: str
    mesh: dict
    time: dict
    mpi_ranks: int
    active_terms: list
    diagnostics: dict
    solver: dict
    steps: list
    setup_s: float
    loop_s: float
    wall_s: float
    step_history: list | None = None
    failure: StepFailure | None = None
    contact_states: dict | None = None
    summary_error: str | None = None
    laws: dict | None = None
    phases: dict | None = None
    error_estimate: dict | None = None

    @property
    def last_good_step(self) -> int:
        """The last step whose state is valid and whose outputs were written (0: none beyond
        the initial state): a step marked ``written: false`` is not one."""
        return next((s["n"] for s in reversed(self.steps) if s.get("written", True)), 0)

    def fail(self, failure: StepFailure) -> None:
        """Mark a completed run as failed (an output written after the loop failed); a run
        that stopped early keeps its status and failure.

        Args:
            failure: why the run failed (kept only if the status was "completed").
        """
        if self.status == "completed":
            self.status, self.failure = "failed", failure

    def as_dict(self) -> dict:
        """Returns: the content of summary.json (keys in a fixed order)."""
        d = {"case": self.case, "source": self.source, "case_data": self.case_data,
             "status": self.status, "mesh": self.mesh, "time": self.time,
             "mpi_ranks": self.mpi_ranks, "active_terms": self.active_terms,
             "diagnostics": self.diagnostics, "solver": self.solver,
             **({} if self.laws is None else {"laws": self.laws}),
             "last_good_step": self.last_good_step, "steps": self.steps,
             "newton_iterations_total": sum(s["newton_iterations"] for s in self.steps),
             "solve_s": sum(s["wall_s"] for s in self.steps),
             "setup_s": self.setup_s, "loop_s": self.loop_s, "wall_s": self.wall_s}
        if self.error_estimate is not None:
            d["error_estimate"] = self.error_estimate
        if self.phases is not None:
            d["phases"] = self.phases
        if self.step_history is not None:
            d["step_history"] = self.step_history
        if self.failure is not None:
            d["failure"] = self.failure.as_dict()
        if self.contact_states is not None:
            d["contact_states"] = self.contact_states
        if self.summary_error is not None:
            d["summary_error"] = self.summary_error
        return d

    def reduced_dicts(self, kept_steps: int = 10):
        """summary.json's content in full, then smaller forms for a little space (a full
        disk, app/io/reserve.py): without step_history and phases and with only the last
        ``kept_steps`` step records ("steps_omitted" counts the others), then also without
        case_data, laws and diagnostics.  Status, failure, last_good_step, mesh, time and
        solver are in every form.

        Args:
            kept_steps: the step records the reduced forms keep (the last ones).

        Yields:
            The dicts, largest first.
        """
        d = self.as_dict()
        yield d
        omitted = max(len(self.steps) - kept_steps, 0)
        d = {k: v for k, v in d.items() if k not in ("step_history", "phases")}
        d.update(steps=self.steps[omitted:], steps_omitted=omitted)
        yield d
        yield {k: v for k, v in d.items() if k not in ("case_data", "laws", "diagnostics")}
