"""Output directories: which files belong to vpcontact, the lock that keeps two processes
out of one directory, and the preparation before a command writes (collective)."""
from __future__ import annotations

import atexit
import os
import shutil
from pathlib import Path

from vpcontact.io.errors import CaseError

# the files of each command besides a run's (app/io/output.py OUTPUT_FILES)
CONVERGENCE_FILES = ("convergence.csv", "convergence.md", "convergence.png",
                     "error_vs_wall.csv", "error_vs_wall.png", "adaptive")   # --adaptive
STABILITY_FILES = ("stability.csv", "stability.md")
BENCH_FILES = ("bench.json", "bench.md", "bench3d.png")
TOLERANCE_FILES = ("passes.csv", "passes.json")    # run --tol, with the pass_<i> directories
# besides the files of each command: a run's directory holds its convergence/ and
# stability/ studies; checkpoints, figures, the lock and temporary files of atomic writes
OUR_DIRECTORIES = ("convergence", "stability", "bench")
OUR_PATTERNS = ("checkpoint_*.npz", "*.png", ".vpcontact.lock", ".solution.work.*", ".*.tmp*",
                "pass_*")

LOCK_NAME = ".vpcontact.lock"
_LOCKS = []      # (path, open file, created by us) of the output directories this process holds


def foreign_files(outdir: Path) -> list[str]:
    """The files in an output directory that no vpcontact command writes.

    Args:
        outdir: an existing directory.

    Returns:
        Their names, sorted.
    """
    from vpcontact.io.output import OUTPUT_FILES
    ours = {*OUTPUT_FILES, *CONVERGENCE_FILES, *STABILITY_FILES, *BENCH_FILES,
            *TOLERANCE_FILES, *OUR_DIRECTORIES}
    return sorted(p.name for p in outdir.iterdir() if p.name not in ours
                  and not any(p.match(pattern) for pattern in OUR_PATTERNS))


def lock(outdir: Path) -> str | None:
    """Create ``outdir`` and take its lock (call on rank 0).

    The lock is flock on outdir/.vpcontact.lock, held until the process ends: the kernel
    releases it however the process ends, so it never goes stale, and the file is removed
    when the process exits (release_locks; only a killed process leaves it, empty and
    harmless: the next command takes it over).

    Args:
        outdir: the output directory.

    Returns:
        None if the directory is ours now; else why not (a file of that name, files that are
        not vpcontact outputs, not writable, locked by another process).
    """
    if outdir.exists() and not outdir.is_dir():
        return f"--out {outdir}: exists and is not a directory (give a directory)"
    if outdir.is_dir():
        foreign = foreign_files(outdir)
        if foreign:
            shown = ", ".join(foreign[:5]) + (", ..." if len(foreign) > 5 else "")
            return (f"--out {outdir}: holds files that are not vpcontact outputs ({shown}); "
                    "give a new or empty directory, or one of an earlier run")
    path = outdir / LOCK_NAME
    created = not outdir.exists()
    try:
        outdir.mkdir(parents=True, exist_ok=True)
        fh = _take(path)
    except OSError as exc:
        return f"--out {outdir}: cannot write there: {exc.strerror}"
    if fh is None:
        return (f"--out {outdir}: another vpcontact process is writing into this directory; "
                "wait for it to end or choose another --out")
    if not _LOCKS:
        atexit.register(release_locks)
    _LOCKS.append((path, fh, created))
    return None


def _take(path: Path):
    """The lock file, opened and flocked; None if another process holds it.

    A process that ends removes the file while it holds the lock: a process that opened
    the file just before may then lock a file that is no longer ``path``; the lock counts
    only if ``path`` is still the file locked (else it is taken again on the new file).

    Raises:
        OSError: the file cannot be created.
    """
    import fcntl
    while True:
        fh = open(path, "a+")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            return None
        held = os.fstat(fh.fileno())
        try:
            current = os.stat(path)
        except FileNotFoundError:
            current = None
        if current is not None and (current.st_dev, current.st_ino) == (held.st_dev,
                                                                         held.st_ino):
            return fh
        fh.close()


def release_locks() -> None:
    """Remove the lock files this process holds, then release them (at exit; the lock
    stays held until the file is gone, see _take); a directory this process created and
    left empty (a case refused once its mesh was loaded) is removed too."""
    while _LOCKS:
        path, fh, created = _LOCKS.pop()
        try:
            path.unlink()
        except OSError:
            pass
        fh.close()
        if created:
            try:
                path.parent.rmdir()          # only if empty
            except OSError:
                pass


def _earlier_outputs(outdir: Path, files) -> list[str]:
    """The outputs of an earlier command in ``outdir`` (a run's: its checkpoints and
    figures as well)."""
    from vpcontact.io.output import OUTPUT_FILES

    existing = [f for f in (files or OUTPUT_FILES) if (outdir / f).exists()]
    if files is None:
        from vpcontact.post.plot import FIGURES
        existing += sorted(p.name for p in outdir.glob("checkpoint_*.npz"))
        existing += [f for f in FIGURES if (outdir / f).exists()]
        existing += [f for f in TOLERANCE_FILES if (outdir / f).exists()]
        existing += sorted(p.name for p in outdir.glob("pass_*") if p.is_dir())
    return existing


def prepare(comm, outdir: Path, overwrite: bool, files=None) -> None:
    """Create and lock the output directory and remove the outputs of an earlier command,
    if allowed (collective).

    Args:
        comm: the MPI communicator.
        outdir: the output directory.
        overwrite: --overwrite: the outputs of an earlier command may be replaced.
        files: the names the command writes (None: a run's, with its checkpoints and figures).

    Raises:
        CaseError: on every rank, if the directory cannot be used or holds earlier outputs
            and ``overwrite`` is False.
    """
    why = lock(outdir) if comm.rank == 0 else None
    why = comm.bcast(why, root=0)
    if why:
        raise CaseError(why)
    existing = _earlier_outputs(outdir, files)
    if existing and not overwrite:
        raise CaseError(f"{outdir}: holds the outputs of an earlier run ({', '.join(existing)}); "
                        "pass --overwrite to replace them or --out DIR for another directory")
    comm.barrier()
    if comm.rank == 0:
        for f in existing:
            if (outdir / f).is_dir():             # run --tol's pass_<i>
                shutil.rmtree(outdir / f)
            else:
                (outdir / f).unlink()
    comm.barrier()
