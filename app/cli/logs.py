"""The run log: the ``vpcontact`` logger on stdout (``[vpcontact] ...`` lines), its level
from --quiet/--verbose, rank 0 only, and the JIT compilers' log lines kept out of it."""
from __future__ import annotations

import logging
import sys

log = logging.getLogger("vpcontact")


def quiet_jit_log() -> None:
    """Keep the JIT compilers' lines out of the run log.

    FFCx installs a root log handler (logging.basicConfig) and cffi's distutils build lowers
    the root level to log every compiler call; the root handlers are set to WARNING.
    """
    import ffcx  # noqa: F401  (installs the handler on import)

    for handler in logging.getLogger().handlers:
        handler.setLevel(logging.WARNING)


def setup_logging(comm, quiet: bool, verbose: bool = False) -> None:
    """Send the ``vpcontact`` logger to stdout at the level the command line asks for.

    Args:
        comm: the MPI communicator; ranks other than 0 log nothing below CRITICAL (the
            messages are collective: rank 0 says them once).
        quiet: --quiet, warnings and errors only.
        verbose: --verbose, one line per step as well (DEBUG).
    """
    level = logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO
    if comm.rank != 0:
        level = logging.CRITICAL
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(logging.Formatter("[vpcontact] %(message)s"))
    log.handlers[:] = [handler]
    quiet_jit_log()
    log.setLevel(level)
    log.propagate = False
