"""Standard streams that never stop a run.

A run's log goes to stdout and its progress bar and errors to stderr.  Whoever started it
may have closed them (``>&-``), piped them into a reader that quits early (``| head``) or
pointed them at a full disk (``>/dev/full``).  None of that is a reason to lose the run:
``repair_std_streams`` gives a closed descriptor /dev/null, and ``SafeStream`` sends a
stream to /dev/null at its first failed write or flush.
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


class SafeStream:
    """A text stream whose writes cannot fail: after the first OSError (EPIPE, ENOSPC,
    EBADF) its descriptor points at /dev/null and output is dropped.

    Args:
        stream: the text stream wrapped.
        fd: its descriptor.
    """

    def __init__(self, stream, fd: int):
        self._stream, self._fd = stream, fd

    def _drop(self) -> None:
        _devnull_at(self._fd)

    def write(self, text: str) -> int:
        """Write, or drop the text if the stream failed.

        Args:
            text: the text.

        Returns:
            The characters written (all of them when dropped).
        """
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
    """Give closed stdout/stderr descriptors /dev/null and wrap both streams in SafeStream
    (idempotent).  Call before ufl is imported: it keeps a reference to sys.stdout."""
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
        setattr(sys, name, SafeStream(stream, fd))
