"""`bench` on tiny levels: both solvers, the same solution, factorisation counts,
speed-up and cost columns, the memory-term cost rows (recursion == direct sum), and the 3D
rows (box3d: iterations, memory, agreement of the solvers and of mpirun, the plot)."""
import json

import pytest

from conftest import run_cli


@pytest.mark.slow
def test_bench_command(tmp_path):
    out = tmp_path / "bench"
    proc = run_cli(["bench", "--levels", "4", "8", "--extra", "--ranks", "1", "2",
                    "--memory-steps", "8", "--repeat", "2", "--scene-n", "8",
                    "--box3d-levels", "4", "6", "--out", out],
                   timeout=900)
    assert proc.returncode == 0, proc.stderr
    data = json.loads((out / "bench.json").read_text())
    rows = data["solvers"]
    assert len(rows) == 2 * 2 * 2 and not any("failed" in r for r in rows)
    for r in rows:
        assert r["solution_difference"] < 1e-9 and r["speedup_fast_vs_snes"] > 0
        # condensed: one factorisation, serial and under mpirun (MUMPS with Gamma3 as Schur
        # variables)
        expected = 1 if r["method"] == "condensed" else None
        assert r["factorisations"] == expected
        assert {"dofs", "wall_s", "setup_s", "step_median_s", "newton_total"} <= set(r)
        assert len(r["wall_runs_s"]) == 2 and r["wall_s"] == min(r["wall_runs_s"])
    mem = data["memory_term"]
    assert {r["sum"] for r in mem} == {"recursion", "direct"}
    assert all(r["recursion_vs_direct_rel_diff"] < 1e-10 for r in mem)
    builtin, scene = data["scene"]
    assert (builtin["kind"], scene["kind"]) == ("builtin", "scene")
    assert builtin["dofs"] == scene["dofs"] == 2 * 9 ** 2
    # the rotated scene solves the same problem: the same solution to the solver's tolerance
    assert scene["norm_u_V_rel_diff"] < 1e-9
    assert scene["ratio_scene_vs_builtin"] == scene["wall_s"] / builtin["wall_s"]
    md = (out / "bench.md").read_text()
    assert "| 1/8 |" in md and "Memory term" in md and "user's scene" in md
    box3d = {r["label"]: r for r in data["box3d"]}
    assert set(box3d) == {"2D reference 1/128, fast", "box3d n = 4", "box3d n = 6",
                          "box3d n = 4, SNES VI", "box3d n = 6, SNES VI",
                          "box3d n = 6, mpirun -n 2"}
    for r in box3d.values():
        assert "failed" not in r and 0 < r["peak_rss_gb"] < 3 and r["max_iterations"] <= 20
        assert len(r["iterations"]) == r["N"] and r["wall_s"] > r["loop_s"] > 0
    assert box3d["box3d n = 6"]["dofs"] == 3 * 7 ** 3
    assert box3d["box3d n = 6"]["method"] == "condensed"
    assert box3d["2D reference 1/128, fast"]["dofs"] == 2 * 129 ** 2
    for n in (4, 6):
        assert box3d[f"box3d n = {n}, SNES VI"]["agreement_vs_default"] < 1e-8
    mpi = box3d["box3d n = 6, mpirun -n 2"]
    assert mpi["agreement_vs_default"] < 1e-8 and mpi["speedup_vs_serial"] > 0
    assert set(data["box3d_scaling"]) == {"time", "memory"}
    assert (out / "bench3d.png").stat().st_size > 10_000 and "## 3D" in md
