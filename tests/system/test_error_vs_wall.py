"""convergence --adaptive (app/studies/errorwall.py): error_vs_wall.csv against the files it
is made of (passes.json and each pass's summary.json, convergence.csv), the first pass
against the uniform level it starts from (the same run by another path), the PNG, and the
refusals before any computation."""
import csv
import json
import struct

import pytest
import yaml

from conftest import PAPER_CASE, paper_raw, run_cli

CHEAP = ["--levels", "4", "8", "--reference", "16"]


def _csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("wall") / "out"
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--adaptive", "0.3", "--out", out,
                    "--no-cache"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return out


def test_adaptive_rows_are_the_passes(study):
    """One row per pass of passes.json: cells, dofs, steps, estimate, scale, relative as
    there; wall_s the running sum of its wall_s, steps_s of the passes' summary solve_s;
    only the last row met the tolerance."""
    js = json.loads((study / "adaptive" / "tol_0.3" / "passes.json").read_text())
    rows = [r for r in _csv(study / "error_vs_wall.csv") if r["kind"] == "adaptive"]
    assert len(rows) == len(js["passes"]) >= 2 and js["met"] and js["tol"] == 0.3
    wall = steps = 0.0
    for r, p in zip(rows, js["passes"]):
        wall += p["wall_s"]
        s = json.loads((study / "adaptive" / "tol_0.3" / f"pass_{p['index']}" /
                        "summary.json").read_text())
        steps += s["solve_s"]
        assert int(r["pass"]) == p["index"] and float(r["tol"]) == 0.3
        assert (int(r["cells"]), int(r["dofs"]), int(r["steps"])) == (p["cells"], p["dofs"],
                                                                       p["steps"])
        assert float(r["estimate"]) == p["est_max"] == s["error_estimate"]["estimate"]
        assert float(r["scale"]) == p["scale"] and float(r["relative"]) == p["relative"]
        assert float(r["wall_s"]) == pytest.approx(wall, rel=1e-12)
        assert float(r["steps_s"]) == pytest.approx(steps, rel=1e-12)
        assert r["status"] == p["status"] == "completed"
    assert [r["met"] for r in rows] == [""] * (len(rows) - 1) + ["True"]
    assert float(rows[-1]["relative"]) <= 0.3 < float(rows[-2]["relative"])


def test_uniform_rows_are_the_study_table(study):
    """One row per level with the study's estimate and Error (convergence.csv), relative
    to the level's scale, and the reference's row (no Error); the first pass is level 4's
    run again (h = k = 1/4): the same estimate and scale."""
    table = _csv(study / "convergence.csv")
    rows = _csv(study / "error_vs_wall.csv")
    uni = [r for r in rows if r["kind"] == "uniform"]
    assert [r["level"] for r in uni] == [t["level"] for t in table] == ["4", "8"]
    for r, t in zip(uni, table):
        assert (r["estimate"], r["error"], r["scale"]) == (t["estimate"], t["error"],
                                                          t["scale"])
        assert float(r["relative"]) == pytest.approx(float(t["estimate"]) / float(t["scale"]),
                                                     rel=1e-14)
        assert float(r["error_relative"]) == pytest.approx(
            float(t["error"]) / float(t["scale"]), rel=1e-14)
        assert float(r["steps_s"]) == float(t["solve_s"])
        assert float(r["wall_s"]) == pytest.approx(float(t["solve_s"]) + float(t["setup_s"]),
                                                   rel=1e-14)
    ref = [r for r in rows if r["kind"] == "reference"]
    assert len(ref) == 1 and ref[0]["level"] == "16" and ref[0]["error"] == ""
    assert int(ref[0]["steps"]) == 16 and float(ref[0]["relative"]) < float(uni[-1]["relative"])
    first = next(r for r in rows if r["kind"] == "adaptive")
    assert (first["dofs"], first["steps"]) == (uni[0]["dofs"], uni[0]["steps"])
    assert float(first["estimate"]) == pytest.approx(float(uni[0]["estimate"]), rel=1e-10)
    assert float(first["scale"]) == pytest.approx(float(uni[0]["scale"]), rel=1e-10)


def test_the_true_error_of_the_last_pass(study, tmp_path):
    """--adaptive 2: met by pass 1, the uniform level 4 again: its Error on the overlay
    (app/studies/overlay.py) is the study's (exact prolongation) to the 10 digits printed;
    against the reference 1/64, --adaptive 0.3's last pass (locally refined, its graded
    steps on the reference's grid) has an Error, relative to its scale; against the
    reference 1/16 (the fixture) the same pass's steps of 1/64 are finer: none."""
    out = tmp_path / "err"
    proc = run_cli(["convergence", PAPER_CASE, "--levels", "4", "8", "--reference", "64",
                    "--adaptive", "2", "0.3", "--out", out, "--no-cache", "--quiet"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = _csv(out / "error_vs_wall.csv")
    level4 = next(r for r in rows if r["kind"] == "uniform" and r["level"] == "4")
    one = [r for r in rows if r["kind"] == "adaptive" and r["tol"] == "2.0"]
    assert len(one) == 1 and one[0]["dofs"] == level4["dofs"]
    assert float(one[0]["error"]) == pytest.approx(float(level4["error"]), rel=1e-9)
    last = [r for r in rows if r["kind"] == "adaptive" and r["tol"] == "0.3"][-1]
    assert int(last["cells"]) > 32 and float(last["error"]) > 0
    assert float(last["error_relative"]) == pytest.approx(
        float(last["error"]) / float(last["scale"]), rel=1e-14)
    fixture_last = [r for r in _csv(study / "error_vs_wall.csv") if r["kind"] == "adaptive"][-1]
    assert fixture_last["steps"] == last["steps"] and fixture_last["error"] == ""


def test_the_png(study):
    """error_vs_wall.png: a PNG (signature, IHDR) of a nonzero size."""
    data = (study / "error_vs_wall.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    assert width > 100 and height > 100


def _refused(tmp_path, *args, case=PAPER_CASE):
    out = tmp_path / "o"
    proc = run_cli(["convergence", case, *args, "--out", out, "--no-cache"])
    text = proc.stdout + proc.stderr
    assert proc.returncode == 2, text
    assert "reference run" not in text and not (out / "convergence.csv").exists()
    return text


@pytest.mark.parametrize("value", ["0", "-0.1", "nan"])
def test_a_tolerance_not_above_zero_is_refused(tmp_path, value):
    text = _refused(tmp_path, *CHEAP, "--adaptive", value)
    assert "--adaptive" in text and "> 0" in text


def test_cases_and_options_the_passes_cannot_run_are_refused(tmp_path):
    """A time grid run --tol refuses (time.times with time.adaptive), a repeated tolerance,
    --vary h, and a mesh.file study not starting at its mesh as read: exit 2, one line
    naming --adaptive."""
    raw = paper_raw()
    raw["time"] = {"times": [0.0, 0.5, 1.0], "adaptive": {}}
    case = tmp_path / "times.yaml"
    case.write_text(yaml.safe_dump(json.loads(json.dumps(raw))))
    text = _refused(tmp_path, *CHEAP, "--adaptive", "0.3", case=case)
    assert "--adaptive: " in text and "time.times" in text
    assert "repeated" in _refused(tmp_path, *CHEAP, "--adaptive", "0.3", "0.3")
    assert "--vary both" in _refused(tmp_path, *CHEAP, "--vary", "h", "--adaptive", "0.3")
    text = _refused(tmp_path, "--levels", "1", "--reference", "2", "--adaptive", "0.3",
                    case=PAPER_CASE.parent / "hertz_cylinder.yaml")
    assert "--levels 0" in text


def test_mpirun_equals_serial(study, tmp_path):
    """Under mpirun -n 2 the same rows: levels, passes, cells, steps, estimates to 1e-12."""
    out = tmp_path / "np2"
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--adaptive", "0.3", "--out", out,
                    "--no-cache", "--quiet"], nprocs=2)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    serial, parallel = _csv(study / "error_vs_wall.csv"), _csv(out / "error_vs_wall.csv")
    assert [(r["kind"], r["level"], r["pass"], r["cells"], r["steps"]) for r in parallel] == \
        [(r["kind"], r["level"], r["pass"], r["cells"], r["steps"]) for r in serial]
    for a, b in zip(serial, parallel):
        assert float(b["estimate"]) == pytest.approx(float(a["estimate"]), rel=1e-12)
        assert (a["error"] == "") == (b["error"] == "")
        if a["error"]:
            assert float(b["error"]) == pytest.approx(float(a["error"]), rel=1e-12)


def test_a_mesh_file_starts_from_its_mesh_as_read(tmp_path):
    """hertz_cylinder (mesh.size 8, one step): the first pass is level 0 (the mesh as read)
    again, the passes refine the mesh only (one step each) until 0.15 is met."""
    out = tmp_path / "hertz"
    proc = run_cli(["convergence", PAPER_CASE.parent / "hertz_cylinder.yaml", "--set",
                    "mesh.size=8", "--levels", "0", "1", "--reference", "2", "--adaptive",
                    "0.15", "--out", out, "--no-cache", "--quiet"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = _csv(out / "error_vs_wall.csv")
    level0 = next(r for r in rows if r["kind"] == "uniform" and r["level"] == "0")
    passes = [r for r in rows if r["kind"] == "adaptive"]
    assert passes[0]["dofs"] == level0["dofs"] and len(passes) >= 2
    assert float(passes[0]["estimate"]) == pytest.approx(float(level0["estimate"]), rel=1e-10)
    assert {r["steps"] for r in passes} == {"1"} and passes[-1]["met"] == "True"
    assert [int(r["cells"]) for r in passes] == sorted({int(r["cells"]) for r in passes})


def test_a_tolerance_not_reached_is_said(tmp_path):
    """--max-passes 2 too few for 0.3: a warning, the two passes in the csv, the last not
    met; the study's files are complete (exit 0)."""
    out = tmp_path / "few"
    proc = run_cli(["convergence", PAPER_CASE, *CHEAP, "--adaptive", "0.3", "--max-passes",
                    "2", "--out", out, "--no-cache"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "run --tol 0.3: not reached after 2 passes" in proc.stdout + proc.stderr
    rows = [r for r in _csv(out / "error_vs_wall.csv") if r["kind"] == "adaptive"]
    assert [r["met"] for r in rows] == ["", "False"]
