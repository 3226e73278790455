"""`python3 -m app bench` / `make bench`: whole-process timings of the paper case with each
step solver, serial and under mpirun -n 2 (issue 6), written to bench.json and bench.md.

Each configuration runs twice as a separate process: a warm-up (one step, fills the JIT
cache) and the measured run (output only at T).  Wall time is the whole process (start-up,
imports, mesh, set-up, steps, output) measured from outside; set-up and per-step times come
from the run's summary.json.  Speed-ups are ratios measured in the same bench run.
"""
from __future__ import annotations

import csv
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from .output import atomic_write

ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
       "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def _run(case, out, n, N, method, nprocs, steps=None, log=print):
    cmd = [sys.executable, "-m", "app", "run", str(case), "--out", str(out), "--overwrite",
           "--no-plots",
           "--quiet", "--set", f"mesh.n={n}", "--set", f"time.N={steps or N}",
           "--set", f"output.every={steps or N}", "--set", f"solver.method={method}"]
    if nprocs > 1:
        cmd = ["mpirun", "-n", str(nprocs), *cmd]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env={**os.environ, **ENV}, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"bench run failed ({' '.join(cmd)}):\n{proc.stderr[-2000:]}")
    return wall, json.loads((Path(out) / "summary.json").read_text())


def bench(case, outdir: Path, levels, methods=("snes_vi", "fast"), nprocs=(1, 2),
          extra=(), log=print) -> list[dict]:
    rows = []
    for n, N in [(L, L) for L in levels] + list(extra):
        finals = {}
        for np_ in nprocs:
            for method in methods:
                out = outdir / "runs" / f"n{n}_N{N}_{method}_np{np_}"
                try:
                    _run(case, out, n, N, method, np_, steps=1)      # warm-up: JIT cache
                    wall, s = _run(case, out, n, N, method, np_)
                except RuntimeError as exc:                          # keep the other rows
                    reason = str(exc).strip().splitlines()[-1][:300]
                    rows.append({"n": n, "h": 1.0 / n, "N": N, "method": method,
                                 "nprocs": np_, "failed": reason})
                    log(f"  h = 1/{n}, N = {N}, {method:8s} np {np_}: FAILED: {reason}")
                    continue
                steps = [st["wall_s"] for st in s["steps"]]
                rows.append({"n": n, "h": 1.0 / n, "N": N, "dofs": s["mesh"]["dofs"],
                             "method": s["solver"]["used"], "nprocs": np_, "wall_s": wall,
                             "setup_s": s["setup_s"], "loop_s": s["loop_s"],
                             "step_min_s": min(steps), "step_median_s": statistics.median(steps),
                             "newton_total": s["newton_iterations_total"],
                             "factorisations": s["solver"].get("factorisations")})
                rows[-1]["final"] = [s["steps"][-1][k] for k in ("norm_u_V", "norm_sigma_Q",
                                                                   "norm_kappa_Y")]
                finals[(method, np_)] = rows[-1]
                u = np.array([[float(r["u_x"]), float(r["u_y"])]
                              for r in csv.DictReader(open(out / "contact.csv"))])
                rows[-1]["_u"] = u
                log(f"  h = 1/{n}, N = {N}, {method:8s} np {np_}: {wall:7.2f} s whole process, "
                    f"set-up {s['setup_s']:.2f} s, steps {s['loop_s']:.2f} s, "
                    f"{s['newton_iterations_total']} Newton iterations")
        for np_ in nprocs:
            a, b = finals.get(("snes_vi", np_)), finals.get(("fast", np_))
            if a and b:
                diff = float(np.abs(a["_u"] - b["_u"]).max() / np.abs(a["_u"]).max())
                for r in (a, b):
                    r["speedup_fast_vs_snes"] = a["wall_s"] / b["wall_s"]
                    r["solution_difference"] = diff
    for r in rows:
        r.pop("_u", None)
    # cost growth of the per-step time against dofs (least squares on log-log, serial)
    for method in methods:
        pts = [(r["dofs"], r["step_median_s"]) for r in rows if "failed" not in r
               and r["method"] == method and r["nprocs"] == 1 and r["step_median_s"] > 0]
        if len(pts) >= 2:
            x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
            slope = float(np.polyfit(x, y, 1)[0])
            for r in rows:
                if "failed" not in r and r["method"] == method and r["nprocs"] == 1:
                    r["step_cost_exponent"] = slope
    return rows


def write(outdir: Path, rows: list[dict]) -> None:
    atomic_write(outdir / "bench.json", json.dumps(rows, indent=2) + "\n")
    lines = ["# Benchmark: paper case (Wang & Cheng 2021, Section 4)", "",
             "Whole-process wall time (start-up, imports, mesh, set-up, steps, output at T), "
             "measured from outside after a warm-up run that fills the JIT cache. Per-step "
             "times and set-up from the run's summary.json. Speed-up = SNES VI wall / fast wall "
             "in the same bench run; difference = max |u_fast - u_snes| / max |u| on Gamma3.",
             "", "| h | N | dofs | solver | ranks | wall s | set-up s | steps s | step min s | "
             "step median s | Newton | factorisations | speed-up | difference | cost exponent |",
             "|" + "---|" * 15]
    for r in rows:
        if "failed" in r:
            lines.append(f"| 1/{r['n']} | {r['N']} | - | {r['method']} | {r['nprocs']} | "
                         f"failed: {r['failed']} |" + " |" * 10)
            continue
        lines.append("| " + " | ".join([
            f"1/{r['n']}", str(r["N"]), str(r["dofs"]), r["method"], str(r["nprocs"]),
            f"{r['wall_s']:.2f}", f"{r['setup_s']:.2f}", f"{r['loop_s']:.2f}",
            f"{r['step_min_s']:.4f}", f"{r['step_median_s']:.4f}", str(r["newton_total"]),
            str(r["factorisations"] if r["factorisations"] is not None else "per iteration"),
            f"{r['speedup_fast_vs_snes']:.1f}x" if "speedup_fast_vs_snes" in r else "-",
            f"{r['solution_difference']:.1e}" if "solution_difference" in r else "-",
            f"{r['step_cost_exponent']:.2f}" if "step_cost_exponent" in r else "-"]) + " |")
    atomic_write(outdir / "bench.md", "\n".join(lines) + "\n")
