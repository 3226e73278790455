"""Interrupts of the studies: SIGINT or SIGTERM ends the whole study with exit 3 and one
line, and keeps what finished (the run cache's entries of the convergence study, the
stability report of the variants done, marked incomplete).

The signals are real: sent to a real process, either by the process itself at a chosen step
of a chosen run (a patched GridSamples.step: deterministic, so the moment is known) or by
the test once the study has logged a given line."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT, run_cli

HERTZ = ROOT / "cases" / "hertz_cylinder.yaml"
# hertz at mesh.size 4, N = 4 steps each: the reference r = 2, then r = 0, then r = 1
HERTZ_STUDY = ["convergence", str(HERTZ), "--set", "mesh.size=4", "--levels", "0", "1",
               "--reference", "2", "--vary", "h"]
ENV = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}

# the study's process sends itself a signal after the given accepted step of all its runs
SIGNAL_AT_STEP = """
import os, signal, sys
from vpcontact.studies import convergence as cv
count, real = [0], cv.GridSamples.step
def step(self, sim, record):
    real(self, sim, record)
    count[0] += 1
    if count[0] == int(sys.argv[1]):
        os.kill(os.getpid(), getattr(signal, sys.argv[2]))
cv.GridSamples.step = step
from vpcontact.cli.main import main
sys.exit(main(sys.argv[3:]))
"""


def _signal_at_step(step: int, sig: str, args: list) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-c", SIGNAL_AT_STEP, str(step), sig, *map(str, args)]
    return subprocess.run(cmd, cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=300)


def _one_line(stdout: str, stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in stdout + stderr, stderr
    return lines[0]


def _cache_entries(cache):
    """The cache's files: every one a whole entry that loads (no temporary file left)."""
    from vpcontact.studies import runcache
    files = sorted(cache.iterdir()) if cache.exists() else []
    assert all(f.name.startswith("run-") and f.suffix == ".h5" for f in files), files
    for f in files:
        runcache.load(f)
    return files


def test_signal_during_a_convergence_run_ends_the_study(tmp_path):
    """The signal in step 1 of the third run (r = 1) stopped that run after its step 2 (the
    time loop acts on a signal when it accepts a step) and the study said "run failed" with
    exit 1; now exit 3, one line, the two finished runs in the cache, and the same command
    continues from them.  SIGINT and SIGTERM side by side, each in its own directories."""
    from concurrent.futures import ThreadPoolExecutor

    def interrupted_then_continued(sig):
        cache, out = tmp_path / sig / "cache", tmp_path / sig / "o"
        args = [*HERTZ_STUDY, "--out", out, "--cache-dir", cache]
        proc = _signal_at_step(9, sig, args)       # steps: 4 (reference) + 4 (r = 0) + 1
        assert proc.returncode == 3, proc.stderr
        assert _one_line(proc.stdout, proc.stderr) == (
            f"vpcontact: convergence study interrupted by {sig} during the run r = 1, N = 4, "
            f"delta = 1e-07 (after its step 2); the 2 run(s) that finished are in the run "
            f"cache {cache} (the same command continues from them); no report was written "
            f"to {out}")
        assert len(_cache_entries(cache)) == 2 and not (out / "convergence.csv").exists()
        again = run_cli([*args, "--overwrite"])
        assert again.returncode == 0, again.stderr
        assert again.stdout.count("from the cache") == 2
        return sig

    with ThreadPoolExecutor(2) as pool:    # an assertion in either is raised here
        assert list(pool.map(interrupted_then_continued, ["SIGINT", "SIGTERM"])) == \
            ["SIGINT", "SIGTERM"]


@pytest.mark.parametrize("step, where", [(4, "the run r = 2, N = 4"), (8, "the run r = 0, N = 4")])
def test_signal_in_the_last_step_of_a_run_ends_the_study(tmp_path, step, where):
    """A signal during the last step of a run was taken by the time loop and lost when the
    run completed: the study went on to the end, exit 0."""
    cache, out = tmp_path / "cache", tmp_path / "o"
    proc = _signal_at_step(step, "SIGINT", [*HERTZ_STUDY, "--out", out, "--cache-dir", cache])
    assert proc.returncode == 3, proc.stderr
    line = _one_line(proc.stdout, proc.stderr)
    assert (f"interrupted by SIGINT during {where}, delta = 1e-07 (at its end; that run "
            f"finished); the {step // 4} run(s) that finished" in line), line
    assert len(_cache_entries(cache)) == step // 4 and not (out / "convergence.csv").exists()


def _popen(args):
    return subprocess.Popen([sys.executable, "-m", "vpcontact", *map(str, args)], cwd=ROOT, env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _signal_after_line(proc, text: str, sig, lines: int = 1) -> list[str]:
    """Send ``sig`` once stdout has shown ``lines`` lines containing ``text``; the lines read
    until then."""
    seen, deadline = [], time.monotonic() + 300
    while sum(text in ln for ln in seen) < lines:
        line = proc.stdout.readline()
        if not line or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"no {text!r} line: " + "".join(seen) + proc.communicate()[1][-2000:])
        seen.append(line)
    proc.send_signal(sig)
    return seen


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_between_or_during_runs_keeps_the_finished_ones(tmp_path, sig):
    """The signal as a user sends it, once the first run has finished: it lands in a run's
    set-up, its steps or between runs; every moment ends the study with exit 3 and one line,
    and the cache holds whole entries only, at least the runs logged as finished."""
    cache = tmp_path / "cache"
    proc = _popen(["convergence", HERTZ, "--set", "mesh.size=4", "--levels", "0", "1", "2",
                   "--reference", "3", "--out", tmp_path / "o", "--cache-dir", cache])
    seen = _signal_after_line(proc, "delta = 1e-07:", sig)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 3, stderr
    line = _one_line(stdout, stderr)
    assert line.startswith(f"vpcontact: convergence study interrupted by {sig.name} during ")
    finished = int(line.split("; the ")[1].split()[0])
    logged = sum("delta = 1e-07:" in ln for ln in seen + stdout.splitlines())
    assert finished == logged == len(_cache_entries(cache)) >= 1


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_ends_the_stability_sweep_with_its_report_so_far(tmp_path, sig):
    """SIGINT/SIGTERM stopped one variant and the sweep went on (exit 0 after every
    variant); now the sweep ends (exit 3, one line) and stability.csv/.md hold the runs that
    finished, the report marked incomplete."""
    out = tmp_path / "s"
    proc = _popen(["stability", PAPER_CASE, "--n", "4", "--steps", "4", "--out", out])
    _signal_after_line(proc, "baseline", sig, lines=2)     # the two baseline runs are done
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 3, stderr
    line = _one_line(stdout, stderr)
    assert line.startswith(f"vpcontact: stability sweep interrupted by {sig.name} during ")
    finished = int(line.split("; the ")[1].split()[0])
    rows = (out / "stability.csv").read_text().splitlines()[1:]
    assert 2 <= finished == len(rows) < 20
    assert [r.split(",")[:3] for r in rows[:2]] == [["baseline", "baseline", "explicit"],
                                                    ["baseline", "baseline", "implicit"]]
    md = (out / "stability.md").read_text()
    assert f"**Incomplete: the sweep was interrupted** by {sig.name} during" in md


def test_signal_while_a_run_is_cached_keeps_the_entry_whole(tmp_path, monkeypatch):
    """A signal while a finished run is written to the cache: the entry is written whole
    (then the signal acts); the run had finished, so it is kept (it was lost before)."""
    import h5py

    from vpcontact.studies import runcache
    real = h5py.File.create_dataset

    def create_dataset(self, name, *args, **kwargs):
        if name == "sigma":
            os.kill(os.getpid(), signal.SIGINT)       # between two datasets of the entry
        return real(self, name, *args, **kwargs)

    monkeypatch.setattr(h5py.Group, "create_dataset", create_dataset)
    path = tmp_path / "run-x.h5"
    snaps = [{"u": np.ones((3, 2)), "sigma": np.ones((2, 2, 2)), "kappa": np.ones(2)}] * 2
    with pytest.raises(KeyboardInterrupt):
        runcache.save(path, [0.0, 1.0], snaps, {"dofs": 6, "solve_s": 0.1, "setup_s": 0.1,
                                                "newton": 2})
    times, back, meta = runcache.load(path, [0.0, 1.0])
    assert len(back) == 2 and meta["dofs"] == 6
    assert [p.name for p in tmp_path.iterdir()] == ["run-x.h5"]


def _children(pid: int) -> list[int]:
    try:
        text = open(f"/proc/{pid}/task/{pid}/children").read()
    except OSError:
        return []
    return [int(c) for c in text.split()]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ")[-1][0] != "Z"      # a zombie has ended
    except OSError:
        return False


def test_sigterm_to_the_bench_stops_its_run(tmp_path):
    """SIGTERM to `bench` (not to its process group) left its current run going on its own
    after the bench had exited, with the line 'interrupted before the time loop started';
    now the run is stopped with the bench: exit 3, one line."""
    proc = _popen(["bench", PAPER_CASE, "--levels", "128", "--extra", "--ranks", "1",
                   "--memory-steps", "--out", tmp_path])
    deadline = time.monotonic() + 120
    while not _children(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    children = _children(proc.pid)
    assert children, proc.communicate()[1]
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 3, stderr
    assert _one_line(stdout, stderr) == ("vpcontact: bench interrupted by SIGTERM; its run was "
                                         f"stopped, no bench.json or bench.md written to "
                                         f"{tmp_path}")
    assert not any(_alive(c) for c in children)
