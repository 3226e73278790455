"""Space on the output file system kept from a run's start for its summary.json, so that a
full disk cannot leave a failed run without the summary that says it failed.

At the start rank 0 writes RESERVE_BYTES into a hidden file beside summary.json
(``.summary.json.tmp-reserve``: a temporary file of the output directory, app/cli/outdir.py
OUR_PATTERNS).  At the end summary.json is written as usual (app/io/output.py write_json)
and the reserve removed; if that write fails (disk full), the summary is written into the
reserve's blocks in place (app/io/files.py overwrite_in_place: no new block is needed on a
file system that rewrites blocks in place, such as ext4, xfs and tmpfs) and renamed to
summary.json: the first of the summary's forms (RunSummary.reduced_dicts: in full, then
without the per-step detail) that fits.
"""
from __future__ import annotations

import os
from pathlib import Path

from vpcontact.io.files import overwrite_in_place
from vpcontact.io.output import on_rank0, to_json

RESERVE_BYTES = 64 * 1024     # a summary of ~80 steps in full; its reduced form ~5 kB


def reserve_path(path: Path) -> Path:
    """The reserve of a file.

    Args:
        path: the file (summary.json).

    Returns:
        The hidden file beside it that keeps its space.
    """
    return path.with_name(f".{path.name}.tmp-reserve")


def _create(path: Path) -> bool:
    try:
        with open(reserve_path(path), "wb") as fh:
            fh.write(b" " * RESERVE_BYTES)       # written, not sparse: the blocks are taken
            fh.flush()
            os.fsync(fh.fileno())
        return True
    except OSError:
        _remove(path)
        return False


def reserve(comm, path: Path) -> bool:
    """Keep RESERVE_BYTES for ``path`` (collective; rank 0 writes).

    Args:
        comm: the MPI communicator.
        path: the file written at the end (summary.json).

    Returns:
        Whether the space is kept (False: the disk is full already; nothing is kept).
    """
    return bool(comm.bcast(_create(path) if comm.rank == 0 else None, root=0))


def _remove(path: Path) -> None:
    try:
        reserve_path(path).unlink()
    except OSError:
        pass


def release(comm, path: Path) -> None:
    """Remove the reserve of ``path`` (collective; rank 0 removes it).

    Args:
        comm: the MPI communicator.
        path: the file it was kept for.
    """
    if comm.rank == 0:
        _remove(path)
    comm.barrier()


def _write(path: Path, texts) -> bool:
    spare = reserve_path(path)
    if not spare.is_file():
        return False
    size = spare.stat().st_size
    data = next((t for t in (text.encode() for text in texts) if len(t) <= size), None)
    if data is None:
        return False
    overwrite_in_place(spare, data)
    os.replace(spare, path)
    return True


def write_reserved(comm, path: Path, contents) -> bool:
    """Write ``path`` into its reserve's blocks (collective; rank 0 writes): the first of
    ``contents`` whose JSON fits.

    Args:
        comm: the MPI communicator.
        path: the file (summary.json).
        contents: the dicts to try, largest first (an iterable, read on rank 0 only).

    Returns:
        Whether ``path`` was written.

    Raises:
        OutputError: on every rank, if the write into the reserve failed.
    """
    texts = (to_json(d) for d in contents) if comm.rank == 0 else ()
    return bool(on_rank0(comm, _write, path, texts))
