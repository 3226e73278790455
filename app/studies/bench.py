"""`./vpcontact bench` / `make bench`: whole-process timings of the paper case with each
step solver, serial and under mpirun -n 2, written to bench.json and bench.md.

Each configuration runs as separate processes: a warm-up (one step, fills the JIT cache) and
the measured run (output only at T), repeated ``repeat`` times for every solver alike (the
extra levels once); the wall time reported is the fastest of the repeats, all of them are
kept.  Wall time is the whole process (start-up, imports, mesh, set-up, steps, output)
measured from outside; set-up and per-step times come from the fastest run's summary.json.
Speed-ups are ratios measured in the same bench run, and every row's times are also given
as ratios to a reference solve on its mesh timed in the same bench run (benchref.py).
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from vpcontact.case import CaseError, load_raw, validate
from vpcontact.io.files import atomic_write
from vpcontact.solvers.choice import condensed_eligible
from vpcontact.studies import bench3d, scenebench
from vpcontact.studies.bench3d import BOX3D
from vpcontact.studies.benchref import REFERENCE_TEXT, References, ratio_text, reference_cells
from vpcontact.studies.benchrun import ENV, busy_text, run_overrides

MAX_REPEAT = 100             # --repeat: more gives no better minimum, only a longer bench


def _overrides(n: int, N: int, method: str, steps: int | None = None) -> list[str]:
    """The --set options of one bench run (``steps``: a shorter warm-up run)."""
    return [f"mesh.n={n}", f"time.N={steps or N}", f"output.every={steps or N}",
            f"solver.method={method}"]


def _run(case, out, n, N, method, nprocs, steps=None, log=print):
    return run_overrides(case, out, _overrides(n, N, method, steps), nprocs)


def _positive_ints(option: str, values, allowed: str = "positive integers") -> None:
    for v in values:
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise CaseError(f"{option}: {v!r} is not allowed (allowed: {allowed})")


def check_arguments(case, levels, extra=(), nprocs=(1, 2), repeat: int = 1,
                    memory_steps=(), methods=("snes_vi", "condensed"), box3d_levels=()) -> None:
    """Refuse a bench that cannot run as asked, before anything runs.

    The case is read and validated at every level with every step solver.

    Args:
        case: the case file.
        levels: mesh levels n (h = k = 1/n).
        extra: further (n, N) configurations.
        nprocs: MPI rank counts.
        repeat: timed runs per configuration.
        memory_steps: step counts of the memory-term rows.
        methods: the step solvers timed.
        box3d_levels: the cells per edge of the 3D rows (cases/box3d.yaml, 8 steps).

    Raises:
        CaseError: naming the option (or the case file) and the allowed values.
    """
    _positive_ints("--levels", levels)
    if not levels and not extra:
        raise CaseError("--levels: nothing to run (allowed: one or more positive integers, "
                        "or --extra n:N)")
    for e in extra:
        if not isinstance(e, (tuple, list)) or len(e) != 2:
            raise CaseError(f"--extra: {e!r} is not allowed (allowed: n:N, e.g. 256:32)")
        _positive_ints("--extra", e, "n:N with positive integers, e.g. 256:32")
    _positive_ints("--ranks", nprocs)
    if not nprocs:
        raise CaseError("--ranks: none given (allowed: positive integers, e.g. 1 2)")
    if any(r > 1 for r in nprocs) and shutil.which("mpirun") is None:
        raise CaseError(f"--ranks {max(nprocs)}: mpirun is not on PATH (allowed here: 1)")
    cores = os.cpu_count() or 1
    if max(nprocs) > cores:
        raise CaseError(f"--ranks {max(nprocs)}: more ranks than the {cores} cores of this "
                        f"machine; mpirun would refuse them or oversubscribe, timing nothing "
                        f"useful (allowed here: 1 to {cores})")
    _positive_ints("--repeat", [repeat], "1 or more")
    if repeat > MAX_REPEAT:
        raise CaseError(f"--repeat: {repeat} is not allowed (allowed: 1 to {MAX_REPEAT})")
    _positive_ints("--memory-steps", memory_steps)
    for n, N in [(L, L) for L in levels] + [tuple(e) for e in extra]:
        for method in methods:
            c = validate(load_raw(case, _overrides(n, N, method)), str(case))
            ok, why = condensed_eligible(c)
            if method == "condensed" and not ok:
                raise CaseError(f"{case}: the bench times the fast step solver, which is not "
                                f"possible for this case: {why}")
    for N in memory_steps:
        for how in ("recursion", "direct"):
            validate(load_raw(MEMORY_CASE, [*_overrides(16, N, "fast"),
                                            f"contact.memory.sum={how}"]), str(MEMORY_CASE))
    _check_box3d(box3d_levels)


def _check_box3d(levels) -> None:
    """The 3D rows' box at every --box3d-levels n is a valid case (e.g. within the vertex
    limit), checked before the 2D rows run."""
    _positive_ints("--box3d-levels", levels)
    for n in levels:
        try:
            validate(load_raw(BOX3D, [f"mesh.n={n}", "time.N=32"]), str(BOX3D))
        except CaseError as exc:
            raise CaseError(f"--box3d-levels {n}: {exc}") from None


def bench(case, outdir: Path, levels, methods=("snes_vi", "condensed"), nprocs=(1, 2),
          extra=(), log=print, repeat: int = 1, references: References | None = None
          ) -> list[dict]:
    """Time the step solvers on the case, each configuration in its own process.

    Args:
        case: the case file.
        outdir: the bench directory (runs go to its ``runs``).
        levels: mesh levels n (h = k = 1/n).
        methods: the step solvers timed.
        nprocs: MPI rank counts.
        extra: further (n, N) configurations, run once.
        log: called with one line per configuration.
        repeat: timed runs per level configuration (the fastest counts).
        references: the bench run's reference solves (benchref.py; None: a new set).

    Returns:
        One row per configuration (level, solver, ranks), its times also as ratios to the
        reference of its mesh; a configuration that fails gets a row with its reason under
        "failed".

    Raises:
        CaseError: for arguments it cannot run as asked.
    """
    check_arguments(case, levels, extra, nprocs, repeat, methods=methods)
    references = references or References(log=log)
    rows = []
    for n, N in [(L, L) for L in levels] + list(extra):
        repeats = repeat if (n, N) not in extra else 1
        finals = {}
        for np_ in nprocs:
            for method in methods:
                out = outdir / "runs" / f"n{n}_N{N}_{method}_np{np_}"
                try:
                    _run(case, out, n, N, method, np_, steps=1)      # warm-up: JIT cache
                    runs = [_run(case, out, n, N, method, np_) for _ in range(repeats)]
                    wall, s = min(runs, key=lambda r: r[0])
                except RuntimeError as exc:                          # keep the other rows
                    reason = str(exc).strip().splitlines()[-1][:300]
                    rows.append({"n": n, "h": 1.0 / n, "N": N, "method": method,
                                 "nprocs": np_, "failed": reason})
                    log(f"  h = 1/{n}, N = {N}, {method:8s} np {np_}: FAILED: {reason}")
                    continue
                rows.append(_row(n, N, np_, s, wall, runs, out))
                references.attach(rows[-1], case, [f"mesh.n={n}"])
                finals[(method, np_)] = rows[-1]
                log(f"  h = 1/{n}, N = {N}, {method:8s} np {np_}: {wall:7.2f} s whole process, "
                    f"set-up {s['setup_s']:.2f} s, steps {s['loop_s']:.2f} s, "
                    f"{s['newton_iterations_total']} Newton iterations, "
                    f"{ratio_text(rows[-1], 'wall_ratio')} the reference{busy_text(rows[-1])}")
        for np_ in nprocs:
            a, b = finals.get(("snes_vi", np_)), finals.get(("condensed", np_))
            if a and b:
                diff = float(np.abs(a["_u"] - b["_u"]).max() / np.abs(a["_u"]).max())
                for r in (a, b):
                    r["speedup_fast_vs_snes"] = a["wall_s"] / b["wall_s"]
                    r["solution_difference"] = diff
        _ranks_ratios(finals)
    for r in rows:
        r.pop("_u", None)
    _cost_exponents(rows, methods)
    return rows


def _ranks_ratios(finals: dict) -> None:
    """Each parallel row's wall time over the serial row's of its solver and level
    (``wall_vs_serial``, measured in the same bench run), with the serial row's others.

    Args:
        finals: {(method, ranks): row} of one level.
    """
    for (method, ranks), row in finals.items():
        serial = finals.get((method, 1))
        if ranks > 1 and serial is not None:
            row["wall_vs_serial"] = row["wall_s"] / serial["wall_s"]
            row["serial_others_cores"] = serial.get("others_cores")


def _ranks_markdown(rows: list[dict]) -> list[str]:
    """bench.md's table of the parallel rows against the serial ones (none: empty)."""
    parallel = [r for r in rows if "wall_vs_serial" in r]
    if not parallel:
        return []
    lines = ["", "## Under mpirun against serial", "",
             "Whole-process wall time of each parallel row over the serial row of the same "
             "solver and level, both in this bench run (below 1: the ranks are faster). "
             "Others: the cores other processes kept busy on average during the fastest run "
             "(the machine's busy CPU time less the run's own, over its wall time); ranks "
             "suffer most from them, as a waiting rank holds the others at every exchange.",
             "", "| h | N | solver | ranks | wall s | serial wall s | wall / serial | "
             "others, cores (serial, ranks) |", "|---|---|---|---|---|---|---|---|"]
    for r in parallel:
        lines.append(f"| 1/{r['n']} | {r['N']} | {_solver_cell(r)} | {r['nprocs']} | "
                     f"{r['wall_s']:.2f} | {r['wall_s'] / r['wall_vs_serial']:.2f} | "
                     f"{r['wall_vs_serial']:.2f} | {_cores(r.get('serial_others_cores'))}, "
                     f"{_cores(r.get('others_cores'))} |")
    return lines


def _cores(value: float | None) -> str:
    """A cores cell: '0.85', or '-' where unknown."""
    return "-" if value is None else f"{value:.2f}"


def _row(n: int, N: int, nprocs: int, s: dict, wall: float, runs: list, out: Path) -> dict:
    """A bench row of one configuration from its run's summary ``s`` (and, under "_u", the
    contact nodes' displacements of contact.csv, for the solvers' difference)."""
    steps = [st["wall_s"] for st in s["steps"]]
    row = {"n": n, "h": 1.0 / n, "N": N, "dofs": s["mesh"]["dofs"],
           "method": s["solver"]["used"], "linear": s["solver"].get("linear"),
           "nprocs": nprocs, "wall_s": wall,
           "wall_runs_s": [r[0] for r in runs],
           "setup_s": s["setup_s"], "loop_s": s["loop_s"],
           "step_min_s": min(steps), "step_median_s": statistics.median(steps),
           "newton_total": s["newton_iterations_total"],
           "factorisations": s["solver"].get("factorisations"),
           "phases": s.get("phases"), "others_cores": s.get("_others_cores")}
    row["final"] = [s["steps"][-1][k] for k in ("norm_u_V", "norm_sigma_Q", "norm_kappa_Y")]
    with open(out / "contact.csv") as f:
        row["_u"] = np.array([[float(r["u_x"]), float(r["u_y"])] for r in csv.DictReader(f)])
    return row


def _solver_cell(row: dict) -> str:
    """The solver column of a bench row: the step solver, SNES VI's with its linear solver
    (e.g. 'snes_vi (schur)')."""
    linear = row.get("linear")
    return f"{row['method']} ({linear})" if row["method"] == "snes_vi" and linear \
        else row["method"]


def _cost_exponents(rows: list[dict], methods) -> None:
    """The growth of the per-step time against dofs (least squares on log-log, serial),
    as ``step_cost_exponent`` of each method's serial rows."""
    for method in methods:
        pts = [(r["dofs"], r["step_median_s"]) for r in rows if "failed" not in r
               and r["method"] == method and r["nprocs"] == 1 and r["step_median_s"] > 0]
        if len(pts) >= 2:
            x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
            slope = float(np.polyfit(x, y, 1)[0])
            for r in rows:
                if "failed" not in r and r["method"] == method and r["nprocs"] == 1:
                    r["step_cost_exponent"] = slope


def failures(rows: list[dict], memory: list[dict], scene: list[dict] = (),
             box3d: list[dict] = ()) -> list[str]:
    """The configurations of a bench that failed, and the runs whose reference solve failed.

    Args:
        rows: the solver rows (``bench``).
        memory: the memory-term rows (``memory_rows``).
        scene: the user-scene rows (app/studies/scenebench.py).
        box3d: the 3D rows (app/studies/bench3d.py).

    Returns:
        One short name per failed configuration or reference.
    """
    names = [(r, f"h = 1/{r['n']}, N = {r['N']}, {r['method']}, {r['nprocs']} rank(s)")
             for r in rows] + [(r, f"memory term {r['sum']}, N = {r['N']}") for r in memory] \
        + [(r, f"scene {r['kind']}, n = {r['n']}") for r in scene] \
        + [(r, r["label"]) for r in box3d]
    return [name for r, name in names if "failed" in r] + \
        [f"the reference of {name}" for r, name in names if "reference_failed" in r]


MEMORY_CASE = Path(__file__).resolve().parents[2] / "cases" / "memory.yaml"


def memory_rows(outdir: Path, steps=(64, 256, 1024), n: int = 16, log=print,
                references: References | None = None) -> list[dict]:
    """Per-step cost of the memory term: the exponential kernel's exact recursion (O(1) per
    step) against the direct sum over the stored history (O(n) at step n), on
    cases/memory.yaml with the fast solver; per-step wall times of the first and last tenth
    of the steps show the growth.

    Args:
        outdir: the bench directory (runs go to its ``runs``).
        steps: the step counts N.
        n: the mesh level.
        log: called with one line per run.
        references: the bench run's reference solves (benchref.py; None: a new set).

    Returns:
        One row per (sum, N), its times also as ratios to the reference of the mesh; a
        failed run's row has its reason under "failed".
    """
    references = references or References(log=log)
    rows = []
    for N in steps:
        for how in ("recursion", "direct"):
            out = outdir / "runs" / f"memory_{how}_N{N}"
            cmd = [sys.executable, "-m", "vpcontact", "run", str(MEMORY_CASE), "--out", str(out),
                   "--overwrite", "--no-plots", "--quiet", "--set", f"mesh.n={n}",
                   "--set", f"time.N={N}", "--set", f"output.every={N}",
                   "--set", f"contact.memory.sum={how}", "--set", "solver.method=fast"]
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, env={**os.environ, **ENV}, capture_output=True,
                                  text=True)
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                rows.append({"sum": how, "N": N, "failed": proc.stderr.strip()[-300:]})
                continue
            s = json.loads((out / "summary.json").read_text())
            st = [x["wall_s"] for x in s["steps"]]
            tenth = max(len(st) // 10, 1)
            mem = [x["gamma3_history_s"] for x in s["steps"]]
            rows.append({"sum": how, "N": N, "n": n, "dofs": s["mesh"]["dofs"], "wall_s": wall,
                         "steps_s": s["loop_s"], "first_tenth_step_s": statistics.mean(st[:tenth]),
                         "last_tenth_step_s": statistics.mean(st[-tenth:]),
                         "memory_first_tenth_s": statistics.mean(mem[:tenth]),
                         "memory_last_tenth_s": statistics.mean(mem[-tenth:]),
                         "memory_total_s": sum(mem),
                         "final_norm_u_V": s["steps"][-1]["norm_u_V"]})
            r = references.attach(rows[-1], MEMORY_CASE, [f"mesh.n={n}"])
            log(f"  memory term, {how:9s} N = {N:5d}: steps {r['steps_s']:.2f} s; memory update "
                f"per step {1e6 * r['memory_first_tenth_s']:.0f} us (first tenth) -> "
                f"{1e6 * r['memory_last_tenth_s']:.0f} us (last tenth)")
    for N in steps:   # the two sums compute the same xi_n
        pair = [r for r in rows if r.get("N") == N and "failed" not in r]
        if len(pair) == 2:
            diff = abs(pair[0]["final_norm_u_V"] - pair[1]["final_norm_u_V"]) \
                / abs(pair[0]["final_norm_u_V"])
            for r in pair:
                r["recursion_vs_direct_rel_diff"] = diff
    return rows


def write(outdir: Path, rows: list[dict], memory: list[dict] | None = None,
          scene: list[dict] | None = None, box3d: list[dict] | None = None) -> None:
    """Write bench.json and bench.md (atomically).

    Args:
        outdir: the bench directory.
        rows: the solver rows.
        memory: the memory-term rows, or None.
        scene: the user-scene rows (app/studies/scenebench.py), or None.
        box3d: the 3D rows (app/studies/bench3d.py), or None.
    """
    atomic_write(outdir / "bench.json", json.dumps(
        {"solvers": rows, "memory_term": memory or [], "scene": scene or [],
         "box3d": box3d or [], "box3d_scaling": bench3d.scaling(box3d or [])}, indent=2) + "\n")
    lines = ["# Benchmark: paper case (Wang & Cheng 2021, Section 4)", "",
             "Whole-process wall time (start-up, imports, mesh, set-up, steps, output at T), "
             "measured from outside after a warm-up run that fills the JIT cache: the fastest "
             "of the repeated runs (all of them under 'runs'; every solver is repeated alike). "
             "Per-step times and set-up from that run's summary.json. SNES VI's linear solver in "
             "brackets (schur: one factorisation of K and the Gamma3 Schur complement, "
             "direct: LU of every Newton system). Speed-up = SNES VI wall "
             "/ condensed wall in the same bench run; difference = max |u_fast - u_snes| / max |u| "
             "on Gamma3. " + REFERENCE_TEXT,
             "", "| h | N | dofs | solver | ranks | wall s | runs s | set-up s | steps s | "
             "step min s | step median s | Newton | factorisations | speed-up | difference | "
             "cost exponent | reference s | wall / ref | set-up / ref | steps / ref |",
             "|" + "---|" * 20]
    for r in rows:
        if "failed" in r:
            lines.append(f"| 1/{r['n']} | {r['N']} | - | {r['method']} | {r['nprocs']} | "
                         f"failed: {r['failed']} |" + " |" * 15)
            continue
        lines.append("| " + " | ".join([
            f"1/{r['n']}", str(r["N"]), str(r["dofs"]), _solver_cell(r), str(r["nprocs"]),
            f"{r['wall_s']:.2f}", " ".join(f"{w:.2f}" for w in r["wall_runs_s"]),
            f"{r['setup_s']:.2f}", f"{r['loop_s']:.2f}",
            f"{r['step_min_s']:.4f}", f"{r['step_median_s']:.4f}", str(r["newton_total"]),
            str(r["factorisations"] if r["factorisations"] is not None
                else "numeric, every Newton it."),
            f"{r['speedup_fast_vs_snes']:.1f}x" if "speedup_fast_vs_snes" in r else "-",
            f"{r['solution_difference']:.1e}" if "solution_difference" in r else "-",
            f"{r['step_cost_exponent']:.2f}" if "step_cost_exponent" in r else "-",
            *reference_cells(r, ("wall_ratio", "setup_ratio", "loop_ratio"))]) + " |")
    lines += _ranks_markdown(rows)
    if memory:
        lines += ["", "## Memory term: cost per step", "",
                  "cases/memory.yaml (h = 1/16, fast solver): the exponential kernel's exact "
                  "recursion costs O(1) per step, the direct sum over the stored history O(n) "
                  "at step n. Mean wall time of the memory update (xi_n) per step over the "
                  "first and the last tenth of the steps, and of the whole step; difference = "
                  "relative difference of the final ||u||_V; steps / ref: the steps' time over "
                  "the reference solve on the mesh.", "",
                  "| sum | N | steps s | memory update s (first tenth) | memory update s (last "
                  "tenth) | growth | memory total s | step s (last tenth) | difference | "
                  "reference s | steps / ref |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in memory:
            if "failed" in r:
                lines.append(f"| {r['sum']} | {r['N']} | failed: {r['failed']} | | | | | | | | |")
                continue
            lines.append(f"| {r['sum']} | {r['N']} | {r['steps_s']:.2f} | "
                         f"{r['memory_first_tenth_s']:.2e} | {r['memory_last_tenth_s']:.2e} | "
                         f"{r['memory_last_tenth_s'] / r['memory_first_tenth_s']:.1f}x | "
                         f"{r['memory_total_s']:.3f} | {r['last_tenth_step_s']:.4f} | "
                         f"{r.get('recursion_vs_direct_rel_diff', float('nan')):.1e} | "
                         f"{' | '.join(reference_cells(r, ('steps_ratio',)))} |")
    if scene:
        lines += scenebench.markdown(scene)
    if box3d:
        lines += bench3d.markdown(box3d)
    atomic_write(outdir / "bench.md", "\n".join(lines) + "\n")
