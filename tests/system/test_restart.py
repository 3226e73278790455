"""Checkpoint/restart (serial, mpirun -n 2, across rank counts), SIGINT/SIGTERM,
a forced solver failure, and readable outputs after each."""
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT, run_cli

CASES = {"paper": PAPER_CASE, "memory_slip": ROOT / "cases" / "slip_weakening.yaml",
         "memory": ROOT / "cases" / "memory.yaml"}


def _final(out):
    s = json.loads((out / "summary.json").read_text())
    return s, np.array([[st["norm_u_V"], st["norm_sigma_Q"], st["norm_kappa_Y"]]
                        for st in s["steps"]])


def _xdmf_steps(out):
    """Time steps in solution.h5 that the XDMF file references (readable output)."""
    text = (out / "solution.xdmf").read_text()
    assert text.rstrip().endswith("</Xdmf>")
    with h5py.File(out / "solution.h5", "r") as f:
        return len(f["Function"]["u"].keys())


def _start_long_run(out, *extra):
    """A long run (h = 1/32, 4000 steps) in the background, returned once solution.xdmf
    holds t = 0 and at least one step: waiting for progress, not for a fixed time, so a
    slow or loaded machine cannot make the signal land before the first step."""
    proc = _launch_long_run(out, *extra)
    _wait_first_step(proc, out)
    return proc


def _launch_long_run(out, *extra):
    """The long run of _start_long_run, started and not waited for."""
    cmd = [sys.executable, "-m", "vpcontact", "run", str(PAPER_CASE), "--out", str(out),
           "--no-plots", "--set", "mesh.n=32", "--set", "time.N=4000",
           "--set", "solver.method=fast", *extra]
    return subprocess.Popen(cmd, cwd=ROOT, env={**MPI_ENV, "PATH": "/usr/bin:/bin",
                                                "PYTHONPATH": str(ROOT)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_first_step(proc, out) -> None:
    """Wait until solution.xdmf holds t = 0 and at least one step (fail if the run ends)."""
    deadline = time.monotonic() + 600
    while _written_steps(out) < 2:
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail("the run wrote no step: " + proc.communicate()[1][-2000:])
        time.sleep(0.05)


def _written_steps(out):
    """How many time points of u solution.xdmf names (0 while it does not exist); the
    file is republished atomically, so it is always whole."""
    try:
        return (out / "solution.xdmf").read_text().count("solution.h5:/Function/u/")
    except FileNotFoundError:
        return 0


@pytest.mark.parametrize("name", ["paper", "memory", "memory_slip"])
def test_restart_equals_uninterrupted_serial(name, tmp_path):
    case = CASES[name]
    full, re_ = tmp_path / "full", tmp_path / "re"
    opts = ["--set", "time.N=8", "--set", "output.checkpoint_every=4"]
    assert run_cli(["run", case, "--out", full, *opts]).returncode == 0
    proc = run_cli(["run", case, "--out", re_, *opts, "--restart",
                    full / "checkpoint_000004.npz"])
    assert proc.returncode == 0, proc.stderr
    assert "restarted from" in proc.stdout
    a, na = _final(full)
    b, nb = _final(re_)
    assert len(nb) == 8 and b["steps"][3]["n"] == 4
    np.testing.assert_allclose(nb, na, rtol=1e-12, atol=1e-15)
    # history.csv: the restored steps' rows, then the new ones, each once
    ha, hb = _history(full), _history(re_)
    assert [r["n"] for r in hb] == [r["n"] for r in ha] == [str(i) for i in range(1, 9)]
    for col in ("nodes_bound", "nodes_compliance", "nodes_separated"):
        assert [r[col] for r in hb] == [r[col] for r in ha], col


def _history(out):
    import csv
    with open(out / "history.csv") as fh:
        return list(csv.DictReader(fh))


MPI_RESTART_OPTS = ["--set", "time.N=8", "--set", "output.checkpoint_every=4"]


@pytest.fixture(scope="module")
def serial_reference(tmp_path_factory):
    """The uninterrupted serial run the restarts under mpirun are compared with (run once)."""
    ref = tmp_path_factory.mktemp("restart_ref") / "ref"
    assert run_cli(["run", CASES["memory_slip"], "--out", ref, *MPI_RESTART_OPTS]).returncode == 0
    return ref


@pytest.mark.slow
@pytest.mark.parametrize("ranks", [(2, 2), (1, 2), (2, 1)])
def test_restart_under_mpi(ranks, tmp_path, serial_reference):
    """Checkpoint written on r1 ranks, restarted on r2 ranks: the same result."""
    r1, r2 = ranks
    ref, full, re_ = serial_reference, tmp_path / "full", tmp_path / "re"
    opts = MPI_RESTART_OPTS
    assert run_cli(["run", CASES["memory_slip"], "--out", full, *opts], nprocs=r1).returncode == 0
    proc = run_cli(["run", CASES["memory_slip"], "--out", re_, *opts, "--restart", full],
                   nprocs=r2)
    assert proc.returncode == 0, proc.stderr
    # the newest checkpoint of 'full' is step 8: restart from step 4 explicitly as well
    proc = run_cli(["run", CASES["memory_slip"], "--out", tmp_path / "re4", *opts, "--restart",
                    full / "checkpoint_000004.npz"], nprocs=r2)
    assert proc.returncode == 0, proc.stderr
    _, n_ref = _final(ref)
    _, n4 = _final(tmp_path / "re4")
    np.testing.assert_allclose(n4, n_ref, rtol=1e-9)


def test_restart_refuses_another_case(tmp_path):
    full = tmp_path / "full"
    opts = ["--set", "time.N=4", "--set", "output.checkpoint_every=2"]
    assert run_cli(["run", PAPER_CASE, "--out", full, *opts]).returncode == 0
    proc = run_cli(["run", PAPER_CASE, "--out", tmp_path / "re", "--set", "time.N=4",
                    "--set", "material.E=2000", "--restart", full])
    assert proc.returncode == 2 and "different case" in proc.stderr
    assert not (tmp_path / "re").exists()


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_ends_the_run_cleanly(sig, tmp_path):
    out = tmp_path / "o"
    proc = _start_long_run(out)                     # step 1 or later is running
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 3, stderr
    assert "Traceback" not in stderr and "interrupted" in stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "interrupted" and 0 < s["last_good_step"] < 4000
    assert s["failure"]["reason"] == f"interrupted by {sig.name}"
    assert _xdmf_steps(out) >= 2                    # t = 0 and the last completed step
    ck = sorted(out.glob("checkpoint_*.npz"))
    assert ck and ck[-1].name == f"checkpoint_{s['last_good_step']:06d}.npz"


def test_forced_snes_failure_keeps_valid_outputs(tmp_path):
    """-snes_max_it 1 fails at step 2 after step 1 converged in ... : status failed, exit 1, XDMF
    with the steps before, readable."""
    out = tmp_path / "o"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "time.N=4",
                    "--set", "solver.method=snes_vi", "-snes_max_it", "0"])
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and s["failure"]["step"] == s["last_good_step"] + 1
    assert _xdmf_steps(out) == s["last_good_step"] + 1


def _kill_outside_hdf5_writes(proc) -> int:
    """SIGKILL at the first moment (stopped with SIGSTOP to look) when the process has no
    output HDF5 file open: HDF5 updates a file's metadata in place, so a kill inside
    its write can damage the file (seen once in about 300 kills, on a loaded machine), which
    the README says.  Returns the stops that landed inside a write."""
    import os
    inside = 0
    for _ in range(1000):
        proc.send_signal(signal.SIGSTOP)
        fds = Path(f"/proc/{proc.pid}/fd")
        targets = []
        for fd in fds.iterdir():
            try:
                targets.append(os.readlink(fd))
            except OSError:                         # closed meanwhile
                pass
        if not any(t.endswith(("/solution.h5", "/contact.h5")) for t in targets):
            proc.kill()
            return inside
        inside += 1
        proc.send_signal(signal.SIGCONT)
        time.sleep(0.002)
    proc.kill()
    pytest.fail("the process had an HDF5 file open at every look")


def test_xdmf_is_readable_after_the_process_is_killed(tmp_path):
    """SIGKILL (no clean-up at all) at an arbitrary moment outside the HDF5 writes while
    every step is written (output.every: 1): solution.xdmf and contact.xdmf still parse and
    every HDF5 dataset they name exists and reads; history.csv has whole rows.  Three runs
    side by side, killed 1.3, 2.1 and 2.9 s after all three wrote their first step."""
    delays = (1.3, 2.1, 2.9)
    outs = [tmp_path / f"o{delay}" for delay in delays]
    procs = []
    try:
        procs += [_launch_long_run(out) for out in outs]
        for proc, out in zip(procs, outs, strict=True):
            _wait_first_step(proc, out)
        start = time.monotonic()
        for proc, delay in zip(procs, delays, strict=True):
            time.sleep(max(0.0, start + delay - time.monotonic()))   # any moment after it
            _kill_outside_hdf5_writes(proc)
            proc.communicate(timeout=60)
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    for out in outs:
        _check_readable_after_a_kill(out)


def _check_readable_after_a_kill(out) -> None:
    """The xdmf files parse, every HDF5 dataset they name reads, history.csv has whole rows."""
    import xml.etree.ElementTree as ET
    root = ET.fromstring((out / "solution.xdmf").read_text())
    steps = root.findall(".//Grid[@Name='solution'][@GridType='Uniform']")
    assert len(steps) >= 2
    assert all(len(g.findall("Attribute")) == 8 for g in steps)   # u, sigma, sigma_vm, kappa,
    #                                                                eps, eps_vp, sigma_nodal, eta
    for stem in ("solution", "contact"):
        root = ET.fromstring((out / f"{stem}.xdmf").read_text())
        with h5py.File(out / f"{stem}.h5", "r") as f:
            for ref in root.iter("DataItem"):
                if ref.get("Format") == "HDF":
                    name, path = ref.text.strip().split(":", 1)
                    assert name == f"{stem}.h5"
                    assert f[path][...].size > 0, path
    lines = (out / "history.csv").read_text().splitlines()
    assert all(line.count(",") == lines[0].count(",") for line in lines)     # whole rows


@pytest.mark.parametrize("extra", [["--set", "time.adaptive={}"],
                                   ["--set", "time.scheme=implicit"]],
                         ids=["adaptive", "implicit"])
def test_restart_adaptive_and_implicit(extra, tmp_path):
    """The adaptive stepper's state and the implicit scheme's committed state survive."""
    full, re_ = tmp_path / "full", tmp_path / "re"
    opts = ["--set", "time.N=8", "--set", "output.checkpoint_every=3",
            "--set", "solver.method=snes_vi", *extra]
    assert run_cli(["run", PAPER_CASE, "--out", full, *opts]).returncode == 0
    ck = sorted(full.glob("checkpoint_*.npz"))[0]
    proc = run_cli(["run", PAPER_CASE, "--out", re_, *opts, "--restart", ck])
    assert proc.returncode == 0, proc.stderr
    a, na = _final(full)
    b, nb = _final(re_)
    assert [s["t"] for s in a["steps"]] == [s["t"] for s in b["steps"]]
    np.testing.assert_allclose(nb, na, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("ranks", [(1, 1), (1, 2)], ids=["serial", "1-to-2-ranks"])
def test_restart_of_a_very_small_body(ranks, tmp_path):
    """The paper case scaled down to 1e-9 m: checkpoint coordinates match relative to the
    mesh (app/io/checkpoint.py match_points), not to an absolute 1e-10 m that merged nodes
    and restarted from the wrong values (2-6% off, reported as success)."""
    r1, r2 = ranks
    full, re_ = tmp_path / "full", tmp_path / "re"
    opts = ["--set", "mesh.L1=1e-9", "--set", "mesh.L2=1e-9", "--set", "time.N=8",
            "--set", "output.checkpoint_every=4", "--set", "solver.method=fast"]
    proc = run_cli(["run", PAPER_CASE, "--out", full, *opts], nprocs=r1)
    assert proc.returncode == 0, proc.stderr
    proc = run_cli(["run", PAPER_CASE, "--out", re_, *opts, "--restart",
                    full / "checkpoint_000004.npz"], nprocs=r2)
    assert proc.returncode == 0, proc.stderr
    _, na = _final(full)
    _, nb = _final(re_)
    np.testing.assert_allclose(nb, na, rtol=1e-10, atol=0)


def test_match_points_is_relative_to_the_mesh():
    from vpcontact.io.checkpoint import match_points
    rng = np.random.default_rng(1)
    grid = np.stack(np.meshgrid(np.linspace(0, 1, 17), np.linspace(0, 1, 17)), -1).reshape(-1, 2)
    order = rng.permutation(len(grid))
    for scale in (1e-9, 1.0, 1e6):
        stored = grid * scale
        wanted = stored[order] * (1 + 1e-14)          # round-off of another partition
        assert np.array_equal(match_points(stored, wanted), order)
        with pytest.raises(ValueError, match="from the nearest stored one"):
            match_points(stored, wanted + 1e-3 * scale / 16)
    with pytest.raises(ValueError, match="coincide"):
        match_points(np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 1.0]]), np.zeros((1, 2)))
