"""`bench` on tiny levels: both solvers, the same solution, factorisation counts,
speed-up and cost columns, the memory-term cost rows (recursion == direct sum), and the 3D
rows (box3d: iterations, memory, agreement of the solvers and of mpirun, the plot).  The
repeats (the fastest of --repeat runs counts, all are kept; the --extra levels run once)
are checked with a stand-in runner: the command's own run takes each configuration once.
Every row's times are also ratios to a reference solve on its mesh (benchref.py): the
columns exist, are finite and positive, and times the reference give the seconds."""
import csv
import json
import math

import pytest

from conftest import PAPER_CASE, run_cli


class _Runner:
    """A stand-in for a bench run: ``run(case, out, overrides, nprocs)`` returns the next
    wall time of ``walls`` (warm-ups: 99 s) with a summary whose set-up time is 10 x the
    wall, and writes the contact.csv that ``bench`` reads; every call is recorded."""

    def __init__(self, walls):
        self.walls, self.calls = list(walls), []

    def __call__(self, case, out, overrides, nprocs=1):
        warm = "time.N=1" in overrides
        wall = 99.0 if warm else self.walls[len([c for c in self.calls if not c[2]])
                                            % len(self.walls)]
        self.calls.append((str(out), tuple(overrides), warm))
        out.mkdir(parents=True, exist_ok=True)
        with open(out / "contact.csv", "w", newline="") as f:
            csv.writer(f).writerows([["u_x", "u_y"], [1.0, 2.0]])
        step = {"wall_s": 0.1, "norm_u_V": wall, "norm_sigma_Q": 1.0, "norm_kappa_Y": 1.0}
        return wall, {"mesh": {"dofs": 50}, "solver": {"used": "x", "factorisations": 1},
                      "setup_s": 10 * wall, "loop_s": 0.1, "steps": [step],
                      "newton_iterations_total": 3}


def _stand_in_references(seconds=0.5):
    """References whose measure returns ``seconds`` (None: fails), every call recorded."""
    from vpcontact.studies.benchref import References
    calls = []

    def measure(case, overrides):
        calls.append((str(case), tuple(overrides)))
        if seconds is None:
            raise RuntimeError("bench reference failed (stand-in):\nno solver")
        return {"reference_s": seconds, "reference_runs_s": [seconds], "reference_dofs": 50,
                "reference_solver": "lu"}
    refs = References(measure, log=lambda _: None)
    refs.calls = calls
    return refs


def _check_ratios(row, keys=("wall", "setup", "loop")):
    """The row's ratio columns: finite, positive, and ratio * reference == seconds."""
    ref = row["reference_s"]
    assert math.isfinite(ref) and ref > 0
    for key in keys:
        ratio = row[f"{key}_ratio"]
        assert math.isfinite(ratio) and ratio > 0
        assert ratio * ref == pytest.approx(row[f"{key}_s"], rel=1e-12)


def test_bench_keeps_every_repeat_and_reports_the_fastest(monkeypatch, tmp_path):
    from vpcontact.studies import bench as bm
    runner = _Runner([3.0, 1.0, 2.0])
    monkeypatch.setattr(bm, "run_overrides", runner)
    refs = _stand_in_references()
    rows = bm.bench(PAPER_CASE, tmp_path, [4], nprocs=(1,), extra=[(8, 8)], repeat=3,
                    log=lambda _: None, references=refs)
    level = [r for r in rows if r["n"] == 4]
    extra = [r for r in rows if r["n"] == 8]
    assert len(level) == len(extra) == 2            # the two solvers
    for r in level:                                 # a warm-up, then three timed runs
        assert r["wall_runs_s"] == [3.0, 1.0, 2.0] and r["wall_s"] == 1.0
        assert r["setup_s"] == 10.0                 # the fastest run's summary
    for r in extra:
        assert len(r["wall_runs_s"]) == 1
    warm = [c for c in runner.calls if c[2]]
    assert len(warm) == 4 and len(runner.calls) == 4 + 2 * 3 + 2 * 1
    # one reference per mesh, shared by the two solvers' rows
    assert [c[1] for c in refs.calls] == [("mesh.n=4",), ("mesh.n=8",)]
    for r in rows:
        _check_ratios(r, ("wall", "setup", "loop", "step_median"))
        assert r["wall_ratio"] == r["wall_s"] / 0.5


def test_bench_reports_a_failed_reference(monkeypatch, tmp_path):
    """A reference that fails leaves the rows' seconds, no ratios, and is a failure of the
    bench (named in its message and marked in bench.md)."""
    from vpcontact.studies import bench as bm
    monkeypatch.setattr(bm, "run_overrides", _Runner([1.0]))
    rows = bm.bench(PAPER_CASE, tmp_path, [4], nprocs=(1,), extra=[], log=lambda _: None,
                    references=_stand_in_references(None))
    assert all("wall_ratio" not in r and r["wall_s"] == 1.0 for r in rows)
    assert bm.failures(rows, []) == ["the reference of h = 1/4, N = 4, x, 1 rank(s)"] * 2
    bm.write(tmp_path, rows)
    assert "| failed | - | - | - |" in (tmp_path / "bench.md").read_text()


def test_scene_rows_keep_every_repeat_and_report_the_fastest(tmp_path):
    from vpcontact.studies.scenebench import scene_rows
    runner = _Runner([2.0, 0.5])
    refs = _stand_in_references()
    builtin, scene = scene_rows(PAPER_CASE, tmp_path, 4, 8, runner, repeat=2,
                                log=lambda _: None, references=refs)
    for r in (builtin, scene):
        assert r["wall_runs_s"] == [2.0, 0.5] and r["wall_s"] == 0.5
    assert scene["ratio_scene_vs_builtin"] == 1.0 and scene["norm_u_V_rel_diff"] == 0.0
    assert [c[2] for c in runner.calls] == [True, False, False] * 2
    # the built-in mesh and the scene's file, each with its own reference
    assert [c[1] for c in refs.calls] == [("mesh.n=4",), ()]
    assert refs.calls[1][0].endswith("scene.yaml")
    for r in (builtin, scene):
        _check_ratios(r)


def test_reference_solve_on_the_rows_mesh():
    """The reference process times K's assembly, factorisation and solve on the mesh the
    row's overrides make: its dofs are those of that mesh (2 (n + 1)^2 in 2D, 3 (n + 1)^3
    for the box), its solver SNES VI's LU there."""
    from vpcontact.studies.bench3d import BOX3D
    from vpcontact.studies.benchref import measure
    for case, n, dofs in ((PAPER_CASE, 6, 2 * 7 ** 2), (BOX3D, 3, 3 * 4 ** 3)):
        ref = measure(case, [f"mesh.n={n}"])
        assert ref["reference_dofs"] == dofs and ref["reference_solver"] == "lu"
        assert len(ref["reference_runs_s"]) == 3
        assert ref["reference_s"] == min(ref["reference_runs_s"]) > 0


def test_bench_command_ratios(tmp_path):
    """The command at one tiny level, serial: the rows carry the reference of their mesh
    and their times as ratios to it, in bench.json and bench.md."""
    from vpcontact.studies.benchref import ratio_text
    proc = run_cli(["bench", "--levels", "4", "--ranks", "1", "--extra", "--memory-steps",
                    "--scene-n", "0", "--box3d-levels", "--repeat", "1", "--out", tmp_path],
                   timeout=600)
    assert proc.returncode == 0, proc.stderr
    rows = json.loads((tmp_path / "bench.json").read_text())["solvers"]
    assert len(rows) == 2 and rows[0]["reference_s"] == rows[1]["reference_s"]
    for r in rows:
        assert r["reference_dofs"] == r["dofs"] == 2 * 5 ** 2
        _check_ratios(r, ("wall", "setup", "loop", "step_median"))
    md = (tmp_path / "bench.md").read_text()
    assert "| reference s | wall / ref | set-up / ref | steps / ref |" in md
    for r in rows:
        assert f"| {r['reference_s']:.3g} | {ratio_text(r, 'wall_ratio')} |" in md


@pytest.mark.slow
def test_bench_command(tmp_path):
    """Two bench commands side by side (the 2-core machine's second core; every row of the
    one command they replace): the solver rows at two levels, serial and mpirun -n 2, with
    the memory-term rows; a serial level with the user scene and the 3D rows."""
    from concurrent.futures import ThreadPoolExecutor
    common = ["bench", "--extra", "--repeat", "1"]
    solvers, rest = tmp_path / "solvers", tmp_path / "rest"
    commands = [[*common, "--levels", "4", "8", "--ranks", "1", "2", "--memory-steps", "8",
                 "--scene-n", "0", "--box3d-levels", "--out", solvers],
                [*common, "--levels", "4", "--ranks", "1", "--memory-steps", "--scene-n", "8",
                 "--box3d-levels", "4", "6", "--out", rest]]
    with ThreadPoolExecutor(2) as pool:
        procs = list(pool.map(lambda args: run_cli(args, timeout=900), commands))
    for proc in procs:
        assert proc.returncode == 0, proc.stderr
    data = json.loads((solvers / "bench.json").read_text())
    other = json.loads((rest / "bench.json").read_text())
    assert not data["scene"] and not data["box3d"] and not other["memory_term"]
    assert len(other["solvers"]) == 2 and {r["nprocs"] for r in other["solvers"]} == {1}
    rows = data["solvers"]
    assert len(rows) == 2 * 2 * 2 and not any("failed" in r for r in rows)
    for r in rows + other["solvers"]:
        _check_ratios(r, ("wall", "setup", "loop", "step_median"))
        assert r["reference_dofs"] == r["dofs"]
        assert r["solution_difference"] < 1e-9 and r["speedup_fast_vs_snes"] > 0
        # one factorisation, serial and under mpirun: condensed (MUMPS with Gamma3 as Schur
        # variables under mpirun), SNES VI (the Gamma3 Schur complement PC, K on rank 0)
        assert r["factorisations"] == 1
        assert r["linear"] == (None if r["method"] == "condensed" else "schur")
        serial = [q for q in rows if (q["n"], q["method"], q["nprocs"]) ==
                  (r["n"], r["method"], 1)]
        assert r.get("wall_vs_serial") == (None if r["nprocs"] == 1 else
                                           r["wall_s"] / serial[0]["wall_s"])
        assert r["others_cores"] >= 0.0
        assert {"dofs", "wall_s", "setup_s", "step_median_s", "newton_total"} <= set(r)
        assert len(r["wall_runs_s"]) == 1 and r["wall_s"] == min(r["wall_runs_s"])
    mem = data["memory_term"]
    assert {r["sum"] for r in mem} == {"recursion", "direct"}
    assert all(r["recursion_vs_direct_rel_diff"] < 1e-10 for r in mem)
    for r in mem:
        _check_ratios(r, ("wall", "steps"))
    builtin, scene = other["scene"]
    assert (builtin["kind"], scene["kind"]) == ("builtin", "scene")
    assert builtin["dofs"] == scene["dofs"] == 2 * 9 ** 2
    for r in (builtin, scene):
        _check_ratios(r)
        assert r["reference_dofs"] == r["dofs"]
    # the rotated scene solves the same problem: the same solution to the solver's tolerance
    assert scene["norm_u_V_rel_diff"] < 1e-9
    assert scene["ratio_scene_vs_builtin"] == scene["wall_s"] / builtin["wall_s"]
    md = (solvers / "bench.md").read_text()
    assert "| 1/8 |" in md and "Memory term" in md
    for r in rows:
        if r["nprocs"] == 2:
            assert f"| {r['wall_s']:.2f} | {r['wall_s'] / r['wall_vs_serial']:.2f} | " \
                   f"{r['wall_vs_serial']:.2f} | {r['serial_others_cores']:.2f}, " \
                   f"{r['others_cores']:.2f} |" in md
    md = (rest / "bench.md").read_text()
    assert "user's scene" in md
    box3d = {r["label"]: r for r in other["box3d"]}
    assert set(box3d) == {"2D reference 1/128, fast", "box3d n = 4", "box3d n = 6",
                          "box3d n = 4, SNES VI", "box3d n = 6, SNES VI",
                          "box3d n = 6, mpirun -n 2"}
    for r in box3d.values():
        assert "failed" not in r and 0 < r["peak_rss_gb"] < 3 and r["max_iterations"] <= 20
        assert len(r["iterations"]) == r["N"] and r["wall_s"] > r["loop_s"] > 0
        _check_ratios(r)
        assert r["reference_dofs"] == r["dofs"]
    assert box3d["box3d n = 6"]["dofs"] == 3 * 7 ** 3
    assert box3d["box3d n = 6"]["method"] == "condensed"
    assert box3d["2D reference 1/128, fast"]["dofs"] == 2 * 129 ** 2
    for n in (4, 6):
        assert box3d[f"box3d n = {n}, SNES VI"]["agreement_vs_default"] < 1e-8
    mpi = box3d["box3d n = 6, mpirun -n 2"]
    assert mpi["agreement_vs_default"] < 1e-8 and mpi["speedup_vs_serial"] > 0
    assert set(other["box3d_scaling"]) == {"time", "memory"}
    assert (rest / "bench3d.png").stat().st_size > 10_000 and "## 3D" in md
