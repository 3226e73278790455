"""One bench run: a whole ``vpcontact run`` process timed from outside, with its peak
resident memory (app/studies/bench.py and bench3d.py time their rows with it)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

# the runs' environment: mpirun allowed as root, one BLAS/OpenMP thread per process
ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
       "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def measured_run(case: Path, out: Path, overrides: list[str], nprocs: int = 1):
    """One whole-process run, timed from outside, with its peak resident memory.

    Args:
        case: the case file.
        out: the output directory (overwritten).
        overrides: --set items.
        nprocs: MPI ranks (mpirun above 1).

    Returns:
        (wall s, peak resident set in bytes of the largest process, summary.json as a dict).

    Raises:
        RuntimeError: the run failed (its command and the end of its error output).
    """
    cmd = [sys.executable, "-m", "vpcontact", "run", str(case), "--out", str(out), "--overwrite",
           "--no-plots", "--quiet"]
    for item in overrides:
        cmd += ["--set", item]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    err = out.parent / f"{out.name}.stderr"
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with open(err, "w") as stderr:
        proc = subprocess.Popen(cmd, env={**os.environ, **ENV}, stdout=subprocess.DEVNULL,
                                stderr=stderr)
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        except BaseException:          # SIGINT/SIGTERM to the bench: its run ends with it
            stop_child(proc)
            raise
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"bench run failed ({' '.join(cmd)}):\n{err.read_text()[-2000:]}")
    peak = usage.ru_maxrss * 1024                      # kilobytes on Linux
    return wall, peak, json.loads((out / "summary.json").read_text())


def stop_child(proc: subprocess.Popen) -> None:
    """End a bench's child process (a run, a reference solve) whose bench was interrupted:
    SIGTERM (a run stops after its step), SIGKILL if it has not ended within 10 s; never
    left running on its own.

    Args:
        proc: the child.
    """
    proc.terminate()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def run_overrides(case, out, overrides: list[str], nprocs: int = 1):
    """One whole-process run of a case, timed from outside (``measured_run`` without the
    memory).

    Args:
        case: the case file.
        out: the output directory (overwritten).
        overrides: --set items.
        nprocs: MPI ranks (mpirun above 1).

    Returns:
        (wall time [s], the run's summary.json).
    """
    wall, _, summary = measured_run(case, out, overrides, nprocs)
    return wall, summary
