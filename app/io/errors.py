"""The package's shared exceptions, kept in one low module so that every layer can raise
and catch them: the exception of invalid input (the case reader, the option checks) and the
failure of a step solve (the step solvers, the Coulomb fixed point, the time loop)."""


class CaseError(ValueError):
    """An invalid case: the message names the file, the key path and what is allowed."""


class StepSolveError(RuntimeError):
    """A step solve of (3.4) failed (raised by every StepSolver); carries the SNES
    converged reason, if SNES ran.

    Args:
        message: what failed, on one line where possible.
        reason: the SNES converged reason (negative), or None.
    """

    def __init__(self, message: str, reason: int | None = None):
        super().__init__(message)
        self.reason = reason
