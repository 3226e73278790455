"""The 3D rows of `bench`: cases/box3d.yaml from n = 8 to 64, beside the 2D reference run.

Every run is a whole process timed from outside (the JIT cache warmed by a one-step run of
the first configuration of each kind), its peak memory the largest resident set of
the process (of any rank under mpirun) from the kernel's accounting (``os.wait4``).  Rows:
- the default solver (``auto``) at each level n with ``steps`` time steps: wall, set-up,
  steps, Newton/Gamma3 iterations per step, the Gamma3 linear algebra, peak memory;
- the target run: n = 32 with 32 steps, and SNES VI with the Gamma3 Schur complement
  (solver.linear: schur) on it, with its wall time as a ratio to the target's;
- SNES VI at the small levels, with the agreement of the two solvers (max |u| difference on
  Gamma3 over max |u|);
- mpirun -n 2 at one level, with its agreement with the serial run and the speed ratio;
- the 2D reference (the paper case at h = k = 1/128 with the fast solver).
The scaling of time and memory with dofs goes to a log-log plot (bench3d.png) and a fitted
exponent per quantity.  Every row's times are also ratios to a reference solve on its mesh
timed in the same bench run (benchref.py).
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from vpcontact.studies.benchref import REFERENCE_TEXT, References, reference_cells
from vpcontact.studies.benchrun import busy_text, measured_run

CASES = Path(__file__).resolve().parents[2] / "cases"
BOX3D = CASES / "box3d.yaml"
REFERENCE_2D = CASES / "wang_cheng_2021.yaml"
LEVELS = (8, 16, 24, 32, 64)


def _u_gamma3(out: Path) -> np.ndarray:
    """The Gamma3 displacements of a run (contact.csv)."""
    rows = list(csv.DictReader(open(out / "contact.csv")))
    keys = [k for k in ("u_x", "u_y", "u_z") if k in rows[0]]
    return np.array([[float(r[k]) for k in keys] for r in rows])


def _row(label: str, n: int, N: int, nprocs: int, run: tuple) -> dict:
    """A bench row from a run's (wall, peak, summary)."""
    wall, peak, s = run
    its = [st["newton_iterations"] for st in s["steps"]]
    g3 = s["solver"].get("gamma3") or {}
    return {"label": label, "case": s["case"], "n": n, "N": N, "dofs": s["mesh"]["dofs"],
            "nprocs": nprocs, "method": s["solver"]["used"], "wall_s": wall,
            "peak_rss_gb": peak / 1e9, "setup_s": s["setup_s"], "loop_s": s["loop_s"],
            "iterations": its, "max_iterations": max(its), "newton_total": sum(its),
            "gamma3_dofs": g3.get("dofs"), "gamma3_factorisations": g3.get("factorisations"),
            "gamma3_cg_iterations": g3.get("cg_iterations"),
            "final_norm_u_V": s["steps"][-1]["norm_u_V"], "phases": s.get("phases"),
            "others_cores": s.get("_others_cores")}


_warmed: set = set()


def _attempt(rows, label, case, out, n, N, nprocs, overrides, log,
             references: References) -> dict | None:
    """Run one configuration and append its row (with the reference of its mesh), or a row
    with the reason under "failed".  The first run of each case, solver options and rank
    count is preceded by a one-step warm-up on the same mesh (it fills the JIT cache; the
    forms do not depend on n)."""
    over = [f"mesh.n={n}", *overrides]
    try:
        key = (str(case), tuple(overrides), nprocs)
        if key not in _warmed:
            measured_run(case, out, over + ["time.N=1", "output.every=1"], nprocs)
            _warmed.add(key)
        row = _row(label, n, N, nprocs,
                   measured_run(case, out, over + [f"time.N={N}", f"output.every={N}"], nprocs))
    except RuntimeError as exc:
        rows.append({"label": label, "n": n, "N": N, "nprocs": nprocs,
                     "failed": str(exc).strip().splitlines()[-1][:300]})
        log(f"  {label}: FAILED: {rows[-1]['failed']}")
        return None
    row["out"] = str(out)
    rows.append(references.attach(row, case, [f"mesh.n={n}"]))
    log(f"  {label}: {row['wall_s']:.2f} s whole process, set-up {row['setup_s']:.2f} s, "
        f"steps {row['loop_s']:.2f} s, {row['method']}, iterations per step "
        f"{' '.join(map(str, row['iterations']))}, peak {row['peak_rss_gb']:.2f} GB, "
        f"{reference_cells(row, ('wall_ratio',))[1]} the reference{busy_text(row)}")
    return row


def _agreement(a: dict | None, b: dict | None) -> float | None:
    """max |u_a - u_b| / max |u_a| on Gamma3 of two runs' contact.csv."""
    if not a or not b:
        return None
    ua, ub = _u_gamma3(Path(a["out"])), _u_gamma3(Path(b["out"]))
    return float(np.abs(ua - ub).max() / np.abs(ua).max())


def box3d_rows(outdir: Path, levels=LEVELS, steps: int = 8, snes_levels=(8, 16),
               target=(32, 32), mpi_level: int | None = 32, log=print,
               references: References | None = None) -> list[dict]:
    """The 3D rows (see the module docstring).

    Args:
        outdir: the bench directory (runs go to its ``runs``).
        levels: the box3d levels n (dofs 3 (n + 1)^3) of the default solver.
        steps: time steps of the level runs.
        snes_levels: the levels also run with SNES VI (agreement of the solvers).
        target: (n, N) of the target run, or None.
        mpi_level: the level also run under mpirun -n 2, or None.
        log: called with one line per run.
        references: the bench run's reference solves (benchref.py; None: a new set).

    Returns:
        The rows; each failed configuration has a row with its reason under "failed".
    """
    runs, rows = outdir / "runs", []
    ref = references or References(log=log)
    _attempt(rows, "2D reference 1/128, fast", REFERENCE_2D, runs / "ref2d_n128", 128, 128, 1,
             ["solver.method=fast"], log, ref)
    level = {}
    for n in levels:
        level[n] = _attempt(rows, f"box3d n = {n}", BOX3D, runs / f"box3d_n{n}_N{steps}", n,
                            steps, 1, [], log, ref)
    for n in snes_levels:
        r = _attempt(rows, f"box3d n = {n}, SNES VI", BOX3D, runs / f"box3d_n{n}_snes", n,
                     steps, 1, ["solver.method=snes_vi"], log, ref)
        if r and level.get(n):
            r["agreement_vs_default"] = _agreement(r, level[n])
    if target:
        _target_rows(rows, runs, target, log, ref)
    if mpi_level:
        r = _attempt(rows, f"box3d n = {mpi_level}, mpirun -n 2", BOX3D,
                     runs / f"box3d_n{mpi_level}_np2", mpi_level, steps, 2, [], log, ref)
        serial = level.get(mpi_level)
        if r and serial:
            r["agreement_vs_default"] = _agreement(r, serial)
            r["speedup_vs_serial"] = serial["wall_s"] / r["wall_s"]
    return rows


def _target_rows(rows: list[dict], runs: Path, target: tuple, log,
                 references: References) -> None:
    """The target run (default solver) and SNES VI with the Gamma3 Schur complement on the
    same (n, N), its wall time as a ratio to the target's (``ratio_vs_default``: SNES VI /
    condensed where the default is the condensed solver) and its agreement with it."""
    n, N = target
    default = _attempt(rows, f"box3d n = {n}, {N} steps (target)", BOX3D,
                       runs / f"box3d_n{n}_N{N}", n, N, 1, [], log, references)
    snes = _attempt(rows, f"box3d n = {n}, {N} steps, SNES VI (schur)", BOX3D,
                    runs / f"box3d_n{n}_N{N}_snes", n, N, 1,
                    ["solver.method=snes_vi", "solver.linear=schur"], log, references)
    if default and snes:
        snes["agreement_vs_default"] = _agreement(snes, default)
        snes["ratio_vs_default"] = snes["wall_s"] / default["wall_s"]
        log(f"  SNES VI (schur) / {default['method']}: {snes['ratio_vs_default']:.2f}x")


def scaling(rows: list[dict]) -> dict:
    """The fitted exponents of wall time and peak memory against dofs (least squares on
    log-log) over the serial default-solver level runs.

    Args:
        rows: box3d_rows' rows.

    Returns:
        {"time": exponent, "memory": exponent}, or {} with fewer than two levels.
    """
    pts = [r for r in rows if r.get("label", "").startswith("box3d")
           and "," not in r["label"] and "failed" not in r]
    if len(pts) < 2:
        return {}
    x = np.log([r["dofs"] for r in pts])
    return {"time": float(np.polyfit(x, np.log([r["wall_s"] for r in pts]), 1)[0]),
            "memory": float(np.polyfit(x, np.log([r["peak_rss_gb"] for r in pts]), 1)[0])}


def plot(rows: list[dict], path: Path) -> None:
    """Log-log plot of wall time and peak memory against dofs (the level runs; the 2D
    reference and the other runs as single points).

    Args:
        rows: box3d_rows' rows.
        path: the PNG file.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    levels = [r for r in rows if "failed" not in r and r["label"].startswith("box3d")
              and "," not in r["label"]]
    others = [r for r in rows if "failed" not in r and r not in levels]
    for ax, key, unit in ((axes[0], "wall_s", "whole-process wall time [s]"),
                          (axes[1], "peak_rss_gb", "peak memory [GB]")):
        ax.loglog([r["dofs"] for r in levels], [r[key] for r in levels], "o-",
                  label=f"box3d, {levels[0]['N'] if levels else ''} steps, default solver")
        for r in others:
            ax.loglog([r["dofs"]], [r[key]], "s", label=r["label"])
        ax.set_xlabel("dofs")
        ax.set_ylabel(unit)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def markdown(rows: list[dict]) -> list[str]:
    """bench.md's 3D section.

    Args:
        rows: box3d_rows' rows.

    Returns:
        The lines.
    """
    fit = scaling(rows)
    lines = ["", "## 3D: box3d from n = 8 up, beside the 2D reference", "",
             "cases/box3d.yaml (unit cube, Gamma3 its bottom), default solver (`auto`); whole "
             "process timed from outside after a one-step warm-up; peak memory = largest "
             "resident set of the process (of one rank under mpirun); iterations = Gamma3 "
             "(fast) or Newton (SNES VI) iterations per step; Gamma3 LA = dense "
             "factorisations / CG iterations with a kept factor; agreement = max |u - u_ref| "
             "/ max |u| on Gamma3 against the default serial run of the same level (SNES "
             "VI's target row: against the target run, its wall time as a ratio to the "
             "target's in the speed-up column). "
             + REFERENCE_TEXT, "",
             "| run | dofs | N | solver | ranks | wall s | set-up s | steps s | iterations per "
             "step | Gamma3 LA | peak GB | agreement | speed-up | reference s | wall / ref |",
             "|" + "---|" * 15]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['label']} | - | {r['N']} | - | {r['nprocs']} | failed: "
                         f"{r['failed']} |" + " |" * 9)
            continue
        la = (f"{r['gamma3_factorisations']} / {r['gamma3_cg_iterations']}"
              if r.get("gamma3_factorisations") is not None else "-")
        agree, speed = r.get("agreement_vs_default"), r.get("speedup_vs_serial")
        ratio = r.get("ratio_vs_default")
        speed = f"{speed:.2f}x" if speed else f"{ratio:.2f}x the target" if ratio else "-"
        lines.append(f"| {r['label']} | {r['dofs']} | {r['N']} | {r['method']} | "
                     f"{r['nprocs']} | {r['wall_s']:.2f} | {r['setup_s']:.2f} | "
                     f"{r['loop_s']:.2f} | {' '.join(map(str, r['iterations'][:40]))} | {la} | "
                     f"{r['peak_rss_gb']:.2f} | {f'{agree:.1e}' if agree is not None else '-'} "
                     f"| {speed} | "
                     f"{' | '.join(reference_cells(r, ('wall_ratio',)))} |")
    if fit:
        lines += ["", f"Scaling of the level runs: wall time ~ dofs^{fit['time']:.2f}, peak "
                      f"memory ~ dofs^{fit['memory']:.2f} (least squares on log-log; plot "
                      "bench3d.png)."]
    return lines
