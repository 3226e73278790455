"""The one printer of the command line's messages on stderr: ``vpcontact: error: ...``,
``vpcontact: warning: ...`` and ``vpcontact: interrupted ...``, one line each, and the exit
codes that go with them.

Imported while the package starts (app/__init__.py, app/io/cachedirs.py), before logging and
before MPI is initialised: it imports nothing at module level but ``sys``.
"""
from __future__ import annotations

import sys

PROG = "vpcontact"
EXIT_FAILED = 1         # a step failed, or an environmental fault (disk full, no memory)
EXIT_BAD_INPUT = 2      # a bad case, option or output directory: nothing was computed
EXIT_INTERRUPTED = 3    # SIGINT/SIGTERM
MAX_MESSAGE = 1000      # characters of an error line; a longer one echoes a huge input


def error_line(message: str, prog: str = PROG) -> str:
    """The text of an error: one line, a huge one shortened.

    Args:
        message: what went wrong; newlines become spaces, and a message longer than
            ``MAX_MESSAGE`` characters keeps its first 700 and last 100.
        prog: the program named at the start ("vpcontact run" for argparse's errors).

    Returns:
        ``"<prog>: error: <message>"``, without a newline.
    """
    message = " ".join(message.split("\n"))
    if len(message) > MAX_MESSAGE:
        cut = len(message) - 800
        message = f"{message[:700]} ... ({cut} characters left out) ... {message[-100:]}"
    return f"{prog}: error: {message}"


def warning_line(message: str) -> str:
    """The text of a warning.

    Args:
        message: the warning, one line.

    Returns:
        ``"vpcontact: warning: <message>"``, without a newline.
    """
    return f"{PROG}: warning: {message}"


def _rank(rank: int | None) -> int:
    if rank is not None:
        return rank
    from mpi4py import MPI
    return MPI.COMM_WORLD.rank


def _print(line: str) -> None:
    print(line, file=sys.stderr)


def error(message: str, code: int, rank: int | None = None) -> int:
    """Print one error line on stderr, from rank 0 only (every rank has the same error).

    Args:
        message: what went wrong and what is allowed (see ``error_line``).
        code: the exit code that goes with it.
        rank: this process's MPI rank (default: its rank in MPI.COMM_WORLD).

    Returns:
        ``code``, for ``return error(...)``.
    """
    if _rank(rank) == 0:
        _print(error_line(message))
    return code


def warning(message: str, rank: int | None = None) -> None:
    """Print one warning line on stderr, from rank 0 only.

    Args:
        message: the warning, one line.
        rank: this process's MPI rank (default: its rank in MPI.COMM_WORLD).
    """
    if _rank(rank) == 0:
        _print(warning_line(message))


def interrupted(message: str, all_ranks: bool = False) -> int:
    """Print the line of an interrupted command (Ctrl-C, SIGTERM) on stderr.

    Args:
        message: what was interrupted and what is left, e.g. "interrupted before the time
            loop started".
        all_ranks: print on every rank (the signal may have reached one rank only), not just
            on rank 0.

    Returns:
        ``EXIT_INTERRUPTED``.
    """
    if all_ranks or _rank(None) == 0:
        _print(f"{PROG}: {message}")
    return EXIT_INTERRUPTED


def internal_error(exc: Exception) -> int:
    """Report a bug in vpcontact (or a PETSc error we do not translate): the traceback and a
    line asking for a report.  An error on one rank must not leave the others waiting in a
    collective, so a parallel run is aborted as a whole.

    Args:
        exc: the exception being handled.

    Returns:
        ``EXIT_FAILED`` (in serial; in parallel the MPI job is aborted).
    """
    import traceback

    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    traceback.print_exc()
    _print(f"{PROG}: internal error on rank {comm.rank}: {type(exc).__name__}: {exc}\n"
           f"{PROG}: this is a bug; please report it with the command line and the case file")
    sys.stderr.flush()
    if comm.size > 1:
        comm.Abort(1)
    return EXIT_FAILED
