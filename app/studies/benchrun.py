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
        (wall s, peak resident set in bytes of the largest process, summary.json as a dict
        with "_others_cores": the cores other processes kept busy on average meanwhile,
        ``others_cores``).

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
    t0, busy0 = time.perf_counter(), busy_cpu_seconds()
    with open(err, "w") as stderr:
        proc = subprocess.Popen(cmd, env={**os.environ, **ENV}, stdout=subprocess.DEVNULL,
                                stderr=stderr)
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        except BaseException:          # SIGINT/SIGTERM to the bench: its run ends with it
            stop_child(proc)
            raise
    wall = time.perf_counter() - t0
    busy = busy_cpu_seconds()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"bench run failed ({' '.join(cmd)}):\n{err.read_text()[-2000:]}")
    peak = usage.ru_maxrss * 1024                      # kilobytes on Linux
    summary = json.loads((out / "summary.json").read_text())
    summary["_others_cores"] = others_cores(busy0, busy, usage.ru_utime + usage.ru_stime, wall)
    return wall, peak, summary


BUSY_CORES = 0.1       # others_cores from which a bench row's log line names them


def busy_text(row: dict) -> str:
    """", other processes busy on 0.85 cores meanwhile" for a bench row whose run had
    others beside it (``others_cores`` >= BUSY_CORES), else "".

    Args:
        row: a bench row (its "others_cores", or None).

    Returns:
        The text.
    """
    others = row.get("others_cores")
    if others is None or others < BUSY_CORES:
        return ""
    return f", other processes busy on {others:.2f} cores meanwhile"


def busy_cpu_seconds() -> float | None:
    """The machine's busy CPU time so far, all cores (/proc/stat: user, nice, system, irq,
    softirq, steal), or None where /proc/stat cannot be read.

    Returns:
        Seconds.
    """
    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != "cpu":
        return None
    user, nice, system, _idle, _iowait, irq, softirq, steal = map(int, fields[1:9])
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def others_cores(busy0: float | None, busy1: float | None, own: float, wall: float
                 ) -> float | None:
    """The cores other processes kept busy on average during a run: the machine's busy CPU
    time over the run less the run's own (its processes and their waited-for children, an
    mpirun's ranks), over its wall time; timings of a run with others busy beside it are
    slower, under mpirun most (docs/performance.md, section 5).

    Args:
        busy0: ``busy_cpu_seconds`` before the run.
        busy1: after it.
        own: the run's CPU seconds (user + system, from wait4).
        wall: its wall time [s].

    Returns:
        Cores (>= 0, rounded to 0.01), or None without /proc/stat.
    """
    if busy0 is None or busy1 is None or wall <= 0:
        return None
    return round(max(busy1 - busy0 - own, 0.0) / wall, 2)


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
