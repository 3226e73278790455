"""A viscoplastic law that fails in the explicit update of step 3 (a user's law returning NaN,
tests/userlaws/failing_law.py) is a failed step: exit 1, summary.json "failed" at step 3 with
the law's message, the outputs of steps 0-2 intact.  Serially in this process, and under
mpirun -n 2 with the law failing on rank 1 only, where rank 0 must learn it rather than
go on into the collective solve (a hang or an abort before)."""
import json
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import PAPER_CASE, ROOT, cli_in_process, run_cli

LAW_MODULE = ROOT / "tests" / "userlaws" / "failing_law.py"
TINY = ["--set", "mesh.n=4", "--set", "time.N=4"]
NAN = "G or Gk returned non-finite values (NaN/Inf)"


def _law(rank: int) -> list[str]:
    return ["--law-module", str(LAW_MODULE), "--set",
            "material.viscoplastic={law: python, class: FailsOnRank, params: {lambda1: 100.0, "
            f"lambda2: 100.0, step: 3, rank: {rank}}}}}"]


def _xdmf_times(out):
    root = ET.parse(out / "solution.xdmf").getroot()
    grid = next(g for g in root.iter("Grid") if g.get("GridType") == "Collection")
    return [float(g.find("Time").get("Value")) for g in grid.findall("Grid")]


def _failed_at_step_3(out) -> str:
    """The checks of both runs; returns the failure's reason."""
    s = json.loads((out / "summary.json").read_text())
    assert s["status"] == "failed" and s["failure"]["step"] == 3 and s["last_good_step"] == 2
    assert s["failure"]["t"] == pytest.approx(0.75)
    assert [r["n"] for r in s["steps"]] == [1, 2]
    assert _xdmf_times(out) == pytest.approx([0.0, 0.25, 0.5])
    rows = [r.split(",") for r in (out / "history.csv").read_text().splitlines()[1:]]
    assert [r[0] for r in rows] == ["1", "2"]
    assert np.isfinite([[float(v) for v in r] for r in rows]).all()
    return s["failure"]["reason"]


def test_serial_law_failure_is_a_failed_step(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    out = tmp_path / "serial"
    code = cli_in_process(["run", PAPER_CASE, "--out", out, "--quiet", "--no-plots", *TINY,
                           *_law(0)])
    assert code == 1
    reason = _failed_at_step_3(out)
    assert NAN in reason and "on rank" not in reason


def test_law_failing_on_one_rank_fails_the_run_on_all(tmp_path):
    out = tmp_path / "np2"
    try:
        proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", *TINY, *_law(1)],
                       nprocs=2, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("mpirun -n 2 hung: rank 0 did not learn of rank 1's failed update")
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    errors = [x for x in proc.stderr.splitlines() if x.startswith("vpcontact: error:")]
    assert len(errors) == 1 and "the run failed at step 3" in errors[0], proc.stderr
    reason = _failed_at_step_3(out)
    assert NAN in reason and reason.endswith("(on rank 1 of 2)")
