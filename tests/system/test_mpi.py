"""mpirun -n 2 gives the same results as a serial run (summary norms to 1e-8 relative)."""
import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import MPI_ENV, PAPER_CASE, ROOT, run_cli

pytestmark = pytest.mark.mpi
KEYS = ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y", "max_vm", "max_kappa")


def _run(tmp_path, nprocs, extra=()):
    out = tmp_path / f"np{nprocs}"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", *extra], nprocs=nprocs)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return _results(out)


def _results(out):
    """(summary.json, the rows of contact.csv) of a results directory."""
    summary = json.loads((out / "summary.json").read_text())
    rows = list(csv.DictReader(open(out / "contact.csv")))
    return summary, rows


@pytest.mark.parametrize("mesh", [[], ["--set", "mesh.kind=unstructured", "--set", "mesh.h=0.08"]],
                         ids=["structured", "unstructured"])
def test_serial_equals_two_ranks(tmp_path, mesh, request):
    """The serial run of the paper case itself is the session's (conftest.paper_cli_run)."""
    s1, c1 = (_run(tmp_path, 1, mesh) if mesh else
              _results(request.getfixturevalue("paper_cli_run")[0]))
    s2, c2 = _run(tmp_path, 2, mesh)
    assert s2["mpi_ranks"] == 2 and s1["mesh"] == s2["mesh"]
    for a, b in zip(s1["steps"], s2["steps"], strict=True):
        for key in KEYS:
            assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-14), key
    assert len(c1) == len(c2)
    for col in ("x", "u_x", "u_y", "neg_sigma_nu", "neg_sigma_tau"):
        v1 = np.array([float(r[col]) for r in c1])
        v2 = np.array([float(r[col]) for r in c2])
        np.testing.assert_allclose(v2, v1, rtol=1e-8, atol=1e-12 * np.abs(v1).max())
    assert [r["state"] for r in c1] == [r["state"] for r in c2]


def test_small_case_note_in_the_log(tmp_path):
    """Under mpirun on few dofs per rank the run log says where the time went: its set-up
    and steps are summary.json's, its dofs per rank half the mesh's."""
    out = tmp_path / "np2"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "mesh.n=4", "--set", "time.N=2"],
                   nprocs=2)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    s = json.loads((out / "summary.json").read_text())
    note = [line for line in proc.stdout.splitlines() if "dofs per rank" in line]
    assert len(note) == 1, proc.stdout
    assert f"mpirun -n 2 on {s['mesh']['dofs'] // 2:,} dofs per rank: start-up " in note[0]
    assert f"set-up {s['setup_s']:.2f} s, steps {s['loop_s']:.2f} s;" in note[0]


ROOT_CALL_SCRIPT = """
import json
import pathlib
import sys
import time
from mpi4py import MPI
from vpcontact import threads
from vpcontact.io.errors import StepSolveError
comm = MPI.COMM_WORLD

def busy():
    t = time.perf_counter()
    while time.perf_counter() - t < 0.5:
        pass
    return comm.rank, [1.0, 2.0]

cpu = time.process_time()
value = threads.root_call(comm, busy)
cpu = time.process_time() - cpu

def fails():
    raise StepSolveError("the root's iteration failed")

try:
    threads.root_call(comm, fails)
    raised = None
except StepSolveError as exc:
    raised = str(exc)
out = pathlib.Path(sys.argv[1]) / f"rank{comm.rank}.json"   # a file per rank: no merged stdout
out.write_text(json.dumps({"rank": comm.rank, "value": value, "cpu": cpu, "raised": raised}))
"""


def test_root_call_lets_the_other_ranks_sleep_and_raises_everywhere(tmp_path):
    """threads.root_call: the root's result and its exception reach every rank, and a rank
    waiting for the root sleeps (its CPU time stays far below the root's 0.5 s of work; a
    rank waiting inside MPI would spin at 100%)."""
    script = tmp_path / "root_call.py"
    script.write_text(ROOT_CALL_SCRIPT)
    proc = subprocess.run(["mpirun", "-n", "2", sys.executable, str(script), str(tmp_path)],
                          cwd=ROOT, env={**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    ranks = [json.loads((tmp_path / f"rank{r}.json").read_text()) for r in (0, 1)]
    assert [r["rank"] for r in ranks] == [0, 1]
    for r in ranks:
        assert r["value"] == [0, [1.0, 2.0]], r
        assert r["raised"] == "the root's iteration failed", r
    assert ranks[1]["cpu"] < 0.15, ranks[1]


SIGNAL_ON_RANK_1 = """
import os, signal, sys
from mpi4py import MPI
from vpcontact.studies import convergence as cv
count, real = [0], cv.GridSamples.step
def step(self, sim, record):
    real(self, sim, record)
    count[0] += 1
    if count[0] == 9 and MPI.COMM_WORLD.rank == 1:
        os.kill(os.getpid(), signal.SIGINT)
cv.GridSamples.step = step
from vpcontact.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_signal_on_one_rank_ends_the_study_on_both(tmp_path):
    """SIGINT reaching rank 1 only, in step 1 of the third run of a convergence study: every
    rank stops that run and the study (exit 3), rank 0 prints the one line, and the two runs
    that finished are in the cache (before: 'run failed', exit 1)."""
    cache = tmp_path / "cache"
    args = ["convergence", ROOT / "cases" / "hertz_cylinder.yaml", "--set", "mesh.size=4",
            "--levels", "0", "1", "--reference", "2", "--vary", "h", "--out", tmp_path / "o",
            "--cache-dir", cache]
    proc = subprocess.run(["mpirun", "-n", "2", sys.executable, "-c", SIGNAL_ON_RANK_1,
                           *map(str, args)], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert proc.returncode == 3, proc.stderr
    assert proc.stderr.count("vpcontact:") == 1, proc.stderr
    assert ("vpcontact: convergence study interrupted by a signal on another rank during the "
            "run r = 1, N = 4, delta = 1e-07 (after its step 2); the 2 run(s) that finished "
            f"are in the run cache {cache}") in proc.stderr
    assert len(list(cache.glob("run-*.h5"))) == 2 and not list(cache.glob(".*"))
