"""Shared helpers: the paper case as a dict, in-process runs and CLI runs (serial / mpirun)."""
import copy
import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OMP_THREAD_LIMIT", "1")      # CHOLMOD's loops, as the command line

import pytest  # noqa: E402

try:   # property-based tests: the same examples on every machine, nothing timed
    from hypothesis import HealthCheck, settings
except ImportError:
    pass
else:
    # derandomize: examples from a fixed seed per test; database=None: no .hypothesis/ in the
    # working directory is read or written; deadline / too_slow time the examples, which
    # fails on slow or loaded machines
    settings.register_profile("vpcontact", deadline=None, derandomize=True, database=None,
                              suppress_health_check=[HealthCheck.too_slow])
    settings.load_profile("vpcontact")

ROOT = Path(__file__).resolve().parents[1]
PAPER_CASE = ROOT / "cases" / "wang_cheng_2021.yaml"
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1", "OPENBLAS_NUM_THREADS": "1"}


def paper_raw() -> dict:
    from vpcontact.case import load_raw
    return load_raw(PAPER_CASE)


def make_case(raw: dict | None = None, **sections):
    """Validate the paper case, with whole sections or keys replaced: make_case(time={'N': 2})
    merges into the section; a value of None removes the section."""
    from vpcontact.case import validate
    raw = copy.deepcopy(raw if raw is not None else paper_raw())
    for name, value in sections.items():
        if value is None:
            raw.pop(name, None)
        elif isinstance(value, dict) and isinstance(raw.get(name), dict):
            raw[name].update(value)
        else:
            raw[name] = value
    return validate(raw, "test-case")


def run_case(case):
    """Run in this process without writing outputs; returns the RunResult."""
    from mpi4py import MPI

    from vpcontact.simulation import run
    return run(case, MPI.COMM_WORLD)


def run_cli(args, nprocs: int = 1, cwd=None, timeout=600, plots=False):
    """Run ``python -m vpcontact`` (under mpirun -n nprocs if > 1); returns CompletedProcess.
    ``run`` commands get --no-plots unless ``plots`` (the figures take seconds to draw)."""
    args = list(map(str, args))
    if args and args[0] == "run" and not plots:
        args.append("--no-plots")
    cmd = [sys.executable, "-m", "vpcontact", *args]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    env = {**os.environ, **MPI_ENV, "PYTHONPATH": str(ROOT)}
    return subprocess.run(cmd, cwd=cwd or ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="session")
def tiny_run_dir(tmp_path_factory):
    """A results directory of the paper case at h = 1/4, two steps, run once by the command
    line (no figures).  Tests that change it work on a copy (shutil.copytree)."""
    out = tmp_path_factory.mktemp("tiny") / "run"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--set", "mesh.n=4", "--set",
                    "time.N=2", "--quiet"])
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="session")
def paper_cli_run(tmp_path_factory):
    """The paper case (h = k = 1/16) run once by the command line as a user runs it, figures
    and progress bar included: (its results directory, the CompletedProcess).  Every module
    that checks the paper case's outputs reads this run; tests that change the directory
    work on a copy (shutil.copytree)."""
    out = tmp_path_factory.mktemp("paper") / "run"
    proc = run_cli(["run", PAPER_CASE, "--out", out], plots=True)
    assert proc.returncode == 0, proc.stderr
    return out, proc


@pytest.fixture(scope="session")
def paper_run():
    """The paper case (h = k = 1/16) run once in-process."""
    return run_case(make_case())


def cli_in_process(args) -> int:
    """cli.main in this process; the 'vpcontact' logger (cli.main sets its own handler) and
    the loaded --law-module are restored / forgotten afterwards.  Returns the exit code."""
    import logging

    import vpcontact.cli.main as cli
    from vpcontact.io.lawfile import forget_law_module
    logger = logging.getLogger("vpcontact")
    state = logger.handlers[:], logger.propagate, logger.level
    try:
        return cli.main([str(a) for a in args])
    finally:
        forget_law_module()
        logger.handlers[:], logger.propagate = state[0], state[1]
        logger.setLevel(state[2])


def summary_steps(out) -> list:
    """The per-step records of a run's summary.json."""
    import json
    return json.loads((Path(out) / "summary.json").read_text())["steps"]


def contact_rows(out):
    """A run's contact.csv: (the nodes' states, the other columns as an array)."""
    import csv

    import numpy as np
    with open(Path(out) / "contact.csv") as f:
        rows = list(csv.DictReader(f))
    return [r.pop("state") for r in rows], np.array([[float(v) for v in r.values()]
                                                     for r in rows])


def validate_raw(raw: dict):
    from vpcontact.case import validate
    return validate(raw, "test-case")


@pytest.fixture(autouse=True)
def _vpcontact_logger():
    """Every test leaves the ``vpcontact`` logger as it found it: the command line's
    setup_logging, which tests that call main() in-process run, stops its propagation, and
    caplog would see nothing from the later tests in the same process."""
    import logging
    log = logging.getLogger("vpcontact")
    handlers, level, propagate = log.handlers[:], log.level, log.propagate
    yield
    log.handlers[:] = handlers
    log.setLevel(level)
    log.propagate = propagate
