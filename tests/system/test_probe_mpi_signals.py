"""Interrupts under mpirun -n 2, as README "Running a case" states them: SIGINT or SIGTERM to
mpirun (which sends SIGTERM to the ranks) ends the run after the current step with a
checkpoint and summary.json `status: interrupted`; mpirun's exit code is its own (Open MPI
4.1: 1 after it forwarded a signal, not the ranks' 3); a log reader that quits does not stop
the run (the ranks drop their output once mpirun's stdout has no reader). The ranks get time
to finish their step (OMPI_MCA_odls_base_sigkill_timeout, as the README advises): by default
Open MPI kills them 1 s after the SIGTERM.

The timeout also sets how long the ranks go on and mpirun waits: Open MPI 4.1's mpirun, on
SIGINT or SIGTERM (or a rank's non-zero exit), sends the ranks SIGCONT at once, SIGTERM one
timeout later, SIGKILL after another, and exits only then, however early the ranks ended
(strace, with 10 s: SIGCONT +0.005 s, SIGTERM +10.0 s, SIGKILL +18.1 s, mpirun gone at +18.2
s; the ranks' summary.json was written 0.07 s after their SIGTERM). 3 s leaves them ample
time and each test about 6 s of waiting (19 s with 10)."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT

pytestmark = pytest.mark.mpi

ENV = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT),
       "OMPI_MCA_odls_base_sigkill_timeout": "3"}


def _command(out, *extra):
    return ["mpirun", "-n", "2", sys.executable, "-m", "vpcontact", "run", str(PAPER_CASE),
            "--out", str(out), "--no-plots", "--set", "mesh.n=8", "--set", "time.N=20000",
            *extra]


def _written_steps(out):
    try:
        return (out / "solution.xdmf").read_text().count("solution.h5:/Function/u/")
    except FileNotFoundError:
        return 0


def _wait_for_steps(proc, out):
    deadline = time.monotonic() + 300
    while _written_steps(out) < 2:
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"the run wrote no step (exit {proc.poll()})")
        time.sleep(0.05)


def _interrupted(out):
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and s["mpi_ranks"] == 2, s.get("failure")
    n = s["last_good_step"]
    assert 0 < n < 20000 and s["failure"]["reason"] == "interrupted by SIGTERM"
    assert (out / f"checkpoint_{n:06d}.npz").exists()
    assert _written_steps(out) >= 2
    return s


def test_signal_to_mpirun_ends_the_run_as_interrupted(tmp_path):
    """SIGINT to one mpirun, SIGTERM to another, the two runs side by side (most of each
    is mpirun waiting out its kill timers, see above)."""
    runs = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            out, err = tmp_path / sig.name, open(tmp_path / f"{sig.name}.stderr", "w")
            runs[sig] = out, err, subprocess.Popen(_command(out, "--quiet"), cwd=ROOT, env=ENV,
                                                   stdout=subprocess.DEVNULL, stderr=err)
        for sig, (out, _, proc) in runs.items():
            _wait_for_steps(proc, out)
            proc.send_signal(sig)
        codes = {sig: proc.wait(timeout=120) for sig, (_, _, proc) in runs.items()}
    finally:
        for _, err, proc in runs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            err.close()
    for sig, (out, _, _) in runs.items():
        stderr = (tmp_path / f"{sig.name}.stderr").read_text()
        # mpirun's own exit code (README): 1 with Open MPI 4.1; never 0, never a crash
        assert codes[sig] in (1, 3), (sig.name, stderr[-2000:])
        _interrupted(out)
        assert "Traceback" not in stderr, sig.name


def test_log_reader_quitting_under_mpirun_does_not_stop_the_run(tmp_path):
    """The reader of a --verbose log reads two lines and quits (`| head -2`, the README's
    promise): mpirun aborted the job at its 11th SIGPIPE (SIGTERM to the ranks after a few
    steps, status interrupted, mpirun's exit 141 or 139); the ranks now see that mpirun's
    stdout has no reader and drop their output (app/cli/streams.py), and the run goes on to
    its end: exit 0, every step in summary.json."""
    out = tmp_path / "o"
    command = " ".join(_command(out, "--verbose", "--set", "time.N=200"))
    proc = subprocess.run(["bash", "-c", f"{command} | head -2; exit ${{PIPESTATUS[0]}}"],
                          cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(proc.stdout.splitlines()) == 2 and "Traceback" not in proc.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "completed" and s["mpi_ranks"] == 2 and len(s["steps"]) == 200
