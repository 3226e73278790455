"""Files replaced whole: a reader (another process, a crash) sees the old file or the new
one, never half of either.  Both helpers write a temporary file beside the target and rename
it over the target (``os.replace``, atomic within a directory); ``overwrite_in_place``
rewrites a file within the blocks it has already (a full disk cannot stop it)."""
from __future__ import annotations

import os
from pathlib import Path


def atomic_write(path: Path, text: str | bytes, sync: bool = True) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename.

    Args:
        path: the file.
        text: its new content (str, or bytes written as they are).
        sync: fsync the file before the rename (the XDMF files skip it: a killed process
            leaves the page cache intact, and the HDF5 data they point at is not synced
            either).

    Raises:
        OSError: the write failed (the old file, if any, is unchanged).
    """
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb" if isinstance(text, bytes) else "w") as fh:
            fh.write(text)
            fh.flush()
            if sync:
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:          # disk full, read-only: the old file stays as it was
        if exc.filename is None:
            exc.filename = str(path)
        try:
            tmp.unlink()
        except OSError:
            pass
        raise


def overwrite_in_place(path: Path, data: bytes) -> None:
    """Replace a file's content by ``data``, at most as long as it, in place: the blocks are
    the file's already, so a full disk cannot leave it empty.

    Args:
        path: the file (at least len(data) bytes long).
        data: its new content.

    Raises:
        OSError: the write failed.
    """
    fd = os.open(path, os.O_WRONLY)
    try:
        os.pwrite(fd, data, 0)
        os.ftruncate(fd, len(data))
    finally:
        os.close(fd)


def write_replacing(path: Path, draw):
    """Write a file (a figure) through a hidden temporary file beside it and a rename, so
    that a reader never sees half a picture.

    Args:
        path: the file.
        draw: called with the temporary file's path (same suffix) to write it.

    Returns:
        What ``draw`` returned.
    """
    tmp = temporary(path)
    result = draw(tmp)
    os.replace(tmp, path)
    return result


def temporary(path: Path) -> Path:
    """The hidden temporary file write_replacing writes ``path`` through.

    Args:
        path: the file.

    Returns:
        .<stem>.tmp<suffix> beside it (the suffix kept: it names the image format).
    """
    return path.with_name(f".{path.stem}.tmp{path.suffix}")
