"""Standard streams that never stop a run.

A run's log goes to stdout and its progress bar and errors to stderr.  Whoever started it
may have closed them (``>&-``), piped them into a reader that quits early (``| head``) or
pointed them at a full disk (``>/dev/full``).  None of that is a reason to lose the run:
``repair_std_streams`` gives a closed descriptor /dev/null, and ``SafeStream`` sends a
stream to /dev/null at its first failed write or flush.

Under mpirun a rank's streams are pipes to mpirun, which copies them to its own stdout and
stderr: a reader that quits (``mpirun -n 2 ./vpcontact run ... | head -2``) fails mpirun's
writes, not the rank's, and Open MPI 4.1's mpirun aborts the job at its 11th SIGPIPE (the
paper case with --verbose and 200 steps: SIGTERM to the ranks after step 8, mpirun exit 141
or 139).  So a rank started by mpirun on its node also watches mpirun's pipe
(``launcher_pipe``: a write end, opened through /proc and never written, polled: POLLERR
once the pipe has no reader) and sends its own stream to /dev/null as soon as that reader
has gone, before each write and at every step (``check_readers``): mpirun then has nothing
more to copy and the run goes on to its end.
"""
from __future__ import annotations

import os
import sys


def _devnull_at(fd: int) -> None:
    """Point descriptor ``fd`` at /dev/null."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    if devnull != fd:
        os.dup2(devnull, fd)
        os.close(devnull)


LAUNCHERS = ("mpirun", "mpiexec", "orterun")     # Open MPI's names of its launcher


def launcher_pipe(fd: int) -> int | None:
    """A descriptor of the pipe mpirun copies this rank's descriptor ``fd`` into.

    Args:
        fd: 1 (stdout) or 2 (stderr): mpirun copies a rank's fd to its own.

    Returns:
        A non-blocking write end of mpirun's own ``fd`` when this process was started by
        mpirun on its node and that is a pipe (never written: only polled), else None.
    """
    if "OMPI_COMM_WORLD_SIZE" not in os.environ:
        return None
    parent = f"/proc/{os.getppid()}"
    try:
        with open(f"{parent}/comm") as fh:
            if fh.read().strip() not in LAUNCHERS:
                return None
        if not os.readlink(f"{parent}/fd/{fd}").startswith("pipe:"):
            return None
        return os.open(f"{parent}/fd/{fd}", os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return None


class SafeStream:
    """A text stream whose writes cannot fail: after the first OSError (EPIPE, ENOSPC,
    EBADF), or once the reader of mpirun's copy of it has gone, its descriptor points at
    /dev/null and output is dropped.

    Args:
        stream: the text stream wrapped.
        fd: its descriptor.
        watch: a write end of the pipe mpirun copies it into (``launcher_pipe``), or None.
    """

    def __init__(self, stream, fd: int, watch: int | None = None):
        self._stream, self._fd, self._watch = stream, fd, watch

    def _drop(self) -> None:
        _devnull_at(self._fd)

    def check_reader(self) -> None:
        """Drop the stream if mpirun's copy of it has no reader any more (POLLERR)."""
        if self._watch is None:
            return
        import select
        poll = select.poll()
        poll.register(self._watch, 0)          # POLLERR and POLLHUP are always reported
        if not poll.poll(0):
            return
        os.close(self._watch)
        self._watch = None
        try:                        # what is buffered goes to mpirun: its reader has gone
            self._stream.flush()
        except OSError:
            pass
        self._drop()

    def write(self, text: str) -> int:
        """Write, or drop the text if the stream failed or its reader has gone.

        Args:
            text: the text.

        Returns:
            The characters written (all of them when dropped).
        """
        self.check_reader()
        try:
            return self._stream.write(text)
        except OSError:
            self._drop()
            return len(text)

    def flush(self) -> None:
        """Flush; a failure sends the stream to /dev/null."""
        try:
            self._stream.flush()
        except OSError:
            self._drop()
            try:                        # the buffered text now goes to /dev/null
                self._stream.flush()
            except OSError:
                pass

    def __getattr__(self, name):
        return getattr(self._stream, name)


def repair_std_streams() -> None:
    """Give closed stdout/stderr descriptors /dev/null and wrap both streams in SafeStream,
    watching mpirun's copies of them (idempotent).  Call before ufl is imported: it keeps
    a reference to sys.stdout."""
    for fd, name in ((1, "stdout"), (2, "stderr")):
        stream = getattr(sys, name)
        if isinstance(stream, SafeStream):
            continue
        try:
            os.fstat(fd)
        except OSError:
            _devnull_at(fd)
            stream = None
        if stream is None:
            stream = open(fd, "w", buffering=1, closefd=False)
        setattr(sys, name, SafeStream(stream, fd, launcher_pipe(fd)))


def check_readers() -> None:
    """Drop stdout and stderr if the reader of mpirun's copy of them has gone (see
    SafeStream); called at every step, for the output PETSc writes without Python."""
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        if isinstance(stream, SafeStream):
            stream.check_reader()
