"""Where the time loop's time goes: the stages of a step timed around them, and PETSc's own
events inside the step solves (summary.json ``phases``, the run log's last lines, the bench).

The stages of step n (``PhaseClock``, seconds summed over the steps, the same names in every
run): the viscoplastic history H_n, kappa_n before the solve (3.2)-(3.3), the contact history
xi_n, s_n (the memory sum and the slip), the step solve (3.4) with its fallbacks and the
Coulomb fixed point, the stress update sigma_n (3.2), the step record (norms, forces, the
contact table's residual) and the outputs (the observers: XDMF, history.csv, checkpoints).
Inside the solve PETSc's default log (begun with the clock) times its events: SNES's residual
and Jacobian callbacks (our assembly), the Krylov solves (KSPSolve) and the preconditioner
set-ups (PCSetUp, which PETSc may count inside KSPSolve).  Under mpirun every number is the
largest over the ranks.
"""
from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

STAGES = ("viscoplastic history", "contact history", "solve", "stress update", "records",
          "outputs")
# PETSc's events in the solve: (our name, PETSc's event)
PETSC_EVENTS = (("residual assembly", "SNESFunctionEval"),
                ("Jacobian assembly", "SNESJacobianEval"),
                ("Krylov solves", "KSPSolve"), ("preconditioner set-up", "PCSetUp"))


def _petsc_seconds() -> dict:
    """The time PETSc's log has counted so far in each of PETSC_EVENTS."""
    return {name: PETSc.Log.Event(event).getPerfInfo()["time"]
            for name, event in PETSC_EVENTS}


class PhaseClock:
    """The seconds of each stage of the time loop and of PETSc's events since it started
    (it begins PETSc's default log).

    Args:
        comm: the run's communicator.
    """

    def __init__(self, comm):
        PETSc.Log.begin()
        self.comm = comm
        self.seconds = dict.fromkeys(STAGES, 0.0)
        self._petsc0 = _petsc_seconds()

    @contextmanager
    def stage(self, name: str):
        """Time the block as the stage ``name`` (one of STAGES).

        Args:
            name: the stage.

        Yields:
            None.
        """
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] += time.perf_counter() - t0

    def report(self) -> dict:
        """The stages' seconds and PETSc's events' since the start, the largest over the
        ranks (collective).

        Returns:
            {"stages": {stage: s}, "petsc": {event: s}}.
        """
        petsc = {k: v - self._petsc0[k] for k, v in _petsc_seconds().items()}
        values = np.array([*self.seconds.values(), *petsc.values()])
        if self.comm.size > 1:
            self.comm.Allreduce(MPI.IN_PLACE, values, op=MPI.MAX)
        n = len(self.seconds)
        return {"stages": dict(zip(self.seconds, map(float, values[:n]))),
                "petsc": dict(zip(petsc, map(float, values[n:])))}


def phase_lines(report: dict) -> list[str]:
    """The run log's lines of a ``PhaseClock.report``.

    Args:
        report: the report.

    Returns:
        One line for the stages, one for PETSc's events (where it counted any time).
    """
    stages = ", ".join(f"{k} {v:.3g} s" for k, v in report["stages"].items() if v > 0)
    lines = [f"time per stage of the loop: {stages}"]
    petsc = ", ".join(f"{k} {v:.3g} s" for k, v in report["petsc"].items() if v > 0)
    if petsc:
        lines.append(f"  of the solves, in PETSc's events: {petsc}")
    return lines
