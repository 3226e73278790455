"""A run of the power-law Perzyna law (material.viscoplastic.law: power) by the command line:
it completes with the condensed solver, and summary.json records the law and its constants
(case_data is the case as read; active_terms names the law); the law gives no relaxation
rate, so the stability indicator is skipped."""
import json

from conftest import PAPER_CASE, run_cli


def test_power_law_run(tmp_path):
    out = tmp_path / "run"
    proc = run_cli(["run", PAPER_CASE, "--out", out, "--quiet", "--set", "mesh.n=4",
                    "--set", "time.N=8", "--set", "solver.method=condensed",
                    "--set", "material.viscoplastic.law=power",
                    "--set", "material.viscoplastic.n=3",
                    "--set", "material.viscoplastic.s_ref=10"])
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["solver"]["used"] == "condensed"
    vp = summary["case_data"]["material"]["viscoplastic"]
    assert (vp["law"], vp["n"], vp["s_ref"]) == ("power", 3, 10)
    assert any("power-law Perzyna (n = 3, s_ref = 10)" in t for t in summary["active_terms"])
    diag = summary["diagnostics"]
    assert diag["relaxation_rate"] is None and diag["stability_indicator"] is None


def test_power_law_key_refused():
    proc = run_cli(["check", PAPER_CASE, "--set", "material.viscoplastic.n=2"])
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "material.viscoplastic.n" in lines[0]
    assert "not used with law perzyna" in lines[0]
