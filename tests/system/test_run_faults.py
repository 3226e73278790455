"""Faults during a run: an exploding explicit run stops as "diverged", output faults (disk
full, read-only) and failing steps record `status: failed` and exit 1 with earlier results
intact, a closed stdout does not kill the run, two runs cannot share an output directory,
Ctrl-C while drawing or writing the summary leaves a truthful summary, bad --out / CLI
numbers are refused in one line before any work."""
import fcntl
import json
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT, run_cli

TINY = ["--set", "mesh.n=4", "--set", "time.N=4"]


@pytest.fixture(autouse=True)
def _restore_log():
    """cli.main sets up the 'vpcontact' logger (own handler, no propagation): put it back,
    so that later tests' caplog sees its records."""
    import logging
    logger = logging.getLogger("vpcontact")
    state = logger.handlers[:], logger.propagate, logger.level
    yield
    logger.handlers[:], logger.propagate = state[0], state[1]
    logger.setLevel(state[2])


def _summary(out):
    return json.loads((out / "summary.json").read_text())


def _xdmf_times(out):
    root = ET.parse(out / "solution.xdmf").getroot()
    grid = next(g for g in root.iter("Grid") if g.get("GridType") == "Collection")
    return [float(g.find("Time").get("Value")) for g in grid.findall("Grid")]


def _one_error_line(proc):
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert "Traceback" not in proc.stderr + proc.stdout
    assert len(lines) == 1 and lines[0].startswith("vpcontact"), proc.stderr
    return lines[0]


# ------------------------------------------------------------------ blow-up of the explicit scheme
def test_exploding_explicit_run_is_diverged(tmp_path):
    """lambda1 = lambda2 = 0.01: k r_max = 5.2e3; ||sigma||_Q grew to 2.3e55 and the run said
    'completed'.  Now: status diverged at the step that left the data's bound, exit 1,
    one line suggesting the implicit scheme, outputs of the earlier steps readable."""
    out = tmp_path / "boom"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet",
                    "--set", "material.viscoplastic.lambda1=0.01",
                    "--set", "material.viscoplastic.lambda2=0.01"])
    assert proc.returncode == 1
    line = _one_error_line(proc)
    assert "diverged at step" in line and "time.scheme: implicit" in line
    s = _summary(out)
    assert s["status"] == "diverged"
    n = s["failure"]["step"]
    assert 2 <= n <= 4 and s["last_good_step"] == n - 1 == len(s["steps"])
    assert "sigma" in s["failure"]["reason"]
    assert max(st["max_vm"] for st in s["steps"]) < 1e8     # stopped long before 1e55
    assert _xdmf_times(out) == pytest.approx([j / 16 for j in range(n)])


def test_run_just_beyond_the_explicit_limit_still_completes(tmp_path):
    """k r_max = 2.17 (lambda1 = 24): the overstress oscillates but stays bounded."""
    out = tmp_path / "edge"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet",
                    "--set", "material.viscoplastic.lambda1=24"])
    assert proc.returncode == 0, proc.stderr
    s = _summary(out)
    assert s["status"] == "completed" and s["diagnostics"]["stability_indicator"] > 2
    assert len(s["steps"]) == 16


def test_monitor_names_non_finite_quantities():
    from vpcontact.post.divergence import BlowUpMonitor
    mon = BlowUpMonitor.__new__(BlowUpMonitor)
    mon.scale, mon.bound, mon.kappa_bound = 1.0, 10.0, 10.0
    rec = {"n": 1, "t": 0.1, "norm_u_V": 1.0, "norm_sigma_Q": float("nan"), "max_vm": 1.0,
           "max_kappa": 0.0}
    assert "norm_sigma_Q" in mon.blow_up(rec)
    assert mon.blow_up({**rec, "norm_sigma_Q": 1.0}) is None
    assert "exceeds" in mon.blow_up({**rec, "norm_sigma_Q": 1.0, "max_vm": 11.0})
    assert "kappa" in mon.blow_up({**rec, "norm_sigma_Q": 1.0, "max_kappa": 11.0})


def test_extreme_grading_fails_cleanly(tmp_path):
    """time.grading = 1e10 (first step 1e-150): the von Mises projection failed inside a
    step with a traceback and no summary.  Now either refused as input (exit 2, one line) or
    a failed step with its summary (exit 1)."""
    out = tmp_path / "graded"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", "--set", "time.grading=1e10"])
    assert proc.returncode in (1, 2) and "Traceback" not in proc.stderr, proc.stderr
    if proc.returncode == 2:
        assert "time.grading" in _one_error_line(proc)
    else:
        s = _summary(out)
        assert s["status"] == "failed" and s["failure"]["step"] == s["last_good_step"] + 1


def _fails_at_call(real, nth: int, error: Exception, counts=lambda *args: True):
    """``real`` wrapped so that its nth counted call raises ``error``."""
    calls = []

    def wrapper(*args):
        if counts(*args):
            calls.append(args)
            if len(calls) == nth:
                raise error
        return real(*args)
    return wrapper


def test_failing_local_update_is_a_failed_step(tmp_path, monkeypatch, capsys):
    """A numerical error of the history update (here injected at step 3) is a failed step:
    summary with status failed naming the step, exit 1, outputs of steps 0-2 intact."""
    from vpcontact.model import history
    failing = _fails_at_call(history.ViscoplasticHistory.before_solve, 3, RuntimeError(
        "von Mises projection: secular equation did not converge"))
    monkeypatch.setattr(history.ViscoplasticHistory, "before_solve", failing)
    out = tmp_path / "local"
    assert _in_process_run(out, monkeypatch) == 1
    s = _summary(out)
    assert s["status"] == "failed" and s["failure"]["step"] == 3 and s["last_good_step"] == 2
    assert "von Mises projection" in s["failure"]["reason"]
    assert _xdmf_times(out) == pytest.approx([0.0, 0.25, 0.5])
    assert "Traceback" not in capsys.readouterr().err


# ------------------------------------------------------------------ output faults
def _in_process_run(out, monkeypatch, extra=()):
    """cli.main in this process (so faults can be injected); returns the exit code."""
    import vpcontact.cli.main as cli
    monkeypatch.chdir(ROOT)
    return cli.main(["run", str(PAPER_CASE), "--out", str(out), "--quiet", "--no-plots",
                     *TINY, *extra])


def test_hdf5_failure_mid_run_is_a_failed_run(tmp_path, monkeypatch, capsys):
    """The file system fills up at the third field write: status failed naming the file,
    exit 1, solution.xdmf still describes the two steps written before."""
    import vpcontact.io.output as output
    failing = _fails_at_call(output.dio.XDMFFile, 3, RuntimeError(
        "Failed to write HDF5 dataset (No space left on device)"),
        counts=lambda comm, path, mode: mode == "a")             # the field writes only
    monkeypatch.setattr(output.dio, "XDMFFile", failing)
    out = tmp_path / "full"
    assert _in_process_run(out, monkeypatch) == 1
    s = _summary(out)
    assert s["status"] == "failed" and "solution.h5" in s["failure"]["reason"]
    assert "No space left" in s["failure"]["reason"]
    assert _xdmf_times(out) == pytest.approx([0.0, 0.25])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "the run failed" in err


def _xdmf_file_times(path):
    root = ET.parse(path).getroot()
    grid = next(g for g in root.iter("Grid") if g.get("GridType") == "Collection")
    return [float(g.find("Time").get("Value")) for g in grid.findall("Grid")]


def test_disk_full_at_an_output_step_names_the_last_step_written(tmp_path, monkeypatch,
                                                                   capsys):
    """The disk fills up while solution.xdmf gets step 3 (injected: its third append raises
    ENOSPC): step 3 is computed, not written, so summary.json's last_good_step, the steps'
    ``written`` mark, the message and every per-step file agree on step 2 (they said 3)."""
    import errno

    from vpcontact.io import xdmf
    real = xdmf.TemporalXdmf._append
    appends = []

    def full(self, grid):
        if self.path.name == "solution.xdmf":
            appends.append(grid)
            if len(appends) == 3:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))
        return real(self, grid)

    monkeypatch.setattr(xdmf.TemporalXdmf, "_append", full)
    out = tmp_path / "full"
    assert _in_process_run(out, monkeypatch) == 1
    s = _summary(out)
    assert s["status"] == "failed" and s["failure"]["step"] == 3
    assert "No space left on device" in s["failure"]["reason"]
    assert s["last_good_step"] == 2
    assert [st["n"] for st in s["steps"]] == [1, 2, 3]
    assert s["steps"][-1]["written"] is False
    assert all("written" not in st for st in s["steps"][:-1])
    err = capsys.readouterr().err
    assert "the run failed at step 3 (t = 0.75)" in err and "outputs up to step 2 are in" in err
    assert _xdmf_times(out) == pytest.approx([0.0, 0.25, 0.5])
    assert _xdmf_file_times(out / "contact.xdmf") == pytest.approx([0.0, 0.25, 0.5])
    rows = (out / "history.csv").read_text().splitlines()
    assert [int(r.split(",")[0]) for r in rows[1:]] == [1, 2]


def test_hdf5_file_size_limit_is_a_failed_run_not_a_crash(tmp_path):
    """A real HDF5 write fault (the file size limit RLIMIT_FSIZE stands for a full disk:
    solution.h5 cannot grow past 150 kB): dolfinx's XDMFFile failed to close the HDF5 file,
    and its destructor, then HDF5's termination in MPI_Finalize, crashed (segmentation
    fault, exit 139 or 59, no summary; and 140 lines of HDF5's error stack).  Now exit 1,
    one error line, summary.json agreeing with the files."""
    import resource
    args = ["run", PAPER_CASE, "--set", "time.N=200", "--set", "mesh.n=8", "--quiet"]
    assert run_cli([*args, "--set", "time.N=2", "--out", tmp_path / "warm"]).returncode == 0

    def limit():                      # the JIT cache is warm: only the outputs grow
        resource.setrlimit(resource.RLIMIT_FSIZE, (150_000, 150_000))
    out = tmp_path / "limited"
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "vpcontact", *map(str, args), "--out", str(out),
                           "--no-plots"], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300, preexec_fn=limit)
    assert proc.returncode == 1, proc.stderr[-3000:]
    assert "Segmentation" not in proc.stderr and "Traceback" not in proc.stderr
    lines = [x for x in proc.stderr.splitlines() if x.strip()]   # no HDF5 error stack
    assert len(lines) == 1 and "cannot write the outputs" in lines[0], proc.stderr[-3000:]
    s = _summary(out)
    assert s["status"] == "failed" and s["steps"][-1]["written"] is False
    n = s["last_good_step"]
    assert 0 < n == s["failure"]["step"] - 1 and f"outputs up to step {n} are in" in lines[0]
    assert len(_xdmf_times(out)) == n + 1


def test_summary_write_failure_is_reported(tmp_path, monkeypatch, capsys):
    import vpcontact.io.output as output
    real = output.atomic_write

    def refuse(path, text, **options):
        if path.name == "summary.json":
            raise OSError(28, "No space left on device", str(path))
        return real(path, text, **options)

    monkeypatch.setattr(output, "atomic_write", refuse)
    out = tmp_path / "nosummary"
    assert _in_process_run(out, monkeypatch) == 1
    err = capsys.readouterr().err
    assert "summary.json" in err and "No space left" in err and "Traceback" not in err
    # written into the space kept for it since the start (it was missing): status failed
    s = _summary(out)
    assert s["status"] == "failed" and "cannot write summary.json" in s["failure"]["reason"]
    assert "No space left on device" in s["summary_error"] and s["last_good_step"] == 4
    assert not list(out.glob(".summary.json.tmp*"))          # no temporary left behind


def test_numpy_types_in_the_summary(tmp_path):
    """contact.friction.c1 = 0: the well-posedness verdict is a numpy bool; the summary is
    written (it was 'bool_ is not JSON serializable', exit 1)."""
    from vpcontact.io.output import to_json
    assert json.loads(to_json({"a": np.bool_(True), "b": np.float64(2.5),
                               "c": np.arange(2)})) == {"a": True, "b": 2.5, "c": [0, 1]}
    out = tmp_path / "c1zero"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", *TINY,
                    "--set", "contact.friction.c1=0"])
    assert proc.returncode == 0, proc.stderr
    assert _summary(out)["diagnostics"]["unique"] is True


# ------------------------------------------------------------------ output directory
@pytest.mark.parametrize("target", ["file", "case", "under_file"])
def test_bad_out_is_refused_in_one_line(tmp_path, target):
    plain = tmp_path / "plain.txt"
    plain.write_text("keep me\n")
    out = {"file": plain, "case": PAPER_CASE, "under_file": plain / "sub"}[target]
    before = PAPER_CASE.read_text()
    proc = run_cli(["run", PAPER_CASE, "--out", out, *TINY])
    assert proc.returncode == 2
    assert "--out" in _one_error_line(proc)
    assert plain.read_text() == "keep me\n" and PAPER_CASE.read_text() == before


def test_second_run_on_a_locked_directory_is_refused(tmp_path):
    """While another process holds the directory's lock, a run there (even with
    --overwrite) exits 2 and touches nothing."""
    out = tmp_path / "shared"
    out.mkdir()
    (out / "summary.json").write_text('{"status": "completed"}\n')
    with open(out / ".vpcontact.lock", "a+") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        proc = run_cli(["run", PAPER_CASE, "--out", out, "--overwrite", *TINY])
    assert proc.returncode == 2
    assert "another vpcontact process" in _one_error_line(proc)
    assert (out / "summary.json").read_text() == '{"status": "completed"}\n'


@pytest.mark.parametrize("args", [["stability", PAPER_CASE, "--n", "0"],
                                  ["stability", PAPER_CASE, "--n", "-3"],
                                  ["stability", PAPER_CASE, "--steps", "0"],
                                  ["bench", "--extra", "foo"],
                                  ["bench", "--extra", "4:0"],
                                  ["bench", "--repeat", "0"],
                                  ["convergence", PAPER_CASE, "--levels", "0"],
                                  ["convergence", PAPER_CASE, "--deltas", "nan"]])
def test_bad_command_numbers_are_refused_in_one_line(tmp_path, args):
    proc = run_cli([*args, "--out", tmp_path / "x"] if args[0] != "bench" else
                   [*args, "--out", tmp_path / "x"])
    assert proc.returncode == 2
    assert "allowed" in _one_error_line(proc)
    assert not (tmp_path / "x").exists()


# ------------------------------------------------------------------ closed stdout, Ctrl-C
def test_closed_stdout_does_not_kill_the_run(tmp_path):
    """`run --verbose CASE | head -1`: PETSc turned SIGPIPE into MPI_ABORT (empty output
    directory).  Now the run finishes its files and exits 0."""
    out = tmp_path / "piped"
    cmd = [sys.executable, "-m", "vpcontact", "run", str(PAPER_CASE), "--out", str(out),
           "--verbose",
           "--no-plots", *TINY]
    proc = subprocess.Popen(cmd, cwd=ROOT, env={**os.environ, **MPI_ENV},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline().startswith("[vpcontact]")
    proc.stdout.close()                                   # the reader goes away
    err = proc.stderr.read()
    assert proc.wait(timeout=300) == 0, err
    assert "PETSC ERROR" not in err and "Traceback" not in err and "MPI_ABORT" not in err
    assert _summary(out)["status"] == "completed" and len(_summary(out)["steps"]) == 4


def test_ctrl_c_while_drawing_keeps_a_true_summary(tmp_path, monkeypatch, capsys):
    import vpcontact.post.plot as plot

    def interrupted(outdir, log=None, **options):
        raise KeyboardInterrupt

    monkeypatch.setattr(plot, "plot_all", interrupted)
    import vpcontact.cli.main as cli
    monkeypatch.chdir(ROOT)
    out = tmp_path / "drawing"
    code = cli.main(["run", str(PAPER_CASE), "--out", str(out), "--quiet", *TINY])
    err = capsys.readouterr().err
    assert code == 3
    assert "while drawing the figures" in err and "before the time loop" not in err
    assert _summary(out)["status"] == "completed"


def test_ctrl_c_while_writing_the_summary_still_writes_it(tmp_path, monkeypatch):
    """SIGINT arriving during the final writes is deferred: summary.json is written."""
    import vpcontact.observers as observers
    real = observers.write_json

    def signalled(comm, path, data):
        os.kill(os.getpid(), signal.SIGINT)
        return real(comm, path, data)

    monkeypatch.setattr(observers, "write_json", signalled)
    out = tmp_path / "summary"
    assert _in_process_run(out, monkeypatch) == 0
    assert _summary(out)["status"] == "completed"


def test_checkpoint_write_failure_is_a_failed_run(tmp_path, monkeypatch, capsys):
    """The disk fills up while a checkpoint is written: status failed naming the file, no
    partial checkpoint left, exit 1 (collective: no rank waits for rank 0)."""
    import vpcontact.io.checkpoint as checkpoint

    def full(fh, **arrays):
        fh.write(b"partial")
        raise OSError(28, "No space left on device", fh.name)

    monkeypatch.setattr(checkpoint.np, "savez", full)
    out = tmp_path / "ckpt"
    assert _in_process_run(out, monkeypatch, ["--set", "output.checkpoint_every=2"]) == 1
    s = _summary(out)
    assert s["status"] == "failed" and s["failure"]["step"] == 2
    assert "No space left" in s["failure"]["reason"]
    assert not list(out.glob("*checkpoint*"))
    assert "Traceback" not in capsys.readouterr().err


# ------------------------------------------------------------------ second probe
@pytest.mark.parametrize("lambda1, N", [(10, 6), (2, 3), (5, 4), (20, 6)])
def test_coarse_explicit_blow_up_is_diverged(tmp_path, lambda1, N):
    """Unstable explicit runs on a 4 x 4 mesh whose stresses reached 1e4-5e5 (stable: ~20)
    and 'completed' with contact states flipping from step to step."""
    out = tmp_path / "coarse"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", "--set", "mesh.n=4",
                    "--set", f"time.N={N}", "--set", f"material.viscoplastic.lambda1={lambda1}",
                    "--set", "solver.method=fast"])
    assert proc.returncode == 1, proc.stderr
    assert _summary(out)["status"] == "diverged"


@pytest.mark.parametrize("target", ["repo", "cases", "nonempty"])
def test_out_with_foreign_files_is_refused(tmp_path, target):
    """--out ., --out cases, or any directory holding files that no vpcontact command
    writes: outputs were written among them (even into / and .git)."""
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep\n")
    out = {"repo": ROOT, "cases": ROOT / "cases", "nonempty": other}[target]
    before = sorted(p.name for p in out.iterdir())
    proc = run_cli(["run", PAPER_CASE, "--out", out, *TINY])
    assert proc.returncode == 2
    assert "not vpcontact outputs" in _one_error_line(proc)
    assert sorted(p.name for p in out.iterdir()) == before


def test_out_of_an_earlier_run_with_studies_is_accepted(tmp_path):
    """A run's directory may hold its convergence/ and stability/ subdirectories."""
    out = tmp_path / "run"
    (out / "convergence").mkdir(parents=True)
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", *TINY])
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("redirect", [">&-", ">/dev/full", "2>&-", "2>/dev/full"])
def test_closed_or_full_std_streams_do_not_stop_the_run(tmp_path, redirect):
    out = tmp_path / "streams"
    cmd = (f"{sys.executable} -m vpcontact run {PAPER_CASE} --out {out} --no-plots "
           f"{' '.join(TINY)} {redirect}")
    proc = subprocess.run(["bash", "-c", cmd], cwd=ROOT, env={**os.environ, **MPI_ENV},
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr
    assert "Logging error" not in proc.stdout + proc.stderr
    assert _summary(out)["status"] == "completed"


def test_petsc_errors_are_one_line(tmp_path):
    """-ksp_error_if_not_converged: PETSc's error (code 91) carries its call stack; the
    failure says the code and the message on one line."""
    out = tmp_path / "ksp"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", *TINY,
                    "--set", "solver.method=snes_vi", "-ksp_type", "gmres", "-pc_type",
                    "jacobi", "-ksp_max_it", "2", "-ksp_error_if_not_converged"])
    assert proc.returncode == 1
    line = [x for x in proc.stderr.splitlines() if x.startswith("vpcontact: error")]
    assert len(line) == 1 and "PETSc error code 91" in line[0] and "DIVERGED_ITS" in line[0]
    assert "() at " not in proc.stderr
    assert "\n" not in _summary(out)["failure"]["reason"]


def test_restart_into_its_own_directory_is_refused(tmp_path):
    """--restart DIR --out DIR --overwrite deleted the checkpoint it continued from."""
    out = tmp_path / "ck"
    assert run_cli(["run", PAPER_CASE, "--out", out, "--quiet", *TINY,
                    "--set", "output.checkpoint_every=2"]).returncode == 0
    before = sorted(p.name for p in out.iterdir())
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--overwrite", "--restart", out, *TINY,
                    "--set", "output.checkpoint_every=2"])
    assert proc.returncode == 2
    assert "--restart" in _one_error_line(proc)
    assert sorted(p.name for p in out.iterdir()) == before


@pytest.mark.parametrize("option", ["--out", "--restart"])
def test_empty_paths_are_refused(option):
    proc = run_cli(["run", PAPER_CASE, option, "", *TINY])
    assert proc.returncode == 2 and "empty path" in _one_error_line(proc)


def test_huge_values_are_not_echoed_in_full():
    proc = run_cli(["check", PAPER_CASE, "--set", "name=" + "a" * 100000])
    assert proc.returncode == 2
    assert len(_one_error_line(proc)) < 1200


def test_adaptive_limit_below_k_min_fails_at_once(tmp_path):
    """max_indicator = 1e-9: the stepper halved 31 times to k = 2e-10, far below k_min,
    before failing; now it fails at once, naming both numbers."""
    out = tmp_path / "adaptive"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", "--set", "mesh.n=4",
                    "--set", "time.N=4", "--set", "time.adaptive={max_indicator: 1e-9}"])
    assert proc.returncode == 1
    s = _summary(out)
    assert s["status"] == "failed" and "k_min" in s["failure"]["reason"]
    assert s["step_history"] == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_while_starting_is_one_line(tmp_path, sig):
    """Ctrl-C or SIGTERM while the modules load (here: once MPI is loaded) printed a
    KeyboardInterrupt traceback (or nothing, exit 143); now one line and exit 3."""
    cmd = [sys.executable, "-m", "vpcontact", "run", str(PAPER_CASE), "--out", str(tmp_path / "s"),
           "--no-plots", *TINY]
    proc = subprocess.Popen(cmd, cwd=ROOT, env={**os.environ, **MPI_ENV},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    maps = f"/proc/{proc.pid}/maps"
    for _ in range(20000):                      # until mpi4py's extension is mapped
        try:
            if "mpi4py" in open(maps).read():
                break
        except OSError:
            pass
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 3, err
    assert "Traceback" not in out + err and "interrupted" in err
