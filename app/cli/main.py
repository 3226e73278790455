"""The entry point: ``main(argv)`` parses the command line, takes the signals over, runs the
command and turns what escapes it into one line and an exit code; ``console`` is the
``vpcontact`` console script.

Exit codes: 0 done, 1 a step failed (or an environmental fault), 2 bad input, 3 interrupted.
"""
from __future__ import annotations

import sys

from vpcontact.cli import commands, ending
from vpcontact.cli.parser import build_parser, split_petsc_args
from vpcontact.io.errors import CaseError
from vpcontact.io.messages import EXIT_BAD_INPUT, EXIT_FAILED, error, internal_error, interrupted
from vpcontact.startup import resume_collector

# command -> (function, takes the command line's PETSc options); a command that does not
# take them refuses them (exit 2) rather than dropping them
COMMANDS = {
    "run": (commands.cmd_run, True),
    "plot": (commands.cmd_plot, False),
    "check": (commands.cmd_check, True),
    "info": (commands.cmd_info, False),
    "convergence": (commands.cmd_convergence, True),
    "stability": (commands.cmd_stability, True),
    "bench": (commands.cmd_bench, False),
}
_BEFORE_THE_LOOP = "interrupted before the time loop started"


def take_signals() -> None:
    """Take the signals as the CLI wants them, after PETSc has installed its handlers (it
    does when first imported).

    SIGPIPE is ignored (PETSc would turn it into an MPI_Abort of the run; a write to a
    closed pipe then fails and app/cli/streams.py drops the stream); SIGINT and SIGTERM end
    the start-up (and a study, between its runs) with KeyboardInterrupt, whose argument
    names the signal, caught by main or the study's command (the time loop installs its own
    handler for both).
    """
    import signal

    from petsc4py import PETSc  # noqa: F401  (PETSc installs its handlers when initialised)
    signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, _interrupt)


def _interrupt(signum, frame):
    import signal
    raise KeyboardInterrupt(signal.Signals(signum).name)


def dispatch(args, petsc_cli: dict) -> int:
    """Run the command the command line names.

    Args:
        args: the parsed command line (``args.command`` names the command).
        petsc_cli: PETSc options given on the command line.

    Returns:
        The command's exit code (2, after one line, if the command takes no PETSc options
        and some are given).
    """
    command, takes_petsc = COMMANDS[args.command]
    if petsc_cli and not takes_petsc:
        given = " ".join(f"-{key}" for key in petsc_cli)
        takers = ", ".join(name for name, (_, takes) in COMMANDS.items() if takes)
        return error(f"{args.command}: PETSc option(s) {given} are not used by this command "
                     f"(allowed with: {takers})", EXIT_BAD_INPUT)
    if args.command != "run":          # run: once set up (observers.CollectorAfterSetUp)
        resume_collector()
    return command(args, petsc_cli) if takes_petsc else command(args)


def _unexpected(exc: Exception) -> int:
    """The exit code of an exception no command handled, after its line."""
    from vpcontact.studies.interrupts import caused_by_interrupt
    if caused_by_interrupt(exc):      # a signal inside a C extension's import or call
        return interrupted(_BEFORE_THE_LOOP, all_ranks=True)
    from petsc4py import PETSc
    if isinstance(exc, PETSc.Error):  # PETSc refused an option or a matrix: not our bug
        from vpcontact.solvers.snesvi import describe_petsc_error
        return error(f"{describe_petsc_error(exc)} (check the PETSc options; "
                     "docs/user-guide.md lists those allowed)", EXIT_FAILED)
    return internal_error(exc)


def main(argv: list[str] | None = None, process: bool = False) -> int:
    """Run ``vpcontact`` with a command line.

    Args:
        argv: the arguments without the program name (default: sys.argv[1:]); PETSc
            options (one leading dash) may be anywhere.
        process: the command line's own process (app/cli/entry.py): SIGINT and SIGTERM are
            held back once the command has its exit code (app/cli/ending.py: one arriving
            later is reported at the process's exit, not acted on by the raw signal).

    Returns:
        The exit code: 0 done, 1 a step failed (or an environmental fault), 2 bad input,
        3 interrupted (SIGINT/SIGTERM; also after the run's time loop, its outputs
        complete).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    ours, petsc_cli = split_petsc_args(argv)
    ending.forget()
    try:
        try:
            args = build_parser().parse_args(ours)
            take_signals()
            code = dispatch(args, petsc_cli)
        finally:
            if process:
                ending.hold_signals()
        return code
    except KeyboardInterrupt as exc:
        from vpcontact.studies.interrupts import signal_name
        return interrupted(ending.after_the_end(signal_name(exc)) or _BEFORE_THE_LOOP,
                           all_ranks=True)
    except CaseError as exc:            # bad input found late (e.g. while building the problem)
        return error(str(exc), EXIT_BAD_INPUT)
    except MemoryError:
        return error("out of memory: the case is too large for this machine (try a coarser "
                     "mesh, mesh.n or mesh.h)", EXIT_FAILED)
    except OSError as exc:              # environmental: disk full, read-only, permissions
        from vpcontact.io.output import describe_os_error
        return error(describe_os_error(exc), EXIT_FAILED)
    except Exception as exc:
        return _unexpected(exc)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
