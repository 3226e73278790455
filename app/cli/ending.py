"""Signals (SIGINT, SIGTERM) at the end of a command, once its time loop is over.

The time loop takes the signals itself (app/simulation.py: the run stops after its step);
before it, the command line's handler raises KeyboardInterrupt (app/cli/main.py). After it,
the run's files are complete and summary.json says how it ended, so a signal then must not
be reported as one "before the time loop started", and must not kill the process by the
raw signal while it finalises PETSc and MPI (PETSc's finalisation puts the default action
back):

- ``run_ended`` records, once the run returned, its status and output directory; a
  KeyboardInterrupt after that is reported by ``after_the_end`` ("interrupted by SIGTERM
  after the run completed; its outputs are complete in DIR"), exit 3;
- ``hold_signals`` records both signals instead of acting on them once the command has its
  exit code (the process's last lines are printed), again after PETSc's finalisation, and
  ``signal_at_exit`` tells, after the finalisation, whether one arrived meanwhile: the
  process then exits 3 with that line instead of dying by it.
"""
from __future__ import annotations

import signal

_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_ended: dict = {}


def run_ended(status: str, outdir) -> None:
    """Record that a run's time loop is over and its outputs written.

    Args:
        status: the run's status ("completed", "failed", "diverged", "interrupted").
        outdir: its output directory.
    """
    _ended.update(status=status, outdir=str(outdir))


def forget() -> None:
    """Forget the run recorded by ``run_ended`` (a new command starts)."""
    _ended.clear()


def after_the_end(name: str) -> str | None:
    """The line of a signal that arrived after the run's time loop.

    Args:
        name: the signal's name ("SIGTERM").

    Returns:
        The message (without "vpcontact: "), or None if no run has ended.
    """
    if not _ended:
        return None
    status, outdir = _ended["status"], _ended["outdir"]
    if status == "completed":
        return (f"interrupted by {name} after the run completed; its outputs are complete "
                f"in {outdir}")
    return (f"interrupted by {name} after the run ended ({status}: see {outdir}/"
            "summary.json); its outputs are as written")


def hold_signals() -> None:
    """Hold SIGINT and SIGTERM back in this process (its command has ended): a handler that
    records them for ``signal_at_exit`` (whichever thread the signal reaches, Python runs it
    in the main thread); called again after PETSc's finalisation, which puts the default
    action (death by the signal) back."""
    for sig in _SIGNALS:
        signal.signal(sig, _record)


def _record(signum, frame):
    _caught.append(signum)


_caught: list = []


def signal_at_exit(code: int) -> int:
    """The exit status of a process whose signals are held, after its finalisation: a
    signal that arrived after a command that succeeded is reported (one line, exit 3).

    Args:
        code: the command's exit code.

    Returns:
        ``code``, or 3 (interrupted) if it was 0 and a signal arrived.
    """
    hold_signals()                   # runs the handler of a signal caught meanwhile
    if not _caught or code != 0:
        return code
    from vpcontact.io.messages import interrupted
    name = signal.Signals(_caught[0]).name
    return interrupted(after_the_end(name) or f"interrupted by {name} as vpcontact ended "
                       "(the command had completed)", all_ranks=True)
